"""Locomotion environments: Task-IDs, the LocoEnv MDP and its Gymnasium adapter."""
from loco_il.environments.base import LocoEnv
from loco_il.environments.gym_adapter import LocoGymEnv, register_gymnasium
from loco_il.environments.registry import UnknownTaskError, get_all_task_names, parse_task_id

register_gymnasium()

__all__ = ["LocoEnv", "LocoGymEnv", "UnknownTaskError", "get_all_task_names", "parse_task_id"]
