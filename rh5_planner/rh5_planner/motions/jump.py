"""Two-footed jumps (:class:`JumpMotion`): ground phases, ballistic flights and touch-down impulses, with a CoM
guess for the warm start."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar, Final

import numpy as np

from rh5_msgs_py.array_types import FloatArray

from .spec import SIDES, KnotSpec, MotionSpec, Reference, knot_count, stance
from .validation import MotionError, check_count, check_nonnegative, check_positive

__all__ = ["GRAVITY", "JumpMotion"]

GRAVITY: Final = 9.81


def _swing(start: FloatArray, end: FloatArray, height: float, s: float) -> FloatArray:
    """Sole position along a ballistic arc (jump flight): linear in x/y, parabolic apex ``height`` above the
    straight line, as a free-falling body moves."""
    p = (1.0 - s) * start + s * end
    p[2] += 4.0 * height * s * (1.0 - s)
    return p


@dataclass(frozen=True)
class JumpMotion(MotionSpec):
    """``n_jumps`` two-footed jumps of apex ``height_m`` (sole clearance), each ``length_m`` / n forward.

    Each jump: ground phase (push-off), flight of the ballistic duration 2 sqrt(2 h / g) for the apex height,
    touch-down impulse of both soles; the ground phases share the remaining time. Sole targets follow a parabola
    of apex ``height_m`` during flight (flight knot k of n at phase k / n, as the walk's swings). No CoM cost (the
    paper's table): the CoM only shapes the warm start (``KnotSpec.com_guess``): hold, a smoothstep crouch, a
    push-off of constant acceleration (at least g, crouch at most ``max_crouch_m``) up to the take-off velocity,
    the ballistic parabola, and a smoothstep recovery of ``recovery_s`` after each landing.
    """

    height_m: float = 0.1
    length_m: float = 0.0
    n_jumps: int = 1
    max_crouch_m: float = 0.1
    recovery_s: float = 0.15

    kind: ClassVar[str] = "jump"
    kinematic_guess: ClassVar[bool] = True

    def __post_init__(self) -> None:
        super().__post_init__()
        check_positive("height_m", self.height_m)
        check_nonnegative("length_m", self.length_m)
        check_count("n_jumps", self.n_jumps)
        check_positive("max_crouch_m", self.max_crouch_m)
        check_nonnegative("recovery_s", self.recovery_s)
        ground = self.n_knots - self.n_jumps * self.flight_knots
        if ground < 3 * (self.n_jumps + 1):
            msg = f"{self.name}: total_time_s = {self.total_time_s} s is too short for {self.n_jumps} jumps"
            raise MotionError(msg)

    @property
    def flight_knots(self) -> int:
        """Knots of each flight phase."""
        return max(2, knot_count(2.0 * math.sqrt(2.0 * self.height_m / GRAVITY), self.dt))

    @property
    def takeoff_velocity(self) -> FloatArray:
        """CoM velocity (x, z) at take-off of the ballistic flight of ``flight_knots``."""
        flight = self.flight_knots * self.dt
        return np.array([self.length_m / self.n_jumps / flight, 0.5 * GRAVITY * flight])

    def initial_base_shift(self) -> FloatArray:
        """The base ends ``length_m`` ahead."""
        return np.array([self.length_m, 0.0, 0.0])

    def _push_knots(self) -> int:
        vz = float(self.takeoff_velocity[1])
        accel = max(GRAVITY, vz * vz / (2.0 * self.max_crouch_m))
        return max(1, round(vz / accel / self.dt))

    def _ground_guess(self, count: int, stand: FloatArray, landing: FloatArray | None, jump: bool) -> list[FloatArray]:
        """CoM guesses of a ground phase: recovery from ``landing``, hold, crouch and push-off (when ``jump``)."""
        recover = min(count // 3, knot_count(self.recovery_s, self.dt)) if landing is not None else 0
        push = min(self._push_knots(), count // 3) if jump else 0
        crouch = min(knot_count(0.2, self.dt), count - recover - push) if jump else 0
        hold = count - recover - push - crouch
        out: list[FloatArray] = []
        for k in range(recover):
            s = (k + 1) / recover
            out.append(landing + (s * s * (3.0 - 2.0 * s)) * (stand - landing))  # type: ignore[operator]
        out.extend(stand.copy() for _ in range(hold))
        if jump:
            t_push = push * self.dt
            vx, vz = self.takeoff_velocity
            low = stand + np.array([-0.5 * vx * t_push, 0.0, -0.5 * vz * t_push])
            for k in range(crouch):
                s = (k + 1) / crouch
                out.append(stand + (s * s * (3.0 - 2.0 * s)) * (low - stand))
            for k in range(push):
                t = k * self.dt
                out.append(low + np.array([vx, 0.0, vz]) * (0.5 * t * t / t_push))
        return out

    def knots(self, reference: Reference) -> list[KnotSpec]:
        """Ground, flight, touch-down impulse, repeated; ground phases split the rest evenly."""
        feet = stance(reference)
        com0 = np.array(reference.com, dtype=float)
        ground_total = self.n_knots - self.n_jumps * self.flight_knots
        grounds = [ground_total // (self.n_jumps + 1)] * (self.n_jumps + 1)
        grounds[-1] += ground_total - sum(grounds)
        step = np.array([self.length_m / self.n_jumps, 0.0, 0.0])
        vx, vz = self.takeoff_velocity
        specs: list[KnotSpec] = []
        landing: FloatArray | None = None
        for j in range(self.n_jumps + 1):
            stand = com0 + j * step
            guesses = self._ground_guess(grounds[j], stand, landing, jump=j < self.n_jumps)
            phase = f"ground_{j}" if j < self.n_jumps else "landing"
            specs.extend(
                KnotSpec(phase, (True, True), {k: v.copy() for k, v in feet.items()}, com_guess=c) for c in guesses
            )
            if j == self.n_jumps:
                break
            start = {k: v.copy() for k, v in feet.items()}
            end = {k: v + step for k, v in feet.items()}
            for k in range(self.flight_knots):
                t = k * self.dt
                targets = {side: _swing(start[side], end[side], self.height_m, k / self.flight_knots) for side in SIDES}
                com = stand + np.array([vx * t, 0.0, vz * t - 0.5 * GRAVITY * t * t])
                specs.append(KnotSpec(f"flight_{j + 1}", (False, False), targets, com_guess=com))
            feet = end
            landing = stand + np.array([vx * self.flight_knots * self.dt, 0.0, 0.0])
            specs.append(
                KnotSpec(
                    f"touchdown_{j + 1}",
                    (True, True),
                    {k: v.copy() for k, v in feet.items()},
                    impulse=True,
                    touchdown=SIDES,
                    com_guess=landing.copy(),
                )
            )
        return specs
