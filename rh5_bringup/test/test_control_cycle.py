"""The composed control cycle over real UDP on 127.0.0.1: its order and the safety rules of all three cores.

The test plays the boards itself, one cycle at a time: it sends every board's telemetry, steps the
cycle (the real DriverCore, MapperCore and StabilizerCore), and decodes the command frames that cycle
put on the wire. So what reached the wire, and from which telemetry, is seen directly.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass

import numpy as np
import pytest

from rh5_bringup.control.cycle import ControlCycle
from rh5_bringup.hardware.driver import STARTUP_GRACE_NS, DriverCore
from rh5_bringup.hardware.driver_node import actuator_limits
from rh5_bringup.hardware.ndlcom.board_map import BoardMap, load_board_map
from rh5_bringup.hardware.ndlcom.codec import FrameEncoder
from rh5_bringup.hardware.ndlcom.payloads import (
    Command,
    CommandMode,
    TelemetryArrays,
    decode_command,
    encode_telemetry_many,
)
from rh5_bringup.hardware.rig import sine_centre
from rh5_bringup.hardware.transports import open_transport
from rh5_hyrodyn_mapper.mapper_core import MapperCore
from rh5_hyrodyn_mapper.mapping import robot_mapper
from rh5_hyrodyn_mapper.model import joint_limits
from rh5_joint_stabilizer.controller import Measurement, SafetyLimits, StabilizerCore, State, load_gains
from rh5_joint_stabilizer.reference import validate_trajectory
from rh5_msgs_py.names import ACTUATOR_NAMES, JOINT_INDEX, JOINT_NAMES, NUM_JOINTS

PERIOD_NS = 1_000_000
COMMAND_TIMEOUT_NS = 5_000_000
SILENCE_TIMEOUT_NS = 5_000_000
MAPPER = robot_mapper()
LIMITS = actuator_limits()
CENTRE = sine_centre(MAPPER.to_actuators(np.zeros(NUM_JOINTS)).position, LIMITS)
Q0 = MAPPER.to_joints(CENTRE).position
ROTARY = next(name for name in JOINT_NAMES if name in ACTUATOR_NAMES and name.startswith("LLHip"))
"""A pass-through joint: its actuator value is the joint value, so the wire shows the stabilizer's torque."""


class Boards:
    """The boards' side of the link, driven by the test: telemetry out, one cycle's command frames in."""

    def __init__(self, board_map: BoardMap) -> None:
        self.board_map = board_map
        self.table = board_map.scaling_table()
        self.link = open_transport("udp", local=("127.0.0.1", 0), remote=None, receivers=board_map.addresses())
        self.encoders = [FrameEncoder(board.address) for board in board_map]
        self.sequence = 0

    def answer(self, position: np.ndarray, *, silent: tuple[str, ...] = ()) -> None:
        """Every board (but ``silent`` ones) reports ``position`` (actuator space) at rest, echoing the last command."""
        n = len(self.board_map)
        zeros = np.zeros(n, dtype=np.int64)
        telemetry = TelemetryArrays(
            np.full(n, int(CommandMode.POSITION_FF)), zeros, zeros, np.full(n, self.sequence), zeros,
            position, np.zeros(n), np.zeros(n), np.zeros(n), np.full(n, 30.0),
        )  # fmt: skip
        payloads = encode_telemetry_many(telemetry, self.table)
        self.link.send_frames(
            encoder.encode(self.board_map.pc_address, payload)
            for board, encoder, payload in zip(self.board_map, self.encoders, payloads, strict=True)
            if board.name not in silent
        )

    def commands(self) -> list[Command]:
        """The command frames of one cycle, one per board in board order."""
        frames = self.link.recv_frames(len(self.board_map), timeout=1.0)
        by_address = {frame.receiver: frame for frame in frames}
        commands = [decode_command(by_address[b.address].payload, b.scaling) for b in self.board_map]
        self.sequence = commands[0].sequence
        return commands


