"""loco_il: imitation learning for legged locomotion in MuJoCo."""
import os
import sys

# headless by default on Linux without a display (servers, CI); set MUJOCO_GL yourself to override
if sys.platform.startswith("linux") and not os.environ.get("DISPLAY"):
    os.environ.setdefault("MUJOCO_GL", "egl")

from loco_il.environments import LocoEnv, LocoGymEnv, UnknownTaskError, get_all_task_names

__version__ = "0.1.0"
__all__ = ["LocoEnv", "LocoGymEnv", "UnknownTaskError", "get_all_task_names", "__version__"]
