"""Leaderboard of finished runs: `python -m loco_il.evaluation.leaderboard results/ [--out DIR] [--no-plots]`.

Reads every `eval.json` below the given folder (one per `train.py` run; run dirs need not follow any
layout), groups the runs by (task, dataset type, algorithm label `name`, training budget) and writes to `--out`
(default: the folder itself):

* `leaderboard.md` and `leaderboard.csv`: per group its budget (eval.json `steps` with its unit: env steps,
  or gradient steps for offline BC; runs of different budgets are never pooled), the number of seeds and
  mean ± 95 % confidence interval over seeds of the final return and the normalized score. The interval is
  the Student-t one, mean ± t(0.975, n-1) * s / sqrt(n) with the sample standard deviation s; with a single
  seed there is no interval. Each seed contributes its final evaluation's mean return (eval.json `return_mean`).
* `curves/<task>.<dataset>.png`: evaluation return against training steps per algorithm (mean and 95 % CI
  over the seeds that logged each step), from the runs' `log.csv`.
* a "published" column with scores from `published.yaml` (next to this file) where one exists for the
  (task, dataset, algorithm). LocoMuJoCo publishes no baseline scores (loco-mujoco issue #13), so none
  come from there; see published.yaml for what it holds.
"""
from __future__ import annotations

import argparse
import csv
import io
import json
import math
import sys
from pathlib import Path
from typing import Any, Iterable, Mapping, Sequence

import numpy as np

PUBLISHED_FILE = Path(__file__).with_name("published.yaml")
NO_PUBLISHED = "n/a"
PUBLISHED_NOTE = ("published: scores from loco_il/evaluation/published.yaml. LocoMuJoCo publishes no baseline "
                  "scores (loco-mujoco issue #13); \"n/a\" = no published number for that row.")
CSV_HEADER = ("task", "dataset", "algorithm", "budget", "n_seeds", "seeds", "return_mean", "return_ci95",
              "normalized_mean", "normalized_ci95", "published", "published_source")


# ----------------------------------------------------------------------------- statistics
def t_quantile(p: float, dof: int) -> float:
    from scipy import stats
    return float(stats.t.ppf(p, dof))


def mean_ci(values: Sequence[float], level: float = 0.95) -> tuple[float, float | None]:
    """(mean, half-width of the two-sided Student-t interval); half-width None for fewer than 2 values."""
    x = np.asarray([v for v in values if v is not None], dtype=np.float64)
    if x.size == 0:
        return float("nan"), None
    if x.size < 2:
        return float(x.mean()), None
    half = t_quantile(0.5 + level / 2.0, x.size - 1) * x.std(ddof=1) / math.sqrt(x.size)
    return float(x.mean()), float(half)


# ----------------------------------------------------------------------------- collecting
def collect_runs(root: str | Path, warn=None) -> list[dict[str, Any]]:
    """Every readable `eval.json` below `root`, with its run dir."""
    runs = []
    for path in sorted(Path(root).rglob("eval.json")):
        try:
            data = json.loads(path.read_text())
            for key in ("task", "dataset_type", "return_mean"):
                if key not in data:
                    raise KeyError(key)
        except (OSError, ValueError, KeyError) as exc:
            if warn:
                warn(f"skipping {path}: {type(exc).__name__}: {exc}")
            continue
        data["run_dir"] = str(path.parent)
        data.setdefault("name", data.get("algorithm", "?"))
        runs.append(data)
    return runs


def load_published(path: str | Path | None = None) -> list[dict[str, Any]]:
    import yaml
    path = Path(path) if path is not None else PUBLISHED_FILE
    if not path.is_file():
        return []
    doc = yaml.safe_load(path.read_text()) or {}
    return list(doc.get("entries") or [])


def _published_for(entries: Iterable[Mapping[str, Any]], task: str, dataset: str, algorithm: str):
    for e in entries:
        if (e.get("task"), e.get("dataset"), str(e.get("algorithm", "")).lower()) == (task, dataset, algorithm.lower()):
            return str(e.get("value")), str(e.get("source", ""))
    return None, None


