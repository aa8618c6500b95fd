"""What a robot module declares: where its model comes from and what is specific to it.

A new robot is one module that builds a `Body` and calls `register_body`, plus the few places listed in
docs/adding-a-robot.md (its import, a keypoint map for `real` data, baselines, expert settings).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Mapping, Sequence

import mujoco

from loco_il.environments.tasks import Task


@dataclass(frozen=True)
class Body:
    """Everything the generic `LocoEnv` needs to know about one robot (or one classic body).

    Attributes:
        name: the first part of the Task-ID, e.g. "UnitreeH1".
        load_spec: returns a fresh `mujoco.MjSpec` of the model (the asset manager resolves files).
        tasks: task name -> `Task` (reward, termination, target, horizon).
        datasets: dataset types this body offers ("real", "perfect", "preference").
        default_task / default_dataset: fill missing Task-ID parts.
        family: "classic", "humanoid", "quadruped" or "musculoskeletal" (docs and grouping).
        joints_to_remove / actuators_to_remove: deleted from the spec before compiling
            (LocoMuJoCo disables e.g. arm joints by default).
        control_dt: seconds per env step; the number of physics substeps is derived from the model's timestep.
        timestep: overrides the model's physics timestep when given.
        init_keyframe: keyframe name for the initial state (else qpos0).
        reset_noise: (kind, scale) of Gymnasium-style start-state noise: ("uniform", s) or ("uniform_normal", s)
            (uniform on qpos, normal on qvel, like HalfCheetah/Ant/Humanoid v5).
        licence: the model files' licence, shown in docs and the asset manager.
        spec_edit: optional extra MjSpec edit (e.g. add a floor), applied before removals.
        pomdp_hide: observation groups the `.pomdp` variant hides.
        exclude_root_xy: drop the root's horizontal world coordinates from observations (False for a cart).
    """

    name: str
    load_spec: Callable[[], mujoco.MjSpec]
    tasks: Mapping[str, Task]
    default_task: str
    datasets: Sequence[str] = ("real", "perfect", "preference")
    default_dataset: str = "real"
    family: str = "humanoid"
    joints_to_remove: Sequence[str] = ()
    actuators_to_remove: Sequence[str] = ()
    control_dt: float = 0.01
    timestep: float | None = None
    init_keyframe: str | None = None
    reset_noise: tuple[str, float] = ("uniform", 0.0)
    licence: str = ""
    source: str = ""
    spec_edit: Callable[[mujoco.MjSpec], None] | None = None
    pomdp_hide: Sequence[str] = ("velocities",)
    exclude_root_xy: bool = True
    extra: Mapping[str, object] = field(default_factory=dict)

    def task_ids(self) -> list[str]:
        return [f"{self.name}.{task}{'.' + mode if mode else ''}.{ds}"
                for task in self.tasks for mode in self.modes(task) for ds in self.datasets]

    def modes(self, task: str) -> tuple[str | None, ...]:
        """The Task-ID modes of a task (LocoMuJoCo's 4Ages body sizes: all, 1, 2, 3, 4); (None,) without modes."""
        draw = self.tasks[task].draw
        return tuple(draw.modes) if draw is not None and draw.modes else (None,)
