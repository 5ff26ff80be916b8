"""What every motion is: its common parameters (:class:`MotionSpec`), validated overrides, and the contact sequence
it produces (:class:`Reference` in, one :class:`KnotSpec` per shooting node out); the knot count and initial stance the
motion kinds share (their parameter checks are :mod:`.validation`).

Conventions: world frame z up, x forward; feet are ``"left"``/``"right"`` (names.FOOT_FRAMES); sole
targets are translations of the sole frame, whose orientation stays that of the initial stance (flat, no
turning); times in s, lengths in m.

Knot timing: a knot's targets apply to the state at the START of its interval (its running cost is
evaluated on x_i), so swing knot k of n targets the sole at phase k / n (the first swing node still on the
ground, where the previous contact left it) and the touch-down impulse node carries the landing placement.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar, Final

import numpy as np

from rh5_msgs_py.array_types import FloatArray

from .validation import MotionError, check_nonnegative, check_positive

__all__ = ["COST_TERMS", "SIDES", "KnotSpec", "MotionSpec", "Reference", "knot_count", "stance"]

SIDES: Final = ("left", "right")
COST_TERMS: Final = ("foot", "com", "friction", "cop", "joint", "posture", "torque")
"""Cost terms of the paper's table; costs.yaml ``motion_costs`` says which a motion switches on."""


@dataclass(frozen=True)
class Reference:
    """Where the motion starts: sole positions (world, m) and the CoM (world, m) of the initial pose."""

    feet: Mapping[str, FloatArray]
    com: FloatArray

    def foot(self, side: str) -> FloatArray:
        """Initial sole position of ``side`` (a copy)."""
        return np.array(self.feet[side], dtype=float)


@dataclass(frozen=True)
class KnotSpec:
    """One shooting node of the contact sequence.

    ``contacts`` (left, right) are the feet held by rigid 6D contacts during the node (after the impact for an
    impulse node). ``feet`` maps every side to its sole target position; ``com`` is the CoM target or None
    when the motion does not track the CoM. ``impulse`` marks a touch-down node of zero duration in which
    the feet of ``touchdown`` hit the ground. ``com_guess`` is a CoM position for the warm start only (never a
    cost): the jumps' crouch, push-off and ballistic flight.
    """

    phase: str
    contacts: tuple[bool, bool]
    feet: Mapping[str, FloatArray]
    com: FloatArray | None = None
    impulse: bool = False
    touchdown: tuple[str, ...] = ()
    com_guess: FloatArray | None = None

    def in_contact(self, side: str) -> bool:
        """Whether ``side`` is in contact at this node."""
        return self.contacts[SIDES.index(side)]


def knot_count(duration: float, dt: float) -> int:
    """Knots of ``dt`` in ``duration`` (rounded, at least one)."""
    return max(1, round(duration / dt))


@dataclass(frozen=True)
class MotionSpec:
    """Fields every motion has; subclasses add their own and build the contact sequence.

    ``costs``: the cost terms to switch on; None takes costs.yaml ``motion_costs[name]`` (the paper's table).
    ``payload_kg_per_hand``: mass added at each hand TCP (the paper's 5 kg aluminium bars).
    ``knee_bend_rad``: knee flexion of the initial (nominal) pose; the CoM is placed over the middle of the feet.
    ``actuator_limits``: also bound the linear actuators' stroke, velocity and force (Table I, through the
    parallel mechanisms' exact maps; costs.yaml ``actuator_limits``); False plans with the paper's cost set
    (``--set actuator_limits=false`` reproduces its feasibility table).
    """

    name: str
    dt: float = 0.03
    total_time_s: float = 1.0
    payload_kg_per_hand: float = 0.0
    knee_bend_rad: float = 0.5
    costs: tuple[str, ...] | None = None
    actuator_limits: bool = False

    kind: ClassVar[str] = "abstract"
    kinematic_guess: ClassVar[bool] = False
    """Whether the warm start is a whole-body IK guess along the knots' targets (rh5_planner.ocp.warm_start.state_guess)
    rather than the initial state at every knot."""

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            msg = f"name must be a non-empty string, got {self.name!r}"
            raise MotionError(msg)
        check_positive("dt", self.dt)
        check_positive("total_time_s", self.total_time_s)
        check_nonnegative("payload_kg_per_hand", self.payload_kg_per_hand)
        check_nonnegative("knee_bend_rad", self.knee_bend_rad)
        if self.dt > self.total_time_s:
            msg = f"dt ({self.dt} s) must not exceed total_time_s ({self.total_time_s} s)"
            raise MotionError(msg)
        if self.costs is not None:
            costs = tuple(self.costs)
            unknown = sorted(set(costs) - set(COST_TERMS))
            if unknown:
                msg = f"unknown cost terms {unknown}; known: {list(COST_TERMS)}"
                raise MotionError(msg)
            object.__setattr__(self, "costs", costs)

    @property
    def n_knots(self) -> int:
        """Number of running (non-impulse) knots of the horizon."""
        return knot_count(self.total_time_s, self.dt)

    def parameters(self) -> dict[str, Any]:
        """The fields as a JSON-able dict (what a trajectory file stores as ``motion.parameters``)."""
        out: dict[str, Any] = {}
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            out[f.name] = list(value) if isinstance(value, tuple) else value
        return out

    def with_overrides(self, overrides: Mapping[str, Any]) -> MotionSpec:
        """A validated copy with ``overrides`` applied; unknown keys and wrong types raise MotionError."""
        if not isinstance(overrides, Mapping):
            msg = f"overrides must be a mapping, got {type(overrides).__name__}"
            raise MotionError(msg)
        fields = {f.name: f for f in dataclasses.fields(self)}
        unknown = sorted(set(overrides) - set(fields))
        if unknown:
            msg = f"{self.name}: unknown parameters {unknown}; known: {sorted(fields)}"
            raise MotionError(msg)
        clean: dict[str, Any] = {}
        for key, raw in overrides.items():
            current = getattr(self, key)
            value = raw
            if isinstance(current, bool) or isinstance(value, bool):
                if not isinstance(value, bool) or not isinstance(current, bool):
                    msg = f"{self.name}: {key} must be {type(current).__name__}, got {value!r}"
                    raise MotionError(msg)
            elif isinstance(current, float) and isinstance(value, int):
                value = float(raw)
            elif isinstance(current, tuple) or (current is None and isinstance(value, list | tuple)):
                if not isinstance(value, list | tuple):
                    msg = f"{self.name}: {key} must be a list, got {value!r}"
                    raise MotionError(msg)
                value = tuple(float(v) if isinstance(v, int) and key != "costs" else v for v in raw)
            elif current is not None and not isinstance(value, type(current)):
                msg = f"{self.name}: {key} must be {type(current).__name__}, got {type(value).__name__} {value!r}"
                raise MotionError(msg)
            clean[key] = value
        return dataclasses.replace(self, **clean)

    def knots(self, reference: Reference) -> list[KnotSpec]:
        """The contact sequence from ``reference`` (the initial stance)."""
        raise NotImplementedError

    def initial_base_shift(self) -> FloatArray:
        """Base displacement from the start to the end of the motion (used to interpolate the warm start)."""
        return np.zeros(3)


def stance(reference: Reference) -> dict[str, FloatArray]:
    """The initial sole position of every side (copies, to be moved by the motion)."""
    return {side: reference.foot(side) for side in SIDES}
