"""Every link's transform from its parent link, for /tf: what robot_state_publisher computes, from Pinocchio.

The tree is the URDF's: one transform per joint, from the joint's parent link to its child link. A fixed joint's
transform never changes (it goes to /tf_static once); a revolute joint's is its origin followed by the rotation
about its axis by the joint angle. Origins and axes are read off the Pinocchio model built from the same URDF
(``origin = parent link placement^-1 * joint placement``; the axis from the joint's motion at one radian), and
the per-update work is a handful of numpy operations over all 32 joints at once (quaternion products), no
Python loop per joint.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from rh5_msgs_py.array_types import FloatArray
from rh5_msgs_py.names import JOINT_NAMES


def rotation_to_quaternion(rotation: FloatArray) -> FloatArray:
    """Quaternion (x, y, z, w) of a 3x3 rotation matrix, w >= 0."""
    q = pin.Quaternion(np.asarray(rotation, dtype=np.float64)).coeffs().copy()  # x, y, z, w
    return -q if q[3] < 0 else q


def quaternion_multiply(a: FloatArray, b: FloatArray) -> FloatArray:
    """Hamilton products a_i * b_i of (n, 4) arrays of (x, y, z, w) quaternions."""
    ax, ay, az, aw = a[..., 0], a[..., 1], a[..., 2], a[..., 3]
    bx, by, bz, bw = b[..., 0], b[..., 1], b[..., 2], b[..., 3]
    return np.stack(
        (
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz,
        ),
        axis=-1,
    )


@dataclass(frozen=True)
class UrdfJoint:
    """One joint of the URDF: its name, type and the links it connects."""

    name: str
    type: str
    parent: str
    child: str


def urdf_joints(urdf: str) -> list[UrdfJoint]:
    """The joints of a URDF text, in document order."""
    root = ET.fromstring(urdf)
    return [
        UrdfJoint(
            j.get("name", ""), j.get("type", ""), j.find("parent").get("link", ""), j.find("child").get("link", "")
        )
        for j in root.iter("joint")
    ]


def urdf_links(urdf: str) -> list[str]:
    """The link names of a URDF text, in document order."""
    return [link.get("name", "") for link in ET.fromstring(urdf).iter("link")]


class KinematicTree:
    """Parent -> child transforms of every joint of a fixed-base URDF, the moving ones as a function of the angles."""

    def __init__(self, urdf: str, joint_names: tuple[str, ...] = JOINT_NAMES) -> None:
        model = pin.buildModelFromXML(urdf)
        data = model.createData()
        joints = urdf_joints(urdf)
        self.root = next(iter(set(urdf_links(urdf)) - {j.child for j in joints}))
        moving = {j.name: j for j in joints if j.type in ("revolute", "continuous")}
        if unknown := [n for n in joint_names if n not in moving]:
            msg = f"joints not revolute in the URDF: {unknown}"
            raise ValueError(msg)
        if extra := sorted(set(moving) - set(joint_names)):
            msg = f"revolute joints of the URDF missing from joint_names: {extra}"
            raise ValueError(msg)

        def body(link: str) -> pin.Frame:
            return model.frames[model.getFrameId(link, pin.FrameType.BODY)]

        # Motion of every joint at one radian: the axis is the rotation it adds to the joint placement.
        pin.forwardKinematics(model, data, np.ones(model.nq))
        at_one = [pin.SE3(data.liMi[i]) for i in range(model.njoints)]
        self.joint_names = joint_names
        self.parents = tuple(moving[n].parent for n in joint_names)
        self.children = tuple(moving[n].child for n in joint_names)
        origins = []
        axes = []
        for name in joint_names:
            jid = model.getJointId(name)
            origin = body(moving[name].parent).placement.inverse() * model.jointPlacements[jid]
            origins.append(origin)
            turn = pin.log3(model.jointPlacements[jid].rotation.T @ at_one[jid].rotation)
            axes.append(turn / np.linalg.norm(turn))
        self.origin_translation: FloatArray = np.array([o.translation for o in origins])
        self.origin_rotation: FloatArray = np.array([rotation_to_quaternion(o.rotation) for o in origins])
        self.axes: FloatArray = np.array(axes)
        # Fixed joints: constant transforms from the placements of their two links at any configuration.
        pin.framesForwardKinematics(model, data, pin.neutral(model))
        fixed = [j for j in joints if j.type == "fixed"]
        self.fixed_parents = tuple(j.parent for j in fixed)
        self.fixed_children = tuple(j.child for j in fixed)
        placements = [
            data.oMf[model.getFrameId(j.parent, pin.FrameType.BODY)].inverse()
            * data.oMf[model.getFrameId(j.child, pin.FrameType.BODY)]
            for j in fixed
        ]
        self.fixed_translation: FloatArray = np.array([p.translation for p in placements]).reshape(-1, 3)
        self.fixed_rotation: FloatArray = np.array([rotation_to_quaternion(p.rotation) for p in placements]).reshape(
            -1, 4
        )

    @property
    def links(self) -> tuple[str, ...]:
        """Every link of the tree: the root and each joint's child."""
        return (self.root, *self.children, *self.fixed_children)

    def rotations(self, angles: FloatArray) -> FloatArray:
        """(32, 4) quaternions (x, y, z, w) of each moving joint's child link in its parent link at ``angles``
        (JOINT_NAMES order); their translations are ``origin_translation``."""
        half = 0.5 * np.asarray(angles, dtype=np.float64)
        turn = np.empty((len(half), 4))
        turn[:, :3] = self.axes * np.sin(half)[:, None]
        turn[:, 3] = np.cos(half)
        return quaternion_multiply(self.origin_rotation, turn)
