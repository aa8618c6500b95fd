"""The reference motion a tracking expert follows: one cycle of the task's retargeted motion capture, looped.

`build_reference(env)` retargets the task's cyclic clip (the first clip of `loco_il.motion.mocap.clips.TASK_CLIPS`,
e.g. DeepMimic's `humanoid3d_walk` for `walk`) to the env's robot with the solver and options of the `real`
datasets, three cycles long, and keeps the middle cycle (the seams of the repeated clip are cross-faded, so the
middle cycle starts and ends in the same pose, shifted by one stride). The cycle is resampled at `samples`
uniform phases and made exactly periodic: the closing error of every coordinate except the root's horizontal
slides is spread linearly over the cycle, and the root's horizontal change over one cycle becomes `drift`,
carried from cycle to cycle (DeepMimic, Peng et al. 2018, sec. 5: cyclic motions, the root offset accumulates).

Time scaling (`target_speed`): the cycle is played `target_speed / speed` times faster, so the reference walks
at the task's target speed (the retargeted DeepMimic walk covers ~1.0 m/s on Atlas; LocoMuJoCo's walk asks
1.25 m/s). Velocities are the derivative of the interpolated positions along the phase, so positions and
velocities agree.

`ReferenceMotion.state(phase)`: qpos and qvel at a phase counted in cycles (2.25 = a quarter into the third
cycle). End-effector positions relative to the root body and the root body's orientation are precomputed per
sample for the tracking reward (`reward.py`). Everything is plain arrays, saved inside the expert file, so an
expert needs no motion capture to act.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import mujoco
import numpy as np

#: the keypoints whose bodies are the end-effectors of the tracking reward (feet: ankles and toes)
END_EFFECTOR_KEYPOINTS = ("l_ankle", "l_toe", "r_ankle", "r_toe")
#: a start pose matches two reference phases "about equally well" when their squared pose distances are within
#: this ratio (ours: UnitreeH1's noisy standing starts are within 1.09 of both double-support phases; a pose on
#: the reference is at distance 0 from its own phase and ~0.5 from any half a period away)
START_TIE_RATIO = 1.25


@dataclass
class ReferenceMotion:
    """One periodic cycle of a robot's reference motion at `samples` uniform phases (see the module docstring).

    Arrays have `samples + 1` rows: row k is phase k / samples, and the last row is the first one shifted by
    one cycle (`qpos[-1] = qpos[0] + drift`), so interpolation never wraps.
    """

    qpos: np.ndarray            # (S + 1, nq)
    qvel: np.ndarray            # (S + 1, nv)
    period: float               # seconds per cycle, after time scaling
    drift: np.ndarray           # (nq,) change of qpos over one cycle (root horizontal slides / free-joint x, y)
    ee_rel: np.ndarray          # (S + 1, E, 3) end-effector body positions minus the root body position (world axes)
    root_pos: np.ndarray        # (S + 1, 3) root body position (world), within the first cycle
    root_quat: np.ndarray       # (S + 1, 4) root body orientation (world)
    ee_bodies: tuple[str, ...]  # names of the end-effector bodies
    actuated_qpos: np.ndarray   # (nu,) qpos address of each actuator's joint
    actuated_qvel: np.ndarray   # (nu,) qvel address of each actuator's joint
    quat_adr: np.ndarray        # (K,) qpos addresses where a quaternion (free/ball joint) starts
    source: str = ""
    time_scale: float = 1.0     # > 1: played faster than captured

    @property
    def samples(self) -> int:
        return int(self.qpos.shape[0] - 1)

    @property
    def speed(self) -> float:
        """Horizontal root speed of the reference (m/s)."""
        return float(np.linalg.norm(self.root_drift) / self.period)

    @property
    def root_drift(self) -> np.ndarray:
        """Horizontal root displacement (x, y) over one cycle."""
        return self.root_pos[-1, :2] - self.root_pos[0, :2]

    def _where(self, phase: float) -> tuple[int, int, float]:
        cycle = int(np.floor(phase))
        x = (phase - cycle) * self.samples
        i = min(int(x), self.samples - 1)
        return cycle, i, x - i

    def _lerp(self, table: np.ndarray, i: int, w: float) -> np.ndarray:
        return (1.0 - w) * table[i] + w * table[i + 1]

    def state(self, phase: float) -> tuple[np.ndarray, np.ndarray]:
        """(qpos, qvel) at `phase` cycles (qpos carries the root drift of the completed cycles)."""
        cycle, i, w = self._where(phase)
        qpos = self._lerp(self.qpos, i, w) + cycle * self.drift
        for adr in self.quat_adr:
            qpos[adr:adr + 4] /= np.linalg.norm(qpos[adr:adr + 4])
        return qpos, self._lerp(self.qvel, i, w)

    def targets(self, phase: float) -> tuple[np.ndarray, np.ndarray]:
        """Actuated joints' reference positions and velocities at `phase` (the PD targets' centre)."""
        _, i, w = self._where(phase)
        q = (1.0 - w) * self.qpos[i, self.actuated_qpos] + w * self.qpos[i + 1, self.actuated_qpos]
        dq = (1.0 - w) * self.qvel[i, self.actuated_qvel] + w * self.qvel[i + 1, self.actuated_qvel]
        return q, dq

    def kinematics(self, phase: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(root position with the drift of completed cycles, root quaternion, end-effectors relative to the root)."""
        cycle, i, w = self._where(phase)
        root = self._lerp(self.root_pos, i, w)
        root[:2] += cycle * self.root_drift
        quat = self._lerp(self.root_quat, i, w)
        return root, quat / np.linalg.norm(quat), self._lerp(self.ee_rel, i, w)

    def nearest_phase(self, qpos: np.ndarray, prefer: float | None = None, tie_ratio: float = START_TIE_RATIO) -> float:
        """The phase in [0, 1) whose actuated-joint pose is closest to `qpos` (start phase of an episode that
        did not start from the reference). With `prefer`: of the local minima of the squared pose distance within
        `tie_ratio` times the smallest, the one circularly nearest `prefer` (a pose between two reference poses
        gets a fixed one of them; a pose on the reference, at distance 0, keeps its own phase)."""
        diff = self.qpos[:-1, self.actuated_qpos] - np.asarray(qpos)[self.actuated_qpos]
        dist = np.einsum("ij,ij->i", diff, diff)
        if prefer is None:
            return float(np.argmin(dist) / self.samples)
        minima = (dist <= np.roll(dist, 1)) & (dist <= np.roll(dist, -1)) & (dist <= tie_ratio * dist.min())
        candidates = np.flatnonzero(minima) / self.samples
        gap = np.abs((candidates - prefer + 0.5) % 1.0 - 0.5)
        return float(candidates[np.argmin(gap)])

    # ------------------------------------------------------------------ (de)serialization
    ARRAYS = ("qpos", "qvel", "drift", "ee_rel", "root_pos", "root_quat", "actuated_qpos", "actuated_qvel",
              "quat_adr")

    def to_dict(self) -> dict[str, Any]:
        import torch
        out: dict[str, Any] = {k: torch.from_numpy(np.ascontiguousarray(getattr(self, k))) for k in self.ARRAYS}
        out.update(period=float(self.period), ee_bodies=list(self.ee_bodies), source=self.source,
                   time_scale=float(self.time_scale))
        return out

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> "ReferenceMotion":
        arrays = {k: np.asarray(d[k].numpy() if hasattr(d[k], "numpy") else d[k]) for k in cls.ARRAYS}
        return cls(period=float(d["period"]), ee_bodies=tuple(d["ee_bodies"]), source=str(d.get("source", "")),
                   time_scale=float(d.get("time_scale", 1.0)), **arrays)

    def digest_bytes(self) -> bytes:
        """Bytes that identify this reference (part of an expert's checksum)."""
        parts = [np.ascontiguousarray(getattr(self, k)).tobytes() for k in self.ARRAYS]
        parts.append(repr((round(self.period, 12), self.ee_bodies)).encode())
        return b"".join(parts)


