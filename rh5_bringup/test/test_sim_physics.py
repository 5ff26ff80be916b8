"""Physics mode of the simulated hardware: the PyBullet world, its coupling with the boards, and the node.

The world and coupling tests run the 1 kHz loop in this process, faster than real time, without ROS.
"""

from __future__ import annotations

import socket
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from rh5_bringup.hardware.ndlcom.payloads import CommandMode
from rh5_bringup.sim.physics import PhysicsActuatorBank, PhysicsWorld, build_physics, contact_links
from rh5_hyrodyn_mapper.model import robot_model
from rh5_msgs_py.names import NUM_ACTUATORS, NUM_JOINTS

POSITION = np.full(NUM_ACTUATORS, int(CommandMode.POSITION))
OFF = np.zeros(NUM_ACTUATORS, dtype=int)


@pytest.fixture(scope="module")
def standing() -> Iterator[PhysicsActuatorBank]:
    """RH5 standing on the crane, boards OFF (one world for the tests that only read it)."""
    coupled = build_physics()
    yield coupled
    coupled.world.close()


def run(coupled: PhysicsActuatorBank, cycles: int, mode: np.ndarray, target: np.ndarray | None = None) -> None:
    for _ in range(cycles):
        coupled.step(1e-3, mode, target)


def test_base_pose_is_the_root_link_frame_with_the_soles_on_the_ground(standing: PhysicsActuatorBank) -> None:
    """The pose read back is the URDF root link (PyBullet's base COM frame is 13 cm away from it), where
    pinocchio's standing configuration puts it; the eight corner spheres touch z = 0."""
    world = standing.world
    pose = world.base_pose()
    q_standing = robot_model().q_standing
    np.testing.assert_allclose(pose.position, q_standing[:3], atol=1e-5)
    assert abs(abs(float(pose.orientation @ q_standing[3:7])) - 1.0) < 1e-8  # same rotation up to ~1e-4 rad
    for side in ("left", "right"):
        sole = world.sole_pose(side)
        assert abs(sole.position[2]) < 1e-5
    assert len(contact_links()) == 8
    assert world.total_mass == pytest.approx(sum(i.mass for i in robot_model().model.inertias))


def test_tau_is_j_transpose_f_by_virtual_power(standing: PhysicsActuatorBank) -> None:
    """f . l_dot == tau . q_dot through the coupling's own maps, at a pose away from the standing one."""
    rng = np.random.default_rng(1)
    q = np.abs(0.1 * rng.standard_normal(NUM_JOINTS))  # the knees bend one way only
    qd = rng.standard_normal(NUM_JOINTS)
    force = rng.standard_normal(NUM_ACTUATORS) * 100.0
    sample = standing.mapper.to_actuators(q, qd)
    standing.q, standing.position = q, sample.position
    tau = standing.torques(force)
    assert sample.velocity is not None
    power_actuators = float(force @ sample.velocity)
    assert power_actuators == pytest.approx(float(tau @ qd), rel=1e-9, abs=1e-9)
    standing.reset()  # back to the standing pose for the other tests


def test_the_crane_holds_the_robot_while_the_boards_are_off(standing: PhysicsActuatorBank) -> None:
    world = standing.world
    start = world.base_pose().position
    run(standing, 200, OFF)
    assert world.supported
    assert np.abs(world.base_pose().position - start).max() < 1e-3


def test_shift_base_xy_moves_the_robot_on_the_ground_and_keeps_it_on_the_crane() -> None:
    coupled = build_physics()
    with coupled.world as world:
        before = world.base_pose()
        after = world.shift_base_xy(np.array([0.3, -0.2]))
        np.testing.assert_allclose(after.position, before.position + np.array([0.3, -0.2, 0.0]), atol=1e-9)
        run(coupled, 200, OFF)  # boards off: only the crane keeps it where it was put
        np.testing.assert_allclose(world.base_pose().position, after.position, atol=2e-3)
        assert abs(world.sole_pose("left").position[2]) < 1e-5


def test_without_crane_or_boards_the_robot_falls() -> None:
    coupled = build_physics(support=False)
    with coupled.world as world:
        start = world.base_pose().position[2]
        run(coupled, 1000, OFF)
        assert world.base_pose().position[2] < start - 0.05


def test_released_robot_stands_on_its_boards() -> None:
    """Boards in position mode at the standing pose, crane released after 0.2 s: over 2.5 simulated seconds
    the base moves less than 6 mm, and the feet carry m g within 3 % (mean of the last 0.5 s), both feet.
    The robot rocks from foot to foot by micrometres (a rigid biped on rigid ground is statically
    indeterminate), so each foot's share is checked on average."""
    coupled = build_physics()
    world = coupled.world
    try:
        target = coupled.position.copy()
        run(coupled, 100, POSITION, target)
        world.release_support()
        start = world.base_pose().position
        drift, vertical, per_foot = 0.0, [], []
        for k in range(2500):
            coupled.step(1e-3, POSITION, target)
            drift = max(drift, float(np.linalg.norm(world.base_pose().position - start)))
            if k >= 2000 and k % 10 == 0:
                wrenches = world.foot_wrenches()
                vertical.append(sum(w.force_world[2] for w in wrenches.values()))
                per_foot.append([wrenches[s].force_world[2] for s in ("left", "right")])
        assert drift < 6e-3
        assert np.mean(vertical) == pytest.approx(world.weight, rel=0.03)
        share = np.mean(per_foot, axis=0) / world.weight
        assert share.min() > 0.1, share  # on both feet, on average (it rocks: rigid soles on rigid ground)
        assert coupled.counts.dropped_steps == 0
    finally:
        world.close()


