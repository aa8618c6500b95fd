"""Built-in experts: a task's expert that needs no weight file (a model-based controller).

A module registers its experts with `register_builtin_expert` when imported; the modules listed in
`BUILTIN_EXPERT_MODULES` are imported on the first lookup. A built-in expert is used when no ``expert.pt``
is installed for the task (`loco_il.experts.files`). The quadrupeds' trot controller
(`loco_il.experts.trot`) is the example.
"""
from __future__ import annotations

import importlib
from dataclasses import dataclass
from typing import Any, Callable

#: Modules imported (once) before looking up a built-in expert; each registers its experts.
BUILTIN_EXPERT_MODULES = ("loco_il.experts.trot",)


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
        _builtin_modules_loaded = True
        for name in BUILTIN_EXPERT_MODULES:
            importlib.import_module(name)
    return _BUILTIN.get(key)


def builtin_experts() -> list[str]:
    """Task keys that have a built-in expert."""
    builtin_expert("")
    return sorted(_BUILTIN)


__all__ = ["BUILTIN_EXPERT_MODULES", "BuiltinExpert", "register_builtin_expert", "builtin_expert", "builtin_experts"]
