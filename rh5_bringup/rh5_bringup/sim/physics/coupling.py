"""The boards on the physics: `PhysicsActuatorBank` is the boards' `ActuatorBank` coupled to the `PhysicsWorld`,
with the bank's ``step`` signature, so `BoardEmulator` runs it unchanged; `build_physics` assembles both.

How the two plants couple (the physics is the truth, the bank is the boards' controller):

1. every cycle the bank's actuator positions and velocities are overwritten with the physics' joint state
   mapped to actuator space (``mapper.to_actuators(q, qd)``, the mechanisms' inverse kinematics);
2. the bank's cascade (position loop, 4 kHz velocity PI, current loop, limits) computes the motor force ``f``
   from there; its own plant integration is only the within-cycle prediction of its sub-steps, and its
   integrators carry over as on a real board;
3. ``tau = J^T f`` (``mapper.to_joints``, virtual power: f . l_dot = tau . q_dot) drives PyBullet for 1 ms;
   the telemetry then reports the new physics state with the bank's force, current, temperature and flags.
``external_force`` is not fed back: the physics applies the load itself, and the overwrite in step 1
resynchronises the bank every cycle.

Stepping: the boards' cascade and the rigid bodies alternate every 0.5 ms (`TIME_STEP`): a 1 ms board cycle
runs the cascade on the physics state, applies its force for 0.5 ms, and again. With one exchange per 1 ms the
coupled velocity loops of the hip pitch and torso actuators (and the wrists) limit-cycled at the Nyquist
frequency at bent-knee poses (measured at the first pose of fast_squats: +-4740 N alternating every cycle, the
robot creeping 15 cm in 3 s); at 2 kHz every tested pose (standing, the squat's start and deepest pose) stands
with joint velocities <= 0.09 rad/s RMS and base drift <= 6 mm over 2 s, for ~0.7 ms of CPU per simulated ms.
The board position loop therefore runs at 2 kHz here instead of 1 kHz. Physics time advances against the board
time it is given; at most `MAX_CATCH_UP_S` per call, the rest is dropped and counted (the simulation then runs
slower than real time instead of spiralling into ever longer catch-ups).
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from rh5_bringup.sim.actuator_model import ActuatorParams
from rh5_bringup.sim.actuators import ActuatorBank, ActuatorMeasurement
from rh5_bringup.sim.physics.world import GroundTruth, JointDynamics, PhysicsWorld, Pose
from rh5_hyrodyn_mapper.mapping import KinematicsError, RobotMapper, robot_mapper
from rh5_msgs_py.array_types import FloatArray
from rh5_msgs_py.names import NUM_JOINTS
from rh5_msgs_py.realtime import LatestValue

MAX_CATCH_UP_S = 3e-3
"""At most this much physics time per call; the rest is dropped and counted."""


def actuator_jacobian(q: FloatArray, mapper: RobotMapper | None = None) -> FloatArray:
    """J = d l / d q (32 actuators x 32 joints) at ``q``, column by column from the mapper's velocity map."""
    mapper = robot_mapper() if mapper is None else mapper
    q = np.asarray(q, dtype=np.float64)
    velocity = mapper.to_actuators(np.tile(q, (NUM_JOINTS, 1)), np.eye(NUM_JOINTS)).velocity
    assert velocity is not None
    return velocity.T


def joint_dynamics(bank: ActuatorBank, q: FloatArray | None = None, mapper: RobotMapper | None = None) -> JointDynamics:
    """The actuators' reflected inertia and viscous friction in joint space at ``q`` (default: the standing pose)."""
    jac = actuator_jacobian(np.zeros(NUM_JOINTS) if q is None else q, mapper)
    p = bank.params
    return JointDynamics(
        armature=(p.inertia[:, None] * jac**2).sum(axis=0),
        viscous=(p.viscous[:, None] * jac**2).sum(axis=0),
    )


