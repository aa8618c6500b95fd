"""Preference labels: the level (0 = worst) of every episode and transition of a `preference` dataset."""
from __future__ import annotations

import numpy as np

from loco_il.datasets.trajectory import Trajectories
from loco_il.utils.errors import DatasetError


def episode_levels(trajs: Trajectories) -> np.ndarray:
    """Preference level (0 = worst) of every episode of a preference dataset (also after ``split``)."""
    levels = trajs.info.get("episode_level")
    if levels is None:
        raise DatasetError("this dataset has no preference levels (info['episode_level']); "
                           "it is not a preference dataset")
    levels = np.asarray(levels, dtype=np.int64)
    if len(levels) == trajs.n_trajectories:
        return levels
    chosen = (trajs.info.get("split") or {}).get("episodes")
    if chosen is not None and len(chosen) == trajs.n_trajectories:
        return levels[np.asarray(chosen, dtype=np.int64)]
    raise DatasetError(f"info['episode_level'] has {len(levels)} entries for {trajs.n_trajectories} episodes")


def transition_levels(trajs: Trajectories) -> np.ndarray:
    """Preference level of every transition (N,)."""
    starts = np.concatenate([[0], np.flatnonzero(trajs.last)[:-1] + 1])
    stops = np.flatnonzero(trajs.last) + 1
    return np.repeat(episode_levels(trajs), stops - starts)


__all__ = ["episode_levels", "transition_levels"]
