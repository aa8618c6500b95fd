"""Where long runs stand: `python -m loco_il.evaluation.progress runs/`.

The leaderboard only counts finished runs (those with an `eval.json`). Runs at the papers' budgets take
days on a small machine and are stopped and resumed many times (from `checkpoint.pt`), so this prints one row per run dir
below the folder, finished or not: its budget, the last evaluation logged in `log.csv` (step, return,
normalized score), the training speed of the last interval and, for unfinished runs, the wall time the
rest of the budget needs at that speed, and the step a re-run resumes from (its last checkpoint, from the
small `checkpoint.json` beside it: after a kill, evaluations logged past it are cut from the log and run
again). It reads only `config.yaml`, `log.csv` and `checkpoint.json`, so it is instant and safe to run while
the runs are training. `--curves` adds each run's learning curve, the
normalized score at every evaluation (`25k:0.33 50k:0.40 ...`), since run dirs are often not kept as long as
the numbers are needed. `--stability 0.9` adds, per run, whether it stays at the expert once it got there:
the first evaluation scoring >= 0.9 and, over the evaluations after it, the share that also do, their
minimum and their mean, and, for logs that record `eval_terminated`, how many of the evaluations after it
that score below the threshold had an episode end in a terminal state (a fall) and how many episodes did.
A run that never gets there is given its best score and where. Runs trained with `algo.params.actor_ema`
get a second line for each, the moving average of the actor (`normalized_score_ema`), marked "actor average".
`--upto STEP` keeps only the evaluations at or before STEP in the curves and the stability lines, so that runs
of different lengths (two settings, or a seed stopped early) are compared over the same env steps. `--every
STEP` keeps only the evaluations at multiples of STEP, so that a run evaluated every 5k is read on the grid of one
evaluated every 25k (counts of evaluations from different grids are not comparable: a coarse grid misses dips).
With `--stability`, each task and algorithm run with several seeds also gets one line over its seeds: how many
reached the threshold and where, the evaluations after the first one at it that score at or above it again,
pooled over the seeds ("held"), and the same over the last 50k env steps of each seed.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any, Callable

from loco_il.experiment.checkpoint import read_checkpoint_summary
from loco_il.utils.fileio import read_csv

HEADER = ("task", "algorithm", "seed", "last eval step", "budget", "done %", "return", "normalized",
          "steps/s", "rest (h)", "resumes from", "state")


def run_progress(run_dir: str | Path) -> dict[str, Any] | None:
    """One run dir's progress, or None when the folder is not a `train.py` run dir."""
    import yaml
    run_dir = Path(run_dir)
    cfg_path = run_dir / "config.yaml"
    if not cfg_path.is_file():
        return None
    cfg = yaml.safe_load(cfg_path.read_text()) or {}
    rows = read_csv(run_dir / "log.csv")
    last = rows[-1] if rows else {}
    budget = int(cfg.get("n_steps") or 0)
    step = int(last.get("step") or 0)
    speed = last.get("steps_per_s")
    finished = (run_dir / "eval.json").is_file()
    rest_h = None if finished or not speed else max(budget - step, 0) / speed / 3600.0
    ckpt = read_checkpoint_summary(run_dir)
    curve = [(int(r["step"]), r.get("normalized_score")) for r in rows if r.get("step") is not None]
    curve_ema = [(int(r["step"]), r.get("normalized_score_ema")) for r in rows if r.get("step") is not None]
    falls = {int(r["step"]): (int(r["eval_terminated"]), int(r.get("eval_episodes") or 0)) for r in rows
             if r.get("step") is not None and r.get("eval_terminated") is not None}
    return {"run_dir": str(run_dir), "task": cfg.get("task_id", "?"), "algorithm": cfg.get("name", "?"),
            "seed": cfg.get("seed"), "step": step, "budget": budget,
            "done": step / budget if budget else None, "return": last.get("eval_return_mean"),
            "normalized": last.get("normalized_score"), "steps_per_s": speed, "rest_hours": rest_h,
            "resume_step": None if finished or ckpt is None else ckpt["step"],
            "state": "finished" if finished else ("no evaluation yet" if not rows else "unfinished"),
            "curve": curve, "curve_ema": curve_ema if any(x is not None for _, x in curve_ema) else None,
            "terminated": falls}


