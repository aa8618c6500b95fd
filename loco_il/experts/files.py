"""Where a task's expert is found, and how a file or an object becomes a policy.

**Layout.** The expert of a task key ``<Body>[-<variant>].<task>`` (`loco_il.environments.registry.task_key`)
is ``<root>/<key>/expert.pt``, its preference snapshots ``<root>/<key>/snapshots/level_<k>.pt``, for each
root of `expert_search_path`: the folders of ``$LOCO_IL_EXPERTS`` (os.pathsep-separated), then the folder
shipped in the package (`SHIPPED_DIR`, ``loco_il/experts/shipped``). A task without a file may have a
built-in expert (`loco_il.experts.registry`).

**Files.** `loco_il.experts.policy.load_expert` reads both expert file formats: `ExpertPolicy`
(``loco_il.expert/v1``) and `TrackingExpert` (``loco_il.tracking_expert/v1``).

**Policy interface.** ``policy(obs) -> action`` and ``policy.checksum() -> str``; optional ``obs_dim``,
``act_dim``, ``metadata``, ``description`` (a one-line name for logs and ``info``) and
``start_episode(env, seed)``: called right after ``env.seed(seed); env.reset()`` of every episode, before
the first call, with the env being rolled out (by the episode loop, `loco_il.environments.episodes`). A policy
that needs the simulator state (not only the observation) reads ``env.model`` / ``env.data`` there and in its
calls, but never writes to them (so the recorded actions replay exactly); anything it draws at random comes
from ``seed``.
"""
from __future__ import annotations

import os
import sys
from pathlib import Path
from typing import Any

from loco_il.experts.policy import load_expert
from loco_il.experts.registry import builtin_expert, builtin_experts
from loco_il.utils.errors import DatasetError

#: Where shipped experts live: ``<SHIPPED_DIR>/<Body>.<task>/expert.pt`` and ``snapshots/level_<k>.pt``.
SHIPPED_DIR = Path(__file__).resolve().parent / "shipped"
#: Fewest snapshots of different quality a preference dataset is built from.
MIN_PREFERENCE_LEVELS = 4


class NoExpertError(DatasetError):
    """No expert (or no preference snapshots) is available for a task."""


# ----------------------------------------------------------------------------- lookup


def expert_search_path() -> list[Path]:
    """Folders searched for ``<Body>.<task>/expert.pt``: ``$LOCO_IL_EXPERTS`` (os.pathsep-separated),
    then the shipped folder ``loco_il/experts/shipped``."""
    extra = [Path(p).expanduser() for p in os.environ.get("LOCO_IL_EXPERTS", "").split(os.pathsep) if p]
    return extra + [Path(SHIPPED_DIR)]


def available_experts() -> list[str]:
    """Task keys (``<Body>.<task>``) that have an ``expert.pt`` in the search path (built-in experts:
    `loco_il.experts.registry.builtin_experts`)."""
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


# ----------------------------------------------------------------------------- loading


def policy_checksum(policy: Any) -> str:
    """``policy.checksum()``, checked to be a non-empty str (it goes into the dataset cache key)."""
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
        policy_checksum(expert)
        return expert, describe_policy(expert)
    if expert_path is None:
        try:
            path = find_expert(key)
        except NoExpertError:
            builtin = builtin_expert(key)
            if builtin is None:
                raise
            policy = builtin.expert(env if env is not None else key)
            policy_checksum(policy)
            return policy, describe_policy(policy)
    else:
        path = Path(expert_path)
    if not path.is_file():
        raise NoExpertError(f"expert file {path} does not exist")
    try:
        policy = load_expert(path)
    except Exception as exc:  # torch/pickle/format errors: name the file
        raise NoExpertError(f"cannot load expert file {path}: {type(exc).__name__}: {exc}") from exc
    return policy, str(path)


__all__ = ["SHIPPED_DIR", "MIN_PREFERENCE_LEVELS", "NoExpertError", "expert_search_path", "available_experts",
           "available_snapshot_sets", "find_expert", "find_snapshots", "policy_checksum", "describe_policy",
           "load_policy"]
