"""What a tracking policy's action means in the env: a phase clock and PD targets around the reference.

The policy sees the env observation plus (sin, cos) of the reference phase and outputs one number per actuator
in [-1, 1]: an offset of that joint's PD target from the reference pose, `target = q_ref + action_scale * a`
(DeepMimic, Peng et al. 2018, sec. 6: actions are PD targets; as an offset from the reference, a zero action
already follows the motion). The env's action space does not change: this controller turns the targets into
the env's normalized actions once per env step, and the env holds them over its physics substeps:

* torque motors: `tau = kp (target - q) + kd (dq_ref - dq)` from the state at the start of the step, toward the
  reference at the end of the step; `action = (tau / gear - centre) / half-range` (clipped by the env);
* position servos (biastype affine with bias = -kp q): the target itself, normalized to the control range.

The same object serves the training env (`env.TrackingEnv`) and the shipped expert (`expert.TrackingExpert`),
so training and deployment cannot differ.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping

import mujoco
import numpy as np

from loco_il.environments.base import action_map
from loco_il.experts.tracking.reference import ReferenceMotion
from loco_il.experts.tracking.settings import TrackingSettings

PHASE_FEATURES = 2     # sin and cos of the phase, appended to the observation


def servo_mask(model: mujoco.MjModel) -> np.ndarray:
    """True for position servos (gain kp on ctrl, bias -kp on the joint position), False for motors."""
    affine = model.actuator_biastype == mujoco.mjtBias.mjBIAS_AFFINE
    kp = model.actuator_gainprm[:, 0]
    return affine & np.isclose(model.actuator_biasprm[:, 1], -kp) & (kp > 0)


def full_mass_matrix(model: mujoco.MjModel, data: mujoco.MjData, out: np.ndarray | None = None) -> np.ndarray:
    """The dense joint-space inertia matrix M(q) of `data` (after `mj_forward` or `mj_step`)."""
    out = np.zeros((model.nv, model.nv)) if out is None else out
    try:
        mujoco.mj_fullM(model, data, out)           # MuJoCo >= 3.3.3: (m, d, dst)
    except TypeError:
        mujoco.mj_fullM(model, out, data.qM)        # earlier 3.x: (m, dst, M)
    return out


def pd_gains(model: mujoco.MjModel, reference: ReferenceMotion, settings: TrackingSettings) -> tuple[np.ndarray, np.ndarray]:
    """(kp, kd) per actuator for the torque motors (zeros for servos, which have their own).

    kp = peak torque / kp_angle; kd = damping_ratio * 2 sqrt(kp I), I the joint's diagonal entry of the mass
    matrix at the reference's first pose (its own inertia with the others locked)."""
    center, half = action_map(model)
    peak = (np.abs(center) + half) * np.abs(model.actuator_gear[:, 0])
    data = mujoco.MjData(model)
    data.qpos[:] = reference.qpos[0]
    mujoco.mj_forward(model, data)
    inertia = np.diag(full_mass_matrix(model, data))[reference.actuated_qvel]
    kp = peak / settings.kp_angle
    kd = settings.damping_ratio * 2.0 * np.sqrt(kp * inertia)
    servo = servo_mask(model)
    return np.where(servo, 0.0, kp), np.where(servo, 0.0, kd)


def stable_pd_torques(model: mujoco.MjModel, data: mujoco.MjData, dofs: np.ndarray, kp: np.ndarray, kd: np.ndarray,
                      q_target: np.ndarray, dq_target: np.ndarray, q: np.ndarray, dt: float) -> np.ndarray:
    """Stable PD (Tan, Liu & Turk 2011, "Stable Proportional-Derivative Controllers", sec. 3.2): the PD law
    evaluated at the state one `dt` ahead, with the acceleration that the torque itself causes,

        (M + Kd dt) ddq = -C - Kp (q + dq dt - q_target) - Kd (dq - dq_target)
        tau = -Kp (q + dq dt - q_target) - Kd (dq + ddq dt - dq_target)

    on the dofs `dofs` (the other dofs have no gains). Stable for any gains when the torque is held for `dt`
    (here a whole env step, over the env's physics substeps), which plain PD at 100 Hz is not for a light
    foot with the gains a stance leg needs. Contact forces are left out of the prediction (as in the paper)."""
    nv = model.nv
    Kp, Kd = np.zeros(nv), np.zeros(nv)
    Kp[dofs], Kd[dofs] = kp, kd
    qv = data.qvel
    p_err = np.zeros(nv)
    p_err[dofs] = q + qv[dofs] * dt - q_target
    d_err = qv.copy()
    d_err[dofs] -= dq_target
    mass = full_mass_matrix(model, data)
    mass[np.diag_indices(nv)] += Kd * dt
    ddq = np.linalg.solve(mass, -(data.qfrc_bias - data.qfrc_passive) - Kp * p_err - Kd * d_err)
    return (-Kp * p_err - Kd * (d_err + ddq * dt))[dofs]


