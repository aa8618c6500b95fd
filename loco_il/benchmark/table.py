"""The leaderboard of a protocol: one row per cell from its finished runs, the runs still missing, the cost estimate.

Statistics come from `loco_il.evaluation.leaderboard` (`aggregate` for the final return and normalized score,
`mean_ci` for the scores along the way): mean ± 95 % Student-t interval over the finished seeds. A cell's
score is its normalized score where the task has an expert baseline, else its evaluation return. The score at a
report step is that of the run's first evaluation at or after it (on-policy learners fit in batches of 1024 env
steps, so their evaluation at "100k" is at 100,352).
"""
from __future__ import annotations

import csv
import io
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Sequence

from loco_il.benchmark import availability, commands, cost, paths, seed_detail
from loco_il.benchmark.cells import Cell
from loco_il.benchmark.protocol import Protocol
from loco_il.benchmark.status import FINISHED, NOT_FINISHED, RunState, finished_eval, run_state
from loco_il.evaluation import leaderboard

NORMALIZED, RETURN = "normalized", "return"


@dataclass
class CellResult:
    cell: Cell
    states: list[RunState]
    runs: list[dict[str, Any]] = field(default_factory=list)     # eval.json of each finished seed (+ run_dir)
    summary: dict[str, Any] | None = None                         # leaderboard.aggregate's row
    metric: str = RETURN
    score: tuple[float, float | None] | None = None               # (mean, 95 % half-width) of the metric
    at: dict[int, tuple[float, float | None, int]] = field(default_factory=dict)   # step -> (mean, ci, n)
    blocked: str | None = None
    command: str = ""
    seeds_detail: list[seed_detail.SeedRun] = field(default_factory=list)   # the finished runs, seed by seed

    @property
    def missing(self) -> list[RunState]:
        return [s for s in self.states if s.state != FINISHED]

    @property
    def status(self) -> str:
        if not self.runs:
            return "blocked" if self.blocked else "missing"
        return "partial" if self.missing else "complete"


def score_at(log_rows: Sequence[dict[str, Any]], step: int, window: int, metric: str) -> float | None:
    """The metric at the first evaluation in [step, step + window) of a run's log.csv rows."""
    key = "normalized_score" if metric == NORMALIZED else "eval_return_mean"
    for row in log_rows:
        s = row.get("step")
        if s is not None and step <= s < step + window and row.get(key) is not None:
            return float(row[key])
    return None


def cell_result(proto: Protocol, cell: Cell, states: Sequence[RunState], blocked: str | None,
                published: Sequence[dict[str, Any]], results_dir: Path) -> CellResult:
    from loco_il.utils.fileio import read_csv
    res = CellResult(cell, list(states), blocked=blocked,
                     command=commands.cell_command(proto, cell, results_dir=results_dir))
    for st in states:
        if st.state == FINISHED:
            run = dict(finished_eval(cell, st.run_dir) or {})
            run["run_dir"] = str(st.run_dir)
            res.runs.append(run)
    if not res.runs:
        return res
    res.summary = leaderboard.aggregate(res.runs, published)[0]
    normalized = res.summary["normalized_mean"] is not None
    res.metric = NORMALIZED if normalized else RETURN
    res.score = ((res.summary["normalized_mean"], res.summary["normalized_ci95"]) if normalized
                 else (res.summary["return_mean"], res.summary["return_ci95"]))
    res.seeds_detail = seed_detail.seed_runs(res.runs, normalized)
    logs = [read_csv(Path(r["run_dir"]) / "log.csv") for r in res.runs]
    for step in cell.family.report_at:
        values = [v for v in (score_at(rows, step, cell.family.eval_every, res.metric) for rows in logs)
                  if v is not None]
        if values:
            mean, ci = leaderboard.mean_ci(values)
            res.at[step] = (mean, ci, len(values))
    return res


def results_of(proto: Protocol, cells: Sequence[Cell], results_dir: Path) -> list[CellResult]:
    """Every cell's result from the run dirs under `results_dir` (and whether its dataset can be built here)."""
    published = leaderboard.load_published()
    return [cell_result(proto, c, [run_state(c, s, results_dir, live=False) for s in c.seeds],
                        availability.blocked_reason(c.task_id), published, results_dir) for c in cells]


