"""`perfect` and `preference` datasets: rollouts of trained experts, cached on disk.

**perfect** -- deterministic rollouts of the task's expert (`ExpertPolicy.__call__`, the Gaussian's
mean) in a fresh env of the same body and task. The expert is an installed ``expert.pt`` (see
`find_expert`), else the task's *built-in* expert (`register_builtin_expert`: a model-based
controller that needs no weights, e.g. the quadrupeds' trot controller of
:mod:`loco_il.datasets.gait.expert`). Episode ``i`` starts from
``env.seed(episode_seeds(seed, n)[i]); env.reset()``: the seeds are derived from one base seed
(``numpy.random.SeedSequence(seed, spawn_key=(i,))``), so asking for more episodes only appends.
The recorded actions are exactly the ones passed to ``env.step`` (clipped to [-1, 1] *before*
recording, so a replay is exact), rewards are the task's default reward, ``absorbing`` marks a
termination (fall or divergence) and ``last`` also marks the time limit.

**preference** -- the same rollouts for several snapshots of increasing quality (at least 4),
one set per snapshot (installed ``snapshots/level_<k>.pt``, else the built-in expert's levels); sets are ordered by their measured mean return, worst first, and labelled
``level`` 0 (worst) .. K-1 (best).

**Observations.** A dataset is always recorded with FULL observations: it is generated in the
task's env without ``.pomdp`` (and without user ``hide=`` masks), and the cache file is shared by
the MDP and POMDP versions of a task. The mask is applied when the dataset is handed out:
``create_dataset(env)`` returns the observations ``env`` emits (``env.obs_mask``), unless
``full_obs=True`` is passed. Experts must be trained on full observations.

**Initial states.** ``Trajectories`` holds no per-episode arrays, so the simulator state at the
start of every episode (``qpos``, ``qvel``) and the episode's reset seed are kept in
:class:`InitStates`, saved next to the dataset as ``<name>.init_states.npz``. Replaying
episode ``i`` from ``(qpos[i], qvel[i])`` with its recorded actions reproduces its observations
exactly (:func:`replay_episode`; tasks with a sampled command also need the reset seed, which
replays the command). Every generated dataset is checked: its first episode is replayed this
way and must reproduce the recorded observations, rewards and flags (else :class:`DatasetError`).

**Policy interface.** ``policy(obs) -> action`` and ``policy.checksum() -> str``; optional
``obs_dim``, ``act_dim``, ``metadata``, ``description`` (a one-line name for logs and ``info``) and
``start_episode(env, seed)``: called right after ``env.seed(seed); env.reset()`` of every episode,
before the first call, with the env being rolled out. A policy that needs the simulator state (not
only the observation) reads ``env.model`` / ``env.data`` there and in its calls, but never writes to
them (so the recorded actions replay exactly); anything it draws at random comes from ``seed``.

**Cache.** ``$LOCO_IL_DATASETS`` or ``~/.cache/loco_il/datasets``::

    <Body>.<task>/perfect-n<N>-seed<S>-<key>.npz                 # the dataset (Trajectories.save)
    <Body>.<task>/perfect-n<N>-seed<S>-<key>.init_states.npz     # its InitStates
    <Body>.<task>/preference-<snapshot>-n<N>-seed<S>-<key>.npz   # one file per preference level

``<key>`` is the first 16 hex digits of the sha256 of the generation task, dataset type, policy
checksum, number of episodes, seed, MuJoCo version and the generator version: any change gives a
new file. Files are written atomically and validated on load; a corrupt file raises
:class:`~loco_il.datasets.DatasetError` naming it, and ``regenerate=True`` rebuilds it (`train.py ...
dataset.regenerate=true`). A cache folder that cannot be written is reported before the episodes are
generated; they are then used without being cached (kept in memory for the process, `UNCACHED`).
"""
from __future__ import annotations

import collections
import hashlib
import json
import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterable, Mapping, Sequence

import numpy as np

from loco_il.datasets.trajectory import DEFAULT_REGENERATE_HINT, DatasetError, Trajectories

