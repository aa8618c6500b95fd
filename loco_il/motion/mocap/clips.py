"""Which motion-capture clips a task uses, where their files are found, and loading one as a `MotionClip`.

A task's clips (:data:`TASK_CLIPS`) are looked up in the first folder that has them all of ``$LOCO_IL_MOCAP``
(if set), the clips shipped in the package (:data:`PACKAGED_MOCAP`) and ``~/.cache/loco_il/mocap``; a file is
found by its relative path (``deepmimic/...``, ``cmu_bvh/...``) and then by its bare name. The `real` datasets
(`loco_il.datasets.real`) and the tracking experts' reference motions both start here.

Tasks with motion: ``walk`` (DeepMimic ``humanoid3d_walk`` repeated to 10 s; CMU subject 131 trial 01 from
4.5 s (a straight walk and stop; before, the subject turns round) and trial 02 from 2 s to 9 s (a slow walk,
without the turns at both ends)), ``run`` (DeepMimic ``humanoid3d_run`` and ``humanoid3d_jog``, each repeated
to 10 s), ``carry`` (the walking clips: the humanoid carried nothing, the robot's load is the task's).
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Optional, Sequence, Union

from loco_il.motion.mocap.bvh import load_bvh
from loco_il.motion.mocap.deepmimic import load_deepmimic
from loco_il.motion.mocap.skeleton import MotionClip
from loco_il.utils.errors import DatasetError

#: environment variable naming the folder of motion files
MOCAP_ENV = "LOCO_IL_MOCAP"
#: the motion clips shipped with loco_il (DeepMimic's walk/run/jog/long_walk3 and character file under the MIT
#: licence, CMU subject 131 trials 01-03 with the CMU acknowledgement): see ``data/README.md``
PACKAGED_MOCAP = Path(__file__).resolve().parent / "data"


@dataclass(frozen=True)
class ClipSpec:
    """One motion file and how to use it.

    ``path``: relative to the mocap folder (or absolute); ``start`` / ``stop``: seconds kept
    (None = the whole clip); ``duration``: repeat a cyclic clip until it lasts at least this long.
    """

    path: str
    start: Optional[float] = None
    stop: Optional[float] = None
    duration: Optional[float] = None


TASK_CLIPS: dict[str, tuple[ClipSpec, ...]] = {
    "walk": (ClipSpec("deepmimic/humanoid3d_walk.txt", duration=10.0),
             ClipSpec("cmu_bvh/131_01.bvh", start=4.5),           # before 4.5 s the subject turns round
             ClipSpec("cmu_bvh/131_02.bvh", start=2.0, stop=9.0)),  # without the turns at the start and end
    "run": (ClipSpec("deepmimic/humanoid3d_run.txt", duration=10.0),
            ClipSpec("deepmimic/humanoid3d_jog.txt", duration=10.0)),
}
TASK_CLIPS["carry"] = TASK_CLIPS["walk"]     # LocoMuJoCo's carry datasets are its walking datasets too

#: licence / provenance line per source folder (from shared/README.md)
PROVENANCE = {
    "deepmimic": "DeepMimic repository (MIT licence, see LICENSE-DeepMimic-MIT.txt); the motions were captured "
                 "at the CMU and SFU motion-capture labs",
    "cmu_bvh": "CMU Graphics Lab Motion Capture Database, subject 131 (BVH conversion): free for use in research "
               "and commercial projects. The data used in this project was obtained from mocap.cs.cmu.edu. The "
               "database was created with funding from NSF EIA-0196217.",
}


class MotionFilesMissingError(DatasetError):
    """The motion-capture files a `real` dataset (or a reference motion) needs are not where loco_il looks."""


def mocap_search_path() -> list[Path]:
    """Folders searched for motion files, in order: ``$LOCO_IL_MOCAP`` (when set: the user's own clips), the
    clips shipped in the package (:data:`PACKAGED_MOCAP`), then ``~/.cache/loco_il/mocap``."""
    given = os.environ.get(MOCAP_ENV)
    user = [Path(given).expanduser()] if given else []
    return user + [PACKAGED_MOCAP, Path.home() / ".cache" / "loco_il" / "mocap"]


def _lookup(folder: Path, rel: str) -> Optional[Path]:
    p = Path(rel)
    if p.is_absolute():
        return p if p.is_file() else None
    for cand in (folder / p, folder / p.name):
        if cand.is_file():
            return cand
    return None


def find_motion_files(specs: Sequence[ClipSpec], what: str = "") -> list[Path]:
    """Paths of the specs' files, all from one folder of the search path (the first that has
    them all); :class:`MotionFilesMissingError` naming the files and where to put them."""
    search = mocap_search_path()
    for folder in search:
        found = [_lookup(folder, s.path) for s in specs]
        if all(f is not None for f in found):
            return found                                        # type: ignore[return-value]
    missing = [s.path for s in specs if all(_lookup(folder, s.path) is None for folder in search)]
    where = ", ".join(str(f) for f in search)
    raise MotionFilesMissingError(
        f"{what or 'this real dataset'} is built from motion-capture files that were not found: "
        f"{', '.join(missing) or 'not all in one folder'} (looked in {where}). Put them in one folder, keeping "
        f"their sub-folders (e.g. <folder>/{specs[0].path}), and set ${MOCAP_ENV} to that folder. More DeepMimic "
        f"clips (humanoid3d_*.txt) come from the DeepMimic repository (data/motions, MIT licence); BVH files from "
        f"the CMU motion-capture database (mocap.cs.cmu.edu, BVH conversions).")


def load_motion(path: Union[str, os.PathLike], spec: Optional[ClipSpec] = None) -> tuple[MotionClip, int]:
    """A :class:`~loco_il.motion.mocap.skeleton.MotionClip` from a DeepMimic or BVH file, trimmed to
    ``spec.start``/``spec.stop``; returns ``(clip, n_cycles)`` (repeats needed for ``spec.duration``)."""
    path = Path(path)
    clip = load_bvh(path) if path.suffix.lower() == ".bvh" else load_deepmimic(path)
    n_cycles = 1
    if spec is not None:
        if spec.start is not None or spec.stop is not None:
            a = 0 if spec.start is None else int(round(spec.start * clip.fps))
            b = None if spec.stop is None else int(round(spec.stop * clip.fps)) + 1
            clip = clip.slice(a, b)
        if spec.duration and clip.loop and clip.duration > 0:
            n_cycles = max(1, math.ceil(spec.duration / clip.duration))
    return clip, n_cycles


def provenance(path: Path) -> str:
    """The licence / provenance line of a motion file, by its source folder."""
    for key, line in PROVENANCE.items():
        if key in path.parts or path.parent.name == key:
            return line
    return "user-supplied motion file (check its licence)"


__all__ = ["MOCAP_ENV", "PACKAGED_MOCAP", "ClipSpec", "TASK_CLIPS", "PROVENANCE", "MotionFilesMissingError",
           "mocap_search_path", "find_motion_files", "load_motion", "provenance"]
