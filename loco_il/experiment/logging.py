"""Per-run logs: `log.csv` + `log.jsonl` (what evaluation and the leaderboard read), W&B, a progress bar.

Every row is one evaluation point::

    {"step": 20000,            # training budget consumed (env steps; gradient steps for offline BC)
     "env_steps": 20000, "updates": 20000, "episodes": 31, "wall_time": 84.2, "steps_per_s": 240.1,
     "train_return": 812.0,    # mean return of the training episodes finished since the last row (or null)
     "eval_return_mean": 1000.0, "eval_return_std": 0.0, "eval_episodes": 10,
     "eval_terminated": 0,     # of them, how many ended in a terminal state (a fall) before the horizon
     "normalized_score": 0.98, # null when the task has no expert/random baseline
     ...}                      # plus the agent's last fit diagnostics (losses), prefixed "fit/"

`log.jsonl` holds every key of every row; `log.csv` holds the fixed `CSV_COLUMNS` (missing -> empty).
Both are append-only while a run goes on; on resume, rows past the checkpoint are dropped
(`RunLogger.truncate(step)`) so the files never hold a step twice.

W&B (`logger.wandb.mode`): "offline" (default: files under `<run_dir>/wandb`, `wandb sync` uploads them
later), "online" (needs `wandb login` or WANDB_API_KEY), or "disabled". A resumed run continues the same
W&B run (its id is kept in the checkpoint).
"""
from __future__ import annotations

import csv
import io
import json
import os
import sys
import time
from pathlib import Path
from typing import IO, Any, Mapping

from loco_il.utils.atomic import atomic_open
from loco_il.utils.fileio import jsonable

CSV_COLUMNS = ("step", "env_steps", "updates", "episodes", "wall_time", "steps_per_s", "train_return",
               "eval_return_mean", "eval_return_std", "eval_episodes",
               "eval_terminated",   # evaluation episodes that ended in a terminal state (a fall) before the horizon
               "normalized_score",
               "normalized_score_ema")   # the actor's moving average (agents with actor_ema; else empty)


def read_jsonl(path: str | os.PathLike) -> list[dict]:
    """The rows of a `log.jsonl` (a torn last line, from a kill mid-write, is skipped)."""
    rows = []
    path = Path(path)
    if not path.is_file():
        return rows
    for line in path.read_text().splitlines():
        line = line.strip()
        if not line:
            continue
        try:
            rows.append(json.loads(line))
        except json.JSONDecodeError:
            continue
    return rows


def _write_csv_rows(fh: IO[str], rows: list[Mapping[str, Any]], *, header: bool) -> None:
    """Write `rows` as `CSV_COLUMNS` (missing -> empty) with the csv module's own line end, the one place that does:
    appended rows and rows rewritten on resume must not end their lines differently."""
    writer = csv.DictWriter(fh, fieldnames=CSV_COLUMNS, extrasaction="ignore")
    if header:
        writer.writeheader()
    for row in rows:
        writer.writerow({k: ("" if row.get(k) is None else row.get(k)) for k in CSV_COLUMNS})


def write_log_csv(path: str | os.PathLike, rows: list[Mapping[str, Any]]) -> None:
    """Replace the log.csv at `path` by `rows`, atomically."""
    buf = io.StringIO(newline="")
    _write_csv_rows(buf, rows, header=True)
    with atomic_open(path, "wb") as fh:   # bytes: the csv module's line ends stay as they are
        fh.write(buf.getvalue().encode())


