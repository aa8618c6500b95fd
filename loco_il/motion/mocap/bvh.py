"""Loader for Biovision Hierarchy (BVH) motion files.

Format (facts of the BVH format as commonly written):

* ``HIERARCHY`` then one ``ROOT name { ... }`` block.  Inside a joint block:
  ``OFFSET x y z`` (rest translation from the parent), ``CHANNELS n c1 .. cn`` with
  channel names ``Xposition Yposition Zposition Xrotation Yrotation Zrotation`` in
  any order, nested ``JOINT name { ... }`` blocks and ``End Site { OFFSET x y z }``
  leaf points.
* ``MOTION``, ``Frames: N``, ``Frame Time: dt`` then ``N`` lines of numbers, one
  value per channel, channels in the order the joints appear in the hierarchy.
* Rotation channels are Euler angles in degrees.  They compose *intrinsically* in
  the order listed: ``Zrotation Xrotation Yrotation`` means
  ``R = Rz(z) @ Rx(x) @ Ry(y)`` and ``v_parent = R @ v_child + offset``.
* Position channels give the joint's translation relative to its parent; this
  loader lets them *replace* the matching ``OFFSET`` component (for the usual root
  with ``OFFSET 0 0 0`` the two readings agree).

Conventions of the returned :class:`~.skeleton.MotionClip`:

* **Axes.**  BVH files are Y-up with the character facing +Z and its left side at
  +X (the CMU conversions follow this).  The loader applies the proper rotation
  ``(x, y, z)_bvh -> (z, x, y)_world``, so the result is Z-up, X-forward, Y-left.
  Pass ``to_world`` (a 3x3 rotation) for files with other axes.
* **Units.**  With ``scale=None`` the length unit is detected from the rest-pose
  height ``h`` (in file units, the vertical extent of all joints and end sites with
  every rotation at zero): the unit among :data:`UNIT_SCALES` that makes ``h`` closest
  (in ratio) to 1.5 m is used.  1.5 m is a typical *joint-span* height of an adult
  skeleton: end sites rarely reach the crown of the head, so the span is 80-95 % of
  stature.  The candidate units are at least a factor 2.2 apart, so this
  tolerates a wide range of skeletons.  The CMU conversions (cgspeed) are written
  in the CMU ASF length unit, 1/0.45 inch = 0.056444 m: subject 131's rest pose
  spans 24.3 units from toe to head end site, i.e. 1.37 m, with the hips about
  0.95 m above the floor, thigh 0.41 m and shank 0.39 m (limb lengths of a
  person of roughly 1.7 m; the CMU head end site stops well short of the crown).
  The detection can be fooled by subjects far from adult size (a 1 m child in
  inches looks like an adult in CMU units); pass ``scale`` (metres per file unit)
  to override.  The chosen unit and
  scale are recorded in ``clip.meta``.
* **CMU proportions.**  In the cgspeed CMU conversions the neck base
  (``lowerneck``) and the collars sit on ``Chest2`` with a zero offset, and the head
  end site is only ~0.5 m above ``Hips``; compared with DeepMimic's humanoid the
  upper body is ~0.2 m shorter, while the legs agree within a few centimetres.
  ``Hips`` (the root, canonical ``pelvis``) lies ~0.1 m above the hip joints.
  Retargeting should therefore fit limbs by direction/ratio rather than copy
  absolute upper-body heights.
* **Frame rate.**  ``fps = 1 / Frame Time``, rounded to the nearest integer when
  within 0.01 % of it (``Frame Time: .0083333`` gives 120.0).
* **Ground.**  No grounding is applied: heights are the capture's (the CMU floor is
  at 0).  Use :meth:`MotionClip.grounded` if needed.
* **Joints.**  ``End Site`` points become fixed site joints named
  ``<parent>_end``.  Joints get standard names from the best-matching name map in
  :data:`BVH_NAME_MAPS` (at least three matches needed; otherwise source names are
  kept).  Source names stay in ``skeleton.source_names``.
"""

from __future__ import annotations

import os
import re
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Optional, Union

