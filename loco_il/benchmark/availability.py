"""Whether a cell's dataset can be built here: `perfect` data need the task's expert, `preference` data its
ranked snapshots (a file in the expert search path, `$LOCO_IL_EXPERTS`, or a built-in controller). Cells without
one are skipped by `run` and listed as blocked by `table`, with how to get the expert."""
from __future__ import annotations

import os
from functools import lru_cache


def blocked_reason(task_id: str) -> str | None:
    """None when the dataset of `task_id` can be built; else a one-line reason with the fix."""
    return _blocked_reason(task_id, os.environ.get("LOCO_IL_EXPERTS", ""))


@lru_cache(maxsize=None)
def _blocked_reason(task_id: str, experts_path: str) -> str | None:
    """`blocked_reason`, cached per expert search path (`experts_path` is part of the key, not read)."""
    from loco_il.environments.registry import task_key
    from loco_il.experts.files import available_experts, available_snapshot_sets
    from loco_il.experts.registry import builtin_expert
    key = task_key(task_id)
    dataset = task_id.rsplit(".", 1)[-1]
    builtin = builtin_expert(key)
    if dataset == "perfect" and key not in available_experts() and builtin is None:
        return (f"no expert for {key}: train one (`python -m loco_il.experts train task={key}`, humanoid robots "
                f"with algo=tracking: docs/tracking_experts.md) and put it in $LOCO_IL_EXPERTS/{key}/expert.pt")
    if dataset == "preference" and key not in available_snapshot_sets() and (builtin is None or builtin.levels is None):
        return (f"no preference snapshots for {key}: train an expert (`python -m loco_il.experts train task={key}`) "
                f"and put >= 4 of its snapshots in $LOCO_IL_EXPERTS/{key}/snapshots/level_<k>.pt")
    return None


__all__ = ["blocked_reason"]
