"""The headline of a leaderboard: one row per task, one column per algorithm, the final score in each cell.

`matrix` builds it from `table.cell_result`s (only tasks and algorithms with finished runs appear, so it grows as
the grid fills); `replace_block` puts it into a document (the README) between two marker lines (`doc_block`),

    <!-- leaderboard:small -->
    ...generated...
    <!-- /leaderboard:small -->

so that `python -m loco_il.benchmark table small --readme README.md` keeps the README's table equal to the
committed logs.
"""
from __future__ import annotations

from typing import Sequence

from loco_il.benchmark import doc_block
from loco_il.benchmark.protocol import Protocol
from loco_il.benchmark.table import CellResult, score_text

NOT_IN_PART = "n/a"


def block_name(protocol_name: str) -> str:
    """The name of the protocol's leaderboard block in a document (see `doc_block`)."""
    return f"leaderboard:{protocol_name}"


def _cell_text(res: CellResult) -> str:
    if not res.runs:
        return ""
    text = score_text(res, res.score)
    return text if not res.missing else f"{text} ({len(res.runs)}/{len(res.cell.seeds)} seeds)"


def matrix(proto: Protocol, results: Sequence[CellResult]) -> list[str]:
    """Markdown lines: the task x algorithm table of final scores, with a one-line legend."""
    done = [r for r in results if r.runs]
    if not done:
        return ["No finished runs yet."]
    finished = {r.cell.label for r in done}
    labels = [label for label in dict.fromkeys(lb for part in proto.parts for lb in part.labels) if label in finished]
    tasks = list(dict.fromkeys(r.cell.task_id for r in done))
    by_key = {(r.cell.task_id, r.cell.label): r for r in results}
    lines = ["| task | " + " | ".join(labels) + " |", "|---|" + "---|" * len(labels)]
    for task in tasks:
        cells = [_cell_text(by_key[(task, label)]) if (task, label) in by_key else NOT_IN_PART for label in labels]
        lines.append(f"| {task} | " + " | ".join(cells) + " |")
    lines += ["", "Final normalized score (\"(return)\" where the task has no expert baseline), mean ± 95 % CI over",
              f"the finished seeds; empty: not run yet; {NOT_IN_PART}: not in the protocol for that dataset type",
              "(e.g. BC on `real` data, which has no actions)."]
    return lines


def replace_block(text: str, protocol_name: str, block: Sequence[str], where: str = "the document") -> str:
    """`text` with the protocol's leaderboard block replaced by `block`."""
    return doc_block.replace_block(text, block_name(protocol_name), block, where)


__all__ = ["block_name", "matrix", "replace_block"]