import numpy as np

from .skeleton import MotionClip, Skeleton, quat_from_matrix, snap_fps

__all__ = [
    "BVHParseError",
    "load_bvh",
    "parse_bvh",
    "BVH_TO_WORLD",
    "UNIT_SCALES",
    "CMU_BVH_NAME_MAP",
    "CMU_MB_BVH_NAME_MAP",
    "MIXAMO_BVH_NAME_MAP",
    "BVH_NAME_MAPS",
    "detect_unit_scale",
]

#: Rotation from BVH axes (Y up, facing +Z, left +X) to the world (Z up, X forward, Y left).
BVH_TO_WORLD = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])

#: Metres per file unit for the units the detector chooses from.
UNIT_SCALES = {
    "m": 1.0,
    "cmu": 0.0254 / 0.45,  # CMU ASF/BVH length unit: 1/0.45 inch
    "in": 0.0254,
    "cm": 0.01,
    "mm": 0.001,
}

#: Reference rest-pose joint-span height used by unit detection, metres.
REFERENCE_HEIGHT_M = 1.5

#: CMU BVH conversions ("131_01.bvh" style joint names) -> standard names.
CMU_BVH_NAME_MAP = {
    "Hips": "pelvis",
    "LHipJoint": "l_pelvis", "LeftHip": "l_hip", "LeftKnee": "l_knee",
    "LeftAnkle": "l_ankle", "LeftToe": "l_toe",
    "RHipJoint": "r_pelvis", "RightHip": "r_hip", "RightKnee": "r_knee",
    "RightAnkle": "r_ankle", "RightToe": "r_toe",
    "lowerback": "spine", "Chest": "spine1", "Chest2": "chest",
    "lowerneck": "lower_neck", "Neck": "neck", "Head": "head",
    "LeftCollar": "l_collar", "LeftShoulder": "l_shoulder", "LeftElbow": "l_elbow",
    "LeftWrist": "l_wrist", "lhand": "l_hand", "LFingers": "l_fingers", "LThumb": "l_thumb",
    "RightCollar": "r_collar", "RightShoulder": "r_shoulder", "RightElbow": "r_elbow",
    "RightWrist": "r_wrist", "rhand": "r_hand", "RFingers": "r_fingers", "RThumb": "r_thumb",
}

#: CMU BVH conversions with MotionBuilder-style names -> standard names.
CMU_MB_BVH_NAME_MAP = {
    "Hips": "pelvis",
    "LHipJoint": "l_pelvis", "LeftUpLeg": "l_hip", "LeftLeg": "l_knee",
    "LeftFoot": "l_ankle", "LeftToeBase": "l_toe",
    "RHipJoint": "r_pelvis", "RightUpLeg": "r_hip", "RightLeg": "r_knee",
    "RightFoot": "r_ankle", "RightToeBase": "r_toe",
    "LowerBack": "spine", "Spine": "spine1", "Spine1": "chest",
    "Neck": "lower_neck", "Neck1": "neck", "Head": "head",
    "LeftShoulder": "l_collar", "LeftArm": "l_shoulder", "LeftForeArm": "l_elbow",
    "LeftHand": "l_wrist", "LeftFingerBase": "l_hand", "LeftHandIndex1": "l_fingers",
    "LThumb": "l_thumb",
    "RightShoulder": "r_collar", "RightArm": "r_shoulder", "RightForeArm": "r_elbow",
    "RightHand": "r_wrist", "RightFingerBase": "r_hand", "RightHandIndex1": "r_fingers",
    "RThumb": "r_thumb",
}

#: Mixamo-style names (a ``prefix:`` such as ``mixamorig:`` is ignored) -> standard names.
MIXAMO_BVH_NAME_MAP = {
    "Hips": "pelvis",
    "LeftUpLeg": "l_hip", "LeftLeg": "l_knee", "LeftFoot": "l_ankle", "LeftToeBase": "l_toe",
    "RightUpLeg": "r_hip", "RightLeg": "r_knee", "RightFoot": "r_ankle", "RightToeBase": "r_toe",
    "Spine": "spine", "Spine1": "spine1", "Spine2": "chest", "Neck": "neck", "Head": "head",
    "LeftShoulder": "l_collar", "LeftArm": "l_shoulder", "LeftForeArm": "l_elbow",
    "LeftHand": "l_wrist",
    "RightShoulder": "r_collar", "RightArm": "r_shoulder", "RightForeArm": "r_elbow",
    "RightHand": "r_wrist",
}

