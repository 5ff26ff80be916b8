"""Experiment reports from synthetic bags with known errors: the metrics must find exactly those errors.

The bags are written like the suite's recorder writes them: rosbag2 folders with MCAP storage, messages
serialised by rclpy (CDR, independent of the report's own batch decoder), topics with a leading slash.
One synthetic experiment: ramp-in, a 3 s planned motion starting at a known time, a hold; measured =
reference + a known offset on one joint and one actuator; the simulated base drifts a known amount.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from rclpy.serialization import serialize_message
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

from rh5_bringup.analysis import NotABagError, ReportError, build_report, default_out_dir, load_recording, write_report
from rh5_bringup.analysis.__main__ import main as report_main
from rh5_bringup.analysis.cdr import decode_joint_states, decode_stamped_floats
from rh5_bringup.analysis.metrics import resample
from rh5_bringup.analysis.records import PlannedBase, PlannedJoints
from rh5_bringup.analysis.results import planned_base_for
from rh5_msgs_py import interfaces
from rh5_msgs_py.conversions import (
    Level,
    Status,
    base_trajectory_to_msg,
    diagnostics_to_msg,
    joint_state_to_msg,
    joint_trajectory_to_msg,
)
from rh5_msgs_py.interfaces import message_class
from rh5_msgs_py.names import ACTUATOR_INDEX, ACTUATOR_NAMES, JOINT_INDEX, JOINT_NAMES, NUM_ACTUATORS, NUM_JOINTS

TYPESTORE = get_typestore(Stores.ROS2_JAZZY)
WALL0 = 1_700_000_000_000_000_000  # bag start (ns): header stamps are on this wall clock
RATE = 1000
T0 = 0.7123  # s after the bag start: the stabilizer starts playing (between two 1 Hz diagnostics reports)
RAMP_START = 0.2
DURATION = 3.0  # the planned motion
HOLD = 0.5
JOINT_OFFSET = ("LLKnee", 0.01)  # rad, measured - reference
ACTUATOR_OFFSET = ("LLAnkle_Act1", 0.002)  # m
BASE_HEIGHT = 0.9
DRIFT_X = 0.004  # m/s: 12 mm after 3 s, outside the paper's +-10 mm
BASE_Z_OFFSET = 0.002


def plan_joints(tau: np.ndarray) -> np.ndarray:
    """The planned joint motion: sinusoids around a bent pose, (n, 32)."""
    phase = np.linspace(0.0, np.pi, NUM_JOINTS)
    return 0.2 + 0.1 * np.sin(2 * np.pi * 0.5 * np.clip(tau, 0.0, DURATION)[:, None] + phase[None, :])


def plan_actuators(tau: np.ndarray) -> np.ndarray:
    """Actuator references (m for the linear ones; the units do not matter to the report)."""
    phase = np.linspace(0.0, np.pi, NUM_ACTUATORS)
    return 0.3 + 0.01 * np.sin(2 * np.pi * 0.5 * np.clip(tau, 0.0, DURATION)[:, None] + phase[None, :])


def plan_base(tau: np.ndarray) -> np.ndarray:
    """The planned base: walks 0.1 m/s forward, sways 2 cm sideways, constant height."""
    tau = np.clip(tau, 0.0, DURATION)
    return np.stack([0.1 * tau, 0.02 * np.sin(np.pi * tau), np.full_like(tau, BASE_HEIGHT)], axis=1)


def stabilizer_reference(t: np.ndarray, plan: Callable[[np.ndarray], np.ndarray], start: np.ndarray) -> np.ndarray:
    """What the stabilizer commands at bag times t: linear ramp to the first sample, then the plan, then hold."""
    first = plan(np.zeros(1))[0]
    ramp = np.clip((t - RAMP_START) / (T0 - RAMP_START), 0.0, 1.0)[:, None]
    out = start + (first - start) * ramp
    playing = t >= T0
    out[playing] = plan(t[playing] - T0)
    return out


@dataclass
class BagSpec:
    """What to put into a synthetic bag."""

    base: bool = True
    diagnostics: bool = True
    fall_at: float | None = None  # tau (s) where the base starts dropping 0.6 m/s
    actuators: bool = True
    trim: bool = True  # False: store rclpy's serialize_message output with its unused trailing bytes


_WIRE_LENGTH: dict[tuple[str, int], int] = {}


def wire_bytes(raw: bytes, typename: str) -> bytes:
    """rclpy's serialize_message output cut to the encoding's length (+ padding to 4), as DDS delivers it.

    serialize_message returns the estimated size, with unused bytes at the end; a recorder's raw
    subscription gets only the encoding (checked against Fast DDS: 60 vs 68 bytes for a small JointState).
    The length is computed once per type and serialized size (the 1 kHz streams keep one layout).
    """
    key = (typename, len(raw))
    if key not in _WIRE_LENGTH:
        msgdef = TYPESTORE.get_msgdef(typename)
        _, end = msgdef.deserialize_cdr_le(memoryview(raw)[4:], 0, msgdef.cls, TYPESTORE)
        _WIRE_LENGTH[key] = 4 + end + (-end % 4)
    return raw[: _WIRE_LENGTH[key]]


class BagWriter:
    """rosbags Writer + rclpy serialisation, topics named as the recorder names them (absolute)."""

    def __init__(self, path: Path, *, trim: bool = True) -> None:
        self.writer = Writer(path, version=9, storage_plugin=StoragePlugin.MCAP)
        self.writer.open()
        self.connections: dict[str, Any] = {}
        self.trim = trim

    def write(self, topic: interfaces.Topic, t: float, msg: Any) -> None:
        name = "/" + topic.name.lstrip("/")
        if name not in self.connections:
            self.connections[name] = self.writer.add_connection(name, topic.type, typestore=TYPESTORE)
        raw = bytes(serialize_message(msg))
        raw = wire_bytes(raw, topic.type) if self.trim else raw
        self.writer.write(self.connections[name], WALL0 + round(t * 1e9) + 200_000, raw)

    def close(self) -> None:
        self.writer.close()


def bag_time(t: float, origin_ns: int) -> float:
    """A time of the synthetic experiment (s after WALL0) on the report's clock (s after the bag's first message)."""
    return t + (WALL0 - origin_ns) / 1e9


def _joint_stream(w: BagWriter, topic: interfaces.Topic, names: tuple[str, ...], t: np.ndarray, q: np.ndarray) -> None:
    for ti, qi in zip(t, q, strict=True):
        w.write(topic, ti, joint_state_to_msg(names, qi, np.zeros(len(names)), None, stamp_ns=WALL0 + round(ti * 1e9)))


def _diagnostics(w: BagWriter, end: float) -> None:
    for t in np.arange(0.05, end, 1.0):
        state = "idle" if t < RAMP_START else "ramp_in" if t < T0 else "playing" if t < T0 + DURATION else "holding"
        reason = "trajectory finished" if state == "holding" else ""
        values = {"state": state, "reason": reason, "loop.rate_hz": 999.8, "loop.jitter_p99_us": 30.0 + t}
        values.update({"loop.jitter_max_us": 80.0, "loop.deadline_misses": 2})
        # run-long histogram: 98 % within 10 us, 1.9 % in (50, 60] us, one period in (2, 3] ms
        values["loop.jitter_histogram"] = " ".join(map(str, [980, 0, 0, 0, 0, 19, *[0] * 10, 1, 0, 0]))
        level = Level.WARN if state == "holding" else Level.OK
        stab = Status("rh5/stabilizer", level, reason or state, values, "rh5")
        mapper = Status(
            "rh5/mapper", Level.WARN, "commands clamped or rejected since start", {"clamped.LLKnee_Act1": 3}
        )
        stamp = WALL0 + round(t * 1e9)
        w.write(interfaces.DIAGNOSTICS, t, diagnostics_to_msg([stab, mapper], stamp_ns=stamp))


def write_bag(path: Path, spec: BagSpec) -> Path:
    """A synthetic recording of one experiment (see the module docstring)."""
    end = T0 + DURATION + HOLD
    w = BagWriter(path, trim=spec.trim)
    knots = np.arange(0.0, DURATION + 1e-9, 0.01)
    w.write(interfaces.PLANNED_TRAJECTORY, 0.01, joint_trajectory_to_msg(JOINT_NAMES, knots, plan_joints(knots)))
    quat = np.tile([0.0, 0.0, 0.0, 1.0], (len(knots), 1))
    w.write(interfaces.PLANNED_BASE_TRAJECTORY, 0.01, base_trajectory_to_msg(knots, plan_base(knots), quat))
    w.write(interfaces.DRIVER_ESTOP, 0.0, message_class(interfaces.DRIVER_ESTOP.type)(data=False))
    if spec.diagnostics:
        _diagnostics(w, end)
    t_cmd = np.arange(RAMP_START, end, 1.0 / RATE)
    t_meas = np.arange(0.0, end, 1.0 / RATE) + 0.00025
    q_start = np.full(NUM_JOINTS, 0.05)
    q_ref = stabilizer_reference(t_cmd, plan_joints, q_start)
    q_meas = resample(t_cmd, q_ref, t_meas, max_gap=np.inf)[0]
    q_meas[t_meas < RAMP_START] = q_start
    q_meas[:, JOINT_INDEX[JOINT_OFFSET[0]]] += JOINT_OFFSET[1]
    _joint_stream(w, interfaces.JOINT_COMMANDS, JOINT_NAMES, t_cmd, q_ref)
    _joint_stream(w, interfaces.JOINT_STATES, JOINT_NAMES, t_meas, q_meas)
    if spec.actuators:
        l_start = np.full(NUM_ACTUATORS, 0.29)
        l_ref = stabilizer_reference(t_cmd, plan_actuators, l_start)
        l_meas = resample(t_cmd, l_ref, t_meas, max_gap=np.inf)[0]
        l_meas[:, ACTUATOR_INDEX[ACTUATOR_OFFSET[0]]] += ACTUATOR_OFFSET[1]
        _joint_stream(w, interfaces.ACTUATOR_COMMANDS, ACTUATOR_NAMES, t_cmd, l_ref)
        _joint_stream(w, interfaces.ACTUATOR_STATES, ACTUATOR_NAMES, t_meas, l_meas)
    if spec.base:
        pose_cls = message_class(interfaces.SIM_BASE_POSE.type)
        tau = t_meas - T0
        pos = plan_base(tau) + np.stack(
            [DRIFT_X * np.clip(tau, 0.0, DURATION), np.zeros_like(tau), np.full_like(tau, BASE_Z_OFFSET)], axis=1
        )
        if spec.fall_at is not None:
            pos[:, 2] -= 0.6 * np.clip(tau - spec.fall_at, 0.0, None)
        for ti, p in zip(t_meas, pos, strict=True):
            msg = pose_cls()
            msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(WALL0 + round(ti * 1e9), 1_000_000_000)
            msg.header.frame_id = "world"
            msg.pose.position.x, msg.pose.position.y, msg.pose.position.z = (float(v) for v in p)
            msg.pose.orientation.w = 1.0
            w.write(interfaces.SIM_BASE_POSE, ti, msg)
    w.close()
    return path


@pytest.fixture(scope="module")
def walk_bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The full experiment: diagnostics, actuators, simulated base drifting in x."""
    return write_bag(tmp_path_factory.mktemp("bags") / "walk", BagSpec())


