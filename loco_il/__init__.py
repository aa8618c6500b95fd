"""loco_il: imitation learning for legged locomotion in MuJoCo."""
from loco_il.environments import LocoEnv, LocoGymEnv, UnknownTaskError, get_all_task_names

__version__ = "0.1.0"
__all__ = ["LocoEnv", "LocoGymEnv", "UnknownTaskError", "get_all_task_names", "__version__"]
