"""Box-FDDP solves of the jump and the hardware-experiment motions: convergence and physical consistency.

Cheap variants only (CI budget): the paper's 1 cm vertical jump (0.9 s, 10 ms knots), and
one_leg_balancing / static_stepping with shortened phases and 50 ms knots. Full-length and expensive motions are in
bench/planner.py. Tolerances as in test_problem.py (CoP 1 mm beyond the 50 % rectangle, friction + 1 N).
"""

from __future__ import annotations

import crocoddyl  # noqa: F401  (before pinocchio, design/crocoddyl_wheels.md)
import numpy as np
import pinocchio as pin
import pytest

from rh5_msgs_py.names import JOINT_NAMES
from rh5_planner.actuator_constraints import check_trajectory
from rh5_planner.cost_config import load_cost_config, motion_config
from rh5_planner.feet import FOOT_SIZE_M
from rh5_planner.limit_scale import limit_factors
from rh5_planner.motions import VERIFIED_MOTIONS, get_motion
from rh5_planner.ocp import PlanResult, SolverSettings, build_robot, solve

CONFIG = load_cost_config()
MU = CONFIG["contact_stability"]["mu"]
COP_HALF = 0.5 * CONFIG["contact_stability"]["cop_fraction"] * np.array(FOOT_SIZE_M) + 1e-3

# the paper's 0.9 s: with the actuator limits the 0.6 s variant's shorter crouch left the soles 6 mm up (costs.yaml
# foot weight 1e6) or did not converge (1e8)
JUMP = get_motion("vertical_jump_1cm")
SHORT_PHASES = [["hold", 0.1], ["shift_left", 0.8], ["lift", 0.5], ["lower", 0.5], ["center", 0.6]]
BALANCING = get_motion("one_leg_balancing", {"phases": SHORT_PHASES, "dt": 0.05})
STEPPING = get_motion("static_stepping", {"phases": SHORT_PHASES, "dt": 0.05})
# one of the three obstacle jumps (0.25 m sole clearance, 0.2 m forward, 10 ms knots); all three in bench/planner.py
OBSTACLE_JUMP = get_motion("obstacle_jumps", {"total_time_s": 0.9, "length_m": 0.2, "n_jumps": 1})


@pytest.fixture(scope="module")
def jump() -> PlanResult:
    return solve(JUMP, SolverSettings(max_iterations=300))


@pytest.fixture(scope="module")
def balancing() -> PlanResult:
    return solve(BALANCING, SolverSettings(max_iterations=150))


@pytest.fixture(scope="module")
def stepping() -> PlanResult:
    return solve(STEPPING, SolverSettings(max_iterations=150))


@pytest.fixture(scope="module")
def fast_walk() -> PlanResult:
    return solve(get_motion("fast_walk_1m_s"), SolverSettings(max_iterations=200))


@pytest.fixture(scope="module", params=["jump", "balancing", "stepping", "fast_walk"])
def plan(request: pytest.FixtureRequest) -> PlanResult:
    return request.getfixturevalue(request.param)


def _sole_positions(plan: PlanResult) -> np.ndarray:
    """(N, 2, 3) world positions of the (left, right) soles at every knot."""
    model = plan.robot.model
    data = model.createData()
    out = []
    for x in plan.xs:
        pin.framesForwardKinematics(model, data, x[: model.nq])
        out.append([data.oMf[fid].translation.copy() for fid in plan.robot.foot_ids.values()])
    return np.array(out)


def test_verified(plan: PlanResult) -> None:
    assert plan.motion.name in VERIFIED_MOTIONS
    log = plan.solver_log
    assert log.converged, log
    assert log.stop_reason in ("gradient", "cost_stalled")
    # the jump's push-off holds the knee actuators at their speed bound (actuator limits, issue 14): ~144 iterations;
    # the balancing motions ~20
    assert log.iterations < (200 if plan.motion.kind == "jump" else 150)


def test_actuator_limits_hold(plan: PlanResult) -> None:
    """Every linear actuator within its Table I stroke, velocity and force at every knot and at 1 kHz."""
    assert plan.motion.actuator_limits
    check = check_trajectory(plan.to_trajectory_data())
    assert check.ok, check.over[:5]
    assert plan.solver_log.actuator_limits.within_limits
    assert plan.solver_log.actuator_limits.enforced == ["stroke", "velocity", "force"]


