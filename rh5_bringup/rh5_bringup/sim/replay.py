"""Play a planned trajectory on the physics in this process, without ROS: the paper's PyBullet check.

Three controllers track the 1 kHz reference (the planner's interpolation) in joint space:

* ``"rigid_pd"``: the paper's setup. The rigid-body RH5 (no actuator model) with PyBullet's own joint position
  motors: an implicit PD inside the constraint solver (position gain 0.1, velocity gain 1), torques limited to
  the joint limits.
* ``"joint_pd"``: the same idea on the suite's physics, which carries the actuators' reflected inertia as joint
  armature (see physics.py): explicit torques tau = Kp (q* - q) + Kd (v* - v), each joint's gains set for a
  20 Hz, 0.7-damped loop on its inertia at the start pose (base free, armature included).
* ``"boards"``: the suite's chain in lockstep, mapper (commands clamped to the actuator limits, as the mapper
  node does) -> the boards' cascade (POSITION_FF) -> tau = J^T f, as `rh5 experiment` runs it through the
  nodes, minus ROS, timing and the stabiliser's feedback.

All optionally feed the planned torques forward (not ``rigid_pd``: PyBullet's motors take no feed-forward).
The result holds the base deviation from the plan (the settled start offset removed) during the motion and
an optional hold of its last pose, and how far each stance sole tilted: a tilting stance sole means the robot
needed a centre of pressure outside the foot and rolled over its edge.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Final, Literal

import numpy as np

from rh5_bringup.hardware.ndlcom.payloads import CommandMode
from rh5_hyrodyn_mapper.mapping import robot_mapper
from rh5_hyrodyn_mapper.model import joint_limits
from rh5_msgs_py.array_types import FloatArray
from rh5_msgs_py.names import NUM_ACTUATORS, NUM_JOINTS
from rh5_msgs_py.trajectory_file import NQ, TrajectoryData

from .actuators import ActuatorBank
from .physics import JointDynamics, PhysicsWorld, build_physics, joint_dynamics, quaternion_matrix

Controller = Literal["rigid_pd", "joint_pd", "boards"]
Advance = Callable[[FloatArray, FloatArray, FloatArray], None]
"""One 1 ms control period towards joint positions, velocities and feed-forward torques."""

CONTROLLERS: Final = ("rigid_pd", "joint_pd", "boards")
RIGID_POSITION_GAIN: Final = 0.1
RIGID_VELOCITY_GAIN: Final = 1.0
PD_BANDWIDTH_HZ: Final = 20.0
PD_DAMPING_RATIO: Final = 0.7
SUPPORT_S: Final = 0.3
"""The crane holds the robot this long at the start pose, then lets go."""
SETTLE_S: Final = 0.7
"""Standing free at the start pose before the motion starts."""
PERIOD_S: Final = 1e-3


@dataclass(frozen=True)
class ReplayResult:
    """Base deviation (measured minus planned, start offset removed) and stance sole tilt during the motion (and
    the hold after it)."""

    controller: str
    times: FloatArray
    """(M,) trajectory time of each sample [s]."""
    base_deviation: FloatArray
    """(M, 3) x, y, z [m]."""
    sole_tilt: FloatArray
    """(M, 2) left, right: angle of the sole to the ground while planned in contact [rad], NaN otherwise."""

    @property
    def deviation_range(self) -> FloatArray:
        """(3, 2) per axis: smallest and largest deviation [m]."""
        return np.stack([self.base_deviation.min(axis=0), self.base_deviation.max(axis=0)], axis=1)

    @property
    def max_sole_tilt(self) -> float:
        """Largest stance sole tilt [rad] (0 when no foot was ever in contact)."""
        tilt = self.sole_tilt[np.isfinite(self.sole_tilt)]
        return float(tilt.max()) if tilt.size else 0.0


def _rigid_pd(world: PhysicsWorld) -> Advance:
    limit = np.asarray(joint_limits().torque_max, dtype=np.float64)
    substeps = round(PERIOD_S / world.time_step)

    def advance(q: FloatArray, v: FloatArray, tau: FloatArray) -> None:  # noqa: ARG001 - no feed-forward input
        for _ in range(substeps):
            world.step_position_motors(q, v, RIGID_POSITION_GAIN, RIGID_VELOCITY_GAIN, limit)

    return advance


def _joint_pd(world: PhysicsWorld, q0: FloatArray) -> Advance:
    inertia = np.diag(world.mass_matrix(q0))
    w = 2.0 * np.pi * PD_BANDWIDTH_HZ
    kp, kd = inertia * w**2, 2.0 * PD_DAMPING_RATIO * inertia * w
    substeps = round(PERIOD_S / world.time_step)

    def advance(q: FloatArray, v: FloatArray, tau: FloatArray) -> None:
        for _ in range(substeps):
            measured_q, measured_v = world.joint_state()
            world.step(kp * (q - measured_q) + kd * (v - measured_v) + tau, (measured_q, measured_v))

    return advance


def _setup(controller: Controller, q0: FloatArray, friction: float, payload: float) -> tuple[PhysicsWorld, Advance]:
    """The world (held by the crane, at the start pose) and the controller's 1 ms step."""
    if controller == "boards":
        coupled = build_physics(friction, payload, q0, tune_to_load=True)
        mapper = robot_mapper()
        track = np.full(NUM_ACTUATORS, int(CommandMode.POSITION_FF))

        def advance(q: FloatArray, v: FloatArray, tau: FloatArray) -> None:
            target, _ = mapper.clamp(mapper.to_actuators(q, v, tau=tau))  # as the mapper node sends it
            coupled.step(PERIOD_S, track, target.position, target.velocity, target.effort)

        return coupled.world, advance
    rigid = controller == "rigid_pd"
    world = PhysicsWorld(friction, payload, JointDynamics.zero() if rigid else joint_dynamics(ActuatorBank(), q0))
    world.reset(q0)
    world.hold_base()
    return world, _rigid_pd(world) if rigid else _joint_pd(world, q0)


