"""`perfect` and `preference` datasets: rollouts of a task's experts, cached on disk.

**perfect** -- deterministic rollouts of the task's expert (`ExpertPolicy.__call__`, the Gaussian's
mean) in a fresh env of the same body and task. The expert is an installed ``expert.pt``, else the
task's *built-in* expert (a model-based controller that needs no weights, e.g. the quadrupeds' trot
controller); `loco_il.experts.files` finds and loads it, and states the policy interface. Episode ``i``
starts from ``env.seed(episode_seeds(seed, n)[i]); env.reset()``: the seeds are derived from one base seed
(``numpy.random.SeedSequence(seed, spawn_key=(i,))``), so asking for more episodes only appends.
Episodes are run by the one episode loop, `loco_il.environments.episodes` (`rollout_episode`).
The recorded actions are exactly the ones passed to ``env.step`` (clipped to [-1, 1] *before*
recording, so a replay is exact), rewards are the task's default reward, ``absorbing`` marks a
termination (fall or divergence) and ``last`` also marks the time limit.

**preference** -- the same rollouts for several snapshots of increasing quality (at least 4),
one set per snapshot (installed ``snapshots/level_<k>.pt``, else the built-in expert's levels); sets are
ordered by their measured mean return, worst first, and labelled ``level`` 0 (worst) .. K-1 (best)
(`loco_il.datasets.providers.levels`).

**Observations.** A dataset is always recorded with FULL observations: it is generated in the
task's env without ``.pomdp`` (and without user ``hide=`` masks), and the cache file is shared by
the MDP and POMDP versions of a task. The mask is applied when the dataset is handed out:
``create_dataset(env)`` returns the observations ``env`` emits (``env.obs_mask``), unless
``full_obs=True`` is passed. Experts must be trained on full observations.

**Initial states.** The simulator state at the start of every episode is kept in
:class:`~loco_il.datasets.providers.init_states.InitStates`, next to the dataset. Every generated dataset
is checked: its first episode is replayed from its initial state with its recorded actions
(:func:`replay_episode`) and must reproduce the recorded observations, rewards and flags (else
:class:`DatasetError`).

**Cache.** Generated once, then loaded from the dataset cache (`loco_il.datasets.providers.cache`, which
describes the file names and keys).
"""
from __future__ import annotations

import collections
import hashlib
import os
import sys
import time
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from loco_il.datasets.providers.cache import (UNCACHED, cache_key, cache_unwritable, datasets_cache_dir,
                                              init_states_path, regenerate_hint, safe_name, save_to_cache,
                                              warn_uncached)
from loco_il.datasets.providers.init_states import InitStates
from loco_il.datasets.trajectory import Trajectories
from loco_il.environments.episodes import (Episode, Policy, episode_seeds, replay_episode, run_episode,
                                           run_episodes, start_episode)
from loco_il.environments.registry import make, task_key
from loco_il.experts.files import (MIN_PREFERENCE_LEVELS, NoExpertError, available_experts, available_snapshot_sets,
                                   find_snapshots, load_policy, policy_checksum)
from loco_il.experts.registry import builtin_expert
from loco_il.utils.errors import DatasetError

#: Bump when the rollout procedure changes in a way that changes the data (invalidates caches).
GENERATOR_VERSION = 1
#: Default number of episodes of a `perfect` dataset (as iMuJoCo) and per preference level.
DEFAULT_PERFECT_EPISODES = 100
DEFAULT_PREFERENCE_EPISODES = 25
SOURCE_PERFECT = "expert rollout"
SOURCE_PREFERENCE = "expert snapshot rollout"

#: Counters for tests and diagnostics: "generated" (datasets rolled out), "cache_hits".
STATS: collections.Counter = collections.Counter()


def _check_policy(policy: Any, key: str, obs_dim: int, act_dim: int, where: str) -> None:
    """Refuse an expert made for other observation or action sizes, or trained on another task."""
    meta = getattr(policy, "metadata", None) or {}
    p_obs, p_act = getattr(policy, "obs_dim", None), getattr(policy, "act_dim", None)
    if p_obs is not None and int(p_obs) != obs_dim:
        raise DatasetError(f"expert {where} expects observations of size {p_obs}, but {key} has {obs_dim} full "
                           f"observation entries (experts must be trained on full observations, without .pomdp)")
    if p_act is not None and int(p_act) != act_dim:
        raise DatasetError(f"expert {where} has {p_act} actions, but {key} has {act_dim}")
    tid = meta.get("task_id")
    if isinstance(tid, str) and tid:
        try:
            other = task_key(tid)
        except Exception:
            other = tid
        if other != key:
            raise DatasetError(f"expert {where} was trained on {tid!r}, not on {key}")


