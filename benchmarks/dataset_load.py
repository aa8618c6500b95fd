"""Time ``Trajectories.load`` on a 1M-transition dataset (obs_dim 30, act_dim 10).

Usage: ``python benchmarks/dataset_load.py [--dtype float64] [--n 1000000]``

Builds a synthetic dataset of 1000-step episodes (next_obs[t] == obs[t+1]
inside an episode, as in a recorded rollout), saves it in a temporary
directory, and prints the best of 3 load times in seconds.
"""

from __future__ import annotations

import argparse
import os
import pathlib
import sys
import tempfile
import time

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))

from loco_il.datasets import Trajectories  # noqa: E402


def build(n: int, obs_dim: int, act_dim: int, episode_len: int, dtype) -> Trajectories:
    rng = np.random.default_rng(0)
    n_eps = -(-n // episode_len)
    rows = np.arange(n)
    episode = rows // episode_len
    states = rng.standard_normal((n + n_eps, obs_dim)).astype(dtype)
    last = np.zeros(n, dtype=bool)
    last[episode_len - 1 :: episode_len] = True
    last[-1] = True
    return Trajectories(
        obs=states[rows + episode],
        next_obs=states[rows + episode + 1],
        actions=rng.uniform(-1, 1, (n, act_dim)).astype(dtype),
        rewards=rng.standard_normal(n).astype(dtype),
        absorbing=np.zeros(n, dtype=bool),
        last=last,
        info={"task_id": "Benchmark.walk.perfect", "dataset_type": "perfect", "source": "benchmark",
              "obs_names": [f"o{i}" for i in range(obs_dim)], "seed": 0},
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=1_000_000)
    parser.add_argument("--obs-dim", type=int, default=30)
    parser.add_argument("--act-dim", type=int, default=10)
    parser.add_argument("--episode-len", type=int, default=1000)
    parser.add_argument("--dtype", choices=["float32", "float64"], default="float64")
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()

    data = build(args.n, args.obs_dim, args.act_dim, args.episode_len, np.dtype(args.dtype))
    with tempfile.TemporaryDirectory() as tmp:
        path = pathlib.Path(tmp) / "bench.npz"
        t0 = time.perf_counter()
        data.save(path)
        save_s = time.perf_counter() - t0
        size_mb = os.path.getsize(path) / 1e6
        del data
        times = []
        for _ in range(args.repeats):
            t0 = time.perf_counter()
            loaded = Trajectories.load(path)
            times.append(time.perf_counter() - t0)
            del loaded
    print(
        f"dataset_load: n={args.n} obs_dim={args.obs_dim} act_dim={args.act_dim} dtype={args.dtype} "
        f"file={size_mb:.0f} MB save={save_s:.2f} s"
    )
    print(f"Trajectories.load best of {args.repeats}: {min(times):.3f} s")


if __name__ == "__main__":
    main()
