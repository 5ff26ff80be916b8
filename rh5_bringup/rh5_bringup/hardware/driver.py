"""The driver's 1 kHz cycle, free of ROS: commands out to every board, telemetry back, safety rules.

Each cycle sends one COMMAND frame per actuator (``write``) and takes the TELEMETRY frames that
arrived (``read``). The stand-alone driver writes then reads (``cycle``); the control process
reads, computes the command from that telemetry, then writes (rh5_bringup.control.cycle).
Safety, in order of precedence:
- estop (latched until reset), a silent board (latched safe hold until re-enabled), not
  enabled, or a command older than ``command_timeout`` -> every board is told to HOLD;
- setpoints outside the stroke, velocity and force limits (or the wire's range) are clamped (and counted);
- non-finite commands are refused on arrival, and a cycle that finds one anyway sends HOLD;
- telemetry from addresses outside the board map is dropped and counted.
"""

from __future__ import annotations

import time
from collections import Counter
from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from rh5_bringup.hardware.ndlcom._framing import decode_telemetry_into, newest_payloads
from rh5_bringup.hardware.ndlcom.board_map import BoardMap
from rh5_bringup.hardware.ndlcom.codec import FrameEncoder
from rh5_bringup.hardware.ndlcom.command_frames import CommandFrames
from rh5_bringup.hardware.ndlcom.payloads import (
    MAX_MODE,
    TELEMETRY_LAYOUT,
    TELEMETRY_VERSION,
    TEMPERATURE_LSB,
    CommandMode,
    PayloadType,
)
from rh5_bringup.hardware.transports.base import Transport
from rh5_hyrodyn_mapper.kinematics.base import ActuatorLimits
from rh5_msgs_py.array_types import FloatArray
from rh5_msgs_py.realtime import LatencyWindow, LatestValue

STARTUP_GRACE_NS = 200_000_000  # the router learns where the driver is from its first commands
BOARD_CLOCK_RESTART_NS = 1_000_000_000  # the boards' clock going back this far is a restart, not a late frame


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


