"""Item 4 (evaluation CLI) and item 9 (steps of an unfinished run): one-line errors, exit status 2."""
from __future__ import annotations

import json

import pytest
import yaml
from damage import truncate
from train_helpers import TASK

from loco_il.evaluation.__main__ import main


@pytest.mark.parametrize("arg, message", [
    ("episodes=0", "episodes=0: expected an integer >= 1"),
    ("episodes=-2", "episodes=-2: expected an integer >= 1"),
    ("episodes=five", "episodes=five: expected an integer >= 1"),
    ("seed=x", "seed=x: expected an integer >= 0"),
    ("similarity=maybe", "similarity=maybe: expected true or false"),
    ("bogus=1", "unknown argument(s) ['bogus']"),
])
def test_bad_arguments(tmp_path, capsys, arg, message):
    assert main([f"run_dir={tmp_path}", arg]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0]


def _run_dir(path):
    path.mkdir()
    (path / "config.yaml").write_text(yaml.safe_dump({"task_id": TASK, "algo": {"name": "bc"}, "seed": 0}))
    return path


def test_a_truncated_final_agent_is_named(tmp_path, capsys):
    d = _run_dir(tmp_path / "run")
    from loco_il.algorithms import factory
    from loco_il.environments.registry import make
    env = make(TASK)
    agent = factory.build_agent("bc", env.info, {"name": "bc", "policy": {"hidden": [8]}}, seed=0)
    agent.save(d / "final_agent.pt")
    env.stop()
    truncate(d / "final_agent.pt")
    assert main([f"run_dir={d}", "episodes=1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"cannot read {d / 'final_agent.pt'}" in err[0]


def test_steps_of_an_unfinished_run_come_from_its_checkpoint(tmp_path):
    from loco_il.evaluation.__main__ import _trained_steps
    d = _run_dir(tmp_path / "run")
    assert _trained_steps(str(d)) is None
    (d / "checkpoint.json").write_text(json.dumps({"step": 400, "sha256": "x"}))
    assert _trained_steps(str(d)) == 400
    from loco_il.evaluation import format_eval_table
    row = {"task": "t", "dataset_type": "perfect", "name": "bc", "seed": 0, "steps": None, "episodes": 1,
           "return_mean": 1.0, "return_std": 0.0}
    assert "None" not in format_eval_table([row])