@dataclass
class TrackingController:
    """Phase clock + PD-target conversion for one robot (see the module docstring)."""

    reference: ReferenceMotion
    settings: TrackingSettings
    control_dt: float
    kp: np.ndarray
    kd: np.ndarray
    gear: np.ndarray
    center: np.ndarray
    half: np.ndarray
    servo: np.ndarray
    phase: float = 0.0
    rate: float = 1.0           # phase clock speed relative to the reference's (see `start`)

    @classmethod
    def for_model(cls, model: mujoco.MjModel, reference: ReferenceMotion, settings: TrackingSettings,
                  control_dt: float) -> "TrackingController":
        kp, kd = pd_gains(model, reference, settings)
        center, half = action_map(model)
        return cls(reference, settings, float(control_dt), kp, kd, model.actuator_gear[:, 0].copy(), center, half,
                   servo_mask(model))

    @property
    def phase_step(self) -> float:
        return self.control_dt / self.reference.period

    def start_phase_of(self, qpos: np.ndarray) -> float:
        """The phase an episode starting in `qpos` (away from the reference) starts the clock at: the nearest one,
        or of two about equally near, the one nearer `settings.start_phase`."""
        return self.reference.nearest_phase(qpos, prefer=self.settings.start_phase)

    def start(self, phase: float, data: mujoco.MjData) -> None:
        """Start the clock at `phase` in the state `data`: the PD targets begin at the start pose and velocities and
        blend into the reference over `ramp_time` seconds (a smoothstep of the start's offset from the reference,
        nothing when the episode starts on the reference; ours: from standing, full reference targets at once
        topple the robot within 0.2 s). With `clock_ramp_time` > 0 the clock itself starts at the start state's
        forward speed relative to the reference's (0 from standing, ~1 on the reference) and reaches full rate
        over `clock_ramp_time` seconds, so the reference accelerates with the body instead of running away; the
        rate is then multiplied by `speed_gain`, reached from 1 over `speed_gain_time` seconds."""
        self.phase = float(phase)
        self._elapsed = 0.0
        # the root's first dof is its forward (x) slide (LocoMuJoCo) or the free joint's world x velocity
        speed_ratio = float(data.qvel[0]) / max(self.reference.speed, 1e-6)
        self._rate0 = 1.0 if self.settings.clock_ramp_time <= 0 else float(np.clip(speed_ratio, 0.0, 1.0))
        self.rate = self._rate0
        q_ref, dq_ref = self.reference.targets(self.phase)
        ref = self.reference
        self._q_offset = data.qpos[ref.actuated_qpos] - q_ref
        self._dq_offset = data.qvel[ref.actuated_qvel] - dq_ref

    def policy_obs(self, obs: np.ndarray) -> np.ndarray:
        angle = 2.0 * np.pi * self.phase
        return np.concatenate([np.asarray(obs, dtype=np.float64), [np.sin(angle), np.cos(angle)]])

    def env_action(self, policy_action: np.ndarray, model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
        """The env action for this step (targets at the end of the step); then advances the phase."""
        ref = self.reference
        self._elapsed += self.control_dt
        settings = self.settings
        self.rate = (_smoothstep_from(self._rate0, self._elapsed, settings.clock_ramp_time)
                     * _smoothstep_from(1.0, self._elapsed, settings.speed_gain_time, end=settings.speed_gain))
        phase_step = self.rate * self.phase_step
        q_ref, dq_ref = ref.targets(self.phase + phase_step)
        dq_ref = self.rate * dq_ref
        ramp = self.settings.ramp_time
        if ramp > 0 and self._elapsed < ramp:
            x = self._elapsed / ramp
            keep = 1.0 - x * x * (3.0 - 2.0 * x)
            q_ref, dq_ref = q_ref + keep * self._q_offset, dq_ref + keep * self._dq_offset
        target = q_ref + self.settings.action_scale * np.clip(np.asarray(policy_action, dtype=np.float64), -1, 1)
        tau = stable_pd_torques(model, data, ref.actuated_qvel, self.kp, self.kd, target, dq_ref,
                                data.qpos[ref.actuated_qpos], self.control_dt)
        ctrl = np.where(self.servo, target, tau / np.where(self.gear == 0, 1.0, self.gear))
        self.phase += phase_step
        return np.clip((ctrl - self.center) / self.half, -1.0, 1.0)

    # ------------------------------------------------------------------ (de)serialization
    ARRAYS = ("kp", "kd", "gear", "center", "half", "servo")

    def to_dict(self) -> dict[str, Any]:
        import torch
        out: dict[str, Any] = {k: torch.from_numpy(np.ascontiguousarray(getattr(self, k))) for k in self.ARRAYS}
        out.update(reference=self.reference.to_dict(), settings=self.settings.to_dict(), control_dt=self.control_dt)
        return out

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> "TrackingController":
        arrays = {k: np.asarray(d[k].numpy()) for k in cls.ARRAYS}
        return cls(ReferenceMotion.from_dict(d["reference"]), TrackingSettings.from_mapping(d["settings"]),
                   float(d["control_dt"]), **arrays)

    def digest_bytes(self) -> bytes:
        parts = [np.ascontiguousarray(getattr(self, k)).tobytes() for k in self.ARRAYS]
        parts += [self.reference.digest_bytes(), repr(self.settings.digest_items()).encode(),
                  repr(self.control_dt).encode()]
        return b"".join(parts)


def _smoothstep_from(start: float, elapsed: float, duration: float, end: float = 1.0) -> float:
    """`start` moving smoothly to `end` over `duration` seconds (`end` at once when duration <= 0)."""
    if duration <= 0 or elapsed >= duration:
        return end
    x = elapsed / duration
    return start + (end - start) * x * x * (3.0 - 2.0 * x)
