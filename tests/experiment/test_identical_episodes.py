"""Evaluation says when its episodes cannot differ (deterministic start and policy), instead of a bare std 0."""
from __future__ import annotations

import numpy as np

from loco_il.environments.registry import make
from loco_il.evaluation import evaluate_policy, format_eval_table, identical_episodes_note


def _evaluate(task_id: str, episodes: int = 3) -> dict:
    env = make(task_id)
    try:
        zero = np.zeros(env.info.action_space.shape)
        return evaluate_policy(env, lambda obs: zero, episodes, seed=1000)
    finally:
        env.stop()


def _row(res: dict, task: str) -> dict:
    return {"task": task, "dataset_type": "real", "name": "zero", "seed": 0, "steps": 0, **res}


def test_robot_without_reset_noise_gives_identical_episodes_and_says_so():
    res = _evaluate("UnitreeGo1.simple.real")   # the Menagerie Go1 starts exactly at its keyframe
    assert res["distinct_episodes"] == 1 and res["return_std"] == 0.0
    note = identical_episodes_note(res)
    assert note is not None and "all 3 evaluation episodes identical" in note
    assert note in format_eval_table([_row(res, "UnitreeGo1.simple")])


def test_locomujoco_humanoids_start_from_distinct_states():
    for task in ("Atlas.walk.real", "UnitreeH1.walk.real"):
        res = _evaluate(task)
        assert res["distinct_episodes"] == 3 and identical_episodes_note(res) is None


def test_body_with_reset_noise_gives_distinct_episodes_and_no_note():
    res = _evaluate("Hopper.run.perfect")
    assert res["distinct_episodes"] == 3 and res["return_std"] > 0.0
    assert identical_episodes_note(res) is None
    assert "identical" not in format_eval_table([_row(res, "Hopper.run")])
    assert identical_episodes_note({**res, "episodes": 1, "distinct_episodes": 1}) is None  # one episode: nothing to say
