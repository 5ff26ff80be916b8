"""The physics moves as rigid links with the actuators' reflected inertia on the joints (sim/armature.py).

Each test steps PyBullet once and compares the joint and base accelerations it produced with the forward dynamics
of the intended model, (M + diag(A)) qdd = tau - h, computed independently here with Pinocchio; the same step
without the correction shows that the link-inertia model alone differs.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pybullet as pb
import pytest

from rh5_bringup.sim.actuators import ActuatorBank
from rh5_bringup.sim.armature import ArmatureCorrection
from rh5_bringup.sim.physics import PhysicsWorld, Pose, joint_dynamics, quaternion_matrix
from rh5_msgs_py.names import JOINT_NAMES, NUM_JOINTS


def _bent_knees() -> np.ndarray:
    """A pose with every joint off its position limits (straight knees rest on theirs)."""
    q = np.zeros(NUM_JOINTS)
    for side in "LR":
        for joint, angle in (("Hip3", -0.3), ("Knee", 0.6), ("AnklePitch", -0.3)):
            q[JOINT_NAMES.index(f"L{side}{joint}")] = angle
    return q


@pytest.fixture
def world() -> PhysicsWorld:
    """The robot with its actuators' armature, knees bent, lifted 1 m off the ground (no contacts)."""
    with PhysicsWorld(0.7, 5.0, joint_dynamics(ActuatorBank())) as world:
        world.reset(_bent_knees())
        pose = world.base_pose()
        world._set_base(Pose(pose.position + np.array([0.0, 0.0, 1.0]), pose.orientation))
        yield world


def _state(world: PhysicsWorld, armature: ArmatureCorrection) -> tuple[np.ndarray, np.ndarray]:
    """Pinocchio's q and v of the PyBullet robot now."""
    pose = world.base_pose()
    rotation = quaternion_matrix(pose.orientation)
    linear, angular = world.base_velocity()
    com = np.asarray(pb.getBasePositionAndOrientation(world.robot, physicsClientId=world._client)[0])
    joints_q, joints_v = world.joint_state()
    q = armature.configuration(pose.position, pose.orientation, joints_q)
    v = armature.velocity(rotation, linear + np.cross(angular, pose.position - com), angular, joints_v)
    return q, v


def _intended_acceleration(armature: ArmatureCorrection, q: np.ndarray, v: np.ndarray, tau: np.ndarray, held: bool):
    """(M + A) qdd = tau - h with the base free, or with the base held (its 6 rows removed), as Pinocchio defines
    joint armature."""
    model = armature.model
    data = model.createData()
    force = -pin.nonLinearEffects(model, data, q, v)
    force[armature.joint_v] += tau
    inertia = pin.crba(model, data, q)  # Pinocchio adds the model's armature A to the diagonal
    if not held:
        return np.linalg.solve(inertia, force)
    out = np.zeros(model.nv)
    out[6:] = np.linalg.solve(inertia[6:, 6:], force[6:])
    return out


def _step_acceleration(world: PhysicsWorld, armature: ArmatureCorrection, tau: np.ndarray) -> np.ndarray:
    """The acceleration PyBullet's step produced ((v+ - v) / dt, Pinocchio's v order)."""
    _, before = _state(world, armature)
    world.step(tau)
    _, after = _state(world, armature)
    return (after - before) / world.time_step


@pytest.mark.parametrize("held", [False, True], ids=["flying", "held"])
def test_a_step_accelerates_as_rigid_links_with_joint_armature(world: PhysicsWorld, held: bool) -> None:
    armature = world.armature
    assert armature is not None
    if held:
        world.hold_base()
    else:  # tumbling, so that the base's rotation couples into the joints
        pb.resetBaseVelocity(world.robot, [0.1, 0.0, 0.0], [0.4, -0.6, 0.3], physicsClientId=world._client)
    tau = np.random.default_rng(7).normal(0.0, 10.0, NUM_JOINTS)
    q, v = _state(world, armature)
    expected = _intended_acceleration(armature, q, v, tau, held)
    measured = _step_acceleration(world, armature, tau)
    scale = np.abs(expected).max()
    assert np.abs(measured - expected).max() < 1e-4 * scale

    # without the correction PyBullet moves the link-inertia model, which is measurably different
    world.armature = None
    q, v = _state(world, armature)
    uncorrected = _step_acceleration(world, armature, tau) - _intended_acceleration(armature, q, v, tau, held)
    assert np.abs(uncorrected).max() > 0.05 * scale


def test_standing_on_the_ground_the_prediction_holds_the_soles(world: PhysicsWorld) -> None:
    """With all eight corners touching, the predicted acceleration keeps both soles still (6D each)."""
    armature = world.armature
    assert armature is not None
    world.reset(_bent_knees())
    q, v = _state(world, armature)
    tau = np.random.default_rng(3).normal(0.0, 20.0, NUM_JOINTS)
    acceleration = armature.predict(q, v, tau, [True] * 8, held=False)
    data = armature.model.createData()
    pin.computeJointJacobians(armature.model, data, q)
    pin.updateFramePlacements(armature.model, data)
    for sole in armature.soles:
        jac = pin.getFrameJacobian(armature.model, data, sole, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
        assert np.abs(jac @ acceleration).max() < 1e-6
    assert np.abs(acceleration[6:]).max() > 1.0  # the torques did move the joints


def test_mass_matrix_is_the_intended_models_with_the_base_free(world: PhysicsWorld) -> None:
    """The boards' tuning and the PD gains use (M + A) with the base free, not the link-inertia model's."""
    free_base = world.mass_matrix(np.zeros(NUM_JOINTS))
    armature = world.armature
    assert armature is not None
    knee = JOINT_NAMES.index("LLKnee")
    reflected = armature.armature[armature.joint_v[knee]]
    assert reflected > 0.5
    # the knee's own inertia is the shank's plus its armature: more than the armature, less than the link model's
    assert reflected < free_base[knee, knee] < reflected + 1.0
    np.testing.assert_allclose(free_base, free_base.T, atol=1e-9)
