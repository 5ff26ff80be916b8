"""A solved motion (:class:`PlanResult`) as read from the solver: states, torques, contact wrenches and CoPs per foot
per knot, the contact phases and the solver log.

``PlanResult.to_trajectory_data`` converts to the project's trajectory file (rh5_msgs_py.trajectory_file),
reordering pinocchio's joints to JOINT_NAMES with q_index/v_index.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import crocoddyl
import numpy as np
import numpy.typing as npt
import pinocchio as pin

from rh5_hyrodyn_mapper.model import model_hash, q_index, v_index
from rh5_msgs_py.array_types import FloatArray
from rh5_msgs_py.names import FOOT_FRAMES
from rh5_msgs_py.trajectory_file import TrajectoryData, save_trajectory

from ..motions import SIDES, MotionSpec
from ..solver_log import SolverLog
from .builder import BuiltProblem
from .robot import RobotSetup

__all__ = ["PlanResult", "extract_result"]


@dataclass(frozen=True, eq=False)
class PlanResult:
    """A solved motion at its knots (impulse nodes merged: the post-impact state is kept).

    Arrays in pinocchio order (q: xyz, quaternion xyzw, joints in pinocchio order; v likewise; u: joint
    torques in pinocchio v order); ``to_trajectory_data`` reorders to JOINT_NAMES. ``wrenches`` (N, 2, 6) are
    the contact wrenches on the (left, right) sole, force then torque, in the sole frame about its origin (zero
    without contact); ``cop`` (N, 2, 2) the CoP x, y in the sole frame (NaN without contact). ``us`` has N-1
    rows: row k acts from knot k to k+1 (zero-order hold, as the Euler integrator applied it).
    """

    motion: MotionSpec
    robot: RobotSetup
    times: FloatArray
    xs: FloatArray
    us: FloatArray
    wrenches: FloatArray
    contact_phases: npt.NDArray[np.bool_]
    cop: FloatArray
    phase_names: tuple[str, ...]
    solver_log: SolverLog
    com: FloatArray = field(default_factory=lambda: np.zeros((0, 3)))
    xs_all: FloatArray = field(default_factory=lambda: np.zeros((0, 0)))
    """The solver's states at every node, impulse nodes included (a warm start for :func:`solve`'s ``guess``)."""
    us_all: FloatArray = field(default_factory=lambda: np.zeros((0, 0)))
    """The solver's controls at every node (impulse nodes have none: a (0,) row each); object array if ragged."""

    @property
    def converged(self) -> bool:
        """Whether Box-FDDP met its stop threshold within the iteration cap."""
        return self.solver_log.converged

    def to_trajectory_data(self) -> TrajectoryData:
        """The project's trajectory file content (joints reordered to JOINT_NAMES)."""
        model = self.robot.model
        qi, vi = q_index(model), v_index(model)
        nq = model.nq
        states = np.concatenate([self.xs[:, :7], self.xs[:, qi], self.xs[:, nq : nq + 6], self.xs[:, nq + vi]], axis=1)
        return TrajectoryData(
            times=self.times,
            states=states,
            controls=self.us[:, vi - 6],
            contact_wrenches=self.wrenches,
            contact_phases=self.contact_phases,
            cop=self.cop,
            motion={"name": self.motion.name, "kind": self.motion.kind, "parameters": self.motion.parameters()},
            model_hash=model_hash(),
            solver_log=self.solver_log.to_dict(),
        )

    def save(self, path: str | Path) -> Path:
        """Write the trajectory file (rh5_msgs_py.trajectory_file.save_trajectory)."""
        return save_trajectory(path, self.to_trajectory_data())


def _wrench(data: Any, name: str) -> FloatArray:
    force = data.differential.multibody.contacts.contacts[name].f
    return np.concatenate([force.linear, force.angular])


def extract_result(built: BuiltProblem, solver: crocoddyl.SolverBoxFDDP, log: SolverLog) -> PlanResult:
    """The solver's final iterate as a :class:`PlanResult`: impulse nodes merged into their post-impact knot,
    contact wrenches read from the solution's data, CoPs and the CoM per knot."""
    problem, specs, robot = built.problem, built.specs, built.robot
    model = robot.model
    xs_all = [np.array(x) for x in solver.xs]
    us_all = [np.array(u) for u in solver.us]
    problem.calc(solver.xs, solver.us)  # make every data hold the final solution
    keep: list[int] = []
    for i in range(len(specs) + 1):
        if i < len(specs) and specs[i].impulse:
            continue  # pre-impact state: replaced by the post-impact state at the same time
        keep.append(i)
    times, xs, us, wrenches, phases, names = [], [], [], [], [], []
    t = 0.0
    dt = built.motion.dt
    for j, i in enumerate(keep):
        times.append(t)
        xs.append(xs_all[i])
        spec = specs[min(i, len(specs) - 1)]
        phases.append(spec.contacts)
        names.append(spec.phase)
        w = np.zeros((2, 6))
        src = i if i < len(specs) else i - 1
        while src >= 0 and specs[src].impulse:
            src -= 1
        for k, side in enumerate(SIDES):
            if specs[src].in_contact(side) and spec.in_contact(side):
                w[k] = _wrench(problem.runningDatas[src], f"{FOOT_FRAMES[side]}_contact")
        wrenches.append(w)
        if j < len(keep) - 1:
            us.append(us_all[i])
            t += dt
    wrench_arr = np.array(wrenches)
    phase_arr = np.array(phases, dtype=bool)
    cop = np.full((len(keep), 2, 2), np.nan)
    fz = wrench_arr[:, :, 2]
    ok = phase_arr & (fz > 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        cop[:, :, 0] = np.where(ok, -wrench_arr[:, :, 4] / fz, np.nan)
        cop[:, :, 1] = np.where(ok, wrench_arr[:, :, 3] / fz, np.nan)
    data = model.createData()
    com = np.array([pin.centerOfMass(model, data, x[: model.nq]) for x in xs])
    return PlanResult(
        motion=built.motion,
        robot=robot,
        times=np.array(times),
        xs=np.array(xs),
        us=np.array(us),
        wrenches=wrench_arr,
        contact_phases=phase_arr,
        cop=cop,
        phase_names=tuple(names),
        solver_log=log,
        com=com,
        xs_all=np.array(xs_all),
        us_all=_stack(us_all),
    )


def _stack(rows: Sequence[FloatArray]) -> FloatArray:
    """Rows of equal length as a 2D array, else an object array of rows (impulse nodes have no controls)."""
    if len({len(r) for r in rows}) <= 1:
        return np.array(rows)
    out = np.empty(len(rows), dtype=object)
    out[:] = list(rows)
    return out
