"""Real Box-FDDP solves on the full RH5 model: convergence, contact stability, limits, physics, interpolation.

Each solve runs once per module (fixtures). Tolerances:
* CoP: the optimiser works on the 50 % rectangle shrunk by costs.yaml ``margin`` (10 %), and the soft barrier
  lets it overshoot its own bound by a little; we accept 1 mm beyond the unshrunk 50 % region (2 % of its
  100 mm length) and demand >= 99 % of contact knots inside.
* Friction: |f_t| <= mu f_z + 1 N (the cone is an inner pyramid of the optimiser's mu (1 - margin)).
* Limits: joint positions and velocities against the real limits, torques against the Box-FDDP box (1e-9).
* Feet in contact: sole twist below 1e-3 (m/s, rad/s): the rigid contact holds the acceleration at zero
  with Baumgarte damping and the touch-down impulse zeroes the velocity.
"""

from __future__ import annotations

import math

import crocoddyl  # noqa: F401  (before pinocchio, design/crocoddyl_wheels.md)
import numpy as np
import pinocchio as pin
import pytest

from rh5_hyrodyn_mapper.model import model_hash, q_index, v_index
from rh5_msgs_py.names import FOOT_FRAMES
from rh5_msgs_py.trajectory_file import NQ, load_trajectory
from rh5_planner.actuator_constraints import check_trajectory
from rh5_planner.cost_config import load_cost_config
from rh5_planner.feet import FOOT_SIZE_M
from rh5_planner.interpolation import euler_tangents, interpolate
from rh5_planner.motions import MOTIONS, PAPER_SETTINGS, MotionError, get_motion
from rh5_planner.ocp import PlanResult, SolverSettings, build_problem, contact_cones, solve

CONFIG = load_cost_config()
MU = CONFIG["contact_stability"]["mu"]
COP_FRACTION = CONFIG["contact_stability"]["cop_fraction"]
COP_TOLERANCE = 1e-3
G = 9.81

# The paper's motions: squat, fast squats (hardware experiment III) and the full walk (0.5 m, 4 steps, 1.5 s,
# 5 kg per hand); all three converge to th_stop 1e-7 within the test budget (~6 s of solving together).
SQUAT = get_motion("squat_with_5kg_weights")
FAST_SQUATS = get_motion("fast_squats")
WALK = get_motion("walk_with_5kg_weights")
STOP = 1e-7


@pytest.fixture(scope="module")
def squat() -> PlanResult:
    return solve(SQUAT, SolverSettings(max_iterations=100, stop_threshold=STOP))


@pytest.fixture(scope="module")
def fast_squats() -> PlanResult:
    return solve(FAST_SQUATS, SolverSettings(max_iterations=100, stop_threshold=STOP))


@pytest.fixture(scope="module")
def walk() -> PlanResult:
    return solve(WALK, SolverSettings(max_iterations=150, stop_threshold=STOP))


@pytest.fixture(scope="module", params=["squat", "fast_squats", "walk"])
def plan(request: pytest.FixtureRequest) -> PlanResult:
    return request.getfixturevalue(request.param)


def _assert_converged(plan: PlanResult, max_iterations: int) -> None:
    log = plan.solver_log
    assert log.converged, log
    # Box-FDDP's gradient test, or the cost stalled over full steps (SolverSettings.cost_tolerance)
    assert log.stop_criterion < STOP or log.stop_reason == "cost_stalled"
    assert log.iterations <= max_iterations, log
    assert math.isfinite(log.cost)


def test_squat_converges(squat: PlanResult) -> None:
    _assert_converged(squat, 30)  # measured 12


def test_iterations_are_counted_as_run() -> None:
    """One progress report per Box-FDDP iteration, numbered 1..N over all continuation stages, and N is the
    logged count (solver.iter alone counts one short in every stage that converges)."""
    reports: list[int] = []
    plan = solve(SQUAT, SolverSettings(max_iterations=100, callback=lambda it, _cost, _stop: reports.append(it)))
    log = plan.solver_log
    assert reports == list(range(1, len(reports) + 1))
    assert log.iterations == len(reports) == sum(stage.iterations for stage in log.stages)


