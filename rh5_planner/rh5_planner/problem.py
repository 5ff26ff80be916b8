"""Contact-stability soft-constrained Box-FDDP on the full RH5 model (paper, "Analysis and control using DDP").

Our own builders on Crocoddyl's public API (crocoddyl.utils.biped is not API and is not used here):

* Dynamics: floating-base contact dynamics with rigid 6D sole contacts (``ContactModel6D`` on
  ``LLFoot_Sole``/``LRFoot_Sole``, LOCAL frame, Baumgarte gains from costs.yaml) in
  ``DifferentialActionModelContactFwdDynamics``, integrated by ``IntegratedActionModelEuler`` (symplectic
  Euler, one knot per ``motion.dt``). Every touch-down is an ``ActionModelImpulseFwdDynamics`` node
  (``ImpulseModel6D`` on the landing soles, zero restitution) of zero duration.
* Costs (``l = sum_c alpha_c Phi_c``, weights in config/costs.yaml), switched per motion as the paper's table:
  foot pose tracking (``ResidualModelFramePlacement``; swing soles and touch-downs: the rigid contact holds the
  soles in contact at the same targets, costs.yaml ``foot.track_stance``), CoM tracking
  (``ResidualModelCoMPosition``), friction cone + CoP (costs.yaml ``contact_stability.form``: one crocoddyl
  ``WrenchCone`` through ``ResidualModelContactWrenchCone``, or the paper's two terms, ``FrictionCone`` through
  ``ResidualModelContactFrictionCone`` and ``CoPSupport`` through ``ResidualModelContactCoPPosition``; each with a
  bounded quadratic barrier), joint position/velocity limits
  (``ResidualModelState`` + ``ActivationModelQuadraticBarrier``), posture (``ResidualModelState`` weighted) and
  torque regularisation (``ResidualModelControl``).
* Torque limits are the hard box of Box-FDDP: every action model's ``u_lb``/``u_ub`` are
  -/+ ``joint_limits().torque_max`` (the upper ends of the paper's configuration-dependent ranges).
* Actuator limits (motions with ``actuator_limits``; costs.yaml ``actuator_limits``): the linear actuators' stroke,
  velocity and force (Table I) through the parallel mechanisms' exact maps, as per-knot joint boxes built at the
  current iterate (:mod:`rh5_planner.actuator_bounds`) and written into the joint-limit barrier's bounds (stroke,
  velocity) and each knot's Box-FDDP box (force) before every continuation stage
  (:mod:`rh5_planner.actuator_constraints`); Crocoddyl's per-knot work stays its own C++. After the final stage an
  exact check at the knots and along the 1 kHz interpolation tightens the bounds where a limit is still exceeded
  and solves again; the solver log's ``actuator_limits`` says what was enforced and the peaks reached.
* Payload: ``motion.payload_kg_per_hand`` is added as a point mass at each hand TCP (``AL_TCP``/``AR_TCP``) to
  the inertia of the link carrying the TCP (pinocchio ``Inertia(m, c, 0)`` with c the TCP position in that
  joint's frame). The 5 kg bars of the paper become 2 x 5 kg at the grasp point.
* Initial pose: the nominal standing pose with the knees bent by ``motion.knee_bend_rad`` and the CoM over the
  middle of the soles (a small damped Gauss-Newton IK, :func:`nominal_configuration`): the all-zero pose of
  the model has straight knees at their 0 rad limit and the CoM 5 cm behind the sole centres.
* Warm start: the quasi-static torques of ``problem.quasiStatic`` on a state guess. In-place motions
  (squats, balancing) use the initial state at every knot. Motions that move the base (walks, jumps) use a
  kinematic guess (:func:`_state_guess`): node i gets whole-body IK to knot i's sole targets and a CoM path
  (the knot's CoM target, else a linear inverted pendulum whose ZMP walks from stance sole to stance sole),
  velocities by backward differences as the symplectic Euler step makes them. That is our reading of the
  paper's remark that walking above 0.35 m/s needs a predefined CoM trajectory as initialisation;
  fast_walk_1m_s also tracks its CoM path as a cost (its table row has the CoM term).
* Terminal cost: posture (terminal weight) and, for motions without a CoM target, the CoM xy over the
  middle of the final soles (``com.terminal_weight``).

* Continuation (costs.yaml ``continuation``): the problem is first solved with the contact wrench cone off, then
  at 1 % and 10 % weight, each stage warm-starting the next (``SolverSettings`` regularisations); then
  with every weight as configured (same optimum, a third of the iterations for the walk and the balancing
  experiments). Convergence: Box-FDDP's gradient test (``stop_threshold``) or the cost unchanged to
  ``cost_tolerance`` over ``stall_iterations`` full steps on a feasible trajectory.
* Scaled limits (design-improvement heuristic): ``limit_scale`` of :func:`solve` / :func:`build_problem` /
  :func:`build_robot` (``{"knee:velocity": 3.0}`` or any object with ``factors(kind)``) widens the position
  ranges about their middle and multiplies velocity and torque maxima for the barrier and the torque box.

``solve(motion, settings)`` builds, solves and returns a :class:`PlanResult` with states, torques, contact
wrenches and CoPs per foot per knot, the contact phases and the solver log; ``PlanResult.to_trajectory_data``
converts to the project's trajectory file (rh5_msgs_py.trajectory_file), reordering pinocchio's joints to
JOINT_NAMES with q_index/v_index.
"""

