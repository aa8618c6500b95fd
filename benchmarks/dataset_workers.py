"""Wall time of generating a `perfect` dataset's episodes in one process against several worker processes
(`create_dataset(..., workers=N)`), in the same run, and whether the data are identical.

The task's expert (shipped or built-in) is rolled out for `--episodes` episodes from the dataset's reset seeds,
without the cache (`rollout` directly), once with one process and once per start method and worker count;
the first pass warms nothing the others use (each worker builds its own env). `spawn` workers each import
torch, mushroom-rl and loco_il themselves; `forkserver` workers are forked from a server that imported them
once (the default where the platform has it), which the first forkserver row pays for and later ones reuse.
Prints seconds, episodes/s and the ratio to one process, and stops with exit status 1 if any pass gives other
data.

    python benchmarks/dataset_workers.py [--task Humanoid.run.perfect] [--episodes 16] [--workers 2 4]
                                         [--start-methods spawn forkserver] [--horizon 1000]
"""
from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", default="Humanoid.run.perfect")
    parser.add_argument("--episodes", type=int, default=16)
    parser.add_argument("--workers", type=int, nargs="+", default=[2])
    parser.add_argument("--start-methods", nargs="+", default=["spawn", "forkserver"],
                        choices=["spawn", "forkserver"], help="how worker processes start (see the module doc)")
    parser.add_argument("--horizon", type=int, default=None, help="episode length cap (default: the task's)")
    args = parser.parse_args(argv)

    import torch
    torch.set_num_threads(1)
    from loco_il.datasets.providers import rollout_workers
    from loco_il.datasets.providers.expert import generation_env, rollout
    from loco_il.environments.episodes import episode_seeds
    from loco_il.environments.registry import make, task_key
    from loco_il.experts.files import load_policy

    env = make(args.task)
    key = task_key(env)
    gen_env = generation_env(env, key)
    policy, where = load_policy(key=key, env=gen_env)
    seeds = episode_seeds(0, args.episodes)
    print(f"task {args.task}, expert {where}, {args.episodes} episodes, {os.cpu_count()} CPUs")
    print(f"{'start':>10}  {'processes':>9}  {'seconds':>8}  {'episodes/s':>10}  {'vs 1':>6}  same data")
    base, base_time, same_everywhere = None, None, True
    passes = [("-", 1)] + [(method, n) for method in args.start_methods for n in args.workers]
    for method, workers in passes:
        if workers > 1:
            rollout_workers.START_METHOD = method
        t0 = time.perf_counter()
        data, init = rollout(gen_env, policy, seeds, horizon=args.horizon, workers=workers)
        seconds = time.perf_counter() - t0
        if base is None:
            base, base_time = (data, init), seconds
            same = True
        else:
            same = all(np.array_equal(getattr(data, k), getattr(base[0], k))
                       for k in ("obs", "next_obs", "actions", "rewards", "absorbing", "last"))
            same = same and np.array_equal(init.qpos, base[1].qpos) and np.array_equal(init.qvel, base[1].qvel)
            same_everywhere &= same
        print(f"{method:>10}  {workers:>9}  {seconds:>8.2f}  {args.episodes / seconds:>10.2f}  "
              f"{base_time / seconds:>5.2f}x  {'yes' if same else 'NO'}")
    gen_env.stop()
    return 0 if same_everywhere else 1


if __name__ == "__main__":
    sys.exit(main())
