"""Task-IDs: `<Body>[-<variant>].<task>[.<mode>].<dataset>[.pomdp]`, defaults for missing parts, close-match errors.

The mode exists for tasks that draw a version of the model per episode from a set the mode names
(LocoMuJoCo's 4Ages humanoids: `HumanoidTorque4Ages.walk.2.real`, `...walk.all.real`); a missing mode
takes the task's default.
"""
from __future__ import annotations

import difflib
from dataclasses import dataclass
from typing import Any

from loco_il.environments.body import Body

#: The dataset types, the last part of a Task-ID (and ``info["dataset_type"]`` of a dataset).
DATASET_TYPES = ("real", "perfect", "preference")
_BODIES: dict[str, Body] = {}


class UnknownTaskError(KeyError):
    """An unknown Task-ID; the message names the closest valid IDs."""

    def __str__(self) -> str:  # KeyError would quote the message
        return str(self.args[0])


def register_body(body: Body) -> None:
    if body.name in _BODIES:
        raise ValueError(f"body {body.name!r} is registered twice")
    if body.default_task not in body.tasks or body.default_dataset not in body.datasets:
        raise ValueError(f"body {body.name!r}: defaults must name one of its tasks and datasets")
    _BODIES[body.name] = body


def bodies() -> dict[str, Body]:
    _load_all()
    return dict(_BODIES)


def get_body(name: str) -> Body:
    _load_all()
    if name not in _BODIES:
        raise UnknownTaskError(f"unknown body {name!r}; did you mean {_suggest(name, list(_BODIES))}? "
                               f"Known bodies: {', '.join(sorted(_BODIES))}")
    return _BODIES[name]


def _load_all() -> None:
    import loco_il.environments.bodies  # noqa: F401 (registers everything)


@dataclass(frozen=True)
class TaskID:
    body: str
    variant: str | None
    task: str
    dataset: str
    pomdp: bool
    mode: str | None = None

    def __str__(self) -> str:
        name = self.body + (f"-{self.variant}" if self.variant else "")
        task = self.task + (f".{self.mode}" if self.mode else "")
        return f"{name}.{task}.{self.dataset}" + (".pomdp" if self.pomdp else "")


def get_all_task_names() -> list[str]:
    """Every full Task-ID of every registered body (without iMuJoCo variants and `.pomdp` suffixes)."""
    _load_all()
    return [tid for body in _BODIES.values() for tid in body.task_ids()]


def _suggest(name: str, options: list[str], n: int = 3) -> str:
    close = difflib.get_close_matches(name, options, n=n, cutoff=0.4)
    if not close:  # fall back to case-insensitive prefix matches
        close = [o for o in options if o.lower().startswith(name.lower()[:3])][:n]
    return ", ".join(repr(c) for c in close) if close else "(no close match)"


def parse_task_id(task_id: str) -> TaskID:
    """Parse and complete a Task-ID; raise `UnknownTaskError` naming close matches when it is invalid."""
    _load_all()
    if not isinstance(task_id, str) or not task_id.strip():
        raise UnknownTaskError(f"a Task-ID must be a non-empty string like 'UnitreeH1.walk.real', got {task_id!r}")
    parts = task_id.strip().split(".")
    pomdp = parts[-1] == "pomdp" and len(parts) > 1
    if pomdp:
        parts = parts[:-1]
    if len(parts) > 4:
        raise UnknownTaskError(f"malformed Task-ID {task_id!r}: expected <Body>.<task>[.<mode>].<dataset>[.pomdp]")
    body_part = parts[0]
    body_name, _, variant = body_part.partition("-")
    all_ids = get_all_task_names()
    if body_name not in _BODIES:
        raise UnknownTaskError(f"unknown Task-ID {task_id!r}: no body {body_name!r}. "
                               f"Closest valid IDs: {_suggest(task_id, all_ids)}")
    body = _BODIES[body_name]
    task = parts[1] if len(parts) > 1 else body.default_task
    rest = parts[2:]
    if len(rest) == 1 and rest[0] not in DATASET_TYPES and task in body.tasks and body.modes(task) != (None,):
        rest = [rest[0], body.default_dataset]       # <Body>.<task>.<mode>
    mode = rest[0] if len(rest) == 2 else None
    dataset = rest[-1] if rest else body.default_dataset
    if task not in body.tasks:
        candidates = [t for t in all_ids if t.startswith(body_name + ".")]
        raise UnknownTaskError(f"unknown Task-ID {task_id!r}: {body_name} has no task {task!r} "
                               f"(its tasks: {', '.join(body.tasks)}). Closest valid IDs: "
                               f"{_suggest(task_id, candidates)}")
    modes = body.modes(task)
    if mode is not None and mode not in modes:
        why = (f"{body_name}.{task} has no mode part; drop {mode!r}" if modes == (None,) else
               f"mode {mode!r} of {body_name}.{task} is not one of {', '.join(modes)} "
               f"(e.g. {body_name}.{task}.{modes[0]}.{dataset})")
        raise UnknownTaskError(f"unknown Task-ID {task_id!r}: {why}")
    if mode is None and modes != (None,):
        mode = body.tasks[task].draw.default_mode
    if dataset not in body.datasets:
        raise UnknownTaskError(f"unknown Task-ID {task_id!r}: {body_name} offers datasets "
                               f"{', '.join(body.datasets)}, not {dataset!r}. Closest valid IDs: "
                               f"{_suggest(f'{body_name}.{task}.{dataset}', body.task_ids())}")
    if variant:
        from loco_il.environments.variants import list_variants
        known = list_variants(body_name)
        if variant not in known:
            raise UnknownTaskError(f"unknown variant {variant!r} of {body_name}; closest: "
                                   f"{_suggest(variant, known)} (see list_variants({body_name!r}))")
    return TaskID(body_name, variant or None, task, dataset, pomdp, mode)


def task_key(env_or_id: Any) -> str:
    """``<Body>[-<variant>].<task>[.<mode>]`` of an env or a Task-ID (dataset type and ``.pomdp`` dropped): the key
    of a task's experts, baselines and cached datasets."""
    if isinstance(env_or_id, str):
        tid = parse_task_id(env_or_id)
        body, variant, task, mode = tid.body, tid.variant, tid.task, tid.mode
    else:
        body, variant, task = env_or_id.body_name, getattr(env_or_id, "variant", None), env_or_id.task_name
        mode = getattr(env_or_id, "mode", None)
    return f"{body}{'-' + variant if variant else ''}.{task}{'.' + mode if mode else ''}"


def make(task_id: str, **kwargs: Any):
    """Build the `LocoEnv` of a Task-ID. kwargs go to `LocoEnv` (seed, reward, randomization, hide, ...)."""
    from loco_il.environments.base import LocoEnv
    tid = parse_task_id(task_id)
    body = _BODIES[tid.body]
    if "randomization" in kwargs and isinstance(kwargs["randomization"], (str, dict)):
        from loco_il.environments.randomization import load_randomization
        kwargs["randomization"] = load_randomization(kwargs["randomization"], tid.body)
    if kwargs.get("randomization") is not None and "randomize_every" not in kwargs:
        kwargs["randomize_every"] = getattr(kwargs["randomization"], "every", 1)
    return LocoEnv(body, tid.task, tid.dataset, variant=tid.variant, mode=tid.mode, pomdp=tid.pomdp, **kwargs)
