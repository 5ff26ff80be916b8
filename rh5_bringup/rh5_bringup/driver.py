"""The driver's 1 kHz cycle, free of ROS: commands out to every board, telemetry back, safety rules.

Each ``cycle(now_ns, period_ns)`` sends one COMMAND frame per actuator and collects the
TELEMETRY frames of the same cycle. Safety, in order of precedence:
- estop (latched until reset), a silent board (latched safe hold until re-enabled), not
  enabled, or a command older than ``command_timeout`` -> every board is told to HOLD;
- setpoints outside the stroke, velocity and force limits are clamped (and counted);
- non-finite commands never get here (refused on arrival) and cannot be encoded anyway;
- telemetry from addresses outside the board map is dropped and counted.
"""

from __future__ import annotations

import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from rh5_bringup.ndlcom.board_map import BoardMap
from rh5_bringup.ndlcom.codec import FrameEncoder
from rh5_bringup.ndlcom.payloads import CommandMode, PayloadError, decode_telemetry, encode_commands
from rh5_bringup.transports.base import Transport
from rh5_msgs_py.realtime import LatencyWindow, LatestValue

FloatArray = np.ndarray
STARTUP_GRACE_NS = 200_000_000  # the router learns where the driver is from its first commands


class ActuatorCommand(NamedTuple):
    """A validated actuator-space setpoint (ACTUATOR_NAMES order): length/angle, rate, force/torque."""

    position: FloatArray
    velocity: FloatArray
    effort: FloatArray


class ActuatorReadings(NamedTuple):
    """The latest telemetry of every board (ACTUATOR_NAMES order)."""

    position: FloatArray
    velocity: FloatArray
    effort: FloatArray
    temperature: FloatArray
    status: np.ndarray
    errors: np.ndarray


@dataclass(frozen=True)
class Limits:
    """Actuator limits the driver clamps setpoints to (stroke, speed, force), in ACTUATOR_NAMES order."""

    position_min: FloatArray
    position_max: FloatArray
    velocity_max: FloatArray
    effort_max: FloatArray


