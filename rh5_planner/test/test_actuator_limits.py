"""The actuator limits (stroke, velocity, force of Table I) as per-knot joint boxes, and inside the shooting problem.

Each limit kind is checked both ways: with its bound tightened below what a configuration uses, the box excludes
it (a violation the barrier or Box-FDDP's control box acts on); relaxed above it, the box holds it (no violation).
1-DoF units (Hip3, knees) are exact; 2-DoF units (torso, wrists, ankles) are inner boxes of the row-wise limit, so
"relaxed" there means above the sum of |A_ij x_j| over the joints.
"""

from __future__ import annotations

import crocoddyl  # noqa: F401  (before pinocchio, design/crocoddyl_wheels.md)
import numpy as np
import pytest

from rh5_hyrodyn_mapper.model import joint_limits
from rh5_msgs_py.names import JOINT_INDEX, JOINT_NAMES
from rh5_planner.actuator_bounds import ActuatorBounds, JointBoxes, parallel_units
from rh5_planner.actuator_constraints import LINEAR_ACTUATORS, actuator_usage
from rh5_planner.cost_config import load_cost_config
from rh5_planner.motions import get_motion
from rh5_planner.ocp import build_problem

# share_floor 0: the 2-DoF boxes take the shape of the sample itself (inside once the row sums allow it)
EXACT = {"stroke_beta": 1.0, "velocity_beta": 1.0, "force_beta": 1.0, "stroke_activation": 0.0, "share_floor": 0.0}
UNITS = {m.name: m for m in parallel_units()}


