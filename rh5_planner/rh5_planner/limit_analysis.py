"""Limit analysis of a planned motion: how close it comes to every joint, actuator and contact limit, and where it
exceeds one.

For one trajectory (a :class:`~rh5_msgs_py.trajectory_file.TrajectoryData` or a
:class:`~rh5_planner.ocp.PlanResult`) :func:`analyse` computes, per joint, the utilisation (peak |value| /
limit; for positions the distance from the middle of the range over its half-width, 1 at either end) and the
number of knots over the limit of

* the joint-space limits of ``joint_limits()`` (position range, velocity and torque, the upper ends of the
  paper's configuration-dependent ranges, as the planner uses them), and
* the actuator-space limits (stroke, velocity, force) of the joints driven by parallel mechanisms or the head
  transmission, through the HyRoDyn-style mapper: the configuration-dependent limits the paper's table could not
  show. Pass-through rotary joints are left out there (their actuator limits are the joint limits);

and the contact stability: the fraction of contact knots whose CoP lies in the allowed rectangle (costs.yaml
``cop_fraction`` of the 200 x 80 mm sole) and whose contact force lies in the friction cone (costs.yaml ``mu``,
|f_t| <= mu f_z with f_z > 0).

The paper's table of such analyses is :mod:`rh5_planner.feasibility`; the scaled limits a solution is checked against
(the design-improvement heuristic of :mod:`rh5_planner.design` checks it against the limits it was planned with) are
:class:`rh5_planner.limit_scale.LimitScale`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from rh5_hyrodyn_mapper.kinematics.base import KinematicsError
from rh5_hyrodyn_mapper.mapping import robot_mapper
from rh5_hyrodyn_mapper.model import JointLimits, joint_limits
from rh5_msgs_py.array_types import FloatArray, IntArray
from rh5_msgs_py.names import ACTUATOR_INDEX, JOINT_NAMES
from rh5_msgs_py.trajectory_file import TrajectoryData

from .cost_config import load_cost_config
from .feasibility import COLUMNS, FeasibilityTable
from .feet import FOOT_SIZE_M
from .limit_scale import ACTUATOR_KINDS, JOINT_KINDS, MAPPED_ACTUATORS, LimitScale
from .solver_log import SolverLog

__all__ = [
    "ContactCheck",
    "LimitAnalysis",
    "LimitUsage",
    "PlannedResult",
    "analyse",
    "contact_check",
    "solver_log_of",
]


class PlannedResult(Protocol):
    """What the analysis reads of a planner result (:class:`rh5_planner.ocp.PlanResult`): its trajectory and
    its solver log. A protocol, so that this module does not import the planner that imports it."""

    @property
    def solver_log(self) -> SolverLog:
        """What the solve did."""
        ...

    def to_trajectory_data(self) -> TrajectoryData:
        """The trajectory file content of the plan."""
        ...


# --------------------------------------------------------------------------------------------------
# results


@dataclass(frozen=True, eq=False)
class LimitUsage:
    """One limit kind for a set of joints or actuators: peak utilisation (1 = at the limit), knots over it."""

    kind: str
    names: tuple[str, ...]
    utilisation: FloatArray
    """(N, len(names)) |value - middle| / half-width at every knot."""
    tolerance: float = 1e-6

    @property
    def peak(self) -> FloatArray:
        """(len(names),) highest utilisation."""
        return self.utilisation.max(axis=0, initial=0.0)

    @property
    def counts(self) -> IntArray:
        """(len(names),) number of knots over the limit (utilisation > 1 + tolerance)."""
        return np.count_nonzero(self.utilisation > 1.0 + self.tolerance, axis=0).astype(np.int64)

    @property
    def violating(self) -> tuple[str, ...]:
        """Names whose limit is exceeded at some knot."""
        return tuple(n for n, c in zip(self.names, self.counts, strict=True) if c > 0)

    @property
    def ok(self) -> bool:
        """Whether the limit holds for every name at every knot."""
        return not self.violating

    def worst(self, count: int = 3) -> list[tuple[str, float]]:
        """The ``count`` names of highest peak utilisation, highest first."""
        order = np.argsort(-self.peak)[:count]
        return [(self.names[i], float(self.peak[i])) for i in order]


@dataclass(frozen=True)
class ContactCheck:
    """Contact stability over the contact knots (counted per foot and knot)."""

    contact_knots: int
    cop_outside: int
    friction_outside: int
    cop_fraction: float
    mu: float

    @property
    def cop_inside_ratio(self) -> float:
        """Fraction of foot-knots in contact with the CoP inside the allowed rectangle (1.0 without contact)."""
        return 1.0 - self.cop_outside / self.contact_knots if self.contact_knots else 1.0

    @property
    def friction_inside_ratio(self) -> float:
        """Fraction of foot-knots in contact whose force lies in the friction cone (1.0 without contact)."""
        return 1.0 - self.friction_outside / self.contact_knots if self.contact_knots else 1.0


@dataclass(frozen=True, eq=False)
class LimitAnalysis:
    """Every limit of one trajectory: joint space, actuator space (None if the mapping failed), contacts."""

    motion: str
    converged: bool | None
    joint: Mapping[str, LimitUsage]
    actuator: Mapping[str, LimitUsage] | None
    contact: ContactCheck
    scale: LimitScale = field(default_factory=LimitScale)
    actuator_error: str = ""
    actuator_limited: bool = False
    """Whether the plan was made with the actuator limits in the problem (its solver log says which)."""

    def count(self, column: str) -> int | None:
        """The table entry of ``column`` (see :data:`COLUMNS`): 0 = holds; None = not available."""
        if column in JOINT_KINDS:
            return len(self.joint[column].violating)
        if column in ACTUATOR_KINDS:
            return None if self.actuator is None else len(self.actuator[column].violating)
        if column == "cop":
            return self.contact.cop_outside
        if column == "friction":
            return self.contact.friction_outside
        msg = f"unknown column {column!r}; known: {list(COLUMNS)}"
        raise KeyError(msg)

    def feasible(self, columns: Sequence[str] = JOINT_KINDS) -> bool:
        """Whether every limit of ``columns`` holds (an unavailable column counts as failed)."""
        return all(self.count(c) == 0 for c in columns)

    def violations(self) -> dict[str, tuple[str, ...]]:
        """The violating joints/actuators per limit kind (kinds without violations left out)."""
        usages = {**self.joint, **(self.actuator or {})}
        return {kind: usage.violating for kind, usage in usages.items() if usage.violating}

    def to_markdown(self) -> str:
        """Per-joint and per-actuator peak utilisation (%) and knots over the limit, plus the contact summary."""
        lines = [f"# Limits of {self.motion}", ""]
        if self.scale:
            lines += [f"Checked against scaled limits: {self.scale.describe()}.", ""]
        status = {True: "converged", False: "NOT converged", None: "convergence unknown"}[self.converged]
        lines += [
            f"Solver: {status}. Utilisation = peak |value| / limit (positions: from mid-range), in %; "
            "in brackets the number of knots over the limit.",
            "",
        ]
        lines += ["## Feasibility", "", *FeasibilityTable([self]).to_markdown().splitlines(), ""]
        lines += ["## Joint space", "", "| joint | position | velocity | torque |", "|---|---:|---:|---:|"]
        usage = [self.joint[k] for k in JOINT_KINDS]
        for i, name in enumerate(JOINT_NAMES):
            lines.append(f"| {name} | " + " | ".join(_cell(u, i) for u in usage) + " |")
        lines += ["", "## Actuator space (parallel mechanisms and head transmission)", ""]
        if self.actuator is None:
            lines.append(f"Not available: {self.actuator_error}")
        else:
            lines += ["| actuator | stroke | velocity | force |", "|---|---:|---:|---:|"]
            usage = [self.actuator[k] for k in ACTUATOR_KINDS]
            for i, name in enumerate(MAPPED_ACTUATORS):
                lines.append(f"| {name} | " + " | ".join(_cell(u, i) for u in usage) + " |")
        c = self.contact
        lines += [
            "",
            "## Contact stability",
            "",
            f"- contact foot-knots: {c.contact_knots}",
            f"- CoP inside the {100 * c.cop_fraction:g} % sole rectangle: {100 * c.cop_inside_ratio:.1f} % "
            f"({c.cop_outside} outside)",
            f"- inside the friction cone (mu = {c.mu:g}): {100 * c.friction_inside_ratio:.1f} % "
            f"({c.friction_outside} outside)",
            "",
        ]
        return "\n".join(lines)


def _cell(usage: LimitUsage, i: int) -> str:
    text = f"{100 * usage.peak[i]:.0f}"
    count = int(usage.counts[i])
    return f"**{text} ({count})**" if count else text


# --------------------------------------------------------------------------------------------------
# analysis


def _scaled_joint_limits(limits: JointLimits, scale: LimitScale) -> dict[str, tuple[FloatArray, FloatArray]]:
    """Per joint kind, (middle, half-width) of the allowed interval after scaling (symmetric kinds: middle 0)."""
    lo, hi = np.asarray(limits.position_lower), np.asarray(limits.position_upper)
    zero = np.zeros(len(JOINT_NAMES))
    return {
        "position": (0.5 * (lo + hi), 0.5 * (hi - lo) * scale.factors("position")),
        "velocity": (zero, np.asarray(limits.velocity_max) * scale.factors("velocity")),
        "torque": (zero, np.asarray(limits.torque_max) * scale.factors("torque")),
    }


def solver_log_of(source: TrajectoryData | PlannedResult) -> SolverLog | None:
    """The solver log of a plan or of a trajectory file (None: a file without one)."""
    if isinstance(source, TrajectoryData):
        return SolverLog.from_dict(source.solver_log) if source.solver_log else None
    return source.solver_log


def _trajectory(source: TrajectoryData | PlannedResult) -> tuple[TrajectoryData, SolverLog | None]:
    """The trajectory and its solver log (None: a file without one)."""
    data = source if isinstance(source, TrajectoryData) else source.to_trajectory_data()
    return data, solver_log_of(source)


def _usage(
    kind: str, names: tuple[str, ...], values: FloatArray, bounds: tuple[FloatArray, FloatArray], tolerance: float
) -> LimitUsage:
    """Utilisation of ``values`` against ``bounds`` = (middle, half-width) of the allowed interval."""
    middle, half = bounds
    utilisation = np.abs(np.atleast_2d(values) - middle) / half
    return LimitUsage(kind, names, utilisation, tolerance)


def contact_check(
    data: TrajectoryData,
    *,
    cop_fraction: float | None = None,
    mu: float | None = None,
    cop_tolerance_m: float = 1e-3,
    friction_tolerance_n: float = 1.0,
) -> ContactCheck:
    """CoP and friction cone at every contact knot of every foot.

    Defaults from costs.yaml (``cop_fraction``, ``mu``: the unshrunk region, not the optimiser's margin). The
    tolerances are the acceptance tolerances of the planner's tests: the soft barrier may overshoot by a little.
    A contact knot without positive normal force fails both checks.
    """
    if cop_fraction is None or mu is None:
        cs = load_cost_config()["contact_stability"]
        cop_fraction = float(cs["cop_fraction"]) if cop_fraction is None else cop_fraction
        mu = float(cs["mu"]) if mu is None else mu
    contact = np.asarray(data.contact_phases, dtype=bool)
    wrench = np.asarray(data.contact_wrenches)[contact]  # (K, 6)
    cop = np.asarray(data.cop)[contact]  # (K, 2)
    half = 0.5 * cop_fraction * np.array(FOOT_SIZE_M) + cop_tolerance_m
    fz = wrench[:, 2]
    with np.errstate(invalid="ignore"):
        cop_in = (fz > 0) & np.all(np.abs(cop) <= half, axis=1)  # NaN CoP compares False
    friction_in = (fz > 0) & (np.linalg.norm(wrench[:, :2], axis=1) <= mu * fz + friction_tolerance_n)
    k = int(contact.sum())
    return ContactCheck(k, k - int(cop_in.sum()), k - int(friction_in.sum()), float(cop_fraction), float(mu))


def analyse(
    source: TrajectoryData | PlannedResult,
    *,
    scale: LimitScale | None = None,
    tolerance: float = 1e-6,
    cop_fraction: float | None = None,
    mu: float | None = None,
) -> LimitAnalysis:
    """All limits of a planned trajectory, against the (optionally scaled) joint and actuator limits.

    ``tolerance`` is relative: a value counts as a violation above (1 + tolerance) x limit. Torques are the
    N-1 controls (row k acts from knot k on) and are mapped to actuator forces at the configuration of knot k.
    """
    data, log = _trajectory(source)
    scale = scale or LimitScale()
    q, v = data.joint_positions(), data.joint_velocities()
    tau = np.asarray(data.controls)
    bounds = _scaled_joint_limits(joint_limits(), scale)
    values = {"position": q, "velocity": v, "torque": tau}
    joint = {k: _usage(k, JOINT_NAMES, values[k], bounds[k], tolerance) for k in JOINT_KINDS}
    actuator, error = _actuator_usage(q, v, tau, scale, tolerance)
    contact = contact_check(data, cop_fraction=cop_fraction, mu=mu)
    name = str(data.motion.get("name", "?"))
    converged = None if log is None else log.converged
    limited = log is not None and bool(log.actuator_limits.enforced)
    return LimitAnalysis(name, converged, joint, actuator, contact, scale, error, limited)


def _actuator_usage(
    q: FloatArray, v: FloatArray, tau: FloatArray, scale: LimitScale, tolerance: float
) -> tuple[dict[str, LimitUsage] | None, str]:
    """Stroke, velocity and force utilisation of the mapped actuators (None and the reason if mapping fails)."""
    mapper = robot_mapper()
    idx = np.array([ACTUATOR_INDEX[a] for a in MAPPED_ACTUATORS])
    try:
        kinematic = mapper.to_actuators(q, v)
        forces = mapper.to_actuators(q[: len(tau)], None, None, tau).effort
    except (KinematicsError, ValueError) as err:
        return None, f"{type(err).__name__}: {err}"
    lo, hi = mapper.limits.length_min[idx], mapper.limits.length_max[idx]
    zero = np.zeros(idx.size)
    bounds = {
        "stroke": (0.5 * (lo + hi), 0.5 * (hi - lo)),
        "actuator_velocity": (zero, mapper.limits.velocity_max[idx]),
        "force": (zero, mapper.limits.force_max[idx]),
    }
    values = {"stroke": kinematic.position, "actuator_velocity": kinematic.velocity, "force": forces}
    out = {
        kind: _usage(
            kind,
            MAPPED_ACTUATORS,
            np.asarray(values[kind])[:, idx],
            (bounds[kind][0], bounds[kind][1] * scale.actuator_factors(kind)),
            tolerance,
        )
        for kind in ACTUATOR_KINDS
    }
    return out, ""
