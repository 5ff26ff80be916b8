"""Round trips and error paths of the numpy <-> message conversions."""

from __future__ import annotations

import array

import numpy as np
import pytest
from builtin_interfaces.msg import Duration, Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import WrenchStamped
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint, MultiDOFJointTrajectory

from rh5_msgs_py.conversions import (
    JointNameIndex,
    JointStateCodec,
    Level,
    Status,
    base_trajectory_from_msg,
    base_trajectory_to_msg,
    diagnostics_from_msg,
    diagnostics_to_msg,
    duration_to_ns,
    duration_to_s,
    joint_state_from_msg,
    joint_state_to_msg,
    joint_trajectory_from_cdr,
    joint_trajectory_from_msg,
    joint_trajectory_to_msg,
    status_from_msg,
    status_to_msg,
    time_to_ns,
    time_to_s,
    to_duration_msg,
    to_time_msg,
    wrench_from_msg,
    wrench_to_msg,
)
from rh5_msgs_py.names import ACTUATOR_NAMES, JOINT_NAMES

N_J = len(JOINT_NAMES)
FINITE = st.floats(allow_nan=False, allow_infinity=False, width=64)
VECTOR = arrays(np.float64, N_J, elements=FINITE)
STAMP_NS = st.integers(min_value=-(2**31) * 10**9, max_value=(2**31 - 1) * 10**9 + 999_999_999)
FAST = settings(max_examples=60, deadline=None)


def roundtrip(msg: object) -> object:
    """Serialize and deserialize as a subscriber would see the message."""
    return deserialize_message(serialize_message(msg), type(msg))


def knot_times(draw: st.DrawFn, n_points: int) -> np.ndarray:
    """Strictly increasing knot times with steps of at least 1 us (well above the 1 ns resolution)."""
    steps = draw(arrays(np.float64, n_points, elements=st.floats(1e-6, 10.0)))
    start = draw(st.floats(-100.0, 100.0))
    return start + np.cumsum(steps)


# --------------------------------------------------------------------------------------------------
# time


@FAST
@given(STAMP_NS)
def test_time_roundtrip_is_exact(ns: int) -> None:
    """Integer nanoseconds survive Time exactly, with nanosec in [0, 1e9) also for negative times."""
    msg = to_time_msg(ns)
    assert 0 <= msg.nanosec < 10**9
    assert time_to_ns(msg) == ns
    assert time_to_ns(roundtrip(msg)) == ns
    assert time_to_s(msg) == pytest.approx(ns * 1e-9, abs=1e-6)


def test_negative_time_follows_the_ros_convention() -> None:
    """-1.7 s is {sec: -2, nanosec: 3e8} (builtin_interfaces/Time.msg)."""
    msg = to_time_msg(-1_700_000_000)
    assert (msg.sec, msg.nanosec) == (-2, 300_000_000)


@FAST
@given(st.floats(-1e6, 1e6))
def test_duration_from_seconds(seconds: float) -> None:
    """Seconds round to the nearest nanosecond."""
    msg = to_duration_msg(seconds)
    assert duration_to_ns(msg) == round(seconds * 1e9)
    assert duration_to_s(msg) == pytest.approx(seconds, abs=1e-9)


def test_duration_from_ns_and_argument_errors() -> None:
    """``ns=`` is exact; giving both or neither, a float ns, or an out-of-range value fails clearly."""
    assert duration_to_ns(to_duration_msg(ns=1_500_000_001)) == 1_500_000_001
    assert isinstance(to_duration_msg(ns=5), Duration)
    with pytest.raises(TypeError, match="exactly one"):
        to_duration_msg(1.0, ns=1)
    with pytest.raises(TypeError, match="exactly one"):
        to_duration_msg()
    with pytest.raises(TypeError):
        to_duration_msg(ns=1.5)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="int32"):
        to_duration_msg(3e9)
    with pytest.raises(ValueError, match="finite"):
        to_duration_msg(float("nan"))
    with pytest.raises(ValueError, match="int32"):
        to_time_msg(2**31 * 10**9)