def collect_progress(root: str | Path) -> list[dict[str, Any]]:
    """Every run dir below `root` (a folder holding `config.yaml`), sorted by task, algorithm, seed.

    Hidden folders are skipped: Hydra keeps its own unresolved copy of the config in `<run dir>/.hydra/`.
    """
    root = Path(root)
    found = (run_progress(p.parent) for p in root.rglob("config.yaml")
             if not any(part.startswith(".") for part in p.relative_to(root).parts))
    rows = [r for r in found if r is not None]
    return sorted(rows, key=lambda r: (r["task"], str(r["algorithm"]), str(r["seed"])))


def _cell(x: Any, fmt: str) -> str:
    return "n/a" if x is None else format(x, fmt)


def to_markdown(rows: list[dict[str, Any]]) -> str:
    lines = ["| " + " | ".join(HEADER) + " |", "|" + "|".join("---" for _ in HEADER) + "|"]
    for r in rows:
        cells = [r["task"], str(r["algorithm"]), str(r["seed"]), str(r["step"]), str(r["budget"]),
                 _cell(None if r["done"] is None else 100 * r["done"], ".1f"), _cell(r["return"], ".1f"),
                 _cell(r["normalized"], ".3f"), _cell(r["steps_per_s"], ".1f"), _cell(r["rest_hours"], ".1f"),
                 _cell(r["resume_step"], "d"), r["state"]]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def _head(row: dict[str, Any], key: str) -> str:
    return f"{row['task']} {row['algorithm']} seed {row['seed']}" + (" (actor average)" if key == "curve_ema" else "")


def format_curve(row: dict[str, Any], key: str = "curve") -> str:
    """`task algorithm seed s: 25k:0.33 50k:0.40 ...` (steps in thousands; n/a where no score was logged);
    key="curve_ema": the actor average's scores."""
    points = " ".join(f"{step / 1000:g}k:{_cell(score, '.2f')}" for step, score in row[key])
    return f"{_head(row, key)}: {points or 'no evaluation yet'}"


def stability(curve: list[tuple[int, float | None]], threshold: float,
              terminated: dict[int, tuple[int, int]] | None = None) -> dict[str, Any]:
    """Does a run stay at the expert once it reached it? `reached`: the first step scoring >= threshold (None if
    never); over the evaluations after it (`n_after`): how many also score >= threshold (`n_held`) and their
    share, their min and mean; `best` and `best_step`: the highest score and the first step it was logged.
    `terminated` ({step: (episodes that ended in a terminal state, episodes)}, from the log) adds, over the
    evaluations after `reached` that score below threshold (`n_dips`) and have that record (`n_dips_logged`):
    how many had at least one such episode (`n_dips_with_fall`), and those episodes against all of theirs;
    the same over all scored evaluations with that record: `n_logged`, `n_with_fall`, `episodes_fell`, `episodes`.
    Evaluations without a score are left out."""
    terminated = terminated or {}
    scored = [(step, score) for step, score in curve if score is not None]
    first = next((i for i, (_, score) in enumerate(scored) if score >= threshold), None)
    after = [] if first is None else scored[first + 1:]
    scores = [score for _, score in after]
    held = sum(x >= threshold for x in scores)
    dips = [step for step, score in after if score < threshold]
    logged = [terminated[step] for step in dips if step in terminated]
    logged_all = [terminated[step] for step, _ in scored if step in terminated]
    best = max(scored, key=lambda point: point[1], default=(None, None))
    return {"reached": None if first is None else scored[first][0], "best": best[1], "best_step": best[0],
            "n_after": len(after), "n_held": held,
            "share_after": held / len(after) if after else None,
            "min_after": min(scores) if scores else None,
            "mean_after": sum(scores) / len(scores) if scores else None,
            "n_dips": len(dips), "n_dips_logged": len(logged), "n_dips_with_fall": sum(n > 0 for n, _ in logged),
            "dip_episodes_fell": sum(n for n, _ in logged), "dip_episodes": sum(m for _, m in logged),
            "n_logged": len(logged_all), "n_with_fall": sum(n > 0 for n, _ in logged_all),
            "episodes_fell": sum(n for n, _ in logged_all), "episodes": sum(m for _, m in logged_all)}