def _sample(seed: int = 3) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A configuration inside the joint ranges (the middle 60 %), velocities and torques of a quarter of the limits."""
    rng = np.random.default_rng(seed)
    limits = joint_limits()
    lo, hi = np.asarray(limits.position_lower), np.asarray(limits.position_upper)
    q = lo + (hi - lo) * rng.uniform(0.2, 0.8, len(JOINT_NAMES))
    v = np.asarray(limits.velocity_max) * rng.uniform(-0.25, 0.25, len(JOINT_NAMES))
    tau = np.asarray(limits.torque_max) * rng.uniform(-0.25, 0.25, len(JOINT_NAMES))
    return q[None], v[None], tau[None]


def _unit_usage(kind: str, unit: str, q: np.ndarray, v: np.ndarray, tau: np.ndarray) -> float:
    usage = actuator_usage(q, v, tau)[kind][0]
    return float(max(usage[LINEAR_ACTUATORS.index(a)] for a in UNITS[unit].actuators))


def _inside(kind: str, unit: str, boxes: JointBoxes, q: np.ndarray, v: np.ndarray, tau: np.ndarray) -> bool:  # noqa: PLR0917
    jj = [JOINT_INDEX[j] for j in UNITS[unit].joints]
    if kind == "stroke":
        return bool(((q[0, jj] >= boxes.q_lower[0, jj]) & (q[0, jj] <= boxes.q_upper[0, jj])).all())
    if kind == "velocity":
        return bool((np.abs(v[0, jj]) <= boxes.v_max[0, jj]).all())
    return bool((np.abs(tau[0, jj]) <= boxes.tau_max[0, jj]).all())


def _row_sum_usage(kind: str, unit: str, q: np.ndarray, v: np.ndarray, tau: np.ndarray) -> float:
    """max_i sum_j |A_ij x_j| / limit: what a 2-DoF inner box must allow to hold x (>= the exact usage)."""
    model = UNITS[unit]
    jj = [JOINT_INDEX[j] for j in model.joints]
    jac = model.jacobian(q[0, jj])
    if kind == "velocity":
        return float((np.abs(jac) @ np.abs(v[0, jj])).max() / model.limits.velocity_max[0])
    inv_t = np.linalg.inv(jac.T)
    return float((np.abs(inv_t) @ np.abs(tau[0, jj])).max() / model.limits.force_max[0])


@pytest.mark.parametrize("unit", ["LLKnee", "LRHip3", "Body", "ALWrist", "LLAnkle"])
@pytest.mark.parametrize("kind", ["velocity", "force"])
def test_velocity_and_force_boxes_tightened_and_relaxed(kind: str, unit: str) -> None:
    q, v, tau = _sample()
    used = _unit_usage(kind, unit, q, v, tau)
    assert used > 0.01
    jj = [JOINT_INDEX[j] for j in UNITS[unit].joints]

    def boxes(factor: float):
        factors = np.ones(len(JOINT_NAMES))
        factors[jj] = factor
        return ActuatorBounds(EXACT, 1, {kind: factors}).boxes(q, v, tau)

    assert not _inside(kind, unit, boxes(0.95 * used), q, v, tau), "tightened below its use: a violation"
    relaxed = 1.05 * (used if UNITS[unit].dof == 1 else _row_sum_usage(kind, unit, q, v, tau))
    assert _inside(kind, unit, boxes(relaxed), q, v, tau), "relaxed above its use: none"


@pytest.mark.parametrize("unit", ["LLKnee", "LRHip3", "Body", "LLAnkle"])
def test_stroke_boxes_tightened_and_relaxed(unit: str) -> None:
    q, v, tau = _sample()
    used = _unit_usage("stroke", unit, q, v, tau)
    jj = [JOINT_INDEX[j] for j in UNITS[unit].joints]

    def boxes(factor: float):
        factors = np.ones(len(JOINT_NAMES))
        factors[jj] = factor
        return ActuatorBounds(EXACT, 1, {"stroke": factors}).boxes(q, v, tau)

    assert not _inside("stroke", unit, boxes(0.95 * used), q, v, tau)
    assert _inside("stroke", unit, boxes(1.05 * max(used, 0.05)), q, v, tau)


def test_one_dof_boxes_are_exact() -> None:
    """Knee: velocity bound v_max / |J|, torque bound f_max |J|, stroke the joint interval of the stroke."""
    q, v, tau = _sample()
    boxes = ActuatorBounds(EXACT, 1).boxes(q, v, tau)
    knee = UNITS["LLKnee"]
    j = JOINT_INDEX["LLKnee"]
    jac = abs(float(knee.jacobian(q[0, [j]])[0, 0]))
    assert boxes.v_max[0, j] == pytest.approx(knee.limits.velocity_max[0] / jac)
    assert boxes.tau_max[0, j] == pytest.approx(knee.limits.force_max[0] * jac)
    for end in (boxes.q_lower[0, j], boxes.q_upper[0, j]):
        length = float(knee.inverse(np.array([end]))[0])
        assert knee.limits.length_min[0] - 1e-4 <= length <= knee.limits.length_max[0] + 1e-4


def test_tighten_lowers_only_the_chosen_knots_and_joints() -> None:
    q, v, tau = _sample()
    qs, vs, taus = np.repeat(q, 3, 0), np.repeat(v, 3, 0), np.repeat(tau, 2, 0)
    bounds = ActuatorBounds(EXACT, 3)
    before = bounds.boxes(qs, vs, taus)
    knee = JOINT_INDEX["LRKnee"]
    bounds.tighten("velocity", [1], [knee], 0.5)
    after = bounds.boxes(qs, vs, taus)
    assert after.v_max[1, knee] == pytest.approx(0.5 * before.v_max[1, knee])
    np.testing.assert_array_equal(np.delete(after.v_max, knee, axis=1), np.delete(before.v_max, knee, axis=1))
    assert after.v_max[0, knee] == before.v_max[0, knee]


@pytest.mark.parametrize("kind", ["stroke", "velocity", "force"])
def test_refresh_writes_the_bounds_into_the_problem(kind: str) -> None:
    """Through the built problem: at a knot whose knee uses its actuator at ``usage``, the joint-limit barrier
    (stroke, velocity) costs nothing with the bound relaxed and something with it tightened; the force bound is
    Box-FDDP's control box of that knot."""
    motion = get_motion("squat_with_5kg_weights", {"total_time_s": 0.6, "hold_s": 0.1})
    knee = JOINT_INDEX["LLKnee"]

    def build(beta: float):
        config = load_cost_config()
        config["actuator_limits"][f"{kind}_beta"] = beta
        built = build_problem(motion, config)
        model = built.robot.model
        xs = [x.copy() for x in built.xs_guess]
        vi = model.nq + int(built.actuators.v_order[knee])
        xs[2][vi] = 1.2  # rad/s of LLKnee at node 2 (half its joint limit, ~40 % of its actuator's speed)
        us = [u.copy() for u in built.us_guess]
        built.actuators.refresh(xs, us)
        return built, xs, us

    tight = {"stroke": 0.2, "velocity": 0.2, "force": 0.03}[kind]  # the standing knee uses ~7 % of its force
    for beta, violated in ((tight, True), (1.0, False)):
        built, xs, us = build(beta)
        model = built.robot.model
        qk = xs[2][built.actuators.q_order][None]
        vk = xs[2][model.nq + built.actuators.v_order][None]
        tk = np.asarray(us[2])[built.actuators.v_order - 6][None]
        usage = actuator_usage(qk, vk, tk)[kind][0][LINEAR_ACTUATORS.index("LLKnee_Act1")]
        assert (usage > beta) == violated, (kind, beta, usage)
        if kind == "force":
            u_ub = np.asarray(built.problem.runningModels[2].u_ub)[built.actuators.v_order[knee] - 6]
            assert (abs(tk[0, knee]) > u_ub) == violated
            continue
        running = built.problem.runningModels[2]
        data = running.createData()
        running.calc(data, xs[2], us[2])
        barrier = data.differential.costs.costs["joint_limits"].cost
        assert (barrier > 0.0) == violated, (kind, beta, barrier)


@pytest.mark.parametrize("unit", sorted(UNITS))
def test_jacobian_of_the_boxes_is_the_derivative_of_the_stroke_map(unit: str) -> None:
    """The velocity and force boxes rest on J(y) = dl/dy; at random configurations it matches central finite
    differences of the exact stroke map l(y) (the mapper's inverse kinematics) to 1e-6 relative."""
    model = UNITS[unit]
    limits = joint_limits()
    jj = [JOINT_INDEX[j] for j in model.joints]
    lo, hi = np.asarray(limits.position_lower)[jj], np.asarray(limits.position_upper)[jj]
    y = lo + (hi - lo) * np.random.default_rng(7).uniform(0.2, 0.8, (5, len(jj)))
    jac = model.jacobian(y)
    h = 1e-6
    for j in range(len(jj)):
        step = np.zeros(len(jj))
        step[j] = h
        column = (model.inverse(y + step) - model.inverse(y - step)) / (2 * h)
        np.testing.assert_allclose(jac[:, :, j], column, rtol=1e-6, atol=1e-9 * np.abs(jac).max())
