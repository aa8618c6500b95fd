"""Record a rollout dataset's episodes in several processes (`rollout(..., workers=N)`).

Generating a dataset is one simulator step and one policy call per transition, in one Python thread (one
Humanoid episode of 1000 steps: ~0.8 s on a GPU machine's core, ~1.7 s on the busy 2-core development
machine). Each episode depends only on its reset seed (`rollout_episode`), so episodes can be recorded by
separate processes, each with its own env of the task, and put back in seed order: the result is the same data
as one process gives, which the tests check exactly.

Workers are not forked from the calling process (a fork of a process that already ran torch or MuJoCo threads
is not safe). Where the platform has it they come from a ``forkserver``: a fresh server process imports torch,
mushroom-rl and loco_il once and forks each worker from itself, so the workers skip those imports (~7 s a
process on the busy 2-core development machine; on a 16-core GPU machine 16 spawned workers took 34 s for 16
Humanoid episodes that one process recorded in 13.5 s; `benchmarks/dataset_workers.py`). Elsewhere (Windows)
they are spawned. Each builds the env from its Task-ID (``make(env.task_id)``: an env made with extra keyword
arguments is not rebuilt the same way, and one whose observation or action size differs is refused), unpickles
the policy and uses one torch thread. A policy that cannot be pickled (e.g. a closure) is recorded in this process
instead, with a message saying why. As with any ``spawn`` or ``forkserver`` pool, a script that generates with
workers must start its work under ``if __name__ == "__main__":``.
"""
from __future__ import annotations

import multiprocessing
import pickle
from concurrent.futures import ProcessPoolExecutor
from typing import Any, Callable, Sequence

from loco_il.datasets.providers.expert import rollout_episode
from loco_il.environments.episodes import Episode

# "forkserver" or "spawn"; read at each call (the benchmark sets it to compare the two)
START_METHOD = "forkserver" if "forkserver" in multiprocessing.get_all_start_methods() else "spawn"
# what the fork server imports once for all its workers: everything a worker needs before its first episode
_PRELOAD = ["torch", "loco_il.environments.registry", "loco_il.datasets.providers.expert", "loco_il.experts.policy"]

_ENV: Any = None        # the worker process's env and policy (set once by _start_worker)
_POLICY: Any = None
_HORIZON = 0


def _start_worker(task_id: str, policy_bytes: bytes, horizon: int, shape: tuple[int, int]) -> None:
    global _ENV, _POLICY, _HORIZON
    import torch
    torch.set_num_threads(1)     # N workers x all cores each would oversubscribe the machine
    from loco_il.environments.registry import make
    _ENV = make(task_id)
    built = (int(_ENV.info.observation_space.shape[0]), int(_ENV.model.nu))
    if built != shape:   # e.g. an env made with hide=: its Task-ID does not say so
        raise RuntimeError(f"make({task_id!r}) in a worker gives observation/action sizes {built}, the env being "
                           f"rolled out has {shape}: record its episodes with workers=1")
    _POLICY = pickle.loads(policy_bytes)
    _HORIZON = horizon


def _record(seed: int) -> Episode:
    return rollout_episode(_ENV, _POLICY, seed, _HORIZON)


def record_in_workers(env: Any, policy: Any, seeds: Sequence[int], horizon: int, workers: int, *,
                      on_episode: Callable[[int, Episode], None] | None = None,
                      log: Callable[[str], None] | None = None) -> list[Episode] | None:
    """`rollout_episode` for every seed, in up to ``workers`` processes; the episodes in seed order, or None
    (after saying why through ``log``) when the policy cannot be sent to another process: the caller then
    records them itself. ``on_episode(i, episode)`` is called in order as they arrive (progress output)."""
    try:
        policy_bytes = pickle.dumps(policy)
    except Exception as exc:  # noqa: BLE001 - any pickling failure: the caller records in its own process
        if log is not None:
            log(f"[loco_il.datasets] recording the episodes in this process (the policy cannot be sent to worker "
                f"processes: {type(exc).__name__}: {exc})")
        return None
    n_procs = max(1, min(int(workers), len(seeds)))
    shape = (int(env.info.observation_space.shape[0]), int(env.model.nu))
    if log is not None:
        log(f"[loco_il.datasets] recording {len(seeds)} episodes in {n_procs} worker processes")
    jobs = [int(s) for s in seeds]
    with ProcessPoolExecutor(n_procs, mp_context=_context(), initializer=_start_worker,
                             initargs=(env.task_id, policy_bytes, int(horizon), shape)) as pool:
        out = []
        for i, episode in enumerate(pool.map(_record, jobs)):
            out.append(episode)
            if on_episode is not None:
                on_episode(i, episode)
    return out


def _context() -> multiprocessing.context.BaseContext:
    context = multiprocessing.get_context(START_METHOD)
    if START_METHOD == "forkserver":      # no effect once this process's fork server runs: it keeps its imports
        context.set_forkserver_preload(_PRELOAD)
    return context
