"""`TrackingExpert`: a trained tracking policy as an env-level expert of the task's own env.

It acts in the plain task env (e.g. `Atlas.walk.perfect`): each step it appends the reference phase to the
observation, runs the policy (`ExpertPolicy`, deterministic by default) and turns the PD-target offsets into the
env's action (`controller.TrackingController`); datasets record only the env's observations and actions. It
keeps a phase clock, so it follows the expert contract of `loco_il.datasets.providers.expert`: the rollout calls
`start_episode(env, seed)` after every `env.reset()`, and the expert starts its clock at the reference phase
nearest to the env's start pose. It reads `env.model` / `env.data` and never writes them.

File format (`torch.load(path, weights_only=True)`; plain tensors, dicts, lists, strings, numbers):

    {"format": "loco_il.tracking_expert/v1",
     "policy": <ExpertPolicy file dict>, "controller": <TrackingController.to_dict()>, "metadata": {...}}
"""
from __future__ import annotations

import dataclasses
import hashlib
import os
import time
from pathlib import Path
from typing import Any, Callable, Mapping

import numpy as np

from loco_il.experts.policy import ExpertPolicy
from loco_il.experts.tracking.controller import PHASE_FEATURES, TrackingController
from loco_il.experts.tracking.settings import TrackingSettings
from loco_il.utils.atomic import atomic_torch_save
from loco_il.utils.plain import to_plain

FORMAT = "loco_il.tracking_expert/v1"


class TrackingExpert:
    """A tracking policy + its reference and PD conversion (see the module docstring)."""

    def __init__(self, policy: ExpertPolicy, controller: TrackingController,
                 metadata: Mapping[str, Any] | None = None):
        self.policy = policy
        self.controller = controller
        self.obs_dim = policy.obs_dim - PHASE_FEATURES     # the env's observation size
        self.act_dim = policy.act_dim
        self.metadata: dict[str, Any] = dict(policy.metadata)
        self.metadata.update(metadata or {})
        self.metadata.setdefault("algorithm", "motion tracking (PPO)")
        self.description = (f"TrackingExpert ({self.metadata.get('task_id', '?')}, "
                            f"{controller.reference.source}, {self.metadata.get('training_steps', '?')} steps)")
        self._env: Any = None

    # ------------------------------------------------------------------ policy contract
    def start_episode(self, env: Any, seed: int) -> None:
        """Follow `env` from its current (start) state: the clock starts at the nearest reference phase
        (`TrackingController.start_phase_of`)."""
        if int(env.model.nu) != self.act_dim:
            raise ValueError(f"{env.task_id} has {env.model.nu} actuators; this expert was trained for {self.act_dim}")
        self._env = env
        self.controller.start(self.controller.start_phase_of(env.data.qpos), env.data)

    def reference_start_sampler(self) -> Callable[[np.random.Generator], tuple[np.ndarray, np.ndarray]]:
        """An env `init_state_sampler`: the reference state at a uniform random phase (evaluation from the
        reference's states, as LocoMuJoCo starts its episodes from dataset states)."""
        reference = self.controller.reference

        def sample(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
            return reference.state(float(rng.random()))
        return sample

    def act(self, obs: np.ndarray, deterministic: bool = True, rng: np.random.Generator | None = None,
            noise_scale: float = 1.0) -> np.ndarray:
        if self._env is None:
            raise RuntimeError("TrackingExpert follows the simulator state: call start_episode(env, seed) after "
                               "env.reset() (loco_il.environments.episodes.run_episode does)")
        obs = np.asarray(obs, dtype=np.float64)
        if obs.shape != (self.obs_dim,):
            raise ValueError(f"expert expects one observation of size {self.obs_dim}, got shape {obs.shape}")
        offsets = self.policy.act(self.controller.policy_obs(obs), deterministic=deterministic, rng=rng,
                                  noise_scale=noise_scale)
        return self.controller.env_action(offsets, self._env.model, self._env.data)

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        return self.act(obs, deterministic=True)

    def checksum(self) -> str:
        """sha256 of the policy's checksum and the controller (reference, gains, settings)."""
        h = hashlib.sha256(self.policy.checksum().encode())
        h.update(self.controller.digest_bytes())
        return h.hexdigest()

    def with_settings(self, **changes: Any) -> "TrackingExpert":
        """A copy with other deployment settings (`TrackingSettings.DEPLOYMENT_FIELDS`, e.g. `speed_gain`); its
        metadata names the expert it derives from. ValueError for any other field."""
        other = sorted(set(changes) - set(TrackingSettings.DEPLOYMENT_FIELDS))
        if other:
            raise ValueError(f"cannot change {other} of a trained expert (they change its reference, gains or "
                             f"inputs: retrain); changeable: {list(TrackingSettings.DEPLOYMENT_FIELDS)}")
        try:      # numbers; start_phase may also be None (the nearest phase); the settings check their ranges
            values = {k: None if v is None and k == "start_phase" else float(v) for k, v in changes.items()}
        except (TypeError, ValueError):
            raise ValueError(f"deployment settings are numbers (start_phase may be None), got {changes}") from None
        settings = dataclasses.replace(self.controller.settings, **values)
        metadata = {k: v for k, v in self.metadata.items() if k not in ("checksum", "commit", "created")}
        metadata["derived_from"] = {"checksum": self.checksum(), "changes": dict(changes)}
        return TrackingExpert(self.policy, dataclasses.replace(self.controller, settings=settings), metadata)

    # ------------------------------------------------------------------ files
    def save(self, path: str | os.PathLike) -> str:
        """Write the expert atomically; returns its checksum."""
        from loco_il.experts.policy import git_commit
        self.metadata.setdefault("commit", git_commit())
        self.metadata.setdefault("created", time.strftime("%Y-%m-%dT%H:%M:%S%z"))
        self.metadata["checksum"] = self.checksum()
        atomic_torch_save({"format": FORMAT, "policy": self.policy.to_file_dict(),
                           "controller": self.controller.to_dict(), "metadata": to_plain(self.metadata)}, path)
        return self.metadata["checksum"]

    @classmethod
    def from_file_dict(cls, data: Mapping[str, Any], path: str | Path = "") -> "TrackingExpert":
        expert = cls(ExpertPolicy.from_file_dict(data["policy"]), TrackingController.from_dict(data["controller"]),
                     data.get("metadata"))
        stored = expert.metadata.get("checksum")
        if stored is not None and stored != expert.checksum():
            raise ValueError(f"{path}: checksum mismatch (file says {stored}, contents hash to {expert.checksum()})")
        return expert

    def __repr__(self) -> str:
        return (f"TrackingExpert(task_id={self.metadata.get('task_id')!r}, obs_dim={self.obs_dim}, "
                f"act_dim={self.act_dim}, eval_return={self.metadata.get('eval_return')})")
