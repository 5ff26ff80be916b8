"""Joint and actuator names of RH5 in the one fixed order every node uses.

Joint space is the 32 independent joints of the serial tree model, ordered as the
submechanisms of the public RH5 model list them (rh5_public_model/hyrodyn/rh5.yml):
torso, head, left arm, right arm, left leg, right leg. Actuator space is what the
boards drive (rh5_public_model/hyrodyn/rh5_hybrid.yml, ``jointnames_active``): the
linear actuators of the parallel submechanisms, the head transmission, and every
rotary joint, which passes through under its joint name.
"""

from __future__ import annotations

from typing import Final, NamedTuple

TORSO_JOINTS: Final = ("BodyPitch", "BodyRoll", "BodyYaw")
HEAD_JOINTS: Final = ("HeadPitch", "HeadRoll", "HeadYaw")


def _arm(side: str) -> tuple[str, ...]:
    return tuple(
        f"A{side}{j}" for j in ("Shoulder1", "Shoulder2", "Shoulder3", "Elbow", "WristRoll", "WristYaw", "WristPitch")
    )


def _leg(side: str) -> tuple[str, ...]:
    return tuple(f"L{side}{j}" for j in ("Hip1", "Hip2", "Hip3", "Knee", "AnkleRoll", "AnklePitch"))


LEFT_ARM_JOINTS: Final = _arm("L")
RIGHT_ARM_JOINTS: Final = _arm("R")
LEFT_LEG_JOINTS: Final = _leg("L")
RIGHT_LEG_JOINTS: Final = _leg("R")

JOINT_NAMES: Final[tuple[str, ...]] = (
    TORSO_JOINTS + HEAD_JOINTS + LEFT_ARM_JOINTS + RIGHT_ARM_JOINTS + LEFT_LEG_JOINTS + RIGHT_LEG_JOINTS
)
"""The 32 independent joints, in the order of every joint-space vector of the suite."""

NUM_JOINTS: Final = len(JOINT_NAMES)
JOINT_INDEX: Final[dict[str, int]] = {name: i for i, name in enumerate(JOINT_NAMES)}

JOINT_GROUPS: Final[dict[str, tuple[str, ...]]] = {
    "torso": TORSO_JOINTS,
    "head": HEAD_JOINTS,
    "left_arm": LEFT_ARM_JOINTS,
    "right_arm": RIGHT_ARM_JOINTS,
    "left_leg": LEFT_LEG_JOINTS,
    "right_leg": RIGHT_LEG_JOINTS,
}


class Submechanism(NamedTuple):
    """A group of independent joints driven together by a group of actuators."""

    name: str
    kind: str  # "1-RRPR", "2-SPRR+1U", "2-SPU+1U", "transmission" or "serial"
    joints: tuple[str, ...]
    actuators: tuple[str, ...]


def _serial(*joints: str) -> list[Submechanism]:
    return [Submechanism(j, "serial", (j,), (j,)) for j in joints]


def _arm_submechanisms(side: str) -> list[Submechanism]:
    a = f"A{side}"
    return [
        *_serial(f"{a}Shoulder1", f"{a}Shoulder2", f"{a}Shoulder3", f"{a}Elbow", f"{a}WristRoll"),
        Submechanism(f"{a}Wrist", "2-SPU+1U", (f"{a}WristYaw", f"{a}WristPitch"), (f"{a}Wrist_Act1", f"{a}Wrist_Act2")),
    ]


def _leg_submechanisms(side: str) -> list[Submechanism]:
    leg = f"L{side}"
    return [
        *_serial(f"{leg}Hip1", f"{leg}Hip2"),
        Submechanism(f"{leg}Hip3", "1-RRPR", (f"{leg}Hip3",), (f"{leg}Hip3_Act1",)),
        Submechanism(f"{leg}Knee", "1-RRPR", (f"{leg}Knee",), (f"{leg}Knee_Act1",)),
        Submechanism(
            f"{leg}Ankle",
            "2-SPRR+1U",
            (f"{leg}AnkleRoll", f"{leg}AnklePitch"),
            (f"{leg}Ankle_Act1", f"{leg}Ankle_Act2"),
        ),
    ]


SUBMECHANISMS: Final[tuple[Submechanism, ...]] = (
    Submechanism("Body", "2-SPU+1U", ("BodyPitch", "BodyRoll"), ("Body_Act1", "Body_Act2")),
    *_serial("BodyYaw"),
    Submechanism("Head", "transmission", HEAD_JOINTS, ("Head_Act1", "Head_Act2", "Head_Act3")),
    *_arm_submechanisms("L"),
    *_arm_submechanisms("R"),
    *_leg_submechanisms("L"),
    *_leg_submechanisms("R"),
)
"""Every submechanism, in joint order: concatenating ``joints`` gives JOINT_NAMES."""

ACTUATOR_NAMES: Final[tuple[str, ...]] = tuple(a for s in SUBMECHANISMS for a in s.actuators)
"""The 32 actuator-space coordinates: linear actuators (m, N), head drives and rotary joints (rad, Nm)."""

NUM_ACTUATORS: Final = len(ACTUATOR_NAMES)
ACTUATOR_INDEX: Final[dict[str, int]] = {name: i for i, name in enumerate(ACTUATOR_NAMES)}

LINEAR_ACTUATOR_NAMES: Final[tuple[str, ...]] = tuple(
    a for s in SUBMECHANISMS if s.kind not in ("serial", "transmission") for a in s.actuators
)
"""The 14 linear actuators of the parallel submechanisms (lengths in m, forces in N)."""

FOOT_FRAMES: Final = {"left": "LLFoot_Sole", "right": "LRFoot_Sole"}
"""Sole frames of the model (centre of the 200 x 80 mm support rectangle, z up)."""

HAND_FRAMES: Final = {"left": "AL_TCP", "right": "AR_TCP"}
BASE_FRAME: Final = "RH5_Root_Link"

assert tuple(j for s in SUBMECHANISMS for j in s.joints) == JOINT_NAMES
assert NUM_JOINTS == 32
assert NUM_ACTUATORS == 32
