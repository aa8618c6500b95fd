"""Roll out a policy (random by default, or an expert file) on a Task-ID, print returns, optionally write an mp4
and a strip of frames. The episodes are those of `loco_il.environments.episodes.run_episode`; episode k starts
from reset seed ``--seed`` + k.

    python -m loco_il.rollout --task Hopper.run.perfect --episodes 3 --video rollout.mp4
    python -m loco_il.rollout --task Atlas.walk.perfect --expert runs/experts/Atlas.walk/seed0/best.pt \
        --episodes 1 --max-steps 300 --strip docs/atlas_walk.png
"""
from __future__ import annotations

import argparse
import os
import time

import numpy as np


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--task", default="Hopper.run.perfect", help="Task-ID, e.g. UnitreeH1.walk.real")
    parser.add_argument("--episodes", type=int, default=3)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--video", default=None, help="write the first episode to this mp4 file")
    parser.add_argument("--max-steps", type=int, default=None, help="cap on steps per episode")
    parser.add_argument("--expert", default=None, help="an expert file (.pt) to roll out instead of random actions")
    parser.add_argument("--strip", default=None, help="write evenly spaced frames of the first episode to this PNG")
    parser.add_argument("--strip-frames", type=int, default=6)
    args = parser.parse_args(argv)
    os.environ.setdefault("MUJOCO_GL", "egl")

    from loco_il import LocoEnv
    from loco_il.environments.episodes import UniformRandomPolicy, run_episode
    from loco_il.environments.rendering import record_episode

    env = LocoEnv.make(args.task, seed=args.seed)
    print(f"{env.task_id}: obs dim {env.obs_spec.dim}, action dim {env.info.action_space.shape[0]}, "
          f"control dt {env.dt:.4f} s, horizon {env.info.horizon}")
    expert = None
    if args.expert:
        from loco_il.experts import load_expert
        expert = load_expert(args.expert)
    # the random policy's stream runs on over the episodes (the recorded one draws from its own)
    policy = expert if expert is not None else UniformRandomPolicy(env.info.action_space.shape,
                                                                   np.random.default_rng(args.seed))
    returns = []
    for episode in range(args.episodes):
        start = time.perf_counter()
        if episode == 0 and (args.video or args.strip):
            result = record_episode(env, expert, args.video, max_steps=args.max_steps, seed=args.seed,
                                    strip=args.strip, strip_frames=args.strip_frames)
            total, steps = result["return"], result["steps"]
            print("wrote " + ", ".join(p for p in (result["path"], result["strip"]) if p))
        else:
            ran = run_episode(env, policy, args.seed + episode, args.max_steps or env.info.horizon)
            total, steps = ran.ret, ran.length
        returns.append(total)
        print(f"episode {episode}: return {total:.2f} over {steps} steps ({time.perf_counter() - start:.2f} s)")
    who = args.expert or "random policy"
    print(f"{who}: mean return {np.mean(returns):.2f} +- {np.std(returns):.2f} over {len(returns)} episodes")


if __name__ == "__main__":
    main()
