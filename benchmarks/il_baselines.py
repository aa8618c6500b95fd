"""Imitation-learning baselines (default task Hopper.run): every algorithm, a fixed env-step budget, several seeds.

For each (algorithm, dataset, seed) the agent is built from `experiment_configs/algo/<algo>.yaml`
(`--set key=value` overrides constructor parameters, e.g. for small budgets), given the expert data
and trained with mushroom-rl's `Core.learn` (BC: `pretrain` gradient steps, no env steps). Every
`--eval-every` env steps (BC: gradient steps) the deterministic policy is evaluated on `--eval-episodes`
episodes of a separate, seeded env, and one CSV row is appended to `--out` at once:

    algo,dataset,seed,env_steps,updates,wall_s,return_mean,return_std,normalized_score,norm_ref,run_id

Datasets (of `--task`, an `<Env>.<task>` id, default Hopper.run):
  perfect   the shipped expert's 100 episodes (`LocoEnv.make("<task>.perfect").create_dataset()`).
  noact     THE SAME episodes with the actions removed (`actions=None`): a stand-in for a state-only
            setting on bodies without motion data (Hopper). Only for the state-only learners
            (gail -> D(s), gaifo -> D(s, s'), lsiqfo -> inverse dynamics model).
  real      the task's `real` dataset (`<task>.real`: retargeted or generated motion, no actions,
            with embodiment mismatch), e.g. `--task UnitreeA1.simple`; only for the state-only learners.

normalized_score = (return - random) / (expert - random): `loco_il.datasets.baselines.normalized_score`
when baselines.yaml has both entries for the task; otherwise random = the measured random return of
baselines.yaml (or measured here if absent) and expert = the dataset's recorded mean return
(`info["expert_return_mean"]`). The reference used is printed and written in the `norm_ref` column.

Resumable: a run whose final row (env_steps == --steps, or updates == --steps for BC) is in the CSV is
skipped; an interrupted run restarts from scratch (its rows carry a new `run_id`, so partial rows of
the interrupted attempt can be told apart). Note: every `Core.learn` call between evaluations starts
a new episode, so an episode is cut at each evaluation point.

    python benchmarks/il_baselines.py --algos gail vail gaifo --seeds 0 1 --steps 50000 --eval-every 10240
    python benchmarks/il_baselines.py --task UnitreeA1.simple --algos gaifo --datasets real --seeds 0 --steps 300000
    python benchmarks/il_baselines.py --summarize a.csv b.csv --stability 0.9   # do runs stay at the expert?

`--set policy.hidden=[64,64]` sets the actor network's sizes (other `policy.*` keys alike).
"""
from __future__ import annotations

import argparse
import csv
import math
import os
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import torch
import yaml

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_TASK = "Hopper.run"
ALL_ALGOS = ["bc", "gail", "vail", "gaifo", "iqlearn", "lsiq", "lsiqfo", "sqil"]
STATE_ONLY = {"gail", "gaifo", "lsiqfo"}
STATE_ONLY_DATASETS = ("noact", "real")  # expert data without actions: only the STATE_ONLY learners
FIELDS = ["algo", "dataset", "seed", "env_steps", "updates", "wall_s", "return_mean", "return_std",
          "normalized_score", "norm_ref", "run_id"]


def load_cfg(algo: str) -> dict:
    with open(ROOT / "experiment_configs" / "algo" / f"{'lsiq' if algo == 'lsiqfo' else algo}.yaml") as fh:
        cfg = yaml.safe_load(fh)
    cfg["name"] = algo
    return cfg


def parse_value(text: str):
    """A --set value as YAML, with numbers such as 1e-3 as floats (YAML 1.1 reads them as strings)."""
    value = yaml.safe_load(text)
    if isinstance(value, str):
        try:
            return float(value)
        except ValueError:
            return value
    return value


def task_id(task: str, dataset: str) -> str:
    """The Task-ID whose env and dataset a run uses (noact: the perfect task's, actions dropped later)."""
    return f"{task}.{'real' if dataset == 'real' else 'perfect'}"


def expert_data(task: str, dataset: str):
    from loco_il import LocoEnv
    data = LocoEnv.make(task_id(task, dataset)).create_dataset(verbose=False)
    if dataset == "noact":
        fields = {k: getattr(data, k) for k in ("obs", "next_obs", "rewards", "absorbing", "last")}
        return SimpleNamespace(actions=None, info=dict(data.info), **fields), data
    return data, data


