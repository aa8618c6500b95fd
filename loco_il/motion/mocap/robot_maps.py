"""Per-robot keypoint maps: which point of a robot corresponds to each canonical keypoint.

The retargeting solver (:mod:`.retarget`) matches the 18 canonical keypoints of a motion
(:data:`~.skeleton.CANONICAL_KEYPOINTS`: pelvis, hips, knees, ankles, toes, torso, neck, head,
shoulders, elbows, wrists) to points on a robot.  A :class:`RobotMap` says, for one robot
(one Task-ID body name), where each of those points is.  Maps are plain data; a robot may
leave keypoints out (a legs-only robot has no arms).

How a point is written (``RobotMap.keypoints[name]``):

* ``"body_name"`` -- the origin of that MuJoCo body;
* ``("body_name", (dx, dy, dz))`` -- a point rigidly attached to that body, given as an
  offset **in world axes (z up, x forward, y left) from the body's origin with the robot in
  its initial pose** (the env's init keyframe).  The solver converts it to the body frame
  once, so offsets can be read off a picture of the robot standing;
* ``("body_name", "sole_front")`` -- the front of the foot sole: the front-most point of the
  foot's contact geometry, centred across the foot, at the height of the sole, attached to
  ``body_name``.  Computed from the model (see :func:`.retarget.sole_points`);
* ``"site:site_name"`` -- a MuJoCo site.

Conventions the solver relies on: the robot faces +x with its left side at +y in its initial
pose (true of every body here); ``*_hip`` is a point of the hip that moves with the pelvis (the
anchor of the first hip joint, where the hip axes meet when they do); ``*_ankle`` is on the ankle pitch axis (so the
ankle keypoint does not move when the foot pitches, and ``*_toe`` does); ``torso`` is a point
on the upper trunk, ``neck`` the base of the neck between the shoulders, ``head`` the centre
of the head; ``*_shoulder`` / ``*_elbow`` / ``*_wrist`` the arm joint centres (the wrist of
robots without a wrist joint: the end of the forearm).

``height`` is the robot's standing height in metres (top of the head, or of the trunk for a
headless robot, in the initial pose): used by ``scale="height"`` and reported in dataset info.
Scaling uses leg length (hip -> knee -> ankle) by default.

Status (see ``RETARGET_NOTES`` for details): maps exist for every humanoid body registered
in loco_il (LocoMuJoCo's Atlas, Talos, UnitreeH1, UnitreeG1, HumanoidTorque, HumanoidMuscle and their
4Ages versions, whose offsets are the adult's: motion is retargeted to the adult size;
Menagerie's H1, G1, BoosterT1, BerkeleyHumanoid, ApptronikApollo, RobotisOP3; MyoLeg;
Gymnasium's Humanoid).  Quadrupeds (UnitreeA1, UnitreeGo1) and the planar classic bodies have
no human keypoint map.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Mapping, Optional, Tuple, Union

__all__ = ["RobotMap", "ROBOT_MAPS", "get_robot_map", "has_robot_map", "PointSpec", "parse_point",
           "KEYPOINT_WEIGHTS", "RETARGET_NOTES"]

#: one keypoint: "body", ("body", (dx, dy, dz)), ("body", "sole_front") or "site:name"
PointSpec = Union[str, Tuple[str, Union[Tuple[float, float, float], str]]]

#: default relative weight of each keypoint in the IK objective (feet matter most: they carry
#: the contacts; the arms least: they do not change where the robot goes)
KEYPOINT_WEIGHTS = {
    "pelvis": 1.0, "l_hip": 1.5, "r_hip": 1.5, "l_knee": 1.0, "r_knee": 1.0,
    "l_ankle": 2.0, "r_ankle": 2.0, "l_toe": 1.5, "r_toe": 1.5,
    "torso": 0.5, "neck": 0.5, "head": 0.2,
    "l_shoulder": 0.5, "r_shoulder": 0.5, "l_elbow": 0.3, "r_elbow": 0.3, "l_wrist": 0.2, "r_wrist": 0.2,
}


@dataclass(frozen=True)
class RobotMap:
    """Keypoint map of one robot body (see the module docstring for the point syntax)."""

    name: str
    height: float
    keypoints: Mapping[str, PointSpec]
    weights: Mapping[str, float] = field(default_factory=dict)
    notes: str = ""

    def weight(self, key: str) -> float:
        return float(self.weights.get(key, KEYPOINT_WEIGHTS.get(key, 1.0)))


@dataclass(frozen=True)
class ParsedPoint:
    body: Optional[str]
    site: Optional[str]
    offset: Union[Tuple[float, float, float], str]


def parse_point(spec: PointSpec) -> ParsedPoint:
    """Normalise a point spec; raises ``ValueError`` naming what is wrong."""
    if isinstance(spec, str):
        if spec.startswith("site:"):
            return ParsedPoint(None, spec[5:], (0.0, 0.0, 0.0))
        return ParsedPoint(spec, None, (0.0, 0.0, 0.0))
    if isinstance(spec, tuple) and len(spec) == 2 and isinstance(spec[0], str):
        body, off = spec
        if isinstance(off, str):
            if off != "sole_front":
                raise ValueError(f"unknown point keyword {off!r} (only 'sole_front')")
            return ParsedPoint(body, None, off)
        off = tuple(float(v) for v in off)
        if len(off) != 3:
            raise ValueError(f"offset of {spec!r} must have 3 numbers")
        return ParsedPoint(body, None, off)
    raise ValueError(f"bad keypoint spec {spec!r}: use 'body', ('body', (dx, dy, dz)), "
                     f"('body', 'sole_front') or 'site:name'")


def _legs(hip_l, knee_l, ankle_l, foot_l, hip_r, knee_r, ankle_r, foot_r):
    return {"l_hip": hip_l, "l_knee": knee_l, "l_ankle": ankle_l, "l_toe": (foot_l, "sole_front"),
            "r_hip": hip_r, "r_knee": knee_r, "r_ankle": ankle_r, "r_toe": (foot_r, "sole_front")}


def _arms(sh_l, el_l, wr_l, sh_r, el_r, wr_r):
    return {"l_shoulder": sh_l, "l_elbow": el_l, "l_wrist": wr_l,
            "r_shoulder": sh_r, "r_elbow": el_r, "r_wrist": wr_r}


def _map(name: str, height: float, *parts: Mapping[str, PointSpec], notes: str = "",
         weights: Optional[Mapping[str, float]] = None) -> RobotMap:
    kp: dict = {}
    for p in parts:
        kp.update(p)
    return RobotMap(name=name, height=height, keypoints=kp, weights=dict(weights or {}), notes=notes)


# --------------------------------------------------------------------------- the maps
# Body names and offsets read from each model in its initial pose (world axes, metres).

_UNITREE_H1_LEGS = _legs("left_hip_yaw_link", "left_knee_link", "left_ankle_link", "left_ankle_link",
                         "right_hip_yaw_link", "right_knee_link", "right_ankle_link", "right_ankle_link")

ROBOT_MAPS: dict[str, RobotMap] = {m.name: m for m in [
    # ---------------------------------------------------------------- LocoMuJoCo bodies
    _map("UnitreeH1", 1.79,
         {"pelvis": "pelvis", "torso": ("torso_link", (0.0, 0.0, 0.20)), "neck": ("torso_link", (0.03, 0.0, 0.43)),
          "head": ("torso_link", (0.05, 0.0, 0.62))},
         _UNITREE_H1_LEGS,
         _arms("left_shoulder_roll_link", "left_elbow_link", ("left_elbow_link", (0.17, 0.01, -0.20)),
               "right_shoulder_roll_link", "right_elbow_link", ("right_elbow_link", (0.17, -0.01, -0.20))),
         notes="LocoMuJoCo removes the arm joints: arms follow the torso, elbow/wrist targets are dropped"),
    _map("UnitreeG1", 1.26,
         {"pelvis": "pelvis", "torso": ("torso_link", (0.0, 0.0, 0.12)), "neck": ("torso_link", (0.0, 0.0, 0.26)),
          "head": ("torso_link", (0.0, 0.0, 0.42))},
         _legs("left_hip_pitch_link", "left_knee_link", "left_ankle_pitch_link", "left_ankle_roll_link",
               "right_hip_pitch_link", "right_knee_link", "right_ankle_pitch_link", "right_ankle_roll_link"),
         _arms("left_shoulder_roll_link", "left_elbow_pitch_link", ("left_elbow_roll_link", (0.13, 0.0, 0.0)),
               "right_shoulder_roll_link", "right_elbow_pitch_link", ("right_elbow_roll_link", (0.13, 0.0, 0.0)))),
    _map("Atlas", 1.97,
         {"pelvis": "pelvis", "torso": ("utorso", (0.0, 0.0, 0.15)), "neck": ("utorso", (0.05, 0.0, 0.45)),
          "head": ("utorso", (0.12, 0.0, 0.70))},
         _legs("l_uglut", "l_lleg", "l_talus", "l_foot", "r_uglut", "r_lleg", "r_talus", "r_foot"),
         _arms("l_scap", "l_larm", "l_lfarm", "r_scap", "r_larm", "r_lfarm"),
         notes="LocoMuJoCo removes the back and arm joints: torso and arms follow the pelvis"),
    _map("Talos", 1.76,
         {"pelvis": "pelvis", "torso": ("torso_2_link", (0.0, 0.0, 0.15)), "neck": ("torso_2_link", (0.0, 0.0, 0.28)),
          "head": ("head_2_link", (0.03, 0.0, 0.18))},
         _legs("leg_left_1_link", "leg_left_4_link", "leg_left_5_link", "leg_left_6_link",
               "leg_right_1_link", "leg_right_4_link", "leg_right_5_link", "leg_right_6_link"),
         _arms("arm_left_2_link", "arm_left_4_link", "arm_left_7_link",
               "arm_right_2_link", "arm_right_4_link", "arm_right_7_link"),
         notes="LocoMuJoCo removes the arm joints: arms follow the torso"),
    *[_map(name, 1.76,
           {"pelvis": "pelvis", "torso": ("torso", (0.0, 0.0, 0.25)), "neck": ("torso", (0.03, 0.0, 0.40)),
            "head": ("torso", (0.03, 0.0, 0.60))},
           _legs("femur_l", "tibia_l", "talus_l", "toes_l", "femur_r", "tibia_r", "talus_r", "toes_r"),
           _arms("humerus_l", "ulna_l", "hand_l", "humerus_r", "ulna_r", "hand_r"),
           notes="arms have no joints in LocoMuJoCo's model: they follow the torso")
      for name in ("HumanoidTorque", "HumanoidMuscle", "HumanoidTorque4Ages", "HumanoidMuscle4Ages")],
    # ---------------------------------------------------------------- MuJoCo Menagerie bodies
    _map("H1", 1.74,
         {"pelvis": "pelvis", "torso": ("torso_link", (0.0, 0.0, 0.20)), "neck": ("torso_link", (0.0, 0.0, 0.43)),
          "head": ("torso_link", (0.03, 0.0, 0.62))},
         _UNITREE_H1_LEGS,
         _arms("left_shoulder_roll_link", "left_elbow_link", ("left_elbow_link", (0.25, 0.0, -0.015)),
               "right_shoulder_roll_link", "right_elbow_link", ("right_elbow_link", (0.25, 0.0, -0.015)))),
    _map("G1", 1.32,
         {"pelvis": "pelvis", "torso": ("torso_link", (0.0, 0.0, 0.12)), "neck": ("torso_link", (0.0, 0.0, 0.25)),
          "head": ("torso_link", (0.03, 0.0, 0.37))},
         _legs("left_hip_pitch_link", "left_knee_link", "left_ankle_pitch_link", "left_ankle_roll_link",
               "right_hip_pitch_link", "right_knee_link", "right_ankle_pitch_link", "right_ankle_roll_link"),
         _arms("left_shoulder_roll_link", "left_elbow_link", "left_wrist_yaw_link",
               "right_shoulder_roll_link", "right_elbow_link", "right_wrist_yaw_link")),
    _map("BoosterT1", 1.16,
         {"pelvis": "Waist", "torso": "Trunk", "neck": ("Trunk", (0.06, 0.0, 0.22)), "head": ("H2", (0.02, 0.0, 0.08))},
         _legs("Hip_Pitch_Left", "Shank_Left", "Ankle_Cross_Left", "left_foot_link",
               "Hip_Pitch_Right", "Shank_Right", "Ankle_Cross_Right", "right_foot_link"),
         _arms("AL2", "left_hand_link", ("left_hand_link", (0.02, 0.0, -0.16)),
               "AR2", "right_hand_link", ("right_hand_link", (0.02, 0.0, -0.16))),
         notes="the free joint is on the trunk; 'Waist' (below the waist joint) plays the pelvis"),
    _map("BerkeleyHumanoid", 0.82,
         {"pelvis": "torso", "torso": ("torso", (0.0, 0.0, 0.15))},
         _legs("ll_hfe", "ll_kfe", "ll_ffe", "ll_faa", "lr_hfe", "lr_kfe", "lr_ffe", "lr_faa"),
         notes="legs only (no arms, no head): upper-body keypoints other than the trunk are not used"),
    _map("ApptronikApollo", 1.73,
         {"pelvis": "base_link", "torso": ("torso_link", (0.0, 0.0, 0.15)), "neck": "neck_yaw_link",
          "head": ("neck_pitch_link", (0.03, 0.0, 0.03))},
         _legs("l_hip_ie_link", "l_knee_fe_link", "l_ankle_ie_link", "l_foot_link",
               "r_hip_ie_link", "r_knee_fe_link", "r_ankle_ie_link", "r_foot_link"),
         _arms("l_shoulder_fe_link", "l_elbow_fe_link", "l_wrist_yaw_link",
               "r_shoulder_fe_link", "r_elbow_fe_link", "r_wrist_yaw_link")),
    _map("RobotisOP3", 0.51,
         {"pelvis": "body_link", "torso": ("body_link", (0.0, 0.0, 0.06)), "neck": ("body_link", (0.0, 0.0, 0.11)),
          "head": ("head_tilt_link", (0.01, -0.019, 0.03))},
         _legs("l_hip_pitch_link", "l_knee_link", "l_ank_pitch_link", "l_ank_roll_link",
               "r_hip_pitch_link", "r_knee_link", "r_ank_pitch_link", "r_ank_roll_link"),
         _arms("l_sho_roll_link", "l_el_link", ("l_el_link", (0.0, 0.13, 0.0)),
               "r_sho_roll_link", "r_el_link", ("r_el_link", (0.0, -0.13, 0.0))),
         notes="the Menagerie model has no joint ranges: limits are not enforced (none exist)"),
    # ---------------------------------------------------------------- musculoskeletal / classic
    _map("MyoLeg", 1.70,
         {"pelvis": "pelvis", "torso": ("torso", (0.0, 0.0, 0.25))},
         _legs("femur_l", "tibia_l", "talus_l", "toes_l", "femur_r", "tibia_r", "talus_r", "toes_r"),
         notes="legs only; the trunk is rigid with the pelvis. Knee translations and patella joints are "
               "coupled to the knee angle by equality constraints, which the solver enforces"),
    _map("Humanoid", 1.68,
         {"pelvis": "pelvis", "torso": ("lwaist", (0.0, 0.0, 0.05)), "neck": "torso",
          "head": ("torso", (0.0, 0.0, 0.19)),
          "l_hip": "left_thigh", "l_knee": "left_shin", "l_ankle": ("left_foot", (0.0, 0.0, 0.10)),
          "r_hip": "right_thigh", "r_knee": "right_shin", "r_ankle": ("right_foot", (0.0, 0.0, 0.10))},
         _arms("left_upper_arm", "left_lower_arm", ("left_lower_arm", (0.18, -0.18, 0.18)),
               "right_upper_arm", "right_lower_arm", ("right_lower_arm", (0.18, 0.18, 0.18))),
         notes="Gymnasium's humanoid: spherical feet without an ankle joint, so no toe keypoints"),
]}

#: one line per robot on what its map can and cannot do (for docs and reports)
RETARGET_NOTES = {name: m.notes for name, m in ROBOT_MAPS.items() if m.notes}


def has_robot_map(body_name: str) -> bool:
    return body_name in ROBOT_MAPS


def get_robot_map(body_name: str) -> RobotMap:
    """The map of a body name (``env.body_name``); ``KeyError`` listing the robots that have one."""
    try:
        return ROBOT_MAPS[body_name]
    except KeyError:
        raise KeyError(f"no keypoint map for body {body_name!r}: retargeting needs a humanoid with a map in "
                       f"loco_il/motion/mocap/robot_maps.py; robots with a map: {', '.join(sorted(ROBOT_MAPS))}"
                       ) from None