BVH_NAME_MAPS = {
    "cmu": CMU_BVH_NAME_MAP,
    "cmu_motionbuilder": CMU_MB_BVH_NAME_MAP,
    "mixamo": MIXAMO_BVH_NAME_MAP,
}

_CHANNEL_RE = re.compile(r"^([XYZ])(position|rotation)$", re.IGNORECASE)
_AXIS = {"X": 0, "Y": 1, "Z": 2}


class BVHParseError(ValueError):
    """A malformed BVH file; the message names the file and line."""


class _Tokens:
    """Whitespace tokens with their 1-based line numbers."""

    def __init__(self, lines: list, first: int, last: int, where: str):
        self.items = []
        for ln in range(first, last):
            for tok in lines[ln].split():
                self.items.append((tok, ln + 1))
        self.i = 0
        self.where = where
        self.last_line = last

    def error(self, msg: str, line: Optional[int] = None) -> BVHParseError:
        if line is None:
            line = self.items[self.i][1] if self.i < len(self.items) else self.last_line
        return BVHParseError(f"{self.where}:{line}: {msg}")

    def peek(self) -> Optional[str]:
        return self.items[self.i][0] if self.i < len(self.items) else None

    def next(self, what: str) -> tuple:
        if self.i >= len(self.items):
            raise self.error(f"unexpected end of HIERARCHY, expected {what}")
        item = self.items[self.i]
        self.i += 1
        return item

    def expect(self, word: str) -> int:
        tok, ln = self.next(repr(word))
        if tok != word:
            raise self.error(f"expected {word!r}, found {tok!r}", ln)
        return ln

    def floats(self, n: int, what: str) -> list:
        out = []
        for _ in range(n):
            tok, ln = self.next(f"{n} numbers for {what}")
            try:
                out.append(float(tok))
            except ValueError:
                raise self.error(f"expected a number for {what}, found {tok!r}", ln) from None
        return out


def _parse_hierarchy(tok: _Tokens) -> list:
    """Returns joints in DFS pre-order as dicts (name, parent, offset, channels, site, line)."""
    joints: list = []

    def parse_block(kind: str, kw_line: int, parent: int) -> None:
        # name: the remaining tokens on the keyword's line, up to an optional "{"
        name_parts = []
        while tok.i < len(tok.items) and tok.items[tok.i][1] == kw_line and tok.peek() != "{":
            name_parts.append(tok.next("joint name")[0])
        name = " ".join(name_parts)
        if kind != "End" and not name:
            raise tok.error(f"{kind} without a name", kw_line)
        tok.expect("{")
        idx = len(joints)
        joints.append(dict(name=name, parent=parent, offset=None, channels=(),
                           site=(kind == "End"), line=kw_line))
        while True:
            t, ln = tok.next("'}' closing joint " + repr(name or "End Site"))
            if t == "}":
                break
            if t.upper() == "OFFSET":
                joints[idx]["offset"] = tok.floats(3, "OFFSET")
            elif t.upper() == "CHANNELS":
                if kind == "End":
                    raise tok.error("End Site cannot have CHANNELS", ln)
                nt, nln = tok.next("channel count")
                try:
                    n = int(nt)
                except ValueError:
                    raise tok.error(f"expected a channel count, found {nt!r}", nln) from None
                if not 0 <= n <= 6:
                    raise tok.error(f"channel count {n} is not within 0..6", nln)
                chans = []
                for _ in range(n):
                    c, cln = tok.next("channel name")
                    m = _CHANNEL_RE.match(c)
                    if not m:
                        raise tok.error(f"unknown channel {c!r}", cln)
                    norm = m.group(1).upper() + m.group(2).lower()
                    if norm in chans:
                        raise tok.error(f"channel {c!r} repeated", cln)
                    chans.append(norm)
                joints[idx]["channels"] = tuple(chans)
            elif t.upper() == "JOINT":
                if kind == "End":
                    raise tok.error("End Site cannot have children", ln)
                parse_block("JOINT", ln, idx)
            elif t.upper() == "END":
                if kind == "End":
                    raise tok.error("End Site cannot have children", ln)
                st, sln = tok.next("'Site'")
                if st.upper() != "SITE":
                    raise tok.error(f"expected 'Site' after 'End', found {st!r}", sln)
                parse_block("End", ln, idx)
            else:
                raise tok.error(f"unexpected {t!r} in joint {name or 'End Site'!r}", ln)
        if joints[idx]["offset"] is None:
            raise tok.error(f"joint {name or 'End Site'!r} has no OFFSET", kw_line)

    t, ln = tok.next("ROOT")
    if t.upper() != "ROOT":
        raise tok.error(f"expected ROOT, found {t!r}", ln)
    parse_block("ROOT", ln, -1)
    if tok.peek() is not None:
        t, ln = tok.next("")
        raise tok.error(f"unexpected {t!r} after the ROOT block (only one ROOT is supported)", ln)
    return joints