def budget_of(run: Mapping[str, Any]) -> tuple[int, str]:
    """(steps, unit) a run trained for: eval.json's `steps` and `step_unit` (-1 when unknown, sorted first)."""
    steps = run.get("steps")
    return (int(steps) if isinstance(steps, (int, float)) else -1), str(run.get("step_unit") or "steps")


def budget_label(budget: tuple[int, str]) -> str:
    steps, unit = budget
    return f"{steps} {unit}" if steps >= 0 else "unknown"


def aggregate(runs: Sequence[Mapping[str, Any]], published: Sequence[Mapping[str, Any]] = ()) -> list[dict[str, Any]]:
    """One row per (task, dataset, algorithm label, budget), sorted by those keys: runs trained for different
    numbers of steps are different experiments, so their returns are not averaged together."""
    groups: dict[tuple[str, str, str, tuple[int, str]], list[Mapping[str, Any]]] = {}
    for r in runs:
        groups.setdefault((r["task"], r["dataset_type"], str(r["name"]), budget_of(r)), []).append(r)
    rows = []
    for (task, dataset, name, budget), members in sorted(groups.items()):
        members = sorted(members, key=lambda r: (r.get("seed") is None, r.get("seed")))
        ret_mean, ret_ci = mean_ci([m["return_mean"] for m in members])
        norms = [m.get("normalized_score") for m in members]
        if all(n is not None for n in norms):
            norm_mean, norm_ci = mean_ci(norms)
        else:
            norm_mean, norm_ci = None, None
        algorithm = str(members[0].get("algorithm", name))
        pub, src = _published_for(published, task, dataset, algorithm)
        rows.append({"task": task, "dataset": dataset, "algorithm": name, "budget": budget_label(budget),
                     "n_seeds": len(members),
                     "seeds": [m.get("seed") for m in members], "return_mean": ret_mean, "return_ci95": ret_ci,
                     "normalized_mean": norm_mean, "normalized_ci95": norm_ci, "published": pub,
                     "published_source": src, "run_dirs": [m["run_dir"] for m in members]})
    return rows


# ----------------------------------------------------------------------------- tables
def _pm(mean: float | None, ci: float | None, digits: int) -> str:
    if mean is None:
        return "n/a"
    return f"{mean:.{digits}f}" if ci is None else f"{mean:.{digits}f} ± {ci:.{digits}f}"


def to_markdown(rows: Sequence[Mapping[str, Any]]) -> str:
    lines = ["# loco_il leaderboard", "",
             "Mean ± 95 % confidence interval over seeds (Student-t, n-1 degrees of freedom; no interval for a "
             "single seed) of each run's final evaluation return. Normalized score: 0 = uniform random actions, "
             "1 = the task's expert (loco_il/datasets/baselines.yaml); n/a where the task has no baseline.", "",
             "| task | dataset | algorithm | budget | seeds | return | normalized | published |",
             "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['task']} | {r['dataset']} | {r['algorithm']} | {r['budget']} | {r['n_seeds']} | "
                     f"{_pm(r['return_mean'], r['return_ci95'], 2)} | "
                     f"{_pm(r['normalized_mean'], r['normalized_ci95'], 3)} | {r['published'] or NO_PUBLISHED} |")
    lines += ["", PUBLISHED_NOTE, ""]
    return "\n".join(lines)


def _num(x: float | None, digits: int) -> str:
    return "" if x is None else f"{x:.{digits}f}"


def to_csv(rows: Sequence[Mapping[str, Any]]) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(CSV_HEADER)
    for r in rows:
        w.writerow([r["task"], r["dataset"], r["algorithm"], r["budget"], r["n_seeds"],
                    " ".join(str(s) for s in r["seeds"]), _num(r["return_mean"], 4), _num(r["return_ci95"], 4), _num(r["normalized_mean"], 4),
                    _num(r["normalized_ci95"], 4), r["published"] or "", r["published_source"] or ""])
    return buf.getvalue()


