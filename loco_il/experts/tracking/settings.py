"""Options of motion tracking (reward, start states, termination, PD targets), one dataclass for all of them.

Defaults follow DeepMimic (Peng et al. 2018, "DeepMimic: Example-Guided Deep Reinforcement Learning of
Physics-Based Character Skills", sec. 5 and 6): reward weights 0.65 pose + 0.1 velocity + 0.15 end-effector +
0.1 centre-of-mass (here: the root body), each term exp(-k * squared error) with k = 2, 0.1, 40, 10; reference
state initialization (RSI) and early termination (ET). Where DeepMimic has no number, the choice is ours and
says so. Per-body values go in the `tracking:` key of `loco_il/experts/configs/body/<Body>.yaml`.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any, Mapping


@dataclass(frozen=True)
class TrackingSettings:
    # reward: weight and scale of each term (DeepMimic eq. 6-10)
    w_pose: float = 0.65
    w_vel: float = 0.1
    w_ee: float = 0.15
    w_root: float = 0.1
    w_task: float = 0.0          # the env's task reward added with this weight (ours; 0 = tracking only)
    k_pose: float = 2.0
    k_vel: float = 0.1
    k_ee: float = 40.0
    k_root: float = 10.0
    # start states: a fraction of training episodes start in the reference state at a uniform random phase
    # (RSI), the rest from the env's own start (standing; ours: the expert must also start from there; Atlas fell
    # from 50 of 50 standing starts after training with 0.8, from 20 of 50 with 0.5, from 7 of 50 with 0.3)
    rsi_fraction: float = 0.3
    rsi_noise: float = 0.02      # uniform noise on RSI joint positions (rad or m) and velocities (ours)
    # early termination: the task's fall rule, plus the root drifting this far (m) from the reference (ours)
    max_root_error: float = 0.6
    # PD targets: target = reference + action_scale * action; motor torques by stable PD (Tan et al. 2011,
    # which DeepMimic uses too) with kp, kd below
    action_scale: float = 0.5    # rad per unit action (ours)
    kp_angle: float = 0.25       # kp = peak torque / kp_angle: the error (rad) that saturates the motor (ours;
    #                              zero-action tracking on Atlas from RSI lasts ~1.0 s with 0.25, ~0.6 s with 0.5)
    damping_ratio: float = 1.0   # kd = ratio * 2 sqrt(kp * I), I the joint's own inertia at the reference pose
    ramp_time: float = 0.5       # s over which PD targets blend from the start state into the reference (ours)
    clock_ramp_time: float = 0.0  # s over which the phase clock speeds up from the start's own forward speed to
    #                              the reference's (ours; 0: full rate at once, so from standing the reference runs
    #                              off at full speed and a body that cannot keep up hits max_root_error)
    target_speed: float | None = None   # time-scale the reference to this speed (None: the task's target)
    speed_gain: float = 1.0      # the phase clock's rate once walking, relative to the reference's (ours: a
    #                              tracker lags its reference, Atlas's by ~5 % in speed; a gain > 1 plays the
    #                              reference that much faster without retraining)
    speed_gain_time: float = 0.0  # s over which the gain rises from 1 (a smoothstep; slow, so that the start,
    #                              where a body falls if anything is new, sees the clock it was trained with)
    start_phase: float | None = None  # a start pose that two reference phases match about equally well (a standing
    #                              pose lies between the two double-support poses, half a period apart) starts the
    #                              clock at the one nearer this phase; None: the nearest phase, which the reset
    #                              noise then picks (ours: UnitreeH1 fell from 18 of 30 standing starts at one of
    #                              its two start phases and from 0 of 30 at the other)

    #: what the shipped expert's actions depend on (fixed for a run); the other fields only shape training
    EXPERT_FIELDS = ("action_scale", "kp_angle", "damping_ratio", "ramp_time", "target_speed", "clock_ramp_time",
                     "speed_gain", "speed_gain_time", "start_phase")
    #: expert fields a trained expert may change (`TrackingExpert.with_settings`): they shape only the phase clock
    #: (its start and rate) and the start's blend, not the reference, the gains or the policy's inputs
    DEPLOYMENT_FIELDS = ("ramp_time", "clock_ramp_time", "speed_gain", "speed_gain_time", "start_phase")
    #: expert fields that enter an expert's checksum only when they differ from these values (fields added after
    #: experts were trained: their files keep their checksums)
    DIGEST_DEFAULTS = {"clock_ramp_time": 0.0, "speed_gain": 1.0, "speed_gain_time": 0.0, "start_phase": None}

    def __post_init__(self) -> None:
        if self.start_phase is not None and not 0.0 <= self.start_phase < 1.0:
            raise ValueError(f"tracking.start_phase must be a phase in [0, 1) or null, got {self.start_phase}")

    def digest_items(self) -> list[tuple[str, Any]]:
        """(name, value) of the expert fields that identify an expert (part of its checksum)."""
        return [(k, getattr(self, k)) for k in self.EXPERT_FIELDS
                if k not in self.DIGEST_DEFAULTS or getattr(self, k) != self.DIGEST_DEFAULTS[k]]

    def for_resume(self, current: "TrackingSettings") -> "TrackingSettings":
        """These (a checkpoint's) settings with `current`'s training-only fields (reward, start states, early
        termination may change when a run is resumed); ValueError naming an expert field that differs."""
        for name in self.EXPERT_FIELDS:
            if getattr(self, name) != getattr(current, name):
                raise ValueError(f"cannot resume: tracking.{name} was {getattr(self, name)!r}, now "
                                 f"{getattr(current, name)!r} (it changes the expert's actions; use another out_dir)")
        return current

    @classmethod
    def from_mapping(cls, values: Mapping[str, Any] | None) -> "TrackingSettings":
        values = dict(values or {})
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(values) - names)
        if unknown:
            raise ValueError(f"unknown tracking option(s) {unknown}; known: {sorted(names)}")
        return cls(**values)

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)