def evaluate(agent, env, n_episodes: int, seed: int) -> np.ndarray:
    """Deterministic returns of `n_episodes` episodes; episode i is reset with seed `seed + i`."""
    agent.deterministic = True
    returns = []
    try:
        for i in range(n_episodes):
            env.seed(seed + i)
            obs, ret = env.reset(), 0.0
            agent.episode_start()
            agent.next_action = None
            for _ in range(env.info.horizon):
                obs, r, absorbing, _ = env.step(agent.draw_action(obs))
                ret += r
                if absorbing:
                    break
            returns.append(ret)
    finally:
        agent.deterministic = False
    return np.asarray(returns)


def random_return(task: str, n_episodes: int = 10, seed: int = 0) -> float:
    from loco_il import LocoEnv
    env = LocoEnv.make(task)
    rng = np.random.default_rng(seed)
    rets = []
    for i in range(n_episodes):
        env.seed(seed + i)
        env.reset()
        ret = 0.0
        for _ in range(env.info.horizon):
            _, r, absorbing, _ = env.step(rng.uniform(-1, 1, env.info.action_space.shape))
            ret += r
            if absorbing:
                break
        rets.append(ret)
    return float(np.mean(rets))


def make_normalizer(task: str, data):
    """(function return -> normalized score, description of the reference)."""
    from loco_il.datasets import baselines as bl
    task = f"{task}.perfect"
    try:
        bl.normalized_score(task, 0.0)
        entry = bl.get_baseline(task)
        desc = (f"baselines.yaml (random {entry['random']['return_mean']:.1f}, "
                f"expert {entry['expert']['return_mean']:.1f})")
        return (lambda r: float(bl.normalized_score(task, r))), desc
    except (KeyError, TypeError):  # BaselineMissingError is a KeyError
        pass
    try:
        rnd = float(bl.get_baseline(task)["random"]["return_mean"])
        rnd_src = "baselines.yaml random"
    except (KeyError, TypeError):
        rnd = random_return(task)
        rnd_src = "random measured here (10 ep, seed 0)"
    exp = float(data.info.get("expert_return_mean") or np.mean(data.info["episode_returns"]))
    desc = f"{rnd_src} {rnd:.1f}; expert = dataset's recorded mean return {exp:.1f}"
    return (lambda r: (r - rnd) / (exp - rnd)), desc


def done_runs(path: Path) -> set[tuple[str, str, int]]:
    done = set()
    if path.is_file():
        with open(path) as fh:
            for row in csv.DictReader(fh):
                if row.get("final") == "1" or row.get("run_id", "").endswith("#final"):
                    done.add((row["algo"], row["dataset"], int(row["seed"])))
    return done


def run_one(algo: str, dataset: str, seed: int, args, writer, fh, norm, norm_desc) -> None:
    from loco_il import LocoEnv
    from mushroom_rl.core import Core
    from loco_il.algorithms.factory import build_agent, is_offline, steps_per_fit, get_algorithm

    torch.manual_seed(seed)
    np.random.seed(seed)
    cfg = load_cfg(algo)
    cfg.setdefault("params", {})
    for item in args.set:
        key, _, value = item.partition("=")
        target_algos, _, key = key.rpartition(":")
        if target_algos and algo not in target_algos.split(","):
            continue
        if key.startswith("policy."):        # the actor network, e.g. policy.hidden=[64,64]
            cfg.setdefault("policy", {})[key[len("policy."):]] = parse_value(value)
        elif key in _accepted(get_algorithm(algo)):
            cfg["params"][key] = parse_value(value)
    if algo == "gail" and dataset in STATE_ONLY_DATASETS:
        cfg["params"]["use_actions"] = None  # -> D(s)
    expert, _ = expert_data(args.task, dataset)
    env_id = task_id(args.task, dataset)
    env = LocoEnv.make(env_id, seed=seed)
    eval_env = LocoEnv.make(env_id)
    agent = build_agent(algo, env.info, cfg, seed=seed)
    agent.set_expert(expert)
    run_id = f"{time.strftime('%Y%m%dT%H%M%S')}-{os.getpid()}"
    cls = type(agent)
    offline = is_offline(cls, cfg)
    spf = 1 if offline else steps_per_fit(cfg)
    every = max(spf, int(math.ceil(args.eval_every / spf)) * spf)
    total = args.steps if offline else int(math.ceil(args.steps / spf)) * spf
    core = None if offline else Core(agent, env)
    start = time.perf_counter()
    done_steps = 0
    eval_time = 0.0

    def log(final: bool) -> None:
        nonlocal eval_time
        t0 = time.perf_counter()
        rets = evaluate(agent, eval_env, args.eval_episodes, 10_000)
        eval_time += time.perf_counter() - t0
        updates = getattr(agent, "n_updates", None)
        if updates is None:
            updates = getattr(agent, "n_fits", 0)
        row = {"algo": algo, "dataset": dataset, "seed": seed, "env_steps": 0 if offline else done_steps,
               "updates": done_steps if offline else updates,
               "wall_s": f"{time.perf_counter() - start - eval_time:.1f}",
               "return_mean": f"{rets.mean():.1f}", "return_std": f"{rets.std():.1f}",
               "normalized_score": f"{norm(float(rets.mean())):.3f}", "norm_ref": norm_desc,
               "run_id": run_id + ("#final" if final else "")}
        writer.writerow(row)
        fh.flush()
        print(",".join(str(row[k]) for k in FIELDS[:-2]), flush=True)

    log(False)  # the untrained policy
    while done_steps < total:
        n = min(every, total - done_steps)
        if offline:
            agent.pretrain(n)
        else:
            core.learn(n_steps=n, n_steps_per_fit=spf, quiet=True)
        done_steps += n
        log(done_steps >= total)


