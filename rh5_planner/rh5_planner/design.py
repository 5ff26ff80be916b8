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
from typing import Final

from . import problem
from .limit_analysis import JOINT_KINDS, LimitAnalysis, LimitScale, analyse, side_free_name
from .motions import MotionSpec
from .problem import PlanResult, SolverSettings

__all__ = [
    "DEFAULT_FACTORS",
    "DesignResult",
    "DesignStep",
    "critical_limits",
    "improve_design",
    "parse_limit",
    "solve_with_limits",
]

DEFAULT_FACTORS: Final = (1.0, 1.5, 2.0, 3.0, 4.0)
"""Scale factors tried in turn (the paper's result, knee velocity x3, is one of them)."""

SolveFunction = Callable[[MotionSpec, LimitScale, SolverSettings], PlanResult]
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
    them; problem.solve's ``limit_scale``). The one place the heuristic reaches the planner."""
    return problem.solve(motion, settings, limit_scale=scale if scale else None)


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

    def describe(self) -> str:
        """One line: limits, verdict, violations."""
        verdict = "feasible" if self.feasible else ("infeasible" if self.converged else "not converged")
        viol = "; ".join(f"{k}: {', '.join(v)}" for k, v in self.violations.items()) or "none"
        return (
            f"{self.scale.describe()}: {verdict} ({self.iterations} iterations, {self.seconds:.1f} s); "
            f"violations: {viol}"
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
            lines.append(f"Result: feasible after scaling {needed}.")
        return "\n".join(lines)


def critical_limits(analysis: LimitAnalysis, required: Sequence[str] = JOINT_KINDS) -> tuple[tuple[str, str], ...]:
    """The (pattern, kind) the solution violates, of the joint-space kinds in ``required``; a symmetric pair of
    joints becomes one pattern (``LLKnee``, ``LRKnee`` -> ``Knee``) so both sides scale together."""
    out: list[tuple[str, str]] = []
    for kind in JOINT_KINDS:
        if kind not in required:
            continue
        for joint in analysis.joint[kind].violating:
            entry = (side_free_name(joint), kind)
            if entry not in out:
                out.append(entry)
    return tuple(out)


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
) -> DesignResult:
    """Scale ``limits`` by ``factors`` in turn and re-plan until the solution is feasible.

    ``limits`` None takes the limits the nominal solution violates (:func:`critical_limits`) and adds those a
    scaled solution newly violates (raising the knee limits lets the body pitch bind). ``required`` are
    the limit columns a feasible solution must hold (joint kinds, and optionally ``stroke``,
    ``actuator_velocity``, ``force``, ``cop``, ``friction``), always checked against the scaled limits.
    ``minimise`` lowers each limit back afterwards where feasibility allows. ``solve_function`` plans one
    scaling (default :func:`solve_with_limits`; tests pass a stand-in).
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
        step = DesignStep(
            scale=scale,
            converged=converged,
            feasible=converged and analysis.feasible(tuple(required)),
            violations=analysis.violations(),
            iterations=int(plan.solver_log.get("iterations", 0)),
            seconds=time.perf_counter() - start,
            analysis=analysis,
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
        chosen = critical_limits(nominal.analysis, required)
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
