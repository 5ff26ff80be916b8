"""Solving a motion with Box-FDDP: continuation over the cost weights, a warm start from a neighbour's solution, and
the exact actuator-limit check that tightens the bounds and solves again.

* Continuation (costs.yaml ``continuation``): the problem is first solved with the contact wrench cone off, then
  at 1 % and 10 % weight, each stage warm-starting the next (``SolverSettings`` regularisations); then
  with every weight as configured (same optimum, a third of the iterations for the walk and the balancing
  experiments). Convergence: Box-FDDP's gradient test (``stop_threshold``) or the cost unchanged to
  ``cost_tolerance`` over ``stall_iterations`` full steps on a feasible trajectory.
* Actuator limits: after the final stage an exact check at the knots and along the 1 kHz interpolation tightens
  the bounds where a limit is still exceeded and solves again; the solver log's ``actuator_limits`` says what was
  enforced and the peaks reached.

``solve(motion, settings)`` builds, solves and returns a :class:`~rh5_planner.ocp.result.PlanResult`.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Mapping, Sequence
from typing import Any, Final

import crocoddyl
import numpy as np

from rh5_msgs_py.array_types import FloatArray
from rh5_msgs_py.names import JOINT_NAMES

from ..cost_config import load_cost_config, motion_config
from ..limit_scale import LimitScaleLike, limit_factors
from ..motions import MotionSpec
from ..solver_log import ActuatorLimitLog, RefineRound, SolverLog, StageLog
from .builder import BuiltProblem, build_problem
from .result import PlanResult, extract_result
from .robot import robot_mass
from .settings import ProgressCallback, SolverSettings

__all__ = ["solve"]


_TERM_OF_COST: Final = {
    "wrench_cone": "contact_stability",
    "friction_cone": "contact_stability",
    "cop": "contact_stability",
    "joint_limits": "joint_limits",
    "foot": "foot",
    "com": "com",
    "posture": "posture",
    "torque": "torque",
}
"""Cost-name prefix in the action models -> costs.yaml section (continuation stages scale by section)."""


def _cost_sums(problem: crocoddyl.ShootingProblem) -> list[crocoddyl.CostModelSum]:
    models = [*problem.runningModels, problem.terminalModel]
    return [m.differential.costs if hasattr(m, "differential") else m.costs for m in models]


def _scale_costs(
    sums: Sequence[crocoddyl.CostModelSum], base: Sequence[Mapping[str, float]], scale: Mapping[str, float]
) -> None:
    """Set every cost's weight to its configured weight times ``scale[section]`` (0 switches the cost off)."""
    for costs, weights in zip(sums, base, strict=True):
        for name, weight in weights.items():
            section = next((v for k, v in _TERM_OF_COST.items() if name.startswith(k)), None)
            factor = float(scale.get(section, 1.0)) if section else 1.0
            costs.changeCostStatus(name, factor > 0.0)
            costs.costs[name].weight = weight * factor if factor > 0.0 else weight


class _ProgressCallback(crocoddyl.CallbackAbstract):  # type: ignore[misc]
    """Forwards (iteration, cost, stop) of every Box-FDDP iteration to a Python callable (iterations counted over
    all stages) and ends the solve once the cost stalls on a feasible trajectory (SolverSettings.cost_tolerance)."""

    def __init__(self, report: ProgressCallback | None, offset: int, tolerance: float, window: int) -> None:
        crocoddyl.CallbackAbstract.__init__(self)
        self._report, self._offset, self._tolerance, self._window = report, offset, tolerance, window
        self._costs: list[float] = []
        self.stalled = False

    @property
    def iterations(self) -> int:
        """Iterations this stage ran (Box-FDDP calls its callbacks once per iteration; ``solver.iter`` is the
        0-based index of the last one when it converges, so it counts one short)."""
        return len(self._costs)

    def __call__(self, solver: crocoddyl.SolverAbstract) -> None:
        cost = float(solver.cost)
        if self._report is not None:
            self._report(self._offset + len(self._costs) + 1, cost, float(solver.stop))
        # a plateau of tiny line-search steps is not convergence: only full steps (the Newton step of the local
        # quadratic model) that no longer change the cost count
        self._costs.append(cost if solver.isFeasible and solver.stepLength >= 1.0 else math.nan)
        if self._tolerance > 0 and len(self._costs) > self._window:
            recent = self._costs[-1 - self._window :]
            if all(math.isfinite(c) for c in recent) and max(recent) - min(recent) <= self._tolerance * max(
                1.0, abs(cost)
            ):
                self.stalled = True
                solver.th_stop = math.inf  # Box-FDDP returns after this callback: the next test of stop passes


