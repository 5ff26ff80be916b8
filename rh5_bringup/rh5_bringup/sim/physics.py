"""Whole-body physics of the simulated RH5: a PyBullet floating-base robot on flat ground, driven by the boards.

Two pieces, both free of ROS:

* `PhysicsWorld`: a PyBullet DIRECT world (gravity, ground plane, RH5 from ``generate_urdf()`` with a free
  base, torque control, self-collision off, a 1 ms step). Foot contact: four spheres of 5 mm radius, one on
  each corner contact frame of the 200 x 80 mm sole (``L?Foot_Contact_*``), replace the sole box of the URDF:
  a sphere touches the plane in exactly one point, so every corner yields one contact, steadily (a box on a
  plane gives a manifold whose points wander). Friction: the sole's ``friction_coefficient`` times the
  ground's 1.0 (PyBullet multiplies the two). Readings: joints in JOINT_NAMES order, the TRUE pose of the
  root link frame (PyBullet's base pose is the base's centre-of-mass frame; converted here), and each foot's
  contact wrench. A crane (`hold_base`/`release_support`) holds the base fixed while the boards are off.
  Hand payloads are point masses at AL_TCP/AR_TCP, as the planner models them.
* `PhysicsActuatorBank`: the boards' `ActuatorBank` coupled to the world, with the bank's ``step`` signature,
  so `BoardEmulator` runs it unchanged.

How the two plants couple (the physics is the truth, the bank is the boards' controller):

1. every cycle the bank's actuator positions and velocities are overwritten with the physics' joint state
   mapped to actuator space (``mapper.to_actuators(q, qd)``, the mechanisms' inverse kinematics);
2. the bank's cascade (position loop, 4 kHz velocity PI, current loop, limits) computes the motor force ``f``
   from there; its own plant integration is only the within-cycle prediction of its sub-steps, and its
   integrators carry over as on a real board;
3. ``tau = J^T f`` (``mapper.to_joints``, virtual power: f . l_dot = tau . q_dot) drives PyBullet for 1 ms;
   the telemetry then reports the new physics state with the bank's force, current, temperature and flags.

The reflected motor inertia M (rotor J N^2, up to 300 kg at a ball screw) dominates the light links: a
velocity loop tuned for M (kp = M w) on a wrist whose own inertia is 40 times smaller is unstable at any
sample rate above ~1/(2 M / kp). PyBullet has no joint armature, so it is added to the inertia of each
joint's child link about the joint axis: A_j = sum_i M_i J_ij^2 at the starting pose (the diagonal of
J^T M J; the symmetric 2-DOF units make it diagonal there), which keeps the stiff loops stable inside Bullet's
implicit step. Bullet also needs a physical tensor, so the least inertia normal to the axis that satisfies the
triangle inequality is added too (`_valid_inertia`). On a link that inertia would also resist every absolute
rotation of the link (a real rotor spins N times faster with 1/N^2 of the inertia); `ArmatureCorrection`
(sim/armature.py) applies, every step, the generalized force that takes that part out again, so the robot moves
as rigid links with A on the joint coordinates (measured: one step matches that model to 5e-6; without it the
robot's centroidal pitch inertia is 2.2 times its own and the planned walk played with joint PD lagged 45 mm
instead of 3). The boards tuned for the motor alone (kp = M w) make the light rotary joints ring (standing in
HOLD: torso yaw 0.073 rad/s RMS, peaks 0.16); `loaded_params` (``tune_to_load``, the node's default) tunes each
board to the inertia it drives, as at commissioning: the ringing drops to <= 0.011 rad/s RMS (peaks 0.036) and
the standing base drift over 3 s from 2.8 to 2.0 mm (the leg boards keep their tuning: their motor inertia
exceeds their load). The actuators' viscous friction acts on the physics as -J^T b J q_dot in the torque; their
Coulomb friction does not (PyBullet velocity motors as implicit stiction cost three times the step).
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

import math
import re
import threading
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from tempfile import TemporaryDirectory
from typing import Any, NamedTuple

import numpy as np
import numpy.typing as npt
import pybullet as pb

from rh5_bringup.sim.actuator_model import ActuatorParams
from rh5_bringup.sim.actuators import ActuatorBank, ActuatorMeasurement
from rh5_bringup.sim.armature import ArmatureCorrection
from rh5_hyrodyn_mapper.mapping import KinematicsError, RobotMapper, robot_mapper
from rh5_hyrodyn_mapper.model.urdf import generate_urdf, load_parameters
from rh5_msgs_py.names import BASE_FRAME, FOOT_FRAMES, HAND_FRAMES, JOINT_NAMES, NUM_JOINTS
from rh5_msgs_py.realtime import LatestValue

FloatArray = npt.NDArray[np.float64]

TIME_STEP = 5e-4
"""PyBullet step [s]: two per 1 ms board cycle, each after a run of the board cascade (see the module docstring)."""

GRAVITY = 9.81
CONTACT_RADIUS = 0.005
"""Radius of the corner spheres [m]; their lowest points lie in the sole plane."""

CORNERS = ("FrontLeft", "FrontRight", "RearLeft", "RearRight")
MAX_CATCH_UP_S = 3e-3
"""At most this much physics time per call; the rest is dropped and counted."""
PAYLOAD_RADIUS = 0.05
"""A hand payload is a solid sphere of this radius at the TCP (its inertia keeps Bullet well conditioned)."""

SUPPORT_MAX_FORCE = 1e5
"""The crane holds up to this force [N] (and the same number as torque [Nm])."""


class Pose(NamedTuple):
    """Position [m] and orientation quaternion (x, y, z, w) of a frame in the world."""

    position: FloatArray
    orientation: FloatArray


class FootWrench(NamedTuple):
    """The ground's contact wrench on one foot: force [N] and moment [Nm] about the sole frame origin.

    ``*_world`` are in world axes; `in_sole_frame` gives them in sole axes (what a sole F/T sensor measures).
    """

    force_world: FloatArray
    moment_world: FloatArray
    sole_rotation: FloatArray  # (3, 3): sole axes in the world
    contacts: int

    def in_sole_frame(self) -> tuple[FloatArray, FloatArray]:
        """Force and moment in sole axes (about the sole origin)."""
        rt = self.sole_rotation.T
        return rt @ self.force_world, rt @ self.moment_world


class GroundTruth(NamedTuple):
    """What the simulation knows and a robot would not: simulated time, true base pose, foot wrenches."""

    sim_ns: int
    base: Pose
    wrenches: dict[str, FootWrench]


@dataclass(frozen=True)
class JointDynamics:
    """Per-joint actuator terms added to the physics (JOINT_NAMES order): armature [kg m^2] and viscous
    friction [Nm s/rad], from the actuator parameters through the mapper's Jacobian at a pose."""

    armature: FloatArray
    viscous: FloatArray

    @classmethod
    def zero(cls) -> JointDynamics:
        """No actuator terms (a bare rigid-body robot)."""
        return cls(np.zeros(NUM_JOINTS), np.zeros(NUM_JOINTS))


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