def _choose_name_map(source_names: list, name_map) -> tuple:
    """Returns (map name or None, {source: standard})."""
    if name_map is False:
        return None, {}
    stripped = [n.split(":")[-1] for n in source_names]
    if isinstance(name_map, dict):
        return "custom", {s: name_map[k] for s, k in zip(source_names, stripped) if k in name_map}
    if isinstance(name_map, str):
        if name_map not in BVH_NAME_MAPS:
            raise ValueError(f"unknown name map {name_map!r}; known: {sorted(BVH_NAME_MAPS)}")
        candidates = {name_map: BVH_NAME_MAPS[name_map]}
    else:
        candidates = BVH_NAME_MAPS
    best, best_hits = None, 0
    for key, m in candidates.items():
        hits = sum(k in m for k in stripped)
        if hits > best_hits:
            best, best_hits = key, hits
    if best is None or (best_hits < 3 and not isinstance(name_map, str)):
        return None, {}
    m = candidates[best]
    return best, {s: m[k] for s, k in zip(source_names, stripped) if k in m}


def detect_unit_scale(rest_height: float) -> tuple:
    """``(unit, metres_per_unit)`` making ``rest_height`` closest to :data:`REFERENCE_HEIGHT_M`."""
    if not np.isfinite(rest_height) or rest_height <= 0:
        raise ValueError(f"cannot detect units from a rest height of {rest_height}")
    best = min(UNIT_SCALES.items(),
               key=lambda kv: abs(np.log(rest_height * kv[1] / REFERENCE_HEIGHT_M)))
    height_m = rest_height * best[1]
    if not 0.5 <= height_m <= 3.0:
        warnings.warn(f"BVH unit detection: rest height {rest_height:g} file units fits no known "
                      f"unit well (best: {best[0]}, {height_m:.2f} m); pass scale= explicitly",
                      stacklevel=3)
    return best


