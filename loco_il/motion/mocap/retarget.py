"""Retargeting motion (human motion capture, or another robot's motion) to a robot, by IK.

Pipeline (:func:`retarget_clip` for a :class:`~.skeleton.MotionClip`,
:func:`retarget_robot_to_robot` for a robot's ``qpos`` trajectory; both end in
:func:`retarget_keypoints`):

1. **Keypoints.**  The source gives the canonical keypoints (:func:`~.skeleton.canonical_keypoints`
   for a clip; forward kinematics of the source robot's :mod:`.robot_maps` map for a robot),
   world positions ``(T, 3)`` each.  Cyclic clips can be repeated (:func:`loop_keypoints`, the
   seam mismatch cross-faded); the motion is turned about the vertical so it heads along +x and
   starts at x = y = 0 (:func:`align_heading`), low-passed (Gaussian, sigma 30 ms: softens capture
   glitches) and resampled to the env's control rate ``1 / env.dt`` with a cubic spline.
2. **Scaling and targets** (:func:`build_targets`).  ``scale = robot leg length / source leg
   length`` (hip -> knee -> ankle; ``scale="height"`` uses heights).  The hip centre (midpoint of
   the hips) follows the scaled source trajectory.  ``mode="segments"`` (default): pelvis and hips
   are the robot's own rest offsets from the hip centre, turned with the source's pelvis frame
   (lateral axis hip -> hip, up hip centre -> torso); shoulders likewise in the chest frame around
   the neck; every limb and spine segment (hip -> knee -> ankle, shoulder -> elbow -> wrist, hip
   centre -> torso -> neck -> head) points the way the source's does, with the robot's length
   (leg segments keep the robot's sideways slant: hips wider than feet); the foot (ankle -> toe)
   too, pitched so that the source's flat foot (median over its contacts) is the robot's flat
   foot.  ``mode="uniform"``: every keypoint is the source's, scaled by ``scale``.
3. **Contacts** (:func:`detect_contacts`).  Per foot point (ankle = heel, toe): in contact when
   low (within 5 % of the leg length of its lowest level) and slow (below 0.6 leg lengths/s);
   runs shorter than 50 ms dropped, gaps shorter than 40 ms filled.  During its contacts a point's
   target is pinned -- horizontally to its mean over the contact, vertically to the robot's own
   standing height of that point -- with the pin (and the higher contact weight) faded in and out
   over 0.1 s; the estimated ground becomes z = 0.  Contacts are found on the scaled source, so
   one IK pass suffices.
4. **IK** (:class:`RobotKinematics`).  Per frame, damped least squares over all degrees of
   freedom (root free joint, or LocoMuJoCo's 3 slides + 3 hinges, and every joint left after the
   env's joint removals): minimise ``sum_k w_k |p_k(q) - target_k|^2 + w_f (roll_l^2 + roll_r^2)
   + mu |q - q_init|^2 (joints) + s |q - q_prev|^2`` with point Jacobians from ``mujoco.mj_jac``
   (``roll`` = height difference of a sole's inner and outer edge: keeps the feet level), steps
   ``dq = (J'WJ + (lambda + s) I + mu P)^-1 (J'We + mu P (q_init - q) + s (q_prev - q))`` applied
   with ``mj_integratePos`` (quaternions handled by MuJoCo; differences by ``mj_differentiatePos``),
   joint limits by clamping plus an active set (a joint at a limit that the step pushes further
   is frozen and the step re-solved), joint equality constraints (MyoLeg's knee couplings) by
   eliminating the dependent joints (chain rule through the polynomial) and re-projecting.  The
   first frame starts from the init pose turned to the source's heading (up to 200 iterations);
   each next frame warm-starts from the previous solution (8 iterations by default, fewer when
   the step falls below 1e-5).  Keypoints the robot cannot move relative to their parent (arms and
   head of LocoMuJoCo bodies, whose arm joints are removed) are left out.
5. **Ground** (:meth:`RobotKinematics.fix_ground`).  The foot soles (contact geometry of the
   ankle body's subtree, :func:`sole_points`) give, per frame, the lowest foot point.  The root is
   shifted vertically so a foot in contact touches the ground (shift interpolated across flight
   phases and smoothed over 50 ms), then raised wherever a sole point would still be below the
   ground: no penetration.
6. **Velocities** by central differences of ``mj_differentiatePos`` (one-sided at the ends).

Quality metrics (``RetargetResult.metrics``): ``keypoint_error_m`` (mean distance between the
robot's keypoints and their targets, over used keypoints and frames, before the ground shift),
``keypoint_error_uniform_m`` (the same against the uniformly scaled source keypoints, hip centres
made to coincide: how far the robot's pose is from the scaled source pose, proportion differences
included), ``foot_sliding_mps`` (mean horizontal speed of the robot's ankle and toe keypoints over
their own contact frames), ``penetration_mean_m`` / ``penetration_max_m`` (depth of the lowest
sole point below z = 0, per frame), ``in_limits_fraction`` (frames whose limited joints are all
within range), ``contact_fraction`` (frames with a foot down, per foot), ``root_shift_mean_m``
(mean |vertical root shift| of step 5), ``seconds``.

Speed: about 1-2 ms per frame for 14-40 degrees of freedom (a 10 s clip at 100 Hz in 1-3 s on one
core, see benchmarks/retarget_quality.py).
"""
from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field
from typing import Any, Mapping, Optional

import mujoco
import numpy as np

from .robot_maps import RobotMap, get_robot_map, parse_point
from .skeleton import MotionClip, canonical_keypoints

__all__ = [
    "RetargetOptions", "RetargetResult", "RobotKinematics", "retarget_clip", "retarget_keypoints",
    "retarget_robot_to_robot", "robot_keypoints", "build_targets", "detect_contacts", "foot_contacts",
    "align_heading", "loop_keypoints", "resample_keypoints", "smooth_keypoints", "sole_points", "leg_length",
    "RETARGET_VERSION", "TARGET_TREE",
]

#: bump when the algorithm changes in a way that changes the output (part of dataset cache keys)
RETARGET_VERSION = 1

#: how each keypoint's target is built from its parent's: (child, parent, kind)
#: kinds: "pelvis" (rigid in the pelvis frame, from the hip centre), "chest" (rigid in the chest
#: frame, from the neck), "dir" (source direction, robot length), "foot" (dir with pitch offset)
TARGET_TREE = (
    ("pelvis", "hip_center", "pelvis"), ("l_hip", "hip_center", "pelvis"), ("r_hip", "hip_center", "pelvis"),
    ("torso", "hip_center", "dir"), ("neck", "torso", "dir"), ("head", "neck", "dir"),
    ("l_shoulder", "neck", "chest"), ("r_shoulder", "neck", "chest"),
    ("l_elbow", "l_shoulder", "dir"), ("l_wrist", "l_elbow", "dir"),
    ("r_elbow", "r_shoulder", "dir"), ("r_wrist", "r_elbow", "dir"),
    ("l_knee", "l_hip", "dir"), ("l_ankle", "l_knee", "dir"), ("l_toe", "l_ankle", "foot"),
    ("r_knee", "r_hip", "dir"), ("r_ankle", "r_knee", "dir"), ("r_toe", "r_ankle", "foot"),
)
_PARENT = {c: p for c, p, _ in TARGET_TREE}
#: keypoints left out when the robot cannot move them relative to their parent keypoint
_DROPPABLE = ("l_elbow", "r_elbow", "l_wrist", "r_wrist", "head")
#: leg segments (child keypoints) whose sideways slant in the robot's rest pose is kept
_LEG_SEGMENTS = ("l_knee", "r_knee", "l_ankle", "r_ankle")
_FEET = ("l", "r")


