"""The cost sum of every knot and the soles' contact-stability regions.

Costs (``l = sum_c alpha_c Phi_c``, weights in config/costs.yaml), switched per motion as the paper's table:
foot pose tracking (``ResidualModelFramePlacement``; swing soles and touch-downs: the rigid contact holds the
soles in contact at the same targets, costs.yaml ``foot.track_stance``), CoM tracking
(``ResidualModelCoMPosition``), friction cone + CoP (costs.yaml ``contact_stability.form``: one crocoddyl
``WrenchCone`` through ``ResidualModelContactWrenchCone``, or the paper's two terms, ``FrictionCone`` through
``ResidualModelContactFrictionCone`` and ``CoPSupport`` through ``ResidualModelContactCoPPosition``; each with a
bounded quadratic barrier), joint position/velocity limits (``ResidualModelState`` +
``ActivationModelQuadraticBarrier``), posture (``ResidualModelState`` weighted) and torque regularisation
(``ResidualModelControl``).

Terminal cost: posture (terminal weight) and, for motions without a CoM target, the CoM xy over the middle of the
final soles (``com.terminal_weight``).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Final

import crocoddyl
import numpy as np
import pinocchio as pin

from rh5_hyrodyn_mapper.model import v_index
from rh5_msgs_py.array_types import FloatArray
from rh5_msgs_py.names import JOINT_GROUPS, JOINT_NAMES

from ..feet import FOOT_SIZE_M
from ..motions import SIDES, KnotSpec, MotionSpec
from .robot import RobotSetup

__all__ = [
    "CONTACT_STABILITY_FORMS",
    "ContactCone",
    "CostTerms",
    "contact_cones",
    "knot_costs",
    "make_cost_terms",
    "unbounded",
]


def _group_vector(values: Mapping[str, float], model: pin.Model) -> FloatArray:
    """Per-joint values in pinocchio v order (without the base) from per-group values of costs.yaml."""
    out = np.zeros(model.nv - 6)
    vidx = v_index(model) - 6
    groups = {
        "torso": ("torso",),
        "head": ("head",),
        "arms": ("left_arm", "right_arm"),
        "legs": ("left_leg", "right_leg"),
    }
    for key, names in groups.items():
        for group in names:
            for joint in JOINT_GROUPS[group]:
                out[vidx[JOINT_NAMES.index(joint)]] = float(values[key])
    return out


ContactCone = crocoddyl.WrenchCone | crocoddyl.FrictionCone | crocoddyl.CoPSupport
"""A contact-stability region of one sole, in the sole frame: rows ``lb <= A w <= ub`` on its contact wrench w."""
CONTACT_STABILITY_FORMS: Final = ("wrench_cone", "friction_and_cop")
"""costs.yaml ``contact_stability.form``: one 17-row wrench cone (friction, CoP and yaw-torque rows) or the paper's
two terms, a friction cone (facets + normal force) and a CoP rectangle (4 rows), without yaw-torque rows."""
_CONE_COSTS: Final[Mapping[type, tuple[str, Any]]] = {
    crocoddyl.WrenchCone: ("wrench_cone", crocoddyl.ResidualModelContactWrenchCone),
    crocoddyl.FrictionCone: ("friction_cone", crocoddyl.ResidualModelContactFrictionCone),
    crocoddyl.CoPSupport: ("cop", crocoddyl.ResidualModelContactCoPPosition),
}
"""Cone type -> (cost-name prefix, the crocoddyl residual on a sole frame id and that cone)."""


@dataclass(frozen=True, eq=False)
class CostTerms:
    """Everything the per-knot builders share: config, switched-on terms and precomputed residual data."""

    robot: RobotSetup
    config: Mapping[str, Any]
    terms: frozenset[str]
    posture_weights: FloatArray
    control_weights: FloatArray
    limit_bounds: crocoddyl.ActivationBounds
    cones: tuple[ContactCone, ...]
    foot_rotations: Mapping[str, FloatArray]
    actuator_limits: bool = False
    barriers: list[Any] = field(default_factory=list)
    """Every node's joint-limit activation in build order (running nodes, then the terminal; None without one):
    the actuator limits rewrite their bounds per node (actuator_constraints.ActuatorConstraints)."""


def make_cost_terms(robot: RobotSetup, motion: MotionSpec, config: Mapping[str, Any]) -> CostTerms:
    """The motion's switched-on terms with their weights, joint-limit bounds, contact cones and sole rotations,
    computed once for all knots."""
    terms = frozenset(motion.costs if motion.costs is not None else config["motion_costs"][motion.name])
    model = robot.model
    pw = config["posture"]["state_weights"]
    nj = model.nv - 6
    posture = np.concatenate(
        [
            np.asarray(pw["base_position"], dtype=float),
            np.asarray(pw["base_orientation"], dtype=float),
            _group_vector({k: pw[k] for k in ("torso", "head", "arms", "legs")}, model),
            np.full(6, float(pw["base_velocity"])),
            np.full(nj, float(pw["joint_velocity"])),
        ]
    )
    if "com" in terms:
        posture[:3] = 0.0  # the CoM task places the base; a base-height pull would fight it (squats)
    control = _group_vector(config["torque"]["control_weights"], model)
    jl = config["joint_limits"]

    def shrink(lo: FloatArray, hi: FloatArray, beta: float) -> tuple[FloatArray, FloatArray]:
        mid, half = 0.5 * (lo + hi), 0.5 * (hi - lo)
        return mid - beta * half, mid + beta * half

    qlo, qhi = shrink(robot.q_lower, robot.q_upper, float(jl["position_beta"]))
    vlo, vhi = shrink(-robot.v_max, robot.v_max, float(jl["velocity_beta"]))
    inf6 = np.full(6, np.inf)
    bounds = crocoddyl.ActivationBounds(
        np.concatenate([-inf6, qlo, -inf6, vlo]), np.concatenate([inf6, qhi, inf6, vhi]), 1.0
    )
    data = model.createData()
    pin.framesForwardKinematics(model, data, robot.x0[: model.nq])
    rotations = {side: data.oMf[fid].rotation.copy() for side, fid in robot.foot_ids.items()}
    cones = contact_cones(config["contact_stability"], terms)
    return CostTerms(
        robot, config, terms, posture, control, bounds, cones, rotations, actuator_limits=bool(motion.actuator_limits)
    )


def contact_cones(settings: Mapping[str, Any], terms: frozenset[str]) -> tuple[ContactCone, ...]:
    """The contact-stability regions of a sole for the switched-on ``terms`` ('friction', 'cop') from the
    costs.yaml ``contact_stability`` section: mu and the CoP rectangle (``cop_fraction`` of the sole) shrunk by
    ``margin``, f_z >= ``min_normal_force``, in the form ``settings['form']`` (default ``wrench_cone``)."""
    form = str(settings.get("form", "wrench_cone"))
    if form not in CONTACT_STABILITY_FORMS:
        msg = f"contact_stability.form {form!r} must be one of {list(CONTACT_STABILITY_FORMS)}"
        raise ValueError(msg)
    if not {"friction", "cop"} & terms:
        return ()
    shrink = 1.0 - float(settings["margin"])
    box = np.array(FOOT_SIZE_M) * float(settings["cop_fraction"]) * shrink
    mu, facets, fz_min = float(settings["mu"]) * shrink, int(settings["facets"]), float(settings["min_normal_force"])
    if form == "wrench_cone":
        # one term for both: the bound of a term that is off never acts
        box = box if "cop" in terms else np.array([10.0, 10.0])
        return (crocoddyl.WrenchCone(np.eye(3), mu if "friction" in terms else 1e3, box, facets, True, fz_min),)
    cones: list[ContactCone] = []
    if "friction" in terms:
        cones.append(crocoddyl.FrictionCone(np.eye(3), mu, facets, True, fz_min))
    if "cop" in terms:
        cones.append(crocoddyl.CoPSupport(np.eye(3), box))
    return tuple(cones)


def knot_costs(ct: CostTerms, spec: KnotSpec, nu: int, *, terminal: bool = False) -> crocoddyl.CostModelSum:
    """The cost sum of one knot: the motion's switched-on terms with costs.yaml weights."""
    robot, cfg, state = ct.robot, ct.config, ct.robot.state
    costs = crocoddyl.CostModelSum(state, nu)
    if "foot" in ct.terms or spec.impulse:
        weight = cfg["foot"]["touchdown_weight"] if spec.impulse else cfg["foot"]["weight"]
        stance = bool(cfg["foot"].get("track_stance", True))
        for side in SIDES:
            if spec.impulse and side not in spec.touchdown:
                continue
            if not spec.impulse and not stance and spec.in_contact(side):
                continue  # the rigid contact (ContactModel6D, Baumgarte position term) holds this sole at the target
            target = pin.SE3(ct.foot_rotations[side], np.asarray(spec.feet[side]))
            residual = crocoddyl.ResidualModelFramePlacement(state, robot.foot_ids[side], target, nu)
            costs.addCost(f"foot_{side}", crocoddyl.CostModelResidual(state, residual), float(weight))
    if "com" in ct.terms and spec.com is not None:
        residual = crocoddyl.ResidualModelCoMPosition(state, np.asarray(spec.com), nu)
        costs.addCost("com", crocoddyl.CostModelResidual(state, residual), float(cfg["com"]["weight"]))
    terminal_com = float(cfg["com"].get("terminal_weight", 0.0))
    if terminal and terminal_com > 0 and spec.com is None:
        # End balanced: CoM (xy) over the middle of the final soles; without it a walk may end with the CoM
        # lagging behind the feet (not at rest after the horizon).
        middle = 0.5 * (np.asarray(spec.feet["left"]) + np.asarray(spec.feet["right"]))
        residual = crocoddyl.ResidualModelCoMPosition(state, middle, nu)
        activation = crocoddyl.ActivationModelWeightedQuad(np.array([1.0, 1.0, 0.0]))
        costs.addCost("com_terminal", crocoddyl.CostModelResidual(state, activation, residual), terminal_com)
    for cone in () if spec.impulse or terminal else ct.cones:
        prefix, residual_model = _CONE_COSTS[type(cone)]
        activation = crocoddyl.ActivationModelQuadraticBarrier(crocoddyl.ActivationBounds(cone.lb, cone.ub))
        for side in SIDES:
            if spec.in_contact(side):
                residual = residual_model(state, robot.foot_ids[side], cone, nu)
                costs.addCost(
                    f"{prefix}_{side}",
                    crocoddyl.CostModelResidual(state, activation, residual),
                    float(cfg["contact_stability"]["weight"]),
                )
    if "joint" in ct.terms or ct.actuator_limits:
        # without the "joint" term the bounds are infinite until the actuator limits write theirs
        bounds = ct.limit_bounds if "joint" in ct.terms else unbounded(state.ndx)
        residual = crocoddyl.ResidualModelState(state, state.zero(), nu)
        activation = crocoddyl.ActivationModelQuadraticBarrier(bounds)
        weight = cfg["joint_limits"]["weight"]
        if ct.actuator_limits and cfg["actuator_limits"].get("barrier_weight") is not None:
            weight = cfg["actuator_limits"]["barrier_weight"]
        costs.addCost("joint_limits", crocoddyl.CostModelResidual(state, activation, residual), float(weight))
        ct.barriers.append(activation)
    else:
        ct.barriers.append(None)
    if "posture" in ct.terms or terminal:
        residual = crocoddyl.ResidualModelState(state, robot.x0, nu)
        activation = crocoddyl.ActivationModelWeightedQuad(ct.posture_weights**2)
        weight = cfg["posture"]["terminal_weight"] if terminal else cfg["posture"]["weight"]
        costs.addCost("posture", crocoddyl.CostModelResidual(state, activation, residual), float(weight))
    if "torque" in ct.terms and nu > 0 and not terminal:
        residual = crocoddyl.ResidualModelControl(state, nu)
        activation = crocoddyl.ActivationModelWeightedQuad(ct.control_weights**2)
        costs.addCost(
            "torque", crocoddyl.CostModelResidual(state, activation, residual), float(cfg["torque"]["weight"])
        )
    return costs


def unbounded(ndx: int) -> crocoddyl.ActivationBounds:
    """Bounds that never act (the joint-limit barrier before the actuator limits write theirs)."""
    return crocoddyl.ActivationBounds(np.full(ndx, -np.inf), np.full(ndx, np.inf), 1.0)