def _accepted(cls) -> set[str]:
    import inspect
    names = set()
    for klass in cls.__mro__:
        if "__init__" in vars(klass):
            names.update(inspect.signature(klass.__init__).parameters)
    return names


def summarize(paths) -> None:
    """Markdown table: per (algo, dataset) the last evaluation of each run (its last row), mean over seeds,
    and the mean normalized score of each run's last three evaluations (single evaluations swing).

    A run that did not finish (no `#final` row) is listed with the steps it reached, marked `*`."""
    runs: dict[tuple, dict] = {}
    history: dict[tuple, list[float]] = {}
    for path in paths:
        with open(path) as fh:
            for row in csv.DictReader(fh):
                key = (row["algo"], row["dataset"], int(row["seed"]), row["run_id"].split("#")[0])
                runs[key] = row  # rows are in order: the last one of a run wins
                history.setdefault(key, []).append(float(row["normalized_score"]))
    groups: dict[tuple, list[dict]] = {}
    for key, row in runs.items():
        if row["env_steps"] == "0" and row["updates"] == "0":
            continue  # a run interrupted before its first evaluation
        row = dict(row, last3=float(np.mean(history[key][-3:])))
        groups.setdefault(key[:2], []).append(row)
    print("| algo | dataset | seeds | env steps (BC: grad steps) | return (mean over seeds) | "
          "normalized score per seed | mean of last 3 evals per seed | wall s / run |")
    print("|---|---|---|---|---|---|---|---|")
    for (algo, dataset), rows in sorted(groups.items(), key=lambda kv: (ALL_ALGOS.index(kv[0][0]), kv[0][1])):
        rows.sort(key=lambda r: int(r["seed"]))
        steps = {r["updates"] if r["env_steps"] == "0" else r["env_steps"] for r in rows}
        unfinished = any(not r["run_id"].endswith("#final") for r in rows)
        ret = np.mean([float(r["return_mean"]) for r in rows])
        scores = ", ".join(f"{float(r['normalized_score']):.2f}" for r in rows)
        last3 = ", ".join(f"{r['last3']:.2f}" for r in rows)
        wall = np.mean([float(r["wall_s"]) for r in rows])
        label = "perfect (no actions: state-only stand-in)" if dataset == "noact" else dataset
        print(f"| {algo} | {label} | {len(rows)} | {'/'.join(sorted(steps))}{'*' if unfinished else ''} | "
              f"{ret:.0f} | {scores} | {last3} | {wall:.0f} |")


def read_curves(path) -> dict[tuple, list[tuple[int, float]]]:
    """{(algo, dataset, seed, run_id): [(env steps or updates, normalized score), ...]} of one CSV."""
    curves: dict[tuple, list[tuple[int, float]]] = {}
    with open(path) as fh:
        for row in csv.DictReader(fh):
            key = (row["algo"], row["dataset"], int(row["seed"]), row["run_id"].split("#")[0])
            step = int(row["updates"] if row["env_steps"] == "0" else row["env_steps"])
            curves.setdefault(key, []).append((step, float(row["normalized_score"])))
    return curves


