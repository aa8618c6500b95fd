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
