"""The cost model (`loco_il.benchmark.cost`) against the wall time of a protocol's finished runs.

For every cell with finished runs (their `eval.json`, whose `wall_time` is the training's own clock summed over
resumes): the model's estimate of one run, the measured time of each seed and their ratio (mean measured / model);
then the median ratio per learner family. A ratio well below 1 means the model overestimates (it counts evaluation
episodes at the full horizon, so falls make runs shorter); above 1 usually means the runs shared the 2-core
machine with another run. Runs trained on a GPU (`device` other than cpu in their config.yaml) are left out: the
model is of CPU training. `benchmarks/cost_model_check.py` prints the report or writes it into RESULTS.md.
"""
from __future__ import annotations

import statistics
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path

from loco_il.benchmark import cost
from loco_il.benchmark.cells import all_cells
from loco_il.benchmark.protocol import Protocol
from loco_il.benchmark.seed_detail import DEFAULT_DEVICE, run_device
from loco_il.benchmark.status import finished_eval


def block_name(protocol_name: str) -> str:
    """The name of the document block (`doc_block`) that holds the protocol's report in RESULTS.md."""
    return f"cost-model-check:{protocol_name}"


@dataclass(frozen=True)
class CostRow:
    key: str            # the cell, "<task>/<label>"
    family: str
    model_s: float      # the model's estimate of one run
    walls: tuple[float, ...]    # measured wall time of each finished CPU seed

    @property
    def ratio(self) -> float:
        return statistics.mean(self.walls) / self.model_s


def trained_on_cpu(run_dir: Path) -> bool:
    return run_device(run_dir) == DEFAULT_DEVICE


def rows(proto: Protocol, results_dir: Path | None = None) -> list[CostRow]:
    """One row per cell with at least one finished run trained on the CPU, in the protocol's cell order."""
    results_dir = results_dir or proto.results_dir
    out = []
    for cell in all_cells(proto):
        run_dirs = [cell.run_dir(results_dir, s) for s in cell.seeds]
        walls = tuple(e["wall_time"] for d in run_dirs
                      if (e := finished_eval(cell, d)) and "wall_time" in e and trained_on_cpu(d))
        if walls:
            out.append(CostRow(cell.key, cell.family.name, cost.run_hours(proto, cell) * 3600, walls))
    return out


def report(proto: Protocol, results_dir: Path | None = None) -> list[str]:
    """The report's lines: a row per cell, then each family's median ratio and range."""
    table = rows(proto, results_dir)
    width = max([len("cell")] + [len(r.key) for r in table])
    lines = [f"{'cell':{width}s} {'model s':>8s}  measured s (per seed)   ratio"]
    lines += [f"{r.key:{width}s} {r.model_s:8.0f}  {', '.join(f'{w:.0f}' for w in r.walls):22s} {r.ratio:5.2f}"
              for r in table]
    by_family: dict[str, list[float]] = defaultdict(list)
    for r in table:
        by_family[r.family].append(r.ratio)
    lines.append("")
    lines += [f"{family}: median ratio {statistics.median(v):.2f} over {len(v)} cells "
              f"(range {min(v):.2f}-{max(v):.2f})" for family, v in by_family.items()]
    return lines


def fenced(lines: list[str]) -> list[str]:
    """The report as RESULTS.md holds it: a fenced code block."""
    return ["```", *lines, "```"]


__all__ = ["CostRow", "block_name", "fenced", "report", "rows"]
