"""Quasi-static balancing and stepping (:class:`BalanceMotion`, the paper's hardware experiments I and II)."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from .spec import KnotSpec, MotionSpec, Reference, knot_count, stance
from .validation import MotionError, check_nonnegative, check_positive

__all__ = ["BalanceMotion"]


@dataclass(frozen=True)
class BalanceMotion(MotionSpec):
    """Quasi-static CoM shifts and one right-foot step (the paper's hardware experiments I and II).

    ``phases`` lists (name, duration) in order; names: ``hold`` (initial pose), ``shift_left`` (CoM over the
    left sole), ``lift`` (right sole up by ``lift_height_m`` and forward by ``step_length_m`` / 2),
    ``lower`` (right sole down to ``step_length_m`` ahead, touch-down impulse), ``center`` (CoM back to the
    middle of the support polygon). one_leg_balancing uses step_length_m = 0 (the foot goes back where it was).
    """

    phases: tuple[tuple[str, float], ...] = ()
    lift_height_m: float = 0.05
    step_length_m: float = 0.0

    kind: ClassVar[str] = "balance"
    kinematic_guess: ClassVar[bool] = True
    PHASE_NAMES: ClassVar[tuple[str, ...]] = ("hold", "shift_left", "lift", "lower", "center")

    def __post_init__(self) -> None:
        phases = tuple((str(p[0]), float(p[1])) for p in self.phases)
        object.__setattr__(self, "phases", phases)
        object.__setattr__(self, "total_time_s", sum(d for _, d in phases) if phases else self.total_time_s)
        super().__post_init__()
        for name, duration in phases:
            if name not in self.PHASE_NAMES:
                msg = f"{self.name}: unknown phase {name!r}; known: {list(self.PHASE_NAMES)}"
                raise MotionError(msg)
            check_positive(f"duration of phase {name}", duration)
        check_positive("lift_height_m", self.lift_height_m)
        check_nonnegative("step_length_m", self.step_length_m)

    def with_overrides(self, overrides: Mapping[str, Any]) -> MotionSpec:
        """As MotionSpec.with_overrides; ``phases`` is a list of [name, duration] pairs (total_time_s follows)."""
        if "total_time_s" in overrides:
            msg = f"{self.name}: total_time_s follows from the phases; override 'phases' instead"
            raise MotionError(msg)
        if "phases" in overrides:
            try:
                phases = tuple((str(n), float(d)) for n, d in overrides["phases"])
            except (TypeError, ValueError):
                msg = f"{self.name}: phases must be a list of [name, duration] pairs, got {overrides['phases']!r}"
                raise MotionError(msg) from None
            rest = {k: v for k, v in overrides.items() if k != "phases"}
            return dataclasses.replace(self, phases=phases).with_overrides(rest)
        return super().with_overrides(overrides)

    def knots(self, reference: Reference) -> list[KnotSpec]:
        """CoM targets interpolate (smoothstep) between the phase end points; the right foot steps."""
        feet = stance(reference)
        com0 = np.array(reference.com, dtype=float)
        com = com0.copy()
        specs: list[KnotSpec] = []
        right_start = feet["right"].copy()
        right_mid = right_start + np.array([0.5 * self.step_length_m, 0.0, self.lift_height_m])
        right_end = right_start + np.array([self.step_length_m, 0.0, 0.0])
        for name, duration in self.phases:
            n = knot_count(duration, self.dt)
            com_start = com.copy()
            if name == "shift_left":
                com_goal = np.array([feet["left"][0], feet["left"][1], com0[2]])
            elif name == "center":
                mid = 0.5 * (feet["left"] + feet["right"])
                com_goal = np.array([mid[0], mid[1], com0[2]])
            else:
                com_goal = com_start.copy()
            for k in range(n):
                s = (k + 1) / n
                smooth = s * s * (3.0 - 2.0 * s)
                com = (1.0 - smooth) * com_start + smooth * com_goal
                targets = {side: v.copy() for side, v in feet.items()}
                contacts = (True, True)
                if name == "lift":
                    targets["right"] = (1.0 - smooth) * right_start + smooth * right_mid
                    contacts = (True, False)
                elif name == "lower":
                    targets["right"] = (1.0 - smooth) * right_mid + smooth * right_end
                    contacts = (True, False)
                specs.append(KnotSpec(name, contacts, targets, com.copy()))
            com = com_goal.copy()
            if name == "lower":
                feet["right"] = right_end.copy()
                specs.append(
                    KnotSpec(
                        "touchdown_right",
                        (True, True),
                        {side: v.copy() for side, v in feet.items()},
                        com.copy(),
                        impulse=True,
                        touchdown=("right",),
                    )
                )
        return specs