def test_fast_squats_converge(fast_squats: PlanResult) -> None:
    _assert_converged(fast_squats, 30)  # measured 10


def test_walk_converges(walk: PlanResult) -> None:
    _assert_converged(walk, 80)  # measured 41 with the rest phase


def test_initial_regularisation_changes_the_path_not_the_optimum() -> None:
    """From Crocoddyl's own initial regularisation (1e-9) in every stage the walk takes another path (46 iterations
    against 41) to the same optimum: SolverSettings' regularisations reach Box-FDDP and only shorten the way.

    On the paper's cost set (actuator limits off): the actuator bounds are built at each stage's iterate, so with
    them another path also means a slightly other problem (the optima then differ by ~1e-6 of the cost)."""
    paper = WALK.with_overrides({"actuator_limits": False})
    ours = solve(paper, SolverSettings(max_iterations=150, stop_threshold=STOP))
    own = solve(
        paper,
        SolverSettings(max_iterations=150, stop_threshold=STOP, guess_regularization=1e-9, stage_regularization=1e-9),
    )
    _assert_converged(own, 80)
    assert own.solver_log.iterations != ours.solver_log.iterations
    assert own.solver_log.cost == pytest.approx(ours.solver_log.cost, rel=1e-6)
    np.testing.assert_allclose(own.xs, ours.xs, atol=1e-3)


def test_walk_moves_forward(walk: PlanResult) -> None:
    # ends balanced: the CoM over the final 50 % CoP rectangle of the soles (measured 0.458, 42 mm behind their middle)
    half_cop_x = 0.5 * COP_FRACTION * FOOT_SIZE_M[0]
    assert walk.com[-1, 0] - walk.com[0, 0] == pytest.approx(WALK.length_m, abs=half_cop_x)
    assert walk.xs[-1, 0] - walk.xs[0, 0] == pytest.approx(WALK.length_m, abs=0.06)  # base (measured 0.454)
    assert not walk.contact_phases.all(), "a walk has single-support knots"


def test_walk_ends_at_rest(walk: PlanResult) -> None:
    """The rest after the steps lets the walk stop: without it the plan ended at 0.03 m/s, CoP on the toes."""
    assert WALK.rest_s > 0
    nq = walk.robot.model.nq
    assert np.linalg.norm(walk.xs[-1, nq : nq + 3]) < 0.01  # base linear velocity [m/s] (measured 0.004)
    assert np.abs(walk.xs[-1, nq + 6 :]).max() < 0.05  # joint velocities [rad/s] (measured 0.005)


def test_squat_tracks_com_range(squat: PlanResult) -> None:
    depth = squat.com[0, 2] - squat.com[:, 2].min()
    assert depth == pytest.approx(SQUAT.com_range_m, abs=0.03)  # soft CoM task vs torque/posture costs


def test_fast_squats_track_com_range(fast_squats: PlanResult) -> None:
    depth = fast_squats.com[0, 2] - fast_squats.com[:, 2].min()
    assert depth == pytest.approx(FAST_SQUATS.com_range_m, abs=0.03)  # measured 0.143 of 0.15


def test_cop_inside_region(plan: PlanResult) -> None:
    contact = plan.contact_phases
    cop = plan.cop[contact]
    half = 0.5 * COP_FRACTION * np.array(FOOT_SIZE_M) + COP_TOLERANCE
    inside = (np.abs(cop[:, 0]) <= half[0]) & (np.abs(cop[:, 1]) <= half[1])
    assert inside.mean() >= 0.99, f"CoP outside the 50 % region at {np.count_nonzero(~inside)} of {inside.size}"


def test_friction_cone(plan: PlanResult) -> None:
    w = plan.wrenches[plan.contact_phases]
    fz = w[:, 2]
    assert (fz > 0).all()
    tangential = np.linalg.norm(w[:, :2], axis=1)
    assert (tangential <= MU * fz + 1.0).all()


def test_joint_limits(plan: PlanResult) -> None:
    robot = plan.robot
    nq = robot.model.nq
    q, v = plan.xs[:, 7:nq], plan.xs[:, nq + 6 :]
    assert (q >= robot.q_lower - 1e-9).all()
    assert (q <= robot.q_upper + 1e-9).all()
    assert (np.abs(v) <= robot.v_max + 1e-9).all()