# ---------------------------------------------------------------------------- building
def actuated_addresses(model: mujoco.MjModel) -> tuple[np.ndarray, np.ndarray]:
    """qpos and qvel address of the joint each actuator drives (hinge/slide joints)."""
    joints = model.actuator_trnid[:, 0]
    if (model.actuator_trntype != mujoco.mjtTrn.mjTRN_JOINT).any():
        raise ValueError("tracking experts need joint actuators (every actuator drives one joint)")
    return model.jnt_qposadr[joints].astype(np.intp), model.jnt_dofadr[joints].astype(np.intp)


def _quat_addresses(model: mujoco.MjModel) -> np.ndarray:
    adr = []
    for j in range(model.njnt):
        if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE:
            adr.append(model.jnt_qposadr[j] + 3)
        elif model.jnt_type[j] == mujoco.mjtJoint.mjJNT_BALL:
            adr.append(model.jnt_qposadr[j])
    return np.array(adr, dtype=np.intp)


def _horizontal_root_addresses(model: mujoco.MjModel) -> np.ndarray:
    """qpos addresses of the root's horizontal position: a free joint's x, y, or the root body's slides along
    world x / y (LocoMuJoCo's robots: three slides then three hinges on the pelvis)."""
    from loco_il.environments.observations import root_xy_projection
    idx, _ = root_xy_projection(model)
    return np.asarray(idx, dtype=np.intp)


def end_effector_bodies(body_name: str) -> tuple[str, ...]:
    """The feet bodies of a robot, from its keypoint map (ankle and toe keypoints, de-duplicated)."""
    from loco_il.motion.mocap.robot_maps import get_robot_map, parse_point
    robot_map = get_robot_map(body_name)
    names: list[str] = []
    for key in END_EFFECTOR_KEYPOINTS:
        spec = robot_map.keypoints.get(key)
        if spec is None:
            continue
        body = parse_point(spec).body
        if body and body not in names:
            names.append(body)
    if not names:
        raise ValueError(f"{body_name}'s keypoint map names no ankle or toe body; the tracking reward needs feet")
    return tuple(names)


