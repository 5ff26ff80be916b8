"""Straight walking (:class:`WalkMotion`): alternating steps with smooth swing arcs, touch-down impulses and
double-support phases."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from rh5_msgs_py.array_types import FloatArray

from .spec import SIDES, KnotSpec, MotionSpec, Reference, knot_count, stance
from .validation import MotionError, check_count, check_nonnegative, check_positive

__all__ = ["WalkMotion"]


def _step(start: FloatArray, end: FloatArray, height: float, s: float) -> FloatArray:
    """Sole position along a walking step: a smoothstep in x/y and a bump 16 h s^2 (1 - s)^2 of apex ``height``
    in z, so the sole leaves and reaches the ground with zero velocity (no velocity jump at lift-off for the
    swing leg to follow, a soft touch-down impulse)."""
    smooth = s * s * (3.0 - 2.0 * s)
    p = (1.0 - smooth) * start + smooth * end
    p[2] += 16.0 * height * s * s * (1.0 - s) * (1.0 - s)
    return p


@dataclass(frozen=True)
class WalkMotion(MotionSpec):
    """Straight walking: ``n_steps`` alternating steps (first: ``first_foot``) covering ``length_m``.

    Sole targets: the feet land at fractions 1/(n-1), 2/(n-1), ... of the length, the last step closes the
    feet side by side at ``length_m``; swing soles follow a parabola of apex ``step_height_m``. The horizon
    ``total_time_s`` is split into ``initial_support_s`` and ``final_support_s`` double support,
    ``support_knots`` double-support knots after each step and equal swing phases; every touch-down is an
    impulse node. ``rest_s`` more of double support follow the walk (the horizon is ``total_time_s + rest_s``)
    so that the robot can come to rest: within ``final_support_s`` alone the CoP region cannot stop the CoM
    (the 5 kg walk ended at 0.03 m/s with its CoP on the toes, and toppled after playback on the suite's
    PyBullet physics).
    ``track_com`` adds a predefined CoM path (linear in x from the initial CoM to the initial CoM + length,
    middle of the feet in y) as a CoM cost and as the warm start: the paper's remedy above 0.35 m/s.
    ``ramp_steps`` > 0 lets the first and last ``ramp_steps`` steps grow and shrink (1/(r+1), 2/(r+1), ... of the
    cruise step) so that a fast walk can accelerate from rest and stop within the CoP region (a linear inverted
    pendulum at RH5's CoM height gains ~1 m/s within two steps with its CoP at the heel, not within one).
    """

    length_m: float = 0.5
    step_height_m: float = 0.05
    n_steps: int = 4
    support_knots: int = 2
    initial_support_s: float = 0.15
    final_support_s: float = 0.15
    rest_s: float = 0.0
    first_foot: str = "right"
    track_com: bool = False
    ramp_steps: int = 0

    kind: ClassVar[str] = "walk"
    kinematic_guess: ClassVar[bool] = True

    def __post_init__(self) -> None:
        super().__post_init__()
        check_nonnegative("length_m", self.length_m)
        check_positive("step_height_m", self.step_height_m)
        check_count("n_steps", self.n_steps, 2)
        check_count("support_knots", self.support_knots, 1)
        check_nonnegative("initial_support_s", self.initial_support_s)
        check_nonnegative("final_support_s", self.final_support_s)
        check_nonnegative("rest_s", self.rest_s)
        check_count("ramp_steps", self.ramp_steps, 0)
        if self.first_foot not in SIDES:
            msg = f"first_foot must be one of {SIDES}, got {self.first_foot!r}"
            raise MotionError(msg)
        if self.swing_knots < 3:
            msg = (
                f"{self.name}: total_time_s = {self.total_time_s} s leaves {self.swing_knots} knots per swing "
                f"(< 3) after the support phases; lengthen the motion or shorten the supports"
            )
            raise MotionError(msg)

    @property
    def speed_m_s(self) -> float:
        """Average forward speed."""
        return self.length_m / self.total_time_s

    @property
    def n_knots(self) -> int:
        """Running knots of the horizon: the walk and the rest after it."""
        return knot_count(self.total_time_s + self.rest_s, self.dt)

    @property
    def swing_knots(self) -> int:
        """Knots of each swing phase (the walk's time after its support phases, split over the steps)."""
        support = knot_count(self.initial_support_s, self.dt) + knot_count(self.final_support_s, self.dt)
        return (knot_count(self.total_time_s, self.dt) - support - self.n_steps * self.support_knots) // self.n_steps

    def initial_base_shift(self) -> FloatArray:
        """The base ends ``length_m`` ahead."""
        return np.array([self.length_m, 0.0, 0.0])

    def landings(self) -> FloatArray:
        """(n_steps,) forward sole position of each step's landing, as a fraction of ``length_m``: equal increments
        (the last step closes the feet side by side), ramped over ``ramp_steps`` at either end."""
        n = self.n_steps
        i = np.arange(1, n)
        ramp = self.ramp_steps + 1
        increments = np.minimum(1.0, np.minimum(i, n - i) / ramp) if self.ramp_steps else np.ones(n - 1)
        positions = np.cumsum(increments) / increments.sum()
        return np.append(positions, 1.0)

    @property
    def cruise_speed_m_s(self) -> float:
        """Average forward speed of the full-length steps: one cruise increment per step period."""
        n = self.n_steps
        i = np.arange(1, n)
        ramp = self.ramp_steps + 1
        increments = np.minimum(1.0, np.minimum(i, n - i) / ramp) if self.ramp_steps else np.ones(n - 1)
        period = (self.swing_knots + self.support_knots + 0) * self.dt
        return float(self.length_m * increments.max() / increments.sum() / period)

    def knots(self, reference: Reference) -> list[KnotSpec]:
        """Double support, then per step: swing, touch-down impulse, double support; then double support."""
        feet = stance(reference)
        com0 = np.array(reference.com, dtype=float)
        specs: list[KnotSpec] = []
        n_init = knot_count(self.initial_support_s, self.dt)
        total = self.n_knots
        mid0 = 0.5 * (feet["left"] + feet["right"])

        def com_at(i: int) -> FloatArray | None:
            if not self.track_com:
                return None
            s = min(1.0, i / max(1, knot_count(self.total_time_s, self.dt) - knot_count(self.final_support_s, self.dt)))
            c = com0.copy()
            c[0] += s * self.length_m
            c[1] = mid0[1]
            return c

        def support(phase: str, count: int) -> None:
            for _ in range(count):
                specs.append(KnotSpec(phase, (True, True), {k: v.copy() for k, v in feet.items()}, com_at(_running())))

        def _running() -> int:
            return sum(1 for k in specs if not k.impulse)

        support("initial_support", n_init)
        order = [self.first_foot if i % 2 == 0 else _other(self.first_foot) for i in range(self.n_steps)]
        for i, side in enumerate(order, start=1):
            start = feet[side].copy()
            end = start.copy()
            end[0] = reference.foot(side)[0] + self.length_m * float(self.landings()[i - 1])
            contacts = (side != "left", side != "right")
            for k in range(self.swing_knots):
                targets = {k2: v.copy() for k2, v in feet.items()}
                targets[side] = _step(start, end, self.step_height_m, k / self.swing_knots)
                specs.append(KnotSpec(f"step_{i}_{side}", contacts, targets, com_at(_running())))
            feet[side] = end
            specs.append(
                KnotSpec(
                    f"touchdown_{i}_{side}",
                    (True, True),
                    {k: v.copy() for k, v in feet.items()},
                    com_at(_running()),
                    impulse=True,
                    touchdown=(side,),
                )
            )
            support(f"support_{i}", self.support_knots)
        support("final_support", total - _running())
        return specs


def _other(side: str) -> str:
    return "left" if side == "right" else "right"