def test_to_time_msg_fills_a_given_message() -> None:
    """The ``msg`` argument is filled in place (no allocation on the loop path)."""
    stamp = Time()
    assert to_time_msg(3_000_000_007, stamp) is stamp
    assert (stamp.sec, stamp.nanosec) == (3, 7)


# --------------------------------------------------------------------------------------------------
# JointState


@FAST
@given(VECTOR, VECTOR, VECTOR, STAMP_NS)
def test_joint_state_roundtrip(pos: np.ndarray, vel: np.ndarray, eff: np.ndarray, stamp_ns: int) -> None:
    """Arrays -> JointState -> wire -> arrays is bit exact, for the functions and the codec."""
    msg = joint_state_to_msg(JOINT_NAMES, pos, vel, eff, stamp_ns=stamp_ns)
    assert list(msg.name) == list(JOINT_NAMES)
    assert time_to_ns(msg.header.stamp) == stamp_ns
    for received in (msg, roundtrip(msg)):
        out = joint_state_from_msg(received, JOINT_NAMES)
        np.testing.assert_array_equal(out.position, pos)
        np.testing.assert_array_equal(out.velocity, vel)
        np.testing.assert_array_equal(out.effort, eff)

    codec = JointStateCodec(JOINT_NAMES)
    wire = roundtrip(codec.encode(pos, vel, eff, stamp_ns=stamp_ns))
    assert time_to_ns(wire.header.stamp) == stamp_ns
    decoded = codec.decode(wire)
    np.testing.assert_array_equal(decoded.position, pos)
    np.testing.assert_array_equal(decoded.velocity, vel)
    np.testing.assert_array_equal(decoded.effort, eff)


@FAST
@given(st.permutations(JOINT_NAMES), VECTOR, st.booleans())
def test_joint_state_is_reordered_by_name(order: list[str], pos: np.ndarray, with_effort: bool) -> None:
    """A message in any joint order decodes into the requested order (all three fields, or a subset)."""
    by_name = dict(zip(JOINT_NAMES, pos.tolist(), strict=True))
    values = np.array([by_name[n] for n in order])
    msg = roundtrip(joint_state_to_msg(order, values, -values, values / 2 if with_effort else None, stamp_ns=1))
    for decoded in (joint_state_from_msg(msg, JOINT_NAMES), JointStateCodec(JOINT_NAMES).decode(msg)):
        np.testing.assert_array_equal(decoded.position, pos)
        np.testing.assert_array_equal(decoded.velocity, -pos)
        if with_effort:
            np.testing.assert_array_equal(decoded.effort, pos / 2)
        else:
            assert decoded.effort is None


def test_codec_encode_reuses_one_message_and_toggles_fields() -> None:
    """encode returns the same message; absent fields are empty, present ones come back."""
    codec = JointStateCodec(JOINT_NAMES, frame_id="base")
    x = np.arange(N_J, dtype=np.float64)
    first = codec.encode(x, x + 1, None, stamp_ns=10)
    assert first.header.frame_id == "base"
    assert len(first.effort) == 0
    second = codec.encode(x * 3, None, x - 1, stamp_ns=20)
    assert second is first
    assert len(second.velocity) == 0
    wire = roundtrip(second)
    decoded = codec.decode(wire)
    np.testing.assert_array_equal(decoded.position, x * 3)
    assert decoded.velocity is None
    np.testing.assert_array_equal(decoded.effort, x - 1)
    third = roundtrip(codec.encode(x, x, x, stamp_ns=30))
    assert [len(third.position), len(third.velocity), len(third.effort)] == [N_J] * 3
    np.testing.assert_array_equal(codec.decode(third).velocity, x)


