"""Emulated actuator boards at the protocol level: NDLCom commands in, telemetry out, every 1 ms.

Each cycle decodes the commands that arrived, runs the actuator models (rh5_bringup.sim.
actuators: motor, transmission and the board's cascaded loops), and answers with one
TELEMETRY frame per board from the board's own NDLCom id. A board without a valid command
for ``command_timeout`` holds on its own (COMMAND_TIMEOUT). Faults are injected
deterministically from a seeded generator: dropped, delayed or CRC-corrupted frames,
silent boards, sensor noise.
"""

from __future__ import annotations

import time
from collections import Counter, deque
from dataclasses import dataclass, field

import numpy as np

from rh5_bringup.hardware.ndlcom.board_map import BoardMap
from rh5_bringup.hardware.ndlcom.codec import Frame, FrameEncoder
from rh5_bringup.hardware.ndlcom.payloads import (
    CommandMode,
    ErrorFlags,
    PayloadError,
    StatusFlags,
    TelemetryArrays,
    decode_command,
    encode_telemetry_many,
)
from rh5_bringup.hardware.transports.base import Transport
from rh5_bringup.sim.actuators import ActuatorBank, ActuatorFlags, ActuatorMeasurement
from rh5_msgs_py.realtime import LoopThread, set_timer_slack

BOARD_COMMAND_TIMEOUT_NS = 20_000_000  # the boards' own watchdog
BOARD_PERIOD_NS = 1_000_000  # the boards' position loop
COMMAND_PACE_GRACE_NS = 500_000_000
"""With ``pace_by_commands``: a driver silent this long is gone (disabled, crashed), not late; the boards tick on
their own again (and their watchdog holds)."""
BURST_GAP_S = 100e-6  # datagrams of one command burst arrive this close together
MAX_CATCH_UP_NS = 50_000_000  # a longer stall (debugger, suspended process) is not replayed


@dataclass(frozen=True)
class Faults:
    """Fault injection settings (all off by default)."""

    drop_rate: float = 0.0  # probability that a telemetry frame is not sent
    delay_s: float = 0.0  # extra latency of every telemetry frame
    corrupt_crc_rate: float = 0.0  # probability that a telemetry frame carries a broken FCS
    silent_boards: frozenset[str] = field(default_factory=frozenset)  # boards that never answer
    sensor_noise_std: float = 0.0  # noise on the measured position (m or rad)
    seed: int = 0


LIMITED = ActuatorFlags.CURRENT_LIMIT | ActuatorFlags.VOLTAGE_LIMIT | ActuatorFlags.VELOCITY_LIMIT
"""The actuator model's flags that the telemetry reports as SATURATED."""


