"""Gait generator: the quadrupeds' reference motion, a trot.

A trot from coupled phase oscillators (:mod:`.cpg`), foot trajectories turned into joint targets by
analytic leg inverse kinematics (:mod:`.leg_ik`), tracked in the env's simulation through the body's
actuators with a PD loop, Raibert foot placement, velocity and heading feedback (:mod:`.controller`),
varied per episode (:mod:`.variation`). It is recorded as the quadrupeds' state-only `real` datasets
(`loco_il.datasets.gait`)::

    from loco_il.datasets.gait import quadruped_real_dataset
    data = quadruped_real_dataset(LocoEnv.make("UnitreeA1.hard.real"), n_episodes=10, seed=0)

and, run at the env's control rate, it is the built-in expert of the quadrupeds' `simple` `perfect` /
`preference` datasets (`loco_il.experts.trot.TrotExpert`; model-based, not an RL policy)::

    data = LocoEnv.make("UnitreeA1.simple.perfect").create_dataset()
"""
from loco_il.motion.gait.controller import ControllerParams, TrotController
from loco_il.motion.gait.cpg import GaitParams, PhaseOscillators
from loco_il.motion.gait.leg_ik import LegGeometry, leg_fk, leg_ik, leg_jacobian, quadruped_legs
from loco_il.motion.gait.quadruped import goal_speed, is_quadruped, model_fingerprint
from loco_il.motion.gait.variation import NO_VARIATION, GaitVariation

__all__ = ["ControllerParams", "TrotController", "GaitParams", "PhaseOscillators", "LegGeometry", "leg_fk",
           "leg_ik", "leg_jacobian", "quadruped_legs", "GaitVariation", "NO_VARIATION", "goal_speed", "is_quadruped",
           "model_fingerprint"]
