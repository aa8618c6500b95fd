"""Run checkpoints: everything needed to continue a killed training run where it stopped.

`<run_dir>/checkpoint.pt` (written atomically with `loco_il.utils.atomic`, so a kill mid-write leaves
the previous checkpoint intact) holds::

    {"format": "loco_il.run_checkpoint/v1",
     "agent": agent.state_dict(),    # networks, optimizers, normalizers, counters, the agent's RNG states
     "agent_extra": {"replay": ...}, # state the agent does not checkpoint itself: the replay memory
                                     # (left out with `checkpoint_replay: false`; a resumed run refills it)
     "counters": {"step", "env_steps", "updates", "episodes", "n_evals", ...},
     "rng": {"python", "numpy", "torch"},            # global RNG states
     "env_rng": {...},                               # the training env's generator (resets, noise)
     "wall_time": seconds trained so far, "wandb_id": ..., "config": the run's resolved config,
     "finished": bool}

Beside it, `<run_dir>/checkpoint.json` names the step it holds (`{"step", "env_steps", "wall_time",
"finished", "saved_at", "sha256", "previous"}`), so tools such as `loco_il.evaluation.progress` can say where a
stopped run resumes without loading a file of up to hundreds of MB. It is written right after the checkpoint, so
a kill between the two leaves it naming the previous checkpoint, never one that does not exist.

The last two checkpoints are kept: a new one moves the old `checkpoint.pt` to `checkpoint.prev.pt`, and
`checkpoint.json` records the sha256 of both (`sha256`, `previous.sha256`). `load_run_checkpoint` verifies a
checkpoint against them before anything resumes or forks from it: a damaged `checkpoint.pt` (or one written
while the run was killed, before its checksum was recorded) is set aside as `checkpoint.pt.damaged` and the run
resumes from the previous one, saying so; with no verified checkpoint left it refuses, naming the file.

Checkpoints are taken at chunk boundaries (after a whole `Core.learn` call), where mushroom-rl's
Core holds no state of its own: it resets the environment at the start of every `learn` call.
A resumed run therefore repeats the interrupted chunk exactly as the killed run would have,
and ends with the same total number of steps as an uninterrupted run.
"""
from __future__ import annotations

import datetime
import hashlib
import json
import os
import random
from pathlib import Path
from typing import Any, Callable, Mapping

import numpy as np
import torch

from loco_il.utils.atomic import atomic_open
from loco_il.utils.hashing import file_sha256

FORMAT = "loco_il.run_checkpoint/v1"
CHECKPOINT_NAME = "checkpoint.pt"
CHECKPOINT_SUMMARY_NAME = "checkpoint.json"
PREVIOUS_CHECKPOINT_NAME = "checkpoint.prev.pt"
DAMAGED_SUFFIX = ".damaged"

#: keys of the run config (dotted where nested) that may change between a run and its resumption
RESUMABLE_KEYS = frozenset({"resume", "stop_after_steps", "logger", "eval", "n_steps", "checkpoint_every",
                            "checkpoint_replay", "fork_from", "keep_checkpoints_above",
                            "device", "torch_threads", "results_dir", "per_algo",
                            "algo.params.cuda_graph",  # how an update is launched, not what it computes
                            "dataset.workers",      # how many processes generate the dataset, not what it holds
                            "dataset.regenerate"})  # rebuilds the same data (the generation is deterministic)
#: config keys added after runs may have been checkpointed, with the value that behaves as those runs did:
#: a checkpoint without the key resumes when the new config holds that value
ADDED_KEYS: dict[str, Any] = {"init_state": "default", "algo.policy.log_std_bounds": [-20.0, 2.0],
                              "algo.params.n_critics": 2, "algo.params.gamma": None, "algo.params.actor_ema": None,
                              "algo.params.freeze_replay": False, "algo.params.conservative_weight": 0.0,
                              "algo.params.conservative_actions": 10, "algo.params.conservative_hinge": False,
                              "algo.params.actor_bc_alpha": None, "algo.params.critic_layer_norm": False}


class CheckpointError(RuntimeError):
    pass


def global_rng_state() -> dict[str, Any]:
    state = {"python": random.getstate(), "numpy": np.random.get_state(), "torch": torch.get_rng_state()}
    if torch.cuda.is_available():
        state["cuda"] = torch.cuda.get_rng_state_all()
    return state


