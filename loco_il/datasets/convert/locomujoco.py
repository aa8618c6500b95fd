"""Load LocoMuJoCo 0.4.x dataset ``.npz`` files as :class:`Trajectories`.

Only for users who already have such files; nothing is downloaded. Two
layouts are recognised (automatically, from the keys in the file):

**Per-joint layout** (LocoMuJoCo *real* / motion-capture datasets)
    One 1-D array per joint, all of the same length, sampled at
    ``source_freq`` (500 Hz in LocoMuJoCo):

    * ``q_<joint>``  - position of joint ``<joint>``
    * ``dq_<joint>`` - velocity of joint ``<joint>``
    * ``split_points`` (optional) - episode boundaries as sample indices: the
      start of every episode plus, last, the total length, e.g. ``[0, 812, 1730]``
      (missing leading 0 / trailing length are added). Without it the file is
      one episode.

    Other keys (``goal_*`` ...) are ignored. The observation of one sample is
    the concatenation, in order, of the arrays named by ``obs_names``. Key
    mapping:

    * ``obs_names`` given: exactly those keys, in that order (pass the env's
      observation names, e.g. ``env.obs_spec.names`` when they are spelled
      ``q_<joint>`` / ``dq_<joint>``).
    * ``joint_order`` given: ``q_<j>`` for every joint ``j`` (minus the keys in
      ``exclude``), then ``dq_<j>`` for every joint.
    * neither: every ``q_*`` key in file order (minus ``exclude``), then every
      ``dq_*`` key in file order. File order is only a guess of the env's
      order; prefer one of the two arguments.

    ``exclude`` defaults to ``("q_pelvis_tx", "q_pelvis_tz")``: LocoMuJoCo's
    humanoids have a root of three slide joints ``pelvis_tx``, ``pelvis_tz``
    (horizontal) and ``pelvis_ty`` (vertical), and their observation leaves
    out the two horizontal positions. Velocities are all kept. Pass another
    ``exclude`` for robots whose horizontal root coordinates are named
    differently. Keys named in ``obs_names`` are taken even if in ``exclude``.

    Every episode is resampled from ``source_freq`` to ``target_freq``
    (default 100 Hz, the env's control frequency) on the grid
    ``0, 1/target_freq, ...`` up to the episode's last sample time, with a
    cubic spline (``scipy.interpolate.CubicSpline``, each key on its own)
    or, when ``interpolation="linear"`` or scipy is missing, with
    ``numpy.interp``. Angles are interpolated as plain numbers (no
    wrapping). Episodes shorter than two resampled samples are dropped with
    a warning. The result has ``obs[t] = x[t]``, ``next_obs[t] = x[t + 1]``,
    no actions, zero rewards (``info["rewards_available"] = False``), no
    absorbing transitions; ``dataset_type`` defaults to ``"real"``.

**States layout** (LocoMuJoCo *perfect* datasets)
    ``states`` (N, obs_dim) - already observations - and ``actions``
    (N, act_dim) at the control frequency, plus ``last`` (episode ends;
    ``episode_starts`` is accepted instead) and optionally ``absorbing``,
    ``next_states`` and ``rewards``. No resampling is done
    (``source_freq`` / ``target_freq`` are ignored). Flags may be stored as
    numbers; non-zero means True. The final transition is always marked
    last, and an absorbing transition ends its episode. Without
    ``next_states``, ``next_obs[t] = states[t + 1]`` inside an episode and
    the final transition of every episode (which has no successor) is
    dropped. Without ``rewards``, rewards are zero
    (``info["rewards_available"] = False``). ``dataset_type`` defaults to
    ``"perfect"``.

Missing keys raise :class:`DatasetError` naming them and listing the keys the
file has.
"""

from __future__ import annotations

import math
import pathlib
import warnings
from typing import Any, Dict, List, Mapping, Optional, Sequence, Union

import numpy as np

from loco_il.datasets.trajectory import DatasetError, Trajectories