# --- decoding ----------------------------------------------------------------------------------------------------


def test_batch_decoder_matches_rclpy_encoding_for_mixed_layouts() -> None:
    """Messages of different names, frame ids and empty arrays decode to exactly what was serialised."""
    js = [
        joint_state_to_msg(("a", "bb"), [1.0, 2.0], [3.0, 4.0], [5.0, 6.0], stamp_ns=1_500_000_001),
        joint_state_to_msg(("a", "bb"), [7.0, 8.0], [9.0, 10.0], [11.0, 12.0], stamp_ns=2_000_000_002),
        joint_state_to_msg(("ccc",), [13.0], None, None, stamp_ns=3, frame_id="frame"),
        joint_state_to_msg(("bb", "a"), [14.0, 15.0], [16.0, 17.0], [18.0, 19.0], stamp_ns=4),  # same length as #0
    ]
    blocks = decode_joint_states([bytes(serialize_message(m)) for m in js])
    by_row = {int(r): (b, i) for b in blocks for i, r in enumerate(b.rows)}
    assert sorted(by_row) == [0, 1, 2, 3]
    for row, msg in enumerate(js):
        block, i = by_row[row]
        assert block.names == tuple(msg.name)
        assert block.stamps_ns[i] == msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
        np.testing.assert_array_equal(block.position[i], msg.position)
        if len(msg.velocity):
            np.testing.assert_array_equal(block.velocity[i], msg.velocity)
        else:
            assert block.velocity is None
    pose_cls = message_class(interfaces.SIM_BASE_POSE.type)
    poses = []
    for k, frame in enumerate(("w", "world", "odom_long_frame")):
        p = pose_cls()
        p.header.frame_id = frame
        p.header.stamp.sec = k
        p.pose.position.x, p.pose.orientation.z, p.pose.orientation.w = 0.5 + k, 0.25, 0.75
        poses.append(bytes(serialize_message(p)))
    stamps, values = decode_stamped_floats(poses, 7)
    np.testing.assert_array_equal(stamps, [0, 1_000_000_000, 2_000_000_000])
    np.testing.assert_array_equal(values[:, 0], [0.5, 1.5, 2.5])
    np.testing.assert_array_equal(values[:, 5:], [[0.25, 0.75]] * 3)


