"""The robot the planner optimises: RH5 with its payload, its Crocoddyl state and actuation, the nominal standing
state and the (optionally scaled) planning limits.

* Payload: ``motion.payload_kg_per_hand`` is added as a point mass at each hand TCP (``AL_TCP``/``AR_TCP``) to
  the inertia of the link carrying the TCP (pinocchio ``Inertia(m, c, 0)`` with c the TCP position in that
  joint's frame). The 5 kg bars of the paper become 2 x 5 kg at the grasp point.
* Scaled limits (design-improvement heuristic): ``limit_scale`` of :func:`build_robot` (and of
  :func:`rh5_planner.ocp.solve` / :func:`rh5_planner.ocp.build_problem`; ``{"knee:velocity": 3.0}`` or any object
  with ``factors(kind)``, :mod:`rh5_planner.limit_scale`) widens the position ranges about their middle and
  multiplies velocity and torque maxima for the barrier and the torque box.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import crocoddyl
import numpy as np
import pinocchio as pin

from rh5_hyrodyn_mapper.model import build_model, joint_limits, v_index
from rh5_msgs_py.array_types import FloatArray
from rh5_msgs_py.names import FOOT_FRAMES, HAND_FRAMES

from ..limit_scale import LimitScaleLike, limit_factors
from ..motions import SIDES, Reference
from .ik import nominal_configuration

__all__ = ["RobotSetup", "build_robot", "robot_mass"]


@dataclass(frozen=True, eq=False)
class RobotSetup:
    """The pinocchio model (with payload), Crocoddyl state/actuation, frame ids, nominal state and limits.

    Limits are in pinocchio's v order (``v_index() - 6`` maps JOINT_NAMES to it).
    """

    model: pin.Model
    state: crocoddyl.StateMultibody
    actuation: crocoddyl.ActuationModelFloatingBase
    foot_ids: Mapping[str, int]
    x0: FloatArray
    q_lower: FloatArray
    q_upper: FloatArray
    v_max: FloatArray
    tau_max: FloatArray
    payload_kg_per_hand: float

    @property
    def mass(self) -> float:
        """Total mass including the payload [kg]."""
        return float(sum(inertia.mass for inertia in self.model.inertias))

    def reference(self, x: FloatArray | None = None) -> Reference:
        """Sole positions and CoM of the state ``x`` (default: the nominal state)."""
        x = self.x0 if x is None else x
        data = self.model.createData()
        q = x[: self.model.nq]
        pin.framesForwardKinematics(self.model, data, q)
        com = pin.centerOfMass(self.model, data, q)
        feet = {side: data.oMf[fid].translation.copy() for side, fid in self.foot_ids.items()}
        return Reference(feet=feet, com=com.copy())


def _add_payload(model: pin.Model, mass: float) -> None:
    for frame_name in HAND_FRAMES.values():
        frame = model.frames[model.getFrameId(frame_name)]
        lever = frame.placement.translation.copy()
        model.inertias[frame.parentJoint] += pin.Inertia(mass, lever, np.zeros((3, 3)))


def build_robot(
    payload_kg_per_hand: float = 0.0, knee_bend_rad: float = 0.5, limit_scale: LimitScaleLike | None = None
) -> RobotSetup:
    """RH5 with the payload at the hands, its Crocoddyl state and actuation, and the nominal standing state.

    ``limit_scale`` (see :data:`LimitScaleLike`) scales the planning limits: position ranges widen about their
    middle, velocity and torque maxima multiply (the design-improvement heuristic plans with these)."""
    model = build_model(free_flyer=True)
    if payload_kg_per_hand > 0:
        _add_payload(model, payload_kg_per_hand)
    state = crocoddyl.StateMultibody(model)
    actuation = crocoddyl.ActuationModelFloatingBase(state)
    q0 = nominal_configuration(model, knee_bend_rad)
    x0 = np.concatenate([q0, np.zeros(model.nv)])
    limits = joint_limits()
    order = np.argsort(v_index(model))  # pinocchio v order -> position in JOINT_NAMES
    factors = {kind: f[order] for kind, f in limit_factors(limit_scale).items()}
    lower, upper = np.asarray(limits.position_lower)[order], np.asarray(limits.position_upper)[order]
    middle, half = 0.5 * (lower + upper), 0.5 * (upper - lower) * factors["position"]
    return RobotSetup(
        model=model,
        state=state,
        actuation=actuation,
        foot_ids={side: model.getFrameId(FOOT_FRAMES[side]) for side in SIDES},
        x0=x0,
        q_lower=middle - half,
        q_upper=middle + half,
        v_max=np.asarray(limits.velocity_max)[order] * factors["velocity"],
        tau_max=np.asarray(limits.torque_max)[order] * factors["torque"],
        payload_kg_per_hand=payload_kg_per_hand,
    )


def robot_mass(robot: RobotSetup) -> float:
    """Total mass of ``robot`` including its payload [kg]."""
    return robot.mass
