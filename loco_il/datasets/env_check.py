"""Does a dataset fit the env it is used with? The policy, applied to every dataset `create_dataset` returns:

* **refused** (`DatasetError`): observations of another size or other named entries; a `task_id` of another
  body or task (a variant's data from its base body is fine); actions outside [-1, 1] (the env's action
  range: data recorded in actuator units or otherwise scaled would teach the wrong actions).
* **warned** (one line on stderr, training goes on): the info lacks `task_id`, `obs_names` or `simulator`
  (nothing to check those against); the data was recorded with another MuJoCo version (same model, possibly
  slightly different dynamics).

The cached datasets of loco_il always pass: their cache key includes the MuJoCo version.
"""
from __future__ import annotations

import sys
from typing import Any

import numpy as np

from loco_il.datasets.trajectory import DatasetError, Trajectories

#: how far outside [-1, 1] an action may lie (float32 rounding of clipped values)
ACTION_TOLERANCE = 1e-5
REGENERATE = ("regenerate the dataset (`python train.py ... dataset.regenerate=true`, or "
              "create_dataset(env, regenerate=True))")


def _body_and_task(task_id: str) -> tuple[str, str] | None:
    from loco_il.environments.registry import UnknownTaskError, parse_task_id
    try:
        parsed = parse_task_id(task_id)
    except (UnknownTaskError, ValueError):
        return None
    return parsed.body, parsed.task


def check_dataset_for_env(data: Trajectories, env: Any) -> list[str]:
    """Raise `DatasetError` for a dataset `env` must not learn from; return the warnings (see the module doc)."""
    import mujoco
    full = env.full_obs_spec
    names = data.info.get("obs_names")
    if data.obs_dim != full.dim or (names is not None and list(names) != list(full.names)):
        raise DatasetError(f"the dataset of {env.task_id} has {data.obs_dim} observation entries "
                           f"{'' if names is None else '(' + ', '.join(names[:4]) + ', ...) '}but the env's full "
                           f"observation has {full.dim} ({', '.join(full.names[:4])}, ...); {REGENERATE}")
    warnings = []
    missing = [k for k in ("task_id", "obs_names", "simulator") if not data.info.get(k)]
    if missing:
        warnings.append(f"the dataset's info lacks {', '.join(missing)}: it cannot be checked against "
                        f"{env.task_id} there")
    task_id = data.info.get("task_id")
    if task_id:
        mine, theirs = _body_and_task(env.task_id), _body_and_task(str(task_id))
        if theirs is None or (mine is not None and theirs != mine):
            raise DatasetError(f"the dataset was recorded for {task_id}, not for {env.task_id} (another "
                               f"{'task' if theirs and theirs[0] == mine[0] else 'body or task'}); {REGENERATE}")
    simulator = data.info.get("simulator")
    if simulator and str(simulator) != f"mujoco {mujoco.__version__}":
        warnings.append(f"the dataset was recorded with {simulator}, this is mujoco {mujoco.__version__} (same "
                        f"model, the dynamics may differ slightly); {REGENERATE} to match")
    if data.actions is not None and data.n_transitions:
        low, high = float(np.min(data.actions)), float(np.max(data.actions))
        if low < -1.0 - ACTION_TOLERANCE or high > 1.0 + ACTION_TOLERANCE:
            raise DatasetError(f"the dataset's actions lie in [{low:.4g}, {high:.4g}] but {env.task_id} takes "
                               f"actions in [-1, 1] (mapped onto the actuators' ranges): they were recorded in "
                               f"another scale; rescale them to [-1, 1] or {REGENERATE}")
    return warnings


def warn(warnings: list[str]) -> None:
    for line in warnings:
        print(f"[loco_il.datasets] warning: {line}", file=sys.stderr, flush=True)


__all__ = ["check_dataset_for_env", "warn", "ACTION_TOLERANCE"]