#: Bump when the rollout procedure changes in a way that changes the data (invalidates caches).
GENERATOR_VERSION = 1
#: Where shipped experts live: ``<SHIPPED_DIR>/<Body>.<task>/expert.pt`` and ``snapshots/level_<k>.pt``.
SHIPPED_DIR = Path(__file__).resolve().parents[2] / "experts" / "shipped"
#: Default number of episodes of a `perfect` dataset (as iMuJoCo) and per preference level.
DEFAULT_PERFECT_EPISODES = 100
DEFAULT_PREFERENCE_EPISODES = 25
MIN_PREFERENCE_LEVELS = 4
SOURCE_PERFECT = "expert rollout"
SOURCE_PREFERENCE = "expert snapshot rollout"

#: Modules imported (once) before looking up a built-in expert; each registers its experts.
BUILTIN_EXPERT_MODULES = ("loco_il.datasets.gait.expert",)

#: Counters for tests and diagnostics: "generated" (datasets rolled out), "cache_hits".
STATS: collections.Counter = collections.Counter()

Policy = Callable[[np.ndarray], np.ndarray]


class NoExpertError(DatasetError):
    """No expert (or no preference snapshots) is available for a task."""


# ----------------------------------------------------------------------------- built-in experts


@dataclass(frozen=True)
class BuiltinExpert:
    """A task's expert that needs no weight file (a model-based controller).

    ``expert(env_or_task_id) -> policy`` builds the expert; ``levels(env_or_task_id) -> [policy, ...]``
    the preference levels (>= 4 degraded versions), or None. ``description`` says what it is (it is
    recorded in dataset ``info`` and baselines).
    """

    expert: Callable[[Any], Any]
    levels: Callable[[Any], list[Any]] | None
    description: str


_BUILTIN: dict[str, BuiltinExpert] = {}
_builtin_modules_loaded = False


def register_builtin_expert(key: str, expert: Callable[[Any], Any], levels: Callable[[Any], list[Any]] | None = None,
                            description: str = "", *, replace: bool = False) -> None:
    """Register the built-in expert of a task key ``<Body>.<task>`` (used when no ``expert.pt`` is installed)."""
    if key in _BUILTIN and not replace:
        raise ValueError(f"a built-in expert for {key} is already registered; pass replace=True to override it")
    _BUILTIN[key] = BuiltinExpert(expert, levels, description)


def builtin_expert(key: str) -> BuiltinExpert | None:
    """The built-in expert of a task key, or None."""
    global _builtin_modules_loaded
    if not _builtin_modules_loaded:
        import importlib
        _builtin_modules_loaded = True
        for name in BUILTIN_EXPERT_MODULES:
            importlib.import_module(name)
    return _BUILTIN.get(key)


def builtin_experts() -> list[str]:
    """Task keys that have a built-in expert."""
    builtin_expert("")
    return sorted(_BUILTIN)


# ----------------------------------------------------------------------------- paths


def datasets_cache_dir() -> Path:
    """``$LOCO_IL_DATASETS`` or ``~/.cache/loco_il/datasets``."""
    given = os.environ.get("LOCO_IL_DATASETS")
    return Path(given).expanduser() if given else Path.home() / ".cache" / "loco_il" / "datasets"


def expert_search_path() -> list[Path]:
    """Folders searched for ``<Body>.<task>/expert.pt``: ``$LOCO_IL_EXPERTS`` (os.pathsep-separated),
    then the shipped folder ``loco_il/experts/shipped``."""
    extra = [Path(p).expanduser() for p in os.environ.get("LOCO_IL_EXPERTS", "").split(os.pathsep) if p]
    return extra + [Path(SHIPPED_DIR)]


def task_key(env_or_id: Any) -> str:
    """``<Body>[-<variant>].<task>[.<mode>]`` of an env or a Task-ID (dataset type and ``.pomdp`` dropped)."""
    if isinstance(env_or_id, str):
        from loco_il.environments.registry import parse_task_id
        tid = parse_task_id(env_or_id)
        body, variant, task, mode = tid.body, tid.variant, tid.task, tid.mode
    else:
        body, variant, task = env_or_id.body_name, getattr(env_or_id, "variant", None), env_or_id.task_name
        mode = getattr(env_or_id, "mode", None)
    return f"{body}{'-' + variant if variant else ''}.{task}{'.' + mode if mode else ''}"


def available_experts() -> list[str]:
    """Task keys (``<Body>.<task>``) that have an ``expert.pt`` in the search path (built-in experts:
    `builtin_experts`)."""
    found = set()
    for root in expert_search_path():
        if root.is_dir():
            found.update(p.parent.name for p in root.glob("*/expert.pt"))
    return sorted(found)