def test_decoded_arrays_are_independent_copies() -> None:
    """Decoded arrays do not alias the message, so the loop may keep them after the message is reused."""
    codec = JointStateCodec(JOINT_NAMES)
    x = np.ones(N_J)
    msg = codec.encode(x, x, x)
    decoded = codec.decode(msg)
    codec.encode(x * 5, x * 5, x * 5)
    np.testing.assert_array_equal(decoded.position, x)
    decoded.position[0] = 99.0
    assert msg.position[0] == 5.0


def test_nan_passes_through() -> None:
    """Conversions do not judge values: NaN and inf survive (the stabiliser decides what they mean)."""
    x = np.zeros(N_J)
    x[3], x[4] = np.nan, np.inf
    out = joint_state_from_msg(roundtrip(joint_state_to_msg(JOINT_NAMES, x)), JOINT_NAMES)
    np.testing.assert_array_equal(out.position, x)
    assert out.velocity is None


def test_unknown_and_missing_joints_are_named() -> None:
    """A message with other joints (here: actuator names) names what is missing and what is unknown."""
    msg = joint_state_to_msg(ACTUATOR_NAMES, np.zeros(N_J))
    with pytest.raises(ValueError, match="missing joints") as info:
        joint_state_from_msg(msg, JOINT_NAMES)
    text = str(info.value)
    assert "BodyPitch" in text
    assert "unknown joints" in text
    assert "Body_Act1" in text
    assert "+" in text  # long lists are shortened


def test_one_wrong_name_is_reported_exactly() -> None:
    """Renaming one joint reports exactly that pair."""
    names = list(JOINT_NAMES)
    names[5] = "HeadYawTypo"
    msg = joint_state_to_msg(names, np.zeros(N_J))
    with pytest.raises(ValueError, match=r"missing joints \[HeadYaw\]; unknown joints \[HeadYawTypo\]"):
        JointStateCodec(JOINT_NAMES).decode(msg)


def test_extra_joints_only_with_allow_extra() -> None:
    """A subset can be read from a bigger message when asked for."""
    pos = np.arange(N_J, dtype=np.float64)
    msg = roundtrip(joint_state_to_msg(JOINT_NAMES, pos))
    legs = JOINT_NAMES[-12:]
    with pytest.raises(ValueError, match="unknown joints"):
        joint_state_from_msg(msg, legs)
    out = joint_state_from_msg(msg, legs, allow_extra=True)
    np.testing.assert_array_equal(out.position, pos[-12:])


def test_malformed_joint_states_are_rejected() -> None:
    """Duplicate names, field lengths that differ from the names and wrong input shapes raise."""
    names = list(JOINT_NAMES)
    names[1] = names[0]
    with pytest.raises(ValueError, match="duplicate joint names"):
        joint_state_from_msg(joint_state_to_msg(names, np.zeros(N_J)), JOINT_NAMES)
    with pytest.raises(ValueError, match="duplicate joint names"):
        JointStateCodec(names)
    msg = JointState(name=list(JOINT_NAMES), position=[0.0] * N_J, velocity=[0.0] * 3)
    with pytest.raises(ValueError, match="velocity has 3 values for 32 names"):
        joint_state_from_msg(msg, JOINT_NAMES)
    with pytest.raises(ValueError, match=r"shape \(32,\)"):
        joint_state_to_msg(JOINT_NAMES, np.zeros(31))
    with pytest.raises(ValueError, match=r"shape \(32,\)"):
        JointStateCodec(JOINT_NAMES).encode(np.zeros(1))  # would broadcast if unchecked


def test_joint_state_name_index_cache_and_fast_path() -> None:
    """Same order -> None (no gather); another order -> the cached index array, built once."""
    index = JointNameIndex(JOINT_NAMES)
    assert index.index(list(JOINT_NAMES)) is None
    reverse = list(reversed(JOINT_NAMES))
    first = index.index(reverse)
    assert first is not None
    np.testing.assert_array_equal(first, np.arange(N_J)[::-1])
    assert index.index(tuple(reverse)) is first