from __future__ import annotations

import dataclasses
import fnmatch
import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Final, Protocol

import crocoddyl  # must come before anything that links pinocchio extensions (design/crocoddyl_wheels.md)
import numpy as np
import numpy.typing as npt
import pinocchio as pin

from rh5_hyrodyn_mapper.model import build_model, joint_limits, model_hash, q_index, standing_configuration, v_index
from rh5_msgs_py.names import FOOT_FRAMES, HAND_FRAMES, JOINT_GROUPS, JOINT_NAMES
from rh5_msgs_py.trajectory_file import TrajectoryData, save_trajectory

from .actuator_bounds import ActuatorBounds
from .actuator_constraints import ActuatorConstraints
from .cost_config import COSTS_FILE, load_cost_config, motion_config
from .feet import FOOT_SIZE_M
from .motions import SIDES, KnotSpec, MotionSpec, Reference
from .solver_log import ActuatorLimitLog, RefineRound, SolverLog, StageLog

__all__ = [
    "CONTACT_STABILITY_FORMS",
    "COSTS_FILE",
    "FOOT_SIZE_M",
    "LIMIT_KINDS",
    "BuiltProblem",
    "ContactCone",
    "LimitFactors",
    "LimitScaleLike",
    "PlanResult",
    "ProgressCallback",
    "RobotSetup",
    "SolverSettings",
    "build_problem",
    "build_robot",
    "contact_cones",
    "limit_factors",
    "load_cost_config",
    "nominal_configuration",
    "solve",
]

FloatArray = npt.NDArray[np.float64]
ProgressCallback = Callable[[int, float, float], None]
"""``callback(iteration, cost, stop)`` called after every Box-FDDP iteration."""


# --------------------------------------------------------------------------------------------------
# robot


@dataclass(frozen=True, eq=False)
class RobotSetup:
    """The pinocchio model (with payload), Crocoddyl state/actuation, frame ids, nominal state and limits.

    Limits are in pinocchio's v order (``v_index() - 6`` maps JOINT_NAMES to it).
    """

    model: pin.Model
    state: crocoddyl.StateMultibody
    actuation: crocoddyl.ActuationModelFloatingBase
    foot_ids: Mapping[str, int]
    x0: FloatArray
    q_lower: FloatArray
    q_upper: FloatArray
    v_max: FloatArray
    tau_max: FloatArray
    payload_kg_per_hand: float

    @property
    def mass(self) -> float:
        """Total mass including the payload [kg]."""
        return float(sum(inertia.mass for inertia in self.model.inertias))

    def reference(self, x: FloatArray | None = None) -> Reference:
        """Sole positions and CoM of the state ``x`` (default: the nominal state)."""
        x = self.x0 if x is None else x
        data = self.model.createData()
        q = x[: self.model.nq]
        pin.framesForwardKinematics(self.model, data, q)
        com = pin.centerOfMass(self.model, data, q)
        feet = {side: data.oMf[fid].translation.copy() for side, fid in self.foot_ids.items()}
        return Reference(feet=feet, com=com.copy())


