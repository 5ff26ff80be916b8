"""tf2_msgs and control_msgs, built by make venv (interfaces/), interoperate with a full ROS 2 Jazzy install.

Two messages interoperate when their names and RIHS01 type hashes match: DDS matches topics by type name, and
rclpy/rosbag2 compare the hashes. The expected hashes are those of the published Jazzy definitions (computed with
rosbags from geometry2 `jazzy` and control_msgs 5.8.0); the built packages report theirs in the type
description rosidl installs beside each interface.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

EXPECTED_HASHES = {
    # rosbags' own Jazzy type store (Stores.ROS2_JAZZY) holds these two.
    "tf2_msgs/msg/TFMessage": "RIHS01_e369d0f05a23ae52508854b66f6aa0437f3449d652e8cbf22d5abe85d020f087",
    "tf2_msgs/msg/TF2Error": "RIHS01_db2485e7d6a0ec75bf087e058ee45df682acc3a621ca7780503d10aac141809a",
    # rosbags' hash_rihs01 of control_msgs 5.8.0's own .msg/.action files (computed once, 2026-11-25).
    "control_msgs/msg/JointTolerance": "RIHS01_c254f9cece0f3b733017b6990fd46d1326e25242d6b8844398c97d9a88e7d648",
    "control_msgs/msg/JointComponentTolerance": (
        "RIHS01_739ea7566931944d33830fa10f1bf5e7a7fbdc3172bce7a7eaac642bd6e3ffa4"
    ),
    "control_msgs/msg/JointTrajectoryControllerState": (
        "RIHS01_51d8dd89cc624cbe9daaeeb4d80d6de9b86168ffdc3be41fefc0953e3c26e480"
    ),
    "control_msgs/action/FollowJointTrajectory_Goal": (
        "RIHS01_8a9060704b269608f5a340934cc26e66869dd14bdac29e2e7fd9ec8b9882d205"
    ),
    "control_msgs/action/FollowJointTrajectory_Result": (
        "RIHS01_8002e99ed2c14c6faa522f2a93c26d744c5982f254f9e98ff9c6f19789bdb220"
    ),
    "control_msgs/action/FollowJointTrajectory_Feedback": (
        "RIHS01_3fd0aaecf71725121ae1ff7f01098a5e0da581e672be18a6b2c286cb43d96b49"
    ),
}


def _share(package: str) -> Path:
    return Path(sys.prefix) / "share" / package


def _hash(type_name: str) -> str:
    package, kind, name = type_name.split("/")
    description = json.loads((_share(package) / kind / f"{name.split('_')[0]}.json").read_text())
    return next(h["hash_string"] for h in description["type_hashes"] if h["type_name"] == type_name)


@pytest.mark.parametrize("type_name", sorted(EXPECTED_HASHES))
def test_type_hashes_are_those_of_the_published_definitions(type_name: str) -> None:
    assert _hash(type_name) == EXPECTED_HASHES[type_name]


def test_rosbags_jazzy_store_agrees_on_tf2_msgs() -> None:
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    assert store.hash_rihs01("tf2_msgs/msg/TFMessage") == EXPECTED_HASHES["tf2_msgs/msg/TFMessage"]


def test_the_build_skips_up_to_date_packages() -> None:
    import subprocess

    out = subprocess.run(
        [sys.executable, str(Path(__file__).resolve().parent.parent / "tools" / "build_interfaces.py")],
        capture_output=True,
        text=True,
        check=True,
        timeout=60,
    ).stdout
    assert "tf2_msgs: up to date" in out
    assert "control_msgs: up to date" in out


def test_messages_round_trip_through_cdr() -> None:
    from control_msgs.action import FollowJointTrajectory
    from control_msgs.msg import JointTolerance
    from geometry_msgs.msg import TransformStamped
    from rclpy.serialization import deserialize_message, serialize_message
    from tf2_msgs.msg import TFMessage

    tf = TFMessage(transforms=[TransformStamped(child_frame_id="a"), TransformStamped(child_frame_id="b")])
    assert deserialize_message(serialize_message(tf), TFMessage) == tf
    goal = FollowJointTrajectory.Goal()
    goal.trajectory.joint_names = ["LLKnee"]
    goal.path_tolerance = [JointTolerance(name="LLKnee", position=0.1)]
    assert deserialize_message(serialize_message(goal), FollowJointTrajectory.Goal) == goal
    assert FollowJointTrajectory.Result.GOAL_TOLERANCE_VIOLATED == -5


def test_the_recorder_finds_their_definitions() -> None:
    from rh5_msgs_py.schemas import message_definition

    assert "geometry_msgs/TransformStamped[] transforms" in message_definition("tf2_msgs/msg/TFMessage")
