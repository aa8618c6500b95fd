"""Headless rendering (MUJOCO_GL=egl) and the mp4 episode recorder."""
import gymnasium as gym
import imageio.v3 as iio
import numpy as np

import loco_il  # noqa: F401
from loco_il import LocoEnv
from loco_il.environments.rendering import record_episode


def test_rgb_array_frames_show_the_scene():
    env = gym.make("LocoMujoco", env_name="Hopper.run.perfect", render_mode="rgb_array")
    env.reset(seed=0)
    frame = env.render()
    assert frame.shape == (480, 640, 3) and frame.dtype == np.uint8
    assert frame.std() > 10          # not a blank image
    env.step(env.action_space.sample())
    assert env.render().shape == frame.shape
    env.close()


def test_record_episode_writes_a_playable_mp4(tmp_path):
    env = LocoEnv.make("Hopper", seed=0, render_size=(120, 160))
    out = record_episode(env, None, tmp_path / "hopper.mp4", max_steps=15)
    frames = iio.imread(out["path"])
    assert frames.shape[0] == out["steps"] + 1 and frames.shape[1:3] == (120, 160)
    assert not list(tmp_path.glob(".*tmp*"))      # written atomically: no temp file left behind


def test_record_episode_writes_a_strip_of_frames_and_calls_the_start_hook(tmp_path):
    class Zero:
        started = None

        def start_episode(self, env, seed):
            self.started = seed

        def __call__(self, obs):
            return np.zeros(3)

    env = LocoEnv.make("Hopper", render_size=(60, 80))
    policy = Zero()
    out = record_episode(env, policy, None, max_steps=10, seed=7, strip=tmp_path / "strip.png", strip_frames=4)
    assert policy.started == 7 and out["path"] is None
    strip = iio.imread(out["strip"])
    assert strip.shape[:2] == (60, 4 * 80) and strip.std() > 5
