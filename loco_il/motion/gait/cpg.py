"""Central pattern generator (coupled phase oscillators) and foot trajectories for a trot.

Oscillators. Leg i has a phase ``phi_i`` in cycles (its fractional part is the gait phase: stance while
``frac(phi) < duty``, swing after). The phases follow Kuramoto-type coupled oscillators::

    dphi_i/dt = f + k * sum_j sin(2 pi (phi_j - phi_i - (o_j - o_i))) / (2 pi)

with gait frequency ``f`` (Hz), coupling ``k`` (1/s) and the gait's phase offsets ``o``: for a trot the
diagonal pairs (FR, RL) and (FL, RR) are in phase and the two pairs in anti-phase (o = 0, 0.5, 0.5, 0).
Started from perturbed phases, the oscillators converge to the trot pattern at rate ~k.

Foot trajectories (horizontal positions are relative to the trunk, in the heading frame):
* stance: the foot moves backwards at the body's commanded velocity (plus the rotation from the yaw
  rate), so that a foot that does not slip carries the body forward -- integrated by the controller;
* swing: from the lift-off point to the touchdown point chosen by the foot-placement rule, along
  a smooth (minimum-jerk-like) horizontal profile and a raised arc ``height * (1 - cos 2 pi s) / 2``
  whose vertical velocity is zero at lift-off and touchdown.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: phase offsets (cycles) of FR, FL, RR, RL
TROT_OFFSETS = np.array([0.0, 0.5, 0.5, 0.0])


@dataclass
class GaitParams:
    """Timing and shape of the gait (all in SI units)."""

    frequency: float = 2.5       # gait cycles per second
    duty: float = 0.5            # stance fraction of a cycle
    swing_height: float = 0.07   # foot apex above the ground (m)
    coupling: float = 4.0        # oscillator coupling k (1/s)

    @property
    def stance_time(self) -> float:
        return self.duty / self.frequency

    @property
    def swing_time(self) -> float:
        return (1.0 - self.duty) / self.frequency


class PhaseOscillators:
    """Four coupled phase oscillators (see the module docstring); phases in cycles."""

    def __init__(self, params: GaitParams, offsets: np.ndarray = TROT_OFFSETS,
                 initial: np.ndarray | None = None):
        self.params = params
        self.offsets = np.asarray(offsets, dtype=np.float64)
        self.phase = (self.offsets.copy() if initial is None else np.asarray(initial, dtype=np.float64).copy())

    def step(self, dt: float, frequency: float | None = None) -> np.ndarray:
        """Advance by ``dt`` seconds (semi-implicit Euler); returns the new phases."""
        f = self.params.frequency if frequency is None else frequency
        diff = (self.phase[None, :] - self.phase[:, None]) - (self.offsets[None, :] - self.offsets[:, None])
        coupling = self.params.coupling * np.sin(2 * np.pi * diff).sum(axis=1) / (2 * np.pi)
        self.phase = self.phase + dt * (f + coupling)
        return self.phase

    @property
    def gait_phase(self) -> np.ndarray:
        """Fractional phase in [0, 1) per leg."""
        return np.mod(self.phase, 1.0)

    def in_stance(self) -> np.ndarray:
        return self.gait_phase < self.params.duty

    def swing_progress(self) -> np.ndarray:
        """Progress s in [0, 1] through the swing (0 during stance)."""
        d = self.params.duty
        return np.clip((self.gait_phase - d) / (1.0 - d), 0.0, 1.0)

    def pattern_error(self) -> float:
        """Largest deviation (cycles, in [0, 0.5]) of the relative phases from the gait pattern."""
        rel = (self.phase - self.phase[0]) - (self.offsets - self.offsets[0])
        rel = np.mod(rel + 0.5, 1.0) - 0.5
        return float(np.abs(rel).max())


def smoothstep(s: np.ndarray | float) -> np.ndarray | float:
    """Quintic 0 -> 1 with zero velocity and acceleration at both ends."""
    s = np.clip(s, 0.0, 1.0)
    return s * s * s * (10.0 - 15.0 * s + 6.0 * s * s)


def swing_height(s: np.ndarray | float, height: float) -> np.ndarray | float:
    """Foot lift above the stance height at swing progress s: ``height * (1 - cos 2 pi s) / 2``."""
    return height * 0.5 * (1.0 - np.cos(2.0 * np.pi * np.clip(s, 0.0, 1.0)))


def swing_position(s: float, lift_off: np.ndarray, touchdown: np.ndarray, height: float,
                   start_velocity: np.ndarray | None = None, end_velocity: np.ndarray | None = None,
                   duration: float = 1.0) -> tuple[np.ndarray, float]:
    """Horizontal position (xy) and lift of a swinging foot at progress s.

    Without velocities the horizontal path is a quintic smoothstep (at rest relative to the trunk at
    both ends). With ``start_velocity`` / ``end_velocity`` (relative to the trunk, m/s, over a swing of
    ``duration`` seconds) it is a cubic Hermite curve that leaves and lands with those velocities: a
    foot that lands moving backwards at the body's speed touches the ground without sliding.
    """
    if start_velocity is None and end_velocity is None:
        w = smoothstep(s)
        return lift_off + (touchdown - lift_off) * w, float(swing_height(s, height))
    s = float(np.clip(s, 0.0, 1.0))
    m0 = np.zeros(2) if start_velocity is None else np.asarray(start_velocity) * duration
    m1 = np.zeros(2) if end_velocity is None else np.asarray(end_velocity) * duration
    s2, s3 = s * s, s * s * s
    xy = ((2 * s3 - 3 * s2 + 1) * lift_off + (s3 - 2 * s2 + s) * m0 + (3 * s2 - 2 * s3) * touchdown
          + (s3 - s2) * m1)
    return xy, float(swing_height(s, height))


def stance_velocity(p_xy: np.ndarray, v_body: np.ndarray, yaw_rate: float) -> np.ndarray:
    """Velocity of a stance foot relative to the trunk (heading frame) when the body moves with planar
    velocity ``v_body`` and yaw rate ``yaw_rate`` over a foot that stays put: -(v + w x p)."""
    return -(v_body + yaw_rate * np.array([-p_xy[1], p_xy[0]]))


__all__ = ["GaitParams", "PhaseOscillators", "TROT_OFFSETS", "smoothstep", "swing_height", "swing_position",
           "stance_velocity"]
