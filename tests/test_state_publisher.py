"""The state publisher as a real process: /tf and /tf_static hold every link of the URDF and odom -> root."""

from __future__ import annotations

import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from rh5_bringup.orchestration.launcher import Bringup, NodeSpec, SuiteRun, wait_for_nodes
from rh5_hyrodyn_mapper.model import robot_model
from rh5_hyrodyn_mapper.tf_tree import KinematicTree, urdf_links
from rh5_msgs_py import interfaces
from rh5_msgs_py.conversions import joint_state_to_msg
from rh5_msgs_py.names import JOINT_NAMES, NUM_JOINTS
from rh5_msgs_py.realtime import DeadlineLoop

pytestmark = pytest.mark.ros

ANGLES = np.linspace(-0.3, 0.3, NUM_JOINTS)
BASE = (0.1, -0.2, 0.9, 0.0, 0.0, np.sin(0.25), np.cos(0.25))  # x y z, quaternion x y z w (yaw 0.5 rad)


class Listener:
    """Publishes joint_states at 1 kHz and the base pose at 250 Hz; records /tf and /tf_static."""

    def __init__(self, node: Any) -> None:
        from geometry_msgs.msg import PoseStamped
        from sensor_msgs.msg import JointState
        from tf2_msgs.msg import TFMessage

        self.node = node
        self.tf: list[tuple[float, Any]] = []
        self.tf_static: list[Any] = []
        self._states = node.create_publisher(JointState, interfaces.JOINT_STATES.name, interfaces.STREAM_QOS)
        self._pose_pub = node.create_publisher(PoseStamped, interfaces.SIM_BASE_POSE.name, interfaces.STREAM_QOS)
        self._pose = PoseStamped()
        self._pose.header.frame_id = "world"
        p, o = self._pose.pose.position, self._pose.pose.orientation
        p.x, p.y, p.z, o.x, o.y, o.z, o.w = (float(v) for v in BASE)
        node.create_subscription(TFMessage, "/tf", lambda m: self.tf.append((time.monotonic(), m)), interfaces.TF_QOS)
        node.create_subscription(TFMessage, "/tf_static", self.tf_static.append, interfaces.TF_STATIC_QOS)
        self._ticks = 0
        self.loop = DeadlineLoop(1000.0, self._publish, name="test-joint-states")

    def _publish(self, _now: int, _period: int) -> None:
        self._states.publish(joint_state_to_msg(JOINT_NAMES, ANGLES, np.zeros(NUM_JOINTS), stamp_ns=123_456_789_000))
        self._ticks += 1
        if self._ticks % 4 == 0:
            self._pose_pub.publish(self._pose)

    def spin_for(self, seconds: float) -> None:
        import rclpy

        end = time.monotonic() + seconds
        while time.monotonic() < end:
            rclpy.spin_once(self.node, timeout_sec=0.01)


@pytest.fixture(scope="module")
def listener(ros_graph: Any, ros_test_environment: dict[str, str]) -> Iterator[Listener]:
    spec = NodeSpec("state_publisher", "rh5_hyrodyn_mapper", "state_publisher_node", {})
    side = Listener(ros_graph)
    side.loop.start()
    log_dir = Path(ros_test_environment["ROS_LOG_DIR"]) / "state_publisher"
    try:
        with SuiteRun(Bringup("", (spec,)), log_dir, int(ros_test_environment["ROS_DOMAIN_ID"])) as run:
            assert wait_for_nodes(ros_graph, {"state_publisher"}) == set()
            side.spin_for(3.0)
            yield side
    finally:
        side.loop.stop()
    assert run.processes[0].process.returncode == 0
    assert "Traceback" not in run.processes[0].stderr_path.read_text()


def test_tf_holds_every_link_of_the_urdf_and_odom(listener: Listener) -> None:
    assert listener.tf, "no /tf"
    assert listener.tf_static, "no /tf_static"
    _, latest = listener.tf[-1]
    edges = {(t.header.frame_id, t.child_frame_id) for t in latest.transforms}
    edges |= {(t.header.frame_id, t.child_frame_id) for m in listener.tf_static for t in m.transforms}
    children = [c for _, c in edges]
    assert len(children) == len(set(children)), "a frame with two parents"
    links = set(urdf_links(robot_model(free_flyer=False).urdf))
    assert links <= {c for _, c in edges} | {"RH5_Root_Link"}
    assert ("odom", "RH5_Root_Link") in edges
    assert {p for p, _ in edges} - set(children) == {"odom"}, "one tree, rooted at odom"


def test_transforms_carry_the_joint_angles_the_base_pose_and_the_stamp(listener: Listener) -> None:
    _, latest = listener.tf[-1]
    by_child = {t.child_frame_id: t for t in latest.transforms}
    odom = by_child["RH5_Root_Link"].transform
    got = (odom.translation.x, odom.translation.y, odom.translation.z, *(getattr(odom.rotation, a) for a in "xyzw"))
    assert np.allclose(got, BASE)
    tree = KinematicTree(robot_model(free_flyer=False).urdf)
    expected = tree.rotations(ANGLES)
    for child, rotation in zip(tree.children, expected, strict=True):
        r = by_child[child].transform.rotation
        assert np.allclose((r.x, r.y, r.z, r.w), rotation, atol=1e-12), child
    assert {(t.header.stamp.sec, t.header.stamp.nanosec) for t in latest.transforms} == {(123, 456_789_000)}


def test_tf_rate_is_the_configured_50_hz(listener: Listener) -> None:
    times = np.array([t for t, _ in listener.tf])
    recent = times[times > times[-1] - 2.0]
    rate = (len(recent) - 1) / (recent[-1] - recent[0])
    assert 35.0 < rate < 60.0, f"/tf at {rate:.1f} Hz"
