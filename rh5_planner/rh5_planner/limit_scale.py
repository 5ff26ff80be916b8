"""Scaled joint limits: the one home of limit kinds, joint-name patterns and the factors the planner plans with.

The design-improvement heuristic (:mod:`rh5_planner.design`) and the parameter sweeps widen chosen limits; the
planner (:func:`rh5_planner.ocp.build_robot`) and the limit analysis (:func:`rh5_planner.limit_analysis.analyse`)
read the same factors from here. Pure numpy: no Crocoddyl, no pinocchio.

* :class:`LimitScale` is (pattern, kind, factor) entries; :func:`match_joints` resolves a pattern;
* :func:`limit_factors` turns a :class:`LimitScale`, any :class:`LimitFactors` or a ``"PATTERN:KIND" -> factor``
  mapping into per-kind factors in JOINT_NAMES order.
"""

from __future__ import annotations

import fnmatch
import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any, Final, Protocol

import numpy as np
import numpy.typing as npt

from rh5_msgs_py.array_types import FloatArray
from rh5_msgs_py.names import JOINT_GROUPS, JOINT_INDEX, JOINT_NAMES, SUBMECHANISMS

__all__ = [
    "ACTUATOR_KINDS",
    "JOINT_KINDS",
    "MAPPED_ACTUATORS",
    "LimitFactors",
    "LimitScale",
    "LimitScaleLike",
    "limit_factors",
    "match_joints",
    "side_free_name",
]


JOINT_KINDS: Final = ("position", "velocity", "torque")
"""Joint-space limit kinds; also the kinds :class:`LimitScale` and :func:`limit_factors` scale."""
ACTUATOR_KINDS: Final = ("stroke", "actuator_velocity", "force")
"""Actuator-space limit kinds, checked through the mapper."""
_ACTUATOR_OF_JOINT_KIND: Final = {"position": "stroke", "velocity": "actuator_velocity", "torque": "force"}
MAPPED_ACTUATORS: Final[tuple[str, ...]] = tuple(a for s in SUBMECHANISMS if s.kind != "serial" for a in s.actuators)
"""Actuators of the parallel mechanisms and the head transmission: the ones with limits of their own."""
_MAPPED_JOINTS: Final[dict[str, tuple[str, ...]]] = {
    a: s.joints for s in SUBMECHANISMS if s.kind != "serial" for a in s.actuators
}


def side_free_name(joint: str) -> str:
    """The joint name without its side letter (``LLKnee`` -> ``Knee``, ``ARElbow`` -> ``Elbow``): one name for a
    symmetric pair, used to group plots and limit patterns."""
    for group in ("left_leg", "right_leg", "left_arm", "right_arm"):
        if joint in JOINT_GROUPS[group]:
            return joint[2:]
    return joint


def match_joints(pattern: str) -> tuple[str, ...]:
    """Joint names matching ``pattern`` (see :class:`LimitScale`), in JOINT_NAMES order."""
    p = pattern.lower()
    glob = p if any(c in p for c in "*?[") else f"*{p}*"
    return tuple(j for j in JOINT_NAMES if fnmatch.fnmatchcase(j.lower(), glob))


