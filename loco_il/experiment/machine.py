"""What a run's final evaluation ran on, recorded in its `eval.json` (`finished_on`): wall times are only
comparable between runs on like machines, and a leaderboard mixes runs from several. No host name is recorded."""
from __future__ import annotations

import os
import platform
from typing import Any


def _cpu_model() -> str | None:
    """The CPU's model name from /proc/cpuinfo (Linux), else `platform.processor()` (often empty), else None."""
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or None


def _usable_cpus() -> int:
    """CPU cores this process may run on (its affinity, e.g. a container's share), else the machine's count."""
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return os.cpu_count() or 1


def machine_record(device: str) -> dict[str, Any]:
    """The machine as a run records it: CPU model and usable cores, the torch device (and GPU name), versions."""
    import mujoco
    import numpy
    import torch

    record: dict[str, Any] = {"cpu": _cpu_model(), "cpu_cores": _usable_cpus(), "device": device}
    if device.startswith("cuda") and torch.cuda.is_available():
        record["gpu"] = torch.cuda.get_device_name(torch.device(device))
    record["versions"] = {"python": platform.python_version(), "torch": torch.__version__,
                          "mujoco": mujoco.__version__, "numpy": numpy.__version__}
    return record


__all__ = ["machine_record"]