@dataclass
class RetargetOptions:
    """Solver settings (defaults are what the `real` datasets use)."""

    mode: str = "segments"            # "segments" or "uniform" (see build_targets)
    scale: Any = "legs"               # "legs", "height" or a number
    iterations: int = 8               # IK iterations per frame (warm-started)
    first_iterations: int = 200       # IK iterations on the first frame
    tolerance: float = 1e-5           # stop a frame when max |dq| is below this
    damping: float = 1e-4             # lambda (step damping)
    posture: float = 2e-4             # mu (pull of the joints toward the init pose)
    max_step: float = 0.25            # largest |dq| entry per iteration (rad or m)
    contact_weight: float = 3.0       # weight multiplier of the feet during contacts
    flat_weight: float = 4.0          # weight of the foot-roll term (sole edges level)
    smoothness: float = 1e-3          # pull toward the previous frame's solution (temporal smoothness)
    pin_blend: float = 0.1            # seconds over which a contact pin fades in and out
    smooth_sigma: float = 0.03        # Gaussian smoothing of the source keypoints (seconds; 0 = none)
    pin_contacts: bool = True         # pin the feet during contacts (foot-sliding cleanup)
    fix_ground: bool = True           # shift the root so feet touch and never penetrate the ground
    align: bool = True                # turn the source to head along +x, starting at x = y = 0
    contact_height: float = 0.05      # contact threshold: height above the foot's low level, leg lengths
    contact_speed: float = 0.6        # contact threshold: horizontal speed, leg lengths per second
    weights: Optional[Mapping[str, float]] = None   # keypoint weight overrides

    def key(self) -> dict:
        d = dataclasses.asdict(self)
        d["weights"] = dict(sorted((self.weights or {}).items()))
        return d


@dataclass
class RetargetResult:
    """Joint trajectory of the robot and how it was obtained."""

    qpos: np.ndarray                  # (T, nq)
    qvel: np.ndarray                  # (T, nv)
    dt: float
    targets: dict                     # keypoint -> (T, 3) final targets (before the ground shift)
    robot_points: dict                # keypoint -> (T, 3) achieved, after the ground shift
    contacts: np.ndarray              # (T, 2) bool, left / right foot in contact
    used_keypoints: list
    scale: float
    metrics: dict
    root_shift: np.ndarray            # (T,) vertical root shift applied by the ground fix
    source: str = ""
    source_points: dict = field(default_factory=dict)   # keypoint -> (T, 3): the source, aligned and scaled

    @property
    def n_frames(self) -> int:
        return int(self.qpos.shape[0])


# =============================================================================== source keypoints


def _hip_center(kp: Mapping[str, np.ndarray]) -> np.ndarray:
    if "l_hip" not in kp or "r_hip" not in kp:
        raise KeyError("retargeting needs the l_hip and r_hip keypoints of the source")
    return 0.5 * (np.asarray(kp["l_hip"]) + np.asarray(kp["r_hip"]))


def leg_length(kp: Mapping[str, np.ndarray]) -> float:
    """Mean hip -> knee -> ankle length over both legs (and all frames)."""
    lengths = []
    for s in _FEET:
        if all(f"{s}_{j}" in kp for j in ("hip", "knee", "ankle")):
            hip, knee, ankle = (np.atleast_2d(kp[f"{s}_{j}"]) for j in ("hip", "knee", "ankle"))
            lengths.append(np.linalg.norm(hip - knee, axis=-1).mean() + np.linalg.norm(knee - ankle, axis=-1).mean())
    if not lengths:
        raise KeyError("leg length needs hip, knee and ankle keypoints of at least one leg")
    return float(np.mean(lengths))


def loop_keypoints(kp: Mapping[str, np.ndarray], n_cycles: int, blend: float = 0.25) -> dict:
    """Repeat a cyclic motion ``n_cycles`` times.

    The last frame is taken as the start of the next cycle (the DeepMimic convention), so one
    cycle is frames ``[0, T-1)`` and advances by the hip centre's horizontal displacement from
    frame 0 to frame T-1.  Captured cycles do not close exactly: the mismatch between frame T-1
    and (frame 0 + displacement) is cross-faded over ``blend`` of the cycle on each side of every
    seam (half of it taken up before the seam, half after, with a smoothstep), so the repeated
    motion has no jump and the middle of the cycle is untouched.
    """
    n_cycles = int(n_cycles)
    kp = {k: np.asarray(v, dtype=float) for k, v in kp.items()}
    t = next(iter(kp.values())).shape[0]
    if n_cycles <= 1 or t < 4:
        return kp
    hc = _hip_center(kp)
    disp = hc[-1] - hc[0]
    disp[2] = 0.0
    n = t - 1                                           # frames per cycle
    w = max(1, int(round(blend * n)))
    j = np.arange(n)
    smooth = lambda x: x * x * (3.0 - 2.0 * x)          # noqa: E731
    end = 0.5 * smooth(np.clip((j - (n - w)) / w, 0.0, 1.0))         # 0 -> 1/2 at the seam (frame n)
    start = -0.5 * smooth(np.clip((w - j) / w, 0.0, 1.0))            # -1/2 -> 0 over the first w frames
    out = {}
    for k, v in kp.items():
        seam = (v[0] + disp) - v[-1]
        cycle = v[:-1]
        parts = []
        for i in range(n_cycles):
            ramp = (end if i < n_cycles - 1 else 0.0) + (start if i > 0 else 0.0)
            parts.append(cycle + i * disp + np.broadcast_to(ramp, (n,))[:, None] * seam)
        parts.append(v[-1:] + (n_cycles - 1) * disp)
        out[k] = np.concatenate(parts)
    return out


def align_heading(kp: Mapping[str, np.ndarray], min_travel: float = 0.3) -> tuple[dict, float]:
    """Turn the motion about the vertical so it heads along +x, and move its start to x = y = 0.

    The heading is the direction of the hip centre's travel from the first to the last frame
    when it travels at least ``min_travel`` metres, else the facing of the first frame (from the
    hips' lateral axis).  Returns ``(keypoints, yaw)`` with ``yaw`` the rotation applied (rad).
    """
    kp = {k: np.asarray(v, dtype=float) for k, v in kp.items()}
    hc = _hip_center(kp)
    travel = hc[-1, :2] - hc[0, :2]
    if np.linalg.norm(travel) >= min_travel:
        heading = np.arctan2(travel[1], travel[0])
    else:
        lat = kp["l_hip"][0] - kp["r_hip"][0]
        heading = np.arctan2(-lat[0], lat[1])      # facing = lateral axis turned by -90 degrees
    yaw = -heading
    c, s = np.cos(yaw), np.sin(yaw)
    rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    origin = np.array([hc[0, 0], hc[0, 1], 0.0])
    return {k: (v - origin) @ rot.T for k, v in kp.items()}, float(yaw)


