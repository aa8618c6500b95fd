"""Hydra callbacks of `train.py` (registered under `hydra.callbacks` in experiment_configs/config.yaml).

* `on_run_start`: the whole config is validated (`config_schema.validate_config`) before Hydra creates the run
  dir, so a bad value or an unusable `results_dir` is one line on stderr and exit status 2.
* Sweeps (`-m`): every job's outcome is recorded in `<sweep dir>/.multirun/<id>/` (jobs may run in other
  processes: joblib, submitit), and `on_multirun_end` prints one line per job (task, algorithm, seed: done, or
  failed with its one-line error) and exits 1 when any job did not finish.
"""
from __future__ import annotations

import contextlib
import json
import os
import shutil
import sys
import time
from pathlib import Path
from typing import Any

from hydra.experimental.callback import Callback
from omegaconf import DictConfig, OmegaConf, open_dict

#: environment variable naming the folder where a sweep's jobs record their outcomes
RECORDS_ENV = "LOCO_IL_SWEEP_RECORDS"
#: exit status of a sweep in which a job did not finish
SWEEP_FAILED_EXIT_CODE = 1


def task_config(config: DictConfig) -> DictConfig:
    """The job's config without Hydra's own node (what the task function receives)."""
    cfg = OmegaConf.create(OmegaConf.to_container(config, resolve=False))
    with open_dict(cfg):
        cfg.pop("hydra", None)
    return cfg


def _fail(message: str) -> None:
    print(f"[loco_il] error: {message}", file=sys.stderr, flush=True)
    raise SystemExit(2)


class TrainCallbacks(Callback):
    def on_run_start(self, config: DictConfig, **kwargs: Any) -> None:
        from hydra.core.hydra_config import HydraConfig

        from loco_il.experiment.config_schema import ConfigValueError, validate_config
        HydraConfig.instance().set_config(config)   # `${hydra:...}` values (task_id) resolve from it
        try:
            validate_config(task_config(config))
        except ConfigValueError as exc:
            _fail(str(exc))

    def on_multirun_start(self, config: DictConfig, **kwargs: Any) -> None:
        from loco_il.experiment.config_schema import ConfigValueError, check_results_dir
        try:   # the sweep dir is made before any job starts; job-level values are checked in each job
            check_results_dir(str(config.hydra.sweep.dir))
        except ConfigValueError as exc:
            _fail(str(exc))
        records = Path(str(config.hydra.sweep.dir)) / ".multirun" / f"{time.strftime('%Y%m%d-%H%M%S')}-{os.getpid()}"
        records.mkdir(parents=True, exist_ok=True)
        os.environ[RECORDS_ENV] = str(records)

    def on_job_end(self, config: DictConfig, job_return: Any, **kwargs: Any) -> None:
        records = os.environ.get(RECORDS_ENV)
        if not records:
            return
        from hydra.core.utils import JobStatus

        from loco_il.utils.atomic import atomic_open
        value = job_return._return_value if hasattr(job_return, "_return_value") else None
        num = int(OmegaConf.select(config, "hydra.job.num", default=0))
        label = _label(job_return.cfg) if job_return.cfg is not None else {}
        if job_return.status == JobStatus.COMPLETED and hasattr(value, "code"):
            record = {"code": value.code, "error": value.error, "task_id": value.task_id, "name": value.name,
                      "seed": value.seed}
        elif job_return.status == JobStatus.COMPLETED:
            record = {"code": int(value or 0), "error": None, **label}
        else:
            first = (str(value).splitlines() or [""])[0]
            record = {"code": 1, "error": f"{type(value).__name__}: {first}", **label}
        record["job"] = num
        with atomic_open(Path(records) / f"job{num}.json", "w") as fh:
            json.dump(record, fh, default=str)

    def on_multirun_end(self, config: DictConfig, **kwargs: Any) -> None:
        records = os.environ.pop(RECORDS_ENV, None)
        if not records:
            return
        folder = Path(records)
        jobs = sorted((json.loads(p.read_text()) for p in folder.glob("job*.json")), key=lambda r: r["job"])
        shutil.rmtree(folder, ignore_errors=True)
        with contextlib.suppress(OSError):   # .multirun/ itself, unless another sweep is recording there
            folder.parent.rmdir()
        print(summary_text(jobs), flush=True)
        if any(r["code"] != 0 for r in jobs):
            raise SystemExit(SWEEP_FAILED_EXIT_CODE)


def _label(cfg: Any) -> dict[str, Any]:
    out = {}
    for key in ("task_id", "name", "seed"):
        try:
            out[key] = OmegaConf.select(cfg, key, throw_on_resolution_failure=False)
        except Exception:  # noqa: BLE001 - a label only
            out[key] = "?"
    return out


def summary_text(jobs: list[dict[str, Any]]) -> str:
    """One line per job: `#<n> <task> <algorithm> seed <s>: done | failed (exit <c>): <error>`."""
    failed = sum(r["code"] != 0 for r in jobs)
    lines = [f"[loco_il] sweep: {len(jobs)} job(s), {len(jobs) - failed} done, {failed} failed"]
    for r in jobs:
        state = "done" if r["code"] == 0 else f"failed (exit {r['code']}): {r.get('error') or 'no message'}"
        lines.append(f"  #{r['job']} {r.get('task_id')} {r.get('name')} seed {r.get('seed')}: {state}")
    return "\n".join(lines)


__all__ = ["TrainCallbacks", "summary_text", "RECORDS_ENV", "SWEEP_FAILED_EXIT_CODE"]