# ----------------------------------------------------------------------------- formatting
def protocol_arg(proto: Protocol) -> str:
    """How commands name the protocol: its name when it is a shipped one, else its file."""
    return proto.name if proto.path.resolve().parent == paths.PROTOCOL_DIR.resolve() else paths.relative(proto.path)


def steps_label(steps: int) -> str:
    """100000 -> 100k, 1500000 -> 1.5M."""
    if steps >= 1_000_000 and steps % 100_000 == 0:
        return f"{steps / 1e6:g}M"
    if steps >= 1000 and steps % 1000 == 0:
        return f"{steps // 1000}k"
    return str(steps)


def _pm(mean: float | None, ci: float | None, digits: int) -> str:
    if mean is None:
        return "n/a"
    return f"{mean:.{digits}f}" if ci is None else f"{mean:.{digits}f} ± {ci:.{digits}f}"


def metric_format(res: CellResult) -> tuple[int, str]:
    """How a cell's scores are written: (decimals, suffix); returns, where there is no baseline, are marked."""
    return (2, "") if res.metric == NORMALIZED else (1, " (return)")


def score_text(res: CellResult, value: tuple[float, float | None] | None) -> str:
    if value is None:
        return "—"
    digits, suffix = metric_format(res)
    return _pm(value[0], value[1], digits) + suffix


def report_steps(proto: Protocol) -> list[int]:
    return sorted({s for f in proto.families for s in f.report_at})


# The published-score sources (leaderboard.PUBLISHED_FILE) and what a search of the literature found for this grid.
PUBLISHED_NOTE = ("\"published\": a paper's score for the same setting, with its source "
                  "(`loco_il/evaluation/published.yaml`); \"n/a\" where none exists. None exists for LocoMuJoCo's "
                  "tasks: LocoMuJoCo publishes no baseline scores (loco-mujoco issue #13). For the classic bodies "
                  "the papers' settings differ (expert episodes, budgets, Gymnasium versions) and no same-setting "
                  "number could be read (`benchmarks/PUBLISHED.md`).")


def published_text(res: CellResult) -> str:
    """A row's published score with its source, or n/a."""
    value = (res.summary or {}).get("published")
    if not value:
        return leaderboard.NO_PUBLISHED
    source = (res.summary or {}).get("published_source")
    return f"{value} ({source})" if source else str(value)


def _seed_note(res: CellResult) -> str:
    done = len(res.runs)
    return f"{done}/{len(res.cell.seeds)}"


def _episodes(n: Any) -> str:
    return f"{n} episode{'' if int(n) == 1 else 's'}"


