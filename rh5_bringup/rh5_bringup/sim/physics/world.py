"""The physics world of the simulated RH5: a PyBullet floating-base robot on flat ground, free of ROS.

`PhysicsWorld` is a PyBullet DIRECT world (gravity, ground plane, RH5 from ``generate_urdf()`` with a free
base, torque control, self-collision off, a 0.5 ms step). Foot contact: four spheres of 5 mm radius, one on
each corner contact frame of the 200 x 80 mm sole (``L?Foot_Contact_*``), replace the sole box of the URDF:
a sphere touches the plane in exactly one point, so every corner yields one contact, steadily (a box on a
plane gives a manifold whose points wander). Friction: the sole's ``friction_coefficient`` times the
ground's 1.0 (PyBullet multiplies the two). Readings: joints in JOINT_NAMES order, the TRUE pose of the
root link frame (PyBullet's base pose is the base's centre-of-mass frame; converted here), and each foot's
contact wrench. A crane (`hold_base`/`release_support`) holds the base fixed while the boards are off.
Hand payloads are point masses at AL_TCP/AR_TCP, as the planner models them.

The reflected motor inertia M (rotor J N^2, up to 300 kg at a ball screw) dominates the light links: a
velocity loop tuned for M (kp = M w) on a wrist whose own inertia is 40 times smaller is unstable at any
sample rate above ~1/(2 M / kp). PyBullet has no joint armature, so it is added to the inertia of each
joint's child link about the joint axis: A_j = sum_i M_i J_ij^2 at the starting pose (the diagonal of
J^T M J; the symmetric 2-DOF units make it diagonal there), which keeps the stiff loops stable inside Bullet's
implicit step. Bullet also needs a physical tensor, so the least inertia normal to the axis that satisfies the
triangle inequality is added too (urdf.py). On a link that inertia would also resist every absolute
rotation of the link (a real rotor spins N times faster with 1/N^2 of the inertia); `ArmatureCorrection`
(sim/armature.py) applies, every step, the generalized force that takes that part out again, so the robot moves
as rigid links with A on the joint coordinates (measured: one step matches that model to 5e-6; without it the
robot's centroidal pitch inertia is 2.2 times its own and the planned walk played with joint PD lagged 45 mm
instead of 3). The boards tuned for the motor alone (kp = M w) make the light rotary joints ring (standing in HOLD:
torso yaw 0.073 rad/s RMS, peaks 0.16); `loaded_params` (coupling.py; ``tune_to_load``, the node's default) tunes
each board to the inertia it drives, as at commissioning: the ringing drops to <= 0.011 rad/s RMS (peaks 0.036) and
the standing base drift over 3 s from 2.8 to 2.0 mm (the leg boards keep their tuning: their motor inertia exceeds
their load). The actuators' viscous friction acts on the physics as -J^T b J q_dot in the torque; their
Coulomb friction does not (PyBullet velocity motors as implicit stiction cost three times the step).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from tempfile import TemporaryDirectory
from typing import Any, NamedTuple

import numpy as np
import pinocchio as pin
import pybullet as pb

from rh5_bringup.sim.armature import ArmatureCorrection
from rh5_bringup.sim.physics.urdf import contact_links, physics_urdf
from rh5_msgs_py.array_types import FloatArray
from rh5_msgs_py.names import FOOT_FRAMES, JOINT_NAMES, NUM_JOINTS

TIME_STEP = 5e-4
"""PyBullet step [s]: two per 1 ms board cycle, each after a run of the board cascade (see coupling.py)."""

GRAVITY = 9.81
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


def quaternion_matrix(quat: Any) -> FloatArray:
    """3x3 rotation of a unit quaternion (x, y, z, w), PyBullet's order."""
    return np.asarray(pb.getMatrixFromQuaternion(quat), dtype=np.float64).reshape(3, 3)


def levelling_quaternion(up: FloatArray) -> FloatArray:
    """The smallest rotation taking the unit vector ``up`` to the world z axis (no yaw added), as (x, y, z, w)."""
    rotation = pin.Quaternion.FromTwoVectors(np.asarray(up, dtype=np.float64), np.array([0.0, 0.0, 1.0]))
    return np.asarray(rotation.coeffs())


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


__all__ = [
    "GRAVITY",
    "SUPPORT_MAX_FORCE",
    "TIME_STEP",
    "FootWrench",
    "GroundTruth",
    "JointDynamics",
    "PhysicsWorld",
    "Pose",
    "levelling_quaternion",
    "quaternion_matrix",
]
