"""StabilizerCore against a simple simulated plant with synthetic time: ramp-in, playback, hold, safety rules."""

from __future__ import annotations

import numpy as np
import pytest

from rh5_hyrodyn_mapper.model import joint_limits
from rh5_joint_stabilizer.controller import (
    Command,
    Measurement,
    SafetyLimits,
    StabilizerCore,
    State,
    load_gains,
)
from rh5_joint_stabilizer.reference import PlannedTrajectory, RampIn, TrajectoryRejectedError, validate_trajectory
from rh5_msgs_py.names import JOINT_INDEX, JOINT_NAMES, NUM_JOINTS

DT_NS = 1_000_000
PLANT_LAG_S = 0.02  # the boards' position cascade, seen from the joint level, as a first-order lag
SINE_AMPLITUDE, SINE_HZ = 0.1, 0.5


class LagPlant:
    """Each joint follows its commanded position with a first-order lag (an idealised board cascade)."""

    def __init__(self, q0: np.ndarray) -> None:
        self.q = q0.copy()
        self.v = np.zeros_like(q0)

    def step(self, command: Command | None) -> None:
        if command is None:
            self.v[:] = 0.0
            return
        new = self.q + (DT_NS / 1e9) / PLANT_LAG_S * (command.position - self.q)
        self.v = (new - self.q) / (DT_NS / 1e9)
        self.q = new


def sine_trajectory(q0: np.ndarray, seconds: float = 4.0) -> PlannedTrajectory:
    t = np.arange(0.0, seconds, 0.01)
    omega = 2 * np.pi * SINE_HZ
    q = q0 + SINE_AMPLITUDE * np.sin(omega * t)[:, None]
    v = SINE_AMPLITUDE * omega * np.cos(omega * t)[:, None] * np.ones(NUM_JOINTS)
    return validate_trajectory(
        JOINT_NAMES, t, q, v, np.full_like(q, 1.0), velocity_limits=np.asarray(joint_limits().velocity_max)
    )


def make_core(events: list[str] | None = None, max_tracking_error: float = 0.2) -> StabilizerCore:
    limits = joint_limits()
    return StabilizerCore(
        load_gains(),
        np.asarray(limits.torque_max),
        ramp_max_velocity=0.3,
        ramp_max_acceleration=1.0,
        safety=SafetyLimits(state_timeout_ns=5_000_000, max_tracking_error=max_tracking_error),
        on_event=(events.append if events is not None else lambda _t: None),
    )


def run(core: StabilizerCore, plant: LagPlant, ticks: int, start_ns: int, stale_after: int | None = None):
    """Advance ``ticks`` milliseconds; measurements stop arriving after ``stale_after`` ticks."""
    commands, now = [], start_ns
    measurement = Measurement(plant.q.copy(), plant.v.copy(), now)
    for k in range(ticks):
        now += DT_NS
        if stale_after is None or k < stale_after:
            measurement = Measurement(plant.q.copy(), plant.v.copy(), now)
        command = core.update(now, DT_NS, measurement)
        plant.step(command)
        commands.append(command)
    return commands, now


@pytest.fixture
def bent_pose() -> np.ndarray:
    q = np.zeros(NUM_JOINTS)
    q[JOINT_INDEX["LLKnee"]] = q[JOINT_INDEX["LRKnee"]] = 0.5
    return q


def test_ramp_in_respects_its_velocity_and_acceleration_limits() -> None:
    start, goal = np.zeros(NUM_JOINTS), np.linspace(-0.4, 0.6, NUM_JOINTS)
    ramp = RampIn(start, goal, max_velocity=0.3, max_acceleration=1.0)
    t = np.arange(0.0, ramp.duration + 0.1, 0.001)
    samples = [ramp.sample(x) for x in t]
    v = np.array([s.velocity for s in samples])
    q = np.array([s.position for s in samples])
    assert np.abs(v).max() <= 0.3 + 1e-12
    assert np.abs(np.diff(v, axis=0) / 0.001).max() <= 1.0 + 1e-9
    np.testing.assert_allclose(q[0], start, atol=1e-12)
    np.testing.assert_allclose(q[-1], goal, atol=1e-12)
    np.testing.assert_allclose(np.diff(q, axis=0) / 0.001, (v[1:] + v[:-1]) / 2, atol=1e-6)
    assert ramp.duration == pytest.approx(0.6 / 0.3 + 0.3 / 1.0)


