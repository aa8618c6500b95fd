"""Item 1: one process per run dir; a second one refuses at once naming the holder; a killed holder leaves no lock."""
from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time

import pytest
from train_helpers import ROOT, run_dir, train, train_command

from loco_il.experiment.lock import RunDirLockedError, run_dir_lock


def test_second_holder_is_refused_with_pid_and_host(tmp_path):
    with run_dir_lock(tmp_path):
        with pytest.raises(RunDirLockedError, match=f"pid {os.getpid()} on host {socket.gethostname()}"):
            with run_dir_lock(tmp_path):
                pass
    with run_dir_lock(tmp_path):   # released at the end of the block
        pass


def test_a_killed_holder_leaves_no_stale_lock(tmp_path):
    code = (f"from loco_il.experiment.lock import run_dir_lock\nimport time\n"
            f"with run_dir_lock({str(tmp_path)!r}):\n    print('locked', flush=True)\n    time.sleep(60)\n")
    holder = subprocess.Popen([sys.executable, "-c", code], cwd=ROOT, stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "locked"
        with pytest.raises(RunDirLockedError, match=f"pid {holder.pid} "):
            with run_dir_lock(tmp_path):
                pass
    finally:
        holder.send_signal(signal.SIGKILL)
        holder.wait()
    with run_dir_lock(tmp_path):   # the OS released it with the process
        pass


@pytest.mark.slow
def test_concurrent_train_on_one_run_dir(env_vars, tmp_path):
    """A second train.py on a run dir that is training exits 2 at once, naming the first one's pid; the first
    run's log has each step once, in order."""
    results = tmp_path / "r"
    args = ["algo=bc", "n_steps=3000", "eval.every=500", "checkpoint_every=500"]
    train(env_vars, results, "algo=bc", "n_steps=10", "eval.every=10", "eval.similarity=false")  # dataset cached
    first = subprocess.Popen(train_command(results, *args, "name=bc_long"), cwd=ROOT, env=env_vars,
                             stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        d = run_dir(results, "bc_long")
        deadline = time.time() + 120
        while not (d / "config.yaml").exists() and time.time() < deadline:
            time.sleep(0.05)
        second = train(env_vars, results, *args, "name=bc_long", check=False)
        assert second.returncode == 2, second.stderr[-2000:]
        assert f"is in use by pid {first.pid} on host {socket.gethostname()}" in second.stderr
        assert first.poll() is None, "the first run ended before the second one started"
    finally:
        _, err = first.communicate(timeout=300)
    assert first.returncode == 0, err[-2000:]
    from train_helpers import csv_rows
    assert [int(r["step"]) for r in csv_rows(d / "log.csv")] == [500, 1000, 1500, 2000, 2500, 3000]
