"""Reference returns per task (expert and random policy) and normalized scores.

``baselines.yaml`` (next to this file) holds, per ``<Body>.<task>``, only numbers that were really
measured, each with how it was produced (command, seed, episodes, commit, simulator)::

    tasks:
      Hopper.run:
        random: {return_mean, return_std, episodes, seed, policy, command, commit, simulator, date}
        expert: {return_mean, return_std, episodes, seed, policy_checksum, expert_file, training_steps,
                 command, commit, simulator, date}    # a built-in (model-based) expert: expert_file null,
                                                       # `expert` (its description) and `source` instead
        datasets:
          perfect: {n_episodes, n_transitions, generation_seed, cache_key, command, commit, simulator, date}
          preference: {..., levels: [{level, mean_return, std_return, snapshot}, ...]}

``normalized_score(task, ret) = (ret - random) / (expert - random)``: 0 = random policy,
1 = expert. Update entries with::

    python -m loco_il.datasets.baselines update Hopper.run --episodes 10 --seed 0            # random + expert
    python -m loco_il.datasets.baselines update Hopper.run --random-only --episodes 10
    python -m loco_il.datasets.baselines update Hopper.run --dataset perfect                # + dataset sizes
    python -m loco_il.datasets.baselines show [Hopper.run]
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any, Callable, Mapping

import numpy as np

from loco_il.environments.episodes import evaluate_task

BASELINES_FILE = Path(__file__).with_name("baselines.yaml")
FORMAT = 1
_HEADER = ("# Reference returns per task, written by `python -m loco_il.datasets.baselines update ...`.\n"
           "# Only measured numbers; each entry records how it was produced (command, seed, commit).\n"
           "# normalized score = (return - random.return_mean) / (expert.return_mean - random.return_mean)\n")


class BaselineMissingError(KeyError):
    """No baseline (or no expert/random part of it) for a task; the message says how to add one."""

    def __str__(self) -> str:
        return str(self.args[0])


#: the baselines' measurement (also `python -m loco_il.experts eval`'s): the shared episode loop's task evaluation
evaluate = evaluate_task


def _key(task_id: str) -> str:
    from loco_il.environments.registry import task_key
    return task_key(task_id)


def load_baselines(path: str | Path | None = None) -> dict[str, dict[str, Any]]:
    """All entries: ``{"<Body>.<task>": {"random": {...}, "expert": {...}, "datasets": {...}}}``."""
    import yaml
    path = Path(path) if path is not None else BASELINES_FILE
    if not path.is_file():
        return {}
    with open(path) as fh:
        doc = yaml.safe_load(fh) or {}
    if not isinstance(doc, dict) or not isinstance(doc.get("tasks", {}), dict):
        raise ValueError(f"{path}: expected a mapping with a 'tasks' mapping")
    return dict(doc.get("tasks") or {})


def get_baseline(task_id: str, path: str | Path | None = None) -> dict[str, Any]:
    """The entry of a task (any Task-ID form: ``Hopper.run``, ``Hopper.run.perfect.pomdp``...)."""
    key = _key(task_id)
    table = load_baselines(path)
    if key not in table:
        have = ", ".join(sorted(table)) or "(none)"
        raise BaselineMissingError(
            f"no baseline for {key} in {path or BASELINES_FILE} (tasks with one: {have}); measure it with "
            f"`python -m loco_il.datasets.baselines update {key}` (the expert part needs an installed or built-in expert)")
    return table[key]


def normalized_score(task_id: str, ret: Any, path: str | Path | None = None) -> Any:
    """(ret - random) / (expert - random) with the task's recorded means; works on scalars and arrays."""
    entry = get_baseline(task_id, path)
    key = _key(task_id)
    for part in ("random", "expert"):
        if not isinstance(entry.get(part), Mapping) or entry[part].get("return_mean") is None:
            extra = "" if part == "random" else " (an expert must be installed: see loco_il/experts/shipped/README.md)"
            raise BaselineMissingError(
                f"the baseline of {key} has no {part} return; measure it with "
                f"`python -m loco_il.datasets.baselines update {key}`{extra}")
    lo, hi = float(entry["random"]["return_mean"]), float(entry["expert"]["return_mean"])
    if hi == lo:
        raise ValueError(f"{key}: expert and random returns are equal ({hi}); cannot normalize")
    out = (np.asarray(ret, dtype=np.float64) - lo) / (hi - lo)
    return float(out) if out.ndim == 0 else out


# ----------------------------------------------------------------------------- measuring


def _provenance(command: str) -> dict[str, Any]:
    import mujoco
    from loco_il.experts.policy import git_commit
    return {"command": command, "commit": git_commit(), "uncommitted_changes": _dirty(),
            "simulator": f"mujoco {mujoco.__version__}", "date": time.strftime("%Y-%m-%d")}


def _dirty() -> bool | None:
    """Whether the checkout had uncommitted changes (read-only `git status`); None if unknown."""
    import subprocess
    try:
        out = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"],
                             cwd=Path(__file__).resolve().parent, capture_output=True, text=True, timeout=10)
    except (OSError, subprocess.SubprocessError):
        return None
    return bool(out.stdout.strip()) if out.returncode == 0 else None