class SyntheticClock:
    """The rig's time, set by the test: every reading moves it on by 1 us, as a real clock moves while the cycle
    runs, so the rules' timeouts count cycles, not how busy the machine is."""

    def __init__(self, start_ns: int = 1_000_000_000) -> None:
        self.ns = start_ns

    def __call__(self) -> int:
        self.ns += 1_000
        return self.ns

    def advance(self, ns: int) -> None:
        """Let ``ns`` pass without a cycle."""
        self.ns += ns


@dataclass
class Rig:
    """A composed cycle against the test's boards, on a synthetic clock."""

    cycle: ControlCycle
    driver: DriverCore
    stabilizer: StabilizerCore
    boards: Boards
    clock: SyntheticClock

    def step(self, position: np.ndarray, **answer: tuple[str, ...]) -> list[Command]:
        """Boards answer with ``position``, the cycle runs once; returns what it put on the wire."""
        self.boards.answer(position, **answer)
        self.clock.advance(PERIOD_NS)
        self.cycle.step(self.clock.ns, PERIOD_NS)
        return self.boards.commands()

    def start_holding_q0(self) -> None:
        """Enable the driver and play a trajectory that stands at Q0, measured at Q0."""
        assert self.driver.enable(True)[0]
        at_rest = Measurement(Q0, np.zeros(NUM_JOINTS), self.clock.ns)
        ok, why = self.stabilizer.request_start(at_rest)
        assert ok, why
        for _ in range(3):
            self.step(CENTRE)
        assert self.stabilizer.state in (State.RAMP_IN, State.PLAYING), self.stabilizer.last_reason


@pytest.fixture
def rig() -> Iterator[Rig]:
    board_map = load_board_map()
    boards = Boards(board_map)
    link = open_transport(
        "udp", local=("127.0.0.1", 0), remote=boards.link.local_address, receivers=[board_map.pc_address]
    )
    clock = SyntheticClock()
    driver = DriverCore(
        board_map,
        link,
        LIMITS,
        command_timeout_ns=COMMAND_TIMEOUT_NS,
        silence_timeout_ns=SILENCE_TIMEOUT_NS,
        clock_ns=clock,
    )
    limits = joint_limits()
    stabilizer = StabilizerCore(
        load_gains(),
        np.asarray(limits.torque_max),
        ramp_max_velocity=0.5,
        ramp_max_acceleration=2.0,
        safety=SafetyLimits(50_000_000, 0.3, rest_velocity=0.05),
    )
    standing = np.vstack([Q0, Q0])
    ok, why = stabilizer.load(
        validate_trajectory(
            JOINT_NAMES, np.array([0.0, 10.0]), standing, None, None, velocity_limits=np.asarray(limits.velocity_max)
        )
    )
    assert ok, why
    cycle = ControlCycle(driver, MapperCore(MAPPER), stabilizer.update, estop_to_stabilizer=stabilizer.set_estop)
    rig = Rig(cycle, driver, stabilizer, boards, clock)
    driver.write(clock.ns, PERIOD_NS)  # the boards' router learns where the driver is
    boards.commands()
    try:
        yield rig
    finally:
        link.shutdown()
        boards.link.shutdown()


def _modes(commands: list[Command]) -> set[CommandMode]:
    return {c.mode for c in commands}


