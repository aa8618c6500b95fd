"""Item 5: a dataset cache that cannot be written is reported before the episodes are generated, and the
generated episodes are used anyway (kept in memory for the process) instead of being thrown away."""
from __future__ import annotations

import subprocess

import pytest
from conftest import read_only
from train_helpers import ROOT, run_dir, train_command


@pytest.mark.slow
def test_train_with_a_read_only_dataset_cache(env_vars, tmp_path, make_read_only):
    cache = make_read_only(tmp_path / "cache")
    env = dict(env_vars, LOCO_IL_DATASETS=str(cache))
    results = tmp_path / "r"
    cmd = train_command(results, "algo=bc", "n_steps=10", "eval.every=10", "eval.final_episodes=1")
    proc = subprocess.run(read_only(cmd, [cache]), cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    warnings = [line for line in proc.stderr.splitlines() if "cannot write the dataset cache" in line]
    assert len(warnings) == 1 and "LOCO_IL_DATASETS=" in warnings[0]   # once: the test split reuses the episodes
    assert proc.stderr.index("cannot write the dataset cache") < proc.stderr.index("episode 1/12")
    assert "Traceback" not in proc.stderr
    assert (run_dir(results) / "eval.json").is_file()
    assert not any(cache.iterdir())


@pytest.mark.slow
def test_dataset_regenerate_rebuilds_the_cached_dataset(env_vars, tmp_path):
    """The advice in dataset errors, `dataset.regenerate=true`, is a real key: the dataset is generated again."""
    from train_helpers import train
    short = ["algo=bc", "n_steps=10", "eval.every=10", "eval.final_episodes=1", "eval.similarity=false"]
    train(env_vars, tmp_path / "r", *short)                        # generates the dataset or finds it cached
    again = train(env_vars, tmp_path / "r", *short, "name=regen", "dataset.regenerate=true")
    assert "generating perfect dataset of InvertedPendulum.balance: 12 episodes" in again.stderr
    cached = train(env_vars, tmp_path / "r", *short, "name=cached")
    assert "generating" not in cached.stderr
