"""Whole-body inverse kinematics of the planner: the nominal standing pose and the poses of the warm start.

Initial pose: the nominal standing pose with the knees bent by ``motion.knee_bend_rad`` and the CoM over the
middle of the soles (a small damped Gauss-Newton IK, :func:`nominal_configuration`): the all-zero pose of
the model has straight knees at their 0 rad limit and the CoM 5 cm behind the sole centres.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import pinocchio as pin

from rh5_hyrodyn_mapper.model import standing_configuration
from rh5_msgs_py.array_types import FloatArray
from rh5_msgs_py.names import FOOT_FRAMES

from ..motions import SIDES

__all__ = ["nominal_configuration", "solve_ik"]


def nominal_configuration(model: pin.Model, knee_bend_rad: float, iterations: int = 60) -> FloatArray:
    """Standing pose with bent knees, flat soles where the straight pose has them, CoM over the soles' middle.

    Damped Gauss-Newton (:func:`solve_ik`) on [left sole 6D, right sole 6D, CoM xy, base orientation, knee
    angles] with a small pull of every joint to the straight pose; converges to ~1e-10.
    """
    data = model.createData()
    q_straight = standing_configuration(model)
    pin.framesForwardKinematics(model, data, q_straight)
    soles = {side: data.oMf[model.getFrameId(FOOT_FRAMES[side])].copy() for side in SIDES}
    com_xy = 0.5 * (soles["left"].translation[:2] + soles["right"].translation[:2])
    q = q_straight.copy()
    for n in ("LLKnee", "LRKnee"):
        q[model.joints[model.getJointId(n)].idx_q] = knee_bend_rad
    return solve_ik(model, q, soles, com=com_xy, knee_rad=knee_bend_rad, iterations=iterations)


def solve_ik(
    model: pin.Model,
    q_init: FloatArray,
    soles: Mapping[str, pin.SE3],
    *,
    com: FloatArray | None = None,
    knee_rad: float | None = None,
    q_ref: FloatArray | None = None,
    iterations: int = 30,
) -> FloatArray:
    """Whole-body IK: sole placements, CoM (xy or xyz), upright base, optionally knee angles; joints pulled to
    ``q_ref`` (default ``q_init``) by a small damping. Used for the nominal pose and the warm-start guesses."""
    data = model.createData()
    q_ref = q_init if q_ref is None else q_ref
    base_rotation = pin.Quaternion(q_ref[3:7]).toRotationMatrix()
    feet = {side: model.getFrameId(FOOT_FRAMES[side]) for side in soles}
    knees = [_q_of_v(model, model.joints[model.getJointId(n)].idx_v) for n in ("LLKnee", "LRKnee")]
    q = q_init.copy()
    for _ in range(iterations):
        pin.computeJointJacobians(model, data, q)
        pin.framesForwardKinematics(model, data, q)
        rows, jacs, weights = [], [], []
        for side, fid in feet.items():
            rows.append(pin.log6(data.oMf[fid].actInv(soles[side])).vector)
            jacs.append(pin.getFrameJacobian(model, data, fid, pin.ReferenceFrame.LOCAL))
            weights.append(np.full(6, 10.0))
        if com is not None:
            c = pin.centerOfMass(model, data, q)
            n = len(com)
            rows.append(np.asarray(com) - c[:n])
            jacs.append(pin.jacobianCenterOfMass(model, data, q)[:n])
            weights.append(np.full(n, 10.0))
        rot = pin.Quaternion(q[3:7]).toRotationMatrix()
        rows.append(pin.log3(rot.T @ base_rotation))
        jbase = np.zeros((3, model.nv))
        jbase[:, 3:6] = np.eye(3)
        jacs.append(jbase)
        weights.append(np.full(3, 1.0))
        if knee_rad is not None:
            for iq in knees:
                jk = np.zeros((1, model.nv))
                jk[0, iq - 1] = 1.0  # free flyer: idx_v = idx_q - 1 for 1-DoF joints
                rows.append(np.array([knee_rad - q[iq]]))
                jacs.append(jk)
                weights.append(np.array([1.0]))
        residual = np.concatenate(rows)
        jacobian = np.vstack(jacs)
        w = np.concatenate(weights)
        jw = (jacobian * w[:, None]).T
        a = jw @ jacobian + 1e-6 * np.eye(model.nv)
        a[6:, 6:] += 1e-3 * np.eye(model.nv - 6)
        b = jw @ residual
        b[6:] += 1e-3 * pin.difference(model, q, q_ref)[6:]
        q = pin.integrate(model, q, np.linalg.solve(a, b))
        if np.max(np.abs(residual)) < 1e-10:
            break
    return q


def _q_of_v(model: pin.Model, idx_v: int) -> int:
    for joint in model.joints:
        if joint.nv == 1 and joint.idx_v == idx_v:
            return int(joint.idx_q)
    raise KeyError(idx_v)