def solve(
    motion: MotionSpec,
    settings: SolverSettings | None = None,
    *,
    limit_scale: LimitScaleLike | None = None,
    guess: tuple[Sequence[FloatArray], Sequence[FloatArray]] | None = None,
) -> PlanResult:
    """Build and solve ``motion`` with Box-FDDP; returns the knots, wrenches, CoPs and the solver log.

    ``limit_scale`` plans with scaled joint limits (see :data:`LimitScaleLike`); ``PlanResult.robot`` then
    carries the scaled limits, and the solver log the factors that differ from 1. ``guess`` = (xs, us) warm-starts
    the solve from another solution of the same knot sequence (a neighbour in a parameter sweep: ``PlanResult.xs_all``
    and ``us_all``): the continuation stages are skipped, since they would lead away from an optimum of the full
    problem, and the final stage starts from it with ``stage_regularization``; a guess of the wrong size raises
    ValueError. The solver log's ``warm_start`` says whether one was used."""
    settings = settings or SolverSettings()
    t_build = time.perf_counter()
    built = build_problem(
        motion, settings.cost_config, interpolate_guess=settings.interpolate_guess, limit_scale=limit_scale
    )
    if guess is not None:
        built = _with_guess(built, guess)
    built.problem.nthreads = settings.nthreads
    # Box-FDDP's own line search is kept (alphas 1, 1/2, ..., 2^-9; th_acceptStep 0.1). alphas 1, 1/4, 1/16, ...
    # (also with th_acceptStep 0.01) cut the walk's forward passes from 3.05 to 2.1-2.3 per iteration, but a forward
    # pass is only ~7 % of an iteration (0.027 of ~0.42 ms per knot) and most motions then need more iterations
    # (vertical_jump_1cm 117-232 for 110, one_leg_balancing 48-53 for 35, walk 64 for 42 with alphas alone).
    solver = crocoddyl.SolverBoxFDDP(built.problem)
    build_time = time.perf_counter() - t_build
    config = motion_config(motion.name, settings.cost_config or load_cost_config())
    stages = [*(config.get("continuation") or []), {}] if settings.continuation and guess is None else [{}]
    sums = _cost_sums(built.problem)
    base = [{name: float(item.weight) for name, item in costs.costs.todict().items()} for costs in sums]
    xs, us, feasible = built.xs_guess, built.us_guess, False
    iterations, stage_log = 0, list[StageLog]()
    t_solve, cpu_solve = time.perf_counter(), time.process_time()
    for k, stage in enumerate(stages):
        final = k == len(stages) - 1
        _scale_costs(sums, base, stage.get("scale", {}))
        threshold = settings.stop_threshold if final else float(stage["stop_threshold"])
        solver.th_stop = threshold
        monitor = _ProgressCallback(
            settings.callback, iterations, settings.cost_tolerance if final else 0.0, settings.stall_iterations
        )
        solver.setCallbacks([monitor, crocoddyl.CallbackVerbose()] if settings.verbose else [monitor])
        budget = (
            settings.max_iterations - iterations
            if final
            else min(int(stage.get("max_iterations", 50)), settings.max_iterations - iterations)
        )
        warm = k > 0 or guess is not None
        regularization = settings.stage_regularization if warm else settings.guess_regularization
        if built.actuators is not None and k > 0:
            built.actuators.refresh(xs, us)  # bounds at the previous stage's optimum (the first: at the guess)
        solved = bool(solver.solve(xs, us, max(1, budget), feasible, regularization)) or monitor.stalled
        iterations += monitor.iterations
        stage_log.append(StageLog(dict(stage.get("scale", {})), monitor.iterations, float(solver.cost)))
        xs, us, feasible = list(solver.xs), list(solver.us), bool(solver.isFeasible)
    actuator_log = ActuatorLimitLog()
    if built.actuators is not None:
        solved, extra, actuator_log = _refine_actuator_limits(
            built, solver, settings, config, solved=solved, offset=iterations
        )
        iterations += extra
    solve_time = time.perf_counter() - t_solve
    solve_cpu = time.process_time() - cpu_solve
    solver.th_stop = settings.stop_threshold
    knots = len(built.specs)
    converged = solved and bool(solver.isFeasible)
    scaled = {
        f"{name}:{kind}": float(f[j])
        for kind, f in limit_factors(limit_scale).items()
        for j, name in enumerate(JOINT_NAMES)
        if f[j] != 1.0
    }
    log = SolverLog(
        solver="BoxFDDP",
        iterations=iterations,
        cost=float(solver.cost),
        stop_criterion=float(solver.stop),
        stop_threshold=settings.stop_threshold,
        converged=converged and math.isfinite(float(solver.cost)),
        is_feasible=bool(solver.isFeasible),
        solve_time_s=solve_time,
        build_time_s=build_time,
        knots=knots,
        ms_per_knot_iteration=1e3 * solve_time / max(1, knots * max(1, iterations)),
        # CPU time of this process (all its threads): robust where other processes share the cores
        solve_cpu_s=solve_cpu,
        cpu_ms_per_knot_iteration=1e3 * solve_cpu / max(1, knots * max(1, iterations)),
        stop_reason=("gradient" if float(solver.stop) < settings.stop_threshold else "cost_stalled")
        if converged
        else "iteration_limit",
        stages=stage_log,
        nthreads=settings.nthreads,
        cost_terms=sorted(built.terms),
        mass_kg=robot_mass(built.robot),
        actuator_limits=actuator_log,
        warm_start=guess is not None,
        limit_factors=scaled or None,
    )
    return extract_result(built, solver, log)


