"""Loader for DeepMimic motion files (``humanoid3d_*.txt``).

Format (facts of the DeepMimic format):

* A motion file is JSON: ``{"Loop": "wrap" | "none", "Frames": [[...], ...]}``.
* Each frame is ``[dt, root_pos(3), root_quat(4, w first), <joint values>]`` where
  the joint values follow the character's joints in ID order: 4 numbers (a w-first
  quaternion) per ``spherical`` joint, 1 number (an angle in radians) per
  ``revolute`` joint, nothing for ``fixed`` joints.  For the ``humanoid3d``
  character this is ``chest(4), neck(4), r_hip(4), r_knee(1), r_ankle(4),
  r_shoulder(4), r_elbow(1), l_hip(4), l_knee(1), l_ankle(4), l_shoulder(4),
  l_elbow(1)``: 44 numbers per frame.
* ``dt`` is the time from this frame to the next (the last frame's is 0).  Units
  are metres and radians; the world is Y up, the character faces +X with its right
  side at +Z.
* A character file is JSON with ``Skeleton.Joints`` (``ID``, ``Name``, ``Type``,
  ``Parent``, ``AttachX/Y/Z`` = offset from the parent joint, ``AttachThetaX/Y/Z``,
  limits) and ``BodyDefs`` (collision shapes attached to joints).  A revolute
  joint rotates about the Z axis of its joint frame.

Conventions of the returned :class:`~.skeleton.MotionClip`: Z up, X forward, Y left
(``(x, y, z)_deepmimic -> (x, -z, y)``), metres, w-first quaternions.  With the
default ``humanoid3d`` skeleton the knee hinge axis becomes ``(0, -1, 0)`` and the
elbow likewise, so :meth:`MotionClip.hinge_angle` reads the file's values: knee
flexion is negative (limits ``[-3.14, 0]``), elbow flexion positive
(``[0, 3.14]``).  ``fps = 1 / dt`` (snapped to an integer within 0.01 %); a file
whose ``dt`` varies by more than 1 % is resampled onto a uniform grid at the
median ``dt``.

Besides the 15 character joints the skeleton has fixed *sites* derived from the
character's body shapes: ``r_toe``/``l_toe`` (front-bottom edge of the foot box),
``r_heel``/``l_heel`` (back-bottom edge) and ``head`` (centre of the head sphere).
"""

from __future__ import annotations

import json
import os
import warnings
from pathlib import Path
from typing import Optional, Union

import numpy as np

from .skeleton import (
    MotionClip,
    Skeleton,
    Y_UP_TO_Z_UP,
    quat_from_axis_angle,
    quat_from_matrix,
    quat_normalize,
    snap_fps,
)

__all__ = [
    "DeepMimicFormatError",
    "DeepMimicCharacter",
    "load_deepmimic",
    "parse_deepmimic",
    "load_deepmimic_character",
    "humanoid3d_skeleton",
    "DEEPMIMIC_NAME_MAP",
    "HUMANOID3D_JOINTS",
    "HUMANOID3D_SITES",
    "DEEPMIMIC_TO_WORLD",
]

#: Rotation from DeepMimic axes (Y up, facing +X, right at +Z) to the world.
DEEPMIMIC_TO_WORLD = Y_UP_TO_Z_UP

#: DeepMimic joint names -> standard names.
DEEPMIMIC_NAME_MAP = {
    "root": "pelvis",
    "chest": "chest",
    "neck": "neck",
    "right_hip": "r_hip",
    "right_knee": "r_knee",
    "right_ankle": "r_ankle",
    "right_shoulder": "r_shoulder",
    "right_elbow": "r_elbow",
    "right_wrist": "r_wrist",
    "left_hip": "l_hip",
    "left_knee": "l_knee",
    "left_ankle": "l_ankle",
    "left_shoulder": "l_shoulder",
    "left_elbow": "l_elbow",
    "left_wrist": "l_wrist",
}