def smooth_keypoints(kp: Mapping[str, np.ndarray], sigma_frames: float) -> dict:
    """Gaussian low-pass of keypoint trajectories (``sigma_frames`` in frames; ends held).  Softens
    capture glitches such as the 7-degree pelvis-yaw step in the middle of DeepMimic's walk cycle."""
    from scipy.ndimage import gaussian_filter1d

    if sigma_frames <= 0:
        return {k: np.asarray(v, dtype=float) for k, v in kp.items()}
    return {k: gaussian_filter1d(np.asarray(v, dtype=float), sigma_frames, axis=0, mode="nearest")
            for k, v in kp.items()}


def resample_keypoints(kp: Mapping[str, np.ndarray], fps: float, new_fps: float) -> dict:
    """Cubic-spline resampling of keypoint trajectories to ``new_fps`` (frames at ``k / new_fps``
    within the source's duration)."""
    from scipy.interpolate import CubicSpline

    kp = {k: np.asarray(v, dtype=float) for k, v in kp.items()}
    t = next(iter(kp.values())).shape[0]
    if abs(fps - new_fps) < 1e-9 * new_fps:
        return kp
    duration = (t - 1) / fps
    n_new = int(np.floor(duration * new_fps + 1e-6)) + 1
    t_old = np.arange(t) / fps
    t_new = np.arange(n_new) / new_fps
    if t < 4:
        return {k: np.stack([np.interp(t_new, t_old, v[:, i]) for i in range(3)], -1) for k, v in kp.items()}
    names = list(kp)
    stacked = np.stack([kp[k] for k in names], axis=1)            # (T, K, 3)
    out = CubicSpline(t_old, stacked, axis=0, bc_type="not-a-knot")(t_new)
    return {k: out[:, i] for i, k in enumerate(names)}


# =============================================================================== targets


def _frame(lateral: np.ndarray, up: np.ndarray) -> np.ndarray:
    """Right-handed frames (..., 3, 3) with columns (forward, left, up) from a lateral (left)
    axis and an approximate up vector."""
    y = lateral / np.maximum(np.linalg.norm(lateral, axis=-1, keepdims=True), 1e-9)
    z = up - np.sum(up * y, axis=-1, keepdims=True) * y
    z = z / np.maximum(np.linalg.norm(z, axis=-1, keepdims=True), 1e-9)
    x = np.cross(y, z)
    return np.stack([x, y, z], axis=-1)


def _pelvis_frame(kp: Mapping[str, np.ndarray]) -> np.ndarray:
    hc = _hip_center(kp)
    up = (np.asarray(kp["torso"]) - hc) if "torso" in kp else np.broadcast_to([0.0, 0.0, 1.0], hc.shape)
    return _frame(np.asarray(kp["l_hip"]) - np.asarray(kp["r_hip"]), up)


def _chest_frame(kp: Mapping[str, np.ndarray]) -> Optional[np.ndarray]:
    if not all(k in kp for k in ("l_shoulder", "r_shoulder", "neck")):
        return None
    base = kp["torso"] if "torso" in kp else _hip_center(kp)
    return _frame(np.asarray(kp["l_shoulder"]) - np.asarray(kp["r_shoulder"]), np.asarray(kp["neck"]) - base)


def _foot_pitch(d: np.ndarray) -> np.ndarray:
    """Downward pitch angle (rad) of direction vectors."""
    return np.arctan2(-d[..., 2], np.linalg.norm(d[..., :2], axis=-1))


def _rotate(d: np.ndarray, axis: np.ndarray, angle: float) -> np.ndarray:
    """Rotate vectors ``d`` (T, 3) about unit axes ``axis`` (T, 3) by ``angle`` (Rodrigues)."""
    c, s = np.cos(angle), np.sin(angle)
    return d * c + np.cross(axis, d) * s + axis * np.sum(axis * d, axis=-1, keepdims=True) * (1.0 - c)


def build_targets(src: Mapping[str, np.ndarray], rest: Mapping[str, np.ndarray], scale: float,
                  mode: str = "segments", stance: Optional[Mapping[str, np.ndarray]] = None) -> dict:
    """Keypoint targets ``(T, 3)`` for the robot from source keypoints ``(T, 3)``.

    ``rest``: the robot's keypoints (3,) in its initial pose; ``scale``: robot / source size;
    ``stance``: optional ``{"l": mask (T,), "r": mask}`` of the source's contact frames, used to
    measure the source's flat-foot pitch (else the frames where the ankle is lowest).
    Only keypoints the robot has (``rest``) and whose chain the source provides get a target.
    """
    src = {k: np.asarray(v, dtype=float) for k, v in src.items()}
    rest = {k: np.asarray(v, dtype=float) for k, v in rest.items()}
    hc_src = _hip_center(src)
    t = hc_src.shape[0]
    if mode == "uniform":
        return {k: scale * src[k] for k in rest if k in src}
    if mode != "segments":
        raise ValueError(f"mode must be 'segments' or 'uniform', got {mode!r}")
    out = {"hip_center": scale * hc_src}
    rest_hc = _hip_center(rest)
    rest_all = dict(rest, hip_center=rest_hc)
    src_all = dict(src, hip_center=hc_src)
    f_src = _pelvis_frame(src)                               # (T, 3, 3)
    f_rest = _pelvis_frame({k: v[None] for k, v in rest.items()})[0]
    c_src = _chest_frame(src)
    c_rest = _chest_frame({k: v[None] for k, v in rest.items()})
    for child, parent, kind in TARGET_TREE:
        if child not in rest or parent not in out:
            continue
        if kind == "pelvis":
            local = f_rest.T @ (rest[child] - rest_hc)
            out[child] = out[parent] + f_src @ local
        elif kind == "chest":
            if c_src is None or c_rest is None:
                continue
            local = c_rest[0].T @ (rest[child] - rest_all[parent])
            out[child] = out[parent] + c_src @ local
        else:
            if child not in src_all or parent not in src_all:
                continue
            d = src_all[child] - src_all[parent]
            d = d / np.maximum(np.linalg.norm(d, axis=-1, keepdims=True), 1e-9)
            length = float(np.linalg.norm(rest[child] - rest_all[parent]))
            if child in _LEG_SEGMENTS:
                # keep the robot's own sideways slant of the segment (hips wider than knees and feet)
                o = f_rest.T @ (rest[child] - rest_all[parent])
                d = _rotate(d, f_src[:, :, 0], float(np.arctan2(o[1], -o[2])))
            if kind == "foot":
                pitch_src = _foot_pitch(d)
                side = child[0]
                mask = None if stance is None else np.asarray(stance.get(side), dtype=bool)
                if mask is None or mask.sum() < 3:
                    ank = src_all[parent][:, 2]
                    mask = ank <= np.quantile(ank, 0.3)
                rest_d = rest[child] - rest_all[parent]
                pitch_rest = float(_foot_pitch(rest_d / max(np.linalg.norm(rest_d), 1e-9)))
                # pitch the foot about the pelvis' lateral axis (well defined even for a vertical foot)
                d = _rotate(d, f_src[:, :, 1], pitch_rest - float(np.median(pitch_src[mask])))
            out[child] = out[parent] + length * d
    del out["hip_center"]
    assert all(v.shape == (t, 3) for v in out.values())
    return out


# =============================================================================== contacts


def _runs(mask: np.ndarray) -> list:
    """[start, stop) of the True runs of a 1-D boolean array."""
    m = np.concatenate([[False], np.asarray(mask, dtype=bool), [False]])
    edges = np.flatnonzero(np.diff(m.astype(np.int8)))
    return list(zip(edges[0::2], edges[1::2]))


