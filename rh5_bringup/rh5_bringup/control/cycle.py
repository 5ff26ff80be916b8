"""One control cycle, as ros2_control's read -> update -> write: every command from the same cycle's telemetry.

Per period, in order:
1. read: take the boards' telemetry (``DriverCore.read``: silence rule included);
2. map actuator -> joint space (``MapperCore.to_joint_state``: refusals included);
3. run the stabilizer on that measurement;
4. map joint -> actuator space with the limits (``MapperCore.to_actuator_command``: clamps and refusals);
5. write: one command frame per board (``DriverCore.write``: estop, safe hold, enable, staleness, limits).

A step whose input did not change since the last cycle (no new telemetry; the same command) reuses its
last result instead of mapping again: on the robot every cycle brings new telemetry, in a simulation
slower than real time most do not. Nothing here waits on ROS: the cycle hands what the topics need to a
``RealtimePublisher`` and goes on.
The safety rules stay where they live, in the driver's, mapper's and stabilizer's cores.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from rh5_bringup.hardware.driver import ActuatorCommand, DriverCore
from rh5_bringup.hardware.ndlcom.payloads import CommandMode
from rh5_hyrodyn_mapper.mapper_core import MapperCore
from rh5_hyrodyn_mapper.mapping import JointSample
from rh5_joint_stabilizer.controller import Command, Measurement
from rh5_msgs_py.array_types import FloatArray
from rh5_msgs_py.realtime import LatencyWindow

Triple = tuple[FloatArray, FloatArray | None, FloatArray | None]
STAGES = ("read", "to_joints", "stabilize", "to_actuators", "write")


class CycleSample(NamedTuple):
    """What one cycle measured and sent, for the topics (position, velocity, effort each; None: not this cycle)."""

    stamp_ns: int
    """The stamp of every message the cycle produces: wall time, or the boards' (simulated) time under use_sim_time."""
    actuator_states: Triple | None
    joint_states: Triple | None
    joint_commands: Triple | None
    actuator_commands: Triple | None
    stabilizer_state_changed: bool


def _same(a: Triple, b: Triple | None) -> bool:
    """Whether two (position, velocity, effort) triples hold equal values (NaN never equals: always recomputed)."""
    return b is not None and all(
        x is y or (x is not None and y is not None and np.array_equal(x, y)) for x, y in zip(a, b, strict=True)
    )


class ControlCycle:
    """The composed 1 kHz cycle over the driver's, mapper's and stabilizer's cores."""

    def __init__(
        self,
        driver: DriverCore,
        mapper: MapperCore,
        stabilize: Callable[[int, int, Measurement | None], Command | None],
        *,
        estop_to_stabilizer: Callable[[bool], None],
        state_changed: Callable[[], bool] = lambda: False,
        hand_off: Callable[[CycleSample], bool] | None = None,
        stamp: Callable[[], int] = time.time_ns,
        board_time: Callable[[int], None] | None = None,
    ) -> None:
        self.driver = driver
        self.mapper = mapper
        self._stabilize = stabilize
        self._estop_to_stabilizer = estop_to_stabilizer
        self._state_changed = state_changed
        self._hand_off = hand_off
        self._stamp = stamp
        """The stamp of the cycle's messages: wall time, or the simulation's time under use_sim_time."""
        self._board_time = board_time
        """Hears the boards' clock after each read (the process's ROS clocks follow it under use_sim_time)."""
        self.telemetry_to_command = LatencyWindow()
        """From the read that took the telemetry to the hand-over of the commands computed from it (ns)."""
        self.compute = LatencyWindow()
        """Duration of the whole cycle, read to write (ns)."""
        self.stages = {name: LatencyWindow() for name in STAGES}
        self.cpu = LatencyWindow()
        """CPU time of the cycle's thread per cycle (ns): wall time beyond it is waiting (interpreter lock, host)."""
        """Duration of each step of the cycle (ns), to see where a long cycle spent its time."""
        self.measurement: Measurement | None = None
        self._actuator_states: Triple | None = None
        self._joints: JointSample | None = None
        self._mapped_command: Triple | None = None
        self._actuator_command: ActuatorCommand | None = None

    def _to_actuators(self, joint_command: Triple) -> ActuatorCommand | None:
        """The actuator setpoints of a joint command within the limits (None: refused by the mapper)."""
        actuators = self.mapper.to_actuator_command(*joint_command)
        if actuators is None:
            return None
        n = len(actuators.position)
        velocity = actuators.velocity if actuators.velocity is not None else np.zeros(n)
        effort = actuators.effort if actuators.effort is not None else np.zeros(n)
        return ActuatorCommand(actuators.position, velocity, effort)

    def step(self, now_ns: int, period_ns: int) -> None:
        """Run one cycle: read, map, stabilise, map, write; then hand the cycle's data to the publisher."""
        driver, clock, stages = self.driver, time.monotonic_ns, self.stages
        cpu0 = time.thread_time_ns()
        readings = driver.read(now_ns, period_ns)
        t_read = clock()
        stages["read"].add(t_read - now_ns)
        if self._board_time is not None:
            self._board_time(driver.board_time_ns)
        self._estop_to_stabilizer(driver.estopped)
        actuator_states = joint_states = joint_commands = actuator_commands = None
        self.measurement = None
        if driver.all_heard:  # before every board has answered, part of the readings would be made-up zeros
            if driver.frames_read or self._joints is None:  # unchanged readings map to the same joint state
                self._actuator_states = (readings.position.copy(), readings.velocity.copy(), readings.effort.copy())
                self._joints = self.mapper.to_joint_state(*self._actuator_states)
            actuator_states, joints = self._actuator_states, self._joints
            if joints is not None:
                joint_states = (joints.position, joints.velocity, joints.effort)
                velocity = joints.velocity if joints.velocity is not None else np.zeros_like(joints.position)
                # as old as the least recently heard board: one silent board makes the measurement stale
                self.measurement = Measurement(joints.position, velocity, int(driver.heard_ns.min()))
        t_map = clock()
        stages["to_joints"].add(t_map - t_read)
        command = self._stabilize(now_ns, period_ns, self.measurement)
        t_stabilize = clock()
        stages["stabilize"].add(t_stabilize - t_map)
        if command is not None:
            joint_commands = (command.position, command.velocity, command.effort)
            if not _same(joint_commands, self._mapped_command):  # an unchanged command maps to the same setpoints
                self._mapped_command = joint_commands
                self._actuator_command = self._to_actuators(joint_commands)
            if self._actuator_command is not None:
                driver.command.set(self._actuator_command, now_ns)
                actuator_commands = tuple(self._actuator_command)
        t_map = clock()
        stages["to_actuators"].add(t_map - t_stabilize)
        sent_ns = driver.write(now_ns, period_ns)
        stages["write"].add(sent_ns - t_map)
        if actuator_commands is not None and driver.frames_read and driver.mode is CommandMode.POSITION_FF:
            self.telemetry_to_command.add(sent_ns - driver.read_ns)
        self.compute.add(clock() - now_ns)
        self.cpu.add(time.thread_time_ns() - cpu0)
        if self._hand_off is not None:
            self._hand_off(
                CycleSample(
                    self._stamp(),
                    actuator_states,
                    joint_states,
                    joint_commands,
                    actuator_commands,
                    self._state_changed(),
                )
            )
