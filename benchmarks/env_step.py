"""Env step throughput vs raw MuJoCo, and env creation time, per body.

For each body: steps/s of `env.step` with random actions, the time of `mj_step(model, data, nstep=n_substeps)`
on the same model and states (the floor: physics only), their ratio (overhead), and the time to create the env
(assets already cached). Raw and env timings alternate in blocks in one process, so machine load hits both alike.

    python benchmarks/env_step.py [--steps 2000] [--bodies Hopper Humanoid ...]
"""
from __future__ import annotations

import argparse
import time

import mujoco
import numpy as np

from loco_il import LocoEnv
from loco_il.environments.registry import bodies


def time_env(env: LocoEnv, actions: np.ndarray) -> tuple[float, dict[int, tuple[np.ndarray, np.ndarray]]]:
    """Time env.step over the actions; return the time and the start states of its episodes by step index."""
    env.seed(0)
    env.reset()
    starts = {0: env.get_sim_state()}
    start = time.perf_counter()
    for i, a in enumerate(actions):
        _, _, absorbing, _ = env.step(a)
        if absorbing:
            env.reset()
            starts[i + 1] = env.get_sim_state()
    elapsed = time.perf_counter() - start
    return elapsed, starts


def time_raw(env: LocoEnv, actions: np.ndarray, starts: dict) -> float:
    """The same physics as `time_env` (same actions, same episode starts), with nothing but mj_step."""
    model, data = env.model, env.data
    ctrl = env._ctrl_center + actions.clip(-1, 1) * env._ctrl_half
    start = time.perf_counter()
    for i, c in enumerate(ctrl):
        if i in starts:
            mujoco.mj_resetData(model, data)
            data.qpos[:], data.qvel[:] = starts[i]
        data.ctrl[:] = c
        mujoco.mj_step(model, data, nstep=env.n_substeps)
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--steps", type=int, default=2000)
    parser.add_argument("--blocks", type=int, default=3)
    parser.add_argument("--bodies", nargs="*", default=None)
    args = parser.parse_args()
    names = args.bodies or sorted(bodies())
    print(f"{'body':<18}{'create s':>10}{'env steps/s':>13}{'raw steps/s':>13}{'env/raw time':>14}{'substeps':>10}")
    for name in names:
        LocoEnv.make(name)          # warm the asset cache and imports
        start = time.perf_counter()
        env = LocoEnv.make(name, seed=0)
        create = time.perf_counter() - start
        rng = np.random.default_rng(0)
        actions = rng.uniform(-1, 1, (args.steps, env.model.nu))
        t_env = t_raw = 0.0
        for _ in range(args.blocks):
            elapsed, starts = time_env(env, actions)
            t_env += elapsed
            t_raw += time_raw(env, actions, starts)
        n = args.steps * args.blocks
        print(f"{name:<18}{create:>10.3f}{n / t_env:>13.0f}{n / t_raw:>13.0f}{t_env / t_raw:>14.2f}"
              f"{env.n_substeps:>10d}", flush=True)


if __name__ == "__main__":
    main()