def _add_payload(model: pin.Model, mass: float) -> None:
    for frame_name in HAND_FRAMES.values():
        frame = model.frames[model.getFrameId(frame_name)]
        lever = frame.placement.translation.copy()
        model.inertias[frame.parentJoint] += pin.Inertia(mass, lever, np.zeros((3, 3)))


def nominal_configuration(model: pin.Model, knee_bend_rad: float, iterations: int = 60) -> FloatArray:
    """Standing pose with bent knees, flat soles where the straight pose has them, CoM over the soles' middle.

    Damped Gauss-Newton (:func:`solve_ik`) on [left sole 6D, right sole 6D, CoM xy, base orientation, knee
    angles] with a small pull of every joint to the straight pose; converges to ~1e-10.
    """
    data = model.createData()
    q_straight = standing_configuration(model)
    pin.framesForwardKinematics(model, data, q_straight)
    soles = {side: data.oMf[model.getFrameId(FOOT_FRAMES[side])].copy() for side in SIDES}
    com_xy = 0.5 * (soles["left"].translation[:2] + soles["right"].translation[:2])
    q = q_straight.copy()
    for n in ("LLKnee", "LRKnee"):
        q[model.joints[model.getJointId(n)].idx_q] = knee_bend_rad
    return solve_ik(model, q, soles, com=com_xy, knee_rad=knee_bend_rad, iterations=iterations)


def solve_ik(
    model: pin.Model,
    q_init: FloatArray,
    soles: Mapping[str, pin.SE3],
    *,
    com: FloatArray | None = None,
    knee_rad: float | None = None,
    q_ref: FloatArray | None = None,
    iterations: int = 30,
) -> FloatArray:
    """Whole-body IK: sole placements, CoM (xy or xyz), upright base, optionally knee angles; joints pulled to
    ``q_ref`` (default ``q_init``) by a small damping. Used for the nominal pose and the warm-start guesses."""
    data = model.createData()
    q_ref = q_init if q_ref is None else q_ref
    base_rotation = pin.Quaternion(q_ref[3:7]).toRotationMatrix()
    feet = {side: model.getFrameId(FOOT_FRAMES[side]) for side in soles}
    knees = [_q_of_v(model, model.joints[model.getJointId(n)].idx_v) for n in ("LLKnee", "LRKnee")]
    q = q_init.copy()
    for _ in range(iterations):
        pin.computeJointJacobians(model, data, q)
        pin.framesForwardKinematics(model, data, q)
        rows, jacs, weights = [], [], []
        for side, fid in feet.items():
            rows.append(pin.log6(data.oMf[fid].actInv(soles[side])).vector)
            jacs.append(pin.getFrameJacobian(model, data, fid, pin.ReferenceFrame.LOCAL))
            weights.append(np.full(6, 10.0))
        if com is not None:
            c = pin.centerOfMass(model, data, q)
            n = len(com)
            rows.append(np.asarray(com) - c[:n])
            jacs.append(pin.jacobianCenterOfMass(model, data, q)[:n])
            weights.append(np.full(n, 10.0))
        rot = pin.Quaternion(q[3:7]).toRotationMatrix()
        rows.append(pin.log3(rot.T @ base_rotation))
        jbase = np.zeros((3, model.nv))
        jbase[:, 3:6] = np.eye(3)
        jacs.append(jbase)
        weights.append(np.full(3, 1.0))
        if knee_rad is not None:
            for iq in knees:
                jk = np.zeros((1, model.nv))
                jk[0, iq - 1] = 1.0  # free flyer: idx_v = idx_q - 1 for 1-DoF joints
                rows.append(np.array([knee_rad - q[iq]]))
                jacs.append(jk)
                weights.append(np.array([1.0]))
        residual = np.concatenate(rows)
        jacobian = np.vstack(jacs)
        w = np.concatenate(weights)
        jw = (jacobian * w[:, None]).T
        a = jw @ jacobian + 1e-6 * np.eye(model.nv)
        a[6:, 6:] += 1e-3 * np.eye(model.nv - 6)
        b = jw @ residual
        b[6:] += 1e-3 * pin.difference(model, q, q_ref)[6:]
        q = pin.integrate(model, q, np.linalg.solve(a, b))
        if np.max(np.abs(residual)) < 1e-10:
            break
    return q