def test_actuator_limits_hold(plan: PlanResult) -> None:
    """Every linear actuator within its Table I stroke, velocity and force at every knot and at 1 kHz (the paper's
    set put the knee actuators of the walk and the squat 28 % and 1 % over their speed)."""
    check = check_trajectory(plan.to_trajectory_data())
    assert check.ok, check.over[:5]
    log = plan.solver_log.actuator_limits
    assert log.within_limits
    assert log.enforced == ["stroke", "velocity", "force"]


def test_torques_within_box(plan: PlanResult) -> None:
    assert (np.abs(plan.us) <= plan.robot.tau_max + 1e-9).all()


def test_newton_law_holds_at_every_knot(plan: PlanResult) -> None:
    """Sum of the extracted contact forces (world) = m (a_CoM - g): the wrenches are the ones the dynamics used."""
    robot, model = plan.robot, plan.robot.model
    data = model.createData()
    nq = model.nq
    impacts = {i for i in range(1, len(plan.times)) if plan.contact_phases[i].sum() > plan.contact_phases[i - 1].sum()}
    for k in range(len(plan.times) - 1):
        if k + 1 in impacts:
            continue  # the velocity jump of the impulse is not a force over the interval
        x0, x1 = plan.xs[k], plan.xs[k + 1]
        a = (x1[nq:] - x0[nq:]) / (plan.times[k + 1] - plan.times[k])
        pin.centerOfMass(model, data, x0[:nq], x0[nq:], a)
        pin.framesForwardKinematics(model, data, x0[:nq])
        force = sum(data.oMf[fid].rotation @ plan.wrenches[k, i, :3] for i, fid in enumerate(robot.foot_ids.values()))
        expected = robot.mass * (data.acom[0] - model.gravity.linear)
        np.testing.assert_allclose(force, expected, atol=1e-6 * robot.mass * G)


def test_standing_forces_balance_gravity_with_payload() -> None:
    """Double support at rest (squat start, quasi-static torques): sum f_z = m g with the 10 kg payload."""
    built = build_problem(SQUAT)
    model = built.robot.model
    assert built.robot.mass == pytest.approx(sum(i.mass for i in model.inertias))
    assert built.robot.mass - 10.0 == pytest.approx(
        sum(i.mass for i in build_problem(SQUAT.with_overrides({"payload_kg_per_hand": 0.0})).robot.model.inertias)
    )
    running, data = built.problem.runningModels[0], built.problem.runningDatas[0]
    running.calc(data, built.robot.x0, built.us_guess[0])
    assert np.abs(data.differential.xout).max() < 1e-6  # at rest
    contacts = data.differential.multibody.contacts.contacts
    fz = sum(contacts[f"{FOOT_FRAMES[side]}_contact"].f.linear[2] for side in ("left", "right"))
    assert fz == pytest.approx(built.robot.mass * G, rel=1e-6)


def test_feet_do_not_slide(plan: PlanResult) -> None:
    """Soles in contact stay put: < 3 mm drift per contact phase (measured <= 1.5 mm with the Baumgarte position
    term), sole twist < 0.03 (m/s, rad/s) (measured <= 0.005 squats, ~0.027 walk).

    The rigid contact constrains the sole acceleration; the symplectic Euler step and the Baumgarte damping
    leave a small first-order velocity residue, not a slide.
    """
    model = plan.robot.model
    data = model.createData()
    nq = model.nq
    worst_twist, worst_drift = 0.0, 0.0
    anchor: dict[int, np.ndarray] = {}
    for k, x in enumerate(plan.xs):
        pin.forwardKinematics(model, data, x[:nq], x[nq:])
        pin.updateFramePlacements(model, data)
        for i, fid in enumerate(plan.robot.foot_ids.values()):
            if not plan.contact_phases[k, i]:
                anchor.pop(i, None)
                continue
            twist = pin.getFrameVelocity(model, data, fid, pin.ReferenceFrame.LOCAL).vector
            worst_twist = max(worst_twist, float(np.abs(twist).max()))
            position = data.oMf[fid].translation.copy()
            start = anchor.setdefault(i, position)
            worst_drift = max(worst_drift, float(np.linalg.norm(position - start)))
    assert worst_twist < 0.03
    assert worst_drift < 3e-3


