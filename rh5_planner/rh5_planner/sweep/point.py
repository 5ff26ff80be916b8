"""Solving one point of a sweep: what crosses to a worker, what comes back, and the row of the result table.

A :class:`PointTask` holds only names, numbers and plain containers (motion name, parameter overrides, limit
factors, solver settings), so it pickles anywhere; :func:`solve_point` rebuilds the motion and its problem from it in
the worker, solves it with the planner's own :func:`rh5_planner.ocp.solve` (scaled limits as the design
heuristic plans them), checks it with :func:`rh5_planner.limit_analysis.analyse` against the limits it was planned
with and, for jumps, the jump height (:func:`rh5_planner.design.jump_height_task`). It never raises: an error becomes a
row with status ``failed``. The outcome carries the solution as a :class:`WarmStart` for the neighbour it seeds.

Verdict (status): ``feasible`` (converged, every required limit held, the task done), ``over_limits`` (converged but a
required limit exceeded), ``task_missed`` (converged within the limits but short of the task, e.g. a jump that stays
low), ``not_converged``, ``failed``. Required are the joint limits (position, velocity, torque) and, for motions
planned with the actuator limits, the actuators' stroke, velocity and force (as ``rh5-plan --design``). The limiting
factor is the required limit used most (``Knee act. velocity``): the one that is over, or that binds first.
"""

from __future__ import annotations

import os
import platform
import time
import traceback
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Final

import numpy as np

from rh5_msgs_py.array_types import FloatArray

from ..limit_analysis import LimitAnalysis
from ..limit_scale import ACTUATOR_KINDS, JOINT_KINDS, MAPPED_ACTUATORS, side_free_name

__all__ = [
    "STATUSES",
    "PointOutcome",
    "PointTask",
    "WarmStart",
    "failed_outcome",
    "limit_label",
    "solve_point",
    "use_columns",
]

STATUSES: Final = ("feasible", "over_limits", "task_missed", "not_converged", "failed")
JUMP_TASK_FRACTION: Final = 0.9
"""A jump does its task when its soles clear this fraction of ``height_m`` (the design heuristic's check)."""
_SIDE_PREFIXES: Final = ("LL", "LR", "AL", "AR")
_KIND_TEXT: Final = {
    "position": "position",
    "velocity": "velocity",
    "torque": "torque",
    "stroke": "act. stroke",
    "actuator_velocity": "act. velocity",
    "force": "act. force",
}


@dataclass(frozen=True)
class WarmStart:
    """A solution at every node (impulse nodes included): states (N+1, nx) and controls (one row per node, empty
    for impulse nodes)."""

    xs: FloatArray
    us: tuple[FloatArray, ...]

    def to_arrays(self) -> dict[str, FloatArray]:
        """Flat arrays for ``np.savez`` (no pickled objects)."""
        sizes = np.array([len(u) for u in self.us], dtype=np.int64)
        flat = np.concatenate([np.asarray(u, dtype=float).ravel() for u in self.us]) if self.us else np.zeros(0)
        return {"xs": np.asarray(self.xs, dtype=float), "us_flat": flat, "us_sizes": sizes}

    @classmethod
    def from_arrays(cls, arrays: Mapping[str, Any]) -> WarmStart:
        """Inverse of :meth:`to_arrays`."""
        sizes = np.asarray(arrays["us_sizes"], dtype=np.int64)
        flat = np.asarray(arrays["us_flat"], dtype=float)
        cuts = np.cumsum(sizes)[:-1]
        return cls(np.asarray(arrays["xs"], dtype=float), tuple(np.split(flat, cuts)))


@dataclass(frozen=True)
class PointTask:
    """Everything a worker needs to solve one point; plain data only."""

    point: str
    motion: str
    values: Mapping[str, float]
    """The swept keys and their values at this point (table columns)."""
    overrides: Mapping[str, Any]
    """Motion parameter overrides (``--set`` and the swept motion parameters)."""
    scale: tuple[tuple[str, str, float], ...]
    """Limit factors (pattern, kind, factor), :class:`rh5_planner.limit_scale.LimitScale` entries."""
    max_iterations: int = 200
    stop_threshold: float = 1e-7
    nthreads: int = 1
    warm_from: str = ""
    """The point whose solution seeds this one (empty: a cold start)."""


@dataclass(frozen=True)
class PointOutcome:
    """The row of the result table and, for a converged plan, its solution to warm-start a neighbour."""

    row: dict[str, Any]
    warm: WarmStart | None = field(default=None, compare=False)


def limit_label(kind: str, name: str) -> str:
    """``("actuator_velocity", "LLKnee_Act1")`` -> ``Knee act. velocity``; ``("velocity", "BodyPitch")`` ->
    ``BodyPitch velocity``: one label for both sides and every actuator of a mechanism."""
    if "_Act" in name:
        mechanism = name.split("_Act", maxsplit=1)[0]
        group = mechanism[2:] if mechanism[:2] in _SIDE_PREFIXES else mechanism
    else:
        group = side_free_name(name)
    return f"{group} {_KIND_TEXT.get(kind, kind)}"