@dataclass(frozen=True)
class LimitScale:
    """Factors on joint limits: ``entries`` are (pattern, kind, factor); kind is one of :data:`JOINT_KINDS`.

    A pattern matches joint names case-insensitively, as a shell pattern (``LL*``) or, without wildcards, as a
    substring (``knee`` matches LLKnee and LRKnee). Where several entries match a joint and kind, the last wins.
    Position factors widen the range about its middle. In actuator space a factor applies to the matching limit
    kind (stroke, velocity, force) of every actuator of the joint's mechanism: a faster knee is a faster knee
    actuator.
    """

    entries: tuple[tuple[str, str, float], ...] = ()

    def __post_init__(self) -> None:
        clean = []
        for pattern, kind, factor in self.entries:
            if kind not in JOINT_KINDS:
                msg = f"unknown limit kind {kind!r}; known: {list(JOINT_KINDS)}"
                raise ValueError(msg)
            if not (isinstance(factor, int | float) and math.isfinite(factor) and factor > 0):
                msg = f"limit factor must be a positive number, got {factor!r}"
                raise ValueError(msg)
            if not match_joints(pattern):
                msg = f"pattern {pattern!r} matches no joint; joints: {list(JOINT_NAMES)}"
                raise ValueError(msg)
            clean.append((str(pattern), str(kind), float(factor)))
        object.__setattr__(self, "entries", tuple(clean))

    @classmethod
    def uniform(cls, limits: Iterable[tuple[str, str]], factor: float) -> LimitScale:
        """Every (pattern, kind) of ``limits`` scaled by ``factor``."""
        return cls(tuple((pattern, kind, factor) for pattern, kind in limits))

    def factors(self, kind: str) -> FloatArray:
        """(32,) factor of every joint (JOINT_NAMES order) for ``kind``."""
        out = np.ones(len(JOINT_NAMES))
        for pattern, entry_kind, factor in self.entries:
            if entry_kind == kind:
                out[[JOINT_INDEX[j] for j in match_joints(pattern)]] = factor
        return out

    def actuator_factors(self, kind: str) -> FloatArray:
        """(len(MAPPED_ACTUATORS),) factor per mapped actuator for actuator kind ``kind`` (largest of its joints)."""
        joint_kind = {v: k for k, v in _ACTUATOR_OF_JOINT_KIND.items()}[kind]
        joint_factors = self.factors(joint_kind)
        return np.array([max(joint_factors[JOINT_INDEX[j]] for j in _MAPPED_JOINTS[a]) for a in MAPPED_ACTUATORS])

    def describe(self) -> str:
        """Human-readable: ``knee velocity x3 (LLKnee, LRKnee)``; ``nominal limits`` when empty."""
        if not self.entries:
            return "nominal limits"
        return "; ".join(
            f"{pattern} {kind} x{factor:g} ({', '.join(match_joints(pattern))})"
            for pattern, kind, factor in self.entries
        )

    def to_json(self) -> list[list[Any]]:
        """JSON-able form (solver logs, reports)."""
        return [list(entry) for entry in self.entries]

    def __bool__(self) -> bool:
        """Whether any limit is scaled by a factor other than 1."""
        return any(factor != 1.0 for _, _, factor in self.entries)


class LimitFactors(Protocol):
    """Anything that gives a per-joint factor (JOINT_NAMES order) for a limit kind, such as :class:`LimitScale`."""

    def factors(self, kind: str) -> npt.ArrayLike:
        """(32,) factors in JOINT_NAMES order for ``kind`` ('position', 'velocity' or 'torque')."""
        ...


LimitScaleLike = LimitFactors | Mapping[str, float]
"""Scaled joint limits for planning: a :class:`LimitFactors` or a mapping ``"PATTERN:KIND" -> factor`` with KIND one
of :data:`JOINT_KINDS` and PATTERN a case-insensitive shell pattern (``LL*``) or substring (``knee``) of joint names
(``"*:velocity"`` scales every joint); later entries win where patterns overlap."""


def limit_factors(scale: LimitScaleLike | None) -> dict[str, FloatArray]:
    """Per limit kind, the (32,) factors in JOINT_NAMES order of ``scale`` (ones where it says nothing).

    ValueError for an unknown kind, a pattern matching no joint or a non-positive factor."""
    out = {kind: np.ones(len(JOINT_NAMES)) for kind in JOINT_KINDS}
    if scale is None:
        return out
    if not isinstance(scale, Mapping):
        for kind in JOINT_KINDS:
            out[kind] = np.asarray(scale.factors(kind), dtype=float).reshape(len(JOINT_NAMES))
    else:
        for key, factor in scale.items():
            pattern, _, kind = str(key).rpartition(":")
            if kind not in JOINT_KINDS or not pattern:
                msg = f"limit scale key {key!r} must be PATTERN:KIND with KIND one of {list(JOINT_KINDS)}"
                raise ValueError(msg)
            matched = set(match_joints(pattern))
            if not matched:
                msg = f"limit scale pattern {pattern!r} matches no joint"
                raise ValueError(msg)
            out[kind][np.array([name in matched for name in JOINT_NAMES])] = float(factor)
    for kind, values in out.items():
        if not (np.isfinite(values).all() and (values > 0).all()):
            msg = f"{kind} limit factors must be positive and finite, got {values}"
            raise ValueError(msg)
    return out