#: The ``humanoid3d`` character, ``(name, type, parent name, attach offset (x, y, z) in
#: metres, DeepMimic axes)``.  Numbers from DeepMimic's ``data/characters/humanoid3d.txt``
#: (MIT licence), as shipped in ``loco_il/motion/mocap/data/deepmimic/humanoid3d_character.txt``.
HUMANOID3D_JOINTS = (
    ("root", "none", None, (0.0, 0.0, 0.0)),
    ("chest", "spherical", "root", (0.0, 0.236151, 0.0)),
    ("neck", "spherical", "chest", (0.0, 0.223894, 0.0)),
    ("right_hip", "spherical", "root", (0.0, 0.0, 0.084887)),
    ("right_knee", "revolute", "right_hip", (0.0, -0.421546, 0.0)),
    ("right_ankle", "spherical", "right_knee", (0.0, -0.409870, 0.0)),
    ("right_shoulder", "spherical", "chest", (-0.02405, 0.24350, 0.18311)),
    ("right_elbow", "revolute", "right_shoulder", (0.0, -0.274788, 0.0)),
    ("right_wrist", "fixed", "right_elbow", (0.0, -0.258947, 0.0)),
    ("left_hip", "spherical", "root", (0.0, 0.0, -0.084887)),
    ("left_knee", "revolute", "left_hip", (0.0, -0.421546, 0.0)),
    ("left_ankle", "spherical", "left_knee", (0.0, -0.409870, 0.0)),
    ("left_shoulder", "spherical", "chest", (-0.02405, 0.24350, -0.18311)),
    ("left_elbow", "revolute", "left_shoulder", (0.0, -0.274788, 0.0)),
    ("left_wrist", "fixed", "left_elbow", (0.0, -0.258947, 0.0)),
)

#: Sites of the ``humanoid3d`` character, ``(standard name, parent joint, offset)`` in
#: DeepMimic axes, from its ``BodyDefs`` (same source): each foot is a box centred at
#: ``(0.045, -0.0225, 0)`` from the ankle with size ``(0.177, 0.055, 0.09)``, so the
#: front-bottom edge is at ``(0.045 + 0.0885, -0.0225 - 0.0275, 0)`` and the back-bottom
#: edge at ``(0.045 - 0.0885, -0.05, 0)``; the head sphere is centred ``0.175`` above
#: the neck joint.
HUMANOID3D_SITES = (
    ("head", "neck", (0.0, 0.175, 0.0)),
    ("r_toe", "right_ankle", (0.1335, -0.05, 0.0)),
    ("r_heel", "right_ankle", (-0.0435, -0.05, 0.0)),
    ("l_toe", "left_ankle", (0.1335, -0.05, 0.0)),
    ("l_heel", "left_ankle", (-0.0435, -0.05, 0.0)),
)

_DOFS = {"none": 7, "spherical": 4, "revolute": 1, "fixed": 0}
_TYPES = {"none": "free", "spherical": "ball", "revolute": "hinge", "fixed": "fixed"}
_CHANNELS = {"none": ("pos", "quat"), "spherical": ("quat",), "revolute": ("hinge",), "fixed": ()}


class DeepMimicFormatError(ValueError):
    """A malformed DeepMimic motion or character file."""


class DeepMimicCharacter:
    """A character's joints ``(name, type, parent index, offset)`` and sites
    ``(standard name, parent index, offset)``, in DeepMimic axes."""

    def __init__(self, joints: list, sites: list, source: str):
        self.joints = joints  # [(name, type, parent index, offset)]
        self.sites = sites  # [(standard name, parent index, offset)]
        self.source = source

    @property
    def frame_size(self) -> int:
        return 1 + sum(_DOFS[t] for _, t, _, _ in self.joints)


def _default_character() -> DeepMimicCharacter:
    names = [j[0] for j in HUMANOID3D_JOINTS]
    joints = [(n, t, -1 if p is None else names.index(p), np.array(o, dtype=float))
              for n, t, p, o in HUMANOID3D_JOINTS]
    sites = [(s, names.index(p), np.array(o, dtype=float)) for s, p, o in HUMANOID3D_SITES]
    return DeepMimicCharacter(joints, sites, "built-in humanoid3d")


def _read_json(path: Path, what: str):
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as e:
        raise DeepMimicFormatError(f"{path}: cannot read {what}: {e}") from e
    try:
        return json.loads(text)
    except json.JSONDecodeError as e:
        raise DeepMimicFormatError(f"{path}:{e.lineno}: invalid JSON in {what}: {e.msg}") from e


