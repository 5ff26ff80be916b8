"""The C kernels of the control cycle's maps (kinematics/_compiled.c) against the Python float paths they mirror:
the same numbers over the whole joint range, and every refusal left to Python, which gives the reason."""

from __future__ import annotations

import numpy as np
import pytest

from rh5_hyrodyn_mapper.kinematics.base import ForwardKinematicsError, SingularityError
from rh5_hyrodyn_mapper.kinematics.compiled import AVAILABLE
from rh5_hyrodyn_mapper.mapping import RobotMapper
from rh5_hyrodyn_mapper.model import joint_limits
from rh5_msgs_py.names import ACTUATOR_INDEX, NUM_JOINTS

pytestmark = pytest.mark.skipif(not AVAILABLE, reason="the C extension is not built (make venv builds it)")

SAMPLES = 400


@pytest.fixture(scope="module")
def mappers() -> tuple[RobotMapper, RobotMapper]:
    """The default mapper (C for the cycle's calls) and one with only the Python float path."""
    compiled, python = RobotMapper(), RobotMapper()
    assert compiled._compiled is not None
    python._compiled = None
    return compiled, python


def _joint_samples(seed: int) -> np.ndarray:
    """(SAMPLES, 3, 32): positions over 95 % of each joint's range, velocities and torques within their limits."""
    limits = joint_limits()
    rng = np.random.default_rng(seed)
    centre = 0.5 * (limits.position_upper + limits.position_lower)
    half = 0.475 * (limits.position_upper - limits.position_lower)
    q = centre + half * rng.uniform(-1, 1, (SAMPLES, NUM_JOINTS))
    v = limits.velocity_max * rng.uniform(-1, 1, (SAMPLES, NUM_JOINTS))
    tau = limits.torque_max * rng.uniform(-1, 1, (SAMPLES, NUM_JOINTS))
    return np.stack((q, v, tau), axis=1)


def test_the_inverse_map_is_the_python_one(mappers: tuple[RobotMapper, RobotMapper]) -> None:
    compiled, python = mappers
    for q, v, tau in _joint_samples(1):
        assert compiled._compiled.to_actuators(q, v, tau, compiled.max_condition) is not None  # C mapped it
        fast, reference = compiled.to_actuators(q, v, tau=tau), python.to_actuators(q, v, tau=tau)
        for got, want in ((fast.position, reference.position), (fast.velocity, reference.velocity)):
            np.testing.assert_allclose(got, want, rtol=1e-14, atol=1e-15)
        np.testing.assert_allclose(fast.effort, reference.effort, rtol=1e-12, atol=1e-12)
        assert fast.acceleration is None


def test_the_forward_map_is_the_python_one(mappers: tuple[RobotMapper, RobotMapper]) -> None:
    """Readings of random poses, warm-started one sample away, as the cycle's forward kinematics is."""
    compiled, python = mappers
    for q, v, tau in _joint_samples(2):
        actuators = python.to_actuators(q, v, tau=tau)
        guess = q + 0.01
        assert compiled._compiled.to_joints(actuators.position, actuators.velocity, actuators.effort, guess) is not None
        fast = compiled.to_joints(actuators.position, actuators.velocity, actuators.effort, q_guess=guess)
        reference = python.to_joints(actuators.position, actuators.velocity, actuators.effort, q_guess=guess)
        np.testing.assert_allclose(fast.position, reference.position, rtol=0, atol=1e-12)
        np.testing.assert_allclose(fast.position, q, rtol=0, atol=1e-9)  # and it is the pose that was mapped
        np.testing.assert_allclose(fast.velocity, reference.velocity, rtol=1e-10, atol=1e-10)
        np.testing.assert_allclose(fast.effort, reference.effort, rtol=1e-12, atol=1e-12)


def test_a_wrapped_angle_comes_back_as_python_wraps_it(mappers: tuple[RobotMapper, RobotMapper]) -> None:
    """A warm start a full turn away converges to the same pose, wrapped to [-pi, pi] as the Python path does."""
    compiled, python = mappers
    q, v, tau = _joint_samples(3)[0]
    actuators = python.to_actuators(q, v, tau=tau)
    guess = q + 2 * np.pi
    fast = compiled.to_joints(actuators.position, actuators.velocity, actuators.effort, q_guess=guess)
    reference = python.to_joints(actuators.position, actuators.velocity, actuators.effort, q_guess=guess)
    np.testing.assert_array_equal(fast.position, reference.position)


def test_a_singular_force_map_is_refused_with_the_python_reason(mappers: tuple[RobotMapper, RobotMapper]) -> None:
    compiled, _ = mappers
    strict = RobotMapper(compiled.submechanisms, max_condition=1.0)  # every parallel unit is "singular" now
    q, v, tau = _joint_samples(4)[0]
    with pytest.raises(SingularityError, match="force map refused"):
        strict.to_actuators(q, v, tau=tau)


def test_lengths_that_do_not_assemble_are_refused_with_the_python_reason(
    mappers: tuple[RobotMapper, RobotMapper],
) -> None:
    compiled, python = mappers
    q, v, tau = _joint_samples(5)[0]
    actuators = python.to_actuators(q, v, tau=tau)
    for actuator in ("LLKnee_Act1", "LLAnkle_Act1", "Body_Act1"):
        broken = actuators.position.copy()
        broken[ACTUATOR_INDEX[actuator]] += 1.0  # a metre longer: no pose has it
        with pytest.raises(ForwardKinematicsError):
            compiled.to_joints(broken, actuators.velocity, actuators.effort, q_guess=q)
