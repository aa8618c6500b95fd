"""The simulator state at the start of every episode of a dataset, and start-state samplers built from data.

``Trajectories`` holds no per-episode arrays, so the simulator state at the start of every episode (``qpos``,
``qvel``) and the episode's reset seed are kept in :class:`InitStates`, saved next to the dataset as
``<name>.init_states.npz`` (`loco_il.datasets.providers.cache.init_states_path`). Replaying episode ``i`` from
``(qpos[i], qvel[i])`` with its recorded actions reproduces its observations exactly
(`loco_il.environments.episodes.replay_episode`; tasks with a sampled command also need the reset seed,
which replays the command).

`dataset_init_state_sampler` turns them (or the states of a full-observation dataset) into an env's
``init_state_sampler``: episodes that start where the data starts.
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterable, Sequence

import numpy as np

from loco_il.datasets.npz import load_error, read_npz
from loco_il.datasets.trajectory import Trajectories
from loco_il.utils.atomic import atomic_open
from loco_il.utils.errors import DatasetError


@dataclass
class InitStates:
    """Simulator state at the start of every episode of a dataset, aligned with its episodes.

    ``qpos`` (E, nq), ``qvel`` (E, nv), ``seeds`` (E,) int64: the seed passed to ``env.seed``
    before the ``reset`` that started the episode (-1 if unknown).
    """

    qpos: np.ndarray
    qvel: np.ndarray
    seeds: np.ndarray

    def __post_init__(self) -> None:
        self.qpos = np.asarray(self.qpos, dtype=np.float64)
        self.qvel = np.asarray(self.qvel, dtype=np.float64)
        self.seeds = np.asarray(self.seeds, dtype=np.int64)
        if self.qpos.ndim != 2 or self.qvel.ndim != 2 or self.seeds.ndim != 1 \
                or not (len(self.qpos) == len(self.qvel) == len(self.seeds)):
            raise DatasetError(f"InitStates: qpos (E, nq), qvel (E, nv) and seeds (E,) must agree; got "
                               f"{self.qpos.shape}, {self.qvel.shape}, {self.seeds.shape}")

    def __len__(self) -> int:
        return len(self.seeds)

    def select(self, indices: Iterable[int]) -> "InitStates":
        idx = np.asarray(list(indices), dtype=np.int64)
        return InitStates(self.qpos[idx], self.qvel[idx], self.seeds[idx])

    @classmethod
    def concatenate(cls, parts: Sequence["InitStates"]) -> "InitStates":
        return cls(np.concatenate([p.qpos for p in parts]), np.concatenate([p.qvel for p in parts]),
                   np.concatenate([p.seeds for p in parts]))

    def save(self, path: str | os.PathLike) -> Path:
        with atomic_open(path) as fh:
            np.savez(fh, format_version=np.asarray(1), qpos=self.qpos, qvel=self.qvel, seeds=self.seeds)
        return Path(path)

    @classmethod
    def load(cls, path: str | os.PathLike, regenerate_hint: str | None = None,
             n_episodes: int | None = None, nq: int | None = None, nv: int | None = None) -> "InitStates":
        path = Path(path)
        fail = load_error(path, "initial-state file", regenerate_hint)
        with read_npz(path, fail) as z:
            try:
                out = cls(z["qpos"], z["qvel"], z["seeds"])
            except DatasetError as exc:
                raise fail(str(exc)) from None
        if n_episodes is not None and len(out) != n_episodes:
            raise fail(f"it has {len(out)} episodes, the dataset has {n_episodes}")
        if (nq is not None and out.qpos.shape[1] != nq) or (nv is not None and out.qvel.shape[1] != nv):
            raise fail(f"its states have nq={out.qpos.shape[1]}, nv={out.qvel.shape[1]}; "
                       f"the model has nq={nq}, nv={nv}")
        if not (np.isfinite(out.qpos).all() and np.isfinite(out.qvel).all()):
            raise fail("it contains non-finite values")
        return out


def dataset_init_state_sampler(init_states: InitStates | None = None, *, env: Any = None,
                               trajs: Trajectories | None = None) -> Callable[[np.random.Generator],
                                                                                tuple[np.ndarray, np.ndarray]]:
    """An ``init_state_sampler`` for ``LocoEnv`` that starts episodes from dataset states.

    * ``dataset_init_state_sampler(init_states)``: a uniformly drawn episode's initial state.
    * ``dataset_init_state_sampler(env=env, trajs=full_obs_dataset)``: any state of the dataset
      (as LocoMuJoCo does), rebuilt from a full observation: positions and velocities are the
      observation's entries; the root's horizontal position (not observed) is the env's default. For a
      task that draws a version of the model per episode (carry's mass, 4Ages' size) only the states
      recorded on the episode's version are drawn (LocoMuJoCo's `scaling_trajectory_map`).

    Use: ``env.init_state_sampler = dataset_init_state_sampler(...)``.
    """
    if init_states is not None:
        qpos, qvel = init_states.qpos.copy(), init_states.qvel.copy()
    else:
        if env is None or trajs is None:
            raise ValueError("pass init_states, or env= and trajs= (a full-observation dataset)")
        spec = env.full_obs_spec
        if trajs.obs_dim != spec.dim:
            raise DatasetError(f"the dataset has {trajs.obs_dim} observation entries; rebuilding states needs the "
                               f"full observation ({spec.dim}); create it with full_obs=True")
        layout = env._layout
        npos, nvel = len(layout.qpos_idx), len(layout.qvel_idx)
        states = np.concatenate([trajs.obs, trajs.next_obs[trajs.last]])
        qpos = np.tile(env._init_qpos, (len(states), 1))
        qpos[:, layout.qpos_idx] = states[:, :npos]
        qvel = np.zeros((len(states), env.model.nv))
        qvel[:, layout.qvel_idx] = states[:, npos:npos + nvel]
        if getattr(env, "draw", None) is not None:
            return _per_version_sampler(env, states[:, npos + nvel:], qpos, qvel)
    if len(qpos) == 0:
        raise DatasetError("no states to sample from")

    def sample(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        i = int(rng.integers(len(qpos)))
        return qpos[i].copy(), qvel[i].copy()

    return sample


def _per_version_sampler(env: Any, entries: np.ndarray, qpos: np.ndarray,
                        qvel: np.ndarray) -> Callable[[np.random.Generator], tuple[np.ndarray, np.ndarray]]:
    """Sample states whose draw entries are those of the env's current version of the model."""
    draw = env.draw
    rows = {}
    for i in env.draw_indices:
        rows[i] = np.flatnonzero(np.all(entries == draw.features(draw.values[i]), axis=1))
        if rows[i].size == 0:
            raise DatasetError(f"the dataset has no states of {env.task_id}'s version {draw.values[i]} "
                               f"({', '.join(draw.names)}); build it for this Task-ID's mode")

    def sample(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        candidates = rows[env.drawn_index]
        i = int(candidates[rng.integers(len(candidates))])
        return qpos[i].copy(), qvel[i].copy()

    return sample


__all__ = ["InitStates", "dataset_init_state_sampler"]