def test_cop_and_friction(plan: PlanResult) -> None:
    contact = plan.contact_phases
    cop = plan.cop[contact]
    inside = (np.abs(cop[:, 0]) <= COP_HALF[0]) & (np.abs(cop[:, 1]) <= COP_HALF[1])
    assert inside.mean() >= 0.99
    w = plan.wrenches[contact]
    assert (w[:, 2] > 0).all()
    assert (np.linalg.norm(w[:, :2], axis=1) <= MU * w[:, 2] + 1.0).all()


def test_limits_hold(plan: PlanResult) -> None:
    robot, nq = plan.robot, plan.robot.model.nq
    assert (np.abs(plan.us) <= robot.tau_max + 1e-9).all()
    q, v = plan.xs[:, 7:nq], plan.xs[:, nq + 6 :]
    assert (q >= robot.q_lower - 1e-9).all()
    assert (q <= robot.q_upper + 1e-9).all()
    assert (np.abs(v) <= robot.v_max + 1e-9).all()


def test_newton_law_and_flight(plan: PlanResult) -> None:
    """Sum of contact forces = m (a_CoM - g) over every interval without an impact; zero without contact, so in
    flight the CoM falls at g."""
    model, robot = plan.robot.model, plan.robot
    data = model.createData()
    nq = model.nq
    assert np.all(plan.wrenches[~plan.contact_phases] == 0.0)
    impacts = {i for i in range(1, len(plan.times)) if plan.contact_phases[i].sum() > plan.contact_phases[i - 1].sum()}
    for k in range(len(plan.times) - 1):
        if k + 1 in impacts:
            continue
        x0, x1 = plan.xs[k], plan.xs[k + 1]
        a = (x1[nq:] - x0[nq:]) / (plan.times[k + 1] - plan.times[k])
        pin.centerOfMass(model, data, x0[:nq], x0[nq:], a)
        pin.framesForwardKinematics(model, data, x0[:nq])
        force = sum(data.oMf[fid].rotation @ plan.wrenches[k, i, :3] for i, fid in enumerate(robot.foot_ids.values()))
        np.testing.assert_allclose(force, robot.mass * (data.acom[0] - model.gravity.linear), atol=1e-5 * robot.mass)


def test_feet_stay_in_contact(plan: PlanResult) -> None:
    soles = _sole_positions(plan)
    for side in range(2):
        contact = plan.contact_phases[:, side]
        starts = np.flatnonzero(contact & ~np.r_[False, contact[:-1]])
        for start in starts:
            end = start + int(np.argmin(contact[start:])) if not contact[start:].all() else len(contact)
            drift = np.linalg.norm(soles[start:end, side] - soles[start, side], axis=1).max()
            # the rigid contacts' Baumgarte term (30 ms Euler knots) lets a loaded sole creep: the 1 m/s walk's cruise
            # stances sink up to 5.5 mm (plus ~2 mm sideways); Kp 400 instead of 100 made it worse. Not yet solved.
            assert drift < (6e-3 if plan.motion.name == "fast_walk_1m_s" else 3e-3), (side, start, drift)


def test_fast_walk_reaches_1_m_s(fast_walk: PlanResult) -> None:
    """The CoM averages >= 1 m/s over a stride (two step periods) of the cruise steps and ends the walk's length
    ahead, at rest."""
    motion = fast_walk.motion
    stride = 2 * (motion.swing_knots + motion.support_knots) * motion.dt  # type: ignore[attr-defined]
    com, times = fast_walk.com[:, 0], fast_walk.times
    ends = np.searchsorted(times, times + stride - 1e-9)
    ok = ends < len(times)
    speed = (com[ends[ok]] - com[ok]) / (times[ends[ok]] - times[ok])
    assert speed.max() >= 1.0  # measured 1.01
    assert com[-1] - com[0] == pytest.approx(motion.length_m, abs=0.05)  # type: ignore[attr-defined]
    assert np.abs(fast_walk.xs[-1, fast_walk.robot.model.nq :]).max() < 0.05


def test_jump_reaches_its_height(jump: PlanResult) -> None:
    soles = _sole_positions(jump)
    flight = ~jump.contact_phases.any(axis=1)
    assert flight.sum() == JUMP.flight_knots
    clearance = soles[flight, :, 2].max() - soles[0, :, 2].max()
    assert clearance == pytest.approx(JUMP.height_m, abs=0.003)  # measured 0.0097 of 0.01
    # the horizontal momentum stays ~0 (vertical jump): the CoM lands where it took off
    assert np.abs(jump.com[-1, :2] - jump.com[0, :2]).max() < 0.01


