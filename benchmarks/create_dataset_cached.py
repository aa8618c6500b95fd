"""Time `env.create_dataset()` on a cached 1M-transition perfect dataset (issue #3: under 2 s).

Generates InvertedPendulum.balance.perfect with 1000 expert episodes (1000 steps each) into the cache once
(a few minutes), then times cache hits, best of 3.

    python benchmarks/create_dataset_cached.py [--episodes 1000]
"""
from __future__ import annotations

import argparse
import time

from loco_il import LocoEnv
from loco_il.datasets.providers import STATS


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--episodes", type=int, default=1000)
    args = parser.parse_args()
    env = LocoEnv.make("InvertedPendulum.balance.perfect")
    start = time.perf_counter()
    data = env.create_dataset(n_episodes=args.episodes, verbose=False)
    print(f"first call (generation or cache hit): {time.perf_counter() - start:.1f} s, "
          f"{data.n_transitions} transitions, obs dim {data.obs_dim}")
    times = []
    for _ in range(3):
        start = time.perf_counter()
        data = env.create_dataset(n_episodes=args.episodes, verbose=False)
        times.append(time.perf_counter() - start)
    print(f"create_dataset on the cached dataset: best of 3 {min(times):.3f} s ({data.n_transitions} transitions); "
          f"cache stats {dict(STATS)}")


if __name__ == "__main__":
    main()
