"""Per-episode variation of the trot: the same draws give the `real` episodes and the trot expert's episodes.

A generator seeded with the episode's reset seed draws the gait frequency, swing height, body height, stance
width and an initial phase jitter, so the episodes of a dataset differ although a task may always start from
the same state.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from loco_il.motion.gait.controller import ControllerParams


@dataclass(frozen=True)
class GaitVariation:
    """Ranges of the per-episode gait variation (uniform draws); all zero-width gives identical gaits."""

    frequency: tuple[float, float] = (2.2, 2.8)          # Hz
    swing_height: tuple[float, float] = (0.05, 0.09)     # m
    height_offset: tuple[float, float] = (-0.015, 0.005)  # m, added to the standing height
    stance_width: tuple[float, float] = (0.0, 0.02)      # m
    phase_jitter: float = 0.05                           # cycles, initial phase perturbation

    def draw(self, base: ControllerParams, rng: np.random.Generator,
             standing_height: float) -> tuple[ControllerParams, float]:
        p = ControllerParams(**{k: v for k, v in asdict(base).items() if k != "gait"})
        p.gait = type(base.gait)(**asdict(base.gait))
        p.gait.frequency = float(rng.uniform(*self.frequency))
        p.gait.swing_height = float(rng.uniform(*self.swing_height))
        if base.body_height is None:
            p.body_height = standing_height + float(rng.uniform(*self.height_offset))
        p.stance_width = base.stance_width + float(rng.uniform(*self.stance_width))
        return p, self.phase_jitter


NO_VARIATION = GaitVariation((2.5, 2.5), (0.07, 0.07), (0.0, 0.0), (0.0, 0.0), 0.0)

__all__ = ["GaitVariation", "NO_VARIATION"]
