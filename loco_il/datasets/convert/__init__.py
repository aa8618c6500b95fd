"""Converters between loco_il's :class:`~loco_il.datasets.Trajectories` and other formats.

* :func:`to_minari` / :func:`from_minari` - Minari datasets (optional
  dependency, ``pip install loco_il[datasets]``; imported only when called).
* :func:`load_locomujoco_npz` - LocoMuJoCo 0.4.x ``.npz`` dataset files.
"""

from loco_il.datasets.convert.locomujoco import load_locomujoco_npz
from loco_il.datasets.convert.minari import from_minari, to_minari

__all__ = ["to_minari", "from_minari", "load_locomujoco_npz"]
