"""How long a position-servo robot stays up under per-step exploration noise around its home action.

    python benchmarks/servo_noise.py [--task G1.walk] [--episodes 4]

Each row drives the robot with env action = clip(home + scale * tanh(sigma * N(0, 1)), -1, 1), fresh noise at
every control step (what a Gaussian RL policy whose mean is the home action explores with; `scale` < 1 is the
"residual action" parametrization of legged-robot RL), and prints the episode lengths (out of the horizon).
"""
from __future__ import annotations

import argparse

import numpy as np

from loco_il.environments import LocoEnv

SETTINGS = [(1.0, 0.0), (1.0, 0.03), (0.2, 0.3), (0.1, 1.0), (0.1, 0.3), (0.05, 1.0)]   # (scale, sigma)


def episode_lengths(env: LocoEnv, home: np.ndarray, scale: float, sigma: float, episodes: int,
                    rng: np.random.Generator) -> list[int]:
    lengths = []
    for ep in range(episodes):
        env.seed(ep)
        env.reset()
        steps = 0
        for steps in range(1, env.info.horizon + 1):
            action = np.clip(home + scale * np.tanh(sigma * rng.standard_normal(home.shape)), -1.0, 1.0)
            _, _, absorbing, _ = env.step(action)
            if absorbing:
                break
        lengths.append(steps)
    return lengths


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--task", default="G1.walk")
    ap.add_argument("--episodes", type=int, default=4)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    env = LocoEnv.make(args.task)
    if "home_action" not in env.body.extra:
        raise SystemExit(f"{args.task} has no home action (only position-servo robots do)")
    home = np.asarray(env.body.extra["home_action"], dtype=np.float64)
    rng = np.random.default_rng(args.seed)
    print(f"{args.task}: horizon {env.info.horizon}, control dt {env.body.control_dt:.3f} s, {home.size} servos")
    print(f"{'env action':40s} episode lengths (steps)")
    for scale, sigma in SETTINGS:
        lengths = episode_lengths(env, home, scale, sigma, args.episodes, rng)
        print(f"{f'home + {scale:g} * tanh({sigma:g} N(0,1))':40s} {' '.join(f'{n:4d}' for n in lengths)}", flush=True)


if __name__ == "__main__":
    main()