def test_start_ramp_play_and_hold_track_the_plant(bent_pose: np.ndarray) -> None:
    """Playback error stays below 1e-2 rad: a lag T tracking a sine of amplitude A, rate w lags by ~A w T = 6.3e-3."""
    events: list[str] = []
    core, plant = make_core(events), LagPlant(np.zeros(NUM_JOINTS))
    trajectory = sine_trajectory(bent_pose)
    assert core.load(trajectory) == (True, "trajectory loaded")
    assert core.request_start(Measurement(plant.q, plant.v, 0))[0]
    ramp_ticks = int(RampIn(np.zeros(NUM_JOINTS), bent_pose, 0.3, 1.0).duration * 1000) + 2
    commands, now = run(core, plant, ramp_ticks, 0)
    assert core.state == State.PLAYING
    commands, now = run(core, plant, 500, now)  # settle the lag after the ramp
    errors = []
    for _ in range(3000):
        commands, now = run(core, plant, 1, now)
        errors.append(np.abs(core.tracking_error).max())
    assert max(errors) < 1e-2
    commands, now = run(core, plant, int(trajectory.duration * 1000), now)
    assert core.state == State.HOLDING
    held = commands[-1].position
    commands, now = run(core, plant, 300, now)
    assert all(np.array_equal(c.position, held) for c in commands)
    np.testing.assert_allclose(plant.q, held, atol=1e-5)
    assert [e.split(":")[0] for e in events if "->" in e] == [
        "idle -> ramp_in",
        "ramp_in -> playing",
        "playing -> holding",
    ]


def test_effort_is_feed_forward_plus_pd_saturated_to_the_torque_limits() -> None:
    core, plant = make_core(), LagPlant(np.zeros(NUM_JOINTS))
    core.load(sine_trajectory(np.zeros(NUM_JOINTS)))
    core.request_start(Measurement(plant.q, plant.v, 0))
    command = core.update(DT_NS, DT_NS, Measurement(plant.q, plant.v, DT_NS))
    np.testing.assert_allclose(command.effort, 1.0 + core.gains.kd * command.velocity, atol=1e-9)
    far = Measurement(plant.q - 0.15, plant.v, 2 * DT_NS)
    command = core.update(2 * DT_NS, DT_NS, far)
    assert np.all(np.abs(command.effort) <= core.torque_limits + 1e-12)
    assert np.any(np.abs(command.effort) == core.torque_limits)


def test_stale_joint_states_hold_the_last_command(bent_pose: np.ndarray) -> None:
    core, plant = make_core(), LagPlant(bent_pose)
    core.load(sine_trajectory(bent_pose))
    core.request_start(Measurement(plant.q, plant.v, 0))
    commands, _ = run(core, plant, 100, 0, stale_after=50)
    assert core.state == State.HOLDING
    assert "joint_states stale" in core.last_reason
    first_stale = 50 + 5  # timeout 5 ms
    last_good = commands[first_stale - 1]
    for command in commands[first_stale + 1 :]:
        np.testing.assert_array_equal(command.position, last_good.position)
        np.testing.assert_array_equal(command.velocity, 0.0)


def test_tracking_error_above_the_bound_holds(bent_pose: np.ndarray) -> None:
    core, plant = make_core(max_tracking_error=0.05), LagPlant(bent_pose)
    core.load(sine_trajectory(bent_pose))
    core.request_start(Measurement(plant.q, plant.v, 0))
    run(core, plant, 20, 0)
    stuck = Measurement(plant.q + np.where(np.arange(NUM_JOINTS) == 7, 0.2, 0.0), plant.v, 21 * DT_NS)
    core.update(21 * DT_NS, DT_NS, stuck)
    assert core.state == State.HOLDING
    assert f"tracking error of {JOINT_NAMES[7]}" in core.last_reason


def test_estop_stops_and_blocks_start(bent_pose: np.ndarray) -> None:
    core, plant = make_core(), LagPlant(bent_pose)
    core.load(sine_trajectory(bent_pose))
    core.request_start(Measurement(plant.q, plant.v, 0))
    run(core, plant, 10, 0)
    core.set_estop(True)
    commands, _ = run(core, plant, 5, 10 * DT_NS)
    assert core.state == State.STOPPED
    assert commands == [None] * 5
    ok, reason = core.request_start(Measurement(plant.q, plant.v, 0))
    assert not ok
    assert "emergency stop" in reason


def test_start_refusals_say_why(bent_pose: np.ndarray) -> None:
    core = make_core()
    rest = Measurement(bent_pose, np.zeros(NUM_JOINTS), 0)
    assert core.request_start(rest) == (
        False,
        "refused: no trajectory (publish planned_trajectory or set trajectory_file)",
    )
    core.load(sine_trajectory(bent_pose))
    assert core.request_start(None) == (False, "refused: no joint_states received")
    moving = Measurement(bent_pose, np.full(NUM_JOINTS, 0.2), 0)
    ok, reason = core.request_start(moving)
    assert not ok
    assert "not at rest" in reason
    assert core.request_hold()[1].startswith("refused: nothing to hold")
    assert core.request_stop() == (False, "refused: already idle")


