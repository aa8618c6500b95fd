"""`TrackingTrainer`: PPO that learns to track the task's reference motion (`algo=tracking`).

    python -m loco_il.experts train task=Atlas.walk algo=tracking total_steps=20000000

The PPO learner, the loop, checkpoints (resumable), evaluations and snapshots are `ppo.PPOTrainer`'s; this class
swaps the envs for `env.TrackingEnv` (training: reference state initialization, tracking reward, early
termination; evaluation: the task env's own starts and reward, so `evals.jsonl` and `best.pt` rank policies by
the task return) and ships `expert.TrackingExpert` files (policy + reference + PD conversion) as `best.pt`,
`final.pt` and `snapshots/`. The reference (`reference.build_reference`, time-scaled to the task's target speed)
is built once and kept in the checkpoint, so a resumed run tracks exactly the same motion.

Options: those of `ppo.TrainConfig` plus `tracking` (a mapping of `settings.TrackingSettings` fields), set in
`configs/algo/tracking.yaml`, the `tracking:` section of `configs/body/<Body>.yaml`, or on the command line
(`tracking.rsi_fraction=0.9`).
"""
from __future__ import annotations

import functools
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Mapping

import numpy as np
import torch

from loco_il.experts.ppo import PPOTrainer, TrainConfig
from loco_il.experts.tracking.controller import PHASE_FEATURES, TrackingController
from loco_il.experts.tracking.env import make_tracking_env
from loco_il.experts.tracking.expert import TrackingExpert
from loco_il.experts.tracking.reference import build_reference
from loco_il.experts.tracking.settings import TrackingSettings


@dataclass
class TrackingConfig(TrainConfig):
    """`ppo.TrainConfig` plus the tracking options."""

    algo: str = "tracking"
    tracking: Mapping[str, Any] = field(default_factory=dict)
    # a new run may start from another tracking run's networks, optimizers and normalizers (`checkpoint.pt` of
    # the same task and network shapes) while its expert settings differ (e.g. clock_ramp_time): the learned
    # tracking carries over; the steps count from 0 and the file is named in every expert's metadata
    init_from: str | None = None

    def to_dict(self) -> dict[str, Any]:
        d = super().to_dict()
        d["tracking"] = dict(self.tracking)
        return d


def task_target_speed(env: Any) -> float | None:
    """The forward speed the task's reward asks for (LocoMuJoCo's walk 1.25 m/s, run 2.5 m/s), if it has one."""
    target = getattr(env.task.reward, "target", None)
    return float(target) if target is not None else None


class TrackingTrainer(PPOTrainer):
    """See the module docstring."""

    config_class = TrackingConfig
    name = "motion tracking (PPO)"

    def build(self) -> None:
        from loco_il.environments import LocoEnv
        settings = TrackingSettings.from_mapping(self.cfg.tracking)
        env = LocoEnv.make(self.task_id, **self.cfg.env_kwargs)
        try:
            speed = settings.target_speed if settings.target_speed is not None else task_target_speed(env)
            reference = build_reference(env, target_speed=speed)
            self.controller = TrackingController.for_model(env.model, reference, settings, env.dt)
        finally:
            env.stop()
        self.obs_dim += PHASE_FEATURES
        super().build()
        if self.cfg.init_from and not self.ckpt_path.exists():
            self._init_networks_from(Path(self.cfg.init_from))

    def _init_networks_from(self, path: Path) -> None:
        if not path.is_file():
            raise ValueError(f"init_from={path}: no such file; give a tracking run's checkpoint.pt")
        data = torch.load(path, map_location="cpu", weights_only=True)
        if data.get("algo") != "tracking" or data.get("task_id") != self.task_id:
            raise ValueError(f"init_from={path} is a {data.get('algo')} run of {data.get('task_id')}, not a tracking "
                             f"run of {self.task_id}")
        for key in self.cfg.RESUME_FIXED:
            if data["config"].get(key) != self.cfg.to_dict()[key]:
                raise ValueError(f"init_from={path}: its {key} is {data['config'].get(key)!r}, this run's "
                                 f"{self.cfg.to_dict()[key]!r}")
        agent = {k: v for k, v in data["agent"].items() if k != "controller"}
        super().load_learner_state(agent)
        self.log(f"[tracking] networks and normalizers from {path} (its step {data['step']})")

    def describe(self) -> str:
        ref = self.controller.reference
        return (f"{super().describe()}; tracking {ref.source} at {ref.speed:.2f} m/s "
                f"(x{ref.time_scale:.2f}, period {ref.period:.3f} s)")

    def learner_state(self) -> dict[str, Any]:
        return {**super().learner_state(), "controller": self.controller.to_dict()}

    def load_learner_state(self, state: Mapping[str, Any]) -> None:
        """The checkpoint's reference and gains; its training-only settings give way to this run's config."""
        state = dict(state)
        controller = TrackingController.from_dict(state.pop("controller"))
        controller.settings = controller.settings.for_resume(TrackingSettings.from_mapping(self.cfg.tracking))
        self.controller = controller
        super().load_learner_state(state)

    def metadata(self, ev: Mapping[str, Any] | None) -> dict[str, Any]:
        out = super().metadata(ev)
        if self.cfg.init_from:
            out["init_from"] = str(self.cfg.init_from)
        return out

    def make_envs(self, num_envs: int, purpose: str):
        factory = functools.partial(make_tracking_env, controller_state=self.controller.to_dict(), mode=purpose)
        return self._make_vec(self.task_id, num_envs, self.cfg.async_envs, autoreset=True,
                              env_kwargs=self.cfg.env_kwargs, factory=factory)

    def eval_act(self, expert: TrackingExpert) -> Callable[[np.ndarray], np.ndarray]:
        return expert.policy.act          # the evaluation envs take the policy's PD offsets themselves

    def make_expert(self, metadata: Mapping[str, Any] | None = None) -> TrackingExpert:
        controller = TrackingController.from_dict(self.controller.to_dict())   # its own phase clock
        return TrackingExpert(super().make_expert(metadata), controller, metadata)
