"""Trot controller for Unitree-style quadrupeds, run in a `LocoEnv`'s simulation.

Each control step (the env's ``dt``, e.g. 10 ms) the controller

1. reads the trunk state from the simulator (position, heading ``psi``, roll/pitch, planar velocity);
2. forms the body command: velocity ``speed * (cos t, sin t)`` toward the commanded direction ``t``
   (ramped up from standing over ``ramp_time``; scaled down to ``away_speed_factor`` while the trunk
   still faces away from ``t``), plus a cross-track term that steers back onto the straight line
   through the start point in direction ``t``; and a yaw rate ``k_yaw * wrap(t - psi)`` (clipped)
   that turns the trunk toward ``t``. The velocity is tracked in any body direction, so the robot
   moves toward ``t`` while it is still turning (it side-steps / backs up, then walks forward);
3. advances the phase oscillators (`cpg.PhaseOscillators`, trot);
4. moves every foot target in the *heading frame* (yaw-aligned, origin at the trunk): stance feet
   slide backwards at the commanded body velocity plus an integral of the velocity error (so the
   mean speed settles on the command despite foot slip and tracking lag) and with the yaw rate;
   swing feet follow a raised arc from lift-off to a touchdown point chosen by Raibert's rule,
   ``p_td = p_nominal + v T_stance / 2 + k_raibert (v_measured - v_cmd)`` (plus the yaw-rate term);
   the vertical target keeps the trunk at ``body_height`` above the feet;
5. solves the analytic leg IK (`leg_ik.leg_ik`) for joint targets ``q_ref``, taking the targets as
   trunk-frame positions: feet held on a plane parallel to the trunk make the stance legs level the
   trunk on flat ground (``level_frame=True`` instead rotates the targets by the measured roll/pitch,
   which leaves the attitude uncontrolled -- kept for experiments);
6. applies them through the body's own actuators for the env's ``n_substeps`` physics steps at the
   env's timestep, the targets interpolated linearly over the substeps:
   * torque motors (LocoMuJoCo's A1): a joint PD loop at the physics rate (1 kHz),
     ``tau = Kp (q_ref - q) + Kd (dq_ref - dq) + tau_ff``, ``ctrl = tau / gear`` clipped to the
     control range (|ctrl| <= 1, i.e. the motor limits). Running the PD at the physics rate, rather
     than holding one torque for the whole 10 ms env step, is what lets stiff gains stay stable;
   * position servos (Menagerie's Go1, fixed servo gain ``kp_servo``): the target itself,
     ``ctrl = q_ref + (tau_ff + servo_kd (dq_ref - dq)) / kp_servo`` clipped to the control range
     (the offset adds the feed-forward and some damping the servos lack).
   ``tau_ff = J^T f`` is a gravity feed-forward: each stance foot pushes down with an equal share of
   the robot's weight.
   As an env-level policy (`env_step_ctrl`, used by `loco_il.experts.trot.TrotExpert`) the controls are instead
   computed once per env step from the state at its start (`held_ctrl`) and held over the substeps
   by ``env.step``; the trot still walks that way (see the expert's docstring for the numbers).

The simulation is driven directly through ``data.ctrl`` and ``mujoco.mj_step`` on the env's own
model and data (same timestep, same substeps per env step); `loco_il.datasets.gait.run_gait_episode` builds
every observation with ``env.set_sim_state`` (the env's own observation function, command features
included) and the reward and termination with the env task's own functions.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np

from loco_il.motion.gait.cpg import GaitParams, PhaseOscillators, TROT_OFFSETS, stance_velocity, swing_position
from loco_il.motion.gait.leg_ik import LegGeometry, leg_ik, leg_jacobian, quadruped_legs

GRAVITY = 9.81


def wrap_angle(a: float) -> float:
    return float((a + np.pi) % (2 * np.pi) - np.pi)


@dataclass
class ControllerParams:
    """Gains and targets of `TrotController` (SI units)."""

    speed: float = 0.5                  # m/s, commanded planar speed
    body_height: float | None = None    # m, trunk-origin height; None: the standing height at reset
    gait: GaitParams = field(default_factory=GaitParams)
    kp: float = 150.0                   # torque-motor PD gains (Nm/rad, Nm s/rad)
    kd: float = 3.0
    raibert_gain: float = 0.2           # s: touchdown shift per m/s of velocity error (~sqrt(h/g))
    yaw_gain: float = 2.0               # 1/s
    max_yaw_rate: float = 1.0           # rad/s
    away_speed_factor: float = 0.5      # speed multiplier when the trunk faces opposite to the direction
    cross_track_gain: float = 1.0       # 1/s
    max_cross_speed: float = 0.15       # m/s
    ramp_time: float = 0.5              # s, speed ramp from standing
    velocity_filter: float = 0.05       # s, time constant of the measured-velocity low-pass
    velocity_integral_gain: float = 2.0  # 1/s: integral of the velocity error added to the stance sweep
    max_velocity_integral: float = 0.3   # m/s
    stance_width: float = 0.0           # m, extra lateral foot offset (outwards)
    gravity_ff: bool = True
    servo_kd: float = 2.0               # position servos: damping (Nm s/rad) emulated by offsetting the target
    level_frame: bool = False           # see the module docstring, step 5
    ground_speed_matching: bool = True  # swing feet leave and land moving at the stance-foot velocity


class TrotController:
    """A trot through the env's actuators; see the module docstring. Use `reset`, then `step` each env step."""

    def __init__(self, env, params: ControllerParams | None = None):
        self.env = env
        self.model: mujoco.MjModel = env.model
        self.data: mujoco.MjData = env.data
        self.params = params or ControllerParams()
        self.dt = float(env.dt)
        self.n_substeps = int(env.n_substeps)
        self.legs: list[LegGeometry] = quadruped_legs(self.model)
        self.trunk = int(self.model.jnt_bodyid[0])
        self.mass = float(self.model.body_mass.sum())
        m = self.model
        self.q_adr = np.concatenate([leg.qpos_adr for leg in self.legs])
        self.v_adr = np.concatenate([leg.dof_adr for leg in self.legs])
        self.act = np.concatenate([leg.actuator_ids for leg in self.legs])
        if (self.act < 0).any():
            raise ValueError("every leg joint needs an actuator")
        gain, bias = m.actuator_gainprm[self.act, 0], m.actuator_biasprm[self.act]
        self.position_servo = bool(np.all(gain > 0) and np.allclose(bias[:, 1], -gain))
        if not self.position_servo and not np.allclose(bias[:, :3], 0):
            raise ValueError("leg actuators are neither torque motors nor position servos")
        self.servo_kp = gain.copy()
        self.gear = m.actuator_gear[self.act, 0].copy()
        limited = m.actuator_ctrllimited[self.act].astype(bool)
        self.ctrl_lo = np.where(limited, m.actuator_ctrlrange[self.act, 0], -np.inf)
        self.ctrl_hi = np.where(limited, m.actuator_ctrlrange[self.act, 1], np.inf)
        self.foot_geoms = np.array([leg.foot_geom for leg in self.legs])
        self._floor = np.array([g for g in range(m.ngeom) if m.geom_bodyid[g] == 0])
        self._vel = np.zeros(6)
        self.reset(0.0)

    # ------------------------------------------------------------------ state
    def heading(self) -> float:
        R = self.data.xmat[self.trunk].reshape(3, 3)
        return float(np.arctan2(R[1, 0], R[0, 0]))

    def _frames(self) -> tuple[float, np.ndarray, np.ndarray]:
        R = self.data.xmat[self.trunk].reshape(3, 3)
        psi = float(np.arctan2(R[1, 0], R[0, 0]))
        c, s = np.cos(psi), np.sin(psi)
        R_yaw = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        return psi, R_yaw, R_yaw.T @ R

    def trunk_velocity(self) -> np.ndarray:
        """(angular xyz, linear xyz) of the trunk in world orientation."""
        mujoco.mj_objectVelocity(self.model, self.data, mujoco.mjtObj.mjOBJ_BODY, self.trunk, self._vel, 0)
        return self._vel.copy()

    def foot_positions(self) -> np.ndarray:
        return self.data.geom_xpos[self.foot_geoms].copy()

    def foot_contacts(self) -> np.ndarray:
        """Which feet touch the floor (4,) bool."""
        ncon = self.data.ncon
        if ncon == 0:
            return np.zeros(4, dtype=bool)
        geom = self.data.contact.geom[:ncon]
        floor1, floor2 = np.isin(geom[:, 0], self._floor), np.isin(geom[:, 1], self._floor)
        others = np.concatenate([geom[floor1, 1], geom[floor2, 0]])
        return np.isin(self.foot_geoms, others)

    def contact_point_speeds(self) -> np.ndarray:
        """Horizontal speed (m/s) of each foot sphere's lowest point: the slip speed of a foot on the floor
        (unlike the sphere centre, it does not move when the foot rolls)."""
        out = np.empty(4)
        res = np.zeros(6)
        down = np.array([0.0, 0.0, -1.0])
        for i, leg in enumerate(self.legs):
            mujoco.mj_objectVelocity(self.model, self.data, mujoco.mjtObj.mjOBJ_GEOM, leg.foot_geom, res, 0)
            v = res[3:] + np.cross(res[:3], leg.foot_radius * down)
            out[i] = np.hypot(v[0], v[1])
        return out

    # ------------------------------------------------------------------ episode
    def reset(self, direction: float, rng: np.random.Generator | None = None,
              phase_jitter: float = 0.0) -> None:
        """Start from the current simulator state (call after ``env.reset()``), walking toward ``direction``."""
        mujoco.mj_kinematics(self.model, self.data)
        self.direction = float(direction)
        self.t = 0.0
        initial = TROT_OFFSETS.copy()
        if rng is not None and phase_jitter > 0:
            initial = initial + rng.uniform(-phase_jitter, phase_jitter, 4)
        # all feet are down: the (FR, RL) pair is about to lift off, the other pair is just touching down
        self.cpg = PhaseOscillators(self.params.gait, TROT_OFFSETS, initial + self.params.gait.duty - 0.02)
        self.start_xy = self.data.xpos[self.trunk, :2].copy()
        psi, R_yaw, _ = self._frames()
        rel = self.data.geom_xpos[self.foot_geoms] - self.data.xpos[self.trunk]
        feet_h = rel @ R_yaw                     # rows: R_yaw^T (foot - trunk)
        self.p_xy = feet_h[:, :2].copy()
        if self.params.body_height is None:
            radius = np.array([leg.foot_radius for leg in self.legs])
            self.body_height = float(np.mean(self.data.xpos[self.trunk, 2] - (self.data.geom_xpos[self.foot_geoms, 2]
                                                                               - radius)))
        else:
            self.body_height = float(self.params.body_height)
        self.lift_off = self.p_xy.copy()
        self.lift_off_velocity = np.zeros((4, 2))
        self.was_stance = self.cpg.in_stance()
        self.v_filt = np.zeros(2)
        self.v_int = np.zeros(2)
        self.q_ref = self.data.qpos[self.q_adr].copy()
        self.q_prev = self.q_ref.copy()
        self.tau_ff = np.zeros(12)
        self.v_cmd_world = np.zeros(2)
        self.yaw_rate_cmd = 0.0

    def nominal_xy(self, leg: LegGeometry) -> np.ndarray:
        side = np.sign(leg.hip_pos[1]) if leg.hip_pos[1] != 0 else np.sign(leg.d)
        n = leg.nominal_foot
        return np.array([n[0], n[1] + side * self.params.stance_width])

    def _command(self, psi: float) -> tuple[np.ndarray, float]:
        p = self.params
        ramp = min(1.0, self.t / p.ramp_time) if p.ramp_time > 0 else 1.0
        u = np.array([np.cos(self.direction), np.sin(self.direction)])
        normal = np.array([-u[1], u[0]])
        offset = float((self.data.xpos[self.trunk, :2] - self.start_xy) @ normal)
        cross = float(np.clip(-p.cross_track_gain * offset, -p.max_cross_speed, p.max_cross_speed))
        err = wrap_angle(self.direction - psi)
        # slower while the trunk still faces away from the direction (side-stepping / walking backwards)
        factor = 1.0 - (1.0 - p.away_speed_factor) * (1.0 - np.cos(err)) / 2.0
        v = p.speed * ramp * factor * u + ramp * cross * normal
        yaw_rate = float(np.clip(p.yaw_gain * err, -p.max_yaw_rate, p.max_yaw_rate))
        return v, yaw_rate

    def plan(self) -> None:
        """Advance the gait by one control step and compute the joint targets (no simulation)."""
        p, dt = self.params, self.dt
        psi, R_yaw, R_rp = self._frames()
        vel = self.trunk_velocity()
        v_h = (R_yaw.T @ vel[3:])[:2]
        alpha = dt / (p.velocity_filter + dt) if p.velocity_filter > 0 else 1.0
        self.v_filt = self.v_filt + alpha * (v_h - self.v_filt)
        v_world, yaw_rate = self._command(psi)
        self.v_cmd_world, self.yaw_rate_cmd = v_world, yaw_rate
        v_cmd = (R_yaw.T @ np.array([v_world[0], v_world[1], 0.0]))[:2]
        # integral of the velocity error, kept in the world frame (it survives turning)
        err_world = v_world - (R_yaw @ np.array([self.v_filt[0], self.v_filt[1], 0.0]))[:2]
        self.v_int = self.v_int + p.velocity_integral_gain * err_world * dt
        norm = np.linalg.norm(self.v_int)
        if norm > p.max_velocity_integral:
            self.v_int *= p.max_velocity_integral / norm
        v_sweep = v_cmd + (R_yaw.T @ np.array([self.v_int[0], self.v_int[1], 0.0]))[:2]

        self.cpg.step(dt)
        stance = self.cpg.in_stance()
        progress = self.cpg.swing_progress()
        t_st = p.gait.stance_time
        self.q_prev = self.q_ref.copy()
        q_ref = np.empty(12)
        tau_ff = np.zeros(12)
        n_stance = max(int(stance.sum()), 1)
        for i, leg in enumerate(self.legs):
            if stance[i]:
                self.p_xy[i] = self.p_xy[i] + stance_velocity(self.p_xy[i], v_sweep, yaw_rate) * dt
                lift = 0.0
            else:
                if self.was_stance[i]:
                    self.lift_off[i] = self.p_xy[i].copy()
                    self.lift_off_velocity[i] = stance_velocity(self.p_xy[i], v_sweep, yaw_rate)
                nom = self.nominal_xy(leg)
                touchdown = (nom + v_sweep * t_st / 2 + p.raibert_gain * (self.v_filt - v_cmd)
                             + yaw_rate * np.array([-nom[1], nom[0]]) * t_st / 2)
                if p.ground_speed_matching:
                    v_rel = stance_velocity(touchdown, v_sweep, yaw_rate)
                    self.p_xy[i], lift = swing_position(progress[i], self.lift_off[i], touchdown,
                                                        p.gait.swing_height, self.lift_off_velocity[i], v_rel,
                                                        p.gait.swing_time)
                else:
                    self.p_xy[i], lift = swing_position(progress[i], self.lift_off[i], touchdown,
                                                        p.gait.swing_height)
            foot_h = np.array([self.p_xy[i, 0], self.p_xy[i, 1], leg.foot_radius - self.body_height + lift])
            target = (R_rp.T @ foot_h if p.level_frame else foot_h) - leg.hip_pos
            q = leg_ik(leg, target)
            q_ref[3 * i:3 * i + 3] = q
            if p.gravity_ff and stance[i]:
                force = R_rp.T @ np.array([0.0, 0.0, -self.mass * GRAVITY / n_stance])
                tau_ff[3 * i:3 * i + 3] = leg_jacobian(leg, q).T @ force
        self.was_stance = stance
        self.q_ref, self.tau_ff = q_ref, tau_ff

    def actuate(self) -> None:
        """Run the env's substeps with the current targets (PD at the physics rate or servo targets)."""
        m, d, n = self.model, self.data, self.n_substeps
        dq_ref = (self.q_ref - self.q_prev) / self.dt
        for k in range(n):
            q_cmd = self.q_prev + (k + 1) / n * (self.q_ref - self.q_prev)
            if self.position_servo:
                extra = self.tau_ff
                if self.params.servo_kd:
                    extra = extra + self.params.servo_kd * (dq_ref - d.qvel[self.v_adr])
                ctrl = q_cmd + extra / self.servo_kp
            else:
                q, dq = d.qpos[self.q_adr], d.qvel[self.v_adr]
                tau = self.params.kp * (q_cmd - q) + self.params.kd * (dq_ref - dq) + self.tau_ff
                ctrl = tau / self.gear
            d.ctrl[self.act] = np.clip(ctrl, self.ctrl_lo, self.ctrl_hi)
            mujoco.mj_step(m, d)
        self.t += self.dt

    def step(self) -> None:
        """One env step: plan, then simulate ``n_substeps`` physics steps."""
        self.plan()
        self.actuate()

    def held_ctrl(self) -> np.ndarray:
        """The leg actuators' controls computed once from the current state and meant to be held over the
        whole env step (what an env-level policy sends; `TrotController.actuate` instead recomputes them
        every substep): torque motors ``tau = Kp (q_ref - q) + Kd (dq_ref - dq) + tau_ff`` with the state
        at the start of the step and the end-of-step target ``q_ref``; position servos the target
        ``q_ref`` plus the feed-forward / damping offset. Clipped to the control ranges; ordered as
        ``self.act``. Call after `plan`."""
        d = self.data
        q, dq = d.qpos[self.q_adr], d.qvel[self.v_adr]
        dq_ref = (self.q_ref - self.q_prev) / self.dt
        if self.position_servo:
            extra = self.tau_ff
            if self.params.servo_kd:
                extra = extra + self.params.servo_kd * (dq_ref - dq)
            ctrl = self.q_ref + extra / self.servo_kp
        else:
            tau = self.params.kp * (self.q_ref - q) + self.params.kd * (dq_ref - dq) + self.tau_ff
            ctrl = tau / self.gear
        return np.clip(ctrl, self.ctrl_lo, self.ctrl_hi)

    def env_step_ctrl(self) -> np.ndarray:
        """One env step at the env's control rate: `plan`, then `held_ctrl` (nothing is simulated; the
        caller applies the controls for the step, e.g. through ``env.step``)."""
        self.plan()
        ctrl = self.held_ctrl()
        self.t += self.dt
        return ctrl

    def normalized_ctrl(self) -> np.ndarray:
        """The current ``data.ctrl`` as the env's normalized action in [-1, 1] (for reward contexts)."""
        from loco_il.environments.base import action_map
        center, half = action_map(self.model)
        return np.clip((self.data.ctrl - center) / half, -1.0, 1.0)


__all__ = ["ControllerParams", "TrotController", "wrap_angle"]
