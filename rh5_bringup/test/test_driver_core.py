"""DriverCore and the emulated boards in one process: CAN round trip, unknown senders, the cycle's safety gates.

The UDP tests at 1 kHz, with the boards in their own process, are in tests/test_driver_sim.py;
here both loops would share one interpreter, so the CAN rig runs at 100 Hz.
"""

from __future__ import annotations

import socket
import time

import numpy as np

from rh5_bringup.hardware.driver_node import actuator_limits
from rh5_bringup.hardware.ndlcom.board_map import load_board_map
from rh5_bringup.hardware.ndlcom.codec import Frame, encode_frame
from rh5_bringup.hardware.ndlcom.payloads import (
    Command,
    CommandMode,
    ErrorFlags,
    StatusFlags,
    Telemetry,
    encode_command,
    encode_telemetry,
)
from rh5_bringup.hardware.rig import LINEAR, DriverLoop, sine_centre
from rh5_bringup.hardware.transports import open_transport
from rh5_bringup.sim.actuators import ActuatorBank
from rh5_bringup.sim.boards import BOARD_PERIOD_NS, COMMAND_PACE_GRACE_NS, BoardEmulator, BoardsServer
from rh5_hyrodyn_mapper.mapping import robot_mapper
from rh5_msgs_py.names import NUM_JOINTS

LIMITS = actuator_limits()
CENTRE = sine_centre(robot_mapper().to_actuators(np.zeros(NUM_JOINTS)).position, LIMITS)


def test_sine_is_tracked_over_the_virtual_can_bus() -> None:
    """python-can's virtual bus at 20 Hz: a cycle of 32 boards is about 320 classic CAN frames (docs/protocol.md:
    CAN cannot carry the full robot at 1 kHz), which the virtual bus deep-copies one by one in this process:
    13 ms of the driver's CPU per cycle measured here, about 25 ms for both sides sharing one GIL, so 50 Hz
    overran its period and the readings fell behind by the backlog, not by the mapping."""
    board_map = load_board_map()
    channel = f"rh5-test-{time.monotonic_ns()}"
    sim = open_transport("can", interface="virtual", channel=channel, receivers=board_map.addresses())
    link = open_transport("can", interface="virtual", channel=channel, receivers=[board_map.pc_address])
    bank = ActuatorBank()
    bank.reset(CENTRE)
    boards = BoardsServer(BoardEmulator(board_map, sim, bank), period_ns=50_000_000, answer_bursts=False)
    driver = DriverLoop(board_map, link, LIMITS, CENTRE, rate_hz=20.0, sine_hz=0.2, silence_timeout_ns=250_000_000)
    assert driver.core.enable(True)[0]
    boards.start()
    driver.loop.start()
    time.sleep(3.5)
    driver.loop.stop()
    boards.stop()
    link.shutdown()
    sim.shutdown()
    errors = driver.tracking_error(percentile=99.0)
    # Two 50 ms cycles of latency plus a 50 ms zero-order hold: A w (100 + 50) ms ~ 0.9 mm at 5 mm and 0.2 Hz
    assert errors[LINEAR].max() < 2.0e-3
    assert errors[~LINEAR].max() < 20e-3
    assert not driver.core.safe_hold_reason


def test_telemetry_from_unknown_addresses_is_dropped_and_counted() -> None:
    board_map = load_board_map()
    link = open_transport("udp", local=("127.0.0.1", 0), remote=("127.0.0.1", 9), receivers=[board_map.pc_address])
    driver = DriverLoop(board_map, link, LIMITS, CENTRE, rate_hz=200.0)
    telemetry = Telemetry(CommandMode.HOLD, StatusFlags.NONE, ErrorFlags.NONE, 0, 0, 0.3, 0.0, 0.0, 0.0, 25.0)
    frame = encode_frame(board_map.pc_address, 0x99, 0, encode_telemetry(telemetry, board_map.boards[3].scaling))
    intruder = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    driver.loop.start()
    for _ in range(20):
        intruder.sendto(frame, link.local_address)
        time.sleep(0.005)
    time.sleep(0.05)
    driver.loop.stop()
    intruder.close()
    link.shutdown()
    assert driver.core.counts["unknown_sender_frames"] == 20
    assert driver.core.readings.position[3] == 0.0  # nothing from the intruder reached the readings


def test_paced_boards_wait_for_a_late_driver_and_tick_again_when_it_is_gone() -> None:
    """Physics mode (``pace_by_commands``): a commandless tick shortly after a command does not step the
    actuators (the simulated time stands still for a late driver); once the driver has been silent for
    COMMAND_PACE_GRACE_NS the boards tick on their own again."""
    board_map = load_board_map()
    channel = f"rh5-pace-{time.monotonic_ns()}"
    sim = open_transport("can", interface="virtual", channel=channel, receivers=board_map.addresses())
    bank = ActuatorBank()
    bank.reset(CENTRE)
    emulator = BoardEmulator(board_map, sim, bank)
    emulator.pace_by_commands = True
    board = board_map.boards[0]
    command = encode_command(Command(CommandMode.HOLD), board.scaling)
    frames = [Frame(board.address, board_map.pc_address, 0, command)]
    period = BOARD_PERIOD_NS
    try:
        t = 10 * period
        emulator.cycle(t, period, frames=frames)
        stepped = emulator.board_time_us
        for _ in range(5):  # the driver is late: five ticks without commands
            t += period
            emulator.cycle(t, period, frames=[])
        assert emulator.board_time_us == stepped
        assert emulator.counts["cycles_paused_for_the_driver"] == 5
        t += period
        emulator.cycle(t, period, frames=frames)  # it comes back: one cycle, the stall is not replayed
        assert emulator.board_time_us == stepped + period // 1000
        t += COMMAND_PACE_GRACE_NS + period  # gone: the boards tick on their own
        emulator.cycle(t, period, frames=[])
        assert emulator.board_time_us > stepped + period // 1000
        emulator.pace_by_commands = False  # wall-clock pacing (kinematic mode) never waits
        before = emulator.board_time_us
        emulator.cycle(t + period, period, frames=[])
        assert emulator.board_time_us == before + period // 1000
    finally:
        sim.shutdown()