# ----------------------------------------------------------------------------- curves
def plot_curves(rows: Sequence[Mapping[str, Any]], out_dir: str | Path) -> list[Path]:
    """One PNG per (task, dataset): eval return vs steps, mean and 95 % CI over seeds per algorithm."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from loco_il.utils.fileio import read_csv
    out_dir = Path(out_dir)
    by_task: dict[tuple[str, str], list[Mapping[str, Any]]] = {}
    for r in rows:
        by_task.setdefault((r["task"], r["dataset"]), []).append(r)
    written = []
    for (task, dataset), members in sorted(by_task.items()):
        fig, ax = plt.subplots(figsize=(6.4, 4.0))
        plotted = False
        for r in members:
            per_step: dict[float, list[float]] = {}
            for run_dir in r["run_dirs"]:
                for row in read_csv(Path(run_dir) / "log.csv"):
                    if row.get("step") is not None and row.get("eval_return_mean") is not None:
                        per_step.setdefault(row["step"], []).append(row["eval_return_mean"])
            if not per_step:
                continue
            steps = np.array(sorted(per_step))
            stats = [mean_ci(per_step[s]) for s in steps]
            mean = np.array([m for m, _ in stats])
            half = np.array([h if h is not None else 0.0 for _, h in stats])
            line, = ax.plot(steps, mean, label=f"{r['algorithm']}, {r['budget']} "
                                               f"({r['n_seeds']} seed{'s' if r['n_seeds'] > 1 else ''})")
            ax.fill_between(steps, mean - half, mean + half, alpha=0.2, color=line.get_color())
            plotted = True
        if plotted:
            ax.set_title(f"{task} ({dataset})")
            ax.set_xlabel("training steps (env steps; BC: gradient steps)")
            ax.set_ylabel("evaluation return")
            ax.grid(alpha=0.3)
            ax.legend(fontsize=8)
            fig.tight_layout()
            out_dir.mkdir(parents=True, exist_ok=True)
            path = out_dir / f"{task}.{dataset}.png"
            fig.savefig(path, dpi=100)
            written.append(path)
        plt.close(fig)
    return written


# ----------------------------------------------------------------------------- entry point
def build(root: str | Path, out: str | Path | None = None, plots: bool = True,
          published_path: str | Path | None = None, warn=None) -> dict[str, Any]:
    from loco_il.utils.atomic import atomic_open
    root = Path(root)
    out = Path(out) if out is not None else root
    runs = collect_runs(root, warn=warn)
    rows = aggregate(runs, load_published(published_path))
    md, table_csv = to_markdown(rows), to_csv(rows)
    out.mkdir(parents=True, exist_ok=True)
    with atomic_open(out / "leaderboard.md", "w") as fh:
        fh.write(md)
    with atomic_open(out / "leaderboard.csv", "w") as fh:
        fh.write(table_csv)
    curves = plot_curves(rows, out / "curves") if plots else []
    return {"rows": rows, "markdown": md, "csv": table_csv, "curves": curves, "n_runs": len(runs)}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m loco_il.evaluation.leaderboard",
                                 description=__doc__.split("\n")[0],
                                 epilog="Writes leaderboard.md, leaderboard.csv and curves/*.png.")
    ap.add_argument("root", help="folder searched (recursively) for the runs' eval.json, e.g. results/")
    ap.add_argument("--out", default=None, help="output folder (default: root)")
    ap.add_argument("--no-plots", action="store_true", help="skip the learning-curve PNGs")
    ap.add_argument("--published", default=None, help="a published-scores YAML instead of the shipped one")
    args = ap.parse_args(argv)
    if not Path(args.root).is_dir():
        print(f"error: {args.root} is not a folder", file=sys.stderr)
        return 2
    res = build(args.root, args.out, plots=not args.no_plots, published_path=args.published,
                warn=lambda m: print(f"warning: {m}", file=sys.stderr))
    if res["n_runs"] == 0:
        print(f"error: no eval.json below {args.root} (train with `python train.py ...` first)", file=sys.stderr)
        return 1
    print(res["markdown"])
    out = Path(args.out) if args.out else Path(args.root)
    print(f"wrote {out / 'leaderboard.md'}, {out / 'leaderboard.csv'}"
          + (f" and {len(res['curves'])} learning-curve PNG(s) in {out / 'curves'}" if res["curves"] else ""))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