class DriverCore:
    """One driver cycle per call; requests (enable, estop) from any thread."""

    def __init__(
        self,
        board_map: BoardMap,
        transport: Transport,
        limits: Limits,
        *,
        command_timeout_ns: int,
        silence_timeout_ns: int,
        on_event: Callable[[str], None] = lambda _text: None,
    ) -> None:
        self.board_map = board_map
        self.transport = transport
        self.limits = limits
        self.command_timeout_ns = command_timeout_ns
        self.silence_timeout_ns = silence_timeout_ns
        self._on_event = on_event
        self._table = board_map.scaling_table()
        self._encoder = FrameEncoder(board_map.pc_address)
        self._addresses = board_map.addresses()
        self._index_of = {board.address: board.index for board in board_map}
        n = len(board_map)
        self.command: LatestValue[ActuatorCommand] = LatestValue()
        self.enabled = False
        self.estopped = False
        self.safe_hold_reason = ""
        self.sequence = 0
        self.readings = ActuatorReadings(*(np.zeros(n) for _ in range(4)), np.zeros(n, int), np.zeros(n, int))
        self.heard_ns = np.zeros(n, dtype=np.int64)
        self.heard_cycle = np.zeros(n, dtype=np.int64)
        self.silence_cycles = 0  # set from the period on the first cycle
        self.started_ns = 0
        self.counts: Counter[str] = Counter()
        self.clamped: Counter[str] = Counter()
        self.mode = CommandMode.HOLD
        self._sent_ns = np.zeros(256, dtype=np.int64)  # send time of the latest 256 sequence numbers
        self._echoed = np.full(n, -1, dtype=np.int64)
        self.latency = LatencyWindow()

    # --- requests ----------------------------------------------------------------------------------------------------

    def enable(self, on: bool) -> tuple[bool, str]:
        """Drive the setpoints (True) or let the boards hold (False); refused under estop or a silent board."""
        if on and self.estopped:
            return False, "refused: emergency stop is latched (call ~/reset_estop)"
        if on:
            silent = self.silent_boards(time.monotonic_ns())
            if silent:
                return False, f"refused: boards silent: {silent}"
            self.safe_hold_reason = ""
        self.enabled = on
        return True, "enabled: driving the actuator setpoints" if on else "disabled: boards hold"

    def estop(self) -> None:
        """Latch the emergency stop: every board holds until ``reset_estop``."""
        self.estopped, self.enabled = True, False

    def reset_estop(self) -> None:
        """Clear the latch; driving needs a new ``enable``."""
        self.estopped = False

    # --- the cycle ---------------------------------------------------------------------------------------------------

    @property
    def all_heard(self) -> bool:
        """Whether every board has answered at least once (before that the readings are partly unknown)."""
        return bool(self.heard_ns.all())

    def silent_boards(self, now_ns: int) -> list[str]:
        """Boards not heard from for longer than the silence timeout, counted in time and in our own cycles.

        Both clocks must agree: when the whole machine stalls (a virtual machine paused by its host), the
        driver's cycles stop too, and the boards get their cycles to answer once it resumes.
        """
        if not self.started_ns or now_ns - self.started_ns < max(self.silence_timeout_ns, STARTUP_GRACE_NS):
            return []
        cycles = self.counts["cycles"]
        silent = (now_ns - self.heard_ns > self.silence_timeout_ns) & (cycles - self.heard_cycle > self.silence_cycles)
        return [self.board_map.boards[i].name for i in np.flatnonzero(silent)]

    def _setpoints(self, now_ns: int) -> tuple[CommandMode, ActuatorCommand | None]:
        if self.estopped or self.safe_hold_reason or not self.enabled:
            return CommandMode.HOLD, None
        command, stamp_ns, version = self.command.try_get()
        if command is None or version <= 0:
            self.counts["no_command_cycles"] += 1
            return CommandMode.HOLD, None
        if now_ns - stamp_ns > self.command_timeout_ns:
            self.counts["stale_command_cycles"] += 1
            return CommandMode.HOLD, None
        lim = self.limits
        position = np.clip(command.position, lim.position_min, lim.position_max)
        velocity = np.clip(command.velocity, -lim.velocity_max, lim.velocity_max)
        effort = np.clip(command.effort, -lim.effort_max, lim.effort_max)
        clamped = (position != command.position) | (velocity != command.velocity) | (effort != command.effort)
        if clamped.any():
            self.clamped.update(self.board_map.boards[i].name for i in np.flatnonzero(clamped))
        return CommandMode.POSITION_FF, ActuatorCommand(position, velocity, effort)

    def cycle(self, now_ns: int, period_ns: int) -> ActuatorReadings:
        """Send this cycle's commands, take the telemetry that arrived, apply the silence rule; return the readings.

        The boards answer a command within their next cycle, so a reading is about one period old.
        """
        if not self.started_ns:
            self.started_ns = now_ns
            self.silence_cycles = max(1, -(-self.silence_timeout_ns // period_ns))
        mode, command = self._setpoints(now_ns)
        self.mode = mode
        n = len(self._addresses)
        zeros = np.zeros(n)
        if command is None:
            payloads = encode_commands(
                np.full(n, int(mode)), zeros, zeros, zeros, sequence=self.sequence, table=self._table
            )
        else:
            payloads = encode_commands(
                np.full(n, int(mode)),
                command.position,
                command.velocity,
                command.effort,
                sequence=self.sequence,
                table=self._table,
            )
        self.transport.send_frames(
            self._encoder.encode(address, payload) for address, payload in zip(self._addresses, payloads, strict=True)
        )
        self._sent_ns[self.sequence % len(self._sent_ns)] = now_ns
        self.counts["cycles"] += 1
        self._receive(time.monotonic_ns())
        self.sequence = (self.sequence + 1) & 0xFFFFFFFF
        silent = self.silent_boards(time.monotonic_ns())
        if silent and not self.safe_hold_reason:
            self.safe_hold_reason = f"boards silent for more than {self.silence_timeout_ns / 1e6:g} ms: {silent}"
            self.enabled = False
            self._on_event(f"safe hold: {self.safe_hold_reason}")
        return self.readings

    def _receive(self, now_ns: int) -> None:
        """Take every telemetry frame waiting (the boards answer each command within the cycle after it)."""
        for frame in self.transport.recv(timeout=0.0):
            index = self._index_of.get(frame.sender)
            if index is None:
                self.counts["unknown_sender_frames"] += 1
                continue
            try:
                telemetry = decode_telemetry(frame.payload, self.board_map.boards[index].scaling)
            except PayloadError:
                self.counts["bad_payloads"] += 1
                continue
            r = self.readings
            r.position[index], r.velocity[index], r.effort[index] = (
                telemetry.position,
                telemetry.velocity,
                telemetry.effort,
            )
            r.temperature[index], r.status[index], r.errors[index] = (
                telemetry.temperature,
                int(telemetry.status),
                int(telemetry.errors),
            )
            self.heard_ns[index] = now_ns
            self.heard_cycle[index] = self.counts["cycles"]
            sent_ns = self._sent_ns[telemetry.sequence % len(self._sent_ns)]
            if sent_ns and telemetry.sequence != self._echoed[index]:
                self._echoed[index] = telemetry.sequence
                self.latency.add(now_ns - sent_ns)