def parse_bvh(text: str, where: str = "<bvh>", scale: Optional[float] = None,
              name_map=None, include_end_sites: bool = True,
              to_world: Optional[np.ndarray] = None) -> MotionClip:
    """Parse BVH text; see :func:`load_bvh` for the arguments."""
    lines = text.splitlines()
    first, motion_line = _locate_sections(lines, where)
    joints = _parse_hierarchy(_Tokens(lines, first + 1, motion_line, where))
    n_frames, frame_time, header_end = _parse_motion_header(lines, motion_line, where)
    data = _parse_frames(lines, header_end + 1, n_frames, sum(len(j["channels"]) for j in joints), where)

    keep = [i for i, j in enumerate(joints) if include_end_sites or not j["site"]]
    src_names, std_names, map_key = _joint_names(joints, keep, name_map, where)
    motion = _map_channels(joints, keep, data)
    skel_file = Skeleton(names=std_names, parents=motion.parents, offsets=motion.offsets,
                         joint_types=motion.joint_types, channels=[joints[i]["channels"] for i in keep],
                         rotation_orders=motion.rotation_orders, hinge_axes=motion.hinge_axes,
                         source_names=src_names, is_site=[joints[i]["site"] for i in keep])
    unit, scale, rest_height = _length_unit(joints, to_world, scale)

    clip = MotionClip(skeleton=skel_file, fps=snap_fps(1.0 / frame_time), root_pos=motion.root_pos,
                      root_quat=motion.joint_quats[:, 0], joint_quats=motion.joint_quats,
                      joint_translations=motion.translations, name=Path(where).stem if where else "",
                      meta=dict(format="bvh", source=str(where), unit=unit, scale=scale,
                                rest_height_file_units=rest_height, frame_time=frame_time,
                                name_map=map_key))
    R = np.asarray(to_world if to_world is not None else BVH_TO_WORLD, dtype=float)
    if R.shape != (3, 3) or not np.allclose(R @ R.T, np.eye(3), atol=1e-6) or np.linalg.det(R) < 0:
        raise ValueError("to_world must be a proper 3x3 rotation matrix")
    return clip.scale(scale).rotated_to_world(quat_from_matrix(R))


# ---------------------------------------------------------------------------- parsing steps


def _locate_sections(lines: list, where: str) -> tuple:
    """``(first, motion)``: indices of the ``HIERARCHY`` line and of the ``MOTION`` line."""
    first = 0
    while first < len(lines) and not lines[first].strip():
        first += 1
    if first >= len(lines) or lines[first].split()[0].upper() != "HIERARCHY":
        raise BVHParseError(f"{where}:{first + 1}: expected 'HIERARCHY' at the start of the file")
    motion_line = None
    for ln in range(first + 1, len(lines)):
        s = lines[ln].split()
        if s and s[0].upper() == "MOTION":
            motion_line = ln
            break
    if motion_line is None:
        raise BVHParseError(f"{where}:{len(lines)}: no MOTION section")
    if len(lines[first].split()) > 1 or len(lines[motion_line].split()) > 1:
        raise BVHParseError(f"{where}: 'HIERARCHY' and 'MOTION' must stand on their own lines")
    return first, motion_line


def _next_nonempty(lines: list, ln: int) -> int:
    while ln < len(lines) and not lines[ln].strip():
        ln += 1
    return ln


def _parse_motion_header(lines: list, motion_line: int, where: str) -> tuple:
    """``(n_frames, frame_time, line)`` from ``Frames: N`` and ``Frame Time: dt``; ``line`` is the index of
    the ``Frame Time`` line (the frames follow it)."""
    ln = _next_nonempty(lines, motion_line + 1)
    m = re.match(r"^\s*Frames\s*:\s*(\S+)\s*$", lines[ln] if ln < len(lines) else "", re.IGNORECASE)
    if not m:
        raise BVHParseError(f"{where}:{ln + 1}: expected 'Frames: <count>'")
    try:
        n_frames = int(m.group(1))
    except ValueError:
        raise BVHParseError(f"{where}:{ln + 1}: frame count {m.group(1)!r} is not an integer") from None
    if n_frames <= 0:
        raise BVHParseError(f"{where}:{ln + 1}: frame count must be positive, got {n_frames}")
    ln = _next_nonempty(lines, ln + 1)
    m = re.match(r"^\s*Frame\s+Time\s*:\s*(\S+)\s*$", lines[ln] if ln < len(lines) else "",
                 re.IGNORECASE)
    if not m:
        raise BVHParseError(f"{where}:{ln + 1}: expected 'Frame Time: <seconds>'")
    try:
        frame_time = float(m.group(1))
    except ValueError:
        raise BVHParseError(f"{where}:{ln + 1}: frame time {m.group(1)!r} is not a number") from None
    if not np.isfinite(frame_time) or frame_time <= 0:
        raise BVHParseError(f"{where}:{ln + 1}: frame time must be positive, got {frame_time}")
    return n_frames, frame_time, ln