def test_functional_api_works_with_field_checks_on() -> None:
    """Filling a message created with check_fields=True (as under ROS_PYTHON_CHECK_FIELDS=1) passes its checks."""
    msg = JointState(check_fields=True)
    out = joint_state_to_msg(JOINT_NAMES, np.ones(N_J), np.ones(N_J), None, stamp_ns=5, msg=msg)
    assert out is msg
    assert isinstance(out.position, array.array)
    assert len(out.effort) == 0
    np.testing.assert_array_equal(joint_state_from_msg(roundtrip(out), JOINT_NAMES).velocity, np.ones(N_J))


def test_serialize_roundtrip_of_converted_joint_state_is_equal() -> None:
    """serialize_message/deserialize_message gives back an equal message."""
    x = np.linspace(-1.0, 1.0, N_J)
    msg = joint_state_to_msg(JOINT_NAMES, x, -x, 2 * x, stamp_ns=1_234_567_890_123)
    data = serialize_message(msg)
    back = deserialize_message(data, JointState)
    assert back == msg
    assert len(data) > 3 * 8 * N_J


# --------------------------------------------------------------------------------------------------
# JointTrajectory


@st.composite
def trajectories(draw: st.DrawFn) -> tuple[np.ndarray, list[np.ndarray | None]]:
    """Knot times and four optional (N, 32) fields."""
    n_points = draw(st.integers(1, 12))
    times = knot_times(draw, n_points)
    matrix = arrays(np.float64, (n_points, N_J), elements=FINITE)
    return times, [draw(matrix), draw(st.none() | matrix), draw(st.none() | matrix), draw(st.none() | matrix)]


@FAST
@given(trajectories(), STAMP_NS)
def test_joint_trajectory_roundtrip(traj: tuple[np.ndarray, list[np.ndarray | None]], stamp_ns: int) -> None:
    """Arrays -> JointTrajectory -> wire -> arrays: fields exact, times to the nanosecond, None stays None."""
    times, (pos, vel, acc, eff) = traj
    msg = joint_trajectory_to_msg(
        JOINT_NAMES, times, pos, velocities=vel, accelerations=acc, efforts=eff, stamp_ns=stamp_ns
    )
    out = joint_trajectory_from_msg(roundtrip(msg), JOINT_NAMES)
    assert out.joint_names == JOINT_NAMES
    assert out.stamp_ns == stamp_ns
    np.testing.assert_allclose(out.times, times, rtol=0, atol=1e-9)
    got_fields = (out.positions, out.velocities, out.accelerations, out.efforts)
    for got, want in zip(got_fields, (pos, vel, acc, eff), strict=True):
        if want is None:
            assert got is None
        else:
            np.testing.assert_array_equal(got, want)


def test_joint_trajectory_reorders_columns() -> None:
    """Columns follow the requested names; names=None keeps the message's order."""
    times = np.array([0.0, 0.5, 1.0])
    pos = np.arange(3 * N_J, dtype=np.float64).reshape(3, N_J)
    reverse = tuple(reversed(JOINT_NAMES))
    msg = roundtrip(joint_trajectory_to_msg(reverse, times, pos[:, ::-1], velocities=pos[:, ::-1] * 2))
    out = joint_trajectory_from_msg(msg, JOINT_NAMES)
    np.testing.assert_array_equal(out.positions, pos)
    np.testing.assert_array_equal(out.velocities, pos * 2)
    raw = joint_trajectory_from_msg(msg)
    assert raw.joint_names == reverse
    np.testing.assert_array_equal(raw.positions, pos[:, ::-1])
    with pytest.raises(ValueError, match=r"missing joints \[Extra\]"):
        joint_trajectory_from_msg(msg, (*JOINT_NAMES, "Extra"))


def test_joint_trajectory_time_encoding() -> None:
    """time_from_start is split into sec/nanosec exactly as builtin_interfaces wants."""
    msg = joint_trajectory_to_msg(["a"], [0.0, 1.25, 2.000000001], [[0.0], [1.0], [2.0]])
    stamps = [(p.time_from_start.sec, p.time_from_start.nanosec) for p in msg.points]
    assert stamps == [(0, 0), (1, 250_000_000), (2, 1)]
    assert all(len(p.velocities) == 0 for p in msg.points)