class RunLogger:
    """CSV + JSON-lines files in the run dir, optional W&B, optional tqdm progress bar."""

    def __init__(self, run_dir: str | os.PathLike, cfg: Mapping[str, Any] | None = None, *,
                 wandb_cfg: Mapping[str, Any] | None = None, progress: Any = "auto", total: int | None = None,
                 initial: int = 0, wandb_id: str | None = None, run_name: str | None = None, unit: str = "step"):
        self.run_dir = Path(run_dir)
        self.run_dir.mkdir(parents=True, exist_ok=True)
        self.csv_path = self.run_dir / "log.csv"
        self.jsonl_path = self.run_dir / "log.jsonl"
        if self.csv_path.is_file() and self.csv_path.stat().st_size and self._csv_header() != list(CSV_COLUMNS):
            # a run resumed from a version with other columns: rewrite the file from log.jsonl (all keys)
            self._write_csv(read_jsonl(self.jsonl_path))
        self._wandb = None
        self.wandb_id = wandb_id
        self._bar = None
        self._postfix: dict[str, Any] = {}
        wandb_cfg = dict(wandb_cfg or {})
        mode = str(wandb_cfg.get("mode", "disabled"))
        if mode != "disabled":
            self._start_wandb(wandb_cfg, mode, cfg, run_name)
        if progress == "auto":
            progress = None  # tqdm: on when stderr is a terminal
        if progress is not False and total is not None:
            from tqdm import tqdm
            self._bar = tqdm(total=int(total), initial=int(initial), unit=unit, unit_scale=True, dynamic_ncols=True,
                             disable=progress is None and not sys.stderr.isatty(), smoothing=0.1,
                             desc=run_name or "train")

    # ------------------------------------------------------------------ W&B
    def _start_wandb(self, wandb_cfg: dict, mode: str, cfg: Mapping[str, Any] | None, run_name: str | None) -> None:
        import wandb
        os.environ.setdefault("WANDB_SILENT", "true")
        kwargs = dict(project=wandb_cfg.get("project") or "loco_il", entity=wandb_cfg.get("entity") or None,
                      group=wandb_cfg.get("group") or None, tags=list(wandb_cfg.get("tags") or []) or None,
                      name=run_name, dir=str(self.run_dir), mode=mode, config=jsonable(dict(cfg or {})),
                      id=self.wandb_id, resume="allow" if self.wandb_id else None, reinit=True)
        try:
            self._wandb = wandb.init(**{k: v for k, v in kwargs.items() if v is not None})
        except Exception as exc:  # a logging backend must not kill a training run
            print(f"[loco_il] W&B disabled: wandb.init failed ({type(exc).__name__}: {exc}). With "
                  f"logger=wandb (online) run `wandb login` first, or use logger=offline.", file=sys.stderr)
            self._wandb = None
            return
        self.wandb_id = self._wandb.id

    # ------------------------------------------------------------------ rows
    def log(self, row: Mapping[str, Any]) -> dict:
        row = {k: jsonable(v) for k, v in row.items()}
        with open(self.jsonl_path, "a") as fh:
            fh.write(json.dumps(row) + "\n")
            fh.flush()
        new = not self.csv_path.is_file() or self.csv_path.stat().st_size == 0
        with open(self.csv_path, "a", newline="") as fh:
            _write_csv_rows(fh, [row], header=new)
            fh.flush()
        if self._wandb is not None:
            data = {k: v for k, v in row.items() if isinstance(v, (int, float)) and v is not None and k != "step"}
            self._wandb.log(data, step=int(row.get("step", 0)))
        return row

    def truncate(self, step: int) -> None:
        """Drop rows with `step` > the given step (after resuming from a checkpoint taken at `step`)."""
        rows = [r for r in read_jsonl(self.jsonl_path) if int(r.get("step", 0)) <= step]
        with atomic_open(self.jsonl_path, "w") as fh:
            fh.write("".join(json.dumps(r) + "\n" for r in rows))
        self._write_csv(rows)

    def _csv_header(self) -> list[str]:
        with open(self.csv_path, newline="") as fh:
            return next(csv.reader(fh), [])

    def _write_csv(self, rows: list[dict]) -> None:
        write_log_csv(self.csv_path, rows)

    def summary(self, values: Mapping[str, Any]) -> None:
        if self._wandb is not None:
            for k, v in values.items():
                if isinstance(v, (int, float, str)) or v is None:
                    self._wandb.summary[k] = v

    # ------------------------------------------------------------------ progress bar
    def progress(self, n: int, **postfix: Any) -> None:
        if self._bar is None:
            return
        if postfix:
            self._postfix.update({k: (f"{v:.4g}" if isinstance(v, float) else v) for k, v in postfix.items()
                                  if v is not None})
            self._bar.set_postfix(self._postfix, refresh=False)
        self._bar.update(int(n))

    def write(self, msg: str) -> None:
        """Print a line without breaking the progress bar."""
        if self._bar is not None and not self._bar.disable:
            self._bar.write(msg)
        else:
            print(msg, flush=True)

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()
            self._bar = None
        if self._wandb is not None:
            try:
                self._wandb.finish()
            except Exception:  # noqa: BLE001 - never fail a finished run on logging
                pass
            self._wandb = None


class Stopwatch:
    """Wall time of a run that survives resumes (the time before the checkpoint is carried over)."""

    def __init__(self, offset: float = 0.0):
        self.offset = float(offset)
        self._start = time.perf_counter()

    def __call__(self) -> float:
        return self.offset + time.perf_counter() - self._start


__all__ = ["RunLogger", "Stopwatch", "CSV_COLUMNS", "read_jsonl", "write_log_csv"]
