"""`python -m loco_il.benchmark {run,table,cost,prune} <protocol> ...`: the leaderboard protocols' command line.

    python -m loco_il.benchmark run small --dry-run                 # what would run, as train.py commands
    python -m loco_il.benchmark run small --parts real --algos gail hydra/launcher=joblib hydra.launcher.n_jobs=2
    python -m loco_il.benchmark table small                         # benchmarks/leaderboard/small.md, .csv, curves
    python -m loco_il.benchmark table small --readme README.md      # ... and the README's overview table
    python -m loco_il.benchmark cost small                          # estimated single-core hours per part
    python -m loco_il.benchmark prune small                         # delete finished runs' checkpoints
"""
from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path
from typing import Any, Sequence

from loco_il.benchmark import availability, commands, cost, launch, paths, status
from loco_il.benchmark.cells import Cell, Selection, select
from loco_il.benchmark.protocol import Protocol, ProtocolError, load_protocol

#: files of a run dir that only resuming needs (`prune` deletes them once the run has finished)
CHECKPOINT_FILES = ("checkpoint.pt", "checkpoint.prev.pt", "checkpoint.pt.damaged", "checkpoint.json")


def _selection_args(ap: argparse.ArgumentParser) -> None:
    ap.add_argument("--parts", nargs="+", default=[], metavar="PART", help="only these parts of the protocol")
    ap.add_argument("--tasks", nargs="+", default=[], metavar="TASK",
                    help="only these tasks (Atlas.walk: every dataset type; Atlas.walk.real: one)")
    ap.add_argument("--algos", nargs="+", default=[], metavar="ALGO",
                    help="only these row labels, or algorithms (lsiq: every row that runs LS-IQ)")
    ap.add_argument("--datasets", nargs="+", default=[], metavar="TYPE", help="only these dataset types")
    ap.add_argument("--seeds", nargs="+", type=int, default=[], metavar="SEED", help="only these seeds")


def _selection(args: argparse.Namespace) -> Selection:
    return Selection(tuple(args.parts), tuple(args.tasks), tuple(args.algos), tuple(args.datasets),
                     tuple(args.seeds))


def parsers() -> dict[str, argparse.ArgumentParser]:
    """One parser per sub-command (train.py overrides, the arguments with "=", are split off before parsing)."""
    prog = "python -m loco_il.benchmark"
    run = argparse.ArgumentParser(prog=f"{prog} run", description="Run or resume every missing run of a protocol "
                                  "through train.py -m (Hydra multirun); finished runs are skipped.",
                                  epilog="Any KEY=VALUE argument goes to every train.py sweep, e.g. "
                                         "hydra/launcher=joblib hydra.launcher.n_jobs=2.")
    run.add_argument("protocol", help="a name in experiment_configs/benchmark/ (small, paper) or a YAML path")
    _selection_args(run)
    run.add_argument("--dry-run", action="store_true", help="print the train.py commands, run nothing")
    run.add_argument("--results-dir", default=None, help="run dirs elsewhere than the protocol's")
    table = argparse.ArgumentParser(prog=f"{prog} table", description="Write <out>/<protocol>.md and .csv and "
                                    "the learning curves from the protocol's run dirs.")
    table.add_argument("protocol")
    table.add_argument("--results-dir", default=None, help="run dirs elsewhere than the protocol's")
    table.add_argument("--out", default=None, help=f"output folder (default {paths.relative(paths.TABLE_DIR)})")
    table.add_argument("--no-plots", action="store_true", help="skip the learning-curve figures")
    table.add_argument("--readme", default=None, metavar="PATH",
                       help="also write the overview table into PATH between its '<!-- leaderboard:<protocol> -->' "
                            "and '<!-- /leaderboard:<protocol> -->' lines (e.g. README.md)")
    est = argparse.ArgumentParser(prog=f"{prog} cost", description="Estimated single-core hours per part, from "
                                  "the costs measured in benchmarks/RESULTS.md.")
    est.add_argument("protocol")
    _selection_args(est)
    est.add_argument("--jobs", type=int, default=2, help="runs at a time, for the wall-clock line (default 2)")
    prune = argparse.ArgumentParser(prog=f"{prog} prune", description="Delete the checkpoints (with their replay "
                                    "memories) of finished runs; eval.json, log.csv, config.yaml and "
                                    "final_agent.pt stay.")
    prune.add_argument("protocol")
    prune.add_argument("--results-dir", default=None)
    prune.add_argument("--dry-run", action="store_true", help="list what would be deleted")
    return {"run": run, "table": table, "cost": est, "prune": prune}


