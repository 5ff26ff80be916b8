"""The shooting problem of a motion: robot, contact sequence, one action model per knot, the warm start and, for
motions with ``actuator_limits``, the actuator bounds of every node.

Actuator limits (costs.yaml ``actuator_limits``): the linear actuators' stroke, velocity and force (Table I) through
the parallel mechanisms' exact maps, as per-knot joint boxes built at the current iterate
(:mod:`rh5_planner.actuator_bounds`) and written into the joint-limit barrier's bounds (stroke, velocity) and each
knot's Box-FDDP box (force) before every continuation stage (:mod:`rh5_planner.actuator_constraints`); Crocoddyl's
per-knot work stays its own C++.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import crocoddyl
import numpy as np

from rh5_hyrodyn_mapper.model import q_index, v_index
from rh5_msgs_py.array_types import FloatArray

from ..actuator_bounds import ActuatorBounds
from ..actuator_constraints import ActuatorConstraints
from ..cost_config import load_cost_config, motion_config
from ..limit_scale import LimitScaleLike, limit_factors
from ..motions import KnotSpec, MotionSpec
from .costs import CostTerms, make_cost_terms, unbounded
from .models import contact_model, impulse_model
from .robot import RobotSetup, build_robot
from .warm_start import state_guess

__all__ = ["BuiltProblem", "build_problem"]


@dataclass(frozen=True, eq=False)
class BuiltProblem:
    """A built shooting problem with its knot specs, robot and warm start."""

    motion: MotionSpec
    robot: RobotSetup
    specs: Sequence[KnotSpec]
    problem: crocoddyl.ShootingProblem
    xs_guess: list[FloatArray]
    us_guess: list[FloatArray]
    terms: frozenset[str]
    actuators: ActuatorConstraints | None = None
    """The per-node actuator bounds (None: the motion plans without actuator limits)."""


def build_problem(
    motion: MotionSpec,
    config: Mapping[str, Any] | None = None,
    *,
    interpolate_guess: bool = True,
    limit_scale: LimitScaleLike | None = None,
) -> BuiltProblem:
    """Robot, contact sequence, one action model per knot (impulse nodes at touch-down), warm start.

    ``config`` defaults to costs.yaml (its ``motion_overrides[motion.name]`` merged in); ``limit_scale`` plans with
    scaled joint limits (:func:`build_robot`): the joint-limit barrier and the Box-FDDP torque box follow them."""
    config = motion_config(motion.name, load_cost_config() if config is None else config)
    robot = build_robot(motion.payload_kg_per_hand, motion.knee_bend_rad, limit_scale)
    specs = motion.knots(robot.reference())
    ct = make_cost_terms(robot, motion, config)
    running = [impulse_model(ct, s) if s.impulse else contact_model(ct, s, dt=motion.dt) for s in specs]
    terminal = contact_model(ct, specs[-1], dt=motion.dt, terminal=True)
    problem = crocoddyl.ShootingProblem(robot.x0.copy(), running, terminal)
    # Kinematic IK guess for motions that move the base or lift a foot; squats start from x0 at every knot.
    if interpolate_guess and motion.kinematic_guess:
        xs = state_guess(motion, robot, specs, ct.foot_rotations)
        for i, spec in enumerate(specs):  # post-impact states: what the impulse model makes of the pre-impact ones
            if spec.impulse:
                data = running[i].createData()
                running[i].calc(data, xs[i])
                xs[i + 1] = np.array(data.xnext)
    else:
        xs = [robot.x0.copy() for _ in range(len(specs) + 1)]
    us = list(problem.quasiStatic(xs[:-1]))
    actuators = _actuator_constraints(ct, specs, running, terminal, limit_scale) if ct.actuator_limits else None
    if actuators is not None:
        actuators.refresh(xs, us)
    return BuiltProblem(motion, robot, specs, problem, xs, us, ct.terms, actuators)


def _actuator_constraints(
    ct: CostTerms,
    specs: Sequence[KnotSpec],
    running: Sequence[crocoddyl.ActionModelAbstract],
    terminal: crocoddyl.ActionModelAbstract,
    limit_scale: LimitScaleLike | None,
) -> ActuatorConstraints:
    """The actuator bounds of every node (joint-limit barriers of ``ct.barriers``, control boxes of the running
    contact nodes); the design heuristic's joint factors scale the matching actuator kinds (position -> stroke,
    velocity -> velocity, torque -> force: a faster knee is a faster knee actuator)."""
    model = ct.robot.model
    factors = limit_factors(limit_scale)
    bounds = ActuatorBounds(
        ct.config["actuator_limits"],
        len(specs) + 1,
        {"stroke": factors["position"], "velocity": factors["velocity"], "force": factors["torque"]},
    )
    base = ct.limit_bounds if "joint" in ct.terms else unbounded(ct.robot.state.ndx)
    controls = [None if spec.impulse else m for spec, m in zip(specs, running, strict=True)]
    kept = [i for i in range(len(specs) + 1) if i == len(specs) or not specs[i].impulse]
    del terminal
    return ActuatorConstraints(
        bounds,
        barriers=ct.barriers,
        controls=controls,
        joint_lb=np.asarray(base.lb),
        joint_ub=np.asarray(base.ub),
        tau_max=ct.robot.tau_max,
        q_order=q_index(model),
        v_order=v_index(model),
        kept=kept,
        nq=model.nq,
    )
