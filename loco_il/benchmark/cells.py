"""The cells of a protocol: one (task, dataset type, algorithm label, budget) with its seeds, and the selection of
cells a command works on (`--parts`, `--tasks`, `--algos`, `--datasets`, `--seeds`)."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

from loco_il.benchmark.protocol import Family, Protocol, ProtocolError


@dataclass(frozen=True)
class Cell:
    part: str
    dataset: str
    task_id: str                         # the full Task-ID, e.g. "Atlas.walk.real"
    label: str                           # the row label: train.py's `name`, the run dir's algorithm folder
    algo: str                            # train.py's `algo=`
    family: Family
    overrides: tuple[tuple[str, Any], ...]   # a variant's own settings
    seeds: tuple[int, ...]

    @property
    def budget(self) -> int:
        return self.family.n_steps

    @property
    def budget_label(self) -> str:
        """The budget as `loco_il.evaluation.leaderboard` writes it ("1000000 env steps")."""
        return f"{self.budget} {self.family.unit_label}"

    @property
    def key(self) -> str:
        return f"{self.task_id}/{self.label}"

    def run_dir(self, results_dir: Path, seed: int) -> Path:
        """train.py's run dir of one seed: <results_dir>/<Task-ID>/<name>/seed<k>."""
        return Path(results_dir) / self.task_id / self.label / f"seed{seed}"


@dataclass(frozen=True)
class Selection:
    """Restrictions of a command to part of the grid (empty = everything)."""
    parts: tuple[str, ...] = ()
    tasks: tuple[str, ...] = ()          # "Atlas.walk" (every dataset type) or "Atlas.walk.real"
    algos: tuple[str, ...] = ()          # a row label, or an algorithm (all of its rows)
    datasets: tuple[str, ...] = ()
    seeds: tuple[int, ...] = ()


def all_cells(proto: Protocol) -> list[Cell]:
    cells = []
    for part in proto.parts:
        for task in part.tasks:
            for label in part.labels:
                algo = proto.algo_of(label)
                variant = proto.variant(label)
                cells.append(Cell(part=part.name, dataset=part.dataset, task_id=f"{task}.{part.dataset}",
                                  label=label, algo=algo, family=proto.family_of(algo),
                                  overrides=variant.overrides if variant else (), seeds=proto.seeds))
    return cells


def _check_values(given: Sequence[Any], known: set[Any], what: str, proto: Protocol) -> None:
    for value in given:
        if value not in known:
            raise ProtocolError(f"no {what} {value!r} in protocol {proto.name}; its {what}s: "
                                f"{', '.join(str(k) for k in sorted(known, key=str))}")


def select(proto: Protocol, sel: Selection = Selection()) -> list[Cell]:
    """The protocol's cells that match every given restriction, their seeds cut to `sel.seeds`; a value that
    matches nothing in the protocol is a `ProtocolError` naming the valid ones."""
    cells = all_cells(proto)
    _check_values(sel.parts, {c.part for c in cells}, "part", proto)
    _check_values(sel.datasets, {c.dataset for c in cells}, "dataset", proto)
    _check_values(sel.tasks, {c.task_id for c in cells} | {c.task_id.rsplit(".", 1)[0] for c in cells}, "task",
                  proto)
    _check_values(sel.algos, {c.label for c in cells} | {c.algo for c in cells}, "algorithm", proto)
    _check_values(sel.seeds, set(proto.seeds), "seed", proto)
    out = []
    for c in cells:
        if ((sel.parts and c.part not in sel.parts) or (sel.datasets and c.dataset not in sel.datasets)
                or (sel.tasks and c.task_id not in sel.tasks and c.task_id.rsplit(".", 1)[0] not in sel.tasks)
                or (sel.algos and c.label not in sel.algos and c.algo not in sel.algos)):
            continue
        seeds = tuple(s for s in c.seeds if not sel.seeds or s in sel.seeds)
        out.append(Cell(c.part, c.dataset, c.task_id, c.label, c.algo, c.family, c.overrides, seeds))
    return out


__all__ = ["Cell", "Selection", "all_cells", "select"]
