"""Evaluation episodes on every body of the leaderboard grids start from seeded, distinct states: episode i gets
the same start in every evaluation of every run, and two episodes differ (so the spread over episodes measures
the policy, not a repeated episode)."""
from __future__ import annotations

import numpy as np
import pytest

from loco_il import LocoEnv
from loco_il.benchmark.protocol import load_protocol
from loco_il.evaluation import evaluate_policy

#: one Task-ID per (body, task) of the shipped protocols' grids (the dataset type does not change the starts)
GRID = sorted({task: f"{task}.{part.dataset}" for part in load_protocol("small").parts for task in part.tasks}.values())


class StartRecorder:
    """The env, with the observation after each reset recorded and every episode cut after one step."""

    def __init__(self, env):
        self.env, self.starts = env, []
        self.info = env.info

    def seed(self, seed: int) -> None:
        self.env.seed(seed)

    def reset(self):
        obs = self.env.reset()
        self.starts.append(np.array(obs, dtype=np.float64))
        return obs

    def step(self, action):
        obs, reward, _, info = self.env.step(action)
        return obs, reward, True, info


def _starts(task_id: str, episodes: int) -> np.ndarray:
    env = LocoEnv.make(task_id, seed=123)
    try:
        rec = StartRecorder(env)
        zero = np.zeros(env.info.action_space.shape)
        evaluate_policy(rec, lambda obs: zero, episodes, seed=1000)
        return np.array(rec.starts)
    finally:
        env.stop()


def test_the_grid_covers_every_body():
    bodies = {t.split(".")[0] for t in GRID}
    assert bodies == {"Atlas", "UnitreeH1", "UnitreeG1", "Talos", "HumanoidTorque", "UnitreeA1", "Hopper", "Walker2d",
                      "HalfCheetah", "Ant", "Humanoid"}


@pytest.mark.parametrize("task_id", GRID)
def test_evaluation_starts_are_seeded_and_distinct(task_id):
    first, again = _starts(task_id, 3), _starts(task_id, 3)
    assert np.array_equal(first, again)                               # episode i: the same start in every run
    for i in range(3):
        for j in range(i + 1, 3):
            assert not np.allclose(first[i], first[j]), f"{task_id}: episodes {i} and {j} start alike"


def test_unitree_a1_start_differs_in_its_pose_not_only_its_command():
    """UnitreeA1.hard draws a walking direction per episode; its body itself must start apart as well."""
    starts = _starts("UnitreeA1.simple.real", 2)
    pose = slice(0, starts.shape[1] - 3)                             # the last three entries: the command
    assert not np.allclose(starts[0][pose], starts[1][pose])
    assert np.abs(starts[0][pose] - starts[1][pose]).max() < 0.05    # small noise around the keyframe
