"""The schema of `train.py`'s config: types (an OmegaConf structured config) and ranges, checked before anything
is built, so a bad value is a one-line error naming the key and the fix instead of a bogus "finished" run.

`validate_config(cfg)` returns the config as a plain dict with every value of its declared type (`"5"` from
the command line is 5), or raises `ConfigValueError`. Groups whose keys differ per choice (`algo`, `logger`,
`per_algo`, `dataset.provider_kwargs`) are typed as open mappings; their values are checked where they are used.
"""
from __future__ import annotations

import math
import os
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Dict, List, Mapping, Optional


class ConfigValueError(ValueError):
    """A config value of the wrong type or out of range: one-line message naming the key and the fix."""


@dataclass
class EvalSchema:
    every: Optional[int] = None
    episodes: int = 5
    final_episodes: int = 10
    seed: int = 1000
    deterministic: bool = True
    similarity: bool = True
    max_points: int = 1000


@dataclass
class DatasetSchema:
    n_trajectories: Optional[int] = None
    portion: List[float] = field(default_factory=lambda: [0.0, 0.75])
    split_seed: int = 0
    generation_seed: int = 0
    n_episodes: Optional[int] = None
    expert_path: Optional[str] = None
    provider_kwargs: Dict[str, Any] = field(default_factory=dict)
    workers: int = 1
    verbose: bool = True
    regenerate: bool = False


@dataclass
class TrainSchema:
    task_id: str = "???"
    name: str = "???"
    seed: int = 0
    results_dir: str = "results"
    device: str = "cpu"
    torch_threads: int = 1
    n_steps: Optional[int] = None
    per_algo: Dict[str, Any] = field(default_factory=dict)
    init_state: str = "default"
    checkpoint_every: Optional[int] = None
    checkpoint_replay: bool = True
    keep_checkpoints_above: Optional[float] = None
    resume: Any = "auto"
    fork_from: Optional[str] = None
    stop_after_steps: Optional[int] = None
    dataset: DatasetSchema = field(default_factory=DatasetSchema)
    eval: EvalSchema = field(default_factory=EvalSchema)
    logger: Dict[str, Any] = field(default_factory=dict)
    algo: Dict[str, Any] = field(default_factory=dict)


#: resume= values and what they mean (Hydra parses `resume=true` as a bool, `resume=1` as an int)
RESUME_MODES: dict[Any, str] = {"auto": "auto", True: "must", "true": "must", "yes": "must", "must": "must", 1: "must",
                                False: "never", "false": "never", "no": "never", "never": "never", 0: "never"}
INIT_STATES = ("default", "dataset")


def resume_mode(value: Any) -> str:
    """"auto", "must" (resume=true) or "never" (resume=false); `ConfigValueError` for anything else."""
    key = value.lower() if isinstance(value, str) else value
    if isinstance(key, (str, bool, int)) and key in RESUME_MODES:
        return RESUME_MODES[key]
    raise ConfigValueError(f"resume={value}: expected auto, true (must resume) or false (start over)")


def _at_least(minimum: int, optional: bool = False) -> Callable[[Any], bool]:
    return lambda v: (optional and v is None) or (v is not None and v >= minimum)


#: (dotted key, condition on the typed value, what a valid value is)
RANGES: tuple[tuple[str, Callable[[Any], bool], str], ...] = (
    ("seed", _at_least(0), "an integer >= 0"),
    ("torch_threads", _at_least(1), "an integer >= 1"),
    ("n_steps", _at_least(1, optional=True), "an integer >= 1, or null for the task's default budget"),
    ("checkpoint_every", _at_least(1, optional=True), "an integer >= 1, or null (checkpoint at every evaluation)"),
    ("stop_after_steps", _at_least(1, optional=True), "an integer >= 1, or null"),
    ("keep_checkpoints_above", lambda v: v is None or not math.isnan(v), "a normalized score (e.g. 0.9) or null"),
    ("init_state", lambda v: v in INIT_STATES, "one of " + ", ".join(INIT_STATES)),
    ("eval.every", _at_least(1, optional=True), "an integer >= 1, or null (the algorithm's epoch)"),
    ("eval.episodes", _at_least(1), "an integer >= 1"),
    ("eval.final_episodes", _at_least(1), "an integer >= 1"),
    ("eval.seed", _at_least(0), "an integer >= 0"),
    ("eval.max_points", _at_least(2), "an integer >= 2"),
    ("dataset.workers", _at_least(1), "an integer >= 1 (processes generating the dataset)"),
    ("dataset.n_episodes", _at_least(1, optional=True), "an integer >= 1, or null (the provider's default)"),
    ("dataset.n_trajectories", _at_least(1, optional=True), "an integer >= 1, or null (all episodes)"),
    ("dataset.split_seed", _at_least(0), "an integer >= 0"),
    ("dataset.generation_seed", _at_least(0), "an integer >= 0"),
    ("dataset.portion", lambda v: len(v) == 2 and 0.0 <= v[0] < v[1] <= 1.0,
     "[start, end] with 0 <= start < end <= 1, e.g. [0.0,0.75]"),
)