def set_global_rng_state(state: Mapping[str, Any]) -> None:
    random.setstate(state["python"])
    np.random.set_state(state["numpy"])
    torch.set_rng_state(state["torch"])
    if "cuda" in state and torch.cuda.is_available():
        torch.cuda.set_rng_state_all(state["cuda"])


def env_rng_state(env: Any) -> dict[str, Any] | None:
    rng = getattr(env, "_rng", None)
    if not isinstance(rng, np.random.Generator):
        return None
    return {"bit_generator": rng.bit_generator.state, "episodes": getattr(env, "_episodes", None)}


def set_env_rng_state(env: Any, state: Mapping[str, Any] | None) -> None:
    if not state:
        return
    rng = getattr(env, "_rng", None)
    if isinstance(rng, np.random.Generator):
        rng.bit_generator.state = state["bit_generator"]
    if state.get("episodes") is not None and hasattr(env, "_episodes"):
        env._episodes = state["episodes"]


def agent_extra_state(agent: Any, include_replay: bool = True) -> dict[str, Any]:
    """State the agent's own `state_dict` leaves out: the replay memory of off-policy agents."""
    extra = {}
    replay = getattr(agent, "replay", None)
    if include_replay and replay is not None and hasattr(replay, "state_dict"):
        extra["replay"] = replay.state_dict()
    return extra


def load_agent_extra_state(agent: Any, extra: Mapping[str, Any]) -> None:
    if "replay" in extra:
        agent.replay.load_state_dict(extra["replay"])


class _HashingWriter:
    """A file wrapper that hashes what `torch.save` writes, so no second pass over a large file is needed."""

    def __init__(self, handle):
        self.handle, self.digest = handle, hashlib.sha256()

    def write(self, data) -> int:
        self.digest.update(data)
        return self.handle.write(data)

    def flush(self) -> None:
        self.handle.flush()


def save_checkpoint(path: str | os.PathLike, *, agent: Any, env: Any, counters: Mapping[str, Any],
                    wall_time: float, config: Mapping[str, Any], wandb_id: str | None = None,
                    finished: bool = False, extra: Mapping[str, Any] | None = None,
                    include_replay: bool = True) -> None:
    path = Path(path)
    old = _read_summary(path.parent)
    state = {"format": FORMAT, "agent": agent.state_dict(), "agent_extra": agent_extra_state(agent, include_replay),
             "counters": dict(counters), "rng": global_rng_state(), "env_rng": env_rng_state(env),
             "wall_time": float(wall_time), "config": dict(config), "wandb_id": wandb_id,
             "finished": bool(finished), "extra": dict(extra or {})}
    previous = old.get("previous")
    with atomic_open(path) as fh:
        writer = _HashingWriter(fh)
        torch.save(state, writer)
        if path.is_file():   # keep the last two: the one being replaced becomes the previous one
            os.replace(path, path.with_name(PREVIOUS_CHECKPOINT_NAME))
            previous = {"step": old.get("step"), "sha256": old.get("sha256")}
    summary = {"step": int(counters.get("step", 0)), "env_steps": int(counters.get("env_steps", 0)),
               "wall_time": float(wall_time), "finished": bool(finished),
               "saved_at": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
               "sha256": writer.digest.hexdigest(), "previous": previous}
    _write_summary(path.parent, summary)


def _write_summary(run_dir: Path, summary: Mapping[str, Any]) -> None:
    with atomic_open(run_dir / CHECKPOINT_SUMMARY_NAME, "w") as fh:
        json.dump(dict(summary), fh)


def _read_summary(run_dir: str | os.PathLike) -> dict[str, Any]:
    try:
        summary = json.loads((Path(run_dir) / CHECKPOINT_SUMMARY_NAME).read_text())
    except (OSError, ValueError):
        return {}
    return summary if isinstance(summary, dict) else {}


def read_checkpoint_summary(run_dir: str | os.PathLike) -> dict[str, Any] | None:
    """`<run_dir>/checkpoint.json` (see the module doc), or None when absent or unreadable (runs
    checkpointed before it existed have only `checkpoint.pt`)."""
    summary = _read_summary(run_dir)
    return summary if isinstance(summary.get("step"), int) else None


def load_checkpoint(path: str | os.PathLike) -> dict[str, Any]:
    path = Path(path)
    try:
        ckpt = torch.load(path, map_location="cpu", weights_only=False)
    except Exception as exc:
        raise CheckpointError(f"cannot read checkpoint {path} ({type(exc).__name__}: {exc}); delete it or run "
                              f"with resume=false to start over") from exc
    if not isinstance(ckpt, dict) or ckpt.get("format") != FORMAT:
        raise CheckpointError(f"{path} is not a loco_il run checkpoint (format {FORMAT}); delete it or run with "
                              f"resume=false to start over")
    return ckpt


