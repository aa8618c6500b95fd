"""The imitation-learning agents (mushroom-rl `Agent`s), one module each:

    from loco_il.algorithms import GAIL, VAIL, GAIfO, IQLearn, LSIQ, LSIQfO, SQIL, BC

`build_agent(name, env_info, cfg)` (`factory.py`) builds one from an `experiment_configs/algo/<name>.yaml` config.
Modules are imported on first use of a name, so `import loco_il.algorithms` stays cheap.
"""
from __future__ import annotations

import importlib
from typing import Any

_MODULES = {"GAIL": "gail", "VAIL": "vail", "GAIfO": "gaifo", "IQLearn": "iq_learn", "LSIQ": "lsiq",
            "LSIQfO": "lsiq", "SQIL": "sqil", "BC": "bc", "build_agent": "factory"}

__all__ = sorted(_MODULES)


def __getattr__(name: str) -> Any:
    if name not in _MODULES:
        raise AttributeError(f"module 'loco_il.algorithms' has no attribute {name!r}")
    return getattr(importlib.import_module(f"{__name__}.{_MODULES[name]}"), name)
