"""Re-score finished runs against the current baselines: the normalized scores of their logs, from their returns.

    python -m loco_il.evaluation.rescore <run dir or folder of run dirs> ...

A run's normalized score is `(return - random) / (expert - random)` with the baselines of
`loco_il/datasets/baselines.yaml` as they were when it ran (`loco_il.experiment.scoring.normalized`). When a
task's baseline is recorded (or re-measured) after its runs, this recomputes, from the returns the runs logged,
`normalized_score` (and `baseline`) of each `eval.json` and the `normalized_score` column of each `log.csv`, so
the leaderboard's tables score every run of a task against the same baseline. `normalized_score_ema` (the score
of the actor's moving average, whose return the log does not keep) is left as it is. Runs of a task without a
baseline are left untouched. Files are rewritten atomically, and only when a value changes.
"""
from __future__ import annotations

import csv
import json
import math
import sys
from pathlib import Path
from typing import Iterator, Sequence

import numpy as np

from loco_il.datasets.baselines import BaselineMissingError, normalized_score
from loco_il.experiment.logging import CSV_COLUMNS, write_log_csv
from loco_il.experiment.scoring import normalized
from loco_il.utils.fileio import write_json

EVAL_FILE, LOG_FILE = "eval.json", "log.csv"


def run_dirs(paths: Sequence[str | Path]) -> Iterator[Path]:
    """Every run dir (a folder holding an eval.json) at or under `paths`, sorted."""
    for path in map(Path, paths):
        if not path.exists():
            raise FileNotFoundError(f"{path}: no such run dir or folder; give a train.py run dir or a folder of them")
        yield from sorted(p.parent for p in ([path / EVAL_FILE] if (path / EVAL_FILE).is_file()
                                             else path.rglob(EVAL_FILE)))


def _same(old: float | None, new: float) -> bool:
    return old is not None and math.isclose(old, new, rel_tol=1e-12, abs_tol=1e-12)


def _rescore_eval(path: Path, task_id: str) -> bool:
    data = json.loads(path.read_text())
    score, note, baseline = normalized(task_id, float(data["return_mean"]))
    if score is None or (_same(data.get("normalized_score"), score) and data.get("baseline") == baseline):
        return False
    data.update(normalized_score=score, normalized_score_note=None, baseline=baseline)
    write_json(path, data)
    return True


def _rescore_log(path: Path, task_id: str) -> bool:
    if not path.is_file():
        return False
    with open(path, newline="") as fh:
        reader = csv.DictReader(fh)
        fields, rows = list(reader.fieldnames or ()), list(reader)
    if tuple(fields) != CSV_COLUMNS:
        raise ValueError(f"{path}: columns {fields} are not a train.py log.csv's {list(CSV_COLUMNS)}")
    evaluated = [row for row in rows if row["eval_return_mean"] not in ("", None)]
    if not evaluated:
        return False
    try:   # one baseline lookup for the whole log (normalized_score works on arrays)
        scores = np.atleast_1d(normalized_score(task_id, [float(row["eval_return_mean"]) for row in evaluated]))
    except (BaselineMissingError, ValueError):   # no baseline (yet): the log stays as it is
        return False
    changed = False
    for row, score in zip(evaluated, map(float, scores)):
        old = None if row["normalized_score"] in ("", None) else float(row["normalized_score"])
        if not _same(old, score):
            row["normalized_score"], changed = repr(score), True
    if changed:
        write_log_csv(path, rows)
    return changed


def rescore_run(run_dir: Path) -> bool:
    """Recompute one run's normalized scores; True when a file changed."""
    task_id = json.loads((run_dir / EVAL_FILE).read_text())["task_id"]
    changed_log = _rescore_log(run_dir / LOG_FILE, task_id)     # first: a foreign log.csv leaves eval.json alone
    changed_eval = _rescore_eval(run_dir / EVAL_FILE, task_id)
    return changed_log or changed_eval


def main(argv: Sequence[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] in ("-h", "--help"):
        print(__doc__, file=sys.stdout if argv else sys.stderr)
        return 0 if argv else 2
    try:
        dirs = list(run_dirs(argv))
        changed = [d for d in dirs if rescore_run(d)]
    except (FileNotFoundError, ValueError) as err:   # a missing path, a log.csv that is not train.py's
        print(f"[rescore] error: {err}", file=sys.stderr)
        return 2
    for d in changed:
        print(f"[rescore] {d}")
    print(f"[rescore] {len(changed)} of {len(dirs)} run(s) re-scored")
    return 0


if __name__ == "__main__":
    sys.exit(main())