def test_hold_and_stop_requests(bent_pose: np.ndarray) -> None:
    core, plant = make_core(), LagPlant(bent_pose)
    core.load(sine_trajectory(bent_pose))
    core.request_start(Measurement(plant.q, plant.v, 0))
    _, now = run(core, plant, 50, 0)
    assert core.request_hold() == (True, "holding")
    commands, now = run(core, plant, 20, now)
    assert core.state == State.HOLDING
    assert np.array_equal(commands[-1].position, commands[0].position)
    assert core.load(sine_trajectory(bent_pose))[0]  # a new trajectory may replace the held one
    assert core.request_stop() == (True, "stopping")
    commands, _ = run(core, plant, 3, now)
    assert core.state == State.STOPPED
    assert commands == [None] * 3


@pytest.mark.parametrize(
    ("change", "fragment"),
    [
        ("unknown", "unknown joints ['LLTail']"),
        ("nan", "NaN or inf in positions at point 3"),
        ("time", "not strictly increasing at point 4"),
        ("jump", "exceeds its velocity limit"),
        ("missing", "missing joints ['LRAnklePitch']"),
    ],
)
def test_bad_trajectories_are_rejected_with_the_reason(change: str, fragment: str) -> None:
    names = list(JOINT_NAMES)
    t = np.arange(0.0, 0.1, 0.01)
    q = np.zeros((len(t), NUM_JOINTS))
    if change == "unknown":
        names[3] = "LLTail"
    elif change == "nan":
        q[3, 5] = np.nan
    elif change == "time":
        t[4] = t[3]
    elif change == "jump":
        q[5:, JOINT_INDEX["LLKnee"]] = 0.5  # 0.5 rad in 10 ms = 50 rad/s
    else:
        names, q = names[:-1], q[:, :-1]
    with pytest.raises(TrajectoryRejectedError, match=fragment.replace("[", r"\[").replace("]", r"\]")):
        validate_trajectory(names, t, q, None, None, velocity_limits=np.asarray(joint_limits().velocity_max))


def test_hermite_sampling_hits_knots_and_reorders_names() -> None:
    names = list(reversed(JOINT_NAMES))
    t = np.array([0.0, 0.5, 1.0])
    q = np.outer([0.0, 0.2, 0.1], np.arange(NUM_JOINTS) / NUM_JOINTS)
    traj = validate_trajectory(names, t + 3.0, q, None, None, velocity_limits=np.full(NUM_JOINTS, 10.0))
    np.testing.assert_allclose(traj.sample(0.5).position, q[1][::-1])
    np.testing.assert_allclose(traj.sample(2.0).position, q[2][::-1])
    assert traj.duration == 1.0


def test_a_rejected_trajectory_drops_the_previous_one_so_start_cannot_play_it(bent_pose: np.ndarray) -> None:
    core = make_core()
    assert core.load(sine_trajectory(bent_pose))[0]
    core.reject("planned_trajectory: jump of LLKnee between points 3 and 4")
    ok, reason = core.request_start(Measurement(bent_pose, np.zeros(NUM_JOINTS), 0))
    assert not ok
    assert "no trajectory" in reason
    assert "jump of LLKnee" in reason
    assert core.load(sine_trajectory(bent_pose))[0]  # a good one clears the rejection
    assert core.rejection == ""


def test_play_replaces_a_playing_trajectory_and_ramps_from_the_reference(bent_pose: np.ndarray) -> None:
    """A FollowJointTrajectory goal preempts: the new trajectory starts from the current reference, no jump."""
    core, plant = make_core(), LagPlant(bent_pose)
    first = sine_trajectory(bent_pose)
    assert core.request_play(first, Measurement(plant.q.copy(), plant.v.copy(), 0))[0]
    commands, now = run(core, plant, 1500, 0)
    assert core.state == State.PLAYING
    assert core.trajectory is first
    reference = core.last_command.position.copy()
    second = sine_trajectory(bent_pose + 0.05)
    ok, message = core.request_play(second, Measurement(plant.q.copy(), plant.v.copy(), now))
    assert ok, message  # also while the robot moves: it follows the reference on
    assert core.start_pending
    commands, now = run(core, plant, 1, now)
    assert core.state == State.RAMP_IN
    assert core.trajectory is second
    assert np.max(np.abs(commands[0].position - reference)) < 0.01
    commands, now = run(core, plant, 3000, now)
    assert core.state == State.PLAYING


def test_play_after_stop_starts_again(bent_pose: np.ndarray) -> None:
    core, plant = make_core(), LagPlant(bent_pose)
    assert core.request_play(sine_trajectory(bent_pose), Measurement(plant.q.copy(), plant.v.copy(), 0))[0]
    _, now = run(core, plant, 100, 0)
    assert core.request_stop()[0]
    _, now = run(core, plant, 10, now)
    assert core.state == State.STOPPED
    assert core.request_play(sine_trajectory(bent_pose), Measurement(plant.q.copy(), plant.v.copy(), now))[0]
    _, now = run(core, plant, 10, now)
    assert core.state in (State.RAMP_IN, State.PLAYING)
    core.set_estop(True)
    ok, message = core.request_play(sine_trajectory(bent_pose), Measurement(plant.q.copy(), plant.v.copy(), now))
    assert not ok
    assert "emergency stop" in message
