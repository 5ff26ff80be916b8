"""The fixed joint and actuator orders every node relies on, checked against literal lists."""

from __future__ import annotations

from rh5_msgs_py.names import (
    ACTUATOR_INDEX,
    ACTUATOR_NAMES,
    JOINT_INDEX,
    JOINT_NAMES,
    LINEAR_ACTUATOR_NAMES,
    NUM_ACTUATORS,
    NUM_JOINTS,
    SUBMECHANISMS,
)

# The documented order (rh5_public_model/hyrodyn/rh5.yml submechanisms): torso, head, left arm,
# right arm, left leg, right leg. Written out so that a change to the generators in names.py shows here.
EXPECTED_JOINTS = (
    "BodyPitch", "BodyRoll", "BodyYaw",
    "HeadPitch", "HeadRoll", "HeadYaw",
    "ALShoulder1", "ALShoulder2", "ALShoulder3", "ALElbow", "ALWristRoll", "ALWristYaw", "ALWristPitch",
    "ARShoulder1", "ARShoulder2", "ARShoulder3", "ARElbow", "ARWristRoll", "ARWristYaw", "ARWristPitch",
    "LLHip1", "LLHip2", "LLHip3", "LLKnee", "LLAnkleRoll", "LLAnklePitch",
    "LRHip1", "LRHip2", "LRHip3", "LRKnee", "LRAnkleRoll", "LRAnklePitch",
)  # fmt: skip

# Linear actuators per the paper's table "ROM of linear actuators": wrist 4, torso 2, hip3 2, knee 2, ankle 4.
EXPECTED_LINEAR = {
    "Body_Act1", "Body_Act2",
    "ALWrist_Act1", "ALWrist_Act2", "ARWrist_Act1", "ARWrist_Act2",
    "LLHip3_Act1", "LLKnee_Act1", "LLAnkle_Act1", "LLAnkle_Act2",
    "LRHip3_Act1", "LRKnee_Act1", "LRAnkle_Act1", "LRAnkle_Act2",
}  # fmt: skip


def test_joint_names_are_32_unique_in_documented_order() -> None:
    """JOINT_NAMES is exactly the documented list: 32 names, no duplicates."""
    assert len(JOINT_NAMES) == NUM_JOINTS == 32
    assert len(set(JOINT_NAMES)) == 32
    assert JOINT_NAMES == EXPECTED_JOINTS
    assert all(JOINT_INDEX[name] == i for i, name in enumerate(JOINT_NAMES))


def test_actuator_names_contain_the_parallel_drives_of_both_sides() -> None:
    """Every linear actuator of both sides (and the head drives) is an actuator-space coordinate."""
    assert len(ACTUATOR_NAMES) == NUM_ACTUATORS == 32
    assert len(set(ACTUATOR_NAMES)) == 32
    assert set(ACTUATOR_NAMES) >= EXPECTED_LINEAR | {"Head_Act1", "Head_Act2", "Head_Act3"}
    assert all(ACTUATOR_INDEX[name] == i for i, name in enumerate(ACTUATOR_NAMES))


def test_rotary_joints_pass_through_under_their_joint_name() -> None:
    """Actuator space = joint space with each parallel submechanism's joints replaced by its actuators."""
    replaced = {j for s in SUBMECHANISMS if s.kind != "serial" for j in s.joints}
    assert set(ACTUATOR_NAMES) - EXPECTED_LINEAR - {"Head_Act1", "Head_Act2", "Head_Act3"} == (
        set(JOINT_NAMES) - replaced
    )


def test_submechanism_joints_concatenate_to_joint_names() -> None:
    """Concatenating the submechanisms' joints gives JOINT_NAMES, their actuators ACTUATOR_NAMES."""
    assert tuple(j for s in SUBMECHANISMS for j in s.joints) == JOINT_NAMES
    assert tuple(a for s in SUBMECHANISMS for a in s.actuators) == ACTUATOR_NAMES


def test_linear_actuators_match_the_paper_count() -> None:
    """14 linear actuators (paper table: 4 wrist + 2 torso + 2 hip3 + 2 knee + 4 ankle), no rotary joint among them."""
    assert set(LINEAR_ACTUATOR_NAMES) == EXPECTED_LINEAR
    assert len(LINEAR_ACTUATOR_NAMES) == 14
    assert not set(LINEAR_ACTUATOR_NAMES) & set(JOINT_NAMES)