def loaded_params(params: ActuatorParams, world: PhysicsWorld, q: FloatArray | None = None) -> ActuatorParams:
    """``params`` with each board tuned to the load its actuator drives in ``world`` at ``q`` (default: the
    standing pose), as a commissioning engineer would: inertia 1 / sum_j |(J H^-1 J^T)_ij| (H with the base free,
    armature included), at least the motor's own. With 1 / (J H^-1 J^T)_ii, the least inertia the actuator sees,
    coupled pairs (coaxial elbow and wrist roll) still ring; the row sum bounds every eigenvalue of the coupled
    velocity loops by the designed gain (Gershgorin). The velocity-loop gains scale with the inertia (kp = M w
    as in `default_params`), the braking curve inversely."""
    q = np.zeros(NUM_JOINTS) if q is None else np.asarray(q, dtype=np.float64)
    jac = actuator_jacobian(q)
    mobility = jac @ np.linalg.solve(world.mass_matrix(q), jac.T)  # J H^-1 J^T: actuator force -> acceleration
    inertia = np.maximum(1.0 / np.abs(mobility).sum(axis=1), params.inertia)
    scale = inertia / params.inertia
    return replace(
        params,
        inertia=inertia,
        kp_velocity=params.kp_velocity * scale,
        ki_velocity=params.ki_velocity * scale,
        braking_acceleration=params.braking_acceleration / scale,
    )


@dataclass
class CouplingCounts:
    """What the coupling did: physics steps taken, steps dropped to stay real time, board cycles."""

    physics_steps: int = 0
    dropped_steps: int = 0
    cycles: int = 0
    kinematics_errors: int = 0  # poses the mechanisms cannot map (a fallen robot): the last map is kept


