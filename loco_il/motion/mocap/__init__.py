"""Motion-capture loaders: BVH and DeepMimic files -> :class:`MotionClip`.

Every loader returns clips in one convention: Z up, X forward, Y left, metres,
w-first quaternions, joints renamed to standard names where known, so that
:func:`canonical_keypoints` gives the same keypoint set for any source (the input
of inverse-kinematics retargeting).  See :mod:`.skeleton` for the details.

:mod:`.clips` says which clips a task uses and finds their files (the shipped ones are in ``data/``, with
their licences); :mod:`.retarget` turns a clip into a robot's motion with the keypoint maps of
:mod:`.robot_maps`.
"""

from .bvh import BVHParseError, load_bvh, parse_bvh
from .deepmimic import DeepMimicFormatError, humanoid3d_skeleton, load_deepmimic, parse_deepmimic
from .skeleton import (
    CANONICAL_KEYPOINTS,
    MotionClip,
    Skeleton,
    canonical_keypoints,
    quat_conj,
    quat_from_axis_angle,
    quat_mul,
    quat_rotate,
    quat_slerp,
)

__all__ = [
    "BVHParseError",
    "CANONICAL_KEYPOINTS",
    "DeepMimicFormatError",
    "MotionClip",
    "Skeleton",
    "canonical_keypoints",
    "humanoid3d_skeleton",
    "load_bvh",
    "load_deepmimic",
    "parse_bvh",
    "parse_deepmimic",
    "quat_conj",
    "quat_from_axis_angle",
    "quat_mul",
    "quat_rotate",
    "quat_slerp",
]