def _get(cfg: Mapping[str, Any], dotted: str) -> Any:
    value: Any = cfg
    for part in dotted.split("."):
        value = value[part]
    return value


def _typed(cfg: Any) -> dict[str, Any]:
    """Merge `cfg` into the structured schema; an OmegaConf validation error becomes one line."""
    from omegaconf import OmegaConf
    from omegaconf.errors import OmegaConfBaseException
    schema = OmegaConf.structured(TrainSchema)
    try:
        merged = OmegaConf.merge(schema, cfg)
        return OmegaConf.to_container(merged, resolve=True, throw_on_missing=True)
    except OmegaConfBaseException as exc:
        key = getattr(exc, "full_key", None) or "?"
        msg = str(exc).splitlines()[0]
        if "not in" in msg and "Key" in msg:
            raise ConfigValueError(f"unknown config key {key!r} ({msg}); `python train.py --cfg job` lists the "
                                   f"keys") from None
        value = _raw_value(cfg, key)
        value = repr(value) if isinstance(value, str) else value
        expected = _expected_type(key)
        raise ConfigValueError(f"{key}={value}: expected {expected}" if expected else f"{key}: {msg}") from None


def _raw_value(cfg: Any, key: str) -> Any:
    from omegaconf import OmegaConf
    try:
        return OmegaConf.select(cfg, key, throw_on_resolution_failure=False) if not isinstance(cfg, dict) \
            else _get(cfg, key)
    except Exception:  # noqa: BLE001 - only for the message
        return "?"


def _expected_type(key: str) -> str | None:
    """'an integer', 'a number', ... for a schema key (None when the key is unknown)."""
    import dataclasses
    import typing
    node: Any = TrainSchema
    hint: Any = None
    for part in key.split("."):
        if not dataclasses.is_dataclass(node):
            return None
        hints = typing.get_type_hints(node)
        if part not in hints:
            return None
        hint = node = hints[part]
    optional = type(None) in typing.get_args(hint)
    base = next((a for a in typing.get_args(hint) if a is not type(None)), hint) if optional else hint
    names = {int: "an integer", float: "a number", bool: "true or false", str: "a string"}
    word = names.get(base, "a list of numbers" if typing.get_origin(base) in (list, List) else None)
    return None if word is None else word + (" or null" if optional else "")


def check_device(value: str) -> None:
    """A torch device that exists on this machine (checked before the env, dataset and agent are built)."""
    import torch
    try:
        device = torch.device(value)
    except (RuntimeError, ValueError):
        raise ConfigValueError(f"device={value}: not a torch device; use device=cpu, device=cuda or "
                               f"device=cuda:<index>") from None
    if device.type == "cuda":
        n = torch.cuda.device_count() if torch.cuda.is_available() else 0
        if n == 0:
            raise ConfigValueError(f"device={value}: this machine has no CUDA device (torch.cuda.is_available() is "
                                   f"False); use device=cpu")
        if device.index is not None and device.index >= n:
            raise ConfigValueError(f"device={value}: this machine has {n} CUDA device(s) (cuda:0..cuda:{n - 1})")
    elif device.type != "cpu":
        raise ConfigValueError(f"device={value}: loco_il trains on cpu or cuda; use device=cpu or device=cuda")


def check_results_dir(value: str | os.PathLike) -> None:
    """`results_dir` is (or can be made) a folder this process can write into; checked by writing a file there,
    which also catches read-only filesystems (os.access does not, for root)."""
    path = Path(value).expanduser()
    try:
        path.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=path):
            pass
    except (FileExistsError, NotADirectoryError):
        raise ConfigValueError(f"results_dir={value}: {path} (or a folder above it) is a file, not a folder; "
                               f"choose another results_dir") from None
    except OSError as exc:
        raise ConfigValueError(f"results_dir={value}: cannot write there ({exc.strerror}); choose a writable "
                               f"results_dir=<folder>") from None


def validate_config(cfg: Any, *, check_paths: bool = True) -> dict[str, Any]:
    """The config as a typed plain dict, or `ConfigValueError` for the first bad value (see the module doc)."""
    typed = _typed(cfg)
    for key, ok, expected in RANGES:
        value = _get(typed, key)
        if not ok(value):
            shown = repr(value) if isinstance(value, str) else value
            raise ConfigValueError(f"{key}={shown}: expected {expected}")
    resume_mode(typed["resume"])
    if not isinstance(typed["algo"].get("name"), str):
        raise ConfigValueError("algo.name is missing: choose an algorithm with algo=<name>")
    check_device(typed["device"])
    if check_paths:
        check_results_dir(typed["results_dir"])
    return typed


__all__ = ["ConfigValueError", "TrainSchema", "validate_config", "resume_mode", "check_device", "check_results_dir",
           "RESUME_MODES", "INIT_STATES"]
