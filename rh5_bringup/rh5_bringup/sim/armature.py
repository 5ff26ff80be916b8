"""Joint armature for PyBullet: the actuators' reflected inertia on the relative joint motion only.

PyBullet has no joint armature, so the physics carries each actuator's reflected inertia A_j as inertia of the
joint's child link about the joint axis (physics.py). That is exact for the joint's own motion, but the child
link then also resists every absolute rotation about that axis: when the base pitches, the pitch rotors of hips,
knees, ankles, torso and shoulders would all have to turn with it (the robot's centroidal inertia at the standing
pose with 5 kg per hand: pitch 14.3 -> 32.1 kg m^2, roll 17.0 -> 31.9, yaw 3.3 -> 16.0), where a real rotor,
spinning N times faster with 1/N^2 of the inertia, barely notices.

`ArmatureCorrection` removes that spurious part. With the link model's dynamics M_a(q) qdd + h_a(q, v) and the
intended model (M(q) + diag(A)) qdd + h(q, v) (rigid links, armature on the joint coordinates, as Featherstone
and MuJoCo define it), the generalized force that turns one into the other at the acceleration qdd is

    F = [M_a qdd + h_a] - [M qdd + h] - A qdd = rnea_a(q, v, qdd) - rnea(q, v, qdd) - A qdd,

two inverse-dynamics passes. qdd is not known before the step, and an explicit correction with the last step's
accelerations is unstable here (the spurious coupling's generalized eigenvalues reach 3.8 times the inertia they
are added to). So qdd is predicted: the forward dynamics of the intended model with what held the robot in
PyBullet's last step still holding it: the touching sole corners (as points that neither move nor pull on the
ground), joints resting on a position limit, the crane. When PyBullet's constraints then do what the prediction
assumed, its next acceleration is the intended model's (rh5_bringup/test/test_armature.py: within 5e-6 of the
largest acceleration); when
they do not (a corner lifting or slipping in that step), the error is a bounded force for one step, not a
feedback loop.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Final

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from rh5_msgs_py.array_types import FloatArray
from rh5_msgs_py.names import JOINT_NAMES, NUM_JOINTS

CONTACT_DAMPING: Final = 1e-9
"""Regularisation of the constraint mobility J K^-1 J^T (a held sole and a joint limit in the same leg can be
dependent)."""

LIMIT_BAND: Final = 1e-4
"""A joint this close to a position limit [rad] counts as resting on it (PyBullet enforces the URDF's limits)."""

_WORLD_ALIGNED: Final = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED


def _skew(vectors: FloatArray) -> FloatArray:
    """Cross-product matrices [r]x of (..., 3) vectors, (..., 3, 3) (np.cross and np.stack cost ~12 us a call)."""
    out = np.zeros((*vectors.shape[:-1], 3, 3))
    x, y, z = vectors[..., 0], vectors[..., 1], vectors[..., 2]
    out[..., 0, 1], out[..., 0, 2], out[..., 1, 2] = -z, y, -x
    out[..., 1, 0], out[..., 2, 0], out[..., 2, 1] = z, -y, x
    return out


class ArmatureCorrection:
    """Generalized force that makes PyBullet's armature-on-links robot move as rigid links plus joint armature.

    ``rigid_urdf`` and ``armature_urdf`` are the same robot without and with the armature on the child links
    (`physics.physics_urdf`); ``armature`` is A in JOINT_NAMES order; ``feet`` maps each sole frame to its
    corner frames, the point contacts, in the order `predict` receives their flags (foot by foot).
    """

    def __init__(
        self, rigid_urdf: str, armature_urdf: str, armature: FloatArray, feet: Mapping[str, Sequence[str]]
    ) -> None:
        self.model = pin.buildModelFromXML(rigid_urdf, pin.JointModelFreeFlyer())
        self.data = self.model.createData()
        self.linked = pin.buildModelFromXML(armature_urdf, pin.JointModelFreeFlyer())
        self.linked_data = self.linked.createData()
        names = list(self.model.names)
        if self.model.nv != 6 + NUM_JOINTS or any(name not in names for name in JOINT_NAMES):
            msg = "ArmatureCorrection: the URDF does not have RH5's joints"
            raise ValueError(msg)
        # each JOINT_NAMES joint's place in Pinocchio's q and v
        self.joint_q = np.array([self.model.joints[names.index(n)].idx_q for n in JOINT_NAMES])
        self.joint_v = np.array([self.model.joints[names.index(n)].idx_v for n in JOINT_NAMES])
        self.armature = np.zeros(self.model.nv)
        self.armature[self.joint_v] = np.asarray(armature, dtype=np.float64)
        self.model.armature = self.armature  # Pinocchio's own joint armature: crba, rnea and aba include A
        self.lower = self.model.lowerPositionLimit[self.joint_q]
        self.upper = self.model.upperPositionLimit[self.joint_q]
        self.soles = [self.model.getFrameId(sole) for sole in feet]
        self.corner_offsets = self._corner_offsets(feet)

    def _corner_offsets(self, feet: Mapping[str, Sequence[str]]) -> list[FloatArray]:
        """Each foot's corners in its sole frame, (corners, 3)."""
        model, data = self.model, self.data
        pin.framesForwardKinematics(model, data, pin.neutral(model))
        offsets = []
        for sole, corners in feet.items():
            sole_pose = data.oMf[model.getFrameId(sole)]
            offsets.append(np.array([sole_pose.actInv(data.oMf[model.getFrameId(c)]).translation for c in corners]))
        return offsets

    def configuration(self, base_position: FloatArray, base_quaternion: FloatArray, joints: FloatArray) -> FloatArray:
        """Pinocchio's q from the root frame's world pose (quaternion x, y, z, w) and the joints (JOINT_NAMES)."""
        q = np.empty(self.model.nq)
        q[:3], q[3:7] = base_position, base_quaternion
        q[self.joint_q] = joints
        return q

    def velocity(self, rotation: FloatArray, linear: FloatArray, angular: FloatArray, joints: FloatArray) -> FloatArray:
        """Pinocchio's v from the root frame's world rotation, its origin's world linear and angular velocity and
        the joint velocities (JOINT_NAMES)."""
        v = np.empty(self.model.nv)
        v[:3], v[3:6] = rotation.T @ linear, rotation.T @ angular
        v[self.joint_v] = joints
        return v

    def mass_matrix(self, joints: FloatArray) -> FloatArray:
        """The intended model's floating-base mass matrix M + diag(A) (Pinocchio's v order) at the joint positions
        ``joints`` (JOINT_NAMES), the base at the origin."""
        q = self.configuration(np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0]), np.asarray(joints, dtype=np.float64))
        return pin.crba(self.model, self.data, q)

    def predict(
        self, q: FloatArray, v: FloatArray, tau: FloatArray, contacts: Sequence[bool], held: bool
    ) -> FloatArray:
        """Acceleration of the intended model (rigid links + joint armature) under joint torques ``tau``
        (JOINT_NAMES) and what holds it: the flagged corner points (not pulling on the ground), joints at a
        position limit (not pulled off it) and, while ``held``, the base."""
        model, data = self.model, self.data
        force = -pin.nonLinearEffects(model, data, q, v)
        force[self.joint_v] += tau
        inertia = pin.crba(model, data, q)  # M + diag(A); Pinocchio 4 fills both triangles
        rows, drift, push, group = self._constraints(q, v, contacts, held)
        solved = np.linalg.solve(inertia, np.column_stack([force, rows.T]))
        free, inv_jt = solved[:, 0], solved[:, 1:]
        while len(rows):  # drop the groups whose one-sided force would pull, then solve again
            mobility = rows @ inv_jt + CONTACT_DAMPING * np.eye(len(rows))
            constraint_force = np.linalg.solve(mobility, -drift - rows @ free)
            pulling_groups = np.zeros(int(group[-1]) + 1, dtype=bool)
            pulling_groups[group[push * constraint_force < 0.0]] = True
            keep = ~pulling_groups[group]
            if keep.all():
                return free + inv_jt @ constraint_force
            rows, drift, push, group, inv_jt = rows[keep], drift[keep], push[keep], group[keep], inv_jt[:, keep]
        return free

    def _constraints(
        self, q: FloatArray, v: FloatArray, contacts: Sequence[bool], held: bool
    ) -> tuple[FloatArray, FloatArray, FloatArray, npt.NDArray[np.int_]]:
        """Constraint rows J, drift J_dot v, each row's one-sided direction (+1: its force must be >= 0, -1: <= 0,
        0: either) and group (rows that are dropped together): the base while ``held``, each joint at a position
        limit, each touching foot (`_foot_constraints`)."""
        nv = self.model.nv
        blocks: list[tuple[FloatArray, FloatArray, FloatArray]] = []
        if held:
            blocks.append((np.eye(6, nv), np.zeros(6), np.zeros(6)))
        joints = q[self.joint_q]
        lower, upper = joints <= self.lower + LIMIT_BAND, joints >= self.upper - LIMIT_BAND
        for index in np.flatnonzero(lower | upper):
            row = np.zeros((1, nv))
            row[0, self.joint_v[index]] = 1.0
            blocks.append((row, np.zeros(1), np.array([1.0 if lower[index] else -1.0])))
        touching = np.asarray(contacts, dtype=bool)
        if touching.any():
            blocks += self._foot_constraints(q, v, touching)
        if not blocks:
            return np.zeros((0, nv)), np.zeros(0), np.zeros(0), np.zeros(0, dtype=np.int_)
        sizes = [len(block[1]) for block in blocks]
        group = np.repeat(np.arange(len(blocks)), sizes)
        rows, drift, push = (np.concatenate([block[i] for block in blocks]) for i in range(3))
        return rows, drift, push, group

    def _foot_constraints(
        self, q: FloatArray, v: FloatArray, touching: npt.NDArray[np.bool_]
    ) -> list[tuple[FloatArray, FloatArray, FloatArray]]:
        """Per foot with three or more corners touching: the sole held (6 world-aligned rows at the sole frame,
        its normal force one-sided); with one or two (an edge or a corner to roll about): each corner point held
        (3 rows each, J_c = J_lin - [r]x J_ang, a_c = a + alpha x r + w x (w x r), r its world offset)."""
        model, data = self.model, self.data
        pin.forwardKinematics(model, data, q, v, np.zeros(model.nv))
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        blocks = []
        start = 0
        for sole, offsets in zip(self.soles, self.corner_offsets, strict=True):
            flags = touching[start : start + len(offsets)]
            start += len(offsets)
            if not flags.any():
                continue
            jac = pin.getFrameJacobian(model, data, sole, _WORLD_ALIGNED)
            alpha = pin.getFrameAcceleration(model, data, sole, _WORLD_ALIGNED).angular
            origin = pin.getFrameClassicalAcceleration(model, data, sole, _WORLD_ALIGNED).linear
            if flags.sum() >= 3:
                blocks.append((jac, np.concatenate([origin, alpha]), np.array([0.0, 0.0, 1.0, 0.0, 0.0, 0.0])))
                continue
            arms = offsets[flags] @ data.oMf[sole].rotation.T  # (k, 3) world offsets
            omega = _skew(pin.getFrameVelocity(model, data, sole, _WORLD_ALIGNED).angular)
            rows = jac[None, :3, :] - _skew(arms) @ jac[3:]
            drift = origin + arms @ (_skew(alpha) + omega @ omega).T
            blocks += [(rows[k], drift[k], np.array([0.0, 0.0, 1.0])) for k in range(len(arms))]
        return blocks

    def correction(self, q: FloatArray, v: FloatArray, acceleration: FloatArray) -> FloatArray:
        """F = rnea_a - (rnea + A qdd) at ``acceleration`` (Pinocchio's v order; its rnea adds the model's armature):
        what PyBullet must be given on top of the intended forces so that its armature-on-links robot accelerates
        as the intended model."""
        linked = pin.rnea(self.linked, self.linked_data, q, v, acceleration)
        return linked - pin.rnea(self.model, self.data, q, v, acceleration)

    def split(self, force: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """The generalized force as joint torques (JOINT_NAMES) and the base's force and torque in its own frame
        (at the root frame origin)."""
        return force[self.joint_v], force[:3], force[3:6]


__all__ = ["ArmatureCorrection"]