def test_load_reads_every_stream_on_the_sender_clock(walk_bag: Path) -> None:
    """Arrays per topic, times from the header stamps (the receive times are 0.2 ms later)."""
    rec = load_recording(walk_bag)
    assert rec.joint_states is not None
    assert rec.joint_commands is not None
    assert rec.base_pose is not None
    assert rec.joint_states.names == JOINT_NAMES
    assert rec.joint_states.time_source == "header"
    assert rec.joint_states.position.shape == (len(rec.joint_states.t), NUM_JOINTS)
    assert rec.joint_commands.t[0] == pytest.approx(bag_time(RAMP_START, rec.origin_ns), abs=1e-9)
    assert rec.actuator_states is not None
    assert rec.actuator_states.names == ACTUATOR_NAMES
    assert len(rec.planned_joints) == 1
    assert rec.planned_joints[0].positions.shape == (301, NUM_JOINTS)
    assert rec.planned_base[0].positions[-1] == pytest.approx([0.3, 0.0, BASE_HEIGHT], abs=1e-12)
    assert {d.name for d in rec.diagnostics} == {"rh5/stabilizer", "rh5/mapper"}
    assert rec.estopped is not None
    assert not rec.estopped.value.any()


# --- metrics -----------------------------------------------------------------------------------------------------