def save_baselines(table: Mapping[str, Any], path: str | Path | None = None) -> Path:
    """Write the table (atomically), tasks sorted."""
    import yaml
    from loco_il.utils.atomic import atomic_open
    path = Path(path) if path is not None else BASELINES_FILE
    doc = {"format": FORMAT, "tasks": {k: table[k] for k in sorted(table)}}
    text = _HEADER + yaml.safe_dump(json.loads(json.dumps(doc)), sort_keys=False, default_flow_style=False)
    with atomic_open(path, "w") as fh:
        fh.write(text)
    return path


def update_baseline(task_id: str, *, episodes: int = 10, seed: int = 0, random: bool = True, expert: bool = True,
                    dataset: str | None = None, command: str | None = None, path: str | Path | None = None,
                    log: Callable[[str], None] | None = None) -> dict[str, Any]:
    """Measure and store the random and/or expert returns (and optionally a dataset's size) of a task."""
    key = _key(task_id)
    command = command or f"python -m loco_il.datasets.baselines update {key} --episodes {episodes} --seed {seed}"
    table = load_baselines(path)
    entry = dict(table.get(key) or {})
    if random:
        entry["random"] = {**evaluate(key, None, episodes, seed, log),
                           "policy": "uniform random actions in [-1, 1] (numpy default_rng(seed))",
                           **_provenance(command)}
    if expert:
        from loco_il.experts.files import NoExpertError, find_expert, load_policy
        from loco_il.experts.registry import builtin_expert
        try:
            path_e: Path | None = find_expert(key)
        except NoExpertError:
            if builtin_expert(key) is None:
                raise
            path_e = None          # the task's built-in (model-based) expert
        pol, where = load_policy(expert_path=path_e, key=key)
        meta = getattr(pol, "metadata", None) or {}
        entry["expert"] = {**evaluate(key, pol, episodes, seed, log), "policy_checksum": pol.checksum(),
                           "expert_file": _relative(path_e) if path_e is not None else None,
                           "training_steps": meta.get("training_steps"), "training_commit": meta.get("commit"),
                           **({"expert": where, "source": meta["source"]} if path_e is None and meta.get("source")
                              else {}),
                           **_provenance(command)}
    if dataset is not None:
        from loco_il.datasets.create import create_dataset
        data = create_dataset(f"{key}.{dataset}", generation_seed=seed, verbose=log is not None)
        sizes = dict(entry.get("datasets") or {})
        sizes[dataset] = {"n_episodes": data.n_trajectories, "n_transitions": data.n_transitions,
                          "generation_seed": int(seed), "cache_key": data.info.get("cache_key"),
                          "return_mean": data.info.get("expert_return_mean"), **_provenance(command)}
        if data.info.get("levels"):     # preference: every level's measured return, worst first
            sizes[dataset]["levels"] = [{"level": lvl.get("level"), "mean_return": lvl.get("mean_return"),
                                         "std_return": lvl.get("std_return"),
                                         "snapshot": _relative_if_file(lvl.get("snapshot"))}
                                        for lvl in data.info["levels"]]
        entry["datasets"] = sizes
    table[key] = entry
    save_baselines(table, path)
    return entry


def _relative_if_file(where: Any) -> Any:
    """A snapshot file as a repository-relative path (the table is committed; absolute paths name one
    machine); a built-in expert's description stays as it is."""
    return _relative(Path(where)) if isinstance(where, str) and Path(where).is_file() else where


def _relative(p: Path) -> str:
    root = Path(__file__).resolve().parents[2]
    try:
        return str(Path(p).resolve().relative_to(root))
    except ValueError:
        return str(p)


__all__ = ["BASELINES_FILE", "BaselineMissingError", "load_baselines", "get_baseline", "normalized_score",
           "evaluate", "update_baseline", "save_baselines"]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m loco_il.datasets.baselines", description=__doc__.split("\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    up = sub.add_parser("update", help="measure and store a task's baseline")
    up.add_argument("task")
    up.add_argument("--episodes", type=int, default=10)
    up.add_argument("--seed", type=int, default=0)
    up.add_argument("--random-only", action="store_true")
    up.add_argument("--expert-only", action="store_true")
    up.add_argument("--dataset", choices=("perfect", "preference"), default=None,
                    help="also generate this dataset and record its size")
    show = sub.add_parser("show", help="print the table (or one task)")
    show.add_argument("task", nargs="?")
    args = ap.parse_args(argv)
    if args.cmd == "show":
        out = get_baseline(args.task) if args.task else load_baselines()
        print(json.dumps(out, indent=2))
        return 0
    cmd = "python -m loco_il.datasets.baselines " + " ".join(argv if argv is not None else sys.argv[1:])
    entry = update_baseline(args.task, episodes=args.episodes, seed=args.seed, random=not args.expert_only,
                            expert=not args.random_only, dataset=args.dataset, command=cmd,
                            log=lambda m: print(m, file=sys.stderr, flush=True))
    print(json.dumps({_key(args.task): entry}, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

