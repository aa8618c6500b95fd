"""MyoLeg: the 80-muscle MyoLegs musculoskeletal model from the `myo-sim` wheel (Apache-2.0).

`myo-sim` 0.2.4 ships no single MyoLegs xml: `myo_sim/models/leg/assets/` holds the parts
(assets, kinematic chain, tendons, muscles) and the wheel's own composer
`myo_sim.load_spec("myolegs")` assembles them onto its passive torso scaffold (pelvis + legs,
29 joints incl. the knee's coupled translation DoFs, 80 muscles, rigid torso, 75 kg) with a
`standing` posture keyframe. We use that composer and then adapt the scene for locomotion:

* MyoSuite's scene stands the model on a pedestal (a collidable cylinder of radius 1.05 m whose
  top is 1.5 cm above the origin; the floor plane lies 0.4 m lower). We delete the pedestal and the
  decorative scene meshes, move the floor plane to z = 0 and lower the standing keyframe by the
  pedestal's top height, so the feet rest on an unbounded flat floor.
* The model faces -y; the keyframe's root orientation is turned +90 deg about z so that it faces
  +x, the direction the walk reward measures.

Measured (keyframe `standing`, after the edits above): root body `Full Body` (free joint `root`,
rigidly carrying the pelvis) at 0.946 m. Observation = 33 positions + 34 velocities = 67; 80 actions.

Rules: termination when the pelvis height leaves (0.6 x 0.946, 2 x 0.946) m or the pelvis tilts more
than 45 deg sideways / 60 deg forwards or backwards (the humanoid rule of `menagerie.py`). Walk target
1.25 m/s (LocoMuJoCo's adult walk target), stand 0 m/s. Muscle controls [0, 1] are reached from
actions [-1, 1] by the env's affine map (action 0 = 50 % excitation). Under a zero action the
co-contraction pushes the model onto its toes and it falls sideways within ~1 s: MyoLeg does not
stand without a controller. Control at 100 Hz (5 substeps of 2 ms), horizon 1000.

Building the spec with the composer takes ~2 s, so it is built once per process and copied.
"""
from __future__ import annotations

import functools
import warnings

import mujoco
import numpy as np

from loco_il.environments.assets import LICENCES, AssetError, myo_sim_root
from loco_il.environments.body import Body
from loco_il.environments.registry import register_body
from loco_il.environments.tasks import FallTermination, Task, TargetVelocityReward

KEYFRAME = "standing"
STAND_HEIGHT = 0.946        # m, root (pelvis) height at the standing keyframe on the flat floor
MAX_ROLL, MAX_PITCH = np.radians(45.0), np.radians(60.0)
WALK_SPEED = 1.25
_FACE_PLUS_X = (np.cos(np.pi / 4), 0.0, 0.0, np.sin(np.pi / 4))   # +90 deg about z: -y -> +x


@functools.lru_cache(maxsize=1)
def _template() -> mujoco.MjSpec:
    myo_sim_root()   # clear error message when the wheel is missing
    import myo_sim
    if not hasattr(myo_sim, "load_spec"):
        raise AssetError("MyoLeg needs myo-sim>=0.2.4 (its `myo_sim.load_spec('myolegs')` composer)")
    with warnings.catch_warnings():   # the composer attaches parts with an empty prefix and says so
        warnings.simplefilter("ignore")
        spec = myo_sim.load_spec("myolegs", build_kwargs={"postures": [KEYFRAME]})
    _flatten_scene(spec)
    return spec


def _flatten_scene(spec: mujoco.MjSpec) -> None:
    """Remove MyoSuite's pedestal and scene decoration, put the floor at z = 0, face +x."""
    floor, pedestal_top = None, 0.0
    for geom in list(spec.worldbody.geoms):
        if geom.type == mujoco.mjtGeom.mjGEOM_PLANE and floor is None:
            floor = geom
            continue
        if geom.type == mujoco.mjtGeom.mjGEOM_CYLINDER and (geom.contype or geom.conaffinity):
            pedestal_top = max(pedestal_top, float(geom.pos[2] + geom.size[1]))
        spec.delete(geom)
    if floor is None:
        raise AssetError("myo_sim's myolegs scene has no floor plane; cannot build MyoLeg")
    floor.pos = [0.0, 0.0, 0.0]
    used = {g.meshname for g in spec.geoms if g.type == mujoco.mjtGeom.mjGEOM_MESH}
    for mesh in list(spec.meshes):
        if mesh.name not in used:
            spec.delete(mesh)
    for key in spec.keys:
        if key.name == KEYFRAME:
            qpos = np.array(key.qpos)
            qpos[2] -= pedestal_top
            qpos[3:7] = _FACE_PLUS_X
            key.qpos = qpos


def load_spec() -> mujoco.MjSpec:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return _template().copy()


def _tasks() -> dict[str, Task]:
    fall = FallTermination((0.6 * STAND_HEIGHT, 2.0 * STAND_HEIGHT), MAX_ROLL, MAX_PITCH)
    return {
        "walk": Task(TargetVelocityReward(WALK_SPEED), fall, description=f"MyoLeg: walk forward at {WALK_SPEED} m/s"),
        "stand": Task(TargetVelocityReward(0.0), fall, description="MyoLeg: stand still (0 m/s)"),
    }


MYOLEG = Body(name="MyoLeg", load_spec=load_spec, tasks=_tasks(), default_task="walk",
              datasets=("real", "perfect", "preference"), default_dataset="real", family="musculoskeletal",
              control_dt=0.01, init_keyframe=KEYFRAME, licence=LICENCES["myo_sim/leg"],
              source="myo_sim.load_spec('myolegs') (myo_sim/models/leg/assets/myolegs_*.xml), flat floor",
              extra={"stand_height": STAND_HEIGHT})

register_body(MYOLEG)
