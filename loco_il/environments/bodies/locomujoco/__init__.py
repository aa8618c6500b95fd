"""LocoMuJoCo 0.4.1's own robots, configured as LocoMuJoCo does by default; importing registers them."""
from loco_il.environments.bodies.locomujoco import (atlas, humanoid_4ages, humanoid_torque, talos,  # noqa: F401
                                                    unitree_a1, unitree_g1, unitree_h1)
