"""Where each run of a protocol stands, read from its run dir: finished, unfinished (resumable) or not started.

A run is finished when its `eval.json` is for the cell's task and label and its `steps` are the cell's budget;
anything else that left a `checkpoint.json` or `log.csv` is unfinished and resumes through train.py's own resume.
A run trained past the budget (its dir reused with a larger `n_steps`) is neither, and a run whose dir a train.py
process holds right now is running: `run` leaves both alone. The leaderboard table reads the results alone
(`live=False`): a run without a finished `eval.json` is "not finished" there, whatever checkpoint or process this
machine has, so that the table made from the committed logs is the same on every machine.
"""
from __future__ import annotations

import fcntl
import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

from loco_il.benchmark import paths
from loco_il.benchmark.cells import Cell

FINISHED, UNFINISHED, NEW, OVER, RUNNING = "finished", "unfinished", "not started", "over budget", "running"
#: a run without a finished result, where only the results are read (the table): not said whether it started
NOT_FINISHED = "not finished"
#: train.py's run-dir lock (loco_il/experiment/lock.py), held by the process that trains the run
LOCK_NAME = ".lock"


@dataclass(frozen=True)
class RunState:
    cell: Cell
    seed: int
    state: str                 # FINISHED, UNFINISHED, NEW, OVER, RUNNING or NOT_FINISHED
    step: int | None           # the final step (finished) or the step a resume starts from (unfinished)
    run_dir: Path

    def describe(self) -> str:
        if self.state == UNFINISHED:
            where = f"resumes at step {self.step}" if self.step is not None else "no checkpoint yet"
            return f"seed {self.seed}: unfinished, {where} of {self.cell.budget}"
        if self.state == RUNNING:
            return f"seed {self.seed}: running now (train.py holds {paths.relative(self.run_dir / LOCK_NAME)})"
        if self.state == OVER:
            return (f"seed {self.seed}: trained to {self.step} steps, past the budget {self.cell.budget}; move "
                    f"{self.run_dir} away to run it again")
        return f"seed {self.seed}: {self.state}"


def _read_json(path: Path) -> dict[str, Any] | None:
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) else None


def final_eval(cell: Cell, run_dir: Path) -> dict[str, Any] | None:
    """The run's final evaluation (`eval.json`) when it is one of this cell's runs, at any budget."""
    result = _read_json(run_dir / "eval.json")
    if (result is None or result.get("task_id") != cell.task_id or result.get("name") != cell.label
            or not isinstance(result.get("steps"), int) or "return_mean" not in result
            or "dataset_type" not in result or "task" not in result):
        return None
    return result


def finished_eval(cell: Cell, run_dir: Path) -> dict[str, Any] | None:
    """The run's final evaluation when it trained for exactly the cell's budget, else None."""
    result = final_eval(cell, run_dir)
    return result if result is not None and result["steps"] == cell.budget else None


def is_running(run_dir: Path) -> bool:
    """Whether a process holds the run dir's lock (checked without taking it, so nothing is written)."""
    try:
        fd = os.open(run_dir / LOCK_NAME, os.O_RDONLY)
    except OSError:
        return False
    try:
        fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
        return False
    except BlockingIOError:
        return True
    finally:
        os.close(fd)   # also releases the shared lock taken above


def run_state(cell: Cell, seed: int, results_dir: Path, live: bool = True) -> RunState:
    """The run's state; `live=False` reads its `eval.json` alone (finished, over budget or NOT_FINISHED)."""
    run_dir = cell.run_dir(results_dir, seed)
    done = final_eval(cell, run_dir)
    if done is not None and done["steps"] >= cell.budget:
        return RunState(cell, seed, FINISHED if done["steps"] == cell.budget else OVER, done["steps"], run_dir)
    if not live:
        return RunState(cell, seed, NOT_FINISHED, None, run_dir)
    if is_running(run_dir):
        return RunState(cell, seed, RUNNING, None, run_dir)
    summary = _read_json(run_dir / "checkpoint.json")
    if summary is not None or (run_dir / "log.csv").is_file():
        step = summary.get("step") if summary else None
        return RunState(cell, seed, UNFINISHED, step if isinstance(step, int) else None, run_dir)
    return RunState(cell, seed, NEW, None, run_dir)


def states(cells: Sequence[Cell], results_dir: Path) -> list[RunState]:
    return [run_state(c, s, results_dir) for c in cells for s in c.seeds]


__all__ = ["RunState", "run_state", "states", "final_eval", "finished_eval", "is_running", "FINISHED", "UNFINISHED",
           "NEW", "OVER", "RUNNING", "NOT_FINISHED"]