# ----------------------------------------------------------------------------- commands
def _hours_per_run(proto: Protocol, lch: commands.Launch) -> float:
    """Estimated hours of a sweep's average run: cheap sweeps go first, so that every learner has results early."""
    try:
        return sum(cost.run_hours(proto, c) for c in lch.cells) / max(len(lch.cells), 1)
    except cost.CostError:
        return float("inf")


def cmd_run(args: argparse.Namespace, echo=print) -> int:
    proto = load_protocol(args.protocol)
    cells = select(proto, _selection(args))
    results_dir = Path(args.results_dir) if args.results_dir else proto.results_dir
    runs = status.states(cells, results_dir)
    counts = {name: sum(r.state == name for r in runs)
              for name in (status.FINISHED, status.RUNNING, status.UNFINISHED, status.NEW, status.OVER)}
    blocked = {c.key: availability.blocked_reason(c.task_id) for c in cells}
    todo = [(r.cell, r.seed) for r in runs
            if r.state in (status.UNFINISHED, status.NEW) and not blocked[r.cell.key]]
    n_blocked = sum(1 for r in runs if r.state != status.FINISHED and blocked[r.cell.key])
    echo(f"[benchmark] {proto.name}: {len(cells)} cells, {len(runs)} runs in {paths.relative(results_dir)}: "
         + ", ".join(f"{n} {name}" for name, n in counts.items() if n) + f"; {len(todo)} to run"
         + (f", {n_blocked} blocked" if n_blocked else ""))
    for reason in sorted({b for b in blocked.values() if b}):
        tasks = sorted({c.task_id for c in cells if blocked[c.key] == reason})
        echo(f"[benchmark] skipped {', '.join(tasks)}: {reason}")
    for r in runs:
        if r.state in (status.OVER, status.RUNNING):
            echo(f"[benchmark] skipped {r.cell.key} {r.describe()}")
        elif r.state == status.UNFINISHED:
            echo(f"[benchmark] resumes {r.cell.key} {r.describe()}")
    changed = [o for o in args.overrides if launch.changes_results(o)]
    if changed:
        echo(f"[benchmark] note: {' '.join(changed)} changes the runs' settings beyond the protocol; the table's "
             f"commands will not reproduce them")
    launches = sorted(commands.plan(proto, todo, results_dir), key=lambda lch: _hours_per_run(proto, lch))
    if args.dry_run:
        for lch in launches:
            echo(lch.display(args.overrides))
        return 0
    if not launches:
        echo("[benchmark] nothing to run")
        return 0
    return launch.execute(launches, args.overrides, env=dict(os.environ), echo=echo)


def table_page(proto: Protocol, cells: Sequence[Cell], results: Sequence[Any], figures: dict[str, str],
               results_dir: Path, headline: Sequence[str]) -> str:
    """The protocol's leaderboard page (`<protocol>.md`): its tables, `figures` (task -> path of its learning-curve
    figure, relative to the page), the overview `headline` and the cost estimate."""
    from loco_il.benchmark import table
    return table.markdown(proto, results, cost.summary_text(proto, cells), figures, results_dir, overview=headline)