def available_snapshot_sets() -> list[str]:
    """Task keys that have preference snapshots (``snapshots/level_<k>.pt``)."""
    found = set()
    for root in expert_search_path():
        if root.is_dir():
            found.update(p.parent.parent.name for p in root.glob("*/snapshots/level_*.pt"))
    return sorted(found)


def _train_hint(key: str) -> str:
    return (f"train one with `python -m loco_il.experts train task={key}` and copy its best.pt to "
            f"{Path(SHIPPED_DIR) / key / 'expert.pt'} (or put it under a folder listed in $LOCO_IL_EXPERTS), "
            f"or pass expert_path=<file.pt>")


def find_expert(key: str) -> Path:
    """The expert file of a task key; :class:`NoExpertError` naming the tasks that have one."""
    for root in expert_search_path():
        path = root / key / "expert.pt"
        if path.is_file():
            return path
    have = available_experts()
    raise NoExpertError(
        f"no expert for {key}: looked for {key}/expert.pt in {', '.join(str(r) for r in expert_search_path())}. "
        f"Tasks with an expert: {', '.join(have) if have else '(none installed)'}{_builtin_note()}. "
        f"To get one, {_train_hint(key)}.")


def find_snapshots(key: str) -> list[Path]:
    """``snapshots/level_<k>.pt`` of a task key, sorted by k (from the first folder that has any)."""
    for root in expert_search_path():
        folder = root / key / "snapshots"
        files = sorted(folder.glob("level_*.pt"), key=_level_number) if folder.is_dir() else []
        if files:
            return files
    have = available_snapshot_sets()
    raise NoExpertError(
        f"no preference snapshots for {key}: looked for {key}/snapshots/level_<k>.pt in "
        f"{', '.join(str(r) for r in expert_search_path())}. Tasks with snapshots: "
        f"{', '.join(have) if have else '(none installed)'}{_builtin_note()}. Train an expert with "
        f"`python -m loco_il.experts train task={key}` (it writes snapshots/step_*.pt), copy "
        f">= {MIN_PREFERENCE_LEVELS} snapshots of increasing quality to {Path(SHIPPED_DIR) / key / 'snapshots'}"
        f"/level_<k>.pt, or pass snapshots=[file.pt, ...]")


def _builtin_note() -> str:
    keys = builtin_experts()
    return f" (built-in model-based experts, no file needed: {', '.join(keys)})" if keys else ""


def _level_number(path: Path) -> tuple[int, str]:
    stem = path.stem.split("_", 1)[-1]
    return (int(stem), path.name) if stem.isdigit() else (sys.maxsize, path.name)


# ----------------------------------------------------------------------------- policies


def _policy_checksum(policy: Any) -> str:
    fn = getattr(policy, "checksum", None)
    if not callable(fn):
        raise TypeError(f"an expert must provide checksum() (used in the dataset cache key); "
                        f"{type(policy).__name__} does not")
    value = fn()
    if not isinstance(value, str) or not value:
        raise TypeError(f"{type(policy).__name__}.checksum() must return a non-empty str, got {value!r}")
    return value


def describe_policy(policy: Any) -> str:
    """A policy object's ``description`` attribute, else ``<ClassName object>``."""
    text = getattr(policy, "description", None)
    return text if isinstance(text, str) and text else f"<{type(policy).__name__} object>"


def load_policy(expert: Any = None, expert_path: str | os.PathLike | None = None, *, key: str,
                env: Any = None) -> tuple[Any, str]:
    """(policy, description): an expert object as given, a file loaded with `load_expert`, the
    task's installed expert, or else its built-in expert (built for ``env``, a full-observation env of
    the task; default: one made from ``key``)."""
    if expert is not None and expert_path is not None:
        raise ValueError("pass either expert= or expert_path=, not both")
    if expert is not None:
        _policy_checksum(expert)
        return expert, describe_policy(expert)
    if expert_path is None:
        try:
            path = find_expert(key)
        except NoExpertError:
            builtin = builtin_expert(key)
            if builtin is None:
                raise
            policy = builtin.expert(env if env is not None else key)
            _policy_checksum(policy)
            return policy, describe_policy(policy)
    else:
        path = Path(expert_path)
    if not path.is_file():
        raise NoExpertError(f"expert file {path} does not exist")
    from loco_il.experts.policy import load_expert
    try:
        policy = load_expert(path)
    except Exception as exc:  # torch/pickle/format errors: name the file
        raise NoExpertError(f"cannot load expert file {path}: {type(exc).__name__}: {exc}") from exc
    return policy, str(path)