def _q_of_v(model: pin.Model, idx_v: int) -> int:
    for joint in model.joints:
        if joint.nv == 1 and joint.idx_v == idx_v:
            return int(joint.idx_q)
    raise KeyError(idx_v)


class LimitFactors(Protocol):
    """Anything that gives a per-joint factor (JOINT_NAMES order) for a limit kind, such as
    rh5_planner.limit_analysis.LimitScale."""

    def factors(self, kind: str) -> npt.ArrayLike:
        """(32,) factors in JOINT_NAMES order for ``kind`` ('position', 'velocity' or 'torque')."""
        ...


LimitScaleLike = LimitFactors | Mapping[str, float]
"""Scaled joint limits for planning: a :class:`LimitFactors` or a mapping ``"PATTERN:KIND" -> factor`` with KIND one
of :data:`LIMIT_KINDS` and PATTERN a case-insensitive shell pattern (``LL*``) or substring (``knee``) of joint names
(``"*:velocity"`` scales every joint); later entries win where patterns overlap."""
LIMIT_KINDS: Final = ("position", "velocity", "torque")


def limit_factors(scale: LimitScaleLike | None) -> dict[str, FloatArray]:
    """Per limit kind, the (32,) factors in JOINT_NAMES order of ``scale`` (ones where it says nothing).

    ValueError for an unknown kind, a pattern matching no joint or a non-positive factor."""
    out = {kind: np.ones(len(JOINT_NAMES)) for kind in LIMIT_KINDS}
    if scale is None:
        return out
    if not isinstance(scale, Mapping):
        for kind in LIMIT_KINDS:
            out[kind] = np.asarray(scale.factors(kind), dtype=float).reshape(len(JOINT_NAMES))
    else:
        for key, factor in scale.items():
            pattern, _, kind = str(key).rpartition(":")
            if kind not in LIMIT_KINDS or not pattern:
                msg = f"limit scale key {key!r} must be PATTERN:KIND with KIND one of {list(LIMIT_KINDS)}"
                raise ValueError(msg)
            mask = _match_joints(pattern)
            if not mask.any():
                msg = f"limit scale pattern {pattern!r} matches no joint"
                raise ValueError(msg)
            out[kind][mask] = float(factor)
    for kind, values in out.items():
        if not (np.isfinite(values).all() and (values > 0).all()):
            msg = f"{kind} limit factors must be positive and finite, got {values}"
            raise ValueError(msg)
    return out


def _match_joints(pattern: str) -> npt.NDArray[np.bool_]:
    """JOINT_NAMES matching a shell pattern (with wildcards) or containing ``pattern`` (without), case-insensitive."""
    pat = pattern.lower()
    if any(ch in pat for ch in "*?["):
        return np.array([fnmatch.fnmatchcase(name.lower(), pat) for name in JOINT_NAMES])
    return np.array([pat in name.lower() for name in JOINT_NAMES])


