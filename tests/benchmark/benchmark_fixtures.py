"""Shared pieces of the benchmark tests: protocol files written by the test, and finished-run folders made of the
files `train.py` leaves (eval.json, log.csv), so that tables are built without training anything."""
from __future__ import annotations

import csv
import json
from pathlib import Path
from typing import Any, Sequence

import yaml


def write_protocol(folder: Path, name: str, doc: dict[str, Any]) -> Path:
    path = folder / f"{name}.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


def tiny_protocol(**changes: Any) -> dict[str, Any]:
    """A valid two-part protocol on cheap tasks; `changes` replace its top-level keys."""
    doc = {
        "seeds": [0, 1, 2],
        "report_at": [100, 200],
        "eval": {"episodes": 5, "final_episodes": 10},
        "overrides": {"logger": "csv"},
        "families": {"onpolicy": {"algos": ["gail", "vail"], "n_steps": 300, "eval_every": 100},
                     "sac": {"algos": ["lsiq"], "n_steps": 200, "eval_every": 100},
                     "offline": {"algos": ["bc"], "n_steps": 50, "eval_every": 10, "unit": "gradient"}},
        "variants": {"lsiq_twin": {"algo": "lsiq", "overrides": {"algo.params.n_critics": 2}}},
        "parts": {"perfect": {"dataset": "perfect", "tasks": ["Hopper.run", "UnitreeH1.run"],   # UnitreeH1.run: no expert
                              "algorithms": ["gail", "vail", "lsiq", "lsiq_twin", "bc"]},
                  "real": {"dataset": "real", "tasks": ["UnitreeH1.walk"], "algorithms": ["gail"]}},
    }
    doc.update(changes)
    return doc


def finished_run(run_dir: Path, task_id: str, name: str, seed: int, steps: int, final: float | None,
                 ret: float, curve: Sequence[tuple[int, float | None, float]], unit: str = "env steps",
                 algorithm: str | None = None, details: dict[str, Any] | None = None,
                 device: str | None = None) -> None:
    """A run dir as train.py leaves it: eval.json (final normalized score `final`, return `ret`, and any further
    `details`, e.g. terminated, episodes, length_mean, wall_time), log.csv rows (step, normalized score, return) and,
    where `device` is given, a config.yaml that names it."""
    run_dir.mkdir(parents=True, exist_ok=True)
    body, task, dataset = task_id.split(".")
    (run_dir / "eval.json").write_text(json.dumps({
        "task_id": task_id, "task": f"{body}.{task}", "dataset_type": dataset, "algorithm": algorithm or name,
        "name": name, "seed": seed, "steps": steps, "step_unit": unit, "return_mean": ret,
        "normalized_score": final, **(details or {})}))
    if device is not None:
        (run_dir / "config.yaml").write_text(yaml.safe_dump({"device": device, "seed": seed}))
    with open(run_dir / "log.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["step", "env_steps", "eval_return_mean", "normalized_score"])
        for step, score, value in curve:
            w.writerow([step, step, value, "" if score is None else score])
