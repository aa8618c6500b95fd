"""Which code builds the dataset of a dataset type (`real`, `perfect`, `preference`).

A provider is called as ``provider(env, **kwargs)`` and returns a :class:`Trajectories` with FULL
observations, or a pair ``(Trajectories, InitStates | None)``. `perfect` and `preference` are
built in (:mod:`.expert`); the `real` provider (motion capture -> observations) is registered by
the module that implements it::

    from loco_il.datasets.providers import register_real_provider
    register_real_provider(my_real_provider)     # my_real_provider(env, **kwargs) -> Trajectories
"""
from __future__ import annotations

import os
from pathlib import Path
from typing import Any, Callable

from loco_il.environments.registry import DATASET_TYPES
from loco_il.utils.errors import DatasetError

Provider = Callable[..., Any]

_PROVIDERS: dict[str, Provider] = {}
#: modules imported (once) before reporting that no `real` provider is registered
REAL_PROVIDER_MODULES = ("loco_il.datasets.real",)


class ProviderUnavailableError(DatasetError):
    """No provider can build this dataset type (e.g. `real` without a registered provider)."""


def register_provider(dataset_type: str, fn: Provider, *, replace: bool = False) -> None:
    """Register the provider of a dataset type; ``replace=True`` overrides an existing one."""
    if dataset_type not in DATASET_TYPES:
        raise ValueError(f"unknown dataset type {dataset_type!r}; one of {DATASET_TYPES}")
    if not callable(fn):
        raise TypeError(f"a provider must be callable, got {type(fn).__name__}")
    if dataset_type in _PROVIDERS and not replace and _PROVIDERS[dataset_type] is not fn:
        raise ValueError(f"a provider for {dataset_type!r} is already registered "
                         f"({_PROVIDERS[dataset_type]!r}); pass replace=True to override it")
    _PROVIDERS[dataset_type] = fn


def register_real_provider(fn: Provider, *, replace: bool = False) -> None:
    """Register the `real` (motion-capture) provider: ``fn(env, **kwargs) -> Trajectories``."""
    register_provider("real", fn, replace=replace)


def unregister_provider(dataset_type: str) -> Provider | None:
    """Remove a provider (tests); returns it."""
    return _PROVIDERS.pop(dataset_type, None)


def motions_dir(env_or_key: Any = None) -> Path:
    """Where the `real` provider looks for motion files: ``$LOCO_IL_MOTIONS`` or
    ``~/.cache/loco_il/motions``, then ``<Body>/`` (and the task name, if the provider wants)."""
    given = os.environ.get("LOCO_IL_MOTIONS")
    root = Path(given).expanduser() if given else Path.home() / ".cache" / "loco_il" / "motions"
    if env_or_key is None:
        return root
    body = env_or_key if isinstance(env_or_key, str) else env_or_key.body_name
    return root / body.split(".")[0].split("-")[0]


def _builtin() -> None:
    if "perfect" not in _PROVIDERS:
        from loco_il.datasets.providers.expert import perfect_provider
        _PROVIDERS["perfect"] = perfect_provider
    if "preference" not in _PROVIDERS:
        from loco_il.datasets.providers.expert import preference_provider
        _PROVIDERS["preference"] = preference_provider


def _try_real_modules() -> None:
    import importlib
    for name in REAL_PROVIDER_MODULES:
        try:
            importlib.import_module(name)
        except ModuleNotFoundError as exc:
            if exc.name is None or not name.startswith(exc.name):
                raise   # the module exists but one of its imports is missing: say so


def get_provider(dataset_type: str, env: Any = None) -> Provider:
    """The provider of a dataset type; a clear error when there is none."""
    _builtin()
    if dataset_type == "real" and "real" not in _PROVIDERS:
        _try_real_modules()
    if dataset_type in _PROVIDERS:
        return _PROVIDERS[dataset_type]
    if dataset_type == "real":
        task = getattr(env, "task_id", None) or "this task"
        where = motions_dir(env) if env is not None else motions_dir() / "<Body>"
        raise ProviderUnavailableError(
            f"{task} uses the `real` dataset (motion capture), and no real-data provider is registered. "
            f"The real dataset is built from the body's motion-capture files: put the LocoMuJoCo 0.4.x "
            f"motion file(s) of this task (`.npz` with per-joint arrays q_<joint>/dq_<joint>, e.g. "
            f"{getattr(env, 'task_name', '<task>')}.npz) in {where} (set $LOCO_IL_MOTIONS to use another "
            f"folder) and import the module that registers the provider "
            f"(loco_il.datasets.providers.register_real_provider). A file you already have can also be "
            f"loaded directly with loco_il.datasets.convert.locomujoco.load_locomujoco_npz.")
    raise ProviderUnavailableError(f"no dataset provider for dataset type {dataset_type!r}; "
                                   f"registered: {', '.join(sorted(_PROVIDERS))}")


def registered_providers() -> dict[str, Provider]:
    _builtin()
    return dict(_PROVIDERS)


__all__ = ["ProviderUnavailableError", "register_provider", "register_real_provider", "unregister_provider",
           "get_provider", "registered_providers", "motions_dir", "REAL_PROVIDER_MODULES"]
