"""The whole-robot map: round trips, batch = per sample, power, trajectories, limit report, clamping."""

from __future__ import annotations

import numpy as np
import pytest

from rh5_hyrodyn_mapper.mapping import ActuatorSample, RobotMapper, robot_mapper
from rh5_hyrodyn_mapper.model import joint_limits
from rh5_msgs_py.names import ACTUATOR_INDEX, JOINT_INDEX, NUM_JOINTS, SUBMECHANISMS


@pytest.fixture(scope="module")
def mapper() -> RobotMapper:
    return robot_mapper()


def feasible_poses(mapper: RobotMapper, n: int, seed: int = 0) -> np.ndarray:
    """Random joint poses inside the joint ROM whose actuator lengths are inside the strokes."""
    limits = joint_limits()
    rng = np.random.default_rng(seed)
    lo, hi = limits.position_lower, limits.position_upper
    mid, half = 0.5 * (lo + hi), 0.5 * (hi - lo)
    poses = []
    while sum(len(p) for p in poses) < n:
        q = mid + rng.uniform(-0.6, 0.6, (4 * n, NUM_JOINTS)) * half
        stroke = mapper.limit_report(mapper.to_actuators(q)).stroke
        poses.append(q[(stroke <= 1.0).all(axis=1)])
    return np.concatenate(poses)[:n]


def test_rotary_joints_pass_through_unchanged(mapper: RobotMapper) -> None:
    q = feasible_poses(mapper, 5)
    tau = np.random.default_rng(1).normal(size=q.shape)
    out = mapper.to_actuators(q, q, tau=tau)
    for sub in SUBMECHANISMS:
        if sub.kind == "serial":
            i, j = JOINT_INDEX[sub.joints[0]], ACTUATOR_INDEX[sub.actuators[0]]
            np.testing.assert_array_equal(out.position[:, j], q[:, i])
            np.testing.assert_array_equal(out.effort[:, j], tau[:, i])


def test_round_trip_positions_velocities_torques(mapper: RobotMapper) -> None:
    rng = np.random.default_rng(2)
    q = feasible_poses(mapper, 500)
    v, tau = rng.normal(size=q.shape), rng.normal(scale=50.0, size=q.shape)
    actuators = mapper.to_actuators(q, v, tau=tau)
    back = mapper.to_joints(actuators.position, actuators.velocity, actuators.effort)
    np.testing.assert_allclose(back.position, q, rtol=0, atol=1e-9)
    np.testing.assert_allclose(back.velocity, v, rtol=0, atol=1e-9)
    np.testing.assert_allclose(back.effort, tau, rtol=1e-9, atol=1e-9)


def test_power_is_conserved(mapper: RobotMapper) -> None:
    rng = np.random.default_rng(3)
    q = feasible_poses(mapper, 200)
    v, tau = rng.normal(size=q.shape), rng.normal(scale=50.0, size=q.shape)
    actuators = mapper.to_actuators(q, v, tau=tau)
    joint_power = np.einsum("ni,ni->n", tau, v)
    actuator_power = np.einsum("ni,ni->n", actuators.effort, actuators.velocity)
    scale = np.linalg.norm(actuators.effort, axis=1) * np.linalg.norm(actuators.velocity, axis=1)
    assert np.max(np.abs(actuator_power - joint_power) / scale) < 1e-9


def test_batch_equals_sample_by_sample(mapper: RobotMapper) -> None:
    rng = np.random.default_rng(4)
    q = feasible_poses(mapper, 20)
    v, a, tau = (rng.normal(size=q.shape) for _ in range(3))
    batch = mapper.to_actuators(q, v, a, tau)
    for k in range(len(q)):
        single = mapper.to_actuators(q[k], v[k], a[k], tau[k])
        for got, want in zip(single, batch, strict=True):
            np.testing.assert_allclose(got, want[k], rtol=1e-12, atol=1e-15)
        joints = mapper.to_joints(single.position, single.velocity, single.effort, q_guess=q[k] + 1e-3)
        np.testing.assert_allclose(joints.position, q[k], rtol=0, atol=1e-9)


