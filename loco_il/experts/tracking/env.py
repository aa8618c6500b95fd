"""`TrackingEnv`: a Gymnasium env in which a policy learns to track the reference motion of a task.

Observation: the task env's observation plus (sin, cos) of the reference phase. Action: PD-target offsets
(`controller.TrackingController`), turned into the task env's own actions. Two modes:

* `train`: a `rsi_fraction` of episodes start in the reference state at a uniform random phase, with small
  noise (reference state initialization); the others start from the env's own start state at the reference
  phase nearest to it. Reward: the tracking reward (`reward.TrackingReward`). Episodes also end when the root
  strays `max_root_error` metres from the reference (early termination), besides the task's fall rule.
* `eval`: the env's own start states, the task's reward and termination: what the shipped expert faces.
"""
from __future__ import annotations

from typing import Any, Mapping

import gymnasium as gym
import numpy as np

from loco_il.experts.tracking.controller import PHASE_FEATURES, TrackingController
from loco_il.experts.tracking.reward import TrackingReward

MODES = ("train", "eval")


class TrackingEnv(gym.Env):
    """See the module docstring. `controller_state` is `TrackingController.to_dict()` (picklable for workers)."""

    def __init__(self, task_id: str, controller_state: Mapping[str, Any], mode: str = "train",
                 env_kwargs: Mapping[str, Any] | None = None):
        from loco_il.environments import LocoEnv
        if mode not in MODES:
            raise ValueError(f"mode must be one of {MODES}, got {mode!r}")
        self.mode = mode
        self.loco_env = LocoEnv.make(task_id, **dict(env_kwargs or {}))
        self.controller = TrackingController.from_dict(controller_state)
        self.settings = self.controller.settings
        self.reward = TrackingReward(self.loco_env.model, self.controller.reference, self.settings)
        obs_dim = self.loco_env.obs_spec.dim + PHASE_FEATURES
        self.observation_space = gym.spaces.Box(-np.inf, np.inf, (obs_dim,), np.float64)
        self.action_space = gym.spaces.Box(-1.0, 1.0, (self.loco_env.model.nu,), np.float32)
        self._horizon = self.loco_env.info.horizon
        self._t = 0
        self._anchor = np.zeros(2)

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        env, ref, rng = self.loco_env, self.controller.reference, self.np_random
        if seed is not None:
            env.seed(seed)
        phase = None
        if self.mode == "eval":
            obs = env.reset()
        else:
            if rng.random() < self.settings.rsi_fraction:
                phase = float(rng.random())
                qpos, qvel = ref.state(phase)
            else:        # the env's own start, with the same small noise (robust to the env's own reset noise)
                env.reset()
                qpos, qvel = env.get_sim_state()
            noise = self.settings.rsi_noise
            qpos[ref.actuated_qpos] += rng.uniform(-noise, noise, ref.actuated_qpos.size)
            qvel = qvel + rng.uniform(-noise, noise, qvel.size)
            obs = env.reset(np.concatenate([qpos, qvel]))
        if phase is None:
            phase = self.controller.start_phase_of(env.data.qpos)
        self.controller.start(phase, env.data)
        root = env.data.xpos[self.reward.root]
        self._anchor = root[:2] - ref.kinematics(phase)[0][:2]
        self._t = 0
        return self.controller.policy_obs(obs), {}

    def step(self, action):
        env = self.loco_env
        obs, reward, terminated, info = env.step(self.controller.env_action(action, env.model, env.data))
        self._t += 1
        if self.mode == "train":
            if info.get("diverged"):
                reward = 0.0
            else:
                tracking, terms = self.reward(env.data, self.controller.phase, self._anchor,
                                              self.controller.rate)
                reward = tracking + self.settings.w_task * reward
                terminated = terminated or terms["root_error"] > self.settings.max_root_error
        truncated = not terminated and self._t >= self._horizon
        return self.controller.policy_obs(obs), float(reward), bool(terminated), truncated, info

    def close(self):
        self.loco_env.stop()


def make_tracking_env(task_id: str, *, controller_state: Mapping[str, Any], mode: str,
                      **env_kwargs: Any) -> TrackingEnv:
    """`TrackingEnv` as a vector-env factory (`loco_il.experts.vec.make_vec_env(..., factory=partial(this, ...))`;
    module level, so worker processes can unpickle it)."""
    return TrackingEnv(task_id, controller_state, mode, env_kwargs)
