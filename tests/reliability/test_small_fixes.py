"""Item 9: algorithm suggestions that `algo=` accepts, `LocoEnv.close()`, huge finite actions, the note on
identical evaluation episodes only where the starts are identical."""
from __future__ import annotations

import re

import numpy as np
import pytest
from train_helpers import ROOT, TASK

from loco_il.environments.registry import make


def test_every_suggested_algorithm_is_an_algo_choice():
    from loco_il.algorithms.factory import get_algorithm
    with pytest.raises(ValueError) as err:
        get_algorithm("bc").check_dataset_type("real")
    suggested = re.findall(r"algo=(\w+)", str(err.value))
    assert "lsiqfo" in suggested
    choices = {p.stem for p in (ROOT / "experiment_configs" / "algo").glob("*.yaml")}
    assert set(suggested) <= choices, set(suggested) - choices


def test_lsiqfo_is_an_algo_choice():
    from hydra import compose, initialize_config_dir
    with initialize_config_dir(config_dir=str(ROOT / "experiment_configs"), version_base="1.3"):
        cfg = compose("config", overrides=["algo=lsiqfo"])
    assert cfg.algo.name == "lsiqfo" and cfg.algo.params.critic_hidden


def test_close_and_huge_finite_actions():
    env = make("Hopper.run.perfect")
    env.reset()
    obs, *_ = env.step(np.array([1.7e308, 1.7e308, 0.0]))   # finite (their sum is not): clipped to 1
    assert np.isfinite(obs).all()
    with pytest.raises(ValueError, match="NaN or inf"):
        env.step(np.array([0.0, np.inf, 0.0]))
    env.close()
    env.close()   # twice is fine, as stop() is


def test_no_identical_episodes_note_where_starts_differ():
    """A policy that balances every InvertedPendulum episode to 1000 gets equal returns from different
    (noisy) starts: no note claiming the env starts without reset noise."""
    from loco_il.evaluation import evaluate_policy, identical_episodes_note
    gains = np.array([1.0, 10.0, 1.0, 1.0]) / 3.0
    env = make(TASK)
    res = evaluate_policy(env, lambda obs: np.clip([gains @ obs], -1, 1), 3)
    env.stop()
    assert res["returns"] == [1000.0] * 3
    assert res["distinct_episodes"] == 3 and identical_episodes_note(res) is None
