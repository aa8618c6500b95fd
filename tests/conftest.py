"""Test-wide settings: single-threaded torch (2-core CI), headless rendering, a private asset cache if asked;
fixtures several test modules share."""
import os

os.environ.setdefault("MUJOCO_GL", "egl")
os.environ.setdefault("WANDB_MODE", "offline")
os.environ.setdefault("WANDB_SILENT", "true")

import pytest  # noqa: E402
import torch  # noqa: E402

torch.set_num_threads(1)


@pytest.fixture(scope="module")
def envs():
    """`envs(task_id)`: one env per Task-ID, made on first use and shared by the module's tests."""
    from loco_il.environments.registry import make
    cache = {}

    def get(task_id):
        if task_id not in cache:
            cache[task_id] = make(task_id)
        return cache[task_id]
    return get
