"""Gymnasium interface: `gymnasium.make("LocoMujoco", env_name="UnitreeH1.walk.real")`.

Unlike LocoMuJoCo 0.4.1's wrapper: `reset(seed=...)` makes resets reproducible, `truncated` is
True at the horizon, and `unwrapped` is this Gymnasium env (the mushroom-rl env is `.loco_env`).
"""
from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np

from loco_il.environments.base import LocoEnv


class LocoGymEnv(gym.Env):
    metadata = {"render_modes": ["human", "rgb_array"], "render_fps": 100}

    def __init__(self, env_name: str, render_mode: str | None = None, **kwargs: Any):
        self.loco_env: LocoEnv = LocoEnv.make(env_name, render_mode=render_mode, **kwargs)
        self.render_mode = render_mode
        self.metadata = dict(self.metadata, render_fps=int(round(1.0 / self.loco_env.dt)))
        obs_dim = self.loco_env.obs_spec.dim
        act_dim = self.loco_env.info.action_space.shape[0]
        self.observation_space = gym.spaces.Box(-np.inf, np.inf, (obs_dim,), np.float64)
        self.action_space = gym.spaces.Box(-1.0, 1.0, (act_dim,), np.float32)
        self._horizon = self.loco_env.info.horizon
        self._t = 0

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        if seed is not None:
            self.loco_env.seed(seed)
        state = (options or {}).get("state")
        obs = self.loco_env.reset(state)
        self._t = 0
        return obs, {}

    def step(self, action):
        obs, reward, terminated, info = self.loco_env.step(action)
        self._t += 1
        truncated = not terminated and self._t >= self._horizon
        return obs, reward, terminated, truncated, info

    def render(self):
        return self.loco_env.render()

    def close(self):
        self.loco_env.stop()


def register_gymnasium() -> None:
    """Register "LocoMujoco" (idempotent); also called through the `gymnasium.envs` entry point."""
    if "LocoMujoco" not in gym.registry:
        gym.register(id="LocoMujoco", entry_point="loco_il.environments.gym_adapter:LocoGymEnv",
                     disable_env_checker=True)