def _parse_character(data, where: str) -> DeepMimicCharacter:
    try:
        raw = data["Skeleton"]["Joints"]
    except (KeyError, TypeError):
        raise DeepMimicFormatError(f"{where}: character file has no Skeleton.Joints") from None
    raw = sorted(raw, key=lambda j: j.get("ID", 0))
    joints = []
    for i, j in enumerate(raw):
        try:
            jid, name = int(j["ID"]), str(j["Name"])
            jtype, parent = str(j["Type"]), int(j["Parent"])
            off = np.array([float(j.get(k, 0.0)) for k in ("AttachX", "AttachY", "AttachZ")])
            theta = [float(j.get(k, 0.0)) for k in ("AttachThetaX", "AttachThetaY", "AttachThetaZ")]
        except (KeyError, TypeError, ValueError) as e:
            raise DeepMimicFormatError(f"{where}: joint entry {i} is malformed: {e!r}") from None
        if jid != i:
            raise DeepMimicFormatError(f"{where}: joint IDs must be 0..N-1, found {jid} at position {i}")
        if jtype not in _DOFS:
            raise DeepMimicFormatError(f"{where}: joint {name!r} has unsupported type {jtype!r} "
                                       f"(supported: {sorted(_DOFS)})")
        if (i == 0) != (parent == -1) or parent >= i:
            raise DeepMimicFormatError(f"{where}: joint {name!r} has parent {parent}; need a single "
                                       "root at ID 0 and parents listed before children")
        if (i == 0) != (jtype == "none"):
            raise DeepMimicFormatError(f"{where}: only the root (ID 0) may have type 'none'")
        if any(abs(t) > 1e-9 for t in theta):
            raise NotImplementedError(f"{where}: joint {name!r} has a non-zero AttachTheta; "
                                      "rotated joint frames are not supported")
        joints.append((name, jtype, parent, off))

    # Sites from the body shapes, where they are recognisable.
    sites = []
    names = [j[0] for j in joints]
    for body in data.get("BodyDefs", []) or []:
        try:
            bname, shape = str(body["Name"]), str(body.get("Shape", ""))
            centre = np.array([float(body.get(k, 0.0)) for k in ("AttachX", "AttachY", "AttachZ")])
            size = np.array([float(body.get(k, 0.0)) for k in ("Param0", "Param1", "Param2")])
        except (KeyError, TypeError, ValueError):
            continue
        if bname not in names:
            continue
        std = DEEPMIMIC_NAME_MAP.get(bname, bname)
        if std in ("l_ankle", "r_ankle") and shape == "box":
            side = std[0]
            bottom = centre[1] - size[1] / 2
            half = size[0] / 2
            ji = names.index(bname)
            sites.append((f"{side}_toe", ji, np.array([centre[0] + half, bottom, centre[2]])))
            sites.append((f"{side}_heel", ji, np.array([centre[0] - half, bottom, centre[2]])))
        elif std == "neck":
            sites.append(("head", names.index(bname), centre))
    return DeepMimicCharacter(joints, sites, where)


def load_deepmimic_character(path: Union[str, os.PathLike]) -> DeepMimicCharacter:
    """Read a DeepMimic character JSON (``Skeleton.Joints`` and ``BodyDefs``)."""
    path = Path(path)
    return _parse_character(_read_json(path, "character file"), str(path))


def _build_skeleton(char: DeepMimicCharacter) -> Skeleton:
    joints, sites = char.joints, char.sites
    n_j = len(joints)
    names, types, parents, offsets, chans, axes, src, is_site = [], [], [], [], [], [], [], []
    z = np.array([0.0, 0.0, 1.0])
    for name, jtype, parent, off in joints:
        names.append(DEEPMIMIC_NAME_MAP.get(name, name))
        src.append(name)
        types.append(_TYPES[jtype])
        parents.append(parent)
        offsets.append(off)
        chans.append(_CHANNELS[jtype])
        axes.append(z if jtype == "revolute" else np.zeros(3))
        is_site.append(False)
    for sname, parent, off in sites:
        if sname in names:
            continue
        names.append(sname)
        src.append(f"{joints[parent][0]}:{sname}")
        types.append("fixed")
        parents.append(parent)
        offsets.append(off)
        chans.append(())
        axes.append(np.zeros(3))
        is_site.append(True)
    sk = Skeleton(names=names, parents=parents, offsets=np.array(offsets), joint_types=types,
                  channels=chans, rotation_orders=[None] * len(names), hinge_axes=np.array(axes),
                  source_names=src, is_site=is_site)
    assert sk.n_joints >= n_j
    return sk


def humanoid3d_skeleton() -> Skeleton:
    """The built-in ``humanoid3d`` skeleton (with sites) in the Z-up world frame."""
    sk = _build_skeleton(_default_character())
    r = DEEPMIMIC_TO_WORLD
    return Skeleton(names=sk.names, parents=sk.parents, offsets=sk.offsets @ r.T,
                    joint_types=sk.joint_types, channels=sk.channels,
                    rotation_orders=sk.rotation_orders, hinge_axes=sk.hinge_axes @ r.T,
                    source_names=sk.source_names, is_site=sk.is_site)