def _parse_frames(lines: list, start: int, n_frames: int, n_chan: int, where: str) -> np.ndarray:
    """The ``(n_frames, n_chan)`` channel values of the frame lines from index ``start`` on."""
    data = np.empty((n_frames, n_chan))
    row = 0
    for ln in range(start, len(lines)):
        s = lines[ln].split()
        if not s:
            continue
        if row >= n_frames:
            raise BVHParseError(f"{where}:{ln + 1}: more frame lines than the "
                                f"declared {n_frames} frames")
        if len(s) != n_chan:
            raise BVHParseError(f"{where}:{ln + 1}: frame {row} has {len(s)} values, "
                                f"the hierarchy declares {n_chan} channels")
        try:
            data[row] = np.array(s, dtype=float)
        except ValueError:
            bad = next(v for v in s if not _is_float(v))
            raise BVHParseError(f"{where}:{ln + 1}: frame {row}: {bad!r} is not a number") from None
        row += 1
    if row < n_frames:
        raise BVHParseError(f"{where}:{len(lines)}: file declares {n_frames} frames "
                            f"but holds {row} (truncated?)")
    if not np.all(np.isfinite(data)):
        bad_row = int(np.nonzero(~np.all(np.isfinite(data), axis=1))[0][0])
        raise BVHParseError(f"{where}: frame {bad_row} holds non-finite values")
    return data


def _joint_names(joints: list, keep: list, name_map, where: str) -> tuple:
    """``(source names, standard names, name map used)`` of the kept joints; end sites are
    ``<parent>_End`` / ``<parent standard name>_end``."""
    src_names = []
    for i in keep:
        j = joints[i]
        src_names.append(f"{joints[j['parent']]['name']}_End" if j["site"] else j["name"])
    dup = {n for n in src_names if src_names.count(n) > 1}
    if dup:
        raise BVHParseError(f"{where}: duplicate joint names {sorted(dup)}")

    real_names = [joints[i]["name"] for i in keep if not joints[i]["site"]]
    map_key, mapping = _choose_name_map(real_names, name_map)
    std_names = []
    for i in keep:
        j = joints[i]
        if j["site"]:
            parent_std = mapping.get(joints[j["parent"]]["name"], joints[j["parent"]]["name"])
            std_names.append(f"{parent_std}_end")
        else:
            std_names.append(mapping.get(j["name"], j["name"]))
    if len(set(std_names)) != len(std_names):  # a map produced a clash: fall back to source names
        std_names, map_key = list(src_names), None
    return src_names, std_names, map_key


@dataclass
class _ChannelMotion:
    """The frames' channels turned into the kept joints' motion and the skeleton's joint description."""

    parents: np.ndarray                  # (J,) int, -1 for the root
    offsets: np.ndarray                  # (J, 3) rest offsets from the parent (file units)
    root_pos: np.ndarray                 # (T, 3)
    joint_quats: np.ndarray              # (T, J, 4) w-first local rotations
    translations: Optional[np.ndarray]   # (T, J, 3) when a non-root joint has position channels, else None
    joint_types: list                    # free / fixed / hinge / ball
    rotation_orders: list                # Euler order per joint ("ZXY", ...) or None
    hinge_axes: np.ndarray               # (J, 3) axis of the hinge joints