def cmd_table(args: argparse.Namespace, echo=print) -> int:
    from loco_il.benchmark import curves, doc_block, overview, table
    from loco_il.utils.atomic import atomic_open
    proto = load_protocol(args.protocol)
    cells = select(proto)
    results_dir = Path(args.results_dir) if args.results_dir else proto.results_dir
    results = table.results_of(proto, cells, results_dir)
    out = Path(args.out) if args.out else paths.TABLE_DIR
    figures: dict[str, str] = {}
    if not args.no_plots:
        folder = out / "curves" / proto.name
        figures = {t: str(p.relative_to(out)) for t, p in curves.plot_all(results, table.report_steps(proto),
                                                                           folder).items()}
    headline = overview.matrix(proto, results)
    readme_text = None
    if args.readme:     # checked before anything is written: a README without markers leaves every file as it was
        readme = Path(args.readme)
        if not readme.is_file():
            echo(f"[benchmark] error: --readme {readme}: no such file; give the README path, e.g. --readme README.md")
            return 2
        try:
            readme_text = overview.replace_block(readme.read_text(), proto.name, headline, where=str(readme))
        except doc_block.MarkerError as err:
            echo(f"[benchmark] error: {err}")
            return 2
    md = table_page(proto, cells, results, figures, results_dir, headline)
    out.mkdir(parents=True, exist_ok=True)
    for suffix, text in ((".md", md), (".csv", table.to_csv(proto, results))):
        with atomic_open(out / f"{proto.name}{suffix}", "w") as fh:
            fh.write(text)
    if readme_text is not None:
        with atomic_open(args.readme, "w") as fh:
            fh.write(readme_text)
        echo(f"[benchmark] wrote the overview table into {args.readme}")
    done = sum(1 for r in results if r.runs)
    missing = sum(len(r.missing) for r in results)
    echo(f"[benchmark] wrote {out / proto.name}.md and .csv: {done} of {len(results)} cells with finished runs, "
         f"{missing} runs missing" + (f"; {len(figures)} figure(s) in {out / 'curves' / proto.name}" if figures
                                      else ""))
    return 0


def cmd_cost(args: argparse.Namespace, echo=print) -> int:
    proto = load_protocol(args.protocol)
    echo(cost.summary_text(proto, select(proto, _selection(args)), args.jobs))
    return 0


def cmd_prune(args: argparse.Namespace, echo=print) -> int:
    proto = load_protocol(args.protocol, check_tasks=False)
    results_dir = Path(args.results_dir) if args.results_dir else proto.results_dir
    freed, n_runs = 0, 0
    for r in status.states(select(proto), results_dir):
        files = [r.run_dir / name for name in CHECKPOINT_FILES if (r.run_dir / name).is_file()]
        if r.state != status.FINISHED or not files:
            continue
        n_runs += 1
        for f in files:
            freed += f.stat().st_size
            if not args.dry_run:
                f.unlink()
    verb = "would free" if args.dry_run else "freed"
    echo(f"[benchmark] {verb} {freed / 2**20:.0f} MiB of checkpoints in {n_runs} finished run(s) "
         f"(eval.json, log.csv, config.yaml and final_agent.pt stay)")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    handlers = {"run": cmd_run, "table": cmd_table, "cost": cmd_cost, "prune": cmd_prune}
    if not argv or argv[0] not in handlers:
        asked = bool(argv) and argv[0] in ("-h", "--help")
        print(__doc__, file=sys.stdout if asked else sys.stderr)
        return 0 if asked else 2
    command, rest = argv[0], argv[1:]
    overrides = [a for a in rest if "=" in a and not a.startswith("-")]
    if overrides and command != "run":
        print(f"error: {command} takes no train.py overrides ({overrides[0]})", file=sys.stderr)
        return 2
    args = parsers()[command].parse_args([a for a in rest if a not in overrides])
    args.overrides = overrides
    handler = handlers[command]
    try:
        return handler(args)
    except (ProtocolError, cost.CostError, FileNotFoundError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    raise SystemExit(main())
