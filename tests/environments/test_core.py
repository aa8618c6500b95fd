"""The environment core: Task-IDs, the mushroom-rl and Gymnasium interfaces, bad input, determinism."""
import gymnasium as gym
import numpy as np
import pytest
from mushroom_rl.core import Agent, Core

import loco_il  # noqa: F401  (registers "LocoMujoco")
from loco_il import LocoEnv, UnknownTaskError
from loco_il.environments.registry import parse_task_id


def test_task_id_defaults_fill_missing_parts():
    assert str(parse_task_id("Hopper")) == "Hopper.run.perfect"
    assert str(parse_task_id("Hopper.run")) == "Hopper.run.perfect"
    assert str(parse_task_id("HumanoidStandup")) == "HumanoidStandup.standup.perfect"
    assert str(parse_task_id("Hopper.run.preference.pomdp")) == "Hopper.run.preference.pomdp"
    assert LocoEnv.make("Walker2d").task_id == "Walker2d.run.perfect"


@pytest.mark.parametrize("bad, expected", [
    ("Hoper.run.perfect", "Hopper.run.perfect"),
    ("Hopper.walk.perfect", "Hopper.run.perfect"),
    ("Hopper.run.perfct", "Hopper.run.perfect"),
    ("Walker2D", "Walker2d"),
])
def test_unknown_task_id_names_close_matches(bad, expected):
    with pytest.raises(UnknownTaskError) as err:
        LocoEnv.make(bad)
    assert expected in str(err.value)


def test_all_task_names_are_makeable_ids():
    names = LocoEnv.get_all_task_names()
    assert "Hopper.run.perfect" in names and "Humanoid.run.preference" in names
    assert len(names) == len(set(names))
    for name in names:
        assert str(parse_task_id(name)) == name


def test_action_mapping_reaches_each_actuator_range():
    env = LocoEnv.make("Humanoid", seed=0)
    env.reset()
    lo, hi = env.model.actuator_ctrlrange.T
    env.step(np.ones(env.model.nu))
    np.testing.assert_allclose(env.data.ctrl, hi)
    env.step(-np.ones(env.model.nu))
    np.testing.assert_allclose(env.data.ctrl, lo)
    env.step(np.full(env.model.nu, 7.0))            # out of range: clipped, documented
    np.testing.assert_allclose(env.data.ctrl, hi)


def test_observation_spec_names_match_state():
    env = LocoEnv.make("Hopper", seed=0)
    obs = env.reset()
    spec = env.obs_spec
    assert spec.dim == obs.shape[0] == 11
    assert "q_rootx" not in spec.names            # horizontal root coordinate excluded
    assert obs[spec.index("q_rootz")] == pytest.approx(env.data.qpos[1])
    assert obs[spec.index("dq_rootx")] == pytest.approx(env.data.qvel[0])
    assert env.obs_spec.slices["q_thigh_joint"] == slice(2, 3)


@pytest.mark.parametrize("action, message", [
    (np.zeros(2), "shape"),
    (np.zeros((3, 1)), "shape"),
    (np.array([0.0, np.nan, 0.0]), "NaN"),
    (np.array([0.0, np.inf, 0.0]), "NaN"),
])
def test_bad_actions_raise_clear_errors(action, message):
    env = LocoEnv.make("Hopper", seed=0)
    env.reset()
    with pytest.raises(ValueError, match=message):
        env.step(action)


def test_step_before_reset_raises():
    env = LocoEnv.make("Hopper")
    with pytest.raises(RuntimeError, match="reset"):
        env.step(np.zeros(3))


def test_diverging_simulation_ends_episode_with_flag():
    env = LocoEnv.make("Hopper", seed=0)
    obs0 = env.reset()
    qpos, qvel = env.get_sim_state()
    env.set_sim_state(qpos, qvel * 0 + 1e12)       # absurd velocities: MuJoCo flags bad qacc / non-finite state
    obs, reward, absorbing, info = env.step(np.zeros(3))
    assert info["diverged"] and absorbing and reward == 0.0
    assert np.isfinite(obs).all()
    with pytest.raises(RuntimeError, match="reset"):
        env.step(np.zeros(3))
    assert env.reset().shape == obs0.shape         # recoverable by reset


def test_seeded_resets_are_reproducible():
    a, b = LocoEnv.make("Ant", seed=3), LocoEnv.make("Ant", seed=3)
    np.testing.assert_array_equal(a.reset(), b.reset())
    c = LocoEnv.make("Ant", seed=4)
    assert not np.array_equal(a.reset(), c.reset())


def test_gymnasium_make_reset_seed_and_truncation():
    env = gym.make("LocoMujoco", env_name="InvertedPendulum.balance.perfect", render_mode=None)
    o1, _ = env.reset(seed=11)
    o2, _ = env.reset(seed=11)
    np.testing.assert_array_equal(o1, o2)
    assert env.unwrapped is not env.unwrapped.loco_env and env.unwrapped.loco_env.task_id.startswith("Inverted")
    # hold the pole upright with a stabilizing controller until the horizon: truncated, not terminated
    env.unwrapped.loco_env.info.horizon = 20
    env.unwrapped._horizon = 20
    for t in range(20):
        obs, r, term, trunc, _ = env.step(np.array([0.0], dtype=np.float32))
        if term:
            break
    assert trunc and not term and t == 19


def test_mushroom_core_runs_a_random_agent_episode():
    env = LocoEnv.make("Walker2d", seed=0)

    class RandomPolicy:
        def draw_action(self, state):
            return np.random.uniform(-1, 1, env.info.action_space.shape)

        def reset(self):
            pass

    agent = Agent(env.info, RandomPolicy())
    dataset = Core(agent, env).evaluate(n_episodes=2, quiet=True)
    assert sum(step[-1] for step in dataset) == 2
    assert all(s[0].shape == (env.obs_spec.dim,) for s in dataset)