def parse_deepmimic(data, where: str = "<deepmimic>",
                    character: Optional[DeepMimicCharacter] = None) -> MotionClip:
    """Build a clip from parsed motion JSON; see :func:`load_deepmimic`."""
    char = character if character is not None else _default_character()
    if not isinstance(data, dict) or "Frames" not in data:
        raise DeepMimicFormatError(f"{where}: not a DeepMimic motion (no 'Frames' key)")
    frames = data["Frames"]
    if not isinstance(frames, list) or not frames:
        raise DeepMimicFormatError(f"{where}: 'Frames' must be a non-empty list")
    size = char.frame_size
    for i, f in enumerate(frames):
        if not isinstance(f, list) or len(f) != size:
            n = len(f) if isinstance(f, list) else type(f).__name__
            raise DeepMimicFormatError(f"{where}: frame {i} has {n} values; the character "
                                       f"({char.source}) needs {size}")
    try:
        arr = np.asarray(frames, dtype=float)
    except (TypeError, ValueError):
        raise DeepMimicFormatError(f"{where}: frames must hold only numbers") from None
    if not np.all(np.isfinite(arr)):
        bad = int(np.nonzero(~np.all(np.isfinite(arr), axis=1))[0][0])
        raise DeepMimicFormatError(f"{where}: frame {bad} holds non-finite values")
    loop_raw = data.get("Loop", "none")
    loop = str(loop_raw).lower() in ("wrap", "true", "1")

    T = arr.shape[0]
    sk = _build_skeleton(char)
    J = sk.n_joints
    jq = np.zeros((T, J, 4))
    jq[..., 0] = 1.0
    col = 1
    root_pos = quat = None
    for j, (name, jtype, _, _) in enumerate(char.joints):
        if jtype == "none":
            root_pos = arr[:, col:col + 3]
            quat = arr[:, col + 3:col + 7]
            jq[:, j] = quat
        elif jtype == "spherical":
            jq[:, j] = arr[:, col:col + 4]
        elif jtype == "revolute":
            jq[:, j] = quat_from_axis_angle(sk.hinge_axes[j], arr[:, col])
        col += _DOFS[jtype]
    assert col == size
    norms = np.linalg.norm(jq[:, :len(char.joints)], axis=-1)
    if np.any(norms < 1e-6):
        t_bad, j_bad = np.argwhere(norms < 1e-6)[0]
        raise DeepMimicFormatError(f"{where}: frame {t_bad} has a zero quaternion for joint "
                                   f"{char.joints[j_bad][0]!r}")
    jq = quat_normalize(jq)

    # frame timing
    dts = arr[:, 0]
    steps = dts[:-1] if T > 1 else dts
    if T > 1 and np.any(steps <= 0):
        bad = int(np.nonzero(steps <= 0)[0][0])
        raise DeepMimicFormatError(f"{where}: frame {bad} has a non-positive dt ({steps[bad]})")
    if T == 1 and dts[0] <= 0:
        raise DeepMimicFormatError(f"{where}: a single-frame motion needs a positive dt")
    med = float(np.median(steps))
    uniform = bool(np.all(np.abs(steps - med) <= 0.01 * med))
    fps = snap_fps(1.0 / float(np.mean(steps))) if uniform else snap_fps(1.0 / med)

    clip = MotionClip(skeleton=sk, fps=fps, root_pos=root_pos, root_quat=quat, joint_quats=jq,
                      loop=loop, name=Path(where).stem if where else "",
                      meta=dict(format="deepmimic", source=str(where), character=char.source,
                                loop_mode=str(loop_raw), uniform_dt=uniform))
    if not uniform:
        warnings.warn(f"{where}: frame dt varies (median {med:g} s); resampling to a uniform "
                      f"{fps:g} fps", stacklevel=3)
        t_src = np.concatenate([[0.0], np.cumsum(steps)])
        t_new = np.arange(0.0, t_src[-1] + 1e-9, 1.0 / fps)
        idx = np.interp(t_new, t_src, np.arange(T))
        clip = clip.replace(fps=fps, **clip._sample(idx))
    return clip.rotated_to_world(quat_from_matrix(DEEPMIMIC_TO_WORLD))


def load_deepmimic(path: Union[str, os.PathLike],
                   character_path: Optional[Union[str, os.PathLike]] = None) -> MotionClip:
    """Load a DeepMimic motion file as a Z-up :class:`~.skeleton.MotionClip`.

    Args:
        path: motion JSON (``{"Loop": ..., "Frames": [...]}``).
        character_path: the character JSON (e.g. ``humanoid3d_character.txt``) giving
            joint order, types (hence the frame layout and the revolute axes), offsets
            and the body shapes used for the toe/heel/head sites.  ``None`` uses the
            built-in ``humanoid3d`` character (:data:`HUMANOID3D_JOINTS`).

    Raises:
        DeepMimicFormatError: malformed JSON or frames that do not fit the character.
    """
    path = Path(path)
    char = load_deepmimic_character(character_path) if character_path is not None else None
    return parse_deepmimic(_read_json(path, "motion file"), where=str(path), character=char)
