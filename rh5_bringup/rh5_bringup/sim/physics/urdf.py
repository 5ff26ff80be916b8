"""The RH5 URDF as PyBullet loads it: ``generate_urdf()`` with corner contact spheres instead of the sole boxes,
the actuators' armature on the joints' child links, and payload spheres at the TCPs (why: physics/world.py).
"""

from __future__ import annotations

import re

import numpy as np

from rh5_hyrodyn_mapper.model.urdf import generate_urdf, load_parameters
from rh5_msgs_py.array_types import FloatArray
from rh5_msgs_py.names import FOOT_FRAMES, HAND_FRAMES, JOINT_NAMES

CONTACT_RADIUS = 0.005
"""Radius of the corner spheres [m]; their lowest points lie in the sole plane."""

CORNERS = ("FrontLeft", "FrontRight", "RearLeft", "RearRight")
PAYLOAD_RADIUS = 0.05
"""A hand payload is a solid sphere of this radius at the TCP (its inertia keeps Bullet well conditioned)."""


def _sphere_inertia(mass: float, radius: float) -> float:
    return 0.4 * mass * radius**2


def _valid_inertia(inertia: FloatArray, axis: FloatArray) -> FloatArray:
    """``inertia`` plus the least inertia about the axes normal to ``axis`` that makes it a rigid body's again
    (principal moments satisfying the triangle inequality; Bullet zeroes a tensor that does not)."""
    normal = np.eye(3) - np.outer(axis, axis)
    for _ in range(50):
        moments = np.linalg.eigvalsh(inertia)
        excess = moments[2] - moments[0] - moments[1]
        if excess <= -1e-9 * moments[2]:
            return inertia
        inertia = inertia + (0.5 * excess + 1e-9 * moments[2]) * normal
    return inertia


def physics_urdf(armature: FloatArray | None = None, hand_payload_kg: float = 0.0) -> str:
    """``generate_urdf()`` for PyBullet: corner spheres instead of the sole boxes, armature on the child links,
    payload spheres at the TCPs."""
    params = load_parameters()
    for sole in FOOT_FRAMES.values():
        params["frames"][sole].pop("collision_box", None)
    if armature is not None:
        for name, joint in params["joints"].items():
            if joint["type"] != "revolute":
                continue
            axis = np.asarray(joint["axis"], dtype=np.float64)
            axis = axis / np.linalg.norm(axis)
            added = float(armature[JOINT_NAMES.index(name)]) * np.outer(axis, axis)
            link = params["links"][joint["child"]]
            ixx, ixy, ixz, iyy, iyz, izz = (float(v) for v in link["inertia"])
            inertia = _valid_inertia(np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]]) + added, axis)
            link["inertia"] = [inertia[0, 0], inertia[0, 1], inertia[0, 2], inertia[1, 1], inertia[1, 2], inertia[2, 2]]
    text = generate_urdf(params)
    collision = (
        "    <collision>\n"
        f'      <origin xyz="0.0 0.0 {CONTACT_RADIUS!r}" rpy="0.0 0.0 0.0"/>\n'
        f'      <geometry><sphere radius="{CONTACT_RADIUS!r}"/></geometry>\n'
        "    </collision>\n  </link>"
    )
    for name in contact_links():
        text, count = re.subn(rf'(<link name="{name}">.*?)\s*</link>', rf"\1\n{collision}", text, count=1, flags=re.S)
        if count != 1:
            msg = f"physics_urdf: no link {name} in the generated URDF"
            raise ValueError(msg)
    if hand_payload_kg > 0:
        i = _sphere_inertia(hand_payload_kg, PAYLOAD_RADIUS)
        inertial = (
            f'<mass value="{hand_payload_kg!r}"/>\n'
            f'      <inertia ixx="{i!r}" ixy="0.0" ixz="0.0" iyy="{i!r}" iyz="0.0" izz="{i!r}"/>'
        )
        for tcp in HAND_FRAMES.values():
            pattern = rf'(<link name="{tcp}">.*?)<mass value="0.0"/>\s*<inertia [^>]*/>'
            text, count = re.subn(pattern, rf"\1{inertial}", text, count=1, flags=re.S)
            if count != 1:
                msg = f"physics_urdf: no massless link {tcp} in the generated URDF"
                raise ValueError(msg)
    return text


def contact_links() -> tuple[str, ...]:
    """The eight corner links that carry the contact spheres, left foot first."""
    return tuple(
        f"{FOOT_FRAMES[side].removesuffix('_Sole')}_Contact_{c}" for side in ("left", "right") for c in CORNERS
    )


__all__ = ["CONTACT_RADIUS", "CORNERS", "PAYLOAD_RADIUS", "contact_links", "physics_urdf"]