# ----------------------------------------------------------------------------------------------------------------
# URDF for the physics


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


# ----------------------------------------------------------------------------------------------------------------
# Rotations (the few needed, on 3x3 matrices and x, y, z, w quaternions)


def quaternion_matrix(quat: Sequence[float]) -> FloatArray:
    """3x3 rotation of a unit quaternion (x, y, z, w)."""
    return np.asarray(pb.getMatrixFromQuaternion(quat), dtype=np.float64).reshape(3, 3)


def axis_angle_quaternion(axis: FloatArray, angle: float) -> FloatArray:
    """Quaternion (x, y, z, w) of a rotation by ``angle`` about the unit ``axis``."""
    s = math.sin(0.5 * angle)
    return np.array([axis[0] * s, axis[1] * s, axis[2] * s, math.cos(0.5 * angle)])


def levelling_quaternion(up: FloatArray) -> FloatArray:
    """The smallest rotation taking the unit vector ``up`` to the world z axis (no yaw added)."""
    z = np.array([0.0, 0.0, 1.0])
    axis = np.cross(up, z)
    norm = float(np.linalg.norm(axis))
    if norm < 1e-12:
        return np.array([0.0, 0.0, 0.0, 1.0]) if up[2] > 0 else np.array([1.0, 0.0, 0.0, 0.0])
    return axis_angle_quaternion(axis / norm, math.atan2(norm, float(up @ z)))


# ----------------------------------------------------------------------------------------------------------------
# The world