def test_obstacle_jump_converges_with_stable_contacts() -> None:
    """A 0.25 m obstacle jump converges with the wrench cone on: every contact pushes (f_z > 0) inside the friction
    pyramid with the CoP in the 50 % rectangle; the soles clear 0.25 m and land 0.2 m ahead without sliding.
    Velocity limits are not kept (the paper's feasibility table: the knees need ~7x theirs)."""
    plan = solve(OBSTACLE_JUMP, SolverSettings(max_iterations=150))
    assert plan.converged, plan.solver_log
    assert plan.solver_log.iterations < 130
    contact = plan.contact_phases
    fz = plan.wrenches[..., 2][contact]
    assert fz.min() > 0.0
    tangential = np.linalg.norm(plan.wrenches[..., :2][contact], axis=1)
    assert np.all(tangential <= MU * fz + 1.0)
    assert np.all(np.abs(plan.cop[contact]) <= COP_HALF)
    nq = plan.robot.model.nq
    q = plan.xs[:, 7:nq]
    assert np.all((q >= plan.robot.q_lower - 1e-9) & (q <= plan.robot.q_upper + 1e-9))
    assert np.all(np.abs(plan.us) <= plan.robot.tau_max + 1e-9)
    soles = _sole_positions(plan)
    clearance = soles[:, :, 2].max(axis=0) - soles[0, :, 2]
    np.testing.assert_allclose(clearance, OBSTACLE_JUMP.height_m, atol=0.01)  # measured 0.245
    np.testing.assert_allclose(soles[-1, :, 0] - soles[0, :, 0], OBSTACLE_JUMP.length_m, atol=0.005)
    test_feet_stay_in_contact(plan)


def test_balancing_lifts_the_right_foot_over_the_left(balancing: PlanResult, stepping: PlanResult) -> None:
    for plan, step in ((balancing, 0.0), (stepping, STEPPING.step_length_m)):
        soles = _sole_positions(plan)
        single = plan.contact_phases[:, 0] & ~plan.contact_phases[:, 1]
        assert single.any()
        assert (soles[single, 1, 2] - soles[0, 1, 2]).max() == pytest.approx(plan.motion.lift_height_m, abs=0.01)
        # in single support the CoM is over the left sole's CoP rectangle
        offset = np.abs(plan.com[single, :2] - soles[single, 0, :2])
        assert (offset <= COP_HALF).all()
        assert soles[-1, 1, 0] - soles[0, 1, 0] == pytest.approx(step, abs=0.01)
        assert np.abs(soles[:, 0] - soles[0, 0]).max() < 3e-3  # the left foot never moves


def test_limit_scale_scales_the_planning_limits() -> None:
    nominal = build_robot()
    scaled = build_robot(limit_scale={"knee:velocity": 3.0, "LL*:torque": 2.0, "BodyPitch:position": 1.5})
    ratio_v, ratio_t = scaled.v_max / nominal.v_max, scaled.tau_max / nominal.tau_max
    assert sorted(np.round(ratio_v, 9)) == [1.0] * 30 + [3.0, 3.0]
    assert np.count_nonzero(ratio_t == 2.0) == 6
    assert np.count_nonzero(ratio_t == 1.0) == 26
    width = (scaled.q_upper - scaled.q_lower) / (nominal.q_upper - nominal.q_lower)
    assert np.count_nonzero(np.isclose(width, 1.5)) == 1
    np.testing.assert_allclose(scaled.q_upper + scaled.q_lower, nominal.q_upper + nominal.q_lower)

    class Factors:  # the LimitFactors protocol (what rh5_planner.limit_scale.LimitScale provides)
        def factors(self, kind: str) -> np.ndarray:
            out = np.ones(len(JOINT_NAMES))
            if kind == "velocity":
                out[JOINT_NAMES.index("LRKnee")] = 2.0
            return out

    assert limit_factors(Factors())["velocity"][JOINT_NAMES.index("LRKnee")] == 2.0
    for bad in ({"knee:speed": 2.0}, {"nosuchjoint:velocity": 2.0}, {"knee:velocity": 0.0}):
        with pytest.raises(ValueError, match=r"PATTERN:KIND|matches no joint|positive"):
            limit_factors(bad)


def test_motion_overrides_merge() -> None:
    merged = motion_config("vertical_jump_1cm", CONFIG)
    assert merged["joint_limits"]["weight"] == CONFIG["motion_overrides"]["vertical_jump_1cm"]["joint_limits"]["weight"]
    assert merged["joint_limits"]["position_beta"] == CONFIG["joint_limits"]["position_beta"]
    assert motion_config("walk_with_5kg_weights", CONFIG)["joint_limits"] == CONFIG["joint_limits"]