def _expert_meta(policy: Any) -> dict[str, Any]:
    """The expert's metadata worth recording in the dataset's ``info``."""
    meta = getattr(policy, "metadata", None) or {}
    keep = ("task_id", "training_steps", "eval_return", "eval_return_std", "commit", "algorithm", "created",
            "source", "controller_version", "action_noise")
    return {k: meta[k] for k in keep if k in meta}


# ----------------------------------------------------------------------------- rollouts


def _log_default(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


def rollout_episode(env: Any, policy: Policy, seed: int, horizon: int) -> Episode:
    """One deterministic episode of ``policy`` from ``env.seed(seed); env.reset()``, recorded as a dataset
    records it (`loco_il.environments.episodes.run_episode` with ``record=True, clip=True``): its initial
    simulator state, the transitions (obs, next_obs, actions, rewards), whether it ended in an absorbing state
    and the horizontal position of the task's velocity point at its start and end (``xy_start``, ``xy_end``).
    Depends on nothing but the seed, so episodes can be recorded in any env of the task, in any order."""
    return run_episode(env, policy, seed, horizon, record=True, clip=True)


def rollout(env: Any, policy: Policy, seeds: Sequence[int], *, info: Mapping[str, Any] | None = None,
            log: Callable[[str], None] | None = None, label: str = "",
            horizon: int | None = None, workers: int = 1) -> tuple[Trajectories, InitStates]:
    """Roll out ``policy`` deterministically, one episode per seed, and record everything.

    ``env`` should be a full-observation LocoEnv; episodes last at most ``horizon`` steps (default:
    the task's). The returned dataset's info is ``info`` plus ``episode_returns`` and
    ``expert_return_mean`` / ``expert_return_std``. ``workers`` > 1 records the episodes in that many
    processes, each with its own env of ``env.task_id`` (`rollout_workers.record_in_workers`); the data are
    the same as with one, since an episode depends only on its seed.
    """
    horizon = int(env.info.horizon if horizon is None else horizon)
    if horizon < 1:
        raise ValueError(f"horizon must be >= 1, got {horizon}")
    n = len(seeds)
    every = max(1, n // 10)
    t0 = time.perf_counter()
    returns: list[float] = []

    def progress(i: int, episode: Episode) -> None:
        returns.append(float(np.sum(episode.rewards)))
        if log is not None and ((i + 1) % every == 0 or i + 1 == n):
            log(f"[loco_il.datasets] {label}: episode {i + 1}/{n}, return {returns[-1]:.2f}, "
                f"length {episode.length}, mean return {np.mean(returns):.2f}, "
                f"{time.perf_counter() - t0:.1f}s")

    episodes = None
    if int(workers) > 1:
        from loco_il.datasets.providers.rollout_workers import record_in_workers
        episodes = record_in_workers(env, policy, seeds, horizon, int(workers), on_episode=progress, log=log)
    if episodes is None:     # one process, or a policy that cannot be sent to workers
        episodes = run_episodes(env, policy, seeds, horizon, record=True, clip=True, on_episode=progress)
    return assemble_episodes(episodes, seeds, info)


def assemble_episodes(episodes: Sequence[Episode], seeds: Sequence[int],
                      info: Mapping[str, Any] | None = None) -> tuple[Trajectories, InitStates]:
    """The dataset and initial states of recorded episodes (`rollout_episode`), in the order given."""
    lengths = [ep.length for ep in episodes]
    ends = np.cumsum(lengths) - 1
    last = np.zeros(sum(lengths), dtype=bool)
    last[ends] = True
    absorbing = np.zeros_like(last)
    absorbing[ends] = [ep.terminated for ep in episodes]    # only an episode's last step can be absorbing
    returns = [float(np.sum(ep.rewards)) for ep in episodes]
    info = dict(info or {})
    info.update(episode_returns=returns, expert_return_mean=float(np.mean(returns)),
                expert_return_std=float(np.std(returns)), n_episodes=len(episodes),
                mean_episode_length=float(np.mean(lengths)))
    columns = [np.concatenate([getattr(ep, k) for ep in episodes]) for k in ("obs", "next_obs", "actions", "rewards")]
    data = Trajectories(*columns, absorbing, last, info)
    init = InitStates(np.asarray([ep.qpos for ep in episodes]), np.asarray([ep.qvel for ep in episodes]),
                      np.asarray(seeds, dtype=np.int64))
    return data, init


# ----------------------------------------------------------------------------- generation and cache


def generation_env(env: Any, key: str) -> Any:
    """A fresh full-observation env of ``key`` (no .pomdp, no hide=, default reward) for rollouts."""
    return make(f"{key}.{env.dataset_type}")


def verify_replay(env: Any, data: Trajectories, init: InitStates, episode: int = 0, atol: float = 1e-9) -> None:
    """Replay one episode of a rollout dataset from its initial state with its actions
    (`replay_episode`, with its reset seed); :class:`DatasetError` if the observations, rewards or
    flags differ."""
    start, stop = data.episode_bounds()[episode]
    out = replay_episode(env, init.qpos[episode], init.qvel[episode], data.actions[start:stop],
                         seed=int(init.seeds[episode]))
    ok = (len(out["obs"]) == stop - start
          and np.allclose(out["obs"], data.obs[start:stop], rtol=0, atol=atol)
          and np.allclose(out["next_obs"], data.next_obs[start:stop], rtol=0, atol=atol)
          and np.allclose(out["rewards"], data.rewards[start:stop], rtol=0, atol=atol)
          and np.array_equal(out["absorbing"], data.absorbing[start:stop]))
    if not ok:
        raise DatasetError(
            f"{data.info.get('task_id', 'the dataset')}: replaying episode {episode} from its initial state with its "
            f"recorded actions does not reproduce its observations (the policy "
            f"{data.info.get('expert') or data.info.get('snapshot') or ''} may change the simulator state "
            f"or act on something the stored state does not hold)")


def cached_rollouts(gen_env: Any, policy: Any, *, key: str, dataset_type: str, name: str, n_episodes: int,
                    seed: int, info: Mapping[str, Any], regenerate: bool = False,
                    log: Callable[[str], None] | None = _log_default,
                    horizon: int | None = None, workers: int = 1) -> tuple[Trajectories, InitStates, Path]:
    """Load the rollouts of ``policy`` from the cache, or generate, verify (`verify_replay`) and save
    them (atomically). ``horizon``: episode length cap (default: the task's; part of the cache key).
    ``workers``: processes recording the episodes (the same data for any number; not part of the key)."""
    import mujoco
    checksum = policy_checksum(policy)
    fields = {"generator": GENERATOR_VERSION, "task": key, "dataset_type": dataset_type, "policy": checksum,
              "n_episodes": int(n_episodes), "seed": int(seed), "mujoco": mujoco.__version__}
    if horizon is not None:          # only when given: the default keeps the keys of existing caches
        fields["horizon"] = int(horizon)
    hkey = cache_key(fields)
    path = datasets_cache_dir() / safe_name(key) / f"{safe_name(name)}-n{int(n_episodes)}-seed{int(seed)}-{hkey}.npz"
    side = init_states_path(path)
    nq, nv = int(gen_env.model.nq), int(gen_env.model.nv)
    if not regenerate and path in UNCACHED:
        data, init = UNCACHED[path]
        return data, init, path
    if not regenerate and path.exists():
        hint = regenerate_hint(path)
        data = Trajectories.load(path, regenerate_hint=hint,
                                 expect={"cache_key": hkey, "policy_checksum": checksum,
                                         "obs_names": list(gen_env.full_obs_spec.names),
                                         "act_dim": int(gen_env.model.nu)})
        init = InitStates.load(side, regenerate_hint=hint, n_episodes=data.n_trajectories, nq=nq, nv=nv)
        STATS["cache_hits"] += 1
        return data, init, path
    unwritable = cache_unwritable(path.parent)
    if unwritable:
        warn_uncached(path.parent, unwritable)
    if log is not None:
        log(f"[loco_il.datasets] generating {name} dataset of {key}: {n_episodes} episodes, seed {seed} -> {path}")
    full_info = {
        "task_id": f"{key}.{dataset_type}", "dataset_type": dataset_type,
        "obs_names": list(gen_env.full_obs_spec.names),
        "simulator": f"mujoco {mujoco.__version__}", "seed": int(seed), "policy_checksum": checksum,
        "cache_key": hkey, "cache_fields": fields,
        "generator": f"loco_il.datasets.providers.expert v{GENERATOR_VERSION}",
        "reward": "task default", "action_space": "[-1, 1] (clipped before recording)",
    }
    full_info.update(info)
    data, init = rollout(gen_env, policy, episode_seeds(seed, n_episodes), info=full_info, log=log,
                         label=f"{key} {name}", horizon=horizon, workers=workers)
    verify_replay(gen_env, data, init)
    if unwritable:
        UNCACHED[path] = (data, init)
    else:
        save_to_cache(path, data, init)
    STATS["generated"] += 1
    return data, init, path


# ----------------------------------------------------------------------------- providers


def perfect_provider(env: Any, *, n_episodes: int | None = None, generation_seed: int = 0, expert: Any = None,
                     expert_path: str | os.PathLike | None = None, regenerate: bool = False,
                     verbose: bool = True, horizon: int | None = None, workers: int = 1,
                     **unused: Any) -> tuple[Trajectories, InitStates]:
    """The `perfect` dataset of ``env``'s task (full observations) and its initial states.
    ``horizon`` caps the episode length (default: the task's horizon); ``workers`` > 1 generates the
    episodes in that many processes (`rollout`)."""
    _reject_unused(unused, "perfect")
    key = _expert_key(env, expert, expert_path)
    gen_env = generation_env(env, key)
    try:
        policy, where = load_policy(expert, expert_path, key=key, env=gen_env)
        _check_policy(policy, key, gen_env.full_obs_spec.dim, int(gen_env.model.nu), where)
        n = DEFAULT_PERFECT_EPISODES if n_episodes is None else int(n_episodes)
        if n < 1:
            raise ValueError(f"n_episodes must be >= 1, got {n}")
        info = {"source": SOURCE_PERFECT, "expert": where, "expert_metadata": _expert_meta(policy)}
        data, init, _ = cached_rollouts(gen_env, policy, key=key, dataset_type="perfect", name="perfect",
                                        n_episodes=n, seed=generation_seed, info=info, regenerate=regenerate,
                                        log=_log_default if verbose else None, horizon=horizon, workers=workers)
    finally:
        gen_env.stop()
    return data, init


def _expert_key(env: Any, expert: Any, expert_path: Any) -> str:
    """The task key whose expert is used: the variant's own if installed, else the base body's."""
    key = task_key(env)
    if (getattr(env, "variant", None) and expert is None and expert_path is None
            and key not in available_experts() and builtin_expert(key) is None):
        return f"{env.body_name}.{env.task_name}"
    return key


def _reject_unused(unused: Mapping[str, Any], kind: str) -> None:
    if unused:
        raise TypeError(f"unexpected argument(s) for a {kind} dataset: {', '.join(sorted(unused))}")


def create_preference_sets(env: Any, *, n_episodes: int | None = None, generation_seed: int = 0,
                           snapshots: Sequence[Any] | None = None, regenerate: bool = False,
                           verbose: bool = True, min_levels: int = MIN_PREFERENCE_LEVELS,
                           return_init_states: bool = False, horizon: int | None = None, workers: int = 1
                           ) -> list[Trajectories] | tuple[list[Trajectories], list[InitStates]]:
    """One dataset per snapshot, ordered by mean return from worst to best (``info["level"]`` 0..K-1).

    ``snapshots``: expert files or expert objects (default: the task's installed
    ``snapshots/level_<k>.pt``, else its built-in expert's levels). Every set has ``n_episodes``
    episodes (default 25) from the same reset seeds, and its info holds ``level``, ``snapshot``,
    ``mean_return`` and the full ``levels`` table. ``horizon`` caps the episode length; ``workers`` > 1
    generates each set's episodes in that many processes (`rollout`).
    """
    if isinstance(env, str):
        env = make(env)
    key = task_key(env)
    if (snapshots is None and getattr(env, "variant", None) and key not in available_snapshot_sets()
            and (builtin_expert(key) is None or builtin_expert(key).levels is None)):
        key = f"{env.body_name}.{env.task_name}"
    n = DEFAULT_PREFERENCE_EPISODES if n_episodes is None else int(n_episodes)
    if n < 1:
        raise ValueError(f"n_episodes must be >= 1, got {n}")
    gen_env = generation_env(env, key)
    sets = []
    try:
        if snapshots is None:
            try:
                snapshots = find_snapshots(key)
            except NoExpertError:
                builtin = builtin_expert(key)
                if builtin is None or builtin.levels is None:
                    raise
                snapshots = builtin.levels(gen_env)
        snapshots = list(snapshots)
        if len(snapshots) < min_levels:
            raise DatasetError(f"a preference dataset needs at least {min_levels} snapshots of different quality; "
                               f"got {len(snapshots)} for {key}")
        for k, snap in enumerate(snapshots):
            if isinstance(snap, (str, os.PathLike)):
                policy, where = load_policy(expert_path=snap, key=key)
                name = f"preference-{Path(snap).stem}"
            else:
                policy, where = load_policy(expert=snap, key=key)
                name = f"preference-snapshot{k}"
            _check_policy(policy, key, gen_env.full_obs_spec.dim, int(gen_env.model.nu), where)
            info = {"source": SOURCE_PREFERENCE, "snapshot": where, "snapshot_index": k,
                    "expert_metadata": _expert_meta(policy)}
            data, init, _ = cached_rollouts(gen_env, policy, key=key, dataset_type="preference", name=name,
                                            n_episodes=n, seed=generation_seed, info=info, regenerate=regenerate,
                                            log=_log_default if verbose else None, horizon=horizon,
                                            workers=workers)
            sets.append((data, init, where))
    finally:
        gen_env.stop()
    sets.sort(key=lambda s: s[0].info["expert_return_mean"])   # stable: ties keep snapshot order
    levels = [{"level": lvl, "snapshot": where, "mean_return": d.info["expert_return_mean"],
               "std_return": d.info["expert_return_std"], "policy_checksum": d.info["policy_checksum"]}
              for lvl, (d, _, where) in enumerate(sets)]
    out, inits = [], []
    for lvl, (d, init, where) in enumerate(sets):
        info = dict(d.info)
        info.update(level=lvl, mean_return=d.info["expert_return_mean"], levels=levels,
                    episode_level=[lvl] * d.n_trajectories)
        out.append(d.replace(info=info))
        inits.append(init)
    return (out, inits) if return_init_states else out


def preference_provider(env: Any, *, n_episodes: int | None = None, generation_seed: int = 0,
                        snapshots: Sequence[Any] | None = None, regenerate: bool = False,
                        verbose: bool = True, expert: Any = None, expert_path: Any = None,
                        horizon: int | None = None, workers: int = 1,
                        **unused: Any) -> tuple[Trajectories, InitStates]:
    """All preference levels concatenated (worst first), with ``info["episode_level"]`` per episode."""
    _reject_unused(unused, "preference")
    if expert is not None or expert_path is not None:
        raise TypeError("a preference dataset is built from several snapshots: pass snapshots=[...] "
                        "(files or expert objects), not expert=/expert_path=")
    sets, inits = create_preference_sets(env, n_episodes=n_episodes, generation_seed=generation_seed,
                                         snapshots=snapshots, regenerate=regenerate, verbose=verbose,
                                         return_init_states=True, horizon=horizon, workers=workers)
    info = dict(sets[0].info)
    for k in ("level", "mean_return", "snapshot", "snapshot_index", "expert_metadata", "episode_returns",
              "expert_return_mean", "expert_return_std", "mean_episode_length", "cache_key", "cache_fields"):
        info.pop(k, None)
    info.update(
        task_id=sets[0].info["task_id"],
        dataset_type="preference", source=SOURCE_PREFERENCE,
        policy_checksum=hashlib.sha256("".join(s.info["policy_checksum"] for s in sets).encode()).hexdigest(),
        episode_level=[lvl for s in sets for lvl in s.info["episode_level"]],
        episode_returns=[r for s in sets for r in s.info["episode_returns"]],
        n_episodes=sum(s.n_trajectories for s in sets), n_levels=len(sets))
    return Trajectories.concatenate(sets, info=info), InitStates.concatenate(inits)


__all__ = [
    "GENERATOR_VERSION", "DEFAULT_PERFECT_EPISODES", "DEFAULT_PREFERENCE_EPISODES", "STATS", "start_episode",
    "verify_replay", "episode_seeds", "rollout", "rollout_episode", "assemble_episodes", "replay_episode",
    "generation_env", "cached_rollouts", "perfect_provider", "create_preference_sets", "preference_provider",
]