def test_report_finds_exactly_the_known_errors(walk_bag: Path, tmp_path: Path) -> None:
    """Offsets, base drift, trajectory time zero and the mapper's clamping are found; nothing else is."""
    report = build_report(walk_bag, tmp_path / "out")
    a = report.analysis
    assert a.time_zero.t0 == pytest.approx(bag_time(T0, a.recording.origin_ns), abs=1.5e-3)
    assert "refined" in a.time_zero.method
    groups = {g.group: g for g in a.joint_groups}
    assert groups["left_leg"].worst == "LLKnee"
    assert groups["left_leg"].max_abs == pytest.approx(JOINT_OFFSET[1], abs=1e-6)
    assert groups["left_leg"].rms == pytest.approx(JOINT_OFFSET[1] / np.sqrt(6), abs=1e-6)
    for name, g in groups.items():
        if name != "left_leg":
            assert g.max_abs < 1e-6, name
    act = {g.group: g for g in a.actuator_groups}
    assert act["left_leg"].worst == ACTUATOR_OFFSET[0]
    assert act["left_leg"].rms == pytest.approx(ACTUATOR_OFFSET[1] / 2, abs=1e-7)  # 1 of 4 linear actuators
    assert act["right_leg"].max_abs < 1e-7
    assert a.base is not None
    assert a.base.maximum[0] == pytest.approx(DRIFT_X * DURATION, abs=1e-4)
    assert a.base.maximum[2] == pytest.approx(BASE_Z_OFFSET, abs=1e-6)
    assert np.abs(a.base.deviation[:, 1]).max() < 1e-4
    assert a.base.within_band() == {"x": False, "y": True, "z": True}
    assert a.fall is not None
    assert not a.fall.fell
    assert [(f.source, f.count) for f in a.faults] == [("rh5/mapper", 5)]
    assert "clamped.LLKnee_Act1=3" in a.faults[0].text
    assert [tr.state for tr in a.transitions] == ["idle", "playing", "holding"]
    loops = {x.node: x for x in a.loops}
    assert loops["rh5/stabilizer"].rate_hz == pytest.approx(999.8)
    assert loops["rh5/stabilizer"].deadline_misses == 2
    assert loops["rh5/stabilizer"].run_jitter_p99_us == 60.0
    assert loops["rh5/stabilizer"].periods_over_2ms == 1
    text = report.markdown.read_text()
    assert "OUTSIDE the paper's PyBullet band in x" in text
    assert "| left_leg | 6 | 4.082 | 10 | LLKnee |" in text
    assert "| rh5/stabilizer | 5 | 999.8 | <= 60 | 34.05 | 80 | 2 | 1 |" in text
    for name in ("tracking", "base", "errors"):
        assert report.figures[name].stat().st_size > 10_000
        assert f"]({report.figures[name].name})" in text


