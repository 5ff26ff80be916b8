"""Limit analysis, feasibility table, design heuristic and plots.

Synthetic trajectories with limits exceeded on purpose check the counting (joint and actuator space, CoP,
friction, scaled limits); a real Box-FDDP solve of a short squat (20 knots, ~5 s) checks the analysis against the
planner's own bounds and the mapper's limit report, the table against the paper's squat row, and the plots; the
heuristic's search runs on a stand-in planner; the scaled-limit adapter is checked on the built problem.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import crocoddyl  # noqa: F401  (before pinocchio, design/crocoddyl_wheels.md)
import numpy as np
import pytest

from rh5_hyrodyn_mapper.mapping import robot_mapper
from rh5_hyrodyn_mapper.model import joint_limits, model_hash, v_index
from rh5_msgs_py.names import ACTUATOR_INDEX, JOINT_INDEX, JOINT_NAMES
from rh5_msgs_py.trajectory_file import NQ, TrajectoryData
from rh5_planner import design, ocp
from rh5_planner.design import critical_limits, improve_design, parse_limit
from rh5_planner.feasibility import PAPER_FEASIBILITY, FeasibilityTable
from rh5_planner.limit_analysis import analyse
from rh5_planner.limit_scale import MAPPED_ACTUATORS, LimitScale, match_joints, side_free_name
from rh5_planner.motions import MotionSpec, get_motion
from rh5_planner.ocp import PlanResult, SolverSettings, solve
from rh5_planner.plots import configuration_limits, plot_cop, plot_joints

LIMITS = joint_limits()
N = 12
FZ = 350.0
SHORT_SQUAT = {"total_time_s": 0.6, "hold_s": 0.1, "com_range_m": 0.1}


def synthetic(name: str = "synthetic", edits: Mapping[str, object] | None = None) -> TrajectoryData:
    """Standing with bent knees, both feet loaded at the sole centre; ``edits`` break chosen limits."""
    edits = dict(edits or {})
    q = np.zeros((N, 32))
    for joint, angle in (("LLKnee", 0.5), ("LRKnee", 0.5), ("LLHip3", -0.25), ("LRHip3", -0.25)):
        q[:, JOINT_INDEX[joint]] = angle
    for joint, angle in (("LLAnklePitch", -0.25), ("LRAnklePitch", -0.25)):
        q[:, JOINT_INDEX[joint]] = angle
    v = np.zeros((N, 32))
    tau = np.zeros((N - 1, 32))
    wrenches = np.zeros((N, 2, 6))
    wrenches[:, :, 2] = FZ
    cop = np.zeros((N, 2, 2))
    for key, value in edits.items():  # "q:JOINT:knot" / "v:..." / "tau:..." -> value; "cop:foot:knot" -> (x, y)
        what, where, knot = key.split(":")
        k = int(knot)
        if what == "cop":
            cop[k, int(where)] = value
            wrenches[k, int(where), 4] = -cop[k, int(where), 0] * FZ
            wrenches[k, int(where), 3] = cop[k, int(where), 1] * FZ
        elif what == "fx":
            wrenches[k, int(where), 0] = value
        else:
            {"q": q, "v": v, "tau": tau}[what][k, JOINT_INDEX[where]] = value
    states = np.zeros((N, NQ + 38))
    states[:, 6] = 1.0  # quaternion w
    states[:, 7:NQ] = q
    states[:, NQ + 6 :] = v
    return TrajectoryData(
        times=np.arange(N) * 0.03,
        states=states,
        controls=tau,
        contact_wrenches=wrenches,
        contact_phases=np.ones((N, 2), dtype=bool),
        cop=cop,
        motion={"name": name},
        model_hash=model_hash(),
        solver_log={"converged": True, "iterations": 7},
    )


def vmax(joint: str) -> float:
    return float(LIMITS.velocity_max[JOINT_INDEX[joint]])


def tmax(joint: str) -> float:
    return float(LIMITS.torque_max[JOINT_INDEX[joint]])


# --------------------------------------------------------------------------------------------------
# synthetic: counting


def test_nominal_synthetic_trajectory_is_feasible() -> None:
    analysis = analyse(synthetic())
    assert analysis.feasible(("position", "torque", "velocity", "stroke", "actuator_velocity", "force"))
    assert analysis.contact.contact_knots == 2 * N
    assert analysis.contact.cop_outside == analysis.contact.friction_outside == 0
    assert analysis.violations() == {}


def test_known_violations_are_counted() -> None:
    upper = float(LIMITS.position_upper[JOINT_INDEX["ALElbow"]])
    half_cop_x = 0.5 * 0.5 * 0.200
    data = synthetic(
        edits={
            "v:LLKnee:3": 1.5 * vmax("LLKnee"),
            "v:LLKnee:4": -1.5 * vmax("LLKnee"),
            "v:LRKnee:4": 0.5 * vmax("LRKnee"),  # inside every limit
            "tau:BodyPitch:2": 1.3 * tmax("BodyPitch"),
            "q:ALElbow:5": upper + 0.05,
            "cop:0:6": (half_cop_x + 0.005, 0.0),  # 5 mm outside the 50 % rectangle (tolerance 1 mm)
            "cop:1:6": (half_cop_x - 0.005, 0.0),  # inside
            "fx:1:7": 0.8 * FZ,  # mu = 0.7
        }
    )
    a = analyse(data)
    assert a.joint["velocity"].violating == ("LLKnee",)
    assert a.joint["velocity"].counts[JOINT_INDEX["LLKnee"]] == 2
    assert a.joint["velocity"].peak[JOINT_INDEX["LLKnee"]] == pytest.approx(1.5)
    assert a.joint["torque"].violating == ("BodyPitch",)
    assert a.joint["position"].violating == ("ALElbow",)
    assert (a.count("position"), a.count("torque"), a.count("velocity")) == (1, 1, 1)
    assert (a.contact.cop_outside, a.contact.friction_outside) == (1, 1)
    assert a.count("cop") == 1
    assert a.count("friction") == 1
    # actuator space: a knee 1.5x its best-case joint speed is too fast for its actuator; the torso pitch torque
    # needs more than the torso actuators' force; nothing else is touched
    assert "LLKnee_Act1" in a.actuator["actuator_velocity"].violating
    assert "LRKnee_Act1" not in a.actuator["actuator_velocity"].violating
    assert set(a.actuator["force"].violating) <= {"Body_Act1", "Body_Act2"}
    assert a.actuator["force"].violating
    assert a.actuator["stroke"].ok
    assert not a.feasible()


def test_configuration_dependent_velocity_limit_shows_only_in_actuator_space() -> None:
    """0.9 x the joint table's knee speed is inside the joint limit but over the actuator's at this angle."""
    data = synthetic(edits={"v:LLKnee:3": 0.95 * vmax("LLKnee")})
    a = analyse(data)
    assert a.joint["velocity"].ok
    limit_here = configuration_limits(data.joint_positions())["LLKnee"]["velocity"][3]
    assert limit_here < 0.95 * vmax("LLKnee")  # the 1-RRPR knee's speed limit at 0.5 rad is below the table's max
    assert a.actuator["actuator_velocity"].violating == ("LLKnee_Act1",)


def test_actuator_usage_agrees_with_the_mapper_limit_report() -> None:
    data = synthetic(edits={"v:LLKnee:3": 1.5 * vmax("LLKnee"), "tau:LRKnee:1": 0.99 * tmax("LRKnee")})
    a = analyse(data)
    mapper = robot_mapper()
    report = mapper.limit_report(mapper.to_actuators(data.joint_positions(), data.joint_velocities()))
    idx = [ACTUATOR_INDEX[n] for n in MAPPED_ACTUATORS]
    np.testing.assert_allclose(a.actuator["actuator_velocity"].utilisation, report.velocity[:, idx], rtol=1e-12)
    np.testing.assert_allclose(a.actuator["stroke"].utilisation, report.stroke[:, idx], rtol=1e-12)


def test_scaled_limits_are_checked_against_the_scale() -> None:
    data = synthetic(edits={"v:LLKnee:3": 1.5 * vmax("LLKnee")})
    assert not analyse(data).feasible(("velocity", "actuator_velocity"))
    scaled = analyse(data, scale=LimitScale((("knee", "velocity", 3.0),)))
    assert scaled.feasible(("velocity", "actuator_velocity"))
    assert scaled.joint["velocity"].peak[JOINT_INDEX["LLKnee"]] == pytest.approx(0.5)
    # scaling another joint does not help
    assert not analyse(data, scale=LimitScale((("Hip3", "velocity", 3.0),))).feasible(("velocity",))


def test_limit_scale_patterns_and_errors() -> None:
    assert match_joints("knee") == ("LLKnee", "LRKnee")
    assert match_joints("LL*") == tuple(j for j in JOINT_NAMES if j.startswith("LL"))
    assert match_joints("BodyPitch") == ("BodyPitch",)
    assert side_free_name("LRAnklePitch") == "AnklePitch"
    assert side_free_name("BodyPitch") == "BodyPitch"
    scale = LimitScale((("knee", "velocity", 3.0), ("LLKnee", "velocity", 2.0)))
    f = scale.factors("velocity")
    assert (f[JOINT_INDEX["LLKnee"]], f[JOINT_INDEX["LRKnee"]], f[JOINT_INDEX["LLHip3"]]) == (2.0, 3.0, 1.0)
    assert (scale.factors("torque") == 1.0).all()
    assert "LLKnee, LRKnee" in scale.describe()
    assert not LimitScale()
    assert not LimitScale((("knee", "torque", 1.0),))
    with pytest.raises(ValueError, match="kind"):
        LimitScale((("knee", "speed", 2.0),))
    with pytest.raises(ValueError, match="matches no joint"):
        LimitScale((("kneee", "velocity", 2.0),))
    with pytest.raises(ValueError, match="positive"):
        LimitScale((("knee", "velocity", 0.0),))
    assert parse_limit("knee:velocity") == ("knee", "velocity")
    with pytest.raises(ValueError, match="PATTERN:KIND"):
        parse_limit("knee")


# --------------------------------------------------------------------------------------------------
# the table


def test_table_marks_and_paper_comparison() -> None:
    jump = synthetic(
        "vertical_jump_10cm",
        {"v:BodyPitch:4": 2.0 * vmax("BodyPitch"), "v:LLKnee:4": 4 * vmax("LLKnee"), "v:LRKnee:4": 4 * vmax("LRKnee")},
    )
    walk = synthetic("walk_with_5kg_weights", {"tau:LLHip2:3": 2 * tmax("LLHip2")})
    table = FeasibilityTable([analyse(jump), analyse(walk)])
    rows = dict(table.rows())
    assert rows["vertical_jump_10cm"][:3] == ["\u2713", "\u2713", "\u27173"]  # the paper's order: pos, torque, vel
    assert rows["walk_with_5kg_weights"][:3] == ["\u2713", "\u27171", "\u2713"]
    cells = {(c.motion, c.column): c for c in table.compare_with_paper()}
    assert len(cells) == 6
    assert all(c.agree for (m, _), c in cells.items() if m == "vertical_jump_10cm")
    assert cells["vertical_jump_10cm", "velocity"].paper == PAPER_FEASIBILITY["vertical_jump_10cm"]["velocity"] == 3
    assert not cells["walk_with_5kg_weights", "torque"].agree
    text = table.comparison_text()
    assert "5/6 cells agree" in text
    assert "DISAGREE" in text
    markdown = table.to_markdown()
    assert markdown.splitlines()[0].startswith("| Motion | Conv. | Pos. Lim. | Torque Lim. | Vel. Lim. | Act. stroke")
    assert len([line for line in markdown.splitlines() if line.startswith("| ")]) == 3
    assert "vertical_jump_10cm" in table.to_text()


# --------------------------------------------------------------------------------------------------
# design heuristic


def fake_planner(speeds: Mapping[str, float]) -> design.SolveFunction:
    """A stand-in planner whose solution moves ``joint`` at ``speeds[joint]`` x its velocity limit, whatever the
    scale (the real planner would use the room; the heuristic only needs the verdicts)."""

    def run(motion: MotionSpec, scale: LimitScale, settings: SolverSettings) -> PlanResult:
        del scale, settings
        edits = {f"v:{j}:4": ratio * vmax(j) for j, ratio in speeds.items()}
        return synthetic(motion.name, edits)  # type: ignore[return-value]  (analyse takes TrajectoryData too)

    return run


def test_heuristic_finds_the_smallest_scaling_and_drops_unneeded_limits() -> None:
    """As the paper's 10 cm jump: body pitch and knee velocities over their limits. The stand-in moves them at 1.2
    and 2.5 x: uniform scaling finds x3, then BodyPitch comes back down to x1.5 and the knees stay at x3."""
    steps: list[design.DesignStep] = []
    result = improve_design(
        get_motion("vertical_jump_10cm"),
        None,
        solve_function=fake_planner({"BodyPitch": 1.2, "LLKnee": 2.5, "LRKnee": 2.5}),
        on_step=steps.append,
    )
    assert result.limits == (("BodyPitch", "velocity"), ("Knee", "velocity"))
    assert result.feasible
    assert result.scaled_limits() == [("BodyPitch", "velocity", 1.5), ("Knee", "velocity", 3.0)]
    factors_tried = [step.scale.entries for step in steps]
    assert factors_tried[0] == ()  # nominal first
    assert [e[0][2] for e in factors_tried[1:4]] == [1.5, 2.0, 3.0]  # uniform until feasible
    assert steps[3].feasible
    assert not steps[1].feasible
    assert "Knee velocity x3" in result.report()


def test_heuristic_adds_limits_that_bind_only_after_scaling() -> None:
    """Nominal: only the knees are too fast; once they may move faster the body pitch is too (as in the paper)."""

    def planner(motion: MotionSpec, scale: LimitScale, settings: SolverSettings) -> PlanResult:
        del settings
        knee = scale.factors("velocity")[JOINT_INDEX["LLKnee"]]
        edits = {"v:LLKnee:4": 2.5 * vmax("LLKnee"), "v:BodyPitch:4": (1.8 if knee > 1 else 0.5) * vmax("BodyPitch")}
        return synthetic(motion.name, edits)  # type: ignore[return-value]

    result = improve_design(get_motion("vertical_jump_10cm"), None, solve_function=planner)
    assert result.limits == (("Knee", "velocity"), ("BodyPitch", "velocity"))
    assert result.scaled_limits() == [("Knee", "velocity", 3.0), ("BodyPitch", "velocity", 2.0)]
    first_scaled = [step.scale.describe() for step in result.steps[1:3]]
    assert "BodyPitch" not in first_scaled[0]
    assert "BodyPitch velocity x2" in first_scaled[1]


def test_heuristic_drops_a_limit_that_need_not_grow() -> None:
    result = improve_design(
        get_motion("vertical_jump_10cm"),
        [("BodyPitch", "velocity"), ("knee", "velocity")],
        solve_function=fake_planner({"LLKnee": 2.5}),
    )
    assert result.scaled_limits() == [("knee", "velocity", 3.0)]


def test_heuristic_reports_failure_and_nominal_success() -> None:
    hopeless = improve_design(
        get_motion("vertical_jump_10cm"), [("knee", "velocity")], solve_function=fake_planner({"LLKnee": 9.0})
    )
    assert not hopeless.feasible
    assert len(hopeless.steps) == 5
    assert "no feasible solution" in hopeless.report()
    fine = improve_design(get_motion("vertical_jump_10cm"), None, solve_function=fake_planner({}))
    assert fine.feasible
    assert fine.scaled_limits() == []
    assert len(fine.steps) == 1


def test_actuator_space_heuristic_reports_an_actuator_specification() -> None:
    """Knees at 0.95 of their joint velocity limit but over their actuators' speed (the configuration-dependent
    limit): required to hold the actuator limits, the heuristic scales the knee velocity and reports it as a knee
    actuator speed (Table I) beside the joint-space factor."""
    result = improve_design(
        get_motion("vertical_jump_10cm"),
        None,
        required=("position", "torque", "velocity", "stroke", "actuator_velocity", "force"),
        solve_function=fake_planner({"LLKnee": 0.95, "LRKnee": 0.95}),
    )
    assert result.steps[0].violations == {"actuator_velocity": ("LLKnee_Act1", "LRKnee_Act1")}
    assert result.limits == (("Knee", "velocity"),)
    assert result.feasible
    (factor,) = {f for _, _, f in result.scaled_limits()}
    report = result.report()
    assert f"Knee velocity x{factor:g} (joint space" in report
    assert f"Knee actuator (LLKnee_Act1, LRKnee_Act1) 140 -> {140 * factor:.0f} mm/s" in report


def test_actuator_specs_and_binding_limits() -> None:
    specs = design.actuator_specs(
        [("Hip3", "velocity", 2.0), ("BodyPitch", "torque", 1.5), ("ALShoulder1", "torque", 3.0)]
    )
    assert specs == [
        "Hip3 actuator (LLHip3_Act1, LRHip3_Act1) 175 -> 350 mm/s (x2)",
        "Body actuator (Body_Act1, Body_Act2) 2716 -> 4074 N (x1.5)",
    ]
    at_the_edge = analyse(synthetic(edits={"v:LLKnee:4": 0.9 * vmax("LLKnee")}))
    assert critical_limits(at_the_edge) == ()
    assert design.binding_limits(at_the_edge) == (("Knee", "velocity"),)


def test_scaled_limits_reach_the_built_problem() -> None:
    """A LimitScale reaches the planner: joint-limit bounds and the Box-FDDP torque box of the built problem (on the
    paper's cost set: with the actuator limits the torso's torque box is its actuators' force bound, which scales
    with the same factor)."""
    scale = LimitScale((("knee", "velocity", 3.0), ("BodyPitch", "torque", 2.0), ("knee", "position", 2.0)))
    motion = get_motion("squat_with_5kg_weights", {**SHORT_SQUAT, "actuator_limits": False})
    nominal = ocp.build_problem(motion)
    scaled = ocp.build_problem(motion, limit_scale=scale)
    vi = v_index(nominal.robot.model) - 6
    body = vi[JOINT_INDEX["BodyPitch"]]
    knees = vi[[JOINT_INDEX["LLKnee"], JOINT_INDEX["LRKnee"]]]
    np.testing.assert_allclose(scaled.robot.v_max[knees], 3 * nominal.robot.v_max[knees])
    np.testing.assert_array_equal(np.delete(scaled.robot.v_max, knees), np.delete(nominal.robot.v_max, knees))
    assert scaled.robot.tau_max[body] == pytest.approx(2 * nominal.robot.tau_max[body])
    assert scaled.problem.runningModels[0].u_ub[body] == pytest.approx(2 * tmax("BodyPitch"))
    mid = 0.5 * (nominal.robot.q_lower + nominal.robot.q_upper)
    factor = np.where(np.isin(np.arange(32), knees), 2, 1)
    np.testing.assert_allclose(scaled.robot.q_upper - mid, factor * (nominal.robot.q_upper - mid))
    # actuator limits: the torso's force bound (a "torque" factor) doubles, below the doubled joint torque limit
    with_actuators = get_motion("squat_with_5kg_weights", SHORT_SQUAT)
    box = ocp.build_problem(with_actuators).problem.runningModels[0].u_ub[body]
    scaled_box = ocp.build_problem(with_actuators, limit_scale=scale).problem.runningModels[0].u_ub[body]
    assert box < tmax("BodyPitch")
    assert scaled_box == pytest.approx(2 * box)


# --------------------------------------------------------------------------------------------------
# a real solve


@pytest.fixture(scope="module")
def squat() -> PlanResult:
    return solve(get_motion("squat_with_5kg_weights", SHORT_SQUAT), SolverSettings(max_iterations=60))


def test_real_squat_analysis(squat: PlanResult) -> None:
    assert squat.converged
    a = analyse(squat)
    # the planner keeps its own bounds: joint positions, velocities (soft) and torques (Box-FDDP box)
    assert a.feasible(("position", "torque", "velocity")), a.violations()
    assert a.contact.cop_inside_ratio >= 0.99
    assert a.contact.friction_inside_ratio == 1.0
    assert a.actuator is not None
    # the knee works hardest in a squat
    assert side_free_name(a.joint["position"].worst(1)[0][0]) in {"Knee", "AnklePitch"}
    assert side_free_name(a.joint["velocity"].worst(1)[0][0]) == "Knee"
    row = FeasibilityTable([a]).compare_with_paper()
    assert [c.agree for c in row] == [True, True, True]  # the paper's squat row: all ticks
    markdown = a.to_markdown()
    assert all(name in markdown for name in (*JOINT_NAMES, *MAPPED_ACTUATORS))
    # the same numbers from the saved file
    again = analyse(squat.to_trajectory_data())
    np.testing.assert_array_equal(again.joint["velocity"].peak, a.joint["velocity"].peak)
    assert critical_limits(a) == ()


def test_plots_are_written(squat: PlanResult, tmp_path: Path) -> None:
    data = squat.to_trajectory_data()
    cop = plot_cop(data, tmp_path / "cop.png")
    joints = plot_joints(data, tmp_path / "joints.png", joints=("LLKnee", "LRKnee", "BodyPitch"))
    for path in (cop, joints):
        assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        assert path.stat().st_size > 10_000
    with pytest.raises(ValueError, match="unknown joint"):
        plot_joints(data, tmp_path / "bad.png", joints=("LLKnee", "Tail"))