def wire_flags(mode: np.ndarray, status: np.ndarray, timed_out: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Telemetry status and error bits (uint16 arrays) from the actuator model's status bits, for all boards."""
    status = status.astype(np.int64)

    def has(bits: int) -> np.ndarray:
        return (status & int(bits)) != 0

    flags = (
        np.where(has(ActuatorFlags.ENABLED), int(StatusFlags.ENABLED | StatusFlags.CALIBRATED), 0)
        | np.where(mode == int(CommandMode.HOLD), int(StatusFlags.HOLDING), 0)
        | np.where(mode == int(CommandMode.POSITION_FF), int(StatusFlags.FEED_FORWARD), 0)
        | np.where(has(ActuatorFlags.AT_LIMIT), int(StatusFlags.AT_LIMIT), 0)
        | np.where(has(LIMITED), int(StatusFlags.SATURATED), 0)
    )
    errors = (
        np.where(has(ActuatorFlags.FOLLOWING_ERROR), int(ErrorFlags.FOLLOWING_ERROR), 0)
        | np.where(has(ActuatorFlags.OVERTEMPERATURE), int(ErrorFlags.OVERTEMP), 0)
        | np.where(timed_out, int(ErrorFlags.COMMAND_TIMEOUT), 0)
    )
    return flags.astype(np.uint16), errors.astype(np.uint16)


def corrupt(frame: bytes) -> bytes:
    """The frame with one payload byte changed, so that its FCS no longer matches (framing kept)."""
    data = bytearray(frame)
    i = len(data) // 2
    changed = data[i] ^ 0x01
    data[i] = changed ^ 0x02 if changed in (0x7D, 0x7E) or data[i] in (0x7D, 0x7E) else changed
    if data[i] in (0x7D, 0x7E):
        data[i] ^= 0x04
    return bytes(data)


class BoardEmulator:
    """All boards of the board map behind one transport, stepped once per cycle."""

    def __init__(
        self, board_map: BoardMap, transport: Transport, bank: ActuatorBank, faults: Faults | None = None
    ) -> None:
        self.board_map = board_map
        self.transport = transport
        self.bank = bank
        self.faults = faults or Faults()
        self._rng = np.random.default_rng(self.faults.seed)
        n = len(board_map)
        self._index_of = {board.address: board.index for board in board_map}
        self._encoders = [FrameEncoder(board.address) for board in board_map]
        self._silent = np.array([board.name in self.faults.silent_boards for board in board_map])
        self._table = board_map.scaling_table()
        self.mode = np.full(n, int(CommandMode.OFF))
        self.setpoint = np.zeros(n)
        self.velocity_ff = np.zeros(n)
        self.effort_ff = np.zeros(n)
        self.sequence = np.zeros(n, dtype=np.int64)
        self.command_ns = np.zeros(n, dtype=np.int64)
        self.counts: Counter[str] = Counter()
        self._delayed: deque[tuple[int, bytes]] = deque()
        self.board_time_us = 0
        self.max_catch_up_ns = MAX_CATCH_UP_NS  # physics mode: a few ms (its steps cost a third of a cycle each)
        self._last_ns: int | None = None
        self._debt_ns = 0  # time passed that the boards have not stepped yet (less than one cycle)
        self.pace_by_commands = False
        """Simulation slower than real time (physics mode): while the driver is sending, the boards step only when
        its commands come, so a late driver (a CPU stall on this machine) pauses the simulated time instead of
        letting the robot run on stale setpoints; after COMMAND_PACE_GRACE_NS of silence they tick on their own."""
        self._last_command_ns: int | None = None

    def set_faults(self, faults: Faults) -> None:
        """Change the injected faults from the next cycle on (the random stream continues)."""
        self._silent = np.array([board.name in faults.silent_boards for board in self.board_map])
        self.faults = faults

    def _receive(self, now_ns: int, frames: list[Frame]) -> None:
        """Take the newest command of every board among ``frames`` (older ones are superseded)."""
        newest: dict[int, bytes] = {}
        for frame in frames:
            newest[frame.receiver] = frame.payload
        for address, payload in newest.items():
            index = self._index_of.get(address)
            if index is None:
                self.counts["frames_for_unknown_boards"] += 1
                continue
            try:
                command = decode_command(payload, self.board_map.boards[index].scaling)
            except PayloadError:
                self.counts["bad_commands"] += 1
                continue
            self.mode[index] = int(command.mode)
            self.setpoint[index] = command.setpoint
            self.velocity_ff[index] = command.velocity_ff
            self.effort_ff[index] = command.effort_ff
            self.sequence[index] = command.sequence
            self.command_ns[index] = now_ns
            self.counts["commands"] += 1

    def cycle(
        self,
        now_ns: int,
        period_ns: int,
        external_force: np.ndarray | None = None,
        frames: list[Frame] | None = None,
    ) -> ActuatorMeasurement:
        """Take the commands (``frames``, or whatever waits on the transport), step the actuators over the time
        since the last cycle, send telemetry; return what the boards measured. With ``pace_by_commands`` a tick
        without commands while the driver is sending steps nothing and sends nothing (the boards wait for it)."""
        frames = self.transport.recv(timeout=0.0) if frames is None else frames
        if frames:
            self._last_command_ns = now_ns
        elif self._waiting_for_driver(now_ns):
            self.counts["cycles_paused_for_the_driver"] += 1
            self._last_ns = now_ns
            return self.bank.measure()
        self._receive(now_ns, frames)
        timed_out = (self.mode != int(CommandMode.OFF)) & (now_ns - self.command_ns > BOARD_COMMAND_TIMEOUT_NS)
        mode = np.where(timed_out, int(CommandMode.HOLD), self.mode)
        setpoint = np.where(mode >= int(CommandMode.POSITION), self.setpoint, 0.0)
        # Real time passes for the actuators even when this loop is late: the boards run their own 1 ms cycles,
        # so step as many whole cycles as have passed (a stall longer than max_catch_up_ns is not replayed). A fixed
        # cycle also keeps the bank's discretised loop coefficients cached (a varying dt recomputed them each time).
        gap = period_ns if self._last_ns is None else max(now_ns - self._last_ns, 0)
        self._last_ns = now_ns
        self._debt_ns += gap
        if self._debt_ns > self.max_catch_up_ns:
            self.counts["time_not_replayed_us"] += (self._debt_ns - self.max_catch_up_ns) // 1000
            self._debt_ns = self.max_catch_up_ns
        steps, self._debt_ns = divmod(self._debt_ns, BOARD_PERIOD_NS)
        measured = None
        for _ in range(steps):
            measured = self.bank.step(
                BOARD_PERIOD_NS / 1e9, mode, setpoint, self.velocity_ff, self.effort_ff, external_force
            )
        if measured is None:  # a burst within the boards' current cycle: they answer with their latest readings
            measured = self.bank.measure()
        self.board_time_us += steps * BOARD_PERIOD_NS // 1000
        self._send(now_ns, mode, timed_out, measured)
        return measured

    def _waiting_for_driver(self, now_ns: int) -> bool:
        """Whether this commandless tick waits for a late driver (``pace_by_commands``) instead of stepping."""
        last = self._last_command_ns
        return self.pace_by_commands and last is not None and now_ns - last < COMMAND_PACE_GRACE_NS

    def _send(self, now_ns: int, mode: np.ndarray, timed_out: np.ndarray, measured: ActuatorMeasurement) -> None:
        faults, rng = self.faults, self._rng
        n = len(self.board_map)
        position = measured.position
        if faults.sensor_noise_std > 0:
            position = position + rng.normal(0.0, faults.sensor_noise_std, n)
        status, errors = wire_flags(mode, measured.status, timed_out)
        payloads = encode_telemetry_many(
            TelemetryArrays(
                mode,
                status,
                errors,
                self.sequence & 0xFFFFFFFF,
                np.full(n, self.board_time_us, dtype=np.uint64),
                position,
                measured.velocity,
                measured.force,
                measured.current,
                measured.temperature,
            ),
            self._table,
        )
        send = ~self._silent
        if faults.drop_rate > 0:
            dropped = rng.random(n) < faults.drop_rate
            self.counts["dropped_frames"] += int((dropped & send).sum())
            send &= ~dropped
        corrupted = rng.random(n) < faults.corrupt_crc_rate if faults.corrupt_crc_rate > 0 else np.zeros(n, bool)
        frames = []
        for i in np.flatnonzero(send):
            frame = self._encoders[i].encode(self.board_map.pc_address, payloads[i])
            if corrupted[i]:
                frame = corrupt(frame)
                self.counts["corrupted_frames"] += 1
            frames.append(frame)
        if faults.delay_s > 0:
            release = now_ns + int(faults.delay_s * 1e9)
            self._delayed.extend((release, frame) for frame in frames)
            frames = []
            while self._delayed and self._delayed[0][0] <= now_ns:
                frames.append(self._delayed.popleft()[1])
        if frames and self.transport_ready():
            self.transport.send_frames(frames)
            self.counts["telemetry_frames"] += len(frames)

    def transport_ready(self) -> bool:
        """Whether the transport knows where to send (a UDP router answers the driver once it has heard it)."""
        remote = getattr(self.transport, "remote", True)
        return remote is not None


class BoardsServer(LoopThread):
    """Runs the emulated boards as the real ones behave: every command burst is answered at once (each board
    replies to its command), and the boards tick every ``period_ns`` even when no command comes."""

    def __init__(
        self,
        emulator: BoardEmulator,
        period_ns: int = BOARD_PERIOD_NS,
        name: str = "sim-boards",
        *,
        answer_bursts: bool = True,
    ) -> None:
        super().__init__(period_ns, name)
        self.emulator = emulator
        self.answer_bursts = answer_bursts  # False: tick on the period only (a CAN burst trickles in frame by frame)

    def _loop(self) -> None:
        set_timer_slack(1_000)
        transport, period = self.emulator.transport, self.period_ns
        next_tick = time.monotonic_ns() + period
        while not self._stop.is_set():
            wait = max(next_tick - time.monotonic_ns(), 0) / 1e9
            if self.answer_bursts:
                # bursts the boards fell behind on (a simulation slower than real time) are superseded unread
                frames = transport.recv_newest(timeout=wait)
                if frames:  # the rest of the burst follows within microseconds (several datagrams)
                    frames += transport.recv_newest(timeout=BURST_GAP_S)
                elif time.monotonic_ns() < next_tick:
                    continue
            else:
                self._stop.wait(wait)
                frames = None  # the cycle drains everything that arrived
            now = time.monotonic_ns()
            self.timer.record(now)
            self.emulator.cycle(now, period, frames=frames)
            if now >= next_tick:
                missed = (now - next_tick) // period
                self.timer.deadline_misses += int(missed)
                next_tick += (missed + 1) * period
            else:
                next_tick = now + period  # a command burst is this cycle's tick
