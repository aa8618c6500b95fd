"""Item 2: checkpoints, final policies and shipped experts are verified against a recorded sha256 before use."""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
import torch
from damage import flip_tensor_bytes, truncate
from train_helpers import ROOT, TASK, run_dir, train

from loco_il.experiment.checkpoint import (CHECKPOINT_NAME, PREVIOUS_CHECKPOINT_NAME, CheckpointError,
                                           load_run_checkpoint, save_checkpoint)


class _Agent:
    def __init__(self, value: float):
        self.w = torch.full((4096,), value)

    def state_dict(self) -> dict:
        return {"w": self.w}


def _save(run: Path, step: int) -> None:
    save_checkpoint(run / CHECKPOINT_NAME, agent=_Agent(float(step)), env=None, counters={"step": step},
                    wall_time=1.0, config={"task_id": TASK})


def test_the_last_two_checkpoints_are_kept_with_their_checksums(tmp_path):
    for step in (100, 200, 300):
        _save(tmp_path, step)
    summary = json.loads((tmp_path / "checkpoint.json").read_text())
    assert summary["step"] == 300 and summary["previous"]["step"] == 200
    ckpt, path = load_run_checkpoint(tmp_path)
    assert path.name == CHECKPOINT_NAME and ckpt["counters"]["step"] == 300
    assert torch.load(tmp_path / PREVIOUS_CHECKPOINT_NAME, weights_only=False)["counters"]["step"] == 200


def test_a_damaged_checkpoint_falls_back_to_the_previous_one(tmp_path):
    _save(tmp_path, 100)
    _save(tmp_path, 200)
    flip_tensor_bytes(tmp_path / CHECKPOINT_NAME)
    notes = []
    ckpt, path = load_run_checkpoint(tmp_path, note=notes.append)
    assert ckpt["counters"]["step"] == 100 and path == tmp_path / CHECKPOINT_NAME
    assert len(notes) == 1 and "checkpoint.pt does not match the sha256" in notes[0] and "(step 100)" in notes[0]
    assert (tmp_path / "checkpoint.pt.damaged").is_file()
    # the pair is consistent again: the next checkpoint keeps the verified one as its previous
    _save(tmp_path, 200)
    flip_tensor_bytes(tmp_path / CHECKPOINT_NAME)
    assert load_run_checkpoint(tmp_path, note=notes.append)[0]["counters"]["step"] == 100


def test_no_verified_checkpoint_left_is_refused_naming_the_file(tmp_path):
    _save(tmp_path, 100)
    _save(tmp_path, 200)
    flip_tensor_bytes(tmp_path / CHECKPOINT_NAME)
    flip_tensor_bytes(tmp_path / PREVIOUS_CHECKPOINT_NAME)
    with pytest.raises(CheckpointError, match=r"checkpoint\.pt .*does not match the sha256.*resume=false"):
        load_run_checkpoint(tmp_path)


def test_a_kill_between_checkpoint_and_summary_resumes_from_the_recorded_one(tmp_path):
    """The new checkpoint.pt exists but checkpoint.json still names the previous one (the process died in
    between): the recorded one is used, never an unverified file."""
    _save(tmp_path, 100)
    summary = (tmp_path / "checkpoint.json").read_text()
    _save(tmp_path, 200)
    (tmp_path / "checkpoint.json").write_text(summary)
    assert load_run_checkpoint(tmp_path, note=lambda m: None)[0]["counters"]["step"] == 100


def test_shipped_expert_weights_are_verified(tmp_path):
    from loco_il.experts.policy import load_expert
    shipped = Path(ROOT) / "loco_il" / "experts" / "shipped" / "InvertedPendulum.balance" / "expert.pt"
    copy = tmp_path / "expert.pt"
    shutil.copyfile(shipped, copy)
    load_expert(copy)
    flip_tensor_bytes(copy)
    with pytest.raises(ValueError, match="checksum mismatch"):
        load_expert(copy)


@pytest.fixture(scope="module")
def damaged_resume(env_vars, tmp_path_factory):
    """A BC run stopped at step 300 (its last two checkpoints: 200 and 300), checkpoint.pt byte-flipped, resumed."""
    results = tmp_path_factory.mktemp("damaged") / "r"
    args = ["algo=bc", "n_steps=400", "eval.every=100", "checkpoint_every=100"]
    stopped = train(env_vars, results, *args, "stop_after_steps=300", check=False)
    assert stopped.returncode == 3, stopped.stderr[-2000:]
    flip_tensor_bytes(run_dir(results) / CHECKPOINT_NAME)
    return results, train(env_vars, results, *args)


@pytest.mark.slow
def test_a_byte_flipped_checkpoint_is_not_resumed(damaged_resume):
    results, resumed = damaged_resume
    out = resumed.stdout
    assert "checkpoint.pt does not match the sha256 recorded in checkpoint.json" in out
    assert f"resuming {run_dir(results)} at step 200/400" in out
    assert json.loads((run_dir(results) / "eval.json").read_text())["steps"] == 400


@pytest.mark.slow
@pytest.mark.parametrize("damage", [flip_tensor_bytes, truncate])
def test_a_damaged_final_agent_is_named(env_vars, damaged_resume, tmp_path, damage):
    import subprocess
    import sys
    results, _ = damaged_resume
    d = tmp_path / "run"
    shutil.copytree(run_dir(results), d)
    damage(d / "final_agent.pt")
    proc = subprocess.run([sys.executable, "-m", "loco_il.evaluation", f"run_dir={d}", "episodes=1"], cwd=ROOT,
                          env=env_vars, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2, proc.stderr[-2000:]
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and str(d / "final_agent.pt") in lines[0] and "checkpoint.pt instead" in lines[0]
