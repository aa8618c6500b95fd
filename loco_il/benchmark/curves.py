"""Learning-curve figures of a protocol: per task, the score against env steps, one line per algorithm label
(mean and 95 % band over the finished seeds that logged each step, `leaderboard.mean_ci`), dotted lines at the
report steps. BC trains offline, without env steps: its final score is a dashed horizontal line."""
from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np

from loco_il.benchmark.table import NORMALIZED, CellResult, steps_label
from loco_il.evaluation.leaderboard import mean_ci


def _curve(res: CellResult) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    from loco_il.utils.fileio import read_csv
    key = "normalized_score" if res.metric == NORMALIZED else "eval_return_mean"
    per_step: dict[float, list[float]] = {}
    for run in res.runs:
        for row in read_csv(Path(run["run_dir"]) / "log.csv"):
            if row.get("step") is not None and row.get(key) is not None:
                per_step.setdefault(row["step"], []).append(row[key])
    steps = np.array(sorted(per_step))
    stats = [mean_ci(per_step[s]) for s in steps]
    mean = np.array([m for m, _ in stats])
    half = np.array([h if h is not None else 0.0 for _, h in stats])
    return steps, mean, half


def plot_task(task_id: str, results: Sequence[CellResult], report_at: Sequence[int], path: Path) -> Path | None:
    """One figure for one task; None when none of its cells has a finished run."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    done = [r for r in results if r.runs]
    if not done:
        return None
    fig, ax = plt.subplots(figsize=(7.0, 4.2))
    for res in done:
        seeds = f"{len(res.runs)} seed{'s' if len(res.runs) > 1 else ''}"
        if res.cell.family.unit != "env":
            ax.axhline(res.score[0], linestyle="--", linewidth=1.2, color="gray",
                       label=f"{res.cell.label} (offline, {res.cell.budget_label}; {seeds})")
            continue
        steps, mean, half = _curve(res)
        line, = ax.plot(steps, mean, label=f"{res.cell.label} ({seeds})")
        ax.fill_between(steps, mean - half, mean + half, alpha=0.2, color=line.get_color())
    for s in report_at:
        ax.axvline(s, linestyle=":", linewidth=0.8, color="black", alpha=0.4)
    metric = "normalized score" if done[0].metric == NORMALIZED else "evaluation return"
    ax.set_title(f"{task_id}: {metric}, mean and 95 % CI over seeds")
    ax.set_xlabel("env steps" + (" (dotted: " + ", ".join(steps_label(s) for s in report_at) + ")"
                                 if report_at else ""))
    ax.set_ylabel(metric)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="best")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def plot_all(results: Sequence[CellResult], report_at: Sequence[int], out_dir: Path) -> dict[str, Path]:
    """Task-ID -> figure path, for every task with a finished run."""
    by_task: dict[str, list[CellResult]] = {}
    for r in results:
        by_task.setdefault(r.cell.task_id, []).append(r)
    written = {}
    for task_id, members in sorted(by_task.items()):
        path = plot_task(task_id, members, report_at, Path(out_dir) / f"{task_id}.png")
        if path is not None:
            written[task_id] = path
    return written


__all__ = ["plot_task", "plot_all"]
