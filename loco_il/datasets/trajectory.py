"""The dataset format of loco_il: :class:`Trajectories`.

A dataset is a flat sequence of ``N`` transitions from one or more episodes,
stored as parallel arrays:

======================  ====================  ==========================================
field                   shape                 meaning
======================  ====================  ==========================================
``obs``                 ``(N, obs_dim)``      observation before the step (float32/64)
``next_obs``            ``(N, obs_dim)``      observation after the step (same dtype)
``actions``             ``(N, act_dim)``      action taken, or ``None`` (``real``
                                              datasets hold states only)
``rewards``             ``(N,)``              reward of the step (float32/64)
``absorbing``           ``(N,)`` bool         the step *terminated* the episode
                                              (not set on time-limit truncation)
``last``                ``(N,)`` bool         the step is the last of its episode
                                              (terminated or truncated)
``info``                dict                  metadata, JSON-serializable
======================  ====================  ==========================================

Episodes are consecutive runs of transitions, each closed by ``last=True``;
the final transition always has ``last=True``. An absorbing transition is
always also a last one.

``info`` always holds the keys of :data:`REQUIRED_INFO_KEYS` (missing ones are
filled with ``None``): ``task_id``, ``dataset_type`` (``real`` | ``perfect`` |
``preference``), ``source``, ``obs_names`` (list of str, one per observation
entry), ``simulator`` (e.g. ``"mujoco 3.17.0"``), ``seed``, ``policy_checksum``;
any other JSON-serializable key may be added (preference level, mean return...).
``info`` is normalized to plain JSON types on construction (tuples become lists,
numpy scalars become Python numbers), so it compares equal after a save/load.

On disk a dataset is one uncompressed ``.npz`` file (see :meth:`Trajectories.save`):
no pickle, info as a JSON string, a ``format_version`` key. When every
non-final ``next_obs[t]`` equals ``obs[t + 1]`` (the usual case) only the
``next_obs`` rows that close an episode are stored, which halves the file.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import pathlib
import tempfile
from dataclasses import dataclass, field
from typing import Any, Dict, Iterable, Iterator, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np

from loco_il.datasets.npz import load_error, read_npz
from loco_il.datasets.splits import DEFAULT_PORTION, make_split
from loco_il.environments.registry import DATASET_TYPES
from loco_il.utils.errors import DatasetError

PathLike = Union[str, "os.PathLike[str]"]

#: Version of the on-disk layout written by :meth:`Trajectories.save`.
FORMAT_VERSION = 1
#: Keys always present in ``info`` (``None`` when unknown).
REQUIRED_INFO_KEYS = (
    "task_id",
    "dataset_type",
    "source",
    "obs_names",
    "simulator",
    "seed",
    "policy_checksum",
)

_FLOAT_DTYPES = (np.dtype(np.float32), np.dtype(np.float64))
_ARRAY_FIELDS = ("obs", "next_obs", "actions", "rewards", "absorbing", "last")


# ----------------------------------------------------------------------------- helpers


def _json_default(obj: Any) -> Any:
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, (set, frozenset)):
        return sorted(obj)
    if isinstance(obj, pathlib.PurePath):
        return str(obj)
    raise TypeError(f"object of type {type(obj).__name__} is not JSON serializable")


def _info_to_json(info: Mapping[str, Any], *, sort_keys: bool = False) -> str:
    return json.dumps(info, default=_json_default, sort_keys=sort_keys)


def _normalize_info(info: Optional[Mapping[str, Any]]) -> Dict[str, Any]:
    if info is None:
        info = {}
    if not isinstance(info, Mapping):
        raise DatasetError(f"info must be a dict, got {type(info).__name__}")
    bad_keys = [k for k in info if not isinstance(k, str)]
    if bad_keys:
        raise DatasetError(f"info keys must be strings, got {bad_keys!r}")
    try:
        normalized = json.loads(_info_to_json(info))
    except (TypeError, ValueError) as exc:
        raise DatasetError(f"info must be JSON-serializable: {exc}") from None
    for key in REQUIRED_INFO_KEYS:
        normalized.setdefault(key, None)
    return normalized


def _as_flag_array(name: str, value: Any) -> np.ndarray:
    arr = np.asarray(value)
    if arr.dtype != np.bool_:
        raise DatasetError(f"'{name}' must have dtype bool, got {arr.dtype}")
    return arr


def _episode_ends(last: np.ndarray) -> np.ndarray:
    """Exclusive stop index of every episode."""
    return np.flatnonzero(last) + 1


# ----------------------------------------------------------------------------- class


@dataclass(eq=False, repr=False)
class Trajectories:
    """Transitions of one or more episodes plus metadata; see the module docstring.

    Construction validates (see :meth:`validate`) and raises :class:`DatasetError`
    on any inconsistency. Arrays are kept as given (no copy) when already numpy
    arrays of the right dtype; lists are converted.
    """

    obs: np.ndarray
    next_obs: np.ndarray
    actions: Optional[np.ndarray]
    rewards: np.ndarray
    absorbing: np.ndarray
    last: np.ndarray
    info: Dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.obs = np.asarray(self.obs)
        self.next_obs = np.asarray(self.next_obs)
        self.actions = None if self.actions is None else np.asarray(self.actions)
        self.rewards = np.asarray(self.rewards)
        self.absorbing = np.asarray(self.absorbing)
        self.last = np.asarray(self.last)
        self.info = _normalize_info(self.info)
        self.validate()

    # ------------------------------------------------------------------ validation

    def validate(self) -> "Trajectories":
        """Check shapes, dtypes, finiteness, episode flags and info; return ``self``.

        Raises:
            DatasetError: naming the first problem found.
        """
        obs, next_obs, actions = self.obs, self.next_obs, self.actions
        if obs.ndim != 2:
            raise DatasetError(f"'obs' must be 2-D (N, obs_dim), got shape {obs.shape}")
        n, obs_dim = obs.shape
        if n == 0:
            raise DatasetError("a dataset needs at least one transition, got N=0")
        if obs.dtype not in _FLOAT_DTYPES:
            raise DatasetError(f"'obs' must be float32 or float64, got {obs.dtype}")
        if next_obs.shape != obs.shape:
            raise DatasetError(f"'next_obs' must have the shape of 'obs' {obs.shape}, got {next_obs.shape}")
        if next_obs.dtype != obs.dtype:
            raise DatasetError(f"'next_obs' must have the dtype of 'obs' ({obs.dtype}), got {next_obs.dtype}")
        if actions is not None:
            if actions.ndim != 2 or actions.shape[0] != n:
                raise DatasetError(f"'actions' must have shape ({n}, act_dim), got {actions.shape}")
            if actions.dtype not in _FLOAT_DTYPES:
                raise DatasetError(f"'actions' must be float32 or float64, got {actions.dtype}")
        if self.rewards.shape != (n,):
            raise DatasetError(f"'rewards' must have shape ({n},), got {self.rewards.shape}")
        if self.rewards.dtype not in _FLOAT_DTYPES:
            raise DatasetError(f"'rewards' must be float32 or float64, got {self.rewards.dtype}")
        for name in ("absorbing", "last"):
            arr = _as_flag_array(name, getattr(self, name))
            if arr.shape != (n,):
                raise DatasetError(f"'{name}' must have shape ({n},), got {arr.shape}")
        for name in ("obs", "next_obs", "actions", "rewards"):
            arr = getattr(self, name)
            if arr is not None and not np.isfinite(arr).all():
                bad = int(np.count_nonzero(~np.isfinite(arr)))
                raise DatasetError(f"'{name}' contains {bad} non-finite value(s) (NaN or inf)")
        if not self.last[-1]:
            raise DatasetError("the final transition must have last=True (every episode must be closed)")
        if np.any(self.absorbing & ~self.last):
            i = int(np.flatnonzero(self.absorbing & ~self.last)[0])
            raise DatasetError(f"transition {i} is absorbing but not last: a terminated episode must end there")

        info = self.info
        dtype = info.get("dataset_type")
        if dtype is not None and dtype not in DATASET_TYPES:
            raise DatasetError(f"info['dataset_type'] must be one of {DATASET_TYPES} or None, got {dtype!r}")
        if dtype in ("perfect", "preference") and actions is None:
            raise DatasetError(f"a '{dtype}' dataset needs actions, got actions=None")
        names = info.get("obs_names")
        if names is not None:
            if not isinstance(names, list) or not all(isinstance(s, str) for s in names):
                raise DatasetError("info['obs_names'] must be a list of str")
            if len(names) != obs_dim:
                raise DatasetError(f"info['obs_names'] has {len(names)} names but obs_dim is {obs_dim}")
        for key in ("task_id", "source", "simulator", "policy_checksum"):
            val = info.get(key)
            if val is not None and not isinstance(val, str):
                raise DatasetError(f"info[{key!r}] must be a str or None, got {type(val).__name__}")
        seed = info.get("seed")
        if seed is not None and (isinstance(seed, bool) or not isinstance(seed, int)):
            raise DatasetError(f"info['seed'] must be an int or None, got {seed!r}")
        return self

    # ------------------------------------------------------------------ sizes

    @property
    def n_transitions(self) -> int:
        """Number of transitions ``N``."""
        return int(self.obs.shape[0])

    def __len__(self) -> int:
        return self.n_transitions

    @property
    def n_trajectories(self) -> int:
        """Number of episodes (count of ``last=True``)."""
        return int(np.count_nonzero(self.last))

    n_episodes = n_trajectories

    @property
    def obs_dim(self) -> int:
        return int(self.obs.shape[1])

    @property
    def act_dim(self) -> Optional[int]:
        """Action dimension, or None for a states-only dataset."""
        return None if self.actions is None else int(self.actions.shape[1])

    @property
    def has_actions(self) -> bool:
        return self.actions is not None

    @property
    def dataset_type(self) -> Optional[str]:
        return self.info.get("dataset_type")

    @property
    def obs_names(self) -> Optional[List[str]]:
        return self.info.get("obs_names")

    def __repr__(self) -> str:
        return (
            f"Trajectories(task_id={self.info.get('task_id')!r}, dataset_type={self.dataset_type!r}, "
            f"n_transitions={self.n_transitions}, n_trajectories={self.n_trajectories}, "
            f"obs_dim={self.obs_dim}, act_dim={self.act_dim}, dtype={self.obs.dtype})"
        )

    # ------------------------------------------------------------------ episodes

    def episode_bounds(self) -> List[Tuple[int, int]]:
        """``[(start, stop), ...]`` of every episode, ``stop`` exclusive, in order."""
        stops = _episode_ends(self.last)
        starts = np.concatenate([[0], stops[:-1]])
        return [(int(a), int(b)) for a, b in zip(starts, stops)]

    def _starts_stops(self) -> Tuple[np.ndarray, np.ndarray]:
        stops = _episode_ends(self.last)
        starts = np.concatenate([np.zeros(1, dtype=stops.dtype), stops[:-1]])
        return starts, stops

    def episode_lengths(self) -> np.ndarray:
        """Number of transitions of every episode (int64 array)."""
        starts, stops = self._starts_stops()
        return (stops - starts).astype(np.int64)

    def episode_returns(self, gamma: float = 1.0) -> np.ndarray:
        """Return of every episode: ``sum_t gamma**t r_t`` (undiscounted by default), float64."""
        starts, stops = self._starts_stops()
        r = self.rewards.astype(np.float64)
        if gamma != 1.0:
            t = np.arange(len(r)) - np.repeat(starts, stops - starts)
            r = r * np.power(float(gamma), t)
        return np.add.reduceat(r, starts)

    def _take(self, index: Union[slice, np.ndarray], info: Optional[Mapping[str, Any]] = None) -> "Trajectories":
        return Trajectories(
            obs=self.obs[index],
            next_obs=self.next_obs[index],
            actions=None if self.actions is None else self.actions[index],
            rewards=self.rewards[index],
            absorbing=self.absorbing[index],
            last=self.last[index],
            info=dict(self.info if info is None else info),
        )

    def trajectory(self, i: int) -> "Trajectories":
        """Episode ``i`` (negative counts from the end) as its own dataset.

        The arrays are views into this dataset's arrays (no copy).
        """
        starts, stops = self._starts_stops()
        n = len(starts)
        if not -n <= i < n:
            raise IndexError(f"episode index {i} out of range for {n} episodes")
        return self._take(slice(int(starts[i]), int(stops[i])))

    def iter_trajectories(self) -> Iterator["Trajectories"]:
        """Yield every episode in order (views, see :meth:`trajectory`)."""
        starts, stops = self._starts_stops()
        for a, b in zip(starts, stops):
            yield self._take(slice(int(a), int(b)))

    def select_episodes(self, indices: Iterable[int], info: Optional[Mapping[str, Any]] = None) -> "Trajectories":
        """New dataset (copied arrays) of the episodes ``indices``, in the order given.

        Args:
            indices: episode indices (repeats allowed, negatives count from the end).
            info: info of the result; default a copy of this dataset's info.
        """
        idx = np.asarray(list(indices) if not isinstance(indices, np.ndarray) else indices, dtype=np.int64)
        if idx.ndim != 1 or idx.size == 0:
            raise DatasetError("select_episodes needs a non-empty 1-D list of episode indices")
        starts, stops = self._starts_stops()
        n = len(starts)
        if np.any(idx < -n) or np.any(idx >= n):
            raise IndexError(f"episode indices out of range for {n} episodes: {idx[(idx < -n) | (idx >= n)].tolist()}")
        idx = np.where(idx < 0, idx + n, idx)
        lengths = stops[idx] - starts[idx]
        offsets = np.repeat(starts[idx] - (np.cumsum(lengths) - lengths), lengths)
        rows = offsets + np.arange(int(lengths.sum()))
        return self._take(rows, info=info)

    @classmethod
    def concatenate(cls, parts: Sequence["Trajectories"], info: Optional[Mapping[str, Any]] = None) -> "Trajectories":
        """Join datasets one after the other (episodes are kept whole).

        All parts must have the same ``obs_dim``, the same ``obs_names`` (or None)
        and either all or none have actions. Arrays are promoted with numpy's rules.
        ``info`` defaults to a copy of the first part's info.
        """
        parts = list(parts)
        if not parts:
            raise DatasetError("concatenate needs at least one dataset")
        first = parts[0]
        for k, p in enumerate(parts[1:], start=1):
            if p.obs_dim != first.obs_dim:
                raise DatasetError(f"cannot concatenate: part {k} has obs_dim {p.obs_dim}, part 0 has {first.obs_dim}")
            if p.has_actions != first.has_actions:
                raise DatasetError(f"cannot concatenate: part {k} and part 0 differ in having actions")
            if p.has_actions and p.act_dim != first.act_dim:
                raise DatasetError(f"cannot concatenate: part {k} has act_dim {p.act_dim}, part 0 has {first.act_dim}")
            if p.obs_names is not None and first.obs_names is not None and p.obs_names != first.obs_names:
                raise DatasetError(f"cannot concatenate: part {k} has different obs_names than part 0")
        obs_dtype = np.result_type(*[p.obs.dtype for p in parts])
        return cls(
            obs=np.concatenate([p.obs for p in parts]).astype(obs_dtype, copy=False),
            next_obs=np.concatenate([p.next_obs for p in parts]).astype(obs_dtype, copy=False),
            actions=np.concatenate([p.actions for p in parts]) if first.has_actions else None,
            rewards=np.concatenate([p.rewards for p in parts]),
            absorbing=np.concatenate([p.absorbing for p in parts]),
            last=np.concatenate([p.last for p in parts]),
            info=dict(first.info if info is None else info),
        )

    # ------------------------------------------------------------------ splits

    def split_indices(
        self,
        n_trajectories: Optional[int] = None,
        split: str = "train",
        portion: Sequence[float] = DEFAULT_PORTION,
        seed: int = 0,
    ) -> np.ndarray:
        """Episode indices of a split; see :func:`loco_il.datasets.splits.make_split`."""
        try:
            return make_split(self.n_trajectories, n_trajectories, split, portion, seed)
        except ValueError as exc:
            raise DatasetError(str(exc)) from None

    def split(
        self,
        n_trajectories: Optional[int] = None,
        split: str = "train",
        portion: Sequence[float] = DEFAULT_PORTION,
        seed: int = 0,
    ) -> "Trajectories":
        """Reproducible episode-level train/test split.

        The episodes are shuffled with ``seed``, the first ``n_trajectories``
        (all when None) form the pool, and ``portion=(lo, hi)`` (fractions of
        the pool) is the train part; ``split="test"`` returns the rest of the
        pool. Train and test are disjoint, and the same arguments always give
        the same episodes. Default: 75 % train / 25 % test of all episodes.
        Selected episodes keep their dataset order. Full rules:
        :mod:`loco_il.datasets.splits`.

        The result's ``info["split"]`` records the arguments and the selected
        original episode indices.

        Raises:
            DatasetError: bad arguments, or the requested split is empty.
        """
        idx = self.split_indices(n_trajectories, split, portion, seed)
        if idx.size == 0:
            raise DatasetError(
                f"the {split!r} split is empty: {self.n_trajectories} episodes, "
                f"n_trajectories={n_trajectories}, portion={tuple(portion)}; use more episodes or another portion"
            )
        info = dict(self.info)
        info["split"] = {
            "split": split,
            "n_trajectories": n_trajectories,
            "portion": [float(p) for p in portion],
            "seed": int(seed),
            "episodes": idx.tolist(),
        }
        return self.select_episodes(idx, info=info)

    # ------------------------------------------------------------------ misc

    def to_dict(self) -> Dict[str, Any]:
        """The arrays and info as a plain dict (no copy)."""
        return {name: getattr(self, name) for name in _ARRAY_FIELDS} | {"info": self.info}

    def copy(self) -> "Trajectories":
        """Deep copy (arrays and info)."""
        return Trajectories(
            obs=self.obs.copy(),
            next_obs=self.next_obs.copy(),
            actions=None if self.actions is None else self.actions.copy(),
            rewards=self.rewards.copy(),
            absorbing=self.absorbing.copy(),
            last=self.last.copy(),
            info=json.loads(_info_to_json(self.info)),
        )

    def replace(self, **changes: Any) -> "Trajectories":
        """New dataset with some fields replaced (validated)."""
        return dataclasses.replace(self, **changes)

    def equals(self, other: "Trajectories", check_info: bool = True) -> bool:
        """Exact equality of arrays (values, shapes and dtypes) and, optionally, info."""
        if not isinstance(other, Trajectories):
            return False
        for name in _ARRAY_FIELDS:
            a, b = getattr(self, name), getattr(other, name)
            if a is None or b is None:
                if a is not b:
                    return False
                continue
            if a.dtype != b.dtype or a.shape != b.shape or not np.array_equal(a, b):
                return False
        return not check_info or self.info == other.info

    def sha256(self, include_info: bool = True) -> str:
        """Hex SHA-256 of the content: every array's name, dtype, shape and bytes,
        then (if ``include_info``) the info as canonical JSON (sorted keys).

        Independent of the file layout, so a dataset and its save/load round trip
        have the same checksum.
        """
        h = hashlib.sha256()
        for name in _ARRAY_FIELDS:
            arr = getattr(self, name)
            if arr is None:
                h.update(f"{name}:none;".encode())
                continue
            arr = np.ascontiguousarray(arr)
            h.update(f"{name}:{arr.dtype.str}:{arr.shape};".encode())
            h.update(memoryview(arr).cast("B"))
        if include_info:
            h.update(b"info:")
            h.update(_info_to_json(self.info, sort_keys=True).encode())
        return h.hexdigest()

    # ------------------------------------------------------------------ save / load

    def _to_npz_arrays(self) -> Dict[str, np.ndarray]:
        arrays: Dict[str, np.ndarray] = {
            "format_version": np.asarray(FORMAT_VERSION, dtype=np.int64),
            "info_json": np.asarray(_info_to_json(self.info)),
            "obs": self.obs,
            "rewards": self.rewards,
            "absorbing": self.absorbing,
            "last": self.last,
        }
        if self.actions is not None:
            arrays["actions"] = self.actions
        # Shifted layout: inside an episode next_obs[t] == obs[t+1]; keep only
        # the next_obs rows that close an episode.
        # Compared bitwise so that e.g. -0.0 vs 0.0 is not mistaken for equal.
        as_bits = np.dtype(f"u{self.obs.dtype.itemsize}")
        same = (self.next_obs[:-1].view(as_bits) == self.obs[1:].view(as_bits)).all(axis=1)
        shifted = bool(np.all(same | self.last[:-1]))
        if shifted:
            arrays["next_obs_last"] = self.next_obs[self.last]
        else:
            arrays["next_obs"] = self.next_obs
        return arrays

    def save(self, path: PathLike) -> pathlib.Path:
        """Write the dataset to ``path`` (an uncompressed ``.npz``), atomically.

        The file is written to a temporary file in the same directory, flushed
        and fsync'ed, then moved over ``path`` with :func:`os.replace`: readers
        see either the old file or the complete new one, and a failure while
        writing leaves the old file untouched and no temporary file behind.
        The parent directory is created if needed. ``path`` is used as given
        (no ``.npz`` suffix is appended).

        Returns:
            The path written.
        """
        self.validate()
        path = pathlib.Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        arrays = self._to_npz_arrays()
        fd, tmp_name = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
        try:
            with os.fdopen(fd, "wb") as fh:
                np.savez(fh, **arrays)
                fh.flush()
                os.fsync(fh.fileno())
            os.replace(tmp_name, path)
        except BaseException:
            try:
                os.unlink(tmp_name)
            except FileNotFoundError:
                pass
            raise
        _fsync_dir(path.parent)
        return path

    @classmethod
    def load(
        cls,
        path: PathLike,
        regenerate_hint: Optional[str] = None,
        expect: Optional[Mapping[str, Any]] = None,
    ) -> "Trajectories":
        """Read and validate a file written by :meth:`save`.

        Args:
            path: the ``.npz`` file.
            regenerate_hint: how the user can rebuild the file, put in error
                messages; default :data:`~loco_il.datasets.npz.DEFAULT_REGENERATE_HINT`.
            expect: optional values the file must match: any ``info`` key
                (e.g. ``{"task_id": ..., "obs_names": [...]}``) and/or the
                special keys ``obs_dim``, ``act_dim`` (None = no actions),
                ``n_transitions``.

        Raises:
            DatasetError: the file is missing, truncated or corrupt, misses a key,
                has another format version, fails validation or does not match
                ``expect``. The message names the file and says how to regenerate it.
        """
        path = pathlib.Path(path)
        fail = load_error(path, "dataset file", regenerate_hint)
        # a file named .npz that is no archive is a damaged dataset (rebuilt by the hint); any other file that is no
        # archive (a log.csv, an .npy) is not a dataset at all: nothing to rebuild or delete, the path is wrong
        kind = None if path.suffix == ".npz" or not path.is_file() else _not_an_archive(path)
        if kind:
            raise DatasetError(f"'{path}' is not a dataset file: it is {kind}, and a dataset is the .npz archive "
                               f"written by Trajectories.save; check the path")
        with read_npz(path, fail) as z:
            keys = set(z.files)
            required = {"format_version", "info_json", "obs", "rewards", "absorbing", "last"}
            missing = sorted(required - keys)
            if not ({"next_obs", "next_obs_last"} & keys):
                missing.append("next_obs")
            if missing:
                raise fail(f"missing key(s) {missing} (found {sorted(keys)})")
            version = z["format_version"]
            if version.shape != () or int(version) != FORMAT_VERSION:
                raise fail(
                    f"it has format version {version.tolist()}, this loco_il reads version {FORMAT_VERSION}"
                )
            info = json.loads(str(z["info_json"]))
            obs = z["obs"]
            last = z["last"]
            if "next_obs" in keys:
                next_obs = z["next_obs"]
            else:
                tail = z["next_obs_last"]
                if obs.ndim != 2 or last.shape != obs.shape[:1] or last.dtype != np.bool_ or not last[-1:].all():
                    raise fail("its obs/last arrays are inconsistent")
                if tail.shape != (int(np.count_nonzero(last)), obs.shape[1]):
                    raise fail(f"'next_obs_last' has shape {tail.shape}, inconsistent with 'obs' and 'last'")
                next_obs = np.empty_like(obs)
                next_obs[:-1] = obs[1:]
                next_obs[last] = tail
            actions = z["actions"] if "actions" in keys else None
            rewards = z["rewards"]
            absorbing = z["absorbing"]
        try:
            data = cls(obs, next_obs, actions, rewards, absorbing, last, info)
        except DatasetError as exc:
            raise fail(f"its content is invalid: {exc}") from None
        if expect:
            mismatches = data._mismatches(expect)
            if mismatches:
                raise fail("it does not match what was expected: " + "; ".join(mismatches))
        return data

    def _mismatches(self, expect: Mapping[str, Any]) -> List[str]:
        actual_special = {"obs_dim": self.obs_dim, "act_dim": self.act_dim, "n_transitions": self.n_transitions}
        out = []
        for key, want in expect.items():
            have = actual_special[key] if key in actual_special else self.info.get(key)
            want_n = json.loads(json.dumps(want, default=_json_default))
            if have != want_n:
                out.append(f"{key} is {have!r}, expected {want_n!r}")
        return out


def _not_an_archive(path: pathlib.Path) -> Optional[str]:
    """What `path` is when it is not a zip archive (an .npz is one, also when truncated: its first bytes stay)."""
    with open(path, "rb") as fh:
        head = fh.read(512)
    if head.startswith(b"PK\x03\x04"):
        return None
    if head.startswith(b"\x93NUMPY"):
        return "a single .npy array"
    if not head:
        return "an empty file"
    try:
        head.decode("utf-8")
        return "a text file"
    except UnicodeDecodeError:
        return "not an .npz archive"


def _fsync_dir(directory: pathlib.Path) -> None:
    """Best-effort fsync of a directory so a rename survives a crash (POSIX only)."""
    try:
        fd = os.open(directory, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


__all__ = [
    "Trajectories",
    "DatasetError",
    "FORMAT_VERSION",
    "REQUIRED_INFO_KEYS",
]