def test_trajectory_file_roundtrip_and_joint_order(squat: PlanResult, tmp_path) -> None:
    path = squat.save(tmp_path / "squat.rh5traj")
    data = load_trajectory(path, expected_model_hash=model_hash())
    model = squat.robot.model
    qi, vi = q_index(model), v_index(model)
    np.testing.assert_array_equal(data.joint_positions(), squat.xs[:, qi])
    np.testing.assert_array_equal(data.joint_velocities(), squat.xs[:, model.nq + vi])
    np.testing.assert_array_equal(data.controls, squat.us[:, vi - 6])
    np.testing.assert_array_equal(data.base_quaternions_xyzw(), squat.xs[:, 3:7])
    assert data.solver_log["converged"]


def test_interpolation_hits_knots_and_matches_velocities(walk: PlanResult) -> None:
    data = walk.to_trajectory_data()
    samples = interpolate(data)
    assert samples.times[0] == data.times[0]
    assert samples.times[-1] == pytest.approx(data.times[-1])
    at_knots = np.searchsorted(samples.times, data.times)
    np.testing.assert_allclose(samples.times[at_knots], data.times)
    np.testing.assert_allclose(samples.states[at_knots, :NQ], data.states[:, :NQ], atol=1e-9)
    # velocities at the knots: the Euler-consistent slopes, or (a segment moved linearly, see _limit_overshoot)
    # the mean velocity of the segment that starts there (what the Euler integrator stores at the next knot)
    planned = data.states[:, NQ + 6 :]
    knots_q = data.states[:, 7:NQ]
    secants = np.diff(knots_q, axis=0) / np.diff(data.times)[:, None]
    following = np.vstack([secants, planned[-1:]])
    at = samples.states[at_knots, NQ + 6 :]
    assert (np.isclose(at, euler_tangents(planned), atol=1e-9) | np.isclose(at, following, atol=1e-6)).all()
    # Euler-consistent slopes: the reference accelerates no harder than the plan did (RMS over all joints);
    # the knot velocities as slopes made every segment swing from 4 a to -2 a (twice the RMS)
    euler_acc = np.diff(planned, axis=0) / np.diff(data.times)[:, None]
    assert np.sqrt(np.mean(samples.joint_accelerations**2)) <= np.sqrt(np.mean(euler_acc**2))
    # no sample moves faster than what was planned around it (no spline overshoot past the knot velocities)
    fd = np.abs(np.diff(samples.states[:, 7:NQ], axis=0) / np.diff(samples.times)[:, None])
    segment_of = np.clip(np.searchsorted(data.times, samples.times[:-1], side="right") - 1, 0, data.times.size - 2)
    slopes = np.maximum(np.abs(planned), np.abs(euler_tangents(planned)))  # either is a planned speed
    envelope = np.maximum(np.maximum(slopes[segment_of], slopes[segment_of + 1]), np.abs(secants[segment_of]))
    assert (fd <= envelope * 1.001 + 1e-6).all()
    # the derivative of the joint splines equals the interpolated velocities (central differences)
    segment = np.searchsorted(data.times, samples.times, side="right")
    interior = np.flatnonzero(segment[:-2] == segment[2:]) + 1  # both neighbours inside the same segment
    q = samples.states[:, 7:NQ]
    numeric = (q[interior + 1] - q[interior - 1]) / (samples.times[interior + 1] - samples.times[interior - 1])[:, None]
    np.testing.assert_allclose(numeric, samples.states[interior, NQ + 6 :], atol=2e-2 * max(1.0, np.abs(q).max()))
    # torques: zero-order hold of the knot controls
    k = 3
    inside = (samples.times >= data.times[k]) & (samples.times < data.times[k + 1])
    np.testing.assert_array_equal(samples.controls[inside], np.broadcast_to(data.controls[k], (inside.sum(), 32)))
    norms = np.linalg.norm(samples.states[:, 3:7], axis=1)
    np.testing.assert_allclose(norms, 1.0, atol=1e-12)