def _check_policy(policy: Any, key: str, obs_dim: int, act_dim: int, where: str) -> None:
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
    meta = getattr(policy, "metadata", None) or {}
    keep = ("task_id", "training_steps", "eval_return", "eval_return_std", "commit", "algorithm", "created",
            "source", "controller_version", "action_noise")
    return {k: meta[k] for k in keep if k in meta}


# ----------------------------------------------------------------------------- init states


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
        from loco_il.utils.atomic import atomic_open
        with atomic_open(path) as fh:
            np.savez(fh, format_version=np.asarray(1), qpos=self.qpos, qvel=self.qvel, seeds=self.seeds)
        return Path(path)

    @classmethod
    def load(cls, path: str | os.PathLike, regenerate_hint: str | None = None,
             n_episodes: int | None = None, nq: int | None = None, nv: int | None = None) -> "InitStates":
        path = Path(path)
        hint = regenerate_hint or DEFAULT_REGENERATE_HINT

        def fail(reason: str) -> DatasetError:
            return DatasetError(f"cannot load initial-state file '{path}': {reason}. To fix this, {hint}.")

        if not path.is_file():
            raise fail("the file does not exist")
        try:
            with np.load(path, allow_pickle=False) as z:
                out = cls(z["qpos"], z["qvel"], z["seeds"])
        except DatasetError as exc:
            raise fail(str(exc)) from None
        except Exception as exc:
            raise fail(f"the file is truncated or corrupt ({type(exc).__name__}: {exc})") from exc
        if n_episodes is not None and len(out) != n_episodes:
            raise fail(f"it has {len(out)} episodes, the dataset has {n_episodes}")
        if (nq is not None and out.qpos.shape[1] != nq) or (nv is not None and out.qvel.shape[1] != nv):
            raise fail(f"its states have nq={out.qpos.shape[1]}, nv={out.qvel.shape[1]}; "
                       f"the model has nq={nq}, nv={nv}")
        if not (np.isfinite(out.qpos).all() and np.isfinite(out.qvel).all()):
            raise fail("it contains non-finite values")
        return out


def init_states_path(dataset_path: str | os.PathLike) -> Path:
    """The sidecar file of a dataset file: ``x.npz`` -> ``x.init_states.npz``."""
    p = Path(dataset_path)
    return p.with_name(p.name[:-4] + ".init_states.npz" if p.name.endswith(".npz") else p.name + ".init_states.npz")


# ----------------------------------------------------------------------------- rollouts


def episode_seeds(seed: int, n: int) -> np.ndarray:
    """Reset seed of episode i: ``SeedSequence(seed, spawn_key=(i,))`` -> uint32; prefix-stable in n."""
    return np.array([np.random.SeedSequence(int(seed), spawn_key=(i,)).generate_state(1, np.uint32)[0]
                     for i in range(int(n))], dtype=np.int64)