def periodic_cycle(model: mujoco.MjModel, times: np.ndarray, qpos: np.ndarray, start: float, period: float,
                   samples: int) -> tuple[np.ndarray, np.ndarray]:
    """Resample `qpos` (rows at `times`) over [start, start + period] at samples + 1 uniform phases and close
    the cycle: returns (cycle qpos (samples + 1, nq), drift (nq,))."""
    phases = np.linspace(0.0, 1.0, samples + 1)
    t = start + phases * period
    cycle = np.stack([np.interp(t, times, qpos[:, c]) for c in range(qpos.shape[1])], axis=1)
    drift = np.zeros(qpos.shape[1])
    xy = _horizontal_root_addresses(model)
    drift[xy] = cycle[-1, xy] - cycle[0, xy]
    closing = cycle[-1] - (cycle[0] + drift)       # what the captured cycle fails to repeat
    cycle -= phases[:, None] * closing[None, :]
    for adr in _quat_addresses(model):
        cycle[:, adr:adr + 4] /= np.linalg.norm(cycle[:, adr:adr + 4], axis=1, keepdims=True)
    return cycle, drift


def cycle_velocities(model: mujoco.MjModel, cycle: np.ndarray, period: float) -> np.ndarray:
    """qvel along a periodic cycle (central differences in MuJoCo's tangent space, `mj_differentiatePos`)."""
    n = cycle.shape[0] - 1
    dt = period / n
    step = np.zeros((n, model.nv))
    for k in range(n):                              # velocity from sample k to k + 1
        mujoco.mj_differentiatePos(model, step[k], dt, cycle[k], cycle[k + 1])
    qvel = 0.5 * (step + np.roll(step, 1, axis=0))  # central: mean of the steps into and out of sample k
    return np.concatenate([qvel, qvel[:1]], axis=0)


def _body_kinematics(model: mujoco.MjModel, cycle: np.ndarray, ee_ids: Sequence[int],
                     root: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    data = mujoco.MjData(model)
    ee_rel = np.zeros((cycle.shape[0], len(ee_ids), 3))
    root_pos = np.zeros((cycle.shape[0], 3))
    root_quat = np.zeros((cycle.shape[0], 4))
    for k, q in enumerate(cycle):
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        root_pos[k] = data.xpos[root]
        root_quat[k] = data.xquat[root]
        ee_rel[k] = data.xpos[list(ee_ids)] - data.xpos[root]
    return ee_rel, root_pos, root_quat


def build_reference(env: Any, *, target_speed: float | None = None, samples: int | None = None,
                    clip: Any = None) -> ReferenceMotion:
    """The reference motion of `env`'s task (see the module docstring).

    `target_speed`: m/s the reference is time-scaled to (None: as captured); `samples`: phases per cycle
    (default: one per control step of the captured cycle); `clip`: a `ClipSpec` instead of the task's first clip.
    """
    from loco_il.motion.mocap.retarget import RetargetOptions, retarget_clip
    from loco_il.motion.mocap.clips import TASK_CLIPS, find_motion_files, load_motion

    if clip is None:
        clips = TASK_CLIPS.get(env.task_name)
        if not clips:
            raise ValueError(f"{env.task_id}: no reference motion for the task {env.task_name!r} (motion exists "
                             f"for {', '.join(sorted(TASK_CLIPS))})")
        clip = clips[0]
    path = find_motion_files([clip], what=f"the reference motion of {env.task_id}")[0]
    motion, _ = load_motion(path, clip)
    if not motion.loop:
        raise ValueError(f"{path.name} is not a cyclic clip; a tracking reference loops one cycle")
    period = float(motion.duration)
    result = retarget_clip(env, motion, n_cycles=3, options=RetargetOptions())
    model = env.model
    times = np.arange(result.n_frames) * result.dt
    n = int(samples or max(8, round(period / env.dt)))
    cycle, drift = periodic_cycle(model, times, result.qpos, period, period, n)
    xy = _horizontal_root_addresses(model)
    speed = float(np.linalg.norm(drift[xy])) / period
    scale = 1.0
    if target_speed is not None and target_speed > 0 and speed > 0:
        scale = float(target_speed) / speed
    period /= scale
    ee_names = end_effector_bodies(env.body_name)
    ee_ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, b) for b in ee_names]
    root = int(model.jnt_bodyid[0])
    ee_rel, root_pos, root_quat = _body_kinematics(model, cycle, ee_ids, root)
    act_q, act_v = actuated_addresses(model)
    return ReferenceMotion(qpos=cycle, qvel=cycle_velocities(model, cycle, period), period=period, drift=drift,
                           ee_rel=ee_rel, root_pos=root_pos, root_quat=root_quat, ee_bodies=ee_names,
                           actuated_qpos=act_q, actuated_qvel=act_v, quat_adr=_quat_addresses(model),
                           source=f"{path.name} retargeted to {env.body_name}", time_scale=scale)