def replay(
    data: TrajectoryData,
    controller: Controller = "boards",
    *,
    friction_coefficient: float = 0.7,
    torque_feedforward: bool = False,
    hold_s: float = 0.0,
) -> ReplayResult:
    """Stand the robot at the plan's first pose, let go of it, play ``data`` with ``controller``, then hold its
    last pose for ``hold_s`` (those samples follow the motion's, against the plan's last base position)."""
    if controller not in CONTROLLERS:
        msg = f"replay: controller must be one of {CONTROLLERS}, got {controller!r}"
        raise ValueError(msg)
    from rh5_planner.interpolation import interpolate  # noqa: PLC0415 - the planner's 1 kHz reference

    reference = interpolate(data, 1.0 / PERIOD_S)
    q_ref = reference.states[:, 7:NQ]
    v_ref = reference.states[:, NQ + 6 :]
    tau_ref = reference.controls if torque_feedforward else np.zeros_like(reference.controls)
    hold = round(hold_s / PERIOD_S)
    if hold > 0:  # the last pose at rest
        q_ref = np.vstack([q_ref, np.repeat(q_ref[-1:], hold, axis=0)])
        v_ref = np.vstack([v_ref, np.zeros((hold, v_ref.shape[1]))])
        tau_ref = np.vstack([tau_ref, np.repeat(tau_ref[-1:], hold, axis=0)])
    base_ref = reference.states[np.minimum(np.arange(len(q_ref)), len(reference.times) - 1), :3]
    phases = reference.contact_phases[np.minimum(np.arange(len(q_ref)), len(reference.times) - 1)]
    times = reference.times[0] + PERIOD_S * np.arange(len(q_ref))
    payload = float(data.motion.get("parameters", {}).get("payload_kg_per_hand", 0.0))
    world, advance = _setup(controller, q_ref[0], friction_coefficient, payload)
    try:
        world.shift_base_xy(base_ref[0, :2])
        at_rest = np.zeros(NUM_JOINTS)
        for _ in range(round(SUPPORT_S / PERIOD_S)):
            advance(q_ref[0], at_rest, tau_ref[0])
        world.release_support()
        for _ in range(round(SETTLE_S / PERIOD_S)):
            advance(q_ref[0], at_rest, tau_ref[0])
        offset = world.base_pose().position - base_ref[0]
        deviation = np.empty_like(base_ref)
        tilt = np.full((len(q_ref), 2), np.nan)
        for k in range(len(q_ref)):
            advance(q_ref[k], v_ref[k], tau_ref[k])
            deviation[k] = world.base_pose().position - base_ref[k] - offset
            for i, side in enumerate(("left", "right")):
                if phases[k, i]:
                    up = quaternion_matrix(world.sole_pose(side).orientation)[2, 2]
                    tilt[k, i] = float(np.arccos(np.clip(up, -1.0, 1.0)))
    finally:
        world.close()
    return ReplayResult(controller, times - times[0], deviation, tilt)


__all__ = ["CONTROLLERS", "Controller", "ReplayResult", "replay"]
