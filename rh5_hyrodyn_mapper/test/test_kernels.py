"""The C kernels (kinematics/unit_maps.c through _compiled.c) as the 1 kHz control cycle calls them, one whole-robot
sample at a time: round trips over the whole joint range, the wrap of a warm start a turn away, every refusal with its
unit's reason, and the argument checks of the C calls."""

from __future__ import annotations

import numpy as np
import pytest

from rh5_hyrodyn_mapper.kinematics import kernels
from rh5_hyrodyn_mapper.kinematics.base import ForwardKinematicsError, SingularityError
from rh5_hyrodyn_mapper.mapping import RobotMapper, robot_mapper
from rh5_hyrodyn_mapper.model import joint_limits
from rh5_msgs_py.names import ACTUATOR_INDEX, NUM_JOINTS

SAMPLES = 400


@pytest.fixture(scope="module")
def mapper() -> RobotMapper:
    return robot_mapper()


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


def test_round_trip_of_the_cycle_calls(mapper: RobotMapper) -> None:
    """Readings of random poses, warm-started one sample away as the cycle's forward kinematics is, come back."""
    for q, v, tau in _joint_samples(2):
        actuators = mapper.to_actuators(q, v, tau=tau)
        assert actuators.acceleration is None
        back = mapper.to_joints(actuators.position, actuators.velocity, actuators.effort, q_guess=q + 0.01)
        np.testing.assert_allclose(back.position, q, rtol=0, atol=1e-9)
        np.testing.assert_allclose(back.velocity, v, rtol=1e-8, atol=1e-8)
        np.testing.assert_allclose(back.effort, tau, rtol=1e-9, atol=1e-9)


def test_a_warm_start_a_turn_away_comes_back_wrapped(mapper: RobotMapper) -> None:
    q, v, tau = _joint_samples(3)[0]
    actuators = mapper.to_actuators(q, v, tau=tau)
    back = mapper.to_joints(actuators.position, actuators.velocity, actuators.effort, q_guess=q + 2 * np.pi)
    np.testing.assert_allclose(back.position, q, rtol=0, atol=1e-9)


def test_a_singular_force_map_is_refused_with_the_reason(mapper: RobotMapper) -> None:
    strict = RobotMapper(mapper.submechanisms, max_condition=1.0)  # every parallel unit is "singular" now
    q, v, tau = _joint_samples(4)[0]
    with pytest.raises(SingularityError, match="force map refused"):
        strict.to_actuators(q, v, tau=tau)
    assert strict.to_actuators(q, v).effort is None  # no forces asked: no refusal


def test_lengths_that_do_not_assemble_are_refused_with_the_reason(mapper: RobotMapper) -> None:
    q, v, tau = _joint_samples(5)[0]
    actuators = mapper.to_actuators(q, v, tau=tau)
    for actuator, unit in (("LLKnee_Act1", "LLKnee"), ("LLAnkle_Act1", "LLAnkle"), ("Body_Act1", "Body")):
        broken = actuators.position.copy()
        broken[ACTUATOR_INDEX[actuator]] += 1.0  # a metre longer: no pose has it
        with pytest.raises(ForwardKinematicsError, match=unit):
            mapper.to_joints(broken, actuators.velocity, actuators.effort, q_guess=q)


def test_the_kernel_calls_check_their_arguments(mapper: RobotMapper) -> None:
    table, q = mapper._table, np.zeros(NUM_JOINTS)
    l = np.empty(NUM_JOINTS)
    with pytest.raises(ValueError, match="table row"):  # units beyond the vectors' width
        kernels.ik(table, 1, q[:10], None, None, None, 1e6, l[:10], None, None, None, None)
    with pytest.raises(ValueError, match="needs its output"):
        kernels.ik(table, 1, q, q, None, None, 1e6, l, None, None, None, None)
    with pytest.raises(ValueError, match="float64 expected"):
        kernels.fk(table, 1, l, None, None, q[:3], q, None, None, None)
    with pytest.raises(ValueError, match="one unit"):
        kernels.pose(table, 1, q, None, None, None, None)