class DriverCore:
    """One driver cycle per call; requests (enable, estop) from any thread."""

    def __init__(
        self,
        board_map: BoardMap,
        transport: Transport,
        limits: ActuatorLimits,
        *,
        command_timeout_ns: int,
        silence_timeout_ns: int,
        on_event: Callable[[str], None] = lambda _text: None,
        clock_ns: Callable[[], int] = time.monotonic_ns,
        wall_clock_ns: Callable[[], int] = time.time_ns,
    ) -> None:
        self.clock_ns = clock_ns
        """Monotonic time [ns] for the safety rules and the latencies; a test passes a synthetic clock and replays
        seconds of the rules in milliseconds."""
        self.wall_clock_ns = wall_clock_ns
        """Wall time [ns] for the readings' stamps without a simulation clock."""
        self.board_map = board_map
        self.transport = transport
        self.limits = limits
        self.command_timeout_ns = command_timeout_ns
        self.silence_timeout_ns = silence_timeout_ns
        self._on_event = on_event
        self._table = board_map.scaling_table()
        self._lsb = np.ascontiguousarray(self._table.lsb, dtype=np.float64)  # (3, n): what the C decoding reads
        self._encoder = FrameEncoder(board_map.pc_address)
        self._frames = CommandFrames(self._encoder, board_map.addresses(), self._table)
        # setpoints are clamped to the actuator limits and to what the wire can carry, so every frame encodes
        low, high = limits.box
        self._box = (np.maximum(low, self._frames.low), np.minimum(high, self._frames.high))
        if len(board_map) >= 255:
            msg = f"{len(board_map)} boards: the telemetry sorting (newest_payloads) takes at most 254"
            raise ValueError(msg)
        board_of = bytearray([255] * 256)  # sender address -> board index (255: not a board of the map)
        for board in board_map:
            board_of[board.address] = board.index
        self._board_of = bytes(board_of)
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
        self._period_ns = 0
        self.counts: Counter[str] = Counter()
        self.clamped: Counter[str] = Counter()
        self.mode = CommandMode.HOLD
        self._checked_source: ActuatorCommand | None = None
        self._checked: tuple[ActuatorCommand | None, list[str]] = (None, [])
        self._sent_ns = np.zeros(256, dtype=np.int64)  # send time of the latest 256 sequence numbers
        self._echoed = np.full(n, -1, dtype=np.int64)
        self._echo_latencies = np.zeros(n, dtype=np.int64)  # one cycle's round trips (at most one per board)
        self.latency = LatencyWindow()
        self.read_ns = 0
        self.frames_read = 0
        self.board_time_ns = 0
        """The boards' clock in their newest telemetry (the simulated boards count the simulation's time): it only
        moves forward, unless it went back by more than BOARD_CLOCK_RESTART_NS (the boards' clock restarted)."""

    def stamp_ns(self, sim_time: bool) -> int:
        """The stamp of what this cycle read: under use_sim_time the simulated boards' clock, which counts the
        simulation's time as /clock does (the time the sample was measured), else wall time."""
        return self.board_time_ns if sim_time else self.wall_clock_ns()

    # --- requests ----------------------------------------------------------------------------------------------------

    def enable(self, on: bool) -> tuple[bool, str]:
        """Drive the setpoints (True) or let the boards hold (False); refused under estop or a silent board."""
        if on and self.estopped:
            return False, "refused: emergency stop is latched (call ~/reset_estop)"
        if on:
            silent = self.silent_boards(self.clock_ns())
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
        if now_ns - int(self.heard_ns.min()) <= self.silence_timeout_ns:
            return []  # the common case, in one reduction: every board heard recently
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
        if command is not self._checked_source:  # the same command object again: its check still holds
            self._checked_source, self._checked = command, self._check(command)
        checked, clamped_names = self._checked
        if checked is None:  # refused on arrival too; never on the wire
            self.counts["non_finite_command_cycles"] += 1
            return CommandMode.HOLD, None
        if clamped_names:
            self.clamped.update(clamped_names)
        return CommandMode.POSITION_FF, checked

    def _check(self, command: ActuatorCommand) -> tuple[ActuatorCommand | None, list[str]]:
        """A command clamped to the limits within the wire range, and which boards it clamped; None if not finite."""
        values = np.array(command)  # (3, n): position, velocity, effort; one pass for every check below
        if not np.isfinite(values).all():
            return None, []
        checked, clamped = self.limits.clamp(values, self._box)
        names = [self.board_map.boards[i].name for i in np.flatnonzero(clamped)] if clamped.any() else []
        return ActuatorCommand(*checked), names

    def _start(self, now_ns: int, period_ns: int) -> None:
        if not self.started_ns:
            self.started_ns = now_ns
            self._period_ns = period_ns
            self.silence_cycles = max(1, -(-self.silence_timeout_ns // period_ns))

    def set_silence_timeout(self, timeout_ns: int) -> None:
        """Change the silence rule at run time: from the next cycle on, in time and in cycles."""
        self.silence_timeout_ns = timeout_ns
        if self.started_ns:
            self.silence_cycles = max(1, -(-timeout_ns // self._period_ns))

    def cycle(self, now_ns: int, period_ns: int) -> ActuatorReadings:
        """The stand-alone driver's cycle: send the latest command (``write``), then take the telemetry (``read``).

        The boards answer a command within their next cycle, so a reading is about one period old.
        """
        self.write(now_ns, period_ns)
        return self.read(now_ns, period_ns)

    def read(self, now_ns: int, period_ns: int) -> ActuatorReadings:
        """Take every telemetry frame waiting and apply the silence rule; return the readings.

        ``read_ns`` is when this read began (what the telemetry-to-command latency counts from) and
        ``frames_read`` how many frames it took.
        """
        self._start(now_ns, period_ns)
        self.read_ns = self.clock_ns()
        self.frames_read = self._receive(self.read_ns)
        silent = self.silent_boards(self.clock_ns())
        if silent and not self.safe_hold_reason:
            self.safe_hold_reason = f"boards silent for more than {self.silence_timeout_ns / 1e6:g} ms: {silent}"
            self.enabled = False
            self._on_event(f"safe hold: {self.safe_hold_reason}")
        return self.readings

    def write(self, now_ns: int, period_ns: int) -> int:
        """Send one command frame per board: the setpoints of ``command``, or HOLD where a safety rule says so.

        Returns when the frames were handed to the transport (``clock_ns``).
        """
        self._start(now_ns, period_ns)
        mode, command = self._setpoints(now_ns)
        self.mode = mode
        if command is None:
            frames = self._frames.frames(mode, self.sequence)
        else:
            frames = self._frames.frames(mode, self.sequence, command.position, command.velocity, command.effort)
        self.transport.send_frames(frames)
        sent_ns = self.clock_ns()
        self._sent_ns[self.sequence % len(self._sent_ns)] = now_ns
        self.counts["cycles"] += 1
        self.sequence = (self.sequence + 1) & 0xFFFFFFFF
        return sent_ns

    def _receive(self, now_ns: int) -> int:
        """Take every telemetry frame waiting (the boards answer each command within the cycle after it) and
        decode the newest of each board into the readings; return how many frames were taken."""
        frames = self.transport.recv(timeout=0.0)
        if not frames:
            return 0
        counts = self.counts
        # the latest frame of each board with TELEMETRY v1's size, type and version, then its fields into the
        # readings (C: the cycle's per-frame work; payloads.decode_telemetry_of is the same decoding in numpy)
        order, payloads, unknown, bad = newest_payloads(
            frames, self._board_of, TELEMETRY_LAYOUT.size, PayloadType.TELEMETRY, TELEMETRY_VERSION
        )
        if unknown:
            counts["unknown_sender_frames"] += unknown
        if bad:
            counts["bad_payloads"] += bad
        if not order:
            return len(frames)
        r = self.readings
        invalid, board_time_us, echoes = decode_telemetry_into(
            payloads, order, self._lsb, r.position, r.velocity, r.effort, r.temperature, r.status, r.errors,
            self.heard_ns, self.heard_cycle, self._sent_ns, self._echoed, self._echo_latencies,
            now_ns, counts["cycles"], TEMPERATURE_LSB, MAX_MODE,
        )  # fmt: skip
        if invalid:
            counts["bad_payloads"] += invalid  # an unknown mode or a nonzero reserved field: dropped
        newest_ns = board_time_us * 1000
        if newest_ns > self.board_time_ns or self.board_time_ns - newest_ns > BOARD_CLOCK_RESTART_NS:
            self.board_time_ns = newest_ns  # forward, or a restarted clock (a new simulation): never a stale maximum
        if echoes:  # one round trip per board and command, however many times the board repeats it
            self.latency.add_many(self._echo_latencies[:echoes])
        return len(frames)