def test_fall_is_detected_when_it_happens(tmp_path: Path) -> None:
    """The base sinks 0.6 m/s from tau 1.5 s: below 60 % of 0.9 m at tau 2.1 s (incl. the +2 mm offset).

    This bag stores rclpy's serialize_message output untrimmed: the report reads it all the same.
    """
    bag = write_bag(tmp_path / "fall", BagSpec(fall_at=1.5, actuators=False, diagnostics=False, trim=False))
    report = build_report(bag, tmp_path / "out")
    fall = report.analysis.fall
    assert fall is not None
    assert fall.fell
    assert fall.t is not None
    assert fall.t - bag_time(T0, report.analysis.recording.origin_ns) == pytest.approx(
        1.5 + (0.4 * BASE_HEIGHT + BASE_Z_OFFSET) / 0.6, abs=2e-3
    )
    assert "Fell: YES" in report.verdicts[1]
    assert "fell" in report.markdown.read_text().lower()


def test_kinematic_bag_degrades_gracefully(tmp_path: Path) -> None:
    """No base pose, no diagnostics: time zero from the commands, base section 'not recorded'."""
    bag = write_bag(tmp_path / "kinematic", BagSpec(base=False, diagnostics=False))
    report = build_report(bag)
    out = report.folder
    assert out == default_out_dir(bag) == tmp_path / "kinematic_report"
    text = (out / "report.md").read_text()
    assert "**Floating base**: not recorded" in text
    assert "Loop diagnostics not recorded" in text
    assert "first planned sample" in text
    assert not (out / "base_deviation.png").exists()
    assert (out / "tracking.png").is_file()
    t0 = bag_time(T0, report.analysis.recording.origin_ns)
    assert report.analysis.time_zero.t0 == pytest.approx(t0, abs=1.5e-3)
    assert report.analysis.joint_groups[4].worst == "LLKnee"


# --- command line ------------------------------------------------------------------------------------------------