def _with_guess(built: BuiltProblem, guess: tuple[Sequence[FloatArray], Sequence[FloatArray]]) -> BuiltProblem:
    """``built`` with the warm start ``guess`` = (xs, us) in place of its own (ValueError if the sizes differ); the
    actuator bounds move to the guess, as they start from the built guess otherwise."""
    xs = [np.array(x, dtype=float) for x in guess[0]]
    us = [np.array(u, dtype=float) for u in guess[1]]
    ok = len(xs) == len(built.xs_guess) and len(us) == len(built.us_guess)
    ok = ok and all(a.shape == b.shape for a, b in zip([*xs, *us], [*built.xs_guess, *built.us_guess], strict=True))
    if not ok:
        msg = f"{built.motion.name}: the warm start does not fit its {len(built.specs)} knots"
        raise ValueError(msg)
    if built.actuators is not None:
        built.actuators.refresh(xs, us)
    return dataclasses.replace(built, xs_guess=xs, us_guess=us)


def _refine_actuator_limits(
    built: BuiltProblem,
    solver: crocoddyl.SolverBoxFDDP,
    settings: SolverSettings,
    config: Mapping[str, Any],
    *,
    solved: bool,
    offset: int,
) -> tuple[bool, int, ActuatorLimitLog]:
    """Check the solution's exact actuator use at the knots and at 1 kHz; where a limit is exceeded, tighten the
    bounds there, refresh every bound at the solution and solve the final stage again (costs.yaml
    ``actuator_limits.refine_rounds`` times at most). Returns (solved, iterations spent, solver-log entry)."""
    actuators = built.actuators
    assert actuators is not None
    settings_al = config["actuator_limits"]
    rounds, extra = list[RefineRound](), 0
    dt = built.motion.dt
    check = actuators.check_iterate(solver.xs, solver.us, dt)
    for _ in range(int(settings_al.get("refine_rounds", 0))):
        if check.ok:
            break
        changed = actuators.tighten_from(check)
        xs, us = list(solver.xs), list(solver.us)
        actuators.refresh(xs, us)
        monitor = _ProgressCallback(
            settings.callback, offset + extra, settings.cost_tolerance, settings.stall_iterations
        )
        solver.setCallbacks([monitor])
        solver.th_stop = settings.stop_threshold
        budget = max(1, min(int(settings_al.get("refine_iterations", 40)), settings.max_iterations - offset - extra))
        solved = bool(solver.solve(xs, us, budget, bool(solver.isFeasible), settings.stage_regularization))
        solved = solved or monitor.stalled
        extra += monitor.iterations
        rounds.append(RefineRound(len(check.over), changed, monitor.iterations))
        check = actuators.check_iterate(solver.xs, solver.us, dt)
    log = ActuatorLimitLog(
        enforced=list(actuators.kinds),
        mechanisms=[unit.model.name for unit in actuators.bounds.units],
        form="per-knot joint boxes at the iterate: joint-limit barrier (stroke, velocity), Box-FDDP box (force)",
        refreshes=actuators.refreshes,
        python_cpu_s=round(actuators.overhead_s, 4),
        refine_rounds=rounds,
        within_limits=check.ok,
        violations_left=len(check.over),
        peak_utilisation=check.summary(),
    )
    return solved, extra, log