def test_trajectory_rates_match_finite_differences(mapper: RobotMapper) -> None:
    """A smooth 1 kHz joint trajectory: l-dot and l-ddot agree with differences of l(t) (mechanisms.md 9.1 #18)."""
    dt = 1e-3
    t = np.arange(0.0, 0.5, dt)[:, None]
    q0 = feasible_poses(mapper, 1, seed=5)[0]
    amplitude, omega = 0.05, np.linspace(2.0, 6.0, NUM_JOINTS)
    q = q0 + amplitude * np.sin(omega * t)
    v = amplitude * omega * np.cos(omega * t)
    a = -amplitude * omega**2 * np.sin(omega * t)
    out = mapper.to_actuators(q, v, a)
    ld_fd = (out.position[2:] - out.position[:-2]) / (2 * dt)
    ldd_fd = (out.velocity[2:] - out.velocity[:-2]) / (2 * dt)
    assert np.max(np.abs(ld_fd - out.velocity[1:-1])) < 1e-4 * max(1.0, np.abs(out.velocity).max())
    assert np.max(np.abs(ldd_fd - out.acceleration[1:-1])) < 1e-3 * max(1.0, np.abs(out.acceleration).max())


def test_limit_report_flags_each_injected_violation_only(mapper: RobotMapper) -> None:
    """mechanisms.md 9.1 #19: one stroke, one speed and one force violation, each found where injected."""
    q = feasible_poses(mapper, 6, seed=6)
    ok = mapper.to_actuators(q, np.zeros_like(q), tau=np.zeros_like(q))
    assert mapper.limit_report(ok).ok
    l, ld, f = ok.position.copy(), ok.velocity.copy(), ok.effort.copy()
    knee, ankle, hip = ACTUATOR_INDEX["LLKnee_Act1"], ACTUATOR_INDEX["LRAnkle_Act2"], ACTUATOR_INDEX["LRHip3_Act1"]
    l[1, knee] = mapper.limits.length_max[knee] + 1e-3
    ld[3, ankle] = -1.01 * mapper.limits.velocity_max[ankle]
    f[5, hip] = 1.2 * mapper.limits.force_max[hip]
    report = mapper.limit_report(ActuatorSample(l, ld, None, f))
    found = [(v.sample, v.actuator, v.kind) for v in report.violations]
    assert found == [(1, "LLKnee_Act1", "stroke"), (3, "LRAnkle_Act2", "velocity"), (5, "LRHip3_Act1", "force")]
    assert report.velocity[3, ankle] == pytest.approx(1.01)
    assert report.peak()["LRHip3_Act1"]["force"] == pytest.approx(1.2)


def test_paper_stroke_limits_are_the_actuator_limits(mapper: RobotMapper) -> None:
    """Paper table "ROM of linear actuators": knee 273-391 mm, 5845 N, 140 mm/s."""
    knee = ACTUATOR_INDEX["LRKnee_Act1"]
    assert (mapper.limits.length_min[knee], mapper.limits.length_max[knee]) == pytest.approx((0.273, 0.391))
    assert mapper.limits.force_max[knee] == pytest.approx(5845.0)
    assert mapper.limits.velocity_max[knee] == pytest.approx(0.140)


def test_clamp_keeps_setpoints_inside_and_reports_which(mapper: RobotMapper) -> None:
    q = feasible_poses(mapper, 1, seed=7)[0]
    sample = mapper.to_actuators(q, np.zeros(NUM_JOINTS), tau=np.zeros(NUM_JOINTS))
    l, f = sample.position.copy(), sample.effort.copy()
    ankle = ACTUATOR_INDEX["LLAnkle_Act1"]
    l[ankle], f[ankle] = 1.0, -1e5
    clamped_sample, clamped = mapper.clamp(ActuatorSample(l, sample.velocity, None, f))
    assert clamped.nonzero()[0].tolist() == [ankle]
    assert clamped_sample.position[ankle] == mapper.limits.length_max[ankle]
    assert clamped_sample.effort[ankle] == -mapper.limits.force_max[ankle]


def test_bad_shapes_and_missing_velocities_are_refused(mapper: RobotMapper) -> None:
    with pytest.raises(ValueError, match="expected 32 values"):
        mapper.to_actuators(np.zeros(31))
    with pytest.raises(ValueError, match="accelerations need velocities"):
        mapper.to_actuators(np.zeros(32), a=np.zeros(32))