def markdown(proto: Protocol, results: Sequence[CellResult], cost_text: str, curves: dict[str, str],
             results_dir: Path | None = None, overview: Sequence[str] = ()) -> str:
    """The protocol's leaderboard page; `overview` (the task x algorithm headline, `overview.matrix`) comes
    first when given."""
    steps = report_steps(proto)
    ev = dict(proto.eval)
    n_runs = sum(len(r.states) for r in results)
    n_done = sum(len(r.runs) for r in results)
    lines = [f"# Leaderboard: protocol `{proto.name}`", ""]
    if proto.description:
        lines += [proto.description, ""]
    along = (", ".join(f"@{steps_label(s)}" for s in steps) + f": the first evaluation "
             f"({_episodes(ev.get('episodes', 5))}) at or after that many env steps; — where the budget ends "
             "before it, or for BC (trained offline, in gradient steps). ") if steps else ""
    lines += [f"Generated by `python -m loco_il.benchmark table {protocol_arg(proto)}` from the run dirs in "
              f"`{paths.relative(results_dir or proto.results_dir)}` (each run's `eval.json` and `log.csv`); "
              f"protocol: `{paths.relative(proto.path)}`. {n_done} of {n_runs} runs finished.", "",
              "Score: the normalized score (0 = uniform random actions, 1 = the task's expert; "
              "`loco_il/datasets/baselines.yaml`) where the task has an expert baseline, else the evaluation return "
              "(marked \"(return)\"). Mean ± 95 % confidence interval over the finished seeds (Student-t, n-1 "
              "degrees of freedom; none for a single seed). \"final\": the final evaluation "
              f"({_episodes(ev.get('final_episodes', 10))}); " + along
              + "Each row's command reproduces it (run from the repository root).", "", PUBLISHED_NOTE, ""]
    if overview:
        lines += ["## Overview", "", *overview, ""]
    head = ["task", "algorithm", "budget", "seeds", "final"] + [f"@{steps_label(s)}" for s in steps] + \
        ["return", "published", "command"]
    for part in proto.parts:
        rows = [r for r in results if r.cell.part == part.name and r.runs]
        lines += [f"## Part `{part.name}` ({part.dataset} datasets)", ""]
        if not rows:
            lines += ["No finished runs yet.", ""]
        else:
            lines += ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
            for r in rows:
                at = [score_text(r, r.at[s][:2]) if s in r.at else "—" for s in steps]
                lines.append("| " + " | ".join([r.cell.task_id, r.cell.label, r.cell.budget_label, _seed_note(r),
                                                score_text(r, r.score), *at,
                                                _pm(r.summary["return_mean"], r.summary["return_ci95"], 1),
                                                published_text(r), f"`{r.command}`"]) + " |")
            lines.append("")
        figs = [f"[{t}]({p})" for t, p in sorted(curves.items()) if t.endswith(f".{part.dataset}")
                and any(r.cell.task_id == t for r in rows)]
        if figs:
            lines += ["Learning curves: " + ", ".join(figs), ""]
    lines += seeds_section(proto, results)
    lines += missing_section(proto, results, results_dir)
    lines += ["## Settings", "", "| family | algorithms | budget | evaluation every |", "|---|---|---|---|"]
    for fam in proto.families:
        lines.append(f"| {fam.name} | {', '.join(fam.algos)} | {fam.n_steps} {fam.unit_label} | {fam.eval_every} |")
    lines.append("")
    for var in proto.variants:
        settings = " ".join(f"{k}={commands.hydra_value(v)}" for k, v in var.overrides)
        lines.append(f"- `{var.label}`: {var.algo} with `{settings}`" + (f" ({var.note})" if var.note else ""))
    lines += ["", "## Estimated cost", "", "```", cost_text, "```", ""]
    return "\n".join(lines)


SEEDS_SECTION = "## Finished runs, seed by seed"


def seeds_section(proto: Protocol, results: Sequence[CellResult]) -> list[str]:
    """Every cell with finished runs, one row each: its seeds' final scores, falls, episode lengths and wall times
    (`seed_detail`), in the order of the parts above."""
    rows = [r for part in proto.parts for r in results if r.cell.part == part.name and r.runs]
    if not rows:
        return []
    n = int(dict(proto.eval).get("final_episodes", 10))
    lines = [SEEDS_SECTION, "",
             f"Per seed, in seed order: the final score, the final evaluation's episodes ending by a fall (early "
             f"termination; of {n}), their mean length in env steps, and the wall time per run as "
             f"train.py measured it (summed over resumes; \"(cuda)\" where the run's config says `device=cuda`).", "",
             "| task | algorithm | seeds | final per seed | episodes falling per seed | mean episode length per seed "
             "| wall per run |", "|---|---|---|---|---|---|---|"]
    for r in rows:
        digits, suffix = metric_format(r)
        runs = r.seeds_detail
        lines.append(f"| {r.cell.task_id} | {r.cell.label} | {' '.join(str(x.seed) for x in runs)} | "
                     f"{seed_detail.finals_text(runs, digits)}{suffix} | "
                     f"{seed_detail.falls_text(runs, n)} | {seed_detail.lengths_text(runs)} | "
                     f"{seed_detail.wall_text(runs)} |")
    return lines + [""]


def state_text(states: Sequence[RunState]) -> str:
    """The missing runs of a cell in a few words: "not finished", "seed 0: trained to 5000 steps, past the budget
    300 ...; seeds 1 2: not finished" (the table reads results alone, see `status.run_state(live=False)`)."""
    parts = [s.describe() for s in states if s.state != NOT_FINISHED]
    seeds = [str(s.seed) for s in states if s.state == NOT_FINISHED]
    if seeds:
        parts.append(NOT_FINISHED if not parts
                     else f"seed{'s' if len(seeds) > 1 else ''} {' '.join(seeds)}: {NOT_FINISHED}")
    return "; ".join(parts)