def _clean_mask(mask: np.ndarray, min_run: int, max_gap: int) -> np.ndarray:
    mask = np.asarray(mask, dtype=bool).copy()
    for a, b in _runs(~mask):                     # fill short gaps between contacts
        if a > 0 and b < len(mask) and b - a <= max_gap:
            mask[a:b] = True
    for a, b in _runs(mask):                      # drop blips
        if b - a < min_run:
            mask[a:b] = False
    return mask


def detect_contacts(kp: Mapping[str, np.ndarray], fps: float, leg: float, height: float = 0.05,
                    speed: float = 0.6) -> dict:
    """Contact masks ``(T,)`` per foot point: ``{"l_ankle", "l_toe", "r_ankle", "r_toe"}`` (those present).

    A point is in contact when it is within ``height * leg`` of its low level (5th percentile over
    the clip, both feet pooled) and its horizontal speed is below ``speed * leg`` per second; runs
    shorter than 50 ms are dropped, gaps shorter than 40 ms filled.  The ankle stands for the heel:
    heel-strike to heel-off is an ankle contact, foot-flat to toe-off a toe contact.
    """
    t = next(iter(kp.values())).shape[0]
    out = {}
    if t < 3:
        return out
    for part in ("ankle", "toe"):
        keys = [f"{s}_{part}" for s in _FEET if f"{s}_{part}" in kp]
        if not keys:
            continue
        low = np.quantile(np.concatenate([kp[k][:, 2] for k in keys]), 0.05)
        for k in keys:
            h = kp[k][:, 2] - low
            v = np.linalg.norm(np.gradient(kp[k][:, :2], 1.0 / fps, axis=0), axis=-1)
            raw = (h < height * leg) & (v < speed * leg)
            out[k] = _clean_mask(raw, min_run=max(2, int(round(0.05 * fps))), max_gap=max(1, int(round(0.04 * fps))))
    return out


def foot_contacts(point_contacts: Mapping[str, np.ndarray], t: int) -> np.ndarray:
    """(T, 2) bool: left / right foot in contact (ankle or toe)."""
    out = np.zeros((t, 2), dtype=bool)
    for i, s in enumerate(_FEET):
        for part in ("ankle", "toe"):
            if f"{s}_{part}" in point_contacts:
                out[:, i] |= point_contacts[f"{s}_{part}"]
    return out


def _pin_feet(targets: dict, point_contacts: Mapping[str, np.ndarray], rest: Mapping[str, np.ndarray],
              ground_rest: float, blend: int) -> tuple[dict, float, dict]:
    """Pin ankle / toe targets during their contacts (see the module docstring); returns the new
    targets, the ground height estimated in target space and the pin strength (T,) in [0, 1] of
    each pinned point (1 during its contacts, fading out over ``blend`` frames around them)."""
    targets = {k: v.copy() for k, v in targets.items()}
    t = next(iter(targets.values())).shape[0]
    strength = {}
    # ground in target space: where the robot's sole is when a contact point is at its standing height
    lows = [targets[k][m, 2] - (rest[k][2] - ground_rest) for k, m in point_contacts.items()
            if k in targets and m.any()]
    if not lows:
        return targets, 0.0, strength
    ground = float(np.median(np.concatenate(lows)))
    smooth = lambda x: x * x * (3.0 - 2.0 * x)          # noqa: E731
    for key, mask in point_contacts.items():
        runs = _runs(mask)
        if key not in targets or not runs:
            continue
        orig = targets[key]
        pinned = orig.copy()
        w = np.zeros(t)
        for a, b in runs:
            p = orig[a:b].mean(axis=0)
            p[2] = ground + (rest[key][2] - ground_rest)
            for j in range(max(0, a - blend), min(t, b + blend)):
                dist = a - j if j < a else (j - b + 1 if j >= b else 0)
                wj = smooth(1.0 - dist / (blend + 1))
                if wj > w[j]:
                    w[j] = wj
                    pinned[j] = p
        targets[key] = orig + w[:, None] * (pinned - orig)
        strength[key] = w
    return targets, ground, strength


# =============================================================================== robot side


def _geom_points(m: mujoco.MjModel, g: int) -> tuple[np.ndarray, np.ndarray]:
    """Candidate lowest points of a geom in its own frame, with a radius to subtract."""
    gt, size = int(m.geom_type[g]), m.geom_size[g]
    if gt == mujoco.mjtGeom.mjGEOM_SPHERE:
        return np.zeros((1, 3)), np.array([size[0]])
    if gt == mujoco.mjtGeom.mjGEOM_CAPSULE:
        return np.array([[0, 0, -size[1]], [0, 0, size[1]]]), np.full(2, size[0])
    if gt == mujoco.mjtGeom.mjGEOM_BOX:
        c = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=float)
        return c * size, np.zeros(8)
    if gt == mujoco.mjtGeom.mjGEOM_CYLINDER:
        a = np.linspace(0, 2 * np.pi, 16, endpoint=False)
        ring = np.stack([size[0] * np.cos(a), size[0] * np.sin(a), np.zeros_like(a)], -1)
        pts = np.concatenate([ring + [0, 0, size[1]], ring - [0, 0, size[1]]])
        return pts, np.zeros(len(pts))
    if gt == mujoco.mjtGeom.mjGEOM_ELLIPSOID:
        dirs = np.array([[i, j, k] for i in (-1, 0, 1) for j in (-1, 0, 1) for k in (-1, 0, 1)
                         if (i, j, k) != (0, 0, 0)], dtype=float)
        dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
        return dirs * size[:3], np.zeros(len(dirs))
    if gt == mujoco.mjtGeom.mjGEOM_MESH:
        mid = int(m.geom_dataid[g])
        adr, num = int(m.mesh_vertadr[mid]), int(m.mesh_vertnum[mid])
        v = np.asarray(m.mesh_vert[adr:adr + num], dtype=float)
        return v, np.zeros(len(v))
    return np.zeros((0, 3)), np.zeros(0)


def _subtree(m: mujoco.MjModel, root: int) -> list:
    out = []
    for b in range(m.nbody):
        x = b
        while x > 0 and x != root:
            x = int(m.body_parentid[x])
        if x == root:
            out.append(b)
    return out