#: Position keys left out by default (horizontal root coordinates).
DEFAULT_EXCLUDE = ("q_pelvis_tx", "q_pelvis_tz")


def _have_scipy() -> bool:
    try:
        import scipy.interpolate  # noqa: F401
    except ImportError:
        return False
    return True


def _resample(x: np.ndarray, source_freq: float, target_freq: float, method: str) -> np.ndarray:
    """Resample the rows of ``x`` (L, D) sampled at ``source_freq`` onto a ``target_freq`` grid."""
    n_src = x.shape[0]
    duration = (n_src - 1) / source_freq
    n_new = int(math.floor(duration * target_freq + 1e-9)) + 1
    t_src = np.arange(n_src) / source_freq
    t_new = np.arange(n_new) / target_freq
    if n_src < 2:
        return x[:n_new].copy()
    if method == "cubic":
        from scipy.interpolate import CubicSpline

        return CubicSpline(t_src, x, axis=0)(t_new)
    out = np.empty((n_new, x.shape[1]), dtype=np.float64)
    for j in range(x.shape[1]):
        out[:, j] = np.interp(t_new, t_src, x[:, j])
    return out


def _missing_error(path: pathlib.Path, missing: Sequence[str], available: Sequence[str]) -> DatasetError:
    return DatasetError(
        f"LocoMuJoCo dataset file '{path}' misses key(s) {list(missing)}; it has {sorted(available)}"
    )


def _resolve_names(
    files: Sequence[str],
    obs_names: Optional[Sequence[str]],
    joint_order: Optional[Sequence[str]],
    exclude: Sequence[str],
) -> List[str]:
    if obs_names is not None and joint_order is not None:
        raise DatasetError("pass either obs_names or joint_order, not both")
    if obs_names is not None:
        return list(obs_names)
    if joint_order is not None:
        q = [f"q_{j}" for j in joint_order if f"q_{j}" not in exclude]
        return q + [f"dq_{j}" for j in joint_order]
    q = [k for k in files if k.startswith("q_") and k not in exclude]
    return q + [k for k in files if k.startswith("dq_")]


def _load_per_joint(
    path: pathlib.Path,
    z: Mapping[str, np.ndarray],
    files: Sequence[str],
    names: List[str],
    source_freq: float,
    target_freq: float,
    method: str,
    dtype: np.dtype,
) -> Dict[str, Any]:
    if not names:
        raise DatasetError(f"LocoMuJoCo dataset file '{path}' has no q_*/dq_* keys; it has {sorted(files)}")
    missing = [k for k in names if k not in files]
    if missing:
        raise _missing_error(path, missing, files)
    columns = []
    for k in names:
        col = np.asarray(z[k])
        if col.ndim == 2 and col.shape[1] == 1:
            col = col[:, 0]
        if col.ndim != 1:
            raise DatasetError(f"key '{k}' of '{path}' must be a 1-D array, got shape {col.shape}")
        columns.append(col)
    lengths = {len(c) for c in columns}
    if len(lengths) != 1:
        raise DatasetError(f"the joint arrays of '{path}' have different lengths {sorted(lengths)}")
    total = lengths.pop()
    data = np.stack(columns, axis=1).astype(np.float64)

    if "split_points" in files:
        sp = np.asarray(z["split_points"]).astype(np.int64).ravel()
        if sp.size and (np.any(np.diff(sp) <= 0) or sp[0] < 0 or sp[-1] > total):
            raise DatasetError(
                f"'split_points' of '{path}' must be strictly increasing indices in [0, {total}], got {sp.tolist()}"
            )
        bounds = sorted(set(sp.tolist()) | {0, total})
    else:
        bounds = [0, total]

    obs, next_obs, last = [], [], []
    dropped = 0
    for a, b in zip(bounds[:-1], bounds[1:]):
        seg = data[a:b]
        if source_freq != target_freq:
            seg = _resample(seg, source_freq, target_freq, method)
        if len(seg) < 2:
            dropped += 1
            continue
        obs.append(seg[:-1])
        next_obs.append(seg[1:])
        flag = np.zeros(len(seg) - 1, dtype=bool)
        flag[-1] = True
        last.append(flag)
    if dropped:
        warnings.warn(f"{dropped} episode(s) of '{path}' were too short to form a transition and were dropped")
    if not obs:
        raise DatasetError(f"no episode of '{path}' is long enough to form a transition")
    obs_a = np.concatenate(obs).astype(dtype)
    n = len(obs_a)
    return dict(
        obs=obs_a,
        next_obs=np.concatenate(next_obs).astype(dtype),
        actions=None,
        rewards=np.zeros(n, dtype=np.float64),
        absorbing=np.zeros(n, dtype=bool),
        last=np.concatenate(last),
        info_extra={
            "locomujoco_layout": "per_joint",
            "source_freq": float(source_freq),
            "target_freq": float(target_freq),
            "interpolation": method if source_freq != target_freq else None,
            "rewards_available": False,
        },
        obs_names=names,
    )