def test_joint_trajectory_rejects_bad_input() -> None:
    """Non-increasing times, wrong shapes and ragged points raise with the offending point named."""
    with pytest.raises(ValueError, match=r"increase strictly.*point 2"):
        joint_trajectory_to_msg(["a"], [0.0, 1.0, 1.0], np.zeros((3, 1)))
    with pytest.raises(ValueError, match=r"shape \(2, 1\)"):
        joint_trajectory_to_msg(["a"], [0.0, 1.0], np.zeros((2, 2)))
    with pytest.raises(ValueError, match="finite"):
        joint_trajectory_to_msg(["a"], [0.0, np.nan], np.zeros((2, 1)))
    msg = JointTrajectory(joint_names=["a", "b"])
    msg.points = [
        JointTrajectoryPoint(positions=[0.0, 1.0], time_from_start=Duration(sec=0)),
        JointTrajectoryPoint(positions=[0.0], time_from_start=Duration(sec=1)),
    ]
    with pytest.raises(ValueError, match="point 1 has 1 positions for 2 joints"):
        joint_trajectory_from_msg(msg)
    msg.points[1].positions = [0.0, 1.0]
    msg.points[1].time_from_start = Duration(sec=0)
    with pytest.raises(ValueError, match="increase strictly"):
        joint_trajectory_from_msg(msg)


def test_empty_joint_trajectory() -> None:
    """An empty trajectory (JTC's "stop") decodes to zero knots and no fields."""
    out = joint_trajectory_from_msg(JointTrajectory(joint_names=list(JOINT_NAMES)), JOINT_NAMES)
    assert out.times.shape == (0,)
    assert out.positions is None


# --------------------------------------------------------------------------------------------------
# MultiDOFJointTrajectory


@st.composite
def base_trajectories(draw: st.DrawFn) -> tuple[np.ndarray, ...]:
    """Times, positions, unit quaternions and optional twists/accelerations."""
    n_points = draw(st.integers(1, 10))
    times = knot_times(draw, n_points)
    pos = draw(arrays(np.float64, (n_points, 3), elements=st.floats(-1e3, 1e3)))
    quat = draw(arrays(np.float64, (n_points, 4), elements=st.floats(0.1, 1.0)))
    quat /= np.linalg.norm(quat, axis=1, keepdims=True)
    twists = draw(st.none() | arrays(np.float64, (n_points, 6), elements=FINITE))
    acc = draw(st.none() | arrays(np.float64, (n_points, 6), elements=FINITE))
    return times, pos, quat, twists, acc


