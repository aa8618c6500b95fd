"""SIGKILL a short run at random points (also mid-checkpoint); each resumed run ends exactly like an
uninterrupted one: the same eval.json (but for wall time and date) and the same evaluation rows."""
from __future__ import annotations

import json
import random
import signal
import subprocess
import time

import pytest
from train_helpers import ROOT, csv_rows, run_dir, train, train_command

ARGS = ["algo=bc", "n_steps=1500", "eval.every=500", "checkpoint_every=100"]
VOLATILE = ("wall_time", "created")


def _result(results) -> dict:
    ev = json.loads((run_dir(results) / "eval.json").read_text())
    return {k: v for k, v in ev.items() if k not in VOLATILE}


def _kill_after(env_vars, results, step: int, delay: float) -> int:
    """Start the run, SIGKILL it `delay` s after its checkpoint reached `step`; returns the checkpointed step."""
    proc = subprocess.Popen(train_command(results, *ARGS), cwd=ROOT, env=env_vars, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    summary = run_dir(results) / "checkpoint.json"
    try:
        deadline = time.time() + 240
        while proc.poll() is None and time.time() < deadline:
            try:
                if json.loads(summary.read_text())["step"] >= step:
                    break
            except (OSError, ValueError, KeyError):
                pass
            time.sleep(0.01)
        time.sleep(delay)
        assert proc.poll() is None, "the run ended before it could be killed"
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait()
    return json.loads(summary.read_text())["step"]


@pytest.mark.slow
def test_killed_at_random_points_resumes_to_the_uninterrupted_result(env_vars, tmp_path):
    full = tmp_path / "full"
    train(env_vars, full, *ARGS)
    expected, expected_rows = _result(full), csv_rows(run_dir(full) / "log.csv")
    rng = random.Random(20261128)
    for i in range(3):
        results = tmp_path / f"killed{i}"
        at = _kill_after(env_vars, results, step=rng.randrange(100, 1200, 100), delay=rng.uniform(0.0, 0.3))
        assert not (run_dir(results) / "eval.json").exists() and 0 < at < 1500
        resumed = train(env_vars, results, *ARGS)
        assert "resuming" in resumed.stdout
        assert _result(results) == expected, f"kill {i} (checkpoint at step {at})"
        rows = csv_rows(run_dir(results) / "log.csv")
        assert [(r["step"], r["eval_return_mean"]) for r in rows] == \
            [(r["step"], r["eval_return_mean"]) for r in expected_rows]
