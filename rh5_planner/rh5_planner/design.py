"""The design-improvement heuristic of the paper: scale critical joint limits step by step until the planner finds a
feasible solution (RH5 paper, "Vertical jumping": the 10 cm jump becomes feasible with the knee velocity limits x3).

:func:`improve_design` plans the motion with the chosen limits (``(pattern, kind)``, e.g. ``("knee", "velocity")``;
by default the limits the nominal solution violates) scaled by each factor in turn (1, 1.5, 2, 3, 4), checks every
solution against the limits it was planned with (:func:`rh5_planner.limit_analysis.analyse`) and stops at the first
feasible one (converged, every required limit kind held; a limit that binds only once others grew joins the scaled
set at the next step). With several limits it then lowers each one back as far as feasibility allows (one at a
time, smallest factor first), so the report names the limits that really had to grow. :func:`solve_with_limits` is
the single place that hands scaled limits to the planner.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, Final

import crocoddyl  # noqa: F401  (before pinocchio, design/crocoddyl_wheels.md)
import numpy as np

from .actuator_bounds import parallel_units
from .limit_analysis import LimitAnalysis, analyse, solver_log_of
from .limit_scale import ACTUATOR_KINDS, JOINT_KINDS, LimitScale, match_joints, side_free_name
from .motions import MotionSpec
from .ocp import PlanResult, SolverSettings, solve

__all__ = [
    "DEFAULT_FACTORS",
    "DesignResult",
    "DesignStep",
    "actuator_specs",
    "binding_limits",
    "critical_limits",
    "improve_design",
    "jump_height_task",
    "parse_limit",
    "sole_clearance",
    "solve_with_limits",
]

DEFAULT_FACTORS: Final = (1.0, 1.5, 2.0, 3.0, 4.0)
"""Scale factors tried in turn (the paper's result, knee velocity x3, is one of them)."""

SolveFunction = Callable[[MotionSpec, LimitScale, SolverSettings], PlanResult]
TaskCheck = Callable[[PlanResult], tuple[bool, str]]
"""Whether a plan does what the motion asks (e.g. the jump's height), and a short text saying how far it got."""
BINDING: Final = 0.85
"""Utilisation from which a limit counts as binding: where a plan holds every limit but misses its task, the
heuristic scales the limits it presses against (the actuator limits are bounded at 0.9-0.97 of Table I)."""
StepCallback = Callable[["DesignStep"], None]


def parse_limit(text: str) -> tuple[str, str]:
    """``"knee:velocity"`` -> ``("knee", "velocity")``; ValueError for a bad kind or a pattern matching no joint."""
    pattern, sep, kind = text.rpartition(":")
    if not sep or not pattern:
        msg = f"limit {text!r} must be PATTERN:KIND with KIND one of {list(JOINT_KINDS)} (e.g. knee:velocity)"
        raise ValueError(msg)
    LimitScale(((pattern, kind, 1.0),))  # validates kind and pattern
    return pattern, kind


# --------------------------------------------------------------------------------------------------
# planning with scaled limits


def solve_with_limits(motion: MotionSpec, scale: LimitScale, settings: SolverSettings) -> PlanResult:
    """Plan ``motion`` with the joint limits scaled by ``scale`` (joint-limit barrier and Box-FDDP torque box follow
    them; :func:`rh5_planner.ocp.solve`'s ``limit_scale``). The one place the heuristic reaches the planner."""
    return solve(motion, settings, limit_scale=scale if scale else None)


# --------------------------------------------------------------------------------------------------
# the heuristic


@dataclass(frozen=True, eq=False)
class DesignStep:
    """One re-plan: the limits it used, whether it converged and met every required limit, what it violated."""

    scale: LimitScale
    converged: bool
    feasible: bool
    violations: dict[str, tuple[str, ...]]
    iterations: int
    seconds: float
    analysis: LimitAnalysis
    task: str = ""
    """What the task check said (empty without one), e.g. ``soles 9.7 of 10.0 cm up``."""

    def describe(self) -> str:
        """One line: limits, verdict, violations."""
        verdict = "feasible" if self.feasible else ("infeasible" if self.converged else "not converged")
        viol = "; ".join(f"{k}: {', '.join(v)}" for k, v in self.violations.items()) or "none"
        task = f"; task: {self.task}" if self.task else ""
        return (
            f"{self.scale.describe()}: {verdict} ({self.iterations} iterations, {self.seconds:.1f} s); "
            f"violations: {viol}{task}"
        )


@dataclass(frozen=True, eq=False)
class DesignResult:
    """Outcome of :func:`improve_design`: every step and the smallest scaling found feasible (None: none was)."""

    motion: str
    limits: tuple[tuple[str, str], ...]
    factors: tuple[float, ...]
    required: tuple[str, ...]
    steps: list[DesignStep] = field(default_factory=list)
    solution: LimitScale | None = None

    @property
    def feasible(self) -> bool:
        """Whether some scaling made the motion feasible."""
        return self.solution is not None

    def scaled_limits(self) -> list[tuple[str, str, float]]:
        """The limits of the solution that had to grow, with their factors (empty: none had to)."""
        if self.solution is None:
            return []
        return [entry for entry in self.solution.entries if entry[2] != 1.0]

    def report(self) -> str:
        """Multi-line summary: the steps, then the verdict."""
        lines = [
            f"Design-improvement heuristic for {self.motion}",
            f"  limits scaled: {', '.join(f'{p}:{k}' for p, k in self.limits) or '(none: nominal solution checked)'}",
            f"  factors: {', '.join(f'{f:g}' for f in self.factors)}; required: {', '.join(self.required)}",
        ]
        lines += [f"  step {i + 1}: {step.describe()}" for i, step in enumerate(self.steps)]
        if self.solution is None:
            lines.append("Result: no feasible solution with these limits and factors.")
        elif not self.scaled_limits():
            lines.append("Result: feasible with the nominal limits (no design change needed).")
        else:
            needed = ", ".join(f"{p} {k} x{f:g}" for p, k, f in self.scaled_limits())
            lines.append(f"Result: feasible after scaling {needed} (joint space, the paper's form).")
            specs = actuator_specs(self.scaled_limits())
            if specs:
                lines.append(f"Actuator specification (Table I): {'; '.join(specs)}.")
        return "\n".join(lines)


_JOINT_KIND_OF_ACTUATOR: Final = {"stroke": "position", "actuator_velocity": "velocity", "force": "torque"}
_UNIT_TEXT: Final = {"position": ("stroke", "mm", 1e3), "velocity": ("", "mm/s", 1e3), "torque": ("", "N", 1.0)}


def critical_limits(analysis: LimitAnalysis, required: Sequence[str] = JOINT_KINDS) -> tuple[tuple[str, str], ...]:
    """The (pattern, kind) the solution violates, of the kinds in ``required``; a symmetric pair of joints becomes one
    pattern (``LLKnee``, ``LRKnee`` -> ``Knee``) so both sides scale together. A violated actuator kind (stroke,
    actuator_velocity, force) names the joints of its mechanism with the matching joint kind (position, velocity,
    torque): their factor scales the mechanism's actuators (LimitScale.actuator_factors)."""
    out: list[tuple[str, str]] = []
    for kind in JOINT_KINDS:
        if kind not in required:
            continue
        for joint in analysis.joint[kind].violating:
            entry = (side_free_name(joint), kind)
            if entry not in out:
                out.append(entry)
    units = {a: m for m in parallel_units() for a in m.actuators}
    for kind in ACTUATOR_KINDS:
        if kind not in required or analysis.actuator is None:
            continue
        for actuator in analysis.actuator[kind].violating:
            unit = units.get(actuator)
            joints = unit.joints if unit is not None else ()
            for joint in joints:
                entry = (side_free_name(joint), _JOINT_KIND_OF_ACTUATOR[kind])
                if entry not in out:
                    out.append(entry)
    return tuple(out)


def binding_limits(
    analysis: LimitAnalysis, required: Sequence[str] = JOINT_KINDS, threshold: float = BINDING
) -> tuple[tuple[str, str], ...]:
    """As :func:`critical_limits`, for the limits used to at least ``threshold`` instead of exceeded."""
    loose = dataclasses.replace(
        analysis,
        joint={k: dataclasses.replace(u, utilisation=u.utilisation / threshold) for k, u in analysis.joint.items()},
        actuator=None
        if analysis.actuator is None
        else {k: dataclasses.replace(u, utilisation=u.utilisation / threshold) for k, u in analysis.actuator.items()},
    )
    return critical_limits(loose, required)


def jump_height_task(fraction: float = 0.9) -> TaskCheck:
    """The task of a jump: its soles clear at least ``fraction`` of ``height_m`` in flight."""

    def check(plan: PlanResult) -> tuple[bool, str]:
        height = float(getattr(plan.motion, "height_m", 0.0))
        clearance = sole_clearance(plan)
        return clearance >= fraction * height, f"soles {100 * clearance:.1f} of {100 * height:.1f} cm up"

    return check


def sole_clearance(plan: PlanResult) -> float:
    """Highest sole height over the knots without contact, above the initial soles [m] (0 without flight)."""
    import pinocchio as pin  # noqa: PLC0415

    model = plan.robot.model
    data = model.createData()
    flight = ~np.asarray(plan.contact_phases).any(axis=1)
    if not flight.any():
        return 0.0
    heights = []
    for x in np.asarray(plan.xs)[[*np.flatnonzero(flight).tolist(), 0]]:
        pin.framesForwardKinematics(model, data, x[: model.nq])
        heights.append(max(data.oMf[fid].translation[2] for fid in plan.robot.foot_ids.values()))
    return float(max(heights[:-1]) - heights[-1])


def actuator_specs(entries: Sequence[tuple[str, str, float]]) -> list[str]:
    """What scaled joint limits (pattern, kind, factor) ask of the linear actuators (Table I), one text per actuator
    type: ``Knee actuator (LLKnee_Act1, LRKnee_Act1) 140 -> 420 mm/s``. A mechanism scales by the largest factor of
    its joints (LimitScale.actuator_factors); joints without a linear actuator give nothing."""
    factor_of: dict[str, dict[str, float]] = {}
    for pattern, kind, factor in entries:
        for joint in match_joints(pattern):
            slot = factor_of.setdefault(kind, {})
            slot[joint] = factor
    out: list[str] = []
    for kind, per_joint in factor_of.items():
        groups: dict[str, tuple[list[str], float, float]] = {}
        for unit in parallel_units():
            factor = max((per_joint.get(j, 1.0) for j in unit.joints), default=1.0)
            if factor == 1.0:
                continue
            label = _unit_label(unit.name)
            names, _, limit = groups.get(label, ([], factor, _unit_limit(unit, kind)))
            groups[label] = ([*names, *unit.actuators], factor, limit)
        what, unit_text, to_text = _UNIT_TEXT[kind]
        for label, (names, factor, limit) in groups.items():
            if kind == "position":
                lo, hi = limit
                mid, half = 0.5 * (lo + hi), 0.5 * (hi - lo)
                old = f"{lo * to_text:.0f}-{hi * to_text:.0f}"
                new = f"{(mid - factor * half) * to_text:.0f}-{(mid + factor * half) * to_text:.0f}"
            else:
                old, new = f"{limit * to_text:.0f}", f"{limit * factor * to_text:.0f}"
            prefix = f"{label} actuator{' ' + what if what else ''} ({', '.join(names)})"
            out.append(f"{prefix} {old} -> {new} {unit_text} (x{factor:g})")
    return out


def _unit_label(name: str) -> str:
    """A mechanism's name without its side (``LLKnee`` -> ``Knee``, ``ARWrist`` -> ``Wrist``)."""
    return name[2:] if name[:2] in ("LL", "LR", "AL", "AR") and len(name) > 2 else name


def _unit_limit(unit: Any, kind: str) -> Any:
    limits = unit.limits
    if kind == "position":
        return (float(limits.length_min[0]), float(limits.length_max[0]))
    return float(limits.velocity_max[0] if kind == "velocity" else limits.force_max[0])


def improve_design(
    motion: MotionSpec,
    limits: Sequence[tuple[str, str]] | None = None,
    *,
    factors: Sequence[float] = DEFAULT_FACTORS,
    settings: SolverSettings | None = None,
    required: Sequence[str] = JOINT_KINDS,
    minimise: bool = True,
    solve_function: SolveFunction = solve_with_limits,
    on_step: StepCallback | None = None,
    task: TaskCheck | None = None,
) -> DesignResult:
    """Scale ``limits`` by ``factors`` in turn and re-plan until the solution is feasible.

    ``limits`` None takes the limits the nominal solution violates (:func:`critical_limits`) and adds those a
    scaled solution newly violates (raising the knee limits lets the body pitch bind). ``required`` are
    the limit columns a feasible solution must hold (joint kinds, and optionally ``stroke``,
    ``actuator_velocity``, ``force``, ``cop``, ``friction``), always checked against the scaled limits.
    ``minimise`` lowers each limit back afterwards where feasibility allows. ``solve_function`` plans one
    scaling (default :func:`solve_with_limits`; tests pass a stand-in). ``task`` also requires the plan to do what
    the motion asks (:func:`jump_height_task`); a plan that holds every limit but misses it scales the limits it
    presses against (utilisation >= :data:`BINDING`).
    """
    settings = settings or SolverSettings()
    ordered = tuple(sorted({float(f) for f in factors}))
    if not ordered or ordered[0] <= 0:
        msg = f"factors must be positive numbers, got {list(factors)}"
        raise ValueError(msg)
    result_steps: list[DesignStep] = []

    def attempt(scale: LimitScale) -> DesignStep:
        start = time.perf_counter()
        plan = solve_function(motion, scale, settings)
        analysis = analyse(plan, scale=scale)
        converged = bool(analysis.converged)
        done, how = task(plan) if task is not None else (True, "")
        log = solver_log_of(plan)  # a plan, or a trajectory file (analyse takes both)
        step = DesignStep(
            scale=scale,
            converged=converged,
            feasible=converged and done and analysis.feasible(tuple(required)),
            violations=analysis.violations(),
            iterations=log.iterations if log is not None else 0,
            seconds=time.perf_counter() - start,
            analysis=analysis,
            task=how,
        )
        result_steps.append(step)
        if on_step is not None:
            on_step(step)
        return step

    chosen: tuple[tuple[str, str], ...]
    if limits is None:
        nominal = attempt(LimitScale())
        if nominal.feasible:
            return DesignResult(motion.name, (), ordered, tuple(required), result_steps, LimitScale())
        chosen = critical_limits(nominal.analysis, required) or binding_limits(nominal.analysis, required)
        candidates = [f for f in ordered if f != 1.0]
    else:
        chosen = tuple((str(p), str(k)) for p, k in limits)
        candidates = list(ordered)
    result = DesignResult(motion.name, chosen, ordered, tuple(required), result_steps)
    if not chosen:
        return result  # infeasible, but not through any joint limit (e.g. not converged, CoP)
    found: dict[tuple[str, str], float] | None = None
    for factor in candidates:
        step = attempt(LimitScale.uniform(chosen, factor))
        if step.feasible:
            found = dict.fromkeys(chosen, factor)
            break
        if limits is None:  # a limit that only binds once others grew joins the set (the jump's body pitch)
            chosen += tuple(c for c in critical_limits(step.analysis, required) if c not in chosen)
    result = dataclasses.replace(result, limits=chosen)
    if found is None:
        return result
    if minimise and len(chosen) > 1:
        for limit in chosen:
            for lower in (f for f in ordered if f < found[limit]):
                trial = {**found, limit: lower}
                if attempt(_scale_of(trial)).feasible:
                    found = trial
                    break
    return dataclasses.replace(result, solution=_scale_of(found))


def _scale_of(factors: dict[tuple[str, str], float]) -> LimitScale:
    return LimitScale(tuple((p, k, f) for (p, k), f in factors.items()))
