"""`create_dataset(env, ...)`: the dataset of an env's Task-ID, whole or as a reproducible split.

    env = LocoEnv.make("Hopper.run.perfect")
    data = env.create_dataset()                                 # all episodes (generated once, then cached)
    train = env.create_dataset(split="train", n_trajectories=20, seed=0)
    test = env.create_dataset(split="test", n_trajectories=20, seed=0)

Observations: datasets are recorded with full observations; the returned dataset has the
observations ``env`` emits (``.pomdp`` and ``hide=`` masks applied, ``info["obs_names"]`` masked,
``info["full_obs_names"]`` and ``info["obs_mask"]`` kept) unless ``full_obs=True``.
"""
from __future__ import annotations

import inspect
import os
from typing import Any, Sequence

import numpy as np

from loco_il.datasets.splits import DEFAULT_PORTION, make_split
from loco_il.datasets.trajectory import DatasetError, Trajectories


def create_dataset(env: Any, n_trajectories: int | None = None, split: str | None = None,
                   portion: Sequence[float] = DEFAULT_PORTION, seed: int = 0, *,
                   n_episodes: int | None = None, generation_seed: int = 0,
                   expert_path: str | os.PathLike | None = None, expert: Any = None,
                   snapshots: Sequence[Any] | None = None, regenerate: bool = False, full_obs: bool = False,
                   return_init_states: bool = False, verbose: bool = True, workers: int = 1,
                   **provider_kwargs: Any):
    """The dataset of ``env``'s Task-ID (a ``LocoEnv`` or a Task-ID string).

    Args:
        n_trajectories: size of the episode pool drawn (with ``seed``) from the dataset; None = all.
        split: None (the whole pool), ``"train"`` or ``"test"``: the reproducible episode split of
            :meth:`Trajectories.split` (``portion`` of the pool is train, the rest test).
        portion, seed: split arguments (``seed`` only shuffles; it does not change the data).
        n_episodes: episodes to generate (perfect: 100; preference: 25 per level).
        generation_seed: base seed of the episodes' reset seeds (part of the cache key).
        expert_path / expert: a user expert file / object (``__call__(obs) -> action``,
            ``checksum()``) instead of the task's installed expert (perfect only).
        snapshots: expert files or objects, one per preference level (preference only).
        regenerate: rebuild the cached files even if they exist (e.g. after a corruption error).
        full_obs: return full observations even for a ``.pomdp`` env.
        return_init_states: also return the :class:`~loco_il.datasets.providers.InitStates`
            of the returned episodes (None for providers that have none).
        verbose: print generation progress.
        workers: processes that generate a rollout dataset's episodes (perfect, preference: the same
            data for any number); providers that roll out nothing ignore it. Scripts that pass > 1 must
            start their work under ``if __name__ == "__main__":`` (workers start from a fork server, or
            are spawned where there is none).
        provider_kwargs: passed on to the provider (e.g. to a `real` provider).

    Returns:
        ``Trajectories`` (or ``(Trajectories, InitStates | None)``).
    """
    from loco_il.datasets.providers.registry import get_provider

    if isinstance(env, str):
        from loco_il.environments.registry import make
        env = make(env)
    if split is not None and split not in ("train", "test"):
        raise ValueError(f"split must be None, 'train' or 'test', got {split!r}")
    provider = get_provider(env.dataset_type, env)
    kwargs = dict(provider_kwargs)
    for name, value in (("n_episodes", n_episodes), ("expert_path", expert_path), ("expert", expert),
                        ("snapshots", snapshots)):
        if value is not None:
            kwargs[name] = value
    kwargs.update(generation_seed=int(generation_seed), regenerate=bool(regenerate), verbose=bool(verbose))
    if int(workers) < 1:
        raise ValueError(f"workers must be >= 1, got {workers}")
    if int(workers) > 1 and "workers" in inspect.signature(provider).parameters:
        kwargs["workers"] = int(workers)
    result = provider(env, **kwargs)
    data, init = result if isinstance(result, tuple) else (result, None)
    if not isinstance(data, Trajectories):
        raise TypeError(f"the {env.dataset_type!r} provider returned {type(data).__name__}, not Trajectories")
    if init is not None and len(init) != data.n_trajectories:
        raise DatasetError(f"the provider returned {len(init)} initial states for {data.n_trajectories} episodes")

    data = _for_env(data, env, full_obs)

    if split is not None:
        data = data.split(n_trajectories, split, portion, seed)
        chosen = np.asarray(data.info["split"]["episodes"], dtype=np.int64)
    elif n_trajectories is not None:
        try:
            chosen = make_split(data.n_trajectories, n_trajectories, "train", (0.0, 1.0), seed)
        except ValueError as exc:
            raise DatasetError(str(exc)) from None
        info = dict(data.info)
        info["split"] = {"split": None, "n_trajectories": int(n_trajectories), "portion": [0.0, 1.0],
                         "seed": int(seed), "episodes": chosen.tolist()}
        data = data.select_episodes(chosen, info=info)
    else:
        chosen = None
    if chosen is not None:
        if "episode_level" in data.info:   # keep per-episode labels aligned with the episodes
            info = dict(data.info)
            info["episode_level"] = [int(data.info["episode_level"][i]) for i in chosen]
            data = data.replace(info=info)
        if init is not None:
            init = init.select(chosen)
    return (data, init) if return_init_states else data


def _for_env(data: Trajectories, env: Any, full_obs: bool) -> Trajectories:
    """Check the dataset against the env's full observation and apply the env's mask."""
    full = getattr(env, "full_obs_spec", None)
    mask = getattr(env, "obs_mask", None)
    if full is None:
        return data
    from loco_il.datasets.env_check import check_dataset_for_env, warn
    warn(check_dataset_for_env(data, env))   # refuses a dataset of another task, observation or action scale
    info = dict(data.info)
    if info.get("task_id") not in (None, env.task_id):
        info.setdefault("generated_in", info["task_id"])   # e.g. a variant's data from the base body's expert
    info["task_id"] = env.task_id
    if full_obs or mask is None or bool(np.all(mask)):
        return data.replace(info=info)
    mask = np.asarray(mask, dtype=bool)
    info.update(obs_names=[n for n, m in zip(full.names, mask) if m], full_obs_names=list(full.names),
                obs_mask=mask.tolist())
    return data.replace(obs=data.obs[:, mask], next_obs=data.next_obs[:, mask], info=info)


__all__ = ["create_dataset"]