def build_robot(
    payload_kg_per_hand: float = 0.0, knee_bend_rad: float = 0.5, limit_scale: LimitScaleLike | None = None
) -> RobotSetup:
    """RH5 with the payload at the hands, its Crocoddyl state and actuation, and the nominal standing state.

    ``limit_scale`` (see :data:`LimitScaleLike`) scales the planning limits: position ranges widen about their
    middle, velocity and torque maxima multiply (the design-improvement heuristic plans with these)."""
    model = build_model(free_flyer=True)
    if payload_kg_per_hand > 0:
        _add_payload(model, payload_kg_per_hand)
    state = crocoddyl.StateMultibody(model)
    actuation = crocoddyl.ActuationModelFloatingBase(state)
    q0 = nominal_configuration(model, knee_bend_rad)
    x0 = np.concatenate([q0, np.zeros(model.nv)])
    limits = joint_limits()
    order = np.argsort(v_index(model))  # pinocchio v order -> position in JOINT_NAMES
    factors = {kind: f[order] for kind, f in limit_factors(limit_scale).items()}
    lower, upper = np.asarray(limits.position_lower)[order], np.asarray(limits.position_upper)[order]
    middle, half = 0.5 * (lower + upper), 0.5 * (upper - lower) * factors["position"]
    return RobotSetup(
        model=model,
        state=state,
        actuation=actuation,
        foot_ids={side: model.getFrameId(FOOT_FRAMES[side]) for side in SIDES},
        x0=x0,
        q_lower=middle - half,
        q_upper=middle + half,
        v_max=np.asarray(limits.velocity_max)[order] * factors["velocity"],
        tau_max=np.asarray(limits.torque_max)[order] * factors["torque"],
        payload_kg_per_hand=payload_kg_per_hand,
    )


# --------------------------------------------------------------------------------------------------
# costs and action models


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
class _CostTerms:
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