def sole_points(m: mujoco.MjModel, d: mujoco.MjData, foot_body: int, tol: float = 0.01,
                max_points: int = 16) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points of a foot's sole: ``(bodies (n,), local points (n, 3), radii (n,))``.

    Taken from the contact geometry (geoms that collide, or are named in contact pairs; all geoms
    when none does) of ``foot_body``'s subtree, in the current pose of ``d`` (the init pose): the
    candidate points within ``tol`` of the lowest one, thinned to the extreme ones in the horizontal
    plane.  A point's world height is ``(xpos + xmat @ local)[2] - radius``.
    """
    bodies = set(_subtree(m, foot_body))
    geoms = [g for g in range(m.ngeom) if int(m.geom_bodyid[g]) in bodies
             and m.geom_type[g] not in (mujoco.mjtGeom.mjGEOM_PLANE, mujoco.mjtGeom.mjGEOM_HFIELD)]
    paired = set(np.asarray(m.pair_geom1).tolist()) | set(np.asarray(m.pair_geom2).tolist())
    colliding = [g for g in geoms if m.geom_contype[g] or m.geom_conaffinity[g] or g in paired]
    geoms = colliding or geoms
    if not geoms:
        raise ValueError(f"body {mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, foot_body)!r} has no geometry "
                         f"to find the foot sole from")
    b_l, p_l, r_l, w_l = [], [], [], []
    for g in geoms:
        pts, rad = _geom_points(m, g)
        if not len(pts):
            continue
        gmat = np.empty(9)
        mujoco.mju_quat2Mat(gmat, m.geom_quat[g])
        local = m.geom_pos[g] + pts @ gmat.reshape(3, 3).T          # in the body frame
        b = int(m.geom_bodyid[g])
        world = d.xpos[b] + local @ d.xmat[b].reshape(3, 3).T
        b_l.append(np.full(len(pts), b))
        p_l.append(local)
        r_l.append(rad)
        w_l.append(world - np.stack([np.zeros_like(rad), np.zeros_like(rad), rad], -1))
    bodies_a, local_a, rad_a, world_a = (np.concatenate(x) for x in (b_l, p_l, r_l, w_l))
    low = world_a[:, 2] <= world_a[:, 2].min() + tol
    idx = np.flatnonzero(low)
    if len(idx) > max_points:
        xy = world_a[idx, :2]
        ang = np.linspace(0, 2 * np.pi, max_points, endpoint=False)
        dirs = np.stack([np.cos(ang), np.sin(ang)], -1)
        idx = np.unique(idx[np.argmax(xy @ dirs.T, axis=0)])
    return bodies_a[idx], local_a[idx], rad_a[idx]


class RobotKinematics:
    """A robot's keypoints, feet, root and limits, and the damped-least-squares IK on them.

    Works on its own ``MjData`` (the env's ``data`` is not touched).
    """

    def __init__(self, env: Any, robot_map: Optional[RobotMap] = None):
        self.env = env
        self.model = m = env.model
        self.data = d = mujoco.MjData(m)
        self.map = robot_map or get_robot_map(env.body_name)
        self.init_qpos = np.array(getattr(env, "_init_qpos", m.qpos0), dtype=float)
        d.qpos[:] = self.init_qpos
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)

        # ---- feet (sole points), needed by "sole_front" keypoints
        self.sole: dict = {}
        for s in _FEET:
            spec = self.map.keypoints.get(f"{s}_ankle")
            if spec is None:
                continue
            pp = parse_point(spec)
            body = self._body_id(pp.body) if pp.body else int(m.site_bodyid[self._site_id(pp.site)])
            self.sole[s] = sole_points(m, d, body)
        self.ground_rest = min((self._sole_world(s)[:, 2].min() for s in self.sole), default=0.0)

        # ---- keypoints -> (body, local offset)
        self.names: list = []
        bodies, offsets = [], []
        for key, spec in self.map.keypoints.items():
            pp = parse_point(spec)
            if pp.site is not None:
                sid = self._site_id(pp.site)
                body = int(m.site_bodyid[sid])
                local = np.array(m.site_pos[sid], dtype=float)
            else:
                body = self._body_id(pp.body)
                xmat = d.xmat[body].reshape(3, 3)
                if isinstance(pp.offset, str):        # "sole_front"
                    side = key[0]
                    if side not in self.sole:
                        raise ValueError(f"{self.map.name}: {key} uses 'sole_front' but the robot has no {side}_ankle")
                    w = self._sole_world(side)
                    world = np.array([w[:, 0].max(), w[:, 1].mean(), w[:, 2].min()])
                    local = xmat.T @ (world - d.xpos[body])
                else:
                    local = xmat.T @ np.asarray(pp.offset, dtype=float)
            self.names.append(key)
            bodies.append(body)
            offsets.append(local)
        self.bodies = np.asarray(bodies, dtype=np.int64)
        self.offsets = np.asarray(offsets, dtype=float)
        self.index = {k: i for i, k in enumerate(self.names)}
        self.rest = {k: p for k, p in zip(self.names, self.points())}
        self.flat = self._lateral_sole_points()

        # ---- joints: limits, root, equality couplings
        self._setup_joints()
        self.droppable = self._uncontrollable()

    # ------------------------------------------------------------------ lookups
    def _body_id(self, name: str) -> int:
        i = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_BODY, name)
        if i < 0:
            raise KeyError(f"{self.map.name}: the model has no body {name!r} (keypoint map out of date?)")
        return int(i)

    def _site_id(self, name: str) -> int:
        i = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_SITE, name)
        if i < 0:
            raise KeyError(f"{self.map.name}: the model has no site {name!r}")
        return int(i)

    def _sole_world(self, side: str) -> np.ndarray:
        b, p, r = self.sole[side]
        d = self.data
        w = d.xpos[b] + np.einsum("nij,nj->ni", d.xmat[b].reshape(-1, 3, 3), p)
        w[:, 2] -= r
        return w

    def _lateral_sole_points(self) -> dict:
        """Per foot, two points at the sole's inner and outer edges (same height in the init pose),
        attached to the foot body: their height difference measures the foot's roll."""
        d = self.data
        out = {}
        for s in self.sole:
            w = self._sole_world(s)
            if np.ptp(w[:, 1]) < 0.02:                   # too narrow (a sphere or a blade): no roll term
                continue
            toe = self.index.get(f"{s}_toe")
            if toe is not None:
                body = int(self.bodies[toe])
            else:
                vals, counts = np.unique(self.sole[s][0], return_counts=True)
                body = int(vals[np.argmax(counts)])
            xmat = d.xmat[body].reshape(3, 3)
            xc, zc = w[:, 0].mean(), w[:, 2].min()
            pts = [np.array([xc, y, zc]) for y in (w[:, 1].min(), w[:, 1].max())]
            out[s] = (body, *(xmat.T @ (p - d.xpos[body]) for p in pts))
        return out

    # ------------------------------------------------------------------ kinematics
    def forward(self, qpos: np.ndarray) -> None:
        d = self.data
        d.qpos[:] = qpos
        mujoco.mj_kinematics(self.model, d)
        mujoco.mj_comPos(self.model, d)

    def points(self) -> np.ndarray:
        """(K, 3) world positions of the keypoints in the current state."""
        d = self.data
        return d.xpos[self.bodies] + np.einsum("kij,kj->ki", d.xmat[self.bodies].reshape(-1, 3, 3), self.offsets)

    def keypoints_of(self, qpos_traj: np.ndarray) -> dict:
        """Forward kinematics of a qpos trajectory: ``{keypoint: (T, 3)}``."""
        qpos_traj = np.atleast_2d(np.asarray(qpos_traj, dtype=float))
        pts = np.empty((len(qpos_traj), len(self.names), 3))
        for t, q in enumerate(qpos_traj):
            self.forward(q)
            pts[t] = self.points()
        return {k: pts[:, i] for i, k in enumerate(self.names)}

    def sole_heights(self) -> np.ndarray:
        """(2,) lowest sole point height per foot (left, right) in the current state (inf if absent)."""
        return np.array([self._sole_world(s)[:, 2].min() if s in self.sole else np.inf for s in _FEET])

    def sole_centers(self) -> np.ndarray:
        return np.array([self._sole_world(s).mean(axis=0) if s in self.sole else np.full(3, np.nan) for s in _FEET])

    # ------------------------------------------------------------------ joints
    def _setup_joints(self) -> None:
        m = self.model
        nv = m.nv
        self.limited_qpos, lo, hi = [], [], []
        posture = np.zeros(nv)
        self.dof_qpos = np.full(nv, -1)
        root_body = int(m.jnt_bodyid[0]) if m.njnt else -1
        self.root_free = bool(m.njnt and m.jnt_type[0] == mujoco.mjtJoint.mjJNT_FREE)
        slide_dofs, slide_axes, self.yaw_dof = [], [], None
        d = self.data
        for j in range(m.njnt):
            jt, qa, da = int(m.jnt_type[j]), int(m.jnt_qposadr[j]), int(m.jnt_dofadr[j])
            on_root = int(m.jnt_bodyid[j]) == root_body and int(m.body_parentid[root_body]) == 0
            if jt in (mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_SLIDE):
                self.dof_qpos[da] = qa
                if m.jnt_limited[j]:
                    self.limited_qpos.append(qa)
                    lo.append(m.jnt_range[j, 0])
                    hi.append(m.jnt_range[j, 1])
                if on_root:
                    if jt == mujoco.mjtJoint.mjJNT_SLIDE:
                        slide_dofs.append(da)
                        slide_axes.append(np.array(d.xaxis[j]))
                    elif self.yaw_dof is None and abs(d.xaxis[j][2]) > 0.9:
                        self.yaw_dof = (da, qa, float(np.sign(d.xaxis[j][2])))
                else:
                    posture[da] = 1.0
            elif jt == mujoco.mjtJoint.mjJNT_BALL and not on_root:
                pass                                    # no posture pull on ball joints
        self.limited_qpos = np.asarray(self.limited_qpos, dtype=np.int64)
        self.lo, self.hi = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
        # root translation basis: dq = B @ world_translation
        self.B = np.zeros((nv, 3))
        if self.root_free:
            self.B[int(m.jnt_dofadr[0]):int(m.jnt_dofadr[0]) + 3] = np.eye(3)
        elif slide_dofs:
            A = np.stack(slide_axes, axis=1)            # (3, n_slides)
            self.B[slide_dofs] = np.linalg.pinv(A)
        # joint equality couplings: joint1 = qpos0_1 + poly(joint2 - qpos0_2)
        self.couplings = []
        dependent = set()
        for e in range(m.neq):
            if not m.eq_active0[e] or int(m.eq_type[e]) != int(mujoco.mjtEq.mjEQ_JOINT):
                continue
            j1, j2 = int(m.eq_obj1id[e]), int(m.eq_obj2id[e])
            coef = np.array(m.eq_data[e][:5], dtype=float)
            self.couplings.append((int(m.jnt_qposadr[j1]), int(m.jnt_dofadr[j1]),
                                   int(m.jnt_qposadr[j2]) if j2 >= 0 else -1,
                                   int(m.jnt_dofadr[j2]) if j2 >= 0 else -1, coef))
            dependent.add(int(m.jnt_dofadr[j1]))
        self.free_dofs = np.array([i for i in range(nv) if i not in dependent], dtype=np.int64)
        self.col = {int(dof): c for c, dof in enumerate(self.free_dofs)}
        self.posture = posture[self.free_dofs]
        # limits per reduced column (hinge/slide with a range)
        qlim = dict(zip(self.limited_qpos.tolist(), zip(self.lo, self.hi)))
        self.col_limits = [(c, int(self.dof_qpos[dof]), *qlim[int(self.dof_qpos[dof])])
                           for c, dof in enumerate(self.free_dofs) if int(self.dof_qpos[dof]) in qlim]
        self._qpos_ref = np.array(m.qpos0, dtype=float)

    def _uncontrollable(self) -> set:
        """Keypoints (elbows, wrists, head) that no degree of freedom moves relative to their parent."""
        m, d = self.model, self.data
        self.forward(self.init_qpos)
        jac = np.zeros((3, m.nv))
        moved = {}
        pts = self.points()
        for k, i in self.index.items():
            mujoco.mj_jac(m, d, jac, None, pts[i], int(self.bodies[i]))
            moved[k] = set(np.flatnonzero(np.abs(jac).sum(axis=0) > 1e-9).tolist())
        out = set()
        for k in _DROPPABLE:
            p = _PARENT[k]
            if k in moved and p in moved and moved[k] <= moved[p]:
                out.add(k)
        return out

    def _project(self, q: np.ndarray) -> None:
        """Enforce joint couplings and limits in place."""
        for qa1, _, qa2, _, c in self.couplings:
            x = q[qa2] - self._qpos_ref[qa2] if qa2 >= 0 else 0.0
            q[qa1] = self._qpos_ref[qa1] + c[0] + x * (c[1] + x * (c[2] + x * (c[3] + x * c[4])))
        if len(self.limited_qpos):
            q[self.limited_qpos] = np.clip(q[self.limited_qpos], self.lo, self.hi)

    def _reduction(self, q: np.ndarray) -> np.ndarray:
        """T (nv, n_free): full velocity = T @ reduced velocity (chain rule through the couplings)."""
        nv = self.model.nv
        T = np.zeros((nv, len(self.free_dofs)))
        T[self.free_dofs, np.arange(len(self.free_dofs))] = 1.0
        for qa1, da1, qa2, da2, c in self.couplings:
            if qa2 < 0 or da2 not in self.col:
                continue
            x = q[qa2] - self._qpos_ref[qa2]
            T[da1, self.col[da2]] = c[1] + x * (2 * c[2] + x * (3 * c[3] + x * 4 * c[4]))
        return T

    # ------------------------------------------------------------------ IK
    def place(self, q: np.ndarray, yaw: float, hip_center: np.ndarray) -> np.ndarray:
        """Turn the robot (about the vertical) by ``yaw`` from ``q`` and move it so its hip centre is at
        ``hip_center``."""
        m = self.model
        q = q.copy()
        if self.root_free:
            qa = int(m.jnt_qposadr[0])
            rot = np.array([np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)])
            out = np.empty(4)
            mujoco.mju_mulQuat(out, rot, q[qa + 3:qa + 7])
            q[qa + 3:qa + 7] = out
        elif self.yaw_dof is not None:
            q[self.yaw_dof[1]] += self.yaw_dof[2] * yaw
        self.forward(q)
        pts = self.points()
        hc = 0.5 * (pts[self.index["l_hip"]] + pts[self.index["r_hip"]])
        mujoco.mj_integratePos(m, q, self.B @ (hip_center - hc), 1.0)
        return q

    def solve(self, q: np.ndarray, targets: np.ndarray, weights: np.ndarray, iterations: int,
              opts: RetargetOptions, idx: np.ndarray, flat_weights: Optional[dict] = None,
              smoothness: float = 0.0) -> tuple[np.ndarray, float]:
        """Damped least-squares IK for one frame from ``q``; returns (q, mean keypoint error).

        ``flat_weights``: ``{foot: weight}`` of the foot-roll rows (height difference of the sole's
        inner and outer edges, target 0); ``smoothness``: weight of ``|q - q_start|^2`` (``q_start``
        = the given ``q``, the previous frame's solution)."""
        q_start = np.array(q, dtype=float)
        back = np.zeros(self.model.nv)
        m, d = self.model, self.data
        k = len(idx)
        flats = [(self.flat[s], w) for s, w in (flat_weights or {}).items() if s in self.flat and w > 0]
        J = np.zeros((3 * k + len(flats), m.nv))
        sw = np.concatenate([np.repeat(np.sqrt(weights), 3), [np.sqrt(w) for _, w in flats]])
        jf = np.zeros((3, m.nv))
        n = len(self.free_dofs)
        eye = np.eye(n)
        q = q.copy()
        qref_cols = self.init_qpos[np.maximum(self.dof_qpos[self.free_dofs], 0)]
        qcols = np.maximum(self.dof_qpos[self.free_dofs], 0)
        for _ in range(max(1, iterations)):
            self.forward(q)
            pts = self.points()[idx]
            for i, ki in enumerate(idx):
                mujoco.mj_jac(m, d, J[3 * i:3 * i + 3], None, pts[i], int(self.bodies[ki]))
            err = (targets - pts).ravel()
            if flats:
                rows = []
                for f, ((body, p_in, p_out), _) in enumerate(flats):
                    xm = d.xmat[body].reshape(3, 3)
                    a, b = d.xpos[body] + xm @ p_in, d.xpos[body] + xm @ p_out
                    mujoco.mj_jac(m, d, jf, None, a, body)
                    row = jf[2].copy()
                    mujoco.mj_jac(m, d, jf, None, b, body)
                    J[3 * k + f] = row - jf[2]
                    rows.append(-(a[2] - b[2]))
                err = np.concatenate([err, rows])
            T = self._reduction(q)
            A = (J @ T) * sw[:, None]
            b = err * sw
            post = opts.posture * self.posture
            H = A.T @ A + (opts.damping + smoothness) * eye + np.diag(post)
            g = A.T @ b + post * (qref_cols - q[qcols])
            if smoothness > 0:
                mujoco.mj_differentiatePos(m, back, 1.0, q, q_start)
                g += smoothness * back[self.free_dofs]
            dq = np.linalg.solve(H, g)
            # active set: freeze columns at a limit that the step pushes further out, re-solve once
            frozen = [c for c, qa, lo, hi in self.col_limits
                      if (q[qa] <= lo + 1e-9 and dq[c] < 0) or (q[qa] >= hi - 1e-9 and dq[c] > 0)]
            if frozen:
                keep = np.ones(n, dtype=bool)
                keep[frozen] = False
                dq = np.zeros(n)
                dq[keep] = np.linalg.solve(H[np.ix_(keep, keep)], g[keep])
            peak = np.abs(dq).max()
            if peak > opts.max_step:
                dq *= opts.max_step / peak
            mujoco.mj_integratePos(m, q, T @ dq, 1.0)
            self._project(q)
            if peak < opts.tolerance:
                break
        self.forward(q)
        res = np.linalg.norm(targets - self.points()[idx], axis=-1)
        return q, float(res.mean())

    # ------------------------------------------------------------------ ground
    def fix_ground(self, qpos: np.ndarray, contacts: np.ndarray, fps: float) -> tuple[np.ndarray, np.ndarray]:
        """Vertical root shift per frame (see the module docstring); returns (qpos, shift)."""
        t = len(qpos)
        low = np.empty((t, 2))
        for i, q in enumerate(qpos):
            self.forward(q)
            low[i] = self.sole_heights()
        any_c = contacts.any(axis=1)
        lowest = low.min(axis=1)
        if any_c.any():
            contact_low = np.where(contacts, low, np.inf).min(axis=1)
            frames = np.flatnonzero(any_c)
            shift = np.interp(np.arange(t), frames, -contact_low[frames])
            win = max(1, int(round(0.05 * fps)))
            if win > 1 and t > win:
                pad = np.pad(shift, (win // 2, win - 1 - win // 2), mode="edge")
                shift = np.convolve(pad, np.ones(win) / win, mode="valid")
        else:
            shift = np.full(t, -float(np.median(lowest)))
        shift = np.maximum(shift, -lowest)              # no sole point below the ground
        out = qpos.copy()
        for i in range(t):
            mujoco.mj_integratePos(self.model, out[i], self.B @ np.array([0.0, 0.0, shift[i]]), 1.0)
        return out, shift

    def velocities(self, qpos: np.ndarray, dt: float) -> np.ndarray:
        """Central finite differences with ``mj_differentiatePos`` (one-sided at the ends)."""
        t, nv = len(qpos), self.model.nv
        qvel = np.zeros((t, nv))
        if t < 2:
            return qvel
        for i in range(t):
            a, b = max(0, i - 1), min(t - 1, i + 1)
            mujoco.mj_differentiatePos(self.model, qvel[i], (b - a) * dt, qpos[a], qpos[b])
        return qvel

    def in_limits(self, qpos: np.ndarray, tol: float = 1e-6) -> np.ndarray:
        if not len(self.limited_qpos):
            return np.ones(len(qpos), dtype=bool)
        v = qpos[:, self.limited_qpos]
        return np.all((v >= self.lo - tol) & (v <= self.hi + tol), axis=1)


# =============================================================================== drivers


def _scale_for(kin: RobotKinematics, src: Mapping[str, np.ndarray], opts: RetargetOptions,
               src_height: Optional[float]) -> float:
    if isinstance(opts.scale, (int, float)) and not isinstance(opts.scale, bool):
        return float(opts.scale)
    if opts.scale == "height":
        if not src_height:
            raise ValueError("scale='height' needs the source's height")
        return kin.map.height / float(src_height)
    if opts.scale != "legs":
        raise ValueError(f"scale must be 'legs', 'height' or a number, got {opts.scale!r}")
    return leg_length(kin.rest) / leg_length(src)


def retarget_keypoints(env: Any, keypoints: Mapping[str, np.ndarray], fps: float, *,
                       options: Optional[RetargetOptions] = None, robot_map: Optional[RobotMap] = None,
                       kinematics: Optional[RobotKinematics] = None, source: str = "",
                       source_height: Optional[float] = None, verbose: bool = False) -> RetargetResult:
    """Retarget source keypoints ``{name: (T, 3)}`` sampled at ``fps`` to ``env``'s robot."""
    t0 = time.perf_counter()
    opts = options or RetargetOptions()
    kin = kinematics or RobotKinematics(env, robot_map)
    dt = float(env.dt)
    env_fps = 1.0 / dt
    src = {k: np.asarray(v, dtype=float) for k, v in keypoints.items()}
    if opts.align:
        src, _ = align_heading(src)
    if opts.smooth_sigma > 0:
        src = smooth_keypoints(src, opts.smooth_sigma * fps)
    src = resample_keypoints(src, fps, env_fps)
    t = next(iter(src.values())).shape[0]
    scale = _scale_for(kin, src, opts, source_height)
    leg = leg_length(kin.rest)

    # contacts on the scaled source (feet positions do not depend on the target mode's details)
    scaled = {k: scale * v for k, v in src.items()}
    point_contacts = detect_contacts(scaled, env_fps, leg, opts.contact_height, opts.contact_speed)
    contacts = foot_contacts(point_contacts, t)
    targets = build_targets(src, kin.rest, scale, opts.mode,
                            stance={"l": contacts[:, 0], "r": contacts[:, 1]})
    strength = {k: v.astype(float) for k, v in point_contacts.items()}
    if opts.pin_contacts:
        targets, ground, strength = _pin_feet(targets, point_contacts, kin.rest, kin.ground_rest,
                                              blend=max(1, int(round(opts.pin_blend * env_fps))))
        for v in targets.values():          # the estimated ground becomes z = 0 (the env's floor)
            v[:, 2] -= ground

    used = [k for k in kin.names if k in targets and k not in kin.droppable]
    if "l_hip" not in used or "r_hip" not in used:
        raise ValueError(f"{kin.map.name}: the source gives no hip targets")
    idx = np.array([kin.index[k] for k in used])
    tgt = np.stack([targets[k] for k in used], axis=1)               # (T, K, 3)
    base_w = np.array([float((opts.weights or {}).get(k, kin.map.weight(k))) for k in used])
    # contact weights fade in and out with the pins (a weight that jumps makes the solution jump)
    boost = np.ones((t, len(used)))
    for i, k in enumerate(used):
        if k in strength:
            boost[:, i] += (opts.contact_weight - 1.0) * strength[k]
    foot_strength = np.zeros((t, 2))
    for j, s in enumerate(_FEET):
        for part in ("ankle", "toe"):
            if f"{s}_{part}" in strength:
                foot_strength[:, j] = np.maximum(foot_strength[:, j], strength[f"{s}_{part}"])

    # first frame: init pose turned to the source's heading, many iterations
    f0 = _pelvis_frame({k: v[:1] for k, v in targets.items() if k in ("l_hip", "r_hip", "torso")})[0]
    f_rest = _pelvis_frame({k: v[None] for k, v in kin.rest.items() if k in ("l_hip", "r_hip", "torso")})[0]
    yaw = float(np.arctan2(f0[1, 0], f0[0, 0]) - np.arctan2(f_rest[1, 0], f_rest[0, 0]))
    hc0 = 0.5 * (targets["l_hip"][0] + targets["r_hip"][0])
    q = kin.place(kin.init_qpos, yaw, hc0)
    qpos = np.empty((t, kin.model.nq))
    errors = np.empty(t)
    for i in range(t):
        w = base_w * boost[i]
        flat = {s: opts.flat_weight * (1.0 + (opts.contact_weight - 1.0) * foot_strength[i, j])
                for j, s in enumerate(_FEET)}
        q, errors[i] = kin.solve(q, tgt[i], w, opts.first_iterations if i == 0 else opts.iterations, opts, idx,
                                 flat_weights=flat, smoothness=0.0 if i == 0 else opts.smoothness)
        qpos[i] = q
        if verbose and (i + 1) % 500 == 0:
            print(f"[retarget] {kin.map.name}: frame {i + 1}/{t}, mean keypoint error {errors[:i + 1].mean():.4f} m",
                  flush=True)

    # achieved keypoints before the ground shift (pose error)
    pts_pre = kin.keypoints_of(qpos)
    if opts.fix_ground:
        qpos, shift = kin.fix_ground(qpos, contacts, env_fps)
    else:
        shift = np.zeros(t)
    qvel = kin.velocities(qpos, dt)

    # ---- metrics
    low = np.empty((t, 2))
    for i, qq in enumerate(qpos):
        kin.forward(qq)
        low[i] = kin.sole_heights()
    pts_post = kin.keypoints_of(qpos)
    err_all = np.stack([np.linalg.norm(pts_pre[k] - targets[k], axis=-1) for k in used], 1)
    hc_r = 0.5 * (pts_pre["l_hip"] + pts_pre["r_hip"])
    hc_s = scale * _hip_center(src)
    uni = [np.linalg.norm((pts_pre[k] - hc_r) - (scale * src[k] - hc_s), axis=-1) for k in used if k in src]
    slide = [np.linalg.norm(np.gradient(pts_post[k][:, :2], dt, axis=0), axis=-1)[m]
             for k, m in point_contacts.items() if k in pts_post and m.any()]
    slide = np.concatenate(slide) if slide else np.zeros(0)
    pen = np.maximum(0.0, -np.nanmin(np.where(np.isfinite(low), low, np.nan), axis=1))
    metrics = {
        "frames": int(t), "fps": env_fps, "scale": float(scale),
        "keypoint_error_m": float(err_all.mean()),
        "keypoint_error_max_m": float(err_all.max()),
        "keypoint_error_uniform_m": float(np.mean(uni)) if uni else float("nan"),
        "foot_sliding_mps": float(slide.mean()) if slide.size else 0.0,
        "penetration_mean_m": float(pen.mean()), "penetration_max_m": float(pen.max()),
        "in_limits_fraction": float(kin.in_limits(qpos).mean()),
        "contact_fraction": float(contacts.mean()),
        "root_shift_mean_m": float(np.abs(shift).mean()),
        "used_keypoints": used, "dropped_keypoints": sorted(set(kin.names) - set(used)),
        "seconds": float(time.perf_counter() - t0),
    }
    ground_z = ground if opts.pin_contacts else 0.0
    source_points = {k: v - np.array([0.0, 0.0, ground_z]) + shift[:, None] * np.array([0.0, 0.0, 1.0])
                     for k, v in scaled.items()}
    return RetargetResult(qpos=qpos, qvel=qvel, dt=dt, targets=targets, robot_points=pts_post, contacts=contacts,
                          used_keypoints=used, scale=float(scale), metrics=metrics, root_shift=shift, source=source,
                          source_points=source_points)


def _clip_height(kp: Mapping[str, np.ndarray]) -> Optional[float]:
    if "head" not in kp:
        return None
    ground = min(np.quantile(kp[k][:, 2], 0.05) for k in ("l_toe", "r_toe", "l_ankle", "r_ankle") if k in kp)
    return float(np.median(kp["head"][:, 2]) - ground + 0.1)      # head centre -> crown ~0.1 m


def retarget_clip(env: Any, clip: MotionClip, *, n_cycles: int = 1, options: Optional[RetargetOptions] = None,
                  robot_map: Optional[RobotMap] = None, kinematics: Optional[RobotKinematics] = None,
                  verbose: bool = False) -> RetargetResult:
    """Retarget a motion-capture clip to ``env``'s robot (``n_cycles`` > 1 repeats a cyclic clip)."""
    kp = canonical_keypoints(clip, require=("l_hip", "r_hip", "l_knee", "r_knee", "l_ankle", "r_ankle"))
    if n_cycles > 1:
        kp = loop_keypoints(kp, n_cycles)
    return retarget_keypoints(env, kp, clip.fps, options=options, robot_map=robot_map, kinematics=kinematics,
                              source=clip.name or str(clip.meta.get("source", "")), source_height=_clip_height(kp),
                              verbose=verbose)


def robot_keypoints(env: Any, qpos_traj: np.ndarray, robot_map: Optional[RobotMap] = None) -> dict:
    """Keypoints ``{name: (T, 3)}`` of a robot's qpos trajectory (forward kinematics on its map)."""
    return RobotKinematics(env, robot_map).keypoints_of(qpos_traj)


def retarget_robot_to_robot(src_env: Any, src_qpos_traj: np.ndarray, dst_env: Any, *,
                            options: Optional[RetargetOptions] = None, src_map: Optional[RobotMap] = None,
                            dst_map: Optional[RobotMap] = None, verbose: bool = False) -> RetargetResult:
    """Retarget a ``(T, nq)`` qpos trajectory of ``src_env``'s robot (sampled every ``src_env.dt``) to
    ``dst_env``'s robot, through both robots' keypoint maps and the same solver.

    The source keeps its heading and position (``align=False`` unless ``options`` say otherwise)."""
    src_kin = RobotKinematics(src_env, src_map)
    kp = src_kin.keypoints_of(src_qpos_traj)
    opts = options or RetargetOptions(align=False)
    return retarget_keypoints(dst_env, kp, 1.0 / float(src_env.dt), options=opts, robot_map=dst_map,
                              source=f"{src_env.body_name} qpos trajectory", source_height=src_kin.map.height,
                              verbose=verbose)
