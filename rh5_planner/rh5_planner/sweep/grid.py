"""The grid of a sweep: its axes, its points and which neighbour warm-starts which point.

An axis is ``key=start:stop:count`` (``count`` values from ``start`` to ``stop``, both included) or
``key=v1,v2,...``. Its key is one of

* a motion parameter (``payload_kg_per_hand``, ``height_m``, ``com_range_m``, ...; ``rh5-plan --list``);
* ``speed_m_s`` for walks: the average speed, reached by the length walked in the motion's own time
  (``length_m = speed_m_s * total_time_s``: longer steps, the same knots);
* a limit of the design heuristic, ``PATTERN:KIND`` (``knee:velocity``, ``hip3:velocity``, ``*:torque``): the factor
  on that joint limit and on the matching limit of the joint's linear actuators (Table I), as
  ``rh5-plan --design --scale`` uses it.

Points are numbered in C order (the last axis varies fastest). Warm starts run along the last axis when it is a
design limit: a point starts from the solution of the point before it on that axis, in chains of at most ``chain``
points, so that a one-axis sweep still has independent chains to run side by side. Only there do they pay: a wider
limit leaves the dynamics as they were and moves only the bounds, so the neighbour's optimum is close (10 cm jump,
knee x5 -> x6: 38 iterations instead of 53; squat: 7 instead of 11), whereas a neighbour with another payload or
speed has other dynamics, and the walk needed more iterations from it than from its own kinematic guess (70 instead
of 57, 7.5 kg from 5 kg; ``bench/sweep.py`` measures it). The source of each point is fixed by the grid alone,
never by which worker finished first, so every engine gets the same results.
Validating a grid builds each point's motion (pure numpy); nothing is solved.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Final

import numpy as np

from ..limit_scale import JOINT_KINDS, LimitScale
from ..motions import MotionError, MotionSpec, WalkMotion, get_motion

__all__ = ["DEFAULT_CHAIN", "SPEED_KEY", "Axis", "Grid", "GridError", "SweepPoint", "parse_axis"]

SPEED_KEY: Final = "speed_m_s"
"""Derived walk parameter: ``length_m = speed_m_s * total_time_s``."""
DEFAULT_CHAIN: Final = 4
"""Longest warm-start chain: every ``chain``-th point of the last axis starts cold."""
MAX_POINTS: Final = 10_000


class GridError(ValueError):
    """A bad axis, or a point whose motion parameters are invalid."""


@dataclass(frozen=True)
class Axis:
    """One swept key and its values."""

    key: str
    values: tuple[float, ...]

    @property
    def is_limit(self) -> bool:
        """Whether the key is a design limit (``PATTERN:KIND``) rather than a motion parameter."""
        return ":" in self.key

    def to_json(self) -> dict[str, Any]:
        """JSON-able form (the checkpoint's sweep description)."""
        return {"key": self.key, "values": list(self.values)}


def _number(text: str, item: str) -> float:
    try:
        value = float(text)
    except ValueError:
        msg = f"axis {item!r}: {text!r} is not a number"
        raise GridError(msg) from None
    if not math.isfinite(value):
        msg = f"axis {item!r}: {text!r} is not finite"
        raise GridError(msg)
    return value


def parse_axis(item: str) -> Axis:
    """``"payload_kg_per_hand=0:10:3"`` -> Axis(values 0, 5, 10); ``"knee:velocity=1,2,4"`` -> three factors."""
    key, sep, spec = item.rpartition("=")
    key = key.strip()
    if not sep or not key or not spec.strip():
        msg = f"axis {item!r}: expected key=start:stop:count or key=v1,v2,..."
        raise GridError(msg)
    if "," in spec or ":" not in spec:
        values = tuple(_number(v.strip(), item) for v in spec.split(",") if v.strip())
    else:
        parts = spec.split(":")
        if len(parts) != 3:
            msg = f"axis {item!r}: expected start:stop:count"
            raise GridError(msg)
        start, stop = _number(parts[0], item), _number(parts[1], item)
        try:
            count = int(parts[2])
        except ValueError:
            msg = f"axis {item!r}: count {parts[2]!r} is not an integer"
            raise GridError(msg) from None
        if count < 1:
            msg = f"axis {item!r}: count must be >= 1"
            raise GridError(msg)
        values = (start,) if count == 1 else tuple(float(v) for v in np.linspace(start, stop, count))
    if not values:
        msg = f"axis {item!r}: no values"
        raise GridError(msg)
    if len(set(values)) != len(values):
        msg = f"axis {item!r}: repeated values {values}"
        raise GridError(msg)
    # round away the float noise of linspace so that keys, file names and tables read as typed
    return Axis(key, tuple(float(f"{v:.10g}") for v in values))


@dataclass(frozen=True)
class SweepPoint:
    """One point of the grid: its number, its index on every axis and its values."""

    index: int
    position: tuple[int, ...]
    values: Mapping[str, float]
    warm_from: int | None
    """The point whose solution warm-starts this one (None: a cold start)."""

    @property
    def id(self) -> str:
        """Stable name within the sweep (checkpoint keys, file names): ``p0007``."""
        return f"p{self.index:04d}"

    def overrides(self, base: Mapping[str, Any], motion: MotionSpec) -> dict[str, Any]:
        """Motion parameter overrides of this point: ``base`` (``--set``), then the swept motion parameters."""
        out = dict(base)
        for key, value in self.values.items():
            if ":" in key:
                continue
            if key == SPEED_KEY:
                total = float(out.get("total_time_s", motion.total_time_s))
                out["length_m"] = value * total
            else:
                current = getattr(motion, key, None)
                out[key] = round(value) if isinstance(current, int) and not isinstance(current, bool) else value
        return out

    def limit_scale(self) -> LimitScale:
        """The scaled limits of this point (empty: nominal limits)."""
        entries = []
        for key, factor in self.values.items():
            pattern, sep, kind = key.rpartition(":")
            if sep:
                entries.append((pattern, kind, float(factor)))
        return LimitScale(tuple(entries))


@dataclass(frozen=True)
class Grid:
    """The points of a sweep over ``axes`` for ``motion`` with the ``base`` overrides of every point."""

    motion: str
    axes: tuple[Axis, ...]
    base: Mapping[str, Any]
    chain: int = DEFAULT_CHAIN
    warm_start: bool = True

    def __post_init__(self) -> None:
        if not self.axes:
            msg = "a sweep needs at least one axis (key=start:stop:count)"
            raise GridError(msg)
        keys = [a.key for a in self.axes]
        if len(set(keys)) != len(keys):
            msg = f"axis keys repeat: {keys}"
            raise GridError(msg)
        if self.chain < 1:
            msg = f"warm-start chain must be >= 1, got {self.chain}"
            raise GridError(msg)
        if self.size > MAX_POINTS:
            msg = f"{self.size} points: more than {MAX_POINTS}; split the sweep"
            raise GridError(msg)
        try:
            nominal = get_motion(self.motion)
        except MotionError as err:
            raise GridError(str(err)) from None
        for axis in self.axes:
            if axis.is_limit:
                pattern, _, kind = axis.key.rpartition(":")
                if kind not in JOINT_KINDS:
                    msg = f"axis {axis.key!r}: limit kind must be one of {list(JOINT_KINDS)}"
                    raise GridError(msg)
                try:
                    LimitScale(((pattern, kind, 1.0),))
                except ValueError as err:
                    raise GridError(f"axis {axis.key!r}: {err}") from None
                if any(v <= 0 for v in axis.values):
                    msg = f"axis {axis.key!r}: limit factors must be positive"
                    raise GridError(msg)
            elif axis.key == SPEED_KEY:
                if not isinstance(nominal, WalkMotion):
                    msg = f"axis {SPEED_KEY!r} applies to walks only, not to {self.motion} ({nominal.kind})"
                    raise GridError(msg)
                if "length_m" in self.base or any(a.key == "length_m" for a in self.axes):
                    msg = f"sweep {SPEED_KEY!r} or length_m, not both"
                    raise GridError(msg)
            elif axis.key not in nominal.parameters() or axis.key == "name":
                known = sorted(k for k in nominal.parameters() if k != "name")
                known += [SPEED_KEY] if isinstance(nominal, WalkMotion) else []
                msg = f"axis {axis.key!r}: {self.motion} has no such parameter; known: {known}, or PATTERN:KIND"
                raise GridError(msg)

    @property
    def shape(self) -> tuple[int, ...]:
        """Number of values per axis."""
        return tuple(len(a.values) for a in self.axes)

    @property
    def size(self) -> int:
        """Number of points."""
        return math.prod(self.shape)

    @property
    def keys(self) -> tuple[str, ...]:
        """The axis keys, in order."""
        return tuple(a.key for a in self.axes)

    def motion_of(self, point: SweepPoint) -> MotionSpec:
        """The validated motion of ``point`` (GridError for invalid parameters)."""
        nominal = get_motion(self.motion)
        try:
            return get_motion(self.motion, point.overrides(self.base, nominal))
        except MotionError as err:
            raise GridError(f"point {dict(point.values)}: {err}") from None

    def points(self) -> list[SweepPoint]:
        """Every point in C order, each validated, with its warm-start source."""
        positions = list(itertools.product(*(range(n) for n in self.shape)))
        provisional = [
            SweepPoint(i, pos, {a.key: a.values[j] for a, j in zip(self.axes, pos, strict=True)}, None)
            for i, pos in enumerate(positions)
        ]
        for point in provisional:
            self.motion_of(point)  # a bad parameter value stops the sweep before anything is solved
        along_limit = self.warm_start and self.axes[-1].is_limit  # a limit moves bounds only: the same knots
        chained = [along_limit and p.position[-1] % self.chain != 0 for p in provisional]
        return [
            SweepPoint(p.index, p.position, p.values, p.index - 1 if warm else None)
            for p, warm in zip(provisional, chained, strict=True)
        ]

    def to_json(self) -> dict[str, Any]:
        """What makes two sweeps the same (a checkpoint resumes only the same sweep)."""
        return {
            "motion": self.motion,
            "axes": [a.to_json() for a in self.axes],
            "base": dict(self.base),
            "chain": self.chain,
            "warm_start": self.warm_start,
        }


def describe_axes(axes: Sequence[Axis]) -> str:
    """``payload_kg_per_hand (3) x knee:velocity (4)``."""
    return " x ".join(f"{a.key} ({len(a.values)})" for a in axes)