def has_checkpoint(run_dir: str | os.PathLike) -> bool:
    run_dir = Path(run_dir)
    return (run_dir / CHECKPOINT_NAME).is_file() or (run_dir / PREVIOUS_CHECKPOINT_NAME).is_file()


def load_run_checkpoint(run_dir: str | os.PathLike, note: Callable[[str], None] = print,
                        repair: bool = True) -> tuple[dict[str, Any], Path]:
    """The newest checkpoint of `run_dir` whose sha256 matches one recorded in its `checkpoint.json`, and its path.

    A checkpoint that does not match is reported through `note`; with `repair` (the run's own process, holding
    its lock) it is set aside as `<name>.damaged` and a verified previous checkpoint becomes `checkpoint.pt` again,
    so the next save keeps a consistent pair. Runs checkpointed before checksums existed (no `sha256` in
    `checkpoint.json`) load unverified. Raises `CheckpointError` naming the file when none verifies."""
    run_dir = Path(run_dir)
    current, previous = run_dir / CHECKPOINT_NAME, run_dir / PREVIOUS_CHECKPOINT_NAME
    summary = _read_summary(run_dir)
    if not summary.get("sha256"):
        return load_checkpoint(current), current
    prev_entry = summary.get("previous") or {}
    known = {summary["sha256"]: summary.get("step"), prev_entry.get("sha256"): prev_entry.get("step")}
    known.pop(None, None)
    bad = []
    for path in (current, previous):
        if not path.is_file():
            continue
        digest = file_sha256(path)
        if digest not in known:
            bad.append(path)
            continue
        ckpt = load_checkpoint(path)
        if bad:
            note(f"{bad[0]} does not match the sha256 recorded in {CHECKPOINT_SUMMARY_NAME} (damaged, or written "
                 f"while the run was killed); resuming from the previous checkpoint {path.name} "
                 f"(step {ckpt['counters'].get('step')})")
        if path != current and repair:
            if current.is_file():
                os.replace(current, current.with_name(current.name + DAMAGED_SUFFIX))
            os.replace(path, current)
            _write_summary(run_dir, {**summary, "step": int(ckpt["counters"].get("step", 0)),
                                     "env_steps": int(ckpt["counters"].get("env_steps", 0)),
                                     "wall_time": float(ckpt.get("wall_time", 0.0)),
                                     "finished": bool(ckpt.get("finished")), "sha256": digest, "previous": None})
            path = current
        return ckpt, path
    names = " and ".join(str(p) for p in bad) or str(current)
    raise CheckpointError(f"{names} does not match the sha256 recorded in {run_dir / CHECKPOINT_SUMMARY_NAME} "
                          f"and no verified checkpoint is left; run with resume=false to start over")


def restore(ckpt: Mapping[str, Any], *, agent: Any, env: Any) -> None:
    """Put agent, env and global RNGs back into the checkpointed state (agent RNGs last: its own)."""
    set_global_rng_state(ckpt["rng"])
    set_env_rng_state(env, ckpt.get("env_rng"))
    agent.load_state_dict(ckpt["agent"])
    load_agent_extra_state(agent, ckpt.get("agent_extra") or {})


def config_differences(old: Mapping[str, Any], new: Mapping[str, Any], prefix: str = "") -> list[str]:
    """Dotted keys whose values differ, ignoring `RESUMABLE_KEYS`."""
    diffs = []
    for key in sorted(set(old) | set(new)):
        name = f"{prefix}{key}"
        if name in RESUMABLE_KEYS:
            continue
        a, b = old.get(key, ADDED_KEYS.get(name, "<missing>")), new.get(key, "<missing>")
        if isinstance(a, Mapping) and isinstance(b, Mapping):
            diffs.extend(config_differences(a, b, name + "."))
        elif a != b:
            diffs.append(f"{name}: {a!r} -> {b!r}")
    return diffs


__all__ = ["CHECKPOINT_NAME", "CHECKPOINT_SUMMARY_NAME", "PREVIOUS_CHECKPOINT_NAME", "CheckpointError",
           "save_checkpoint", "read_checkpoint_summary", "load_checkpoint", "load_run_checkpoint", "has_checkpoint",
           "restore",
           "config_differences", "RESUMABLE_KEYS", "ADDED_KEYS"]
