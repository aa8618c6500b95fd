"""`evaluate_policy` counts the episodes that ended in a terminal state (a fall) apart from those cut by the horizon."""
from __future__ import annotations

import numpy as np

from loco_il.environments.registry import make
from loco_il.evaluation import evaluate_policy


def test_terminated_counts_the_falls_not_the_horizon_cuts():
    env = make("Hopper.run.perfect")
    try:
        zero = np.zeros(env.info.action_space.shape)
        fell = evaluate_policy(env, lambda obs: zero, 3, seed=1000)
        env.info.horizon = 5          # too short to fall: every episode is cut, none terminates
        cut = evaluate_policy(env, lambda obs: zero, 3, seed=1000)
    finally:
        env.stop()
    assert fell["terminated"] == 3 and max(fell["lengths"]) < 1000   # an unpowered hopper falls over
    assert cut["terminated"] == 0 and cut["lengths"] == [5, 5, 5]


def test_evaluation_starts_a_clocked_policy_after_every_reset():
    """A policy with a `start_episode` hook (an expert with a phase clock) is started like in the datasets."""
    from loco_il.environments.episodes import episode_seeds

    class Started:
        def __init__(self, nu):
            self.nu, self.seeds = nu, []

        def start_episode(self, env, seed):
            self.seeds.append(seed)

        def __call__(self, obs):
            return np.zeros(self.nu)

    env = make("Hopper.run.perfect")
    try:
        env.info.horizon = 3
        policy = Started(int(env.model.nu))
        evaluate_policy(env, policy, 2, seed=1000)
    finally:
        env.stop()
    assert policy.seeds == episode_seeds(1000, 2).tolist()
