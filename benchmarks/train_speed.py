"""Env steps per second of whole `train.py` runs (env stepping, acting and updates together), by torch device
and by how many runs share the machine.

Each group of runs starts as `train.py` subprocesses side by side (one CPU thread each), trains for
`--seconds`, is stopped with SIGTERM (each run checkpoints and exits), and is read back from the runs'
`log.csv`: the `steps_per_s` of every evaluation interval (evaluation time excluded) after the first one that
ran updates. Prints the median per run, and per group the sum over its concurrent runs. Groups run one after
the other; a group `cpu:1,cuda:1` runs one CPU and one CUDA run at the same time, so the CUDA figure has its
CPU baseline from the same machine and minutes.

    python benchmarks/train_speed.py [--task Hopper.run.perfect] [--algo lsiq] [--seconds 90] [--every 1000]
                                     [--groups cpu:1,cuda:1 cuda:8] [--results DIR] [-- train.py overrides ...]

The overrides default to `dataset.n_episodes=12 algo.params.initial_replay_size=1000` (a small dataset and an
early first update: the speed depends on neither). Runs are written under `--results` (a temporary folder by
default) and are not resumed: every invocation starts fresh.
"""
from __future__ import annotations

import argparse
import csv
import os
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_OVERRIDES = ["dataset.n_episodes=12", "algo.params.initial_replay_size=1000"]


def parse_group(text: str) -> list[tuple[str, int]]:
    """'cpu:1,cuda:2' -> [('cpu', 1), ('cuda', 2)]."""
    group = []
    for part in text.split(","):
        device, _, count = part.partition(":")
        if not device or not count.isdigit() or int(count) < 1:
            raise argparse.ArgumentTypeError(f"group {text!r}: expected DEVICE:COUNT[,DEVICE:COUNT...], e.g. cpu:1,cuda:1")
        group.append((device, int(count)))
    return group


def train_command(args, device: str, seed: int, name: str, results: Path, n_steps: int = 10**8) -> list[str]:
    """A run that trains until it is stopped (n_steps far beyond --seconds), evaluated every --every steps."""
    return [sys.executable, "train.py", f"task={args.task}", f"algo={args.algo}", f"device={device}", f"seed={seed}",
            f"n_steps={n_steps}", "eval=quick", f"eval.every={args.every}", "checkpoint_every=100000000",
            "logger=csv", "hydra/job_logging=disabled", f"results_dir={results}", f"name={name}", *args.overrides]


def interval_rates(log_csv: Path) -> list[float]:
    """steps_per_s of the evaluation intervals after the first interval that ran updates."""
    if not log_csv.is_file():
        return []
    with open(log_csv, newline="") as fh:
        rows = list(csv.DictReader(fh))
    rates = []
    for prev, row in zip(rows, rows[1:]):
        if float(prev.get("updates") or 1) > 0:
            rates.append(float(row["steps_per_s"]))
    return rates


def run_group(args, group: list[tuple[str, int]], label: str, results: Path, env: dict) -> list[tuple[str, float]]:
    procs = []
    seed = 0  # one seed per run of the group (the run folder is <name>/seed<seed>)
    for device, count in group:
        for _ in range(count):
            name = f"{label}_{device}_{seed}"
            log = open(results / f"{name}.out", "w")
            proc = subprocess.Popen(train_command(args, device, seed, name, results), cwd=ROOT, env=env, stdout=log,
                                    stderr=subprocess.STDOUT)
            procs.append((device, name, seed, proc, log))
            seed += 1
    time.sleep(args.seconds)
    for _, _, _, proc, _ in procs:
        if proc.poll() is None:
            proc.send_signal(signal.SIGTERM)
    out = []
    for device, name, seed, proc, log in procs:
        try:
            proc.wait(timeout=120)
        except subprocess.TimeoutExpired:
            proc.kill()
        log.close()
        rates = interval_rates(results / args.task / name / f"seed{seed}" / "log.csv")
        if not rates:
            tail = (results / f"{name}.out").read_text()[-1500:]
            raise RuntimeError(f"run {name} logged no interval with updates in {args.seconds} s; its output ends:\n{tail}")
        out.append((device, statistics.median(rates)))
        print(f"  {name:<22} device {device:<6} {statistics.median(rates):8.1f} env steps/s "
              f"(median of {len(rates)} intervals of {args.every} steps)", flush=True)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--task", default="Hopper.run.perfect")
    parser.add_argument("--algo", default="lsiq")
    parser.add_argument("--seconds", type=float, default=90.0, help="training time of each group")
    parser.add_argument("--every", type=int, default=1000, help="env steps per evaluation interval")
    parser.add_argument("--groups", nargs="+", type=parse_group, default=[parse_group("cpu:1,cuda:1")])
    parser.add_argument("--results", type=Path, default=None, help="run folder (default: a temporary one)")
    parser.add_argument("overrides", nargs="*", default=DEFAULT_OVERRIDES, help="train.py overrides, after --")
    args = parser.parse_args()
    results = args.results or Path(tempfile.mkdtemp(prefix="train_speed_"))
    results.mkdir(parents=True, exist_ok=True)
    env = dict(os.environ, OMP_NUM_THREADS="1", PYTHONUNBUFFERED="1", WANDB_MODE="offline")
    print(f"task {args.task}, algo {args.algo}, {args.seconds:.0f} s per group, overrides {' '.join(args.overrides)}, "
          f"{os.cpu_count()} CPU cores; runs in {results}", flush=True)
    # one short run first (on the first group's device, which the overrides may need), so that the dataset is
    # generated and cached before the timed groups start
    warm = subprocess.run(train_command(args, args.groups[0][0][0], 0, "warmup", results, n_steps=args.every),
                          cwd=ROOT, env=env, capture_output=True, text=True)
    if warm.returncode != 0:
        raise SystemExit(f"warm-up run failed:\n{warm.stdout[-2000:]}\n{warm.stderr[-2000:]}")
    summary = []
    for i, group in enumerate(args.groups):
        label = "+".join(f"{d}x{n}" for d, n in group)
        print(f"\n## group {i + 1}: {label}", flush=True)
        for device, rate in run_group(args, group, f"g{i + 1}", results, env):
            summary.append((label, device, rate))
    print(f"\n{'group':<18}{'device':<8}{'runs':>5}{'median steps/s':>16}{'sum steps/s':>13}")
    for label in dict.fromkeys(s[0] for s in summary):
        for device in dict.fromkeys(s[1] for s in summary if s[0] == label):
            rates = [r for g, d, r in summary if g == label and d == device]
            print(f"{label:<18}{device:<8}{len(rates):>5}{statistics.median(rates):>16.1f}{sum(rates):>13.1f}")


if __name__ == "__main__":
    main()
