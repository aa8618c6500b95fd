"""Reproducible train/test splits over the *episodes* of a dataset.

The sampler works on episode indices, never on single transitions, so one
episode is never cut in two and train and test never share an episode.

Semantics of :func:`make_split` (used by :meth:`Trajectories.split`):

1. The episode indices ``0 .. n_episodes - 1`` are shuffled with
   ``numpy.random.default_rng(seed).permutation``. The permutation depends
   only on ``seed`` and ``n_episodes``, so it is the same on every machine
   and in every run.
2. The first ``n_trajectories`` entries of the permutation are kept
   (all of them when ``n_trajectories`` is None). This is the pool.
3. ``portion = (lo, hi)`` selects the *train* part of the pool: pool entries
   ``[round(lo * n), round(hi * n))`` where ``n = len(pool)`` and ``round``
   rounds halves up. The *test* part is every other pool entry (before ``lo``
   and from ``hi`` on), so train and test are disjoint and together make the
   whole pool. The default ``(0.0, 0.75)`` gives 75 % train, 25 % test.

Because the pool is a prefix of one fixed permutation, asking for more
trajectories with the same seed only adds episodes: the pool for
``n_trajectories=10`` is contained in the pool for ``n_trajectories=20``.

The returned indices are sorted ascending, so the selected episodes keep
their order in the dataset.
"""

from __future__ import annotations

import math
from typing import Optional, Sequence, Tuple

import numpy as np

SPLIT_NAMES = ("train", "test")
DEFAULT_PORTION: Tuple[float, float] = (0.0, 0.75)


def _round_half_up(x: float) -> int:
    return int(math.floor(x + 0.5))


def make_split(
    n_episodes: int,
    n_trajectories: Optional[int] = None,
    split: str = "train",
    portion: Sequence[float] = DEFAULT_PORTION,
    seed: int = 0,
) -> np.ndarray:
    """Return the sorted episode indices of one split.

    Args:
        n_episodes: number of episodes in the dataset (> 0).
        n_trajectories: size of the pool drawn from the shuffled episodes;
            None takes all episodes. Must be in ``1 .. n_episodes``.
        split: ``"train"`` (episodes inside ``portion``) or ``"test"``
            (the rest of the pool).
        portion: ``(lo, hi)`` with ``0 <= lo <= hi <= 1``: the train interval,
            as fractions of the pool.
        seed: seed of the shuffle.

    Returns:
        1-D int64 array of episode indices, sorted ascending. It may be empty
        (e.g. the test split of a one-episode pool); :meth:`Trajectories.split`
        turns that into a clear error.

    Raises:
        ValueError: on an unknown split name, a bad portion or a bad count.
    """
    n_episodes = int(n_episodes)
    if n_episodes <= 0:
        raise ValueError(f"make_split needs at least one episode, got n_episodes={n_episodes}")
    if split not in SPLIT_NAMES:
        raise ValueError(f"split must be one of {SPLIT_NAMES}, got {split!r}")
    try:
        lo, hi = (float(p) for p in portion)
    except (TypeError, ValueError):
        raise ValueError(f"portion must be a pair (lo, hi) of floats, got {portion!r}") from None
    if not (0.0 <= lo <= hi <= 1.0):
        raise ValueError(f"portion must satisfy 0 <= lo <= hi <= 1, got {(lo, hi)}")
    if n_trajectories is None:
        n_pool = n_episodes
    else:
        n_pool = int(n_trajectories)
        if not (1 <= n_pool <= n_episodes):
            raise ValueError(
                f"n_trajectories must be between 1 and the number of episodes ({n_episodes}), "
                f"got {n_trajectories}"
            )

    perm = np.random.default_rng(int(seed)).permutation(n_episodes)
    pool = perm[:n_pool]
    a, b = _round_half_up(lo * n_pool), _round_half_up(hi * n_pool)
    if split == "train":
        chosen = pool[a:b]
    else:
        chosen = np.concatenate([pool[:a], pool[b:]])
    return np.sort(chosen).astype(np.int64)


__all__ = ["make_split", "SPLIT_NAMES", "DEFAULT_PORTION"]