def _log_default(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


def start_episode(policy: Any, env: Any, seed: int) -> None:
    """Call the policy's optional ``start_episode(env, seed)`` hook (see the module docstring)."""
    hook = getattr(policy, "start_episode", None)
    if callable(hook):
        hook(env, int(seed))


def _step_episode(env: Any, obs: np.ndarray, act: Callable[[np.ndarray, int], np.ndarray],
                  n_steps: int) -> dict[str, np.ndarray]:
    """Step ``env`` from ``obs`` with ``act(obs, t)`` for at most ``n_steps`` steps, stopping after an absorbing
    one: the transitions (obs, actions, next_obs, rewards, absorbing per step). Shared by recording and replay."""
    out: dict[str, list] = {"obs": [], "actions": [], "next_obs": [], "rewards": [], "absorbing": []}
    for t in range(n_steps):
        a = act(obs, t)
        nobs, r, absorbing, _ = env.step(a)
        for key, value in zip(out, (obs, a, nobs, r, absorbing)):
            out[key].append(value)
        obs = nobs
        if absorbing:
            break
    return {k: np.asarray(v, dtype=bool if k == "absorbing" else np.float64) for k, v in out.items()}


def rollout_episode(env: Any, policy: Policy, seed: int, horizon: int, index: int = 0) -> dict[str, Any]:
    """One deterministic episode of ``policy`` from ``env.seed(seed); env.reset()``: its initial simulator
    state, the transitions (obs, next_obs, actions, rewards), whether it ended in an absorbing state and the
    horizontal position of the task's velocity point at its start and end (``xy_start``, ``xy_end``).
    Depends on nothing but the seed, so episodes can be recorded in any env of the task, in any order."""
    nu = int(env.model.nu)

    def act(obs: np.ndarray, t: int) -> np.ndarray:
        a = np.asarray(policy(obs), dtype=np.float64).reshape(-1)
        if a.shape != (nu,):
            raise ValueError(f"the expert returned an action of shape {a.shape}, the env needs ({nu},)")
        if not np.isfinite(a).all():
            raise ValueError(f"the expert returned a non-finite action at step {t} of episode {index}: {a}")
        return np.clip(a, -1.0, 1.0)   # what env.step applies anyway: record exactly what was executed

    env.seed(int(seed))
    obs = env.reset()
    qpos, qvel = env.get_sim_state()
    xy_start = env.horizontal_position()
    start_episode(policy, env, int(seed))
    steps = _step_episode(env, obs, act, horizon)
    return {"qpos": np.asarray(qpos), "qvel": np.asarray(qvel), **steps, "absorbing": bool(steps["absorbing"][-1]),
            "xy_start": xy_start, "xy_end": env.horizontal_position()}


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

    def progress(i: int, episode: Mapping[str, Any]) -> None:
        returns.append(float(np.sum(episode["rewards"])))
        if log is not None and ((i + 1) % every == 0 or i + 1 == n):
            log(f"[loco_il.datasets] {label}: episode {i + 1}/{n}, return {returns[-1]:.2f}, "
                f"length {len(episode['rewards'])}, mean return {np.mean(returns):.2f}, "
                f"{time.perf_counter() - t0:.1f}s")

    episodes = None
    if int(workers) > 1:
        from loco_il.datasets.providers.rollout_workers import record_in_workers
        episodes = record_in_workers(env, policy, seeds, horizon, int(workers), on_episode=progress, log=log)
    if episodes is None:     # one process, or a policy that cannot be sent to workers
        episodes = []
        for i, s in enumerate(seeds):
            episodes.append(rollout_episode(env, policy, int(s), horizon, i))
            progress(i, episodes[-1])
    return assemble_episodes(episodes, seeds, info)


def assemble_episodes(episodes: Sequence[Mapping[str, Any]], seeds: Sequence[int],
                      info: Mapping[str, Any] | None = None) -> tuple[Trajectories, InitStates]:
    """The dataset and initial states of recorded episodes (`rollout_episode`), in the order given."""
    lengths = [len(ep["rewards"]) for ep in episodes]
    ends = np.cumsum(lengths) - 1
    last = np.zeros(sum(lengths), dtype=bool)
    last[ends] = True
    absorbing = np.zeros_like(last)
    absorbing[ends] = [ep["absorbing"] for ep in episodes]    # only an episode's last step can be absorbing
    returns = [float(np.sum(ep["rewards"])) for ep in episodes]
    info = dict(info or {})
    info.update(episode_returns=returns, expert_return_mean=float(np.mean(returns)),
                expert_return_std=float(np.std(returns)), n_episodes=len(episodes),
                mean_episode_length=float(np.mean(lengths)))
    columns = [np.concatenate([ep[k] for ep in episodes]) for k in ("obs", "next_obs", "actions", "rewards")]
    data = Trajectories(*columns, absorbing, last, info)
    init = InitStates(np.asarray([ep["qpos"] for ep in episodes]), np.asarray([ep["qvel"] for ep in episodes]),
                      np.asarray(seeds, dtype=np.int64))
    return data, init


def replay_episode(env: Any, qpos: np.ndarray, qvel: np.ndarray, actions: np.ndarray,
                   seed: int | None = None) -> dict[str, np.ndarray]:
    """Replay recorded actions from a stored initial state; returns obs, next_obs, rewards, absorbing.

    With ``seed`` the env is first reset with that seed (reproducing a sampled task command and the
    env's random stream); the simulator is then put in ``(qpos, qvel)``. ``env`` must emit the same
    observations as the generation env (no ``.pomdp``).
    """
    if seed is not None and int(seed) >= 0:
        env.seed(int(seed))
    env.reset()
    obs = env.set_sim_state(np.asarray(qpos, dtype=np.float64), np.asarray(qvel, dtype=np.float64))
    actions = np.asarray(actions)
    steps = _step_episode(env, obs, lambda _, t: actions[t], len(actions))
    return {k: steps[k] for k in ("obs", "next_obs", "rewards", "absorbing")}


# ----------------------------------------------------------------------------- cache


def generation_env(env: Any, key: str) -> Any:
    """A fresh full-observation env of ``key`` (no .pomdp, no hide=, default reward) for rollouts."""
    from loco_il.environments.registry import make
    return make(f"{key}.{env.dataset_type}")


def cache_key(fields: Mapping[str, Any]) -> str:
    return hashlib.sha256(json.dumps(dict(fields), sort_keys=True).encode()).hexdigest()[:16]


def _safe(name: str) -> str:
    return "".join(c if c.isalnum() or c in "-_." else "_" for c in name)


def cache_unwritable(folder: Path) -> str | None:
    """None when `folder` can hold cache files (made if missing); else why not. Checked by writing a file, which
    also catches read-only filesystems, before minutes of rollouts are spent on data that could not be kept."""
    import tempfile
    try:
        folder.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=folder):
            pass
    except OSError as exc:
        return exc.strerror or type(exc).__name__
    return None