def _map_channels(joints: list, keep: list, data: np.ndarray) -> _ChannelMotion:
    """Each kept joint's channel columns: positions replace the offset, rotations compose intrinsically in the
    order listed (see the module docstring)."""
    from scipy.spatial.transform import Rotation

    new_index = {old: new for new, old in enumerate(keep)}
    J, T = len(keep), len(data)
    parents = np.array([-1 if joints[i]["parent"] < 0 else new_index[joints[i]["parent"]]
                        for i in keep], dtype=np.int64)
    offsets = np.array([joints[i]["offset"] for i in keep], dtype=float)
    joint_types, rot_orders, hinge_axes = [], [], np.zeros((J, 3))
    jq = np.zeros((T, J, 4))
    jq[..., 0] = 1.0
    translations = None
    if any(any(c.endswith("position") for c in joints[i]["channels"]) for i in keep[1:]):
        translations = np.broadcast_to(offsets, (T, J, 3)).copy()
    root_pos = np.broadcast_to(offsets[0], (T, 3)).copy()

    col = 0
    col_of = {}
    for i, j in enumerate(joints):
        col_of[i] = col
        col += len(j["channels"])
    for new, i in enumerate(keep):
        j = joints[i]
        c0 = col_of[i]
        rot_axes, rot_cols = [], []
        for k, ch in enumerate(j["channels"]):
            axis = _AXIS[ch[0]]
            if ch.endswith("position"):
                if new == 0:
                    root_pos[:, axis] = data[:, c0 + k]
                else:
                    translations[:, new, axis] = data[:, c0 + k]
            else:
                rot_axes.append(ch[0])
                rot_cols.append(c0 + k)
        if rot_axes:
            order = "".join(rot_axes)
            q = Rotation.from_euler(order, data[:, rot_cols], degrees=True).as_quat(scalar_first=True)
            jq[:, new] = q
            rot_orders.append(order)
        else:
            rot_orders.append(None)
        if new == 0:
            joint_types.append("free")
        elif len(rot_axes) == 0:
            joint_types.append("fixed")
        elif len(rot_axes) == 1:
            joint_types.append("hinge")
            hinge_axes[new, _AXIS[rot_axes[0]]] = 1.0
        else:
            joint_types.append("ball")
    return _ChannelMotion(parents, offsets, root_pos, jq, translations, joint_types, rot_orders, hinge_axes)


def _length_unit(joints: list, to_world: Optional[np.ndarray], scale: Optional[float]) -> tuple:
    """``(unit, metres per file unit, rest height in file units)``: the given scale, or the unit detected from
    the rest-pose height along the file's up axis (measured with the sites, whatever include_end_sites)."""
    rest = _rest_positions(joints)
    up = np.asarray(to_world if to_world is not None else BVH_TO_WORLD, dtype=float)[2]
    rest_height = float(np.ptp(rest @ up))
    if scale is None:
        unit, scale = detect_unit_scale(rest_height)
    else:
        unit = "given"
        scale = float(scale)
        if not np.isfinite(scale) or scale <= 0:
            raise ValueError(f"scale must be positive, got {scale}")
    return unit, scale, rest_height


def _rest_positions(joints: list) -> np.ndarray:
    pos = np.zeros((len(joints), 3))
    for i, j in enumerate(joints):
        if j["parent"] >= 0:
            pos[i] = pos[j["parent"]] + np.asarray(j["offset"])
    return pos


def _is_float(s: str) -> bool:
    try:
        float(s)
        return True
    except ValueError:
        return False


def load_bvh(path: Union[str, os.PathLike], scale: Optional[float] = None, name_map=None,
             include_end_sites: bool = True, to_world: Optional[np.ndarray] = None) -> MotionClip:
    """Load a BVH file as a Z-up, metric :class:`~.skeleton.MotionClip`.

    Args:
        path: the ``.bvh`` file.
        scale: metres per file unit; ``None`` detects it from the rest-pose height
            (see the module docstring; CMU files give ``0.0254 / 0.45``).
        name_map: ``None`` picks the best of :data:`BVH_NAME_MAPS`; a key of it
            forces that map; a ``{source name: standard name}`` dict uses it;
            ``False`` keeps the source names.
        include_end_sites: keep ``End Site`` points as fixed site joints.
        to_world: 3x3 rotation from file axes to the world (default
            :data:`BVH_TO_WORLD`).

    Raises:
        BVHParseError: malformed file; the message gives ``path:line``.
    """
    path = Path(path)
    text = path.read_text(encoding="utf-8", errors="replace")
    return parse_bvh(text, where=str(path), scale=scale, name_map=name_map,
                     include_end_sites=include_end_sites, to_world=to_world)