def test_the_board_clock_stamps_forward_and_follows_a_restarted_simulation() -> None:
    """The stamp under use_sim_time is the boards' clock: a late frame with an older time does not move it back,
    a clock that went back by more than a second (a simulation started anew) is followed, not outwaited."""
    from rh5_bringup.hardware.driver import BOARD_CLOCK_RESTART_NS, DriverCore

    board_map = load_board_map()
    link = open_transport("udp", local=("127.0.0.1", 0), remote=("127.0.0.1", 9), receivers=[board_map.pc_address])
    driver = DriverCore(board_map, link, LIMITS, command_timeout_ns=10**8, silence_timeout_ns=10**9)
    boards = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)

    def telemetry_at(board_time_us: int) -> int:
        telemetry = Telemetry(
            CommandMode.HOLD, StatusFlags.NONE, ErrorFlags.NONE, 0, board_time_us, 0.0, 0.0, 0.0, 0.0, 25.0
        )
        frames = b"".join(
            encode_frame(board_map.pc_address, b.address, 0, encode_telemetry(telemetry, b.scaling)) for b in board_map
        )
        boards.sendto(frames, link.local_address)
        time.sleep(0.02)
        driver.read(time.monotonic_ns(), 1_000_000)
        return driver.stamp_ns(sim_time=True)

    try:
        assert telemetry_at(5_000_000) == 5_000_000_000
        assert telemetry_at(4_900_000) == 5_000_000_000  # 0.1 s older: a late frame, the stamp stays
        assert telemetry_at(5_001_000) == 5_001_000_000
        restarted = 5_001_000 - BOARD_CLOCK_RESTART_NS // 1000 - 1
        assert telemetry_at(restarted) == restarted * 1000  # over a second back: the clock restarted
    finally:
        boards.close()
        link.shutdown()


def test_the_safety_rules_run_on_the_callers_clock() -> None:
    """With a synthetic clock the staleness and silence rules' half second replays in milliseconds, and each rule
    fires at the synthetic time it names: a command older than 100 ms is not sent, boards silent for 500 ms (and
    as many cycles) stop the driving."""
    from rh5_bringup.hardware.driver import ActuatorCommand, DriverCore

    board_map = load_board_map()
    link = open_transport("udp", local=("127.0.0.1", 0), remote=("127.0.0.1", 9), receivers=[board_map.pc_address])
    start_ns, period_ns = 1_000_000_000, 1_000_000
    now = [start_ns]
    driver = DriverCore(
        board_map,
        link,
        LIMITS,
        command_timeout_ns=100_000_000,
        silence_timeout_ns=500_000_000,
        clock_ns=lambda: now[0],
    )
    boards = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        telemetry = Telemetry(CommandMode.HOLD, StatusFlags.NONE, ErrorFlags.NONE, 0, 0, 0.0, 0.0, 0.0, 0.0, 25.0)
        boards.sendto(
            b"".join(
                encode_frame(board_map.pc_address, b.address, 0, encode_telemetry(telemetry, b.scaling))
                for b in board_map
            ),
            link.local_address,
        )
        deadline = time.monotonic() + 2.0
        while not driver.all_heard and time.monotonic() < deadline:
            driver.read(now[0], period_ns)  # the synthetic clock stands still until every board is heard
        assert driver.all_heard
        assert driver.enable(True)[0]
        driver.command.set(ActuatorCommand(CENTRE, np.zeros_like(CENTRE), np.zeros_like(CENTRE)), now[0])
        wall = time.monotonic()
        modes = []
        while not driver.safe_hold_reason and now[0] < start_ns + 2_000_000_000:
            now[0] += period_ns
            driver.write(now[0], period_ns)
            driver.read(now[0], period_ns)
            modes.append(driver.mode)
        wall = time.monotonic() - wall
    finally:
        boards.close()
        link.shutdown()
    first_hold = modes.index(CommandMode.HOLD)
    assert set(modes[:first_hold]) == {CommandMode.POSITION_FF}
    assert first_hold == 100  # the cycle at +101 ms: the command is 101 ms old
    assert driver.counts["stale_command_cycles"] > 0
    held_after_ms = (now[0] - start_ns) / 1e6
    assert 500 < held_after_ms <= 502, held_after_ms
    assert "boards silent" in driver.safe_hold_reason
    assert wall < held_after_ms / 1e3, f"{wall:.3f} s of wall time for {held_after_ms:.0f} ms of rules"