def format_stability(row: dict[str, Any], threshold: float, key: str = "curve") -> str:
    # the actor average is evaluated on other episodes, whose terminal states the log does not count
    st = stability(row[key], threshold, row.get("terminated") if key == "curve" else None)
    head = _head(row, key) + ":"
    if st["reached"] is None:
        best = "" if st["best"] is None else f" (best {st['best']:.3f} at {st['best_step'] / 1000:g}k)"
        falls = "" if not st["n_logged"] else (f"; {st['n_with_fall']} of its {st['n_logged']} evaluations had an "
                                                 f"episode end in a fall ({st['episodes_fell']} of {st['episodes']} "
                                                 "episodes)")
        return f"{head} never >= {threshold:g}{best}{falls}"
    line = (f"{head} >= {threshold:g} first at {st['reached'] / 1000:g}k; after it {st['n_after']} evaluations, "
            f"{_cell(None if st['share_after'] is None else 100 * st['share_after'], '.0f')} % >= {threshold:g}, "
            f"min {_cell(st['min_after'], '.3f')}, mean {_cell(st['mean_after'], '.2f')}")
    if st["n_dips_logged"]:
        unlogged = st["n_dips"] - st["n_dips_logged"]
        line += (f"; of the {st['n_dips_logged']} below it" + (f" with a logged count ({unlogged} without)"
                                                             if unlogged else "")
                 + f", {st['n_dips_with_fall']} had an episode end in a fall "
                   f"({st['dip_episodes_fell']} of {st['dip_episodes']} episodes)")
    return line


#: env steps at the end of each seed that `summarize_seeds` scores apart (the README's "last 50k" column)
LAST_WINDOW = 50_000


def summarize_seeds(rows: list[dict[str, Any]], threshold: float,
                    last_window: int = LAST_WINDOW) -> dict[str, Any]:
    """One setting (task and algorithm) over its seeds' rows: `n_seeds`, the range of their last scored steps
    (`last_steps`), the steps where each reached the threshold first (`reached`, sorted; seeds that never did
    are left out), the evaluations after those (`n_after`) and how many score >= threshold (`n_held`), pooled
    over the seeds, and over each seed's evaluations in its last `last_window` env steps (those after
    last step - last_window): `n_last`, `n_last_held`; `best` is the best score of any seed."""
    per_seed = [stability(row["curve"], threshold) for row in rows]
    scored = [[(step, x) for step, x in row["curve"] if x is not None] for row in rows]
    ends = [curve[-1][0] for curve in scored if curve]
    last = [x for curve in scored if curve for step, x in curve if step > curve[-1][0] - last_window]
    return {"n_seeds": len(rows), "last_steps": (min(ends), max(ends)) if ends else None,
            "reached": sorted(st["reached"] for st in per_seed if st["reached"] is not None),
            "n_after": sum(st["n_after"] for st in per_seed), "n_held": sum(st["n_held"] for st in per_seed),
            "n_last": len(last), "n_last_held": sum(x >= threshold for x in last),
            "best": max((st["best"] for st in per_seed if st["best"] is not None), default=None)}


def _k_range(lo: int, hi: int) -> str:
    return f"{lo / 1000:g}k" if lo == hi else f"{lo / 1000:g}k-{hi / 1000:g}k"


def format_seeds_summary(rows: list[dict[str, Any]], threshold: float, last_window: int = LAST_WINDOW) -> str:
    """`task algorithm, 4 seeds to 300k: 4 reached >= 0.9 (first at 65k-115k); held 148/172 (86 %); last 50k
    of each: 38/40 >= 0.9`."""
    head = f"{rows[0]['task']} {rows[0]['algorithm']}"
    # a run dir copied elsewhere below the root (runs/ and its committed logs) would otherwise count twice
    seeds = [str(row["seed"]) for row in rows]
    repeated = sorted({seed for seed in seeds if seeds.count(seed) > 1})
    if repeated:
        dirs = ", ".join(row["run_dir"] for row in rows if str(row["seed"]) in repeated)
        which = f"seed {repeated[0]} is" if len(repeated) == 1 else f"seeds {', '.join(repeated)} are"
        return (f"{head}: not pooled, {which} in several run dirs ({dirs}); "
                "point progress at a folder holding one copy of each")
    sm = summarize_seeds(rows, threshold, last_window)
    head += f", {sm['n_seeds']} seeds"
    if sm["last_steps"] is None:
        return f"{head}: no evaluation yet"
    head += f" to {_k_range(*sm['last_steps'])}: "
    if not sm["reached"]:
        return head + f"none reached >= {threshold:g} (best {sm['best']:.3f})"
    held = "" if not sm["n_after"] else f" ({100 * sm['n_held'] / sm['n_after']:.0f} %)"
    first = _k_range(sm["reached"][0], sm["reached"][-1])
    return (head + f"{len(sm['reached'])} reached >= {threshold:g} (first at {first}); "
            f"held {sm['n_held']}/{sm['n_after']}{held}; last {last_window / 1000:g}k of each: "
            f"{sm['n_last_held']}/{sm['n_last']} >= {threshold:g}")


