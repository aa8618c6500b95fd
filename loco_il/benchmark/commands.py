"""The train.py command lines of a protocol: one Hydra multirun per group of runs that share their settings."""
from __future__ import annotations

import shlex
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Sequence

from loco_il.benchmark import paths
from loco_il.benchmark.cells import Cell
from loco_il.benchmark.protocol import Protocol


def hydra_value(value: Any) -> str:
    """A YAML value as a Hydra command-line value (true, null, [256,256])."""
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (list, tuple)):
        return "[" + ",".join(hydra_value(v) for v in value) + "]"
    return str(value)


def fixed_overrides(proto: Protocol, cell: Cell, results_dir: Path | None = None) -> tuple[str, ...]:
    """Every train.py setting of a cell's runs except task, algo and seed (the swept ones)."""
    out = [f"n_steps={cell.budget}", f"eval.every={cell.family.eval_every}"]
    out += [f"eval.{k}={hydra_value(v)}" for k, v in proto.eval]
    out += [f"{k}={hydra_value(v)}" for k, v in proto.overrides]
    if cell.label != cell.algo:
        out.append(f"name={cell.label}")
    out += [f"{k}={hydra_value(v)}" for k, v in cell.overrides]
    out.append(f"results_dir={paths.relative(results_dir or proto.results_dir)}")
    return tuple(out)


@dataclass(frozen=True)
class Launch:
    """One `train.py -m` sweep: every task x algorithm x seed combination, with the same fixed settings."""
    tasks: tuple[str, ...]
    algos: tuple[str, ...]
    seeds: tuple[int, ...]
    fixed: tuple[str, ...]
    cells: tuple[Cell, ...] = field(default=(), compare=False)   # the cells whose runs it makes

    @property
    def n_runs(self) -> int:
        return len(self.tasks) * len(self.algos) * len(self.seeds)

    def args(self, extra: Sequence[str] = ()) -> list[str]:
        """train.py's arguments (after the script's path)."""
        return ["-m", f"task={','.join(self.tasks)}", f"algo={','.join(self.algos)}",
                f"seed={','.join(map(str, self.seeds))}", *self.fixed, *extra]

    def display(self, extra: Sequence[str] = ()) -> str:
        return "python " + shlex.join(["train.py", *self.args(extra)])


def cell_command(proto: Protocol, cell: Cell, seeds: Sequence[int] | None = None,
                 results_dir: Path | None = None) -> str:
    """The command that (re)produces a cell's runs (or only `seeds` of them)."""
    return Launch((cell.task_id,), (cell.algo,), tuple(seeds if seeds is not None else cell.seeds),
                  fixed_overrides(proto, cell, results_dir)).display()


def plan(proto: Protocol, runs: Sequence[tuple[Cell, int]], results_dir: Path | None = None) -> list[Launch]:
    """As few sweeps as cover exactly `runs` ((cell, seed) pairs): runs with the same fixed settings are grouped,
    tasks that miss the same seeds share a sweep, and algorithms with the same tasks and seeds share one too
    (e.g. every on-policy learner of a part in one sweep), so parallel launchers get many jobs at once."""
    by_fixed: dict[tuple[str, ...], dict[str, dict[str, list[int]]]] = {}
    cell_of: dict[tuple[tuple[str, ...], str, str], Cell] = {}
    for cell, seed in runs:
        fixed = fixed_overrides(proto, cell, results_dir)
        by_fixed.setdefault(fixed, {}).setdefault(cell.algo, {}).setdefault(cell.task_id, []).append(seed)
        cell_of[(fixed, cell.algo, cell.task_id)] = cell
    launches = []
    for fixed, algos in by_fixed.items():
        merged: dict[tuple[tuple[int, ...], tuple[str, ...]], list[str]] = {}
        for algo, tasks in algos.items():
            by_seeds: dict[tuple[int, ...], list[str]] = {}
            for task, seeds in tasks.items():
                by_seeds.setdefault(tuple(sorted(set(seeds))), []).append(task)
            for seeds, task_list in by_seeds.items():
                merged.setdefault((seeds, tuple(task_list)), []).append(algo)
        for (seeds, tasks), algo_list in merged.items():
            cells = tuple(cell_of[(fixed, a, t)] for a in algo_list for t in tasks)
            launches.append(Launch(tasks, tuple(algo_list), seeds, fixed, cells))
    return launches


__all__ = ["Launch", "fixed_overrides", "cell_command", "plan", "hydra_value"]