def _flag(z: Mapping[str, np.ndarray], key: str, n: int) -> np.ndarray:
    arr = np.asarray(z[key]).ravel()
    if arr.shape != (n,):
        raise DatasetError(f"'{key}' must have {n} entries, got shape {np.asarray(z[key]).shape}")
    return arr != 0


def _load_states(path: pathlib.Path, z: Mapping[str, np.ndarray], files: Sequence[str], dtype: np.dtype) -> Dict[str, Any]:
    missing = [k for k in ("states", "actions") if k not in files]
    if "last" not in files and "episode_starts" not in files:
        missing.append("last")
    if missing:
        raise _missing_error(path, missing, files)
    states = np.asarray(z["states"], dtype=np.float64)
    actions = np.asarray(z["actions"], dtype=np.float64)
    if states.ndim != 2:
        raise DatasetError(f"'states' of '{path}' must be 2-D (N, obs_dim), got shape {states.shape}")
    n = states.shape[0]
    if n == 0:
        raise DatasetError(f"'{path}' holds no states")
    if actions.ndim == 1:
        actions = actions[:, None]
    if actions.ndim != 2 or actions.shape[0] != n:
        raise DatasetError(f"'actions' of '{path}' must have shape ({n}, act_dim), got {actions.shape}")
    if "last" in files:
        last = _flag(z, "last", n)
    else:
        starts = _flag(z, "episode_starts", n)
        last = np.zeros(n, dtype=bool)
        last[:-1] = starts[1:]
    last[-1] = True
    absorbing = _flag(z, "absorbing", n) if "absorbing" in files else np.zeros(n, dtype=bool)
    last |= absorbing
    rewards_available = "rewards" in files
    rewards = np.asarray(z["rewards"], dtype=np.float64).ravel() if rewards_available else np.zeros(n)
    if rewards.shape != (n,):
        raise DatasetError(f"'rewards' of '{path}' must have {n} entries, got {rewards.shape}")
    extra: Dict[str, Any] = {"locomujoco_layout": "states", "rewards_available": rewards_available}

    if "next_states" in files:
        next_states = np.asarray(z["next_states"], dtype=np.float64)
        if next_states.shape != states.shape:
            raise DatasetError(f"'next_states' of '{path}' must have shape {states.shape}, got {next_states.shape}")
        obs, next_obs = states, next_states
    else:
        rows = np.flatnonzero(~last)
        if rows.size == 0:
            raise DatasetError(
                f"'{path}' has no 'next_states' and every episode is one state long: no transition can be formed"
            )
        obs, next_obs = states[rows], states[rows + 1]
        actions, rewards, absorbing = actions[rows], rewards[rows], absorbing[rows]
        last = last[rows + 1]
        extra["next_obs_from"] = "states[t + 1]; the final state of every episode was dropped"
    return dict(
        obs=obs.astype(dtype),
        next_obs=next_obs.astype(dtype),
        actions=actions.astype(dtype),
        rewards=rewards,
        absorbing=absorbing,
        last=last,
        info_extra=extra,
        obs_names=None,
    )