def keep_evaluations(row: dict[str, Any], keep: Callable[[int], bool]) -> dict[str, Any]:
    """The row with its curves (and fall counts) cut to the evaluations whose step `keep` accepts."""
    cut = dict(row)
    for key in ("curve", "curve_ema"):
        if row.get(key) is not None:
            cut[key] = [(s, x) for s, x in row[key] if keep(s)]
    cut["terminated"] = {s: n for s, n in row.get("terminated", {}).items() if keep(s)}
    return cut


def upto(row: dict[str, Any], step: int) -> dict[str, Any]:
    """The row with its curves (and fall counts) cut to the evaluations at or before `step`."""
    return keep_evaluations(row, lambda s: s <= step)


def on_grid(row: dict[str, Any], every: int) -> dict[str, Any]:
    """The row with only the evaluations at multiples of `every` env steps."""
    return keep_evaluations(row, lambda s: s % every == 0)


def _selection_note(upto_step: int | None, every: int | None) -> str:
    """Which evaluations the curves and stability lines use, for their headings ("" for all)."""
    parts = ([] if every is None else [f"every {every / 1000:g}k"]) + \
        ([] if upto_step is None else [f"up to {upto_step / 1000:g}k"])
    return "" if not parts else "evaluations " + " ".join(parts)


def _curve_keys(row: dict[str, Any]) -> tuple[str, ...]:
    return ("curve", "curve_ema") if row.get("curve_ema") else ("curve",)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m loco_il.evaluation.progress",
                                     description=__doc__.splitlines()[0])
    parser.add_argument("root", help="folder searched (recursively) for train.py run dirs, e.g. runs/")
    parser.add_argument("--curves", action="store_true",
                        help="also print each run's normalized score at every evaluation")
    parser.add_argument("--stability", type=float, metavar="SCORE",
                        help="also print whether each run stays at or above this normalized score once reached")
    parser.add_argument("--upto", type=int, metavar="STEP",
                        help="curves and stability over the evaluations at or before this env step only")
    parser.add_argument("--every", type=int, metavar="STEP",
                        help="curves and stability over the evaluations at multiples of this env step only")
    args = parser.parse_args(argv)
    if args.every is not None and args.every <= 0:
        parser.error(f"--every must be a positive number of env steps, got {args.every}")
    if not Path(args.root).is_dir():
        print(f"error: {args.root} is not a folder", file=sys.stderr)
        return 2
    rows = collect_progress(args.root)
    if not rows:
        print(f"no train.py run dirs (folders with config.yaml) below {args.root}", file=sys.stderr)
        return 1
    print(to_markdown(rows))
    print("\n'rest (h)': the rest of the budget at the last interval's speed. 'resumes from': the step of the "
          "run's last checkpoint, where re-running its command continues (evaluations logged after it are run "
          "again); n/a for finished runs and runs without checkpoint.json.")
    if args.upto is not None:
        rows = [upto(row, args.upto) for row in rows]
    if args.every is not None:
        rows = [on_grid(row, args.every) for row in rows]
    selection = _selection_note(args.upto, args.every)
    selection_note = f" ({selection})" if selection else ""
    if args.curves:
        print(f"\nnormalized score at each evaluation{selection_note}:")
        for row in rows:
            for key in _curve_keys(row):
                print(format_curve(row, key))
    if args.stability is not None:
        print(f"\nonce at >= {args.stability:g}, does it stay?{selection_note}")
        for row in rows:
            for key in _curve_keys(row):
                print(format_stability(row, args.stability, key))
        settings: dict[tuple[str, str], list[dict[str, Any]]] = {}
        for row in rows:
            settings.setdefault((row["task"], str(row["algorithm"])), []).append(row)
        several = [group for group in settings.values() if len(group) > 1]
        if several:
            cut = f"{selection}; " if selection else ""
            print(f"\nover the seeds of each setting ({cut}held: the evaluations after each seed's first "
                  f">= {args.stability:g}, pooled):")
            for group in several:
                print(format_seeds_summary(group, args.stability))
    return 0


if __name__ == "__main__":
    sys.exit(main())
