"""Configs and metadata as plain Python data: dicts, lists, numbers, strings, bools and None.

Run configs arrive as OmegaConf configs (from Hydra) or as dicts (from Python); they are stored in checkpoints,
compared on resume and written to `config.yaml`. Expert files keep their metadata in this form so that
`torch.load(..., weights_only=True)` accepts them.
"""
from __future__ import annotations

import sys
from typing import Any, Mapping

import numpy as np

#: what a value that cannot be resolved becomes with `to_plain(..., loose=True)`
UNRESOLVED = "?"


def to_plain(obj: Any, *, loose: bool = False) -> Any:
    """`obj` as plain Python data, recursively.

    OmegaConf configs are resolved first (a missing mandatory value `???` or a broken interpolation raises);
    mappings become dicts with str keys, lists and tuples become lists, numpy scalars and arrays become numbers
    and lists, and anything else that is not a number, string, bool or None becomes its str().

    loose=True, for labels of a config that may be invalid: a value that cannot be resolved becomes "?" instead
    of raising.
    """
    omegaconf = sys.modules.get("omegaconf")   # an OmegaConf config can only exist once omegaconf is imported
    if omegaconf is not None and isinstance(obj, omegaconf.Container):
        try:
            obj = omegaconf.OmegaConf.to_container(obj, resolve=True, throw_on_missing=True)
        except Exception:  # noqa: BLE001 - any resolution error; re-raised unless loose
            if not loose:
                raise
            return _each_resolved(obj)
    if isinstance(obj, Mapping):
        return {str(k): to_plain(v, loose=loose) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [to_plain(v, loose=loose) for v in obj]
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if obj is None or isinstance(obj, (bool, int, float, str)):
        return obj
    return str(obj)


def _each_resolved(cfg: Any) -> Any:
    """An OmegaConf config that does not resolve as a whole, value by value ("?" where one fails)."""
    from omegaconf import DictConfig

    def value(key: Any) -> Any:
        try:
            return to_plain(cfg[key], loose=True)
        except Exception:  # noqa: BLE001 - unresolvable: only a label is wanted
            return UNRESOLVED

    if isinstance(cfg, DictConfig):
        return {str(k): value(k) for k in cfg.keys()}
    return [value(i) for i in range(len(cfg))]


__all__ = ["to_plain", "UNRESOLVED"]