def _make_terms(robot: RobotSetup, motion: MotionSpec, config: Mapping[str, Any]) -> _CostTerms:
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
    return _CostTerms(
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


def _costs(ct: _CostTerms, spec: KnotSpec, nu: int, *, terminal: bool = False) -> crocoddyl.CostModelSum:
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
        bounds = ct.limit_bounds if "joint" in ct.terms else _unbounded(state.ndx)
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


def _unbounded(ndx: int) -> crocoddyl.ActivationBounds:
    return crocoddyl.ActivationBounds(np.full(ndx, -np.inf), np.full(ndx, np.inf), 1.0)


def _contact_model(
    ct: _CostTerms, spec: KnotSpec, *, dt: float, terminal: bool = False
) -> crocoddyl.ActionModelAbstract:
    robot = ct.robot
    nu = robot.actuation.nu
    contacts = crocoddyl.ContactModelMultiple(robot.state, nu)
    gains = np.asarray(ct.config["contact_stability"]["baumgarte_gains"], dtype=float)
    for side in SIDES:
        if spec.in_contact(side):
            placement = pin.SE3(ct.foot_rotations[side], np.asarray(spec.feet[side]))
            contact = crocoddyl.ContactModel6D(
                robot.state, robot.foot_ids[side], placement, pin.ReferenceFrame.LOCAL, nu, gains
            )
            contacts.addContact(f"{FOOT_FRAMES[side]}_contact", contact)
    costs = _costs(ct, spec, nu, terminal=terminal)
    dam = crocoddyl.DifferentialActionModelContactFwdDynamics(robot.state, robot.actuation, contacts, costs, 0.0, True)
    iam = crocoddyl.IntegratedActionModelEuler(dam, 0.0 if terminal else dt)
    iam.u_lb = -robot.tau_max
    iam.u_ub = robot.tau_max
    return iam


def _impulse_model(ct: _CostTerms, spec: KnotSpec) -> crocoddyl.ActionModelAbstract:
    robot = ct.robot
    impulses = crocoddyl.ImpulseModelMultiple(robot.state)
    for side in SIDES:
        if spec.in_contact(side):
            impulse = crocoddyl.ImpulseModel6D(robot.state, robot.foot_ids[side], pin.ReferenceFrame.LOCAL)
            impulses.addImpulse(f"{FOOT_FRAMES[side]}_impulse", impulse)
    costs = _costs(ct, spec, 0)
    return crocoddyl.ActionModelImpulseFwdDynamics(robot.state, impulses, costs, 0.0, 0.0, True)


def _zmp_reference(specs: Sequence[KnotSpec]) -> tuple[FloatArray, FloatArray]:
    """Per running (non-impulse) knot, the xy point the CoP should be at and how firmly: the stance sole in
    single support (weight 1); a smoothstep from one stance sole to the next over each double-support block
    (from/to the middle of the feet at the start/end of the motion) with weight 0.1, since the CoP may be
    anywhere between the feet there. Knots without contact keep the previous value with weight 0."""
    running = [s for s in specs if not s.impulse]
    out = np.zeros((len(running), 2))

    def stance(spec: KnotSpec) -> FloatArray | None:
        inside = [side for side in SIDES if spec.in_contact(side)]
        if len(inside) == 1:
            return np.asarray(spec.feet[inside[0]])[:2]
        if len(inside) == 2:
            return None
        return np.full(2, np.nan)

    values = [stance(s) for s in running]
    j = 0
    while j < len(running):
        if values[j] is not None:
            out[j] = values[j]
            j += 1
            continue
        end = j
        while end < len(running) and values[end] is None:
            end += 1
        mid_start = 0.5 * (np.asarray(running[j].feet["left"]) + np.asarray(running[j].feet["right"]))[:2]
        mid_end = 0.5 * (np.asarray(running[end - 1].feet["left"]) + np.asarray(running[end - 1].feet["right"]))[:2]
        before = out[j - 1] if j > 0 else mid_start
        after = values[end] if end < len(running) else mid_end
        after = before if after is None or np.isnan(after).any() else after
        for m in range(j, end):
            s = (m - j + 1) / (end - j + 1)
            smooth = s * s * (3.0 - 2.0 * s)
            out[m] = (1.0 - smooth) * before + smooth * after
        j = end
    weights = np.array([1.0 if v is not None and not np.isnan(v).any() else 0.1 for v in values])
    for m in range(len(out)):
        if np.isnan(out[m]).any():
            out[m] = out[m - 1] if m > 0 else 0.0
            weights[m] = 0.0
    return out, weights


def _lipm_com_path(zmp: FloatArray, weights: FloatArray, com0: FloatArray, dt: float) -> FloatArray:
    """CoM xy at the running knots and the final node (len(zmp) + 1 rows) of a linear inverted pendulum of
    height ``com0[2]`` whose ZMP tracks ``zmp``: weighted least squares on
    c_k - h/g (c_{k+1} - 2 c_k + c_{k-1}) / dt^2 = zmp_k, with the CoM at rest at ``com0`` at the start and at
    rest over the last ZMP at the end (firm)."""
    n = len(zmp) + 1
    ratio = float(com0[2]) / 9.81 / dt**2
    rows, rhs = [], []

    def row(entries: Mapping[int, float], value: FloatArray, weight: float) -> None:
        r = np.zeros(n)
        for idx, coeff in entries.items():
            r[idx] += coeff
        rows.append(weight * r)
        rhs.append(weight * value)

    big = 1e3
    row({0: 1.0}, com0[:2], big)
    row({1: 1.0, 0: -1.0}, np.zeros(2), big)
    for k in range(1, n - 1):
        row({k: 1.0 + 2.0 * ratio, k + 1: -ratio, k - 1: -ratio}, zmp[k], float(weights[k]))
    row({n - 1: 1.0, n - 2: -1.0}, np.zeros(2), big)
    row({n - 1: 1.0}, zmp[-1], big)
    solution, *_ = np.linalg.lstsq(np.array(rows), np.array(rhs), rcond=None)
    return np.asarray(solution)


def _state_guess(
    motion: MotionSpec, robot: RobotSetup, specs: Sequence[KnotSpec], rotations: Mapping[str, FloatArray]
) -> list[FloatArray]:
    """Kinematic warm start: per node, IK to the sole targets of its knot and a CoM path, velocities by
    backward differences (zero after an impulse node). Node i carries knot i's targets (its running cost is evaluated
    on x_i); the final node those of the last knot. The CoM path is the knot's CoM target where the motion
    has one, else a linear inverted pendulum whose ZMP walks from sole to sole (:func:`_lipm_com_path`), at
    the initial CoM height."""
    model = robot.model
    nq = model.nq
    reference = robot.reference()
    n = len(specs)
    com_xy = _lipm_com_path(*_zmp_reference(specs), reference.com, motion.dt)
    running = -1
    qs = []
    q = robot.x0[:nq].copy()
    for i in range(n + 1):
        spec = specs[min(i, n - 1)]
        if i == n or not spec.impulse:
            running += 1
        if spec.com_guess is not None:
            com = np.asarray(spec.com_guess)
        elif spec.com is not None:
            com = np.asarray(spec.com)
        else:
            com = np.array([*com_xy[max(running, 0)], reference.com[2]])
        soles = {side: pin.SE3(rotations[side], np.asarray(spec.feet[side])) for side in SIDES}
        q = robot.x0[:nq].copy() if i == 0 else solve_ik(model, q, soles, com=com, q_ref=robot.x0[:nq], iterations=8)
        qs.append(q)
    # Backward differences, as the symplectic Euler step makes them (q_{i+1} = q_i + v_{i+1} dt): a sole that
    # leaves the ground at node i has zero velocity there. An impulse node takes no time: the node after it has
    # its configuration (the post-impact velocity is set by build_problem from the impulse model).
    xs = [robot.x0.copy()]
    for i in range(1, n + 1):
        if specs[i - 1].impulse:
            qs[i] = qs[i - 1]
            xs.append(np.concatenate([qs[i], xs[-1][nq:]]))
            continue
        v = pin.difference(model, qs[i - 1], qs[i]) / motion.dt
        xs.append(np.concatenate([qs[i], v]))
    return xs


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
    ct = _make_terms(robot, motion, config)
    running = [_impulse_model(ct, s) if s.impulse else _contact_model(ct, s, dt=motion.dt) for s in specs]
    terminal = _contact_model(ct, specs[-1], dt=motion.dt, terminal=True)
    problem = crocoddyl.ShootingProblem(robot.x0.copy(), running, terminal)
    # Kinematic IK guess for motions that move the base or lift a foot; squats start from x0 at every knot.
    if interpolate_guess and motion.kinematic_guess:
        xs = _state_guess(motion, robot, specs, ct.foot_rotations)
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
    ct: _CostTerms,
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
    base = ct.limit_bounds if "joint" in ct.terms else _unbounded(ct.robot.state.ndx)
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


# --------------------------------------------------------------------------------------------------
# solving


@dataclass(frozen=True)
class SolverSettings:
    """Box-FDDP settings: iteration cap, stop threshold, threads of the derivative pass, progress callback."""

    max_iterations: int = 200
    stop_threshold: float = 1e-7
    nthreads: int = 2
    callback: ProgressCallback | None = None
    verbose: bool = False
    cost_config: Mapping[str, Any] | None = None
    interpolate_guess: bool = True
    continuation: bool = True
    """Solve the stages of costs.yaml ``continuation`` (cost terms faded in) before the final problem."""
    cost_tolerance: float = 1e-7
    """Also stop (converged, reason ``cost_stalled``) once the trajectory is feasible and the cost changed by less
    than this fraction over the last ``stall_iterations`` iterations, all full steps; 0 disables it."""
    stall_iterations: int = 5
    guess_regularization: float = 1e-2
    """Box-FDDP's initial regularisation of the first stage, which starts from the built guess (kinematic, with
    dynamic gaps): Crocoddyl's own 1e-9 trusts it like a converged solution, and fast_walk_1m_s then spent 7
    iterations of 10 rejected line-search steps raising it; from 1e-2 it needs 34 iterations instead of 52,
    vertical_jump_10cm 99 instead of 109, obstacle_jumps 68 instead of 72 (same optima, the others within 2)."""
    stage_regularization: float = 1e-4
    """The same for every later continuation stage. Such a stage starts from the previous stage's optimum, closer
    but no Newton-close guess once its cost terms have stiffened: from 1e-9 the walk's final stage spent 7
    iterations of rejected steps; from 1e-4 it needs 41 iterations instead of 46 and vertical_jump_10cm 109 instead
    of 126 (1e-2 here: 43 and 119)."""


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


def _extract(built: BuiltProblem, solver: crocoddyl.SolverBoxFDDP, log: SolverLog) -> PlanResult:
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
    return _extract(built, solver, log)


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


def robot_mass(robot: RobotSetup) -> float:
    """Total mass of ``robot`` including its payload [kg]."""
    return robot.mass