def test_each_command_is_computed_from_the_same_cycles_telemetry(rig: Rig) -> None:
    """Telemetry changes every cycle; the torque on the wire answers the telemetry of its own cycle.

    At a standing reference with the joint at rest, tau = Kp (q_ref - q) for the pass-through joint, so the
    command of cycle k shows which measurement it used: k's own, not k-1's as a pipeline of nodes would.
    """
    rig.start_holding_q0()
    j = JOINT_INDEX[ROTARY]
    a = ACTUATOR_NAMES.index(ROTARY)
    kp = load_gains().kp[j]
    offsets = 1e-3 * np.array([1.0, -2.0, 3.0, -4.0, 5.0, -6.0, 7.0])
    torques = []
    for offset in offsets:
        position = CENTRE.copy()
        position[a] += offset
        commands = rig.step(position)
        assert commands[a].mode == CommandMode.POSITION_FF
        torques.append(commands[a].effort_ff)
    lsb = rig.boards.board_map.boards[a].scaling.effort.lsb
    np.testing.assert_allclose(torques, -kp * offsets, atol=2 * lsb + 1e-6 * kp)
    assert rig.cycle.telemetry_to_command.percentiles_us()["p50_us"] > 0  # measured on every commanding cycle


def test_commands_go_stale_when_the_stabilizer_stops(rig: Rig) -> None:
    rig.start_holding_q0()
    assert _modes(rig.step(CENTRE)) == {CommandMode.POSITION_FF}
    assert rig.stabilizer.request_stop()[0]
    rig.clock.advance(COMMAND_TIMEOUT_NS * 3 // 2)  # the last command outlives the timeout
    assert _modes(rig.step(CENTRE)) == {CommandMode.HOLD}
    assert rig.driver.counts["stale_command_cycles"] >= 1


def test_a_silent_board_makes_every_board_hold(rig: Rig) -> None:
    rig.start_holding_q0()
    silent = (rig.boards.board_map.boards[5].name,)
    for _ in range((STARTUP_GRACE_NS + 3 * SILENCE_TIMEOUT_NS) // PERIOD_NS):  # the rule waits out the start-up
        commands = rig.step(CENTRE, silent=silent)
        if rig.driver.safe_hold_reason:
            break
    assert silent[0] in rig.driver.safe_hold_reason
    assert _modes(commands) == {CommandMode.HOLD}
    assert _modes(rig.step(CENTRE)) == {CommandMode.HOLD}  # latched until a new enable


def test_estop_holds_every_board_and_stops_the_stabilizer_at_once(rig: Rig) -> None:
    rig.start_holding_q0()
    rig.driver.estop()
    assert _modes(rig.step(CENTRE)) == {CommandMode.HOLD}
    assert rig.stabilizer.state == State.STOPPED
    assert not rig.driver.enable(True)[0]


@pytest.mark.parametrize(
    ("corrupt", "rule"),
    [
        (lambda tau: tau * np.nan, "non-finite"),
        (lambda tau: tau + 1e6, "force limit"),
    ],
)
def test_nan_and_out_of_limit_setpoints_never_reach_the_wire(
    rig: Rig, corrupt: Callable[[np.ndarray], np.ndarray], rule: str
) -> None:
    """A broken stabilizer output: NaN is refused by the mapper (the last good command goes stale, then HOLD);
    an out-of-limit force is clamped to the actuator's limit."""
    rig.start_holding_q0()
    update = rig.stabilizer.update

    def broken(now_ns: int, period_ns: int, measurement: Measurement | None) -> object:
        command = update(now_ns, period_ns, measurement)
        return None if command is None else command._replace(effort=corrupt(command.effort))

    rig.cycle._stabilize = broken  # the test swaps in a broken stabilizer
    seen = [rig.step(CENTRE) for _ in range(3)]
    rig.clock.advance(COMMAND_TIMEOUT_NS * 3 // 2)
    seen.append(rig.step(CENTRE))
    for commands in seen:
        efforts = np.array([c.effort_ff for c in commands])
        assert np.isfinite(efforts).all()
        assert (np.abs(efforts) <= LIMITS.force_max * (1 + 1e-6)).all(), rule
    if rule == "non-finite":
        assert rig.cycle.mapper.rejected["joint_commands"] >= 3
        assert _modes(seen[-1]) == {CommandMode.HOLD}
    else:
        assert rig.cycle.mapper.clamped
        assert _modes(seen[-1]) == {CommandMode.POSITION_FF}