def test_hand_payload_adds_mass_at_both_hands() -> None:
    with PhysicsWorld(hand_payload_kg=5.0) as loaded, PhysicsWorld() as bare:
        assert loaded.total_mass == pytest.approx(bare.total_mass + 10.0)


def test_physics_time_follows_board_time_in_half_ms_steps(standing: PhysicsActuatorBank) -> None:
    """Board cycles of any length step the physics (and the boards' cascade between) in whole 0.5 ms steps,
    carrying the remainder; a call shorter than a step runs the boards only."""
    world, before = standing.world, standing.world.steps
    for _ in range(2):
        standing.step(1e-3, OFF)  # a board cycle is two physics steps
    assert world.steps - before == 4
    standing.step(0.2e-3, OFF)  # less than a step: carried
    assert world.steps - before == 4
    standing.step(1.2e-3, OFF)  # 1.4 ms: three steps, -0.1 ms carried
    assert world.steps - before == 7
    assert world.time == pytest.approx(world.steps * 0.5e-3)


# ----------------------------------------------------------------------------------------------------------------
# The node


def free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


@pytest.mark.ros
def test_node_in_physics_mode_answers_the_driver_and_publishes_ground_truth(
    ros_graph: Any, ros_test_environment: dict[str, str]
) -> None:
    import rclpy

    from rh5_bringup.hardware.driver_node import actuator_limits
    from rh5_bringup.hardware.ndlcom.board_map import load_board_map
    from rh5_bringup.hardware.rig import DriverLoop, sine_centre
    from rh5_bringup.hardware.transports import open_transport
    from rh5_bringup.orchestration.cli import call_trigger
    from rh5_bringup.orchestration.launcher import Bringup, NodeSpec, SuiteRun, wait_for_nodes
    from rh5_hyrodyn_mapper.mapping import robot_mapper
    from rh5_msgs_py import interfaces

    port = free_udp_port()
    spec = NodeSpec("sim_hardware", "rh5_bringup", "sim_hardware_node", {"listen_port": port, "mode": "physics"})
    log_dir = Path(ros_test_environment["ROS_LOG_DIR"]) / "sim_physics"
    poses: list[Any] = []
    subscription = ros_graph.create_subscription(
        interfaces.message_class(interfaces.SIM_BASE_POSE.type),
        interfaces.SIM_BASE_POSE.name,
        poses.append,
        interfaces.SIM_BASE_POSE.qos,
    )
    limits = actuator_limits()
    centre = sine_centre(robot_mapper().to_actuators(np.zeros(NUM_JOINTS)).position, limits)
    board_map = load_board_map()
    with SuiteRun(Bringup("", (spec,)), log_dir, int(ros_test_environment["ROS_DOMAIN_ID"])) as suite:
        assert wait_for_nodes(ros_graph, {"sim_hardware"}) == set()
        link = open_transport(
            "udp", local=("127.0.0.1", 0), remote=("127.0.0.1", port), receivers=[board_map.pc_address]
        )
        rig = DriverLoop(board_map, link, limits, centre, silence_timeout_ns=50_000_000)
        rig.loop.start()
        try:
            time.sleep(0.1)
            assert rig.core.enable(True)[0]
            deadline = time.monotonic() + 2.0
            while time.monotonic() < deadline:
                rclpy.spin_once(ros_graph, timeout_sec=0.05)
            assert call_trigger(ros_graph, "/sim_hardware/release_support", timeout_s=10.0)
            heard = np.asarray(rig.core.heard_ns).copy()
            answered = time.monotonic_ns()
        finally:
            rig.loop.stop()
            link.shutdown()
            ros_graph.destroy_subscription(subscription)
    summary = suite.processes[0].summary()
    assert suite.processes[0].process.returncode == 0
    assert summary["mode"] == "physics"
    # the physics stepped (how fast is bench/physics.py's: this host ran it at 0.08-0.3 x real time on one day)
    assert summary["physics"]["physics_steps"] > 200
    assert summary["physics"]["supported"] is False
    # ground truth arrives (250 Hz of simulated time, best effort; at 0.1 x real time that is 50 in these 2 s)
    assert len(poses) > 10
    assert poses[-1].header.frame_id == "world"
    assert poses[-1].pose.position.z == pytest.approx(robot_model().q_standing[2], abs=0.02)
    assert (answered - heard < 100_000_000).all()  # every board answered the driver within the last 0.1 s