def load_locomujoco_npz(
    path: Union[str, pathlib.Path],
    obs_names: Optional[Sequence[str]] = None,
    joint_order: Optional[Sequence[str]] = None,
    source_freq: float = 500.0,
    target_freq: float = 100.0,
    dataset_type: Optional[str] = None,
    *,
    exclude: Sequence[str] = DEFAULT_EXCLUDE,
    interpolation: str = "cubic",
    dtype: Any = np.float64,
    info: Optional[Mapping[str, Any]] = None,
) -> Trajectories:
    """Read a LocoMuJoCo 0.4.x ``.npz`` dataset (layouts: see the module docstring).

    Args:
        path: the ``.npz`` file.
        obs_names: per-joint layout: the ``q_<joint>`` / ``dq_<joint>`` keys
            to take, in the env's observation order. States layout: names of
            the ``states`` columns, stored in ``info["obs_names"]``.
        joint_order: per-joint layout only: joint names in the env's order
            (alternative to ``obs_names``).
        source_freq: sampling frequency of the per-joint arrays (Hz).
        target_freq: control frequency to resample to (Hz).
        dataset_type: ``info["dataset_type"]``; default ``"real"`` for the
            per-joint layout and ``"perfect"`` for the states layout.
        exclude: per-joint layout: position keys left out when ``obs_names``
            is not given.
        interpolation: ``"cubic"`` (scipy) or ``"linear"`` (numpy).
        dtype: float dtype of the observations and actions.
        info: extra/overriding ``info`` entries (e.g. ``task_id``).

    Raises:
        DatasetError: unreadable file, missing keys, inconsistent shapes.
    """
    path = pathlib.Path(path)
    if interpolation not in ("cubic", "linear"):
        raise ValueError(f"interpolation must be 'cubic' or 'linear', got {interpolation!r}")
    if source_freq <= 0 or target_freq <= 0:
        raise ValueError("source_freq and target_freq must be positive")
    method = interpolation
    if method == "cubic" and not _have_scipy():
        warnings.warn("scipy is not installed: resampling LocoMuJoCo data with linear interpolation")
        method = "linear"
    dtype = np.dtype(dtype)
    if dtype not in (np.dtype(np.float32), np.dtype(np.float64)):
        raise ValueError(f"dtype must be float32 or float64, got {dtype}")
    if not path.is_file():
        raise DatasetError(f"LocoMuJoCo dataset file '{path}' does not exist")
    try:
        with np.load(path, allow_pickle=False) as npz:
            files = list(npz.files)
            z = {k: npz[k] for k in files}
    except Exception as exc:  # zipfile, pickle refusal, OS errors ...
        raise DatasetError(f"cannot read LocoMuJoCo dataset file '{path}': {type(exc).__name__}: {exc}") from exc

    if "states" in files:
        if joint_order is not None:
            raise DatasetError(f"'{path}' has the states layout: joint_order does not apply, use obs_names")
        parts = _load_states(path, z, files, dtype)
        names = list(obs_names) if obs_names is not None else None
        default_type = "perfect"
    else:
        names = _resolve_names(files, obs_names, joint_order, exclude)
        parts = _load_per_joint(path, z, files, names, float(source_freq), float(target_freq), method, dtype)
        default_type = "real"

    full_info: Dict[str, Any] = {
        "task_id": None,
        "dataset_type": dataset_type or default_type,
        "source": f"locomujoco:{path.name}",
        "obs_names": names,
        "simulator": None,
        "seed": None,
        "policy_checksum": None,
    }
    full_info.update(parts.pop("info_extra"))
    parts.pop("obs_names")
    if info:
        full_info.update(info)
    return Trajectories(info=full_info, **parts)


__all__ = ["load_locomujoco_npz", "DEFAULT_EXCLUDE"]