#: generated datasets whose cache file could not be written, by that path: later calls of this process (the test
#: split, the start-state sampler) use them instead of generating them again
UNCACHED: dict[Path, tuple[Trajectories, "InitStates"]] = {}


def warn_uncached(folder: Path, reason: str) -> None:
    print(f"[loco_il.datasets] warning: cannot write the dataset cache {folder} ({reason}); the dataset is generated "
          f"for this process only and again next time. Set LOCO_IL_DATASETS=<a writable folder> to cache it.",
          file=sys.stderr, flush=True)


def save_to_cache(path: Path, data: Trajectories, init: InitStates) -> bool:
    """Write a generated dataset and its initial states (sidecar first: a dataset file on disk always has its
    sidecar). A failed write only warns: the generated episodes are still returned to the caller."""
    try:
        init_path = init_states_path(path)
        init.save(init_path)
        data.save(path)
        return True
    except OSError as exc:
        warn_uncached(path.parent, exc.strerror or str(exc))
        UNCACHED[path] = (data, init)
        return False


def _regen_hint(path: Path) -> str:
    return (f"rebuild it with `python train.py ... dataset.regenerate=true` or create_dataset(env, regenerate=True) "
            f"(or delete {path} and its .init_states.npz)")


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
    checksum = _policy_checksum(policy)
    fields = {"generator": GENERATOR_VERSION, "task": key, "dataset_type": dataset_type, "policy": checksum,
              "n_episodes": int(n_episodes), "seed": int(seed), "mujoco": mujoco.__version__}
    if horizon is not None:          # only when given: the default keeps the keys of existing caches
        fields["horizon"] = int(horizon)
    hkey = cache_key(fields)
    path = datasets_cache_dir() / _safe(key) / f"{_safe(name)}-n{int(n_episodes)}-seed{int(seed)}-{hkey}.npz"
    side = init_states_path(path)
    nq, nv = int(gen_env.model.nq), int(gen_env.model.nv)
    if not regenerate and path in UNCACHED:
        data, init = UNCACHED[path]
        return data, init, path
    if not regenerate and path.exists():
        hint = _regen_hint(path)
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
        from loco_il.environments.registry import make
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


# ----------------------------------------------------------------------------- labels and init states


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


__all__ = [
    "GENERATOR_VERSION", "SHIPPED_DIR", "DEFAULT_PERFECT_EPISODES", "DEFAULT_PREFERENCE_EPISODES",
    "MIN_PREFERENCE_LEVELS", "STATS", "NoExpertError", "BUILTIN_EXPERT_MODULES", "BuiltinExpert",
    "register_builtin_expert", "builtin_expert", "builtin_experts", "describe_policy", "start_episode",
    "verify_replay", "InitStates", "datasets_cache_dir", "expert_search_path",
    "task_key", "available_experts", "available_snapshot_sets", "find_expert", "find_snapshots", "load_policy",
    "episode_seeds", "rollout", "rollout_episode", "assemble_episodes", "replay_episode", "generation_env",
    "cached_rollouts", "init_states_path",
    "perfect_provider", "create_preference_sets", "preference_provider", "episode_levels", "transition_levels",
    "dataset_init_state_sampler",
]
