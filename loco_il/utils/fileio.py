"""Plain data in run files: JSON-safe values (`jsonable`), JSON files (`write_json`), CSV rows (`read_csv`).

Used by the training loop (`log.jsonl`, `eval.json`) and by the tools that read run dirs (evaluation, leaderboard,
progress), so that neither has to import the other for them.
"""
from __future__ import annotations

import csv
import json
import math
import os
from pathlib import Path
from typing import Any, Mapping

from loco_il.utils.atomic import atomic_open


def jsonable(value: Any) -> Any:
    """`value` as JSON data: tensors and numpy scalars as numbers, NaN and infinities as None (JSON has
    neither), mappings and sequences recursively, anything else as its str()."""
    if hasattr(value, "item") and callable(value.item):
        try:
            value = value.item()
        except (ValueError, RuntimeError):
            return str(value)
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, (str, int, float, bool)) or value is None:
        return value
    if isinstance(value, Mapping):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [jsonable(v) for v in value]
    return str(value)


def write_json(path: str | os.PathLike, data: Mapping[str, Any]) -> None:
    """`data` (made `jsonable`) as an indented JSON file, written atomically."""
    with atomic_open(path, "w") as fh:
        json.dump(jsonable(dict(data)), fh, indent=2)
        fh.write("\n")


def read_csv(path: str | os.PathLike) -> list[dict]:
    """The rows of a CSV file such as a run's `log.csv`, as dicts of floats (empty cells -> None; no file -> [])."""
    path = Path(path)
    if not path.is_file():
        return []
    out = []
    with open(path, newline="") as fh:
        for row in csv.DictReader(fh):
            out.append({k: (float(v) if v not in ("", None) else None) for k, v in row.items()})
    return out


__all__ = ["jsonable", "write_json", "read_csv"]
