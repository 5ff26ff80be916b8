"""Drive the boards without ROS: a DriverCore loop feeding a sine to every actuator and recording what comes back.

Used by the hardware-layer tests and bench/driver.py against the simulated boards (in this
process through ``sim.boards.BoardsServer``, or the sim_hardware node in its own process)
and, with care, against a real robot on its stand.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

import numpy as np

from rh5_bringup.hardware.driver import ActuatorCommand, DriverCore
from rh5_bringup.hardware.ndlcom.board_map import BoardMap
from rh5_bringup.hardware.transports.base import Transport
from rh5_hyrodyn_mapper.kinematics.base import ActuatorLimits
from rh5_msgs_py.names import ACTUATOR_NAMES, LINEAR_ACTUATOR_NAMES
from rh5_msgs_py.realtime import DeadlineLoop

N = len(ACTUATOR_NAMES)
LINEAR = np.array([name in LINEAR_ACTUATOR_NAMES for name in ACTUATOR_NAMES])
SINE_AMPLITUDE = np.where(LINEAR, 0.005, 0.05)  # 5 mm on the linear actuators, 0.05 rad on the rotary drives


def sine_centre(standing: np.ndarray, limits: ActuatorLimits, amplitude: np.ndarray = SINE_AMPLITUDE) -> np.ndarray:
    """The standing pose moved inside every stroke far enough for the sine (the straight knee sits at its end)."""
    return np.clip(standing, limits.length_min + 2 * amplitude, limits.length_max - 2 * amplitude)


class DriverLoop:
    """A DriverCore in its own deadline loop, commanding ``centre + offset + A sin(2 pi f t)`` (with its
    velocity as feed-forward, as the mapper sends it) and recording reference and readings."""

    def __init__(
        self,
        board_map: BoardMap,
        transport: Transport,
        limits: ActuatorLimits,
        centre: np.ndarray,
        *,
        rate_hz: float = 1000.0,
        sine_hz: float = 0.5,
        silence_timeout_ns: int = 5_000_000,
        command_timeout_ns: int = 20_000_000,
        seconds_kept: float = 70.0,
    ) -> None:
        self.events: list[tuple[int, str]] = []
        self.core = DriverCore(
            board_map,
            transport,
            limits,
            command_timeout_ns=command_timeout_ns,
            silence_timeout_ns=silence_timeout_ns,
            on_event=lambda text: self.events.append((time.monotonic_ns(), text)),
        )
        self.centre = centre
        self.offset = np.zeros(N)
        self.sine_hz = sine_hz
        self.commanding = True
        self.on_cycle: Callable[[int], None] | None = None
        capacity = int(seconds_kept * rate_hz)  # preallocated: a growing list of arrays makes the GC pause the loop
        self._times = np.zeros(capacity, dtype=np.int64)
        self._references = np.zeros((capacity, N))
        self._measured = np.zeros((capacity, N))
        self._count = 0
        self._t0 = time.monotonic_ns()
        self._lock = threading.Lock()
        self.loop = DeadlineLoop(rate_hz, self._cycle, "rig-driver")

    def reference(self, now_ns: int) -> tuple[np.ndarray, np.ndarray]:
        """Position and velocity of the commanded sine at ``now_ns``."""
        w = 2 * np.pi * self.sine_hz
        t = (now_ns - self._t0) / 1e9
        return self.centre + self.offset + SINE_AMPLITUDE * np.sin(w * t), SINE_AMPLITUDE * w * np.cos(w * t)

    def _cycle(self, now_ns: int, period_ns: int) -> None:
        position, velocity = self.reference(now_ns)
        if self.commanding:
            self.core.command.set(ActuatorCommand(position, velocity, np.zeros(N)), now_ns)
        readings = self.core.cycle(now_ns, period_ns)
        with self._lock:
            k = self._count % len(self._times)
            self._times[k], self._references[k], self._measured[k] = now_ns, position, readings.position
            self._count += 1
        if self.on_cycle is not None:
            self.on_cycle(now_ns)

    def history(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Times, references and readings of the cycles kept so far (oldest first)."""
        with self._lock:
            n, size = min(self._count, len(self._times)), len(self._times)
            order = np.arange(self._count - n, self._count) % size
            return self._times[order], self._references[order], self._measured[order]

    def tracking_error(self, skip_s: float = 1.0, percentile: float = 100.0) -> np.ndarray:
        """|reference - reading| per actuator after the first ``skip_s`` seconds: the max, or a percentile."""
        t, ref, measured = self.history()
        keep = t - t[0] > skip_s * 1e9
        return np.percentile(np.abs(ref[keep] - measured[keep]), percentile, axis=0)
