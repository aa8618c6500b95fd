"""Vectorized stepping of loco_il environments with Gymnasium's vector API.

* `make_vec_env(task_id, num_envs, async_mode="auto")`: `SyncVectorEnv` (all envs in this process)
  or `AsyncVectorEnv` (one subprocess per env; worth it with many cores). "auto" picks async when
  `num_envs > 1` and the machine has at least `num_envs` / 2 + 1 ... see `resolve_async`.
* Training envs auto-reset in Gymnasium's SAME_STEP mode: on the step that ends an episode the
  returned observation is the next episode's first one and the real last observation is in
  `infos["final_obs"][i]` (needed to bootstrap V(s_T) on truncation).
* `evaluate(act_fn, vec_env, episodes, seed)`: evaluation episodes spread over the envs of an
  auto-resetting vector env, reproducible given the seed. This is the one episode loop kept apart from
  `loco_il.environments.episodes`: it steps all envs in lockstep with one batched policy call per step (and,
  async, the envs in parallel processes), which the trainers' frequent evaluations need; running the episodes
  one at a time would call the network once per env and step. It shares the per-episode outcome
  (`Outcome`, `outcome_arrays`).

Each env is a `LocoGymEnv` behind `_LeanEnv`, which drops the per-step `info` dict (reward terms
are not needed for training, and passing them between processes costs time) and, once an episode
ended, keeps returning its last observation with zero reward instead of stepping a finished (perhaps
diverged) simulation.
"""
from __future__ import annotations

import functools
import multiprocessing
import os
import signal
from typing import Any, Callable, Mapping

import gymnasium as gym
import numpy as np
from gymnasium.vector import AsyncVectorEnv, AutoresetMode, SyncVectorEnv, VectorEnv

from loco_il.environments.episodes import Outcome, outcome_arrays


class _LeanEnv(gym.Wrapper):
    def __init__(self, env: gym.Env):
        super().__init__(env)
        self._done = False
        self._last: np.ndarray | None = None

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        obs, _ = self.env.reset(seed=seed, options=options)
        self._done, self._last = False, obs
        return obs, {}

    def step(self, action):
        if self._done:
            return self._last, 0.0, True, False, {}
        obs, reward, terminated, truncated, _ = self.env.step(action)
        self._done, self._last = bool(terminated or truncated), obs
        return obs, reward, terminated, truncated, {}


def _make_env(task_id: str, env_kwargs: Mapping[str, Any] | None = None,
              factory: Callable[..., gym.Env] | None = None) -> gym.Env:
    """`factory(task_id, **env_kwargs)` (default: the task's `LocoGymEnv`) behind `_LeanEnv`."""
    if factory is None:
        from loco_il.environments.gym_adapter import LocoGymEnv as factory
    return _LeanEnv(factory(task_id, **dict(env_kwargs or {})))


def _make_worker_env(task_id: str, env_kwargs: Mapping[str, Any] | None = None,
                     factory: Callable[..., gym.Env] | None = None) -> gym.Env:
    """`_make_env` inside an AsyncVectorEnv worker process. Ctrl-C / SIGTERM reach the whole process group,
    and the trainer (parent) stops after its iteration with a checkpoint; a worker that died on the signal
    would break that last iteration. Workers exit when the parent closes them or its pipe goes away.
    Gymnasium's AsyncVectorEnv also calls this once in the parent (to read the spaces): there the signals
    must keep the trainer's handlers."""
    if multiprocessing.parent_process() is not None:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
    return _make_env(task_id, env_kwargs, factory)


def resolve_async(async_mode: bool | str | None, num_envs: int) -> bool:
    """"auto"/None: subprocesses when there are >1 envs and at least 4 cores; else the given bool."""
    if isinstance(async_mode, str):
        mode = async_mode.strip().lower()
        if mode in ("auto", ""):
            async_mode = None
        elif mode in ("true", "1", "yes", "async"):
            async_mode = True
        elif mode in ("false", "0", "no", "sync"):
            async_mode = False
        else:
            raise ValueError(f"async must be auto, true or false; got {async_mode!r}")
    if async_mode is None:
        return num_envs > 1 and (os.cpu_count() or 1) >= 4
    return bool(async_mode)


def make_vec_env(task_id: str, num_envs: int, async_mode: bool | str | None = "auto", autoreset: bool = True,
                 env_kwargs: Mapping[str, Any] | None = None, context: str | None = "forkserver",
                 factory: Callable[..., gym.Env] | None = None) -> VectorEnv:
    """A Gymnasium vector env of `num_envs` copies of `task_id` (see the module docstring); `factory(task_id,
    **env_kwargs)` builds each env instead of `LocoGymEnv` (a module-level callable, so workers can unpickle it)."""
    if num_envs < 1:
        raise ValueError(f"num_envs must be >= 1, got {num_envs}")
    is_async = resolve_async(async_mode, num_envs)
    make = _make_worker_env if is_async else _make_env
    fns: list[Callable[[], gym.Env]] = [functools.partial(make, task_id, dict(env_kwargs or {}), factory)
                                        for _ in range(num_envs)]
    mode = AutoresetMode.SAME_STEP if autoreset else AutoresetMode.DISABLED
    if is_async:
        return AsyncVectorEnv(fns, shared_memory=True, copy=True, context=context, autoreset_mode=mode)
    return SyncVectorEnv(fns, copy=True, autoreset_mode=mode)


def evaluate(act_fn: Callable[[np.ndarray], np.ndarray], vec_env: VectorEnv, episodes: int,
             seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Run `episodes` episodes with `act_fn` (batched obs -> batched actions); returns (returns, lengths).

    Env i is reset with seed `seed + i` and runs episodes i, i + n, i + 2n, ... (n = num_envs; the
    auto-reset draws the later start states from its seeded generator), so the result is a function
    of (act_fn, seed, n). Envs that finished their share keep stepping until all have; those steps
    are ignored.
    """
    returns, lengths, _ = evaluate_episodes(act_fn, vec_env, episodes, seed)
    return returns, lengths


def evaluate_episodes(act_fn: Callable[[np.ndarray], np.ndarray], vec_env: VectorEnv, episodes: int,
                      seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """`evaluate`, plus for each episode whether it was terminated (a fall, leaving the healthy range) rather
    than truncated at the time limit."""
    n = vec_env.num_envs
    quota = np.array([episodes // n + (1 if i < episodes % n else 0) for i in range(n)])
    done: list[list[Outcome]] = [[] for _ in range(n)]
    obs, _ = vec_env.reset(seed=[seed + i for i in range(n)])
    ret, length = np.zeros(n), np.zeros(n, dtype=np.int64)
    while any(len(done[i]) < quota[i] for i in range(n)):
        actions = np.asarray(act_fn(obs), dtype=np.float32)
        obs, reward, terminated, truncated, _ = vec_env.step(actions)
        ret += reward
        length += 1
        terminated = np.asarray(terminated)
        ended = terminated | np.asarray(truncated)
        for i in np.flatnonzero(ended):
            if len(done[i]) < quota[i]:
                done[i].append(Outcome(float(ret[i]), int(length[i]), bool(terminated[i])))
        ret[ended], length[ended] = 0.0, 0
    return outcome_arrays([done[k % n][k // n] for k in range(episodes)])