def use_columns() -> list[str]:
    """The per-limit utilisation columns of the table: ``use.<kind>.<joint or actuator>`` (peak |value| / limit)."""
    from rh5_msgs_py.names import JOINT_NAMES  # noqa: PLC0415

    return [f"use.{k}.{n}" for k in JOINT_KINDS for n in JOINT_NAMES] + [
        f"use.{k}.{n}" for k in ACTUATOR_KINDS for n in MAPPED_ACTUATORS
    ]


def _limit_use(analysis: LimitAnalysis) -> dict[str, float]:
    out: dict[str, float] = {}
    for kind, usage in {**analysis.joint, **(analysis.actuator or {})}.items():
        out.update({f"use.{kind}.{n}": float(p) for n, p in zip(usage.names, usage.peak, strict=True)})
    return out


def _limiting(analysis: LimitAnalysis, required: Sequence[str]) -> tuple[str, float]:
    """The required limit used most (its label) and its peak utilisation."""
    best, best_use = "", -np.inf
    for kind, usage in {**analysis.joint, **(analysis.actuator or {})}.items():
        if kind not in required or not len(usage.names):
            continue
        i = int(np.argmax(usage.peak))
        if usage.peak[i] > best_use:
            best, best_use = limit_label(kind, usage.names[i]), float(usage.peak[i])
    return best, best_use


def _base_row(task: PointTask) -> dict[str, Any]:
    return {
        "point": task.point,
        **{k: float(v) for k, v in task.values.items()},
        "status": "failed",
        "converged": False,
        "feasible": False,
        "limiting": "",
        "limiting_use": float("nan"),
        "task": "",
        "iterations": 0,
        "solve_s": 0.0,
        "cpu_s": 0.0,
        "warm_from": task.warm_from,
        "warm_started": False,
        "host": platform.node(),
        "pid": os.getpid(),
        "error": "",
    }


def failed_outcome(task: PointTask, error: str) -> PointOutcome:
    """The row of a point that no worker delivered (e.g. every attempt's worker died)."""
    row = {**_base_row(task), "host": "", "pid": 0, "error": error[:500]}
    return PointOutcome(row)


def solve_point(task: PointTask, warm: WarmStart | None = None) -> PointOutcome:
    """Rebuild the point's motion and problem, solve it (from ``warm`` when given), check it, return its row."""
    row = _base_row(task)
    start, cpu = time.perf_counter(), time.process_time()
    try:
        # crocoddyl before pinocchio (design/crocoddyl_wheels.md): rh5_planner.design imports it first
        from ..design import jump_height_task  # noqa: PLC0415
        from ..limit_analysis import analyse  # noqa: PLC0415
        from ..limit_scale import LimitScale  # noqa: PLC0415
        from ..motions import get_motion  # noqa: PLC0415
        from ..ocp import SolverSettings, solve  # noqa: PLC0415

        motion = get_motion(task.motion, dict(task.overrides))
        scale = LimitScale(tuple(task.scale))
        settings = SolverSettings(task.max_iterations, task.stop_threshold, task.nthreads)
        guess = (list(warm.xs), list(warm.us)) if warm is not None else None
        plan = solve(motion, settings, limit_scale=scale if scale else None, guess=guess)
        analysis = analyse(plan, scale=scale)
        required = (*JOINT_KINDS, *ACTUATOR_KINDS) if motion.actuator_limits else JOINT_KINDS
        task_ok, task_text = jump_height_task(JUMP_TASK_FRACTION)(plan) if motion.kind == "jump" else (True, "")
        converged = bool(analysis.converged)
        within = analysis.feasible(required)
        if not converged:
            status = "not_converged"
        elif not within:
            status = "over_limits"
        elif not task_ok:
            status = "task_missed"
        else:
            status = "feasible"
        limiting, use = _limiting(analysis, required)
        contact = analysis.contact
        peaks = {
            f"peak.{kind}": float(usage.peak.max(initial=0.0))
            for kind, usage in {**analysis.joint, **(analysis.actuator or {})}.items()
        }
        row.update(
            status=status,
            converged=converged,
            feasible=status == "feasible",
            limiting=limiting,
            limiting_use=use,
            task=task_text,
            iterations=plan.solver_log.iterations,
            warm_started=plan.solver_log.warm_start,
            cop_inside=float(contact.cop_inside_ratio),
            friction_inside=float(contact.friction_inside_ratio),
            **peaks,
            **_limit_use(analysis),
        )
        solution = WarmStart(
            np.asarray(plan.xs_all, dtype=float), tuple(np.asarray(u, dtype=float) for u in plan.us_all)
        )
        outcome_warm = solution if converged else None
    except Exception as err:  # a point's failure is a result, never the sweep's end
        row["error"] = f"{type(err).__name__}: {err}"[:500]
        row["traceback"] = traceback.format_exc(limit=8)[-2000:]
        outcome_warm = None
    row["solve_s"] = time.perf_counter() - start
    row["cpu_s"] = time.process_time() - cpu
    return PointOutcome(row, outcome_warm)
