"""The simulated-hardware node: every actuator board of RH5, emulated at the protocol level.

It listens where the central router would (UDP, or CAN through python-can), decodes the
driver's NDLCom commands, runs the motor, transmission and cascaded-loop model of every
actuator in a dedicated thread, and answers every command burst at once with telemetry
(ticking every 1 ms on its own when no command comes).
Kinematic mode: the actuators move free of whole-body physics, starting in the nominal
standing pose. Physics mode: the actuators drive the floating-base RH5 in PyBullet on flat
ground (rh5_bringup.sim.physics: coupling, contacts, armature), held by a crane until
``~/release_support``; the true base pose and foot wrenches are published at
``ground_truth_rate_hz``. Faults are injected through parameters (see params/sim_hardware.yaml).

Time: the boards step whole 1 ms cycles of the time that passed (physics: two 0.5 ms rigid-body steps
each). A stall is not replayed (counted as ``counts.time_not_replayed_us``), so when the host cannot keep
up the simulation runs slower than real time. Physics mode does, on a 2-core machine: the coupled step
with the armature correction costs ~1.3 ms of CPU per simulated ms next to the rest of the suite (measured:
0.21-0.23 x real time in `rh5 experiment`; 0.14-0.16 while it published each ground-truth sample up to six
times). It then publishes /clock (``publish_clock``), and whatever plays a trajectory against it follows that
clock (the stabilizer with use_sim_time:=true and playback_clock:=ros; ``rh5 experiment`` sets both); the
nodes' 1 kHz loops, staleness rules and message stamps stay on wall time.
In physics mode the boards also step only when the driver's commands come (``pace_by_commands``): a driver
stalled by the host (loop jitter up to 0.2 s measured here) then pauses the simulated time instead of the
robot walking on for tens of simulated ms on stale setpoints and its boards' 20 ms watchdog holding the
joints mid-step; after 0.5 s of silence the boards tick on their own again.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np
from std_srvs.srv import Trigger

from rh5_bringup.hardware.ndlcom.board_map import load_board_map
from rh5_bringup.hardware.transports import open_transport
from rh5_bringup.sim.actuators import ActuatorBank
from rh5_bringup.sim.boards import BoardEmulator, BoardsServer, Faults
from rh5_bringup.sim.physics import PhysicsActuatorBank, build_physics
from rh5_hyrodyn_mapper.mapping import robot_mapper
from rh5_msgs_py import interfaces
from rh5_msgs_py.conversions import Level, Status, diagnostics_to_msg, to_time_msg, wrench_to_msg
from rh5_msgs_py.diagnostic_keys import PHYSICS_TASK
from rh5_msgs_py.diagnostic_tasks import Increases, task_status
from rh5_msgs_py.names import ACTUATOR_NAMES, FOOT_FRAMES, NUM_JOINTS
from rh5_msgs_py.node_runtime import SuiteNode, run_node
from rh5_msgs_py.realtime import pin_process

DIAGNOSTICS_PERIOD_S = 1.0
SLOW_SIMULATION = 0.5
"""Below this fraction of real time (over one report period) ``sim_hardware: physics`` warns."""
PHYSICS_MAX_CATCH_UP_NS = 1_000_000
"""Physics mode: a late cycle steps 1 ms, never more. A physics cycle costs 0.3-0.7 ms of CPU here; replaying
3 ms after a stall costs more than 1 ms, so the next cycle is late again (measured: 3 ms periods, 230 Hz).
Without replay, simulated time falls behind the wall clock by the stalls (counted as time_not_replayed_us)."""


class SimHardwareNode(SuiteNode):
    """Stand-in for the FPGA boards and the robot."""

    def __init__(self) -> None:
        super().__init__(interfaces.SIM_HARDWARE_NODE, "rh5_bringup", "params/sim_hardware.yaml")
        params = self.params
        unknown = set(params["silent_boards"]) - set(ACTUATOR_NAMES)
        if unknown:
            msg = f"parameter silent_boards: unknown actuators {sorted(unknown)}"
            raise ValueError(msg)
        if params["cpu_affinity"]:  # before the boards' thread starts: it inherits the CPUs
            self.get_logger().info(f"simulated hardware on CPUs {pin_process(params['cpu_affinity'])}")
        board_map = load_board_map()
        if params["transport"] == "udp":
            transport = open_transport(
                "udp", local=(params["listen_host"], params["listen_port"]), receivers=board_map.addresses()
            )
        else:
            transport = open_transport("can", interface="virtual", channel="rh5", receivers=board_map.addresses())
        self.transport = transport
        self.physics: PhysicsActuatorBank | None = None
        bank: Any
        if params["mode"] == "physics":
            bank = self.physics = self._start_physics(params)
        else:
            bank = ActuatorBank()
            bank.reset(robot_mapper().to_actuators(np.zeros(NUM_JOINTS)).position)
        faults = Faults(
            drop_rate=params["drop_rate"],
            delay_s=params["delay_s"],
            corrupt_crc_rate=params["corrupt_crc_rate"],
            silent_boards=frozenset(params["silent_boards"]),
            sensor_noise_std=params["sensor_noise_std"],
        )
        self.emulator = BoardEmulator(board_map, transport, bank, faults)
        if self.physics is not None:  # no replay of a stall: the simulation falls behind instead
            self.emulator.max_catch_up_ns = PHYSICS_MAX_CATCH_UP_NS
            self.emulator.pace_by_commands = params["pace_by_commands"]
        update = lambda _: self._update_faults  # noqa: E731 (the faults are rebuilt from all their parameters)
        self.apply_live(
            {
                "drop_rate": update,
                "delay_s": update,
                "corrupt_crc_rate": update,
                "sensor_noise_std": update,
                "silent_boards": self._check_silent_boards,
            }
        )
        self.server = BoardsServer(self.emulator)
        self.context.on_shutdown(self.server.stop)
        self.server.start()
        self._publish_diagnostics = self.advertise(interfaces.DIAGNOSTICS)
        self._increases = Increases()
        self._last_report = (time.monotonic(), self.physics.world.time if self.physics is not None else 0.0)
        self.create_wall_timer(DIAGNOSTICS_PERIOD_S, self._publish_status)

    def _start_physics(self, params: dict[str, Any]) -> PhysicsActuatorBank:
        """The PyBullet world coupled to the boards (stepped under a lock: PyBullet is not thread-safe), its
        ground-truth publishers, the crane's release service and, if asked for, /clock."""
        initial = list(params["initial_joint_positions"])
        if initial and len(initial) != NUM_JOINTS:
            msg = f"parameter initial_joint_positions: {len(initial)} values, expected {NUM_JOINTS} or none"
            raise ValueError(msg)
        physics = build_physics(
            params["friction_coefficient"],
            params["hand_payload_kg"],
            np.array(initial, dtype=np.float64) if initial else None,
            support=params["support"],
            tune_to_load=params["tune_boards_to_load"],
        )
        xy = list(params["initial_base_xy"])
        if xy:
            if len(xy) != 2:
                msg = f"parameter initial_base_xy: {len(xy)} values, expected 2 (x, y) or none"
                raise ValueError(msg)
            physics.world.shift_base_xy(np.array(xy, dtype=np.float64))
        self._publish_pose = self.advertise(interfaces.SIM_BASE_POSE)
        self._publish_wrench = {
            "left": self.advertise(interfaces.SIM_WRENCH_LEFT),
            "right": self.advertise(interfaces.SIM_WRENCH_RIGHT),
        }
        self._publish_clock = self.advertise(interfaces.CLOCK) if params["publish_clock"] else None
        self.create_service(Trigger, interfaces.RELEASE_SUPPORT_SERVICE, self._release_support)
        physics.ground_truth_every = max(1, round(1.0 / (params["ground_truth_rate_hz"] * physics.world.time_step)))
        physics.snapshot()
        self._ground_truth_version = 0  # of the last sample published
        self.create_wall_timer(1.0 / params["ground_truth_rate_hz"], self._publish_ground_truth)
        self.get_logger().info(
            f"physics: {physics.world.total_mass:.2f} kg, friction {params['friction_coefficient']}, "
            f"support {'on' if params['support'] else 'off'}"
        )
        return physics

    def _release_support(self, _request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        """Let the crane go: from now on the robot stands on its own feet (or falls)."""
        assert self.physics is not None
        with self.physics.lock:
            released = self.physics.world.release_support()
        response.success = released
        response.message = "support released" if released else "the base was not supported"
        self.get_logger().info(response.message)
        return response

    def _publish_ground_truth(self) -> None:
        """The true base pose (frame "world") and each foot's contact wrench (in and about its sole frame), and
        /clock: each sample the physics took (every 1 / ground_truth_rate_hz of simulated time) once. The timer
        runs on the wall clock, and a simulation slower than real time would otherwise publish the same sample
        several times (at 0.17 x real time six), to the recorder and every /clock subscriber."""
        assert self.physics is not None
        from geometry_msgs.msg import PoseStamped  # noqa: PLC0415 - physics mode only

        truth, _, version = self.physics.ground_truth.try_get()  # taken by the boards thread: no lock, no PyBullet
        if truth is None or version == self._ground_truth_version:
            return
        self._ground_truth_version = version
        pose, wrenches = truth.base, truth.wrenches
        # publishing /clock, the simulation's time is the clock: each sample carries the time it was taken at
        now_ns = truth.sim_ns if self._publish_clock is not None else self.get_clock().now().nanoseconds
        msg = PoseStamped()
        to_time_msg(now_ns, msg.header.stamp)
        msg.header.frame_id = "world"
        p, o = pose.position.tolist(), pose.orientation.tolist()
        msg.pose.position.x, msg.pose.position.y, msg.pose.position.z = p
        o_msg = msg.pose.orientation
        o_msg.x, o_msg.y, o_msg.z, o_msg.w = o
        self._publish_pose(msg)
        for side, wrench in wrenches.items():
            self._publish_wrench[side](wrench_to_msg(np.concatenate(wrench.in_sole_frame()), FOOT_FRAMES[side], now_ns))
        if self._publish_clock is not None:
            from rosgraph_msgs.msg import Clock  # noqa: PLC0415

            clock = Clock()  # the sample's simulated time: the physics may have stepped on since it was taken
            to_time_msg(truth.sim_ns, clock.clock)
            self._publish_clock(clock)

    def task_statuses(self) -> list[Status]:
        """``sim_hardware: physics`` (WARN when the simulation runs slower than SLOW_SIMULATION x real time; ERROR
        when the physics fails to step) or, without physics, ``sim_hardware: boards``; both name the faults on."""
        faults = self.emulator.faults
        values: dict[str, object] = {
            "drop_rate": faults.drop_rate,
            "silent_boards": ", ".join(sorted(faults.silent_boards)) or "none",
        }
        if self.physics is None:
            return [task_status("sim_hardware", "boards", Level.OK, "kinematic boards running", values)]
        wall, sim = time.monotonic(), self.physics.world.time
        last_wall, last_sim = self._last_report
        self._last_report = (wall, sim)
        factor = (sim - last_sim) / (wall - last_wall) if wall > last_wall else 0.0
        errors = int(self._increases("kinematics_errors", self.physics.counts.kinematics_errors))
        values.update({"real_time_factor": round(factor, 3), "sim_time_s": round(sim, 3), "new_errors": errors})
        values["supported"] = self.physics.world.supported
        if errors:
            level, text = Level.ERROR, "physics step failed"
        elif factor < SLOW_SIMULATION:
            level, text = Level.WARN, "simulation slower than real time"
        else:
            level, text = Level.OK, "running"
        return [task_status(interfaces.SIM_HARDWARE_NODE, PHYSICS_TASK, level, text, values)]

    def _publish_status(self) -> None:
        statuses = self.task_statuses()
        self._publish_diagnostics(diagnostics_to_msg(statuses, stamp_ns=self.stamp_ns()))

    def _check_silent_boards(self, names: list[str]) -> Callable[[], None]:
        """Refuse actuator names the robot does not have (a misspelt board would silently stay alive)."""
        if unknown := set(names) - set(ACTUATOR_NAMES):
            msg = f"unknown actuators {sorted(unknown)}"
            raise ValueError(msg)
        return self._update_faults

    def _update_faults(self) -> None:
        """Fault-injection parameters act at once (validated before they were accepted)."""
        params = self.params
        self.emulator.set_faults(
            Faults(
                drop_rate=params["drop_rate"],
                delay_s=params["delay_s"],
                corrupt_crc_rate=params["corrupt_crc_rate"],
                silent_boards=frozenset(params["silent_boards"]),
                sensor_noise_std=params["sensor_noise_std"],
            )
        )
        self.get_logger().info(f"faults now: {self.emulator.faults}")

    def summary(self) -> dict[str, Any]:
        """Adds the simulation mode, frame counts and loop timing to the base summary."""
        summary = {
            **super().summary(),
            "mode": self.params["mode"],
            "boards_emulated": len(self.emulator.board_map),
            "counts": dict(self.emulator.counts),
            "superseded_datagrams": self.emulator.transport.stats().superseded_chunks,
            "loop": self.server.stats().as_dict(),
        }
        if self.physics is not None:
            counts = self.physics.counts
            summary["physics"] = {
                "physics_steps": counts.physics_steps,
                "dropped_steps": counts.dropped_steps,
                "kinematics_errors": counts.kinematics_errors,
                "sim_time_s": self.physics.world.time,
                "supported": self.physics.world.supported,
            }
        return summary

    def destroy_node(self) -> None:
        """Stop the loop, then close the link."""
        self.server.stop()
        self.transport.shutdown()
        if self.physics is not None:
            with self.physics.lock:
                self.physics.world.close()
        super().destroy_node()


def main(args: list[str] | None = None) -> None:
    """Entry point of ``ros2 run rh5_bringup sim_hardware_node``."""
    run_node(SimHardwareNode, args)
