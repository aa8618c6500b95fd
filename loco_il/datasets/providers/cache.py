"""The dataset cache: where generated datasets are kept, their keys, and writing them.

``$LOCO_IL_DATASETS`` or ``~/.cache/loco_il/datasets``::

    <Body>.<task>/perfect-n<N>-seed<S>-<key>.npz                 # the dataset (Trajectories.save)
    <Body>.<task>/perfect-n<N>-seed<S>-<key>.init_states.npz     # its InitStates
    <Body>.<task>/preference-<snapshot>-n<N>-seed<S>-<key>.npz   # one file per preference level

``<key>`` (`cache_key`) is the first 16 hex digits of the sha256 of what the data depends on (for a rollout:
the generation task, dataset type, policy checksum, number of episodes, seed, MuJoCo version and the generator
version): any change gives a new file. Files are written atomically and validated on load; a corrupt file
raises :class:`~loco_il.datasets.DatasetError` naming it, and ``regenerate=True`` rebuilds it (`train.py ...
dataset.regenerate=true`). A cache folder that cannot be written is reported before the episodes are
generated; they are then used without being cached (kept in memory for the process, `UNCACHED`).
"""
from __future__ import annotations

import hashlib
import json
import os
import sys
import tempfile
from pathlib import Path
from typing import Any, Mapping

from loco_il.datasets.providers.init_states import InitStates
from loco_il.datasets.trajectory import Trajectories


def datasets_cache_dir() -> Path:
    """``$LOCO_IL_DATASETS`` or ``~/.cache/loco_il/datasets``."""
    given = os.environ.get("LOCO_IL_DATASETS")
    return Path(given).expanduser() if given else Path.home() / ".cache" / "loco_il" / "datasets"


def init_states_path(dataset_path: str | os.PathLike) -> Path:
    """The sidecar file of a dataset file: ``x.npz`` -> ``x.init_states.npz``."""
    p = Path(dataset_path)
    return p.with_name(p.name[:-4] + ".init_states.npz" if p.name.endswith(".npz") else p.name + ".init_states.npz")


def cache_key(fields: Mapping[str, Any]) -> str:
    """The first 16 hex digits of the sha256 of ``fields`` as canonical JSON."""
    return hashlib.sha256(json.dumps(dict(fields), sort_keys=True).encode()).hexdigest()[:16]


def safe_name(name: str) -> str:
    """``name`` with every character but letters, digits and ``-_.`` replaced by ``_`` (a folder or file name)."""
    return "".join(c if c.isalnum() or c in "-_." else "_" for c in name)


def cache_unwritable(folder: Path) -> str | None:
    """None when `folder` can hold cache files (made if missing); else why not. Checked by writing a file, which
    also catches read-only filesystems, before minutes of rollouts are spent on data that could not be kept."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=folder):
            pass
    except OSError as exc:
        return exc.strerror or type(exc).__name__
    return None


#: generated datasets whose cache file could not be written, by that path: later calls of this process (the test
#: split, the start-state sampler) use them instead of generating them again
UNCACHED: dict[Path, tuple[Trajectories, InitStates]] = {}


def warn_uncached(folder: Path, reason: str) -> None:
    """Say on stderr that a generated dataset cannot be cached, and how to fix it."""
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


def regenerate_hint(path: Path) -> str:
    """How to rebuild a cached dataset file, for load errors."""
    return (f"rebuild it with `python train.py ... dataset.regenerate=true` or create_dataset(env, regenerate=True) "
            f"(or delete {path} and its .init_states.npz)")


__all__ = ["datasets_cache_dir", "init_states_path", "cache_key", "safe_name", "cache_unwritable", "UNCACHED",
           "warn_uncached", "save_to_cache", "regenerate_hint"]
