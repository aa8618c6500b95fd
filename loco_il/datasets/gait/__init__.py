"""Gait generator for the quadrupeds' `real` datasets.

A trot from coupled phase oscillators (:mod:`.cpg`), foot trajectories turned into joint targets by
analytic leg inverse kinematics (:mod:`.leg_ik`), tracked in the env's simulation through the body's
actuators with a PD loop, Raibert foot placement, velocity and heading feedback (:mod:`.controller`),
and recorded as state-only datasets (:mod:`.provider`)::

    from loco_il.datasets.gait import quadruped_real_dataset
    data = quadruped_real_dataset(LocoEnv.make("UnitreeA1.hard.real"), n_episodes=10, seed=0)

The same controller run at the env's control rate is the built-in expert of the quadrupeds' `simple`
`perfect` / `preference` datasets (:mod:`.expert`, `TrotExpert`; model-based, not an RL policy)::

    data = LocoEnv.make("UnitreeA1.simple.perfect").create_dataset()
"""
from loco_il.datasets.gait.controller import ControllerParams, TrotController
from loco_il.datasets.gait.cpg import GaitParams, PhaseOscillators
from loco_il.datasets.gait.expert import TrotExpert, trot_expert, trot_levels
from loco_il.datasets.gait.leg_ik import LegGeometry, leg_fk, leg_ik, leg_jacobian, quadruped_legs
from loco_il.datasets.gait.provider import (DEFAULT_REAL_EPISODES, GaitEpisode, GaitVariation, NO_VARIATION,
                                            generate_episodes, is_quadruped, quadruped_real_dataset,
                                            quadruped_real_provider, real_dispatcher, run_gait_episode)

__all__ = ["ControllerParams", "TrotController", "GaitParams", "PhaseOscillators", "LegGeometry", "leg_fk",
           "leg_ik", "leg_jacobian", "quadruped_legs", "DEFAULT_REAL_EPISODES", "GaitEpisode", "GaitVariation",
           "NO_VARIATION", "generate_episodes", "is_quadruped", "quadruped_real_dataset", "quadruped_real_provider",
           "real_dispatcher", "run_gait_episode", "TrotExpert", "trot_expert", "trot_levels"]