def test_walk_step_ramp_and_the_papers_fast_walk() -> None:
    """ramp_steps grows and shrinks the first and last steps around equal cruise steps; without it the landings
    are the old equal fractions. PAPER_SETTINGS gives back the paper's 0.7 m / 0.7 s fast walk (23 knots)."""
    fast = get_motion("fast_walk_1m_s")
    steps = np.diff(np.r_[0.0, fast.landings()[:-1]])  # type: ignore[attr-defined]
    np.testing.assert_allclose(steps / steps.max(), [1 / 3, 2 / 3, 1, 1, 1, 1, 1, 2 / 3, 1 / 3])
    assert fast.cruise_speed_m_s == pytest.approx(1.03, abs=0.01)  # type: ignore[attr-defined]
    np.testing.assert_allclose(WALK.landings(), [1 / 3, 2 / 3, 1, 1])  # type: ignore[attr-defined]
    paper = get_motion("fast_walk_1m_s", PAPER_SETTINGS["fast_walk_1m_s"])
    assert (paper.n_knots, paper.swing_knots, paper.actuator_limits) == (23, 5, False)  # type: ignore[attr-defined]


def test_motion_library_overrides() -> None:
    assert set(MOTIONS) == {
        "walk_with_5kg_weights",
        "fast_walk_1m_s",
        "squat_with_5kg_weights",
        "vertical_jump_1cm",
        "vertical_jump_10cm",
        "obstacle_jumps",
        "one_leg_balancing",
        "static_stepping",
        "fast_squats",
    }
    walk = get_motion("walk_with_5kg_weights")
    assert (walk.length_m, walk.step_height_m, walk.total_time_s, walk.dt) == (0.5, 0.05, 1.5, 0.03)
    assert walk.with_overrides({"length_m": 1}).length_m == 1.0
    with pytest.raises(MotionError, match="unknown parameters"):
        walk.with_overrides({"lenght_m": 0.4})
    with pytest.raises(MotionError, match="must be"):
        walk.with_overrides({"n_steps": "four"})
    with pytest.raises(MotionError, match="positive"):
        walk.with_overrides({"dt": -0.01})
    with pytest.raises(MotionError, match="unknown motion"):
        get_motion("moonwalk")
    specs = get_motion("walk_with_5kg_weights").knots(build_problem(SQUAT).robot.reference())
    assert sum(not s.impulse for s in specs) == walk.n_knots
    assert sum(s.impulse for s in specs) == walk.n_steps


def test_contact_stability_forms_bound_the_same_region() -> None:
    """friction_and_cop is the wrench cone without its 8 yaw-torque rows: the same friction, normal-force and CoP
    rows from the same mu, cop_fraction, margin and min_normal_force; each form names its costs in the knots."""
    settings = CONFIG["contact_stability"]
    both = frozenset({"friction", "cop"})
    (cone,) = contact_cones({**settings, "form": "wrench_cone"}, both)
    friction, cop = contact_cones({**settings, "form": "friction_and_cop"}, both)
    assert (cone.A.shape[0], friction.A.shape[0], cop.A.shape[0]) == (17, 5, 4)
    np.testing.assert_allclose(cone.A[:5, :3], friction.A)
    np.testing.assert_allclose(cone.A[:5, 3:], 0.0)
    np.testing.assert_allclose(cone.A[5:9], cop.A)
    np.testing.assert_allclose(np.r_[cone.lb[:9], cone.ub[:9]], np.r_[friction.lb, cop.lb, friction.ub, cop.ub])
    (only,) = contact_cones({**settings, "form": "friction_and_cop"}, frozenset({"cop"}))
    assert isinstance(only, type(cop))
    assert contact_cones({**settings, "form": "friction_and_cop"}, frozenset()) == ()
    with pytest.raises(ValueError, match=r"contact_stability\.form"):
        contact_cones({**settings, "form": "pyramid"}, both)
    for form, names in (
        ("wrench_cone", {"wrench_cone_left"}),
        ("friction_and_cop", {"friction_cone_left", "cop_left"}),
    ):
        config = load_cost_config()
        config["contact_stability"]["form"] = form
        knot = build_problem(SQUAT, config).problem.runningModels[0]
        costs = set(knot.differential.costs.costs.todict())
        assert names <= costs
        assert not ({"wrench_cone_left", "friction_cone_left", "cop_left"} - names) & costs