def missing_section(proto: Protocol, results: Sequence[CellResult], results_dir: Path | None) -> list[str]:
    """The runs still to make: one row per cell with the command that fills it; cells waiting for a dataset are
    grouped per task, with the reason and the command that runs them once the dataset can be built."""
    missing = [r for r in results if r.missing and not r.blocked]
    blocked: dict[str, list[CellResult]] = {}
    for r in results:
        if r.missing and r.blocked:
            blocked.setdefault(r.cell.task_id, []).append(r)
    lines = ["## Missing runs", ""]
    if not missing and not blocked:
        return lines + ["None: every run of the protocol has finished.", ""]
    n = sum(len(r.missing) for r in results)
    # a cell's missing seeds at the full estimate (an unfinished run resumes, so this is an upper bound)
    hours = {id(r): len(r.missing) * cost.run_hours(proto, r.cell) for r in results if r.missing}
    lines += [f"{n} runs, ~{cost.hours_text(sum(hours.values()))} single-core hours by the cost model (`python -m "
              f"loco_il.benchmark cost`; \"est. hours\" below). `python -m loco_il.benchmark run "
              f"{protocol_arg(proto)}` starts or resumes all of them (with `--dry-run` it says which have started on "
              f"this machine); each command below fills one cell.", ""]
    if missing:
        lines += ["| task | algorithm | seeds | state | est. hours | command |", "|---|---|---|---|---|---|"]
        for r in missing:
            seeds = [s.seed for s in r.missing]
            cmd = commands.cell_command(proto, r.cell, seeds, results_dir=results_dir)
            lines.append(f"| {r.cell.task_id} | {r.cell.label} | {' '.join(map(str, seeds))} | "
                         f"{state_text(r.missing)} | {cost.hours_text(hours[id(r)])} | `{cmd}` |")
        lines.append("")
    if blocked:
        lines += ["Blocked until their dataset can be built (the CSV has each cell's train.py command):", "",
                  "| task | algorithms | reason | command once unblocked |", "|---|---|---|---|"]
        for task_id, members in blocked.items():
            labels = ", ".join(r.cell.label for r in members)
            lines.append(f"| {task_id} | {labels} | {members[0].blocked} | "
                         f"`python -m loco_il.benchmark run {protocol_arg(proto)} --tasks {task_id}` |")
        lines.append("")
    return lines


CSV_HEAD = ("part", "task", "dataset", "algorithm", "algo", "family", "budget", "seeds_planned", "seeds_finished",
            "status", "metric", "final_mean", "final_ci95")


def to_csv(proto: Protocol, results: Sequence[CellResult]) -> str:
    steps = report_steps(proto)
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow([*CSV_HEAD, *(f"at_{s}_{k}" for s in steps for k in ("mean", "ci95", "n")), "return_mean",
                "return_ci95", "normalized_mean", "normalized_ci95", "published", "missing_seeds", "blocked",
                "command", *seed_detail.CSV_COLUMNS])
    num = lambda x: "" if x is None else f"{x:.4f}"  # noqa: E731
    for r in results:
        c, s = r.cell, r.summary or {}
        at = []
        for step in steps:
            mean, ci, n = r.at.get(step, (None, None, None))
            at += [num(mean), num(ci), "" if n is None else n]
        w.writerow([c.part, c.task_id, c.dataset, c.label, c.algo, c.family.name, c.budget_label,
                    " ".join(map(str, c.seeds)), " ".join(str(x.get("seed")) for x in r.runs), r.status,
                    r.metric if r.runs else "", num(r.score[0] if r.score else None),
                    num(r.score[1] if r.score else None), *at, num(s.get("return_mean")), num(s.get("return_ci95")),
                    num(s.get("normalized_mean")), num(s.get("normalized_ci95")), s.get("published") or "",
                    " ".join(str(x.seed) for x in r.missing), r.blocked or "", r.command,
                    *seed_detail.csv_values(r.seeds_detail)])
    return buf.getvalue()


__all__ = ["CellResult", "cell_result", "results_of", "markdown", "to_csv", "score_at", "score_text", "steps_label",
           "report_steps"]