class PhysicsActuatorBank:
    """An `ActuatorBank` whose plant is the `PhysicsWorld` (see the module docstring); ``step`` as the bank's.

    ``step`` holds ``lock``; other threads that touch the world (PyBullet is not thread-safe) take it too.
    """

    def __init__(self, world: PhysicsWorld, bank: ActuatorBank, mapper: RobotMapper | None = None) -> None:
        self.world = world
        self.bank = bank
        self.params = bank.params
        self.mapper = robot_mapper() if mapper is None else mapper
        self.counts = CouplingCounts()
        self.lock = threading.Lock()
        self.ground_truth_every = 0
        """Take a `GroundTruth` snapshot every this many physics steps (0: never), in the stepping thread, so
        readers in other threads need neither the lock nor PyBullet."""
        self.ground_truth: LatestValue[GroundTruth] = LatestValue()
        self._debt = 0.0
        self._tau = np.zeros(NUM_JOINTS)
        self._read()

    def _read(self) -> None:
        """Physics joints -> actuator space (the mechanisms' inverse kinematics)."""
        q, v = self.world.joint_state()
        try:
            sample = self.mapper.to_actuators(q, v)
        except (KinematicsError, ValueError, FloatingPointError):
            self.counts.kinematics_errors += 1
            return
        assert sample.velocity is not None
        self.q, self.v = q, v
        self.position, self.velocity = sample.position, sample.velocity

    def reset(self, q_joints: FloatArray | None = None, base_pose: Pose | None = None) -> ActuatorMeasurement:
        """Place the robot (`PhysicsWorld.reset`) and start the boards there, OFF."""
        self.world.reset(q_joints, base_pose)
        self._read()
        self._debt = 0.0
        return self.bank.reset(self.position)

    def measure(self) -> ActuatorMeasurement:
        """The last readings again without stepping (the bank's, with the physics' positions and velocities)."""
        with self.lock:
            return self.bank.measure()._replace(position=self.position.copy(), velocity=self.velocity.copy())

    def snapshot(self) -> GroundTruth:
        """Record (and return) the ground truth now; the caller holds the lock or is the stepping thread."""
        world = self.world
        truth = GroundTruth(world.steps * round(world.time_step * 1e9), world.base_pose(), world.foot_wrenches())
        self.ground_truth.set(truth)
        return truth

    def torques(self, force: FloatArray) -> FloatArray:
        """tau = J(q)^T f at the current physics pose [Nm]."""
        tau = self.mapper.to_joints(self.position, None, force, self.q).effort
        assert tau is not None
        return tau

    def step(  # noqa: PLR0917 - the signature of ActuatorBank.step
        self,
        dt: float,
        mode: Any,
        setpoint: Any = None,
        velocity_ff: Any = None,
        force_ff: Any = None,
        external_force: Any = None,
    ) -> ActuatorMeasurement:
        """One board cycle of ``dt``: overwrite the bank's plant with the physics, run the cascade, apply
        tau = J^T f to the physics for the whole 1 ms steps that ``dt`` completes; return the telemetry."""
        with self.lock:
            return self._step(dt, mode, setpoint, velocity_ff, force_ff, external_force)

    def _step(  # noqa: PLR0917
        self, dt: float, mode: Any, setpoint: Any, velocity_ff: Any, force_ff: Any, external_force: Any
    ) -> ActuatorMeasurement:
        time_step = self.world.time_step
        self._debt += dt
        steps = int((self._debt + 0.5 * time_step) // time_step)
        self._debt -= steps * time_step
        self.counts.cycles += 1
        if steps == 0:  # less than one physics step: the boards run on the last physics state
            measured = self._board_cycle(dt, mode, setpoint, velocity_ff, force_ff, external_force)
            return measured._replace(position=self.position.copy(), velocity=self.velocity.copy())
        taken = min(steps, round(MAX_CATCH_UP_S / time_step))
        for _ in range(taken):  # boards and rigid bodies alternate every physics step
            measured = self._board_cycle(time_step, mode, setpoint, velocity_ff, force_ff, external_force)
            try:
                tau = self._tau = self.torques(measured.force)
            except (KinematicsError, ValueError, FloatingPointError):
                self.counts.kinematics_errors += 1
                tau = self._tau
            self.world.step(tau, (self.q, self.v))
            self._read()
        self.counts.physics_steps += taken
        self.counts.dropped_steps += steps - taken
        every = self.ground_truth_every
        if every and self.world.steps % every < taken:
            self.snapshot()
        return measured._replace(position=self.position.copy(), velocity=self.velocity.copy())

    def _board_cycle(  # noqa: PLR0917
        self, dt: float, mode: Any, setpoint: Any, velocity_ff: Any, force_ff: Any, external_force: Any
    ) -> ActuatorMeasurement:
        """The bank's cascade for ``dt`` from the physics state (positions clipped to the stroke, as measured)."""
        state = self.bank.state
        np.copyto(state.position, np.clip(self.position, self.params.position_min, self.params.position_max))
        np.copyto(state.velocity, self.velocity)
        return self.bank.step(dt, mode, setpoint, velocity_ff, force_ff, external_force)


def build_physics(
    friction_coefficient: float = 0.7,
    hand_payload_kg: float = 0.0,
    q_joints: FloatArray | None = None,
    *,
    support: bool = True,
    bank: ActuatorBank | None = None,
    tune_to_load: bool = False,
) -> PhysicsActuatorBank:
    """World + boards as the simulated-hardware node uses them: actuator terms from the bank, the robot standing
    at ``q_joints`` (default: the nominal standing pose), held by the crane when ``support``, boards OFF."""
    bank = ActuatorBank() if bank is None else bank
    world = PhysicsWorld(friction_coefficient, hand_payload_kg, joint_dynamics(bank, q_joints))
    if tune_to_load:  # armature and tuning at the starting pose: the mechanisms' Jacobians change with the pose
        bank = ActuatorBank(loaded_params(bank.params, world, q_joints))
    coupled = PhysicsActuatorBank(world, bank)
    coupled.reset(q_joints)
    if support:
        world.hold_base()
    return coupled


__all__ = [
    "MAX_CATCH_UP_S",
    "CouplingCounts",
    "PhysicsActuatorBank",
    "actuator_jacobian",
    "build_physics",
    "joint_dynamics",
    "loaded_params",
]
