"""A finished cell seed by seed: each run's final score, how many final evaluation episodes ended by a fall (early
termination), their mean length, and the run's wall time with the device it trained on, all read from the run dir
train.py left (`eval.json`, `config.yaml`).

The cell's mean ± CI hides a seed that fails where the others succeed; these columns show it, and the wall times
say what a run costs (`python -m loco_il.benchmark cost` models them).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping, Sequence

from loco_il.evaluation.runs import load_run_config

#: the device of train.py's default config (experiment_configs/config.yaml); runs on it carry no device note
DEFAULT_DEVICE = "cpu"


@dataclass(frozen=True)
class SeedRun:
    seed: int
    final: float | None           # the cell's metric: normalized score, or return where there is no baseline
    falls: int | None             # final evaluation episodes that ended by termination
    episodes: int | None
    length: float | None          # their mean length (env steps)
    wall_time: float | None       # seconds, as train.py measured it (summed over resumes)
    device: str


def run_device(run_dir: Path) -> str:
    """The `device` of a run's saved config (`config.yaml`); the config's default (cpu) where the run dir has no
    config or the config no device."""
    if not (Path(run_dir) / "config.yaml").is_file():
        return DEFAULT_DEVICE
    return str((load_run_config(run_dir) or {}).get("device") or DEFAULT_DEVICE)


def seed_runs(runs: Sequence[Mapping[str, Any]], normalized: bool) -> list[SeedRun]:
    """The per-seed view of a cell's finished runs (each an `eval.json` with its `run_dir`)."""
    key = "normalized_score" if normalized else "return_mean"
    return [SeedRun(seed=int(r["seed"]), final=r.get(key), falls=r.get("terminated"), episodes=r.get("episodes"),
                    length=r.get("length_mean"), wall_time=r.get("wall_time"), device=run_device(r["run_dir"]))
            for r in runs]


def _join(values: Sequence[str]) -> str:
    return ", ".join(values)


def finals_text(runs: Sequence[SeedRun], digits: int) -> str:
    return _join(["?" if r.final is None else f"{r.final:.{digits}f}" for r in runs])


def falls_text(runs: Sequence[SeedRun], final_episodes: int) -> str:
    """"3, 0, 0": falls per seed; "3/8" where a run evaluated another number of episodes than the protocol's."""
    out = []
    for r in runs:
        if r.falls is None:
            out.append("?")
        else:
            out.append(str(r.falls) if r.episodes in (None, final_episodes) else f"{r.falls}/{r.episodes}")
    return _join(out)


def lengths_text(runs: Sequence[SeedRun]) -> str:
    return _join(["?" if r.length is None else f"{r.length:.0f}" for r in runs])


def _range(seconds: Sequence[float]) -> str:
    lo, hi = round(min(seconds)), round(max(seconds))
    return f"{lo} s" if lo == hi else f"{lo}-{hi} s"


def wall_text(runs: Sequence[SeedRun]) -> str:
    """The range of wall time per run, one range per device, the default device first: "3401-3441 s, 450 s (cuda)"."""
    by_device: dict[str, list[float]] = {}
    for r in runs:
        if r.wall_time is not None:
            by_device.setdefault(r.device, []).append(float(r.wall_time))
    order = sorted(by_device, key=lambda d: (d != DEFAULT_DEVICE, d))
    parts = [_range(by_device[d]) + ("" if d == DEFAULT_DEVICE else f" ({d})") for d in order]
    return _join(parts) or "?"


#: the CSV's per-seed columns: (column, SeedRun field, format); space-separated values in seed order, "nan" where the
#: run's eval.json does not hold the value
_CSV_FIELDS = (("final_per_seed", "final", ".4f"), ("falls_per_seed", "falls", "d"),
               ("episodes_per_seed", "episodes", "d"), ("length_per_seed", "length", ".1f"),
               ("wall_time_per_seed", "wall_time", ".1f"), ("device_per_seed", "device", "s"))
CSV_COLUMNS = tuple(column for column, _, _ in _CSV_FIELDS)


def csv_values(runs: Sequence[SeedRun]) -> list[str]:
    """One value per `CSV_COLUMNS` entry."""
    def text(value: Any, fmt: str) -> str:
        return "nan" if value is None else format(value, fmt)
    return [" ".join(text(getattr(r, name), fmt) for r in runs) for _, name, fmt in _CSV_FIELDS]


__all__ = ["SeedRun", "run_device", "seed_runs", "finals_text", "falls_text", "lengths_text", "wall_text",
           "CSV_COLUMNS", "csv_values"]
