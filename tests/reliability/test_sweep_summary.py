"""Item 7: a sweep ends with one line per job and exits non-zero when any job failed."""
from __future__ import annotations

import json

import pytest
from train_helpers import TASK, run_dir, train

from loco_il.experiment.hydra_callbacks import summary_text


def test_summary_lines():
    jobs = [{"job": 0, "code": 0, "error": None, "task_id": TASK, "name": "bc", "seed": 0},
            {"job": 1, "code": 2, "error": "seed=-1: expected an integer >= 0", "task_id": TASK, "name": "bc",
             "seed": -1}]
    assert summary_text(jobs).splitlines() == [
        "[loco_il] sweep: 2 job(s), 1 done, 1 failed",
        f"  #0 {TASK} bc seed 0: done",
        f"  #1 {TASK} bc seed -1: failed (exit 2): seed=-1: expected an integer >= 0"]


def test_an_unexpected_error_in_a_sweep_job_becomes_a_failed_outcome(tmp_path, monkeypatch, capsys):
    from loco_il.experiment import runner

    def broken(*args, **kwargs):
        raise RuntimeError("boom\nsecond line")
    monkeypatch.setattr(runner, "run", broken)
    cfg = {"task_id": TASK, "name": "bc", "seed": 0, "results_dir": str(tmp_path), "algo": {"name": "bc"}}
    outcome = runner.run_job(cfg, tmp_path, catch_all=True)
    assert (outcome.code, outcome.error, outcome.task_id, outcome.seed) == (1, "RuntimeError: boom", TASK, 0)
    assert "Traceback" in capsys.readouterr().err
    with pytest.raises(RuntimeError, match="boom"):   # a single run keeps its traceback
        runner.run_job(cfg, tmp_path)


@pytest.mark.slow
def test_a_sweep_with_a_failed_job(env_vars, tmp_path):
    results = tmp_path / "r"
    proc = train(env_vars, results, "algo=bc", "seed=0,-1", "n_steps=10", "eval.every=10", "eval.final_episodes=1",
                 "eval.similarity=false", multirun=True, check=False)
    assert proc.returncode == 1, proc.stderr[-3000:]
    out = proc.stdout
    assert "[loco_il] sweep: 2 job(s), 1 done, 1 failed" in out
    assert f"#0 {TASK} bc seed 0: done" in out
    assert f"#1 {TASK} bc seed -1: failed (exit 2): seed=-1: expected an integer >= 0" in out
    assert json.loads((run_dir(results, seed=0) / "eval.json").read_text())["steps"] == 10
    assert not (results / ".multirun").exists()


@pytest.mark.slow
def test_a_sweep_of_good_jobs_exits_0(env_vars, tmp_path):
    proc = train(env_vars, tmp_path / "r", "algo=bc", "seed=0,1", "n_steps=10", "eval.every=10",
                 "eval.final_episodes=1", "eval.similarity=false", multirun=True)
    assert "[loco_il] sweep: 2 job(s), 2 done, 0 failed" in proc.stdout
