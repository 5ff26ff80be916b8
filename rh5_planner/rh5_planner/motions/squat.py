"""Squats (:class:`SquatMotion`): the CoM dips and rises with both feet on the ground."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from .spec import KnotSpec, MotionSpec, Reference, knot_count, stance
from .validation import MotionError, check_count, check_nonnegative, check_positive

__all__ = ["SquatMotion"]


@dataclass(frozen=True)
class SquatMotion(MotionSpec):
    """``n_squats`` squats: the CoM goes down by ``com_range_m`` and back up, a cosine in time per squat.

    The horizon is ``hold_s`` at rest, the squats (``total_time_s - 2 hold_s`` split evenly), ``hold_s`` at
    rest. Both feet stay in contact; CoM x/y stay over the middle of the feet.
    """

    com_range_m: float = 0.2
    n_squats: int = 1
    hold_s: float = 0.15

    kind: ClassVar[str] = "squat"

    def __post_init__(self) -> None:
        super().__post_init__()
        check_positive("com_range_m", self.com_range_m)
        check_count("n_squats", self.n_squats)
        check_nonnegative("hold_s", self.hold_s)
        if 2 * self.hold_s >= self.total_time_s:
            msg = f"{self.name}: 2 * hold_s ({2 * self.hold_s} s) must be shorter than total_time_s"
            raise MotionError(msg)
        if self.com_range_m > 0.35:
            msg = f"{self.name}: com_range_m = {self.com_range_m} m is beyond the knee range (<= 0.35 m)"
            raise MotionError(msg)

    def knots(self, reference: Reference) -> list[KnotSpec]:
        """Both feet in contact at every knot; CoM height follows (1 - cos) / 2 dips."""
        feet = stance(reference)
        com0 = np.array(reference.com, dtype=float)
        mid = 0.5 * (feet["left"] + feet["right"])
        n_hold = knot_count(self.hold_s, self.dt)
        n_move = self.n_knots - 2 * n_hold
        specs = []
        for i in range(self.n_knots):
            s = min(max(i - n_hold, 0), n_move) / n_move  # 0..1 over all squats
            depth = 0.5 * self.com_range_m * (1.0 - math.cos(2.0 * math.pi * self.n_squats * s))
            com = np.array([mid[0], mid[1], com0[2] - depth])
            phase = (
                "hold"
                if i < n_hold or i >= n_hold + n_move
                else f"squat_{min(int(s * self.n_squats), self.n_squats - 1) + 1}"
            )
            specs.append(KnotSpec(phase, (True, True), {k: v.copy() for k, v in feet.items()}, com))
        return specs