def test_cli_extra_joints_and_bad_input(walk_bag: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """--joints adds a figure and rows; a non-bag and an unknown joint exit 2 with the reason."""
    out = tmp_path / "cli"
    assert report_main([str(walk_bag), "--joints", "LLKnee,LLAnkle_Act1,LRHip1", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "Floating base: OUTSIDE" in printed
    assert str(out / "report.md") in printed
    text = (out / "report.md").read_text()
    assert (out / "extra_tracking.png").stat().st_size > 10_000
    assert "| LLKnee | 10 | 10 | mrad |" in text
    assert "| LLAnkle_Act1 | 2 | 2 | mm |" in text
    assert re.search(r"\| LRHip1 \| [0-9.e-]+ \| [0-9.e-]+ \| mrad \|", text)
    not_a_bag = tmp_path / "empty"
    not_a_bag.mkdir()
    assert report_main([str(not_a_bag)]) == 2
    assert "not a rosbag2 folder" in capsys.readouterr().err
    (not_a_bag / "metadata.yaml").write_text("this: is not rosbag2\n")
    assert report_main([str(not_a_bag)]) == 2
    assert "not a readable rosbag2 folder" in capsys.readouterr().err
    assert report_main([str(walk_bag), "--joints", "LLKnee,Tail"]) == 2
    assert "Tail" in capsys.readouterr().err
    with pytest.raises(NotABagError):
        load_recording(tmp_path / "missing")
    with pytest.raises(ReportError, match="unknown joint"):
        write_report(walk_bag, tmp_path / "x", ["Nope"])


def test_clock_moves_every_time_axis_onto_simulated_time() -> None:
    """A simulation at half real time: 2 s of recorder time after the first /clock message are 1 s simulated."""
    from rh5_bringup.analysis.load import on_simulated_time
    from rh5_bringup.analysis.records import DiagnosticRecord, PoseSeries, Recording

    t = np.array([0.0, 1.0, 2.0, 3.0, 4.0])
    pose = PoseSeries("/sim/base_pose", t, np.zeros((5, 3)), np.tile([0.0, 0.0, 0.0, 1.0], (5, 1)), "header")
    rec = Recording(Path("bag"), 0, 4.0, {}, base_pose=pose)
    rec.diagnostics.append(DiagnosticRecord(3.0, "rh5/stabilizer", 0, "playing", {"state": "playing"}))
    clock_t = np.array([1.0, 2.0, 3.0])  # receive times of three /clock messages [s]
    clock_ns = np.array([10_000_000_000, 10_500_000_000, 11_000_000_000])  # 0.5 s simulated per second
    moved = on_simulated_time(rec, clock_t, clock_ns)
    np.testing.assert_allclose(moved.base_pose.t, [0.0, 1.0, 1.5, 2.0, 3.0])  # before/after: wall rate
    assert moved.diagnostics[0].t == pytest.approx(2.0)
    assert moved.duration_s == pytest.approx(3.0)
    assert "0.50 x real time" in moved.notes[-1]


def test_stream_rates_are_on_the_wall_clock_when_the_time_axis_is_simulated() -> None:
    """A 1 kHz stream recorded while the simulation ran at 0.25 x real time is 1 kHz, not 4 kHz of simulated time."""
    from rh5_bringup.analysis.load import on_simulated_time
    from rh5_bringup.analysis.metrics import stream_timing
    from rh5_bringup.analysis.records import PoseSeries, Recording

    t = np.arange(0.0, 2.0, 1e-3)
    pose = PoseSeries("/sim/base_pose", t, np.zeros((len(t), 3)), np.tile([0.0, 0.0, 0.0, 1.0], (len(t), 1)), "header")
    rec = Recording(Path("bag"), 0, 2.0, {}, base_pose=pose)
    clock_t = np.arange(0.0, 2.01, 0.01)
    moved = on_simulated_time(rec, clock_t, (clock_t * 0.25e9).astype(np.int64))
    assert moved.base_pose.t[-1] == pytest.approx(0.5, abs=2e-3)  # the report's time axis: simulated
    timing = stream_timing(moved.base_pose)
    assert timing.rate_hz == pytest.approx(1000.0, rel=1e-3)
    assert timing.period_p50_ms == pytest.approx(1.0, rel=1e-3)


def test_a_bag_recorded_on_simulated_time_keeps_its_times_and_measures_rates_on_publish_times() -> None:
    """use_sim_time: the bag's times already are simulated (/clock logged at the time it carries), so nothing moves;
    a 1 kHz stream stamped in simulated time at 0.25 x real time still measures 1 kHz on its publish times, and the
    simulation's speed comes from /clock's publish times."""
    from rh5_bringup.analysis.load import recorded_on_simulated_time, with_wall_times
    from rh5_bringup.analysis.metrics import stream_timing
    from rh5_bringup.analysis.records import PoseSeries, Recording

    wall0 = 1_795_000_000_000_000_000
    publish = wall0 + np.arange(0, 2_000_000_000, 1_000_000)  # 1 kHz on the wall clock
    t = (publish - wall0) * 0.25 / 1e9  # simulated seconds
    quaternions = np.tile([0.0, 0.0, 0.0, 1.0], (len(t), 1))
    pose = PoseSeries("/sim/base_pose", t, np.zeros((len(t), 3)), quaternions, "header", publish_ns=publish)
    rec = Recording(Path("bag"), 0, 0.5, {}, base_pose=pose)
    clock_publish = wall0 + np.arange(0, 2_010_000_000, 16_000_000)
    clock_ns = ((clock_publish - wall0) * 0.25).astype(np.int64)
    assert recorded_on_simulated_time(clock_ns + 2_000_000, clock_ns)  # logged a recorder's take later
    assert not recorded_on_simulated_time(clock_publish, clock_ns)  # a bag on the wall clock
    out = with_wall_times(rec, clock_ns / 1e9, clock_publish, clock_ns)
    np.testing.assert_array_equal(out.base_pose.t, t)
    timing = stream_timing(out.base_pose)
    assert timing.rate_hz == pytest.approx(1000.0, rel=1e-3)
    assert out.sim_speed == pytest.approx(0.25, rel=1e-3)
    assert "0.25 x real time" in out.notes[-1]


def test_planned_base_is_the_one_published_with_the_planned_joints() -> None:
    """Under load the trajectory's base message can reach the recorder after playback started; the report must
    still compare with it, not with the planner's earlier 2-sample hold."""
    hold = PlannedBase(0.2, np.array([0.0, 1.0]), np.zeros((2, 3)), np.tile([0.0, 0.0, 0.0, 1.0], (2, 1)))
    times = np.linspace(0.0, 6.3, 64)
    motion = PlannedBase(1.9, times, np.zeros((64, 3)), np.tile([0.0, 0.0, 0.0, 1.0], (64, 1)))
    joints = PlannedJoints(1.0, JOINT_NAMES, times, np.zeros((64, len(JOINT_NAMES))), None)
    assert planned_base_for([hold, motion], joints, t0=1.85) is motion
    assert planned_base_for([hold, motion], None, t0=1.85) is hold  # no joint plan: the last one received by t0
    assert planned_base_for([], joints, t0=1.85) is None


def test_a_stream_stamped_from_simulated_time_zero_keeps_its_header_stamps() -> None:
    """The simulation's first base pose is taken at t = 0: a zero stamp logged at zero is set, not missing (read as
    missing, the whole stream fell back to receive times that lag by up to a /clock tick). A zero stamp on a
    wall-clock recording still is missing."""
    from rh5_bringup.analysis.load import pick_times

    stamps = np.arange(0, 40_000_000, 4_000_000)
    logged = np.array([0, 4, 8, 32, 32, 32, 32, 32, 32, 40]) * 1_000_000  # /clock ticks reach the recorder late
    times, source = pick_times(stamps, logged)
    assert source == "header"
    np.testing.assert_array_equal(times, stamps)
    wall0 = 1_795_000_000_000_000_000
    assert pick_times(stamps, wall0 + logged)[1] == "receive"
    unset_first = wall0 + stamps
    unset_first[0] = 0
    assert pick_times(unset_first, wall0 + logged)[1] == "receive"
    assert pick_times(wall0 + stamps, wall0 + logged)[1] == "header"