def summarize_stability(paths, threshold: float) -> None:
    """Markdown table: does a run stay at the expert once it got there? Per CSV (its file name is the variant)
    and (algo, dataset), for each seed: the first evaluation scoring >= threshold and, of the evaluations after
    it, how many also do and their minimum (`loco_il.evaluation.progress.stability`); the untrained policy's
    row (step 0) is left out."""
    from loco_il.evaluation.progress import stability
    print(f"| variant (CSV) | algo | dataset | seeds | first >= {threshold:g} at (per seed) | "
          f"later evaluations >= {threshold:g} | min after | falls back (seeds) |")
    print("|---|---|---|---|---|---|---|---|")
    for path in paths:
        groups: dict[tuple, list[dict]] = {}
        for (algo, dataset, seed, _), curve in sorted(read_curves(path).items(), key=lambda kv: kv[0][2]):
            groups.setdefault((algo, dataset), []).append(
                dict(stability([(step, x) for step, x in curve if step > 0], threshold), seed=seed))
        for (algo, dataset), runs in groups.items():
            reached = ", ".join("never" if r["reached"] is None else f"{r['reached'] / 1000:g}k" for r in runs)
            kept = sum(r["n_held"] for r in runs)
            later = sum(r["n_after"] for r in runs)
            mins = [r["min_after"] for r in runs if r["min_after"] is not None]
            fell = sum(1 for r in runs if r["min_after"] is not None and r["min_after"] < threshold)
            print(f"| {Path(path).stem} | {algo} | {dataset} | {len(runs)} | {reached} | {kept}/{later} | "
                  f"{min(mins) if mins else float('nan'):.2f} | {fell}/{sum(r['reached'] is not None for r in runs)} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--task", default=DEFAULT_TASK, help="<Env>.<task> (its perfect/real datasets are used)")
    parser.add_argument("--algos", nargs="+", default=ALL_ALGOS)
    parser.add_argument("--datasets", nargs="+", default=["perfect", "noact"], choices=["perfect", "noact", "real"],
                        help="noact and real only run the state-only learners gail, gaifo, lsiqfo")
    parser.add_argument("--seeds", nargs="+", type=int, default=[0, 1])
    parser.add_argument("--steps", type=int, default=50_000, help="env steps per run (BC: gradient steps)")
    parser.add_argument("--eval-every", type=int, default=10_000)
    parser.add_argument("--eval-episodes", type=int, default=5)
    parser.add_argument("--set", nargs="*", default=[], metavar="[ALGOS:]KEY=VALUE",
                        help="constructor overrides, e.g. initial_replay_size=1000 or iqlearn,lsiq:actor_lr=1e-4; "
                             "a key is applied only to agents that accept it")
    parser.add_argument("--out", default=None,
                        help="CSV to append to (default benchmarks/il_results/<task>_baselines.csv)")
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--summarize", nargs="+", metavar="CSV",
                        help="only print a Markdown table of the last evaluation of every run in these CSVs")
    parser.add_argument("--stability", type=float, metavar="SCORE",
                        help="with --summarize: instead of the last evaluations, whether runs stay at or above "
                             "this normalized score once they reached it (one row per CSV and algorithm)")
    args = parser.parse_args()
    if args.summarize:
        if args.stability is not None:
            summarize_stability(args.summarize, args.stability)
        else:
            summarize(args.summarize)
        return
    torch.set_num_threads(args.threads)
    unknown = set(args.algos) - set(ALL_ALGOS)
    if unknown:
        sys.exit(f"unknown algos {sorted(unknown)}; known: {ALL_ALGOS}")

    out = Path(args.out or ROOT / "benchmarks" / "il_results" / f"{args.task.lower().replace('.', '_')}_baselines.csv")
    out.parent.mkdir(parents=True, exist_ok=True)
    done = done_runs(out)
    _, data = expert_data(args.task, "perfect")
    norm, norm_desc = make_normalizer(args.task, data)
    print(f"# task {args.task}", flush=True)
    print(f"# normalized score reference: {norm_desc}", flush=True)
    print(f"# overrides: {args.set or 'none'}", flush=True)
    new = not out.is_file() or out.stat().st_size == 0
    with open(out, "a", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=FIELDS)
        if new:
            writer.writeheader()
            print(",".join(FIELDS[:-2]), flush=True)
        for algo in args.algos:
            for dataset in args.datasets:
                if dataset in STATE_ONLY_DATASETS and algo not in STATE_ONLY:
                    continue
                for seed in args.seeds:
                    if (algo, dataset, seed) in done:
                        print(f"# skip {algo} {dataset} seed {seed}: finished in {out}", flush=True)
                        continue
                    run_one(algo, dataset, seed, args, writer, fh, norm, norm_desc)


if __name__ == "__main__":
    main()