def _cross(a: FloatArray, b: FloatArray) -> FloatArray:
    """a x b of two 3-vectors (np.cross costs ~20 us a call)."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def _free_base(full: FloatArray) -> FloatArray:
    """The joint block of a floating-base mass matrix (base first, 6 rows) with the base free: its Schur complement."""
    base, coupling, joints = full[:6, :6], full[:6, 6:], full[6:, 6:]
    return joints - coupling.T @ np.linalg.solve(base, coupling)


class PhysicsWorld:
    """RH5 on flat ground in its own PyBullet DIRECT client; ``close`` (or ``with``) disconnects."""

    def __init__(
        self,
        friction_coefficient: float = 0.7,
        hand_payload_kg: float = 0.0,
        dynamics: JointDynamics | None = None,
        time_step: float = TIME_STEP,
        solver_iterations: int = 50,
    ) -> None:
        if friction_coefficient < 0 or hand_payload_kg < 0 or time_step <= 0:
            msg = "PhysicsWorld: friction, payload and time step must be >= 0 (time step > 0)"
            raise ValueError(msg)
        self.dynamics = JointDynamics.zero() if dynamics is None else dynamics
        self.time_step = time_step
        self.friction_coefficient = friction_coefficient
        self.hand_payload_kg = hand_payload_kg
        self.steps = 0
        self._client = pb.connect(pb.DIRECT)
        cid = self._client
        try:
            pb.setGravity(0.0, 0.0, -GRAVITY, physicsClientId=cid)
            pb.setPhysicsEngineParameter(
                fixedTimeStep=time_step, numSubSteps=0, numSolverIterations=solver_iterations, physicsClientId=cid
            )
            self.ground = self._load_ground()
            linked_urdf = physics_urdf(self.dynamics.armature, hand_payload_kg)
            with TemporaryDirectory(prefix="rh5_physics_") as tmp:
                path = Path(tmp) / "rh5.urdf"
                path.write_text(linked_urdf, encoding="utf-8")
                self.robot = pb.loadURDF(
                    str(path), flags=pb.URDF_USE_INERTIA_FROM_FILE, useFixedBase=False, physicsClientId=cid
                )
            self._index_links()
            self._configure()
            self.armature = (
                ArmatureCorrection(
                    physics_urdf(None, hand_payload_kg),
                    linked_urdf,
                    self.dynamics.armature,
                    {FOOT_FRAMES[side]: self._corner_names[side] for side in ("left", "right")},
                )
                if self.dynamics.armature.any()
                else None
            )
            """Turns the armature on the child links into armature on the joints (sim/armature.py); None: rigid."""
        except BaseException:
            pb.disconnect(physicsClientId=cid)
            raise
        self._support: int | None = None
        self._tau = [0.0] * NUM_JOINTS

    # --- construction -------------------------------------------------------------------------------------------

    def _load_ground(self) -> int:
        cid = self._client
        shape = pb.createCollisionShape(pb.GEOM_PLANE, physicsClientId=cid)
        ground = pb.createMultiBody(0.0, shape, physicsClientId=cid)
        pb.changeDynamics(ground, -1, lateralFriction=1.0, restitution=0.0, physicsClientId=cid)
        return ground

    def _index_links(self) -> None:
        cid, robot = self._client, self.robot
        joint_of: dict[str, int] = {}
        link_of: dict[str, int] = {}
        for j in range(pb.getNumJoints(robot, physicsClientId=cid)):
            info = pb.getJointInfo(robot, j, physicsClientId=cid)
            joint_of[info[1].decode()] = j
            link_of[info[12].decode()] = j
        missing = [name for name in JOINT_NAMES if name not in joint_of]
        if missing:
            msg = f"PhysicsWorld: joints {missing} are not in the loaded URDF"
            raise ValueError(msg)
        self.joint_indices = [joint_of[name] for name in JOINT_NAMES]
        self.sole_links = {side: link_of[name] for side, name in FOOT_FRAMES.items()}
        corners = contact_links()
        self.contact_links = {
            "left": [link_of[n] for n in corners[:4]],
            "right": [link_of[n] for n in corners[4:]],
        }
        self._corner_names = {"left": corners[:4], "right": corners[4:]}
        self._corner_links = [link_of[n] for n in corners]  # left foot first, as the armature correction's flags
        self._foot_of_link = {link: side for side, links in self.contact_links.items() for link in links}
        info = pb.getDynamicsInfo(robot, -1, physicsClientId=cid)
        self._base_inertial = (info[3], info[4])  # the COM frame in the root link frame
        self._base_inertial_inv = pb.invertTransform(*self._base_inertial)
        masses = [info[0]] + [
            pb.getDynamicsInfo(robot, j, physicsClientId=cid)[0]
            for j in range(pb.getNumJoints(robot, physicsClientId=cid))
        ]
        self.total_mass = float(sum(masses))

    def _configure(self) -> None:
        cid, robot = self._client, self.robot
        for link in (link for links in self.contact_links.values() for link in links):
            pb.changeDynamics(
                robot,
                link,
                lateralFriction=self.friction_coefficient,
                spinningFriction=0.0,
                rollingFriction=0.0,
                restitution=0.0,
                physicsClientId=cid,
            )
        pb.changeDynamics(robot, -1, linearDamping=0.0, angularDamping=0.0, physicsClientId=cid)
        for j in range(pb.getNumJoints(robot, physicsClientId=cid)):
            pb.changeDynamics(robot, j, linearDamping=0.0, angularDamping=0.0, jointDamping=0.0, physicsClientId=cid)
        # the default velocity motors off: the joints are torque-driven only
        pb.setJointMotorControlArray(
            robot, self.joint_indices, pb.VELOCITY_CONTROL, forces=[0.0] * NUM_JOINTS, physicsClientId=cid
        )

    # --- state ---------------------------------------------------------------------------------------------------

    def reset(self, q_joints: FloatArray | None = None, base_pose: Pose | None = None) -> Pose:
        """Joints at ``q_joints`` (default 0: the nominal standing pose) at rest; the root link at ``base_pose``,
        or (None) placed so that the soles are level and the lowest corner rests on the ground. Returns the pose."""
        cid, robot = self._client, self.robot
        q = np.zeros(NUM_JOINTS) if q_joints is None else np.asarray(q_joints, dtype=np.float64)
        if q.shape != (NUM_JOINTS,):
            msg = f"reset: expected {NUM_JOINTS} joint positions, got shape {q.shape}"
            raise ValueError(msg)
        for index, value in zip(self.joint_indices, q.tolist(), strict=True):
            pb.resetJointState(robot, index, value, 0.0, physicsClientId=cid)
        if base_pose is None:
            self._set_base(Pose(np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0])))
            base_pose = self._standing_base_pose()
        self._set_base(base_pose)
        pb.resetBaseVelocity(robot, [0.0] * 3, [0.0] * 3, physicsClientId=cid)
        if self._support is not None:
            self.hold_base()
        self._tau = [0.0] * NUM_JOINTS
        return self.base_pose()

    def shift_base_xy(self, xy: FloatArray) -> Pose:
        """Move the robot (at rest, as placed) so that its root link is at ``xy`` on the ground; re-attach the crane."""
        pose = self.base_pose()
        self._set_base(Pose(np.array([xy[0], xy[1], pose.position[2]]), pose.orientation))
        pb.resetBaseVelocity(self.robot, [0.0] * 3, [0.0] * 3, physicsClientId=self._client)
        if self._support is not None:
            self.hold_base()
        return self.base_pose()

    def _set_base(self, pose: Pose) -> None:
        com = pb.multiplyTransforms(
            pose.position.tolist(), pose.orientation.tolist(), *self._base_inertial, physicsClientId=self._client
        )
        pb.resetBasePositionAndOrientation(self.robot, com[0], com[1], physicsClientId=self._client)

    def _standing_base_pose(self) -> Pose:
        """With the base at the origin: the base pose that levels the mean sole and puts the lowest corner on z = 0."""
        ups = [quaternion_matrix(self._link_frame(link)[1])[:, 2] for link in self.sole_links.values()]
        up = np.mean(ups, axis=0)
        level = levelling_quaternion(up / np.linalg.norm(up))
        rotation = quaternion_matrix(level)
        corners = [self._link_frame(link)[0] for links in self.contact_links.values() for link in links]
        lowest = min(float((rotation @ np.asarray(c))[2]) for c in corners)
        return Pose(np.array([0.0, 0.0, -lowest]), level)

    def _link_frame(self, link: int) -> tuple[Any, Any]:
        state = pb.getLinkState(self.robot, link, computeForwardKinematics=True, physicsClientId=self._client)
        return state[4], state[5]

    def joint_state(self) -> tuple[FloatArray, FloatArray]:
        """Joint positions [rad] and velocities [rad/s], JOINT_NAMES order."""
        states = pb.getJointStates(self.robot, self.joint_indices, physicsClientId=self._client)
        q = np.fromiter((s[0] for s in states), np.float64, NUM_JOINTS)
        v = np.fromiter((s[1] for s in states), np.float64, NUM_JOINTS)
        return q, v

    def base_pose(self) -> Pose:
        """The true pose of the root link frame (BASE_FRAME) in the world (not PyBullet's base COM frame)."""
        return self._root_and_com()[0]

    def _root_and_com(self) -> tuple[Pose, FloatArray]:
        """The root link frame's world pose and the base COM's world position (PyBullet's base frame)."""
        com_pos, com_orn = pb.getBasePositionAndOrientation(self.robot, physicsClientId=self._client)
        pos, orn = pb.multiplyTransforms(com_pos, com_orn, *self._base_inertial_inv, physicsClientId=self._client)
        return Pose(np.asarray(pos), np.asarray(orn)), np.asarray(com_pos)

    def base_velocity(self) -> tuple[FloatArray, FloatArray]:
        """Linear velocity of the base COM and angular velocity [world axes]."""
        linear, angular = pb.getBaseVelocity(self.robot, physicsClientId=self._client)
        return np.asarray(linear), np.asarray(angular)

    def foot_wrenches(self) -> dict[str, FootWrench]:
        """The ground's wrench on each foot (sum over its corner contacts: normal force plus both friction forces),
        about the sole frame origin, from the last step."""
        cid = self._client
        points = pb.getContactPoints(bodyA=self.robot, bodyB=self.ground, physicsClientId=cid)
        sums = {side: [np.zeros(3), np.zeros(3), 0] for side in FOOT_FRAMES}
        soles = {side: self._link_frame(link) for side, link in self.sole_links.items()}
        for point in points:
            side = self._foot_of_link.get(point[3])
            if side is None:
                continue
            force = (
                point[9] * np.asarray(point[7]) + point[10] * np.asarray(point[11]) + point[12] * np.asarray(point[13])
            )
            arm = np.asarray(point[5]) - np.asarray(soles[side][0])
            total = sums[side]
            total[0] += force
            total[1] += np.cross(arm, force)
            total[2] += 1
        return {
            side: FootWrench(force, moment, quaternion_matrix(soles[side][1]), int(count))
            for side, (force, moment, count) in sums.items()
        }

    def sole_pose(self, side: str) -> Pose:
        """Pose of the sole frame of ``side`` ("left"/"right") in the world."""
        pos, orn = self._link_frame(self.sole_links[side])
        return Pose(np.asarray(pos), np.asarray(orn))

    def mass_matrix(self, q: FloatArray) -> FloatArray:
        """Joint-space mass matrix (32 x 32, JOINT_NAMES order, armature on the joints included) at ``q`` with the
        base free: the Schur complement of the base block of the floating-base matrix (the intended model's when
        the world has armature, else PyBullet's)."""
        if self.armature is not None:
            full = self.armature.mass_matrix(q)
            return _free_base(full)[np.ix_(self.armature.joint_v - 6, self.armature.joint_v - 6)]
        rank = np.argsort(np.argsort(self.joint_indices))  # each joint's place in PyBullet's dof order
        ordered = np.empty(NUM_JOINTS)
        ordered[rank] = q
        full = np.asarray(pb.calculateMassMatrix(self.robot, ordered.tolist(), physicsClientId=self._client))
        return _free_base(full)[np.ix_(rank, rank)]

    @property
    def time(self) -> float:
        """Simulated time since construction [s]."""
        return self.steps * self.time_step

    @property
    def weight(self) -> float:
        """m g of the whole robot [N] (payloads included)."""
        return self.total_mass * GRAVITY

    # --- driving -------------------------------------------------------------------------------------------------

    def set_torques(self, tau: FloatArray) -> None:
        """Joint torques [Nm] (JOINT_NAMES order) applied from the next step on."""
        self._tau = np.asarray(tau, dtype=np.float64).tolist()

    def step(self, tau: FloatArray | None = None, state: tuple[FloatArray, FloatArray] | None = None) -> None:
        """Advance one time step with ``tau`` (or the last torques) minus the viscous term, at the joint ``state``
        (positions, velocities: the caller's if it has them, else read here); with armature, plus the forces
        that move the links as rigid links with armature on the joints (`ArmatureCorrection`)."""
        cid = self._client
        if tau is not None:
            self._tau = np.asarray(tau, dtype=np.float64).tolist()
        torques = self._tau
        if self.dynamics.viscous.any() or self.armature is not None:
            q, v = self.joint_state() if state is None else state
            torques = np.asarray(torques) - self.dynamics.viscous * v
            if self.armature is not None:
                torques = torques + self._apply_armature(torques, q, v)
            torques = torques.tolist()
        robot, joints = self.robot, self.joint_indices
        pb.setJointMotorControlArray(robot, joints, pb.TORQUE_CONTROL, forces=torques, physicsClientId=cid)
        pb.stepSimulation(physicsClientId=cid)
        self.steps += 1

    def _apply_armature(self, tau: FloatArray, q: FloatArray, v: FloatArray) -> FloatArray:
        """Apply the armature correction's base wrench for the next step; return its joint torques."""
        cid, robot, armature = self._client, self.robot, self.armature
        assert armature is not None
        root, com = self._root_and_com()
        position = root.position.tolist()
        rotation = quaternion_matrix(root.orientation)
        linear, angular = self.base_velocity()
        root_linear = linear + _cross(angular, root.position - com)
        q_full = armature.configuration(root.position, root.orientation, q)
        v_full = armature.velocity(rotation, root_linear, angular, v)
        touching = {point[3] for point in pb.getContactPoints(bodyA=robot, bodyB=self.ground, physicsClientId=cid)}
        contacts = [link in touching for link in self._corner_links]
        acceleration = armature.predict(q_full, v_full, tau, contacts, held=self._support is not None)
        joint_torque, base_force, base_torque = armature.split(armature.correction(q_full, v_full, acceleration))
        pb.applyExternalForce(
            robot, -1, (rotation @ base_force).tolist(), position, pb.WORLD_FRAME, physicsClientId=cid
        )
        pb.applyExternalTorque(robot, -1, (rotation @ base_torque).tolist(), pb.WORLD_FRAME, physicsClientId=cid)
        return joint_torque

    def step_position_motors(
        self, q: FloatArray, v: FloatArray, position_gain: float, velocity_gain: float, max_torque: FloatArray
    ) -> None:
        """Advance one time step with PyBullet's own joint position motors (an implicit PD inside its constraint
        solver, stable at any gain) tracking ``q``, ``v``, each torque limited to ``max_torque`` [Nm]."""
        cid = self._client
        n = NUM_JOINTS
        pb.setJointMotorControlArray(
            self.robot,
            self.joint_indices,
            pb.POSITION_CONTROL,
            targetPositions=np.asarray(q, dtype=np.float64).tolist(),
            targetVelocities=np.asarray(v, dtype=np.float64).tolist(),
            positionGains=[position_gain] * n,
            velocityGains=[velocity_gain] * n,
            forces=np.asarray(max_torque, dtype=np.float64).tolist(),
            physicsClientId=cid,
        )
        pb.stepSimulation(physicsClientId=cid)
        self.steps += 1

    # --- the crane -----------------------------------------------------------------------------------------------

    @property
    def supported(self) -> bool:
        """Whether the crane holds the base."""
        return self._support is not None

    def hold_base(self) -> None:
        """Hold the base fixed where it is now (a crane; re-holds at the current pose if already holding)."""
        cid = self._client
        if self._support is not None:
            pb.removeConstraint(self._support, physicsClientId=cid)
        com_pos, com_orn = pb.getBasePositionAndOrientation(self.robot, physicsClientId=cid)
        self._support = pb.createConstraint(
            self.robot,
            -1,
            -1,
            -1,
            pb.JOINT_FIXED,
            [0.0, 0.0, 0.0],
            [0.0, 0.0, 0.0],
            com_pos,
            childFrameOrientation=com_orn,
            physicsClientId=cid,
        )
        pb.changeConstraint(self._support, maxForce=SUPPORT_MAX_FORCE, physicsClientId=cid)

    def release_support(self) -> bool:
        """Let go of the base; False if it was not held."""
        if self._support is None:
            return False
        pb.removeConstraint(self._support, physicsClientId=self._client)
        self._support = None
        return True

    # --- lifetime ------------------------------------------------------------------------------------------------

    def close(self) -> None:
        """Disconnect the PyBullet client (idempotent)."""
        if self._client >= 0:
            pb.disconnect(physicsClientId=self._client)
            self._client = -1

    def __enter__(self) -> PhysicsWorld:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


# ----------------------------------------------------------------------------------------------------------------
# The boards on the physics


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
    "BASE_FRAME",
    "CONTACT_RADIUS",
    "TIME_STEP",
    "CouplingCounts",
    "FootWrench",
    "GroundTruth",
    "JointDynamics",
    "PhysicsActuatorBank",
    "PhysicsWorld",
    "Pose",
    "actuator_jacobian",
    "build_physics",
    "contact_links",
    "joint_dynamics",
    "physics_urdf",
]
