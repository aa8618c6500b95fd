"""Every registered Task-ID passes Gymnasium's env checker, and mushroom-rl's Core runs a random
agent for an episode on every body."""
import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from mushroom_rl.core import Agent, Core

from loco_il import LocoEnv
from loco_il.environments.registry import bodies

pytestmark = pytest.mark.slow      # every task: the full suite (CI) runs them; -m "not slow" skips them

ALL_TASKS = LocoEnv.get_all_task_names()


@pytest.mark.parametrize("task_id", ALL_TASKS)
def test_gymnasium_env_checker_passes(task_id):
    env = gym.make("LocoMujoco", env_name=task_id)
    check_env(env.unwrapped, skip_render_check=True)
    env.close()


class _Uniform:
    def __init__(self, shape, seed=0):
        self.shape, self.rng = shape, np.random.default_rng(seed)

    def draw_action(self, state):
        return self.rng.uniform(-1, 1, self.shape)

    def reset(self):
        pass


@pytest.mark.parametrize("body", sorted(bodies()))
def test_mushroom_core_random_episode_on_every_body(body):
    env = LocoEnv.make(body, seed=0)
    env.info.horizon = 200   # an episode ends at a fall or at 200 steps: enough to exercise the loop
    agent = Agent(env.info, _Uniform(env.info.action_space.shape))
    dataset = Core(agent, env).evaluate(n_episodes=1, quiet=True)
    assert dataset[-1][-1] and 1 <= len(dataset) <= 200
    assert all(np.isfinite(step[3]).all() for step in dataset)