@FAST
@given(base_trajectories())
def test_base_trajectory_roundtrip(traj: tuple[np.ndarray, ...]) -> None:
    """Arrays -> MultiDOFJointTrajectory -> wire -> arrays, with joint name and frame."""
    times, pos, quat, twists, acc = traj
    msg = base_trajectory_to_msg(times, pos, quat, twists=twists, accelerations=acc, stamp_ns=42)
    assert list(msg.joint_names) == ["floating_base"]
    assert msg.header.frame_id == "world"
    out = base_trajectory_from_msg(roundtrip(msg))
    np.testing.assert_allclose(out.times, times, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(out.positions, pos)
    np.testing.assert_array_equal(out.quaternions_xyzw, quat)
    for got, want in ((out.twists, twists), (out.accelerations, acc)):
        if want is None:
            assert got is None
        else:
            np.testing.assert_array_equal(got, want)
    assert (out.joint_name, out.frame_id, out.stamp_ns) == ("floating_base", "world", 42)


def test_base_trajectory_component_order() -> None:
    """Quaternion columns are x, y, z, w; twist columns linear xyz then angular xyz."""
    msg = base_trajectory_to_msg([0.0], [[1, 2, 3]], [[0.1, 0.2, 0.3, 0.9]], twists=[[1, 2, 3, 4, 5, 6]])
    point = msg.points[0]
    rot = point.transforms[0].rotation
    assert (rot.x, rot.y, rot.z, rot.w) == (0.1, 0.2, 0.3, 0.9)
    tw = point.velocities[0]
    assert (tw.linear.x, tw.linear.z, tw.angular.x, tw.angular.z) == (1, 3, 4, 6)
    assert len(point.accelerations) == 0


def test_base_trajectory_joint_selection() -> None:
    """With several joints the caller must pick one; an unknown name is named in the error."""
    msg = base_trajectory_to_msg([0.0, 1.0], np.zeros((2, 3)), [[0, 0, 0, 1]] * 2)
    msg.joint_names = ["floating_base", "other"]
    for p in msg.points:
        p.transforms = [p.transforms[0], p.transforms[0]]
    with pytest.raises(ValueError, match="has 2 joints"):
        base_trajectory_from_msg(msg)
    with pytest.raises(ValueError, match="no joint 'pelvis'"):
        base_trajectory_from_msg(msg, "pelvis")
    assert base_trajectory_from_msg(msg, "other").joint_name == "other"
    empty = MultiDOFJointTrajectory(joint_names=["floating_base"])
    assert base_trajectory_from_msg(empty).positions.shape == (0, 3)


# --------------------------------------------------------------------------------------------------
# WrenchStamped


@FAST
@given(arrays(np.float64, 6, elements=FINITE), STAMP_NS)
def test_wrench_roundtrip(wrench: np.ndarray, stamp_ns: int) -> None:
    """(6,) force xyz, torque xyz <-> WrenchStamped, stamp and frame kept."""
    msg = wrench_to_msg(wrench, "LLFoot_Sole", stamp_ns)
    assert (msg.wrench.force.y, msg.wrench.torque.x) == (wrench[1], wrench[3])
    back = roundtrip(msg)
    np.testing.assert_array_equal(wrench_from_msg(back), wrench)
    assert back.header.frame_id == "LLFoot_Sole"
    assert time_to_ns(back.header.stamp) == stamp_ns


def test_wrench_errors_and_reuse() -> None:
    """Wrong length raises; ``msg=`` fills in place."""
    with pytest.raises(ValueError, match=r"shape \(6,\)"):
        wrench_to_msg(np.zeros(3), "f", 0)
    msg = WrenchStamped()
    assert wrench_to_msg(np.ones(6), "f", 0, msg=msg) is msg


# --------------------------------------------------------------------------------------------------
# diagnostics

TEXT = st.text(st.characters(exclude_categories=("Cs",), exclude_characters="\x00"), max_size=20)


@FAST
@given(
    st.lists(
        st.builds(
            Status,
            name=TEXT,
            level=st.sampled_from(Level),
            message=TEXT,
            values=st.dictionaries(TEXT, TEXT, max_size=4),
            hardware_id=TEXT,
        ),
        max_size=4,
    ),
    STAMP_NS,
)
def test_diagnostics_roundtrip(statuses: list[Status], stamp_ns: int) -> None:
    """Statuses -> DiagnosticArray -> wire -> statuses (string values compare equal)."""
    msg = diagnostics_to_msg(statuses, stamp_ns)
    assert isinstance(msg, DiagnosticArray)
    back = diagnostics_from_msg(roundtrip(msg))
    assert back == statuses
    assert time_to_ns(msg.header.stamp) == stamp_ns


def test_levels_have_the_wire_values() -> None:
    """Level values equal DiagnosticStatus' byte constants; non-string values become strings."""
    assert [int(level) for level in Level] == [0, 1, 2, 3]
    for level, constant in zip(
        Level,
        (DiagnosticStatus.OK, DiagnosticStatus.WARN, DiagnosticStatus.ERROR, DiagnosticStatus.STALE),
        strict=True,
    ):
        assert status_to_msg(Status("x", level, "")).level == constant
    msg = status_to_msg(Status("loop", Level.WARN, "late", {"misses": 3, "jitter_us": 12.5, "ok": False}))
    assert [(kv.key, kv.value) for kv in msg.values] == [("misses", "3"), ("jitter_us", "12.5"), ("ok", "False")]
    back = status_from_msg(roundtrip(msg))
    assert back.level is Level.WARN
    assert dict(back.values) == {"misses": "3", "jitter_us": "12.5", "ok": "False"}


def test_invalid_levels_raise() -> None:
    """A level outside OK..STALE fails in both directions, naming the status."""
    with pytest.raises(ValueError, match="7"):
        status_to_msg(Status("x", 7, ""))  # type: ignore[arg-type]
    msg = DiagnosticStatus(name="driver", level=b"\x07")
    with pytest.raises(ValueError, match="'driver': level 7"):
        status_from_msg(msg)


@pytest.mark.parametrize(
    "present", [(True, True, True), (True, False, True), (True, True, False), (True, False, False)]
)
def test_serialized_joint_state_is_the_message_rclpy_would_send(present: tuple[bool, bool, bool]) -> None:
    """encode_serialized writes stamp and arrays into rclpy's own serialisation of a template: deserialised,
    it is the message encode builds (padding bytes aside, which CDR leaves unspecified)."""
    from rclpy.serialization import deserialize_message

    codec = JointStateCodec(JOINT_NAMES, frame_id="base")
    rng = np.random.default_rng(7)
    for stamp in (0, 1_700_000_000_123_456_789, 5):
        fields = [rng.normal(size=len(JOINT_NAMES)) if on else None for on in present]
        received = deserialize_message(codec.encode_serialized(*fields, stamp_ns=stamp), JointState)
        expected = codec.encode(*fields, stamp_ns=stamp)
        assert received.header == expected.header
        assert list(received.name) == list(expected.name)
        for field in ("position", "velocity", "effort"):
            assert list(getattr(received, field)) == list(getattr(expected, field)), field
    with pytest.raises(ValueError, match="shape"):
        codec.encode_serialized(np.zeros(3))


@pytest.mark.parametrize("points", [0, 1, 2, 3, 6, 301])
@pytest.mark.parametrize(("velocities", "efforts"), [(True, True), (False, True), (True, False), (False, False)])
def test_trajectory_from_cdr_reads_what_rclpy_reads(points: int, velocities: bool, efforts: bool) -> None:
    """The strided read of a serialised JointTrajectory (even and odd points may be padded differently) gives
    what rclpy's deserialisation gives, also reordered to other names; ragged points fall back to rclpy."""
    from rclpy.serialization import deserialize_message, serialize_message
    from trajectory_msgs.msg import JointTrajectory

    rng = np.random.default_rng(points)
    q = rng.normal(size=(points, len(JOINT_NAMES)))
    msg = joint_trajectory_to_msg(
        JOINT_NAMES, np.arange(points) * 0.01 + 5e-10, q, velocities=2 * q if velocities else None,
        efforts=3 * q if efforts else None, stamp_ns=1_700_000_000_123_456_789, frame_id="world",
    )  # fmt: skip
    data = serialize_message(msg)
    for names in (None, tuple(reversed(JOINT_NAMES))):
        fast = joint_trajectory_from_cdr(data, names)
        slow = joint_trajectory_from_msg(deserialize_message(data, JointTrajectory), names)
        for field in slow._fields:
            a, b = getattr(fast, field), getattr(slow, field)
            assert np.array_equal(a, b) if isinstance(b, np.ndarray) else a == b, field
    if points > 1:
        msg.points[1].positions = msg.points[1].positions[:-1]  # ragged: rclpy's path, and its error
        with pytest.raises(ValueError, match="JointTrajectory"):
            joint_trajectory_from_cdr(serialize_message(msg))
