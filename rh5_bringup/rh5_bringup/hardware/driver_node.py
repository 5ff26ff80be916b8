"""The driver node: the 1 kHz link between the ROS graph and the actuator boards (NDLCom over UDP or CAN).

A dedicated loop thread runs DriverCore every millisecond and publishes ``actuator_states``
each cycle; ``actuator_commands`` are validated in their callback and handed to the loop
through a latest-value slot. ``~/enable`` (SetBool), ``~/estop`` (latching) and
``~/reset_estop`` switch what the boards are told; the latch is also published on
``driver/estopped``.

It is a lifecycle node, as ros2_control's hardware drivers are (``~/change_state``; send transitions by
label): configure opens the link (rh5_bringup.hardware.driver_link) and checks that every board of the board map
answers; activate drives the boards; deactivate makes every board hold; cleanup and shutdown hold and close
the link; an error holds and closes it. The emergency stop stays latching and independent of the lifecycle.
Parameter ``autostart`` makes the first transitions by itself (default: configure).
``/diagnostics`` at 1 Hz: loop timing, safety state, per-board frame
statistics and errors.
"""

from __future__ import annotations

import time
from typing import Any, Final

import numpy as np
from rclpy._rclpy_pybind11 import RCLError
from rclpy.lifecycle import LifecycleNodeMixin, LifecycleState, TransitionCallbackReturn
from std_msgs.msg import Bool
from std_srvs.srv import SetBool, Trigger

from rh5_bringup.hardware.driver import ActuatorCommand, DriverCore
from rh5_bringup.hardware.driver_link import SwitchableLink
from rh5_bringup.hardware.ndlcom.board_map import load_board_map
from rh5_bringup.hardware.transports import open_transport
from rh5_hyrodyn_mapper.kinematics.base import ActuatorLimits
from rh5_hyrodyn_mapper.mapping import robot_mapper
from rh5_msgs_py import interfaces
from rh5_msgs_py.conversions import JointStateCodec, Level, Status, diagnostics_to_msg
from rh5_msgs_py.diagnostic_keys import DRIVER_STATUS, HARDWARE_ID, DriverKeys, LoopKeys
from rh5_msgs_py.diagnostic_tasks import Increases, task_status
from rh5_msgs_py.names import ACTUATOR_NAMES
from rh5_msgs_py.node_runtime import SuiteNode, run_node
from rh5_msgs_py.realtime import DeadlineLoop

DIAGNOSTICS_PERIOD_S: Final = 1.0


def actuator_limits() -> ActuatorLimits:
    """The stroke, speed and force limits of every actuator (the mapper's, from the paper's tables)."""
    return robot_mapper().limits


NO_SILENCE_RULE_NS: Final = 10**18
"""The silence rule's timeout while the link is closed: boards that cannot be heard are not silent."""


class DriverNode(SuiteNode, LifecycleNodeMixin):
    """ROS wiring around DriverCore and its 1 kHz loop.

    ``composed=True``: hosted by the control process (rh5_bringup.control.node), whose cycle reads and
    writes ``core`` itself and publishes ``actuator_states``; the node then runs no loop and takes no
    ``actuator_commands``.
    """

    def __init__(self, *, composed: bool = False) -> None:
        super().__init__(interfaces.DRIVER_NODE, "rh5_bringup", "params/driver.yaml")
        params = self.params
        board_map = load_board_map(params["board_map"] or None)

        def open_link() -> Any:
            if params["transport"] == "udp":
                host = params["router_host"]
                local = (
                    "127.0.0.1" if host.startswith("127.") else "0.0.0.0",
                    0,
                )  # any interface: the router is on the robot network
                return open_transport(
                    "udp", local=local, remote=(host, params["router_port"]), receivers=[board_map.pc_address]
                )
            return open_transport(
                "can",
                interface=params["can_interface"],
                channel=params["can_channel"],
                receivers=[board_map.pc_address],
            )

        self.transport = self.link = SwitchableLink(open_link)
        self._silence_ns = int(params["board_silence_timeout_s"] * 1e9)
        self.core = DriverCore(
            board_map,
            self.link,
            actuator_limits(),
            command_timeout_ns=int(params["command_timeout_s"] * 1e9),
            silence_timeout_ns=NO_SILENCE_RULE_NS,
            on_event=self._on_event,
        )
        self._command_codec = JointStateCodec(ACTUATOR_NAMES, what="actuator_commands")
        self.state_codec = JointStateCodec(ACTUATOR_NAMES)
        if not composed:  # composed: the control process's stream publisher sends them
            self.publish_states = self.advertise(interfaces.ACTUATOR_STATES)
        self._publish_estop = self.advertise(interfaces.DRIVER_ESTOP)
        self._publish_diagnostics = self.advertise(interfaces.DIAGNOSTICS)
        self._publish_estop(Bool(data=False))
        if not composed:
            self.subscribe_stream(interfaces.ACTUATOR_COMMANDS, self._on_command)
        self.create_service(SetBool, interfaces.ENABLE_SERVICE, self._on_enable)
        self.create_service(Trigger, interfaces.ESTOP_SERVICE, self._on_estop)
        self.create_service(Trigger, interfaces.RESET_ESTOP_SERVICE, self._on_reset_estop)
        if not composed:  # composed: the control node publishes every hosted node's status on one timer
            self.create_wall_timer(DIAGNOSTICS_PERIOD_S, self.publish_status)
        self._increases = Increases()
        core = self.core
        self.apply_live(
            {
                "command_timeout_s": lambda s: lambda: setattr(core, "command_timeout_ns", int(s * 1e9)),
                "board_silence_timeout_s": lambda s: lambda: self._set_silence(int(s * 1e9)),
            }
        )
        self.loop: DeadlineLoop | None = None
        if not composed:
            self.loop = self.start_loop(params["rate_hz"], self._tick, "driver-1kHz", params["realtime_priority"])
        LifecycleNodeMixin.__init__(self, enable_communication_interface=True)
        self._guard_change_state()
        self._autostart: Any = None
        if params["autostart"] != "none":
            self._autostart = self.create_wall_timer(0.01, self._start_up)

    # --- lifecycle -------------------------------------------------------------------------------------------------

    def _guard_change_state(self) -> None:
        """A transition requested by an id the current state does not have raises out of rclpy's service callback
        (rclpy#1209) and would end the process: answer it with success=false instead."""
        service = self._service_change_state
        original = service.callback

        def guarded(request: Any, response: Any) -> Any:
            try:
                return original(request, response)
            except RCLError as err:
                self.get_logger().warning(f"lifecycle transition refused: {err}")
                response.success = False
                return response

        service.callback = guarded

    def _start_up(self) -> None:
        """The autostart transitions, once, from the executor (after the node is fully built); an ~/enable that
        comes first runs them before it is answered."""
        if self._autostart is None:
            return
        self._autostart.cancel()
        self.destroy_timer(self._autostart)
        self._autostart = None
        if self.trigger_configure() == TransitionCallbackReturn.SUCCESS and self.params["autostart"] == "activate":
            self.trigger_activate()

    def _set_silence(self, timeout_ns: int) -> None:
        self._silence_ns = timeout_ns
        if self.link.is_open:
            self.core.set_silence_timeout(timeout_ns)

    def on_configure(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Open the link and wait until every board of the board map has answered (FAILURE: closed again)."""
        del state
        try:
            self.link.open()
        except (OSError, ValueError) as err:
            self.get_logger().error(f"configure: cannot open the link to the boards: {err}")
            return TransitionCallbackReturn.FAILURE
        core = self.core
        core.heard_ns[:] = 0  # only answers from now on count
        deadline = time.monotonic() + self.params["configure_timeout_s"]
        while not core.all_heard and time.monotonic() < deadline:
            time.sleep(0.01)
        if not core.all_heard:
            silent = [b.name for b in core.board_map if not core.heard_ns[b.index]]
            self.link.close()
            self.get_logger().error(f"configure: boards did not answer: {silent}")
            return TransitionCallbackReturn.FAILURE
        core.set_silence_timeout(self._silence_ns)
        self.get_logger().info(f"configured: all {len(core.board_map)} boards answer")
        return TransitionCallbackReturn.SUCCESS

    def on_activate(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Drive the boards (refused under the estop or with a silent board)."""
        del state
        ok, reason = self.core.enable(True)
        if not ok:  # one severity per call site (rclpy refuses a change)
            self.get_logger().error(f"activate: {reason}")
            return TransitionCallbackReturn.FAILURE
        self.get_logger().info(f"activate: {reason}")
        return TransitionCallbackReturn.SUCCESS

    def on_deactivate(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Every board holds."""
        del state
        self.core.enable(False)
        return TransitionCallbackReturn.SUCCESS

    def _hold_and_close(self) -> TransitionCallbackReturn:
        self.core.enable(False)
        self.core.set_silence_timeout(NO_SILENCE_RULE_NS)
        self.link.close()
        return TransitionCallbackReturn.SUCCESS

    def on_cleanup(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Hold, then close the link."""
        del state
        return self._hold_and_close()

    def on_shutdown(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Hold, then close the link."""
        del state
        return self._hold_and_close()

    def on_error(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Safe hold: every board holds, the link closes; the node goes back to unconfigured."""
        self.get_logger().error(f"lifecycle error in state {state.label}: holding and closing the link")
        return self._hold_and_close()

    def _on_event(self, text: str) -> None:
        self.get_logger().error(text)

    def _on_command(self, msg: Any) -> None:
        try:
            position, velocity, effort = self._command_codec.decode(msg)
        except ValueError as err:
            self.core.counts["rejected_commands"] += 1
            self.get_logger().warning(f"actuator_commands rejected: {err}", throttle_duration_sec=1.0)
            return
        n = len(ACTUATOR_NAMES)
        velocity = np.zeros(n) if velocity is None else velocity
        effort = np.zeros(n) if effort is None else effort
        if position is None or not all(np.isfinite(x).all() for x in (position, velocity, effort)):
            self.core.counts["rejected_commands"] += 1
            self.get_logger().warning(
                "actuator_commands rejected: missing positions, NaN or inf", throttle_duration_sec=1.0
            )
            return
        self.core.command.set(ActuatorCommand(position, velocity, effort), time.monotonic_ns())

    def _tick(self, now_ns: int, period_ns: int) -> None:
        readings = self.core.cycle(now_ns, period_ns)
        if not self.core.all_heard:
            self.core.counts["cycles_before_all_heard"] += 1
            return  # no actuator_states until every board has reported once (no made-up zeros downstream)
        stamp_ns = self.core.stamp_ns(self.sim_time)
        self.publish_states(
            self.state_codec.encode(readings.position, readings.velocity, readings.effort, stamp_ns=stamp_ns)
        )

    def _on_enable(self, request: Any, response: Any) -> Any:
        self._start_up()  # an enable right after start-up: the node configures itself first (autostart)
        if request.data and not self.link.is_open:
            response.success, response.message = False, "refused: not configured (no link to the boards)"
            return response
        response.success, response.message = self.core.enable(bool(request.data))
        return response

    def _on_estop(self, _request: Any, response: Any) -> Any:
        self.core.estop()
        self._publish_estop(Bool(data=True))
        self.get_logger().error("emergency stop latched: every board holds")
        response.success, response.message = True, "emergency stop latched; boards hold"
        return response

    def _on_reset_estop(self, _request: Any, response: Any) -> Any:
        self.core.reset_estop()
        self._publish_estop(Bool(data=False))
        response.success, response.message = True, "emergency stop cleared; call ~/enable to drive again"
        return response

    def publish_status(self) -> None:
        self.status_gate()
        core = self.core
        values: dict[str, object] = {
            "mode": core.mode.name,
            "enabled": core.enabled,
            DriverKeys.ESTOPPED: core.estopped,
            DriverKeys.SAFE_HOLD: core.safe_hold_reason,
        }
        if self.loop is not None:
            values.update(self.loop.diagnostics())
        values.update({f"count.{k}": v for k, v in core.counts.items()})
        values.update({f"{DriverKeys.CLAMPED_PREFIX}{k}": v for k, v in core.clamped.items()})
        decoder = self.transport.stats().decoder
        values["garbage_bytes"] = decoder.garbage_bytes
        for board in core.board_map:  # frame statistics of every board since start
            stats = decoder.senders.get(board.address)
            frames, crc, lost, bad = (
                (0, 0, 0, 0)
                if stats is None
                else (stats.frames, stats.crc_errors, stats.lost, stats.malformed + stats.oversize)
            )
            values[f"board.{board.name}"] = f"frames={frames} crc={crc} lost={lost} malformed={bad}"
        errors = [core.board_map.boards[i].name for i in np.flatnonzero(core.readings.errors)]
        if errors:
            values[DriverKeys.BOARD_ERRORS] = ", ".join(errors)
        loop_error = None if self.loop is None else self.loop.error
        if core.safe_hold_reason or loop_error is not None:
            level, message = Level.ERROR, core.safe_hold_reason or f"loop died: {loop_error!r}"
        elif core.estopped:
            level, message = Level.WARN, "emergency stop latched"
        else:
            level, message = Level.OK, "driving" if core.enabled else "boards hold (not enabled)"
        status = Status(DRIVER_STATUS, level, message, values, hardware_id=HARDWARE_ID)
        statuses = [status, *self.task_statuses(decoder)]
        self._publish_diagnostics(diagnostics_to_msg(statuses, stamp_ns=self.stamp_ns()))

    def task_statuses(self, decoder: Any) -> list[Status]:
        """``driver: safety``, ``driver: loop`` (on its own) and ``driver: board <name>`` for every board."""
        core, grew = self.core, self._increases
        if core.estopped:
            safety = task_status("driver", "safety", Level.ERROR, "emergency stop latched")
        elif core.safe_hold_reason:
            safety = task_status("driver", "safety", Level.ERROR, "safe hold", {"reason": core.safe_hold_reason})
        else:
            safety = task_status("driver", "safety", Level.OK, "driving" if core.enabled else "boards hold")
        out = [safety]
        if self.loop is not None:
            stats = self.loop.stats()
            new = grew("loop.misses", stats.deadline_misses)
            level, text = (Level.WARN, "deadline misses") if new > 0 else (Level.OK, "on time")
            # without the "loop." prefix: the report's loop table reads those keys from rh5/driver
            timing = {k.removeprefix(LoopKeys.PREFIX): v for k, v in self.loop.diagnostics().items()}
            out.append(task_status("driver", "loop", level, text, {"new_deadline_misses": int(new), **timing}))
        now = time.monotonic_ns()
        started = core.started_ns and now - core.started_ns > max(core.silence_timeout_ns, 200_000_000)
        for board in core.board_map:
            stats = decoder.senders.get(board.address)
            frames = 0 if stats is None else stats.frames
            bad = 0 if stats is None else stats.crc_errors + stats.lost + stats.malformed + stats.oversize
            new_bad = grew(f"bad.{board.name}", bad)
            silent_ms = (now - int(core.heard_ns[board.index])) / 1e6
            values = {"frames": frames, "bad_frames": bad, "new_bad_frames": int(new_bad), "error_bits": 0}
            values["error_bits"] = int(core.readings.errors[board.index])
            if started and silent_ms > core.silence_timeout_ns / 1e6:
                level, text = Level.ERROR, "silent"
                values["silent_ms"] = round(silent_ms, 1) if core.heard_ns[board.index] else "never heard"
            elif values["error_bits"]:
                level, text = Level.ERROR, "reports errors"
            elif new_bad > 0:
                level, text = Level.WARN, "lost or corrupt frames"
            else:
                level, text = Level.OK, "answering"
            out.append(task_status("driver", f"board {board.name}", level, text, values))
        return out

    def summary(self) -> dict[str, Any]:
        """Adds the safety state, counters and loop timing to the base summary."""
        return {
            **super().summary(),
            "enabled": self.core.enabled,
            "estopped": self.core.estopped,
            "safe_hold": self.core.safe_hold_reason,
            "counts": dict(self.core.counts),
            "clamped": dict(self.core.clamped),
            **({} if self.loop is None else {"loop": self.loop.stats().as_dict()}),
        }

    def destroy_node(self) -> None:
        """Stop the loop, then close the link to the boards."""
        if self.loop is not None:
            self.loop.stop()
        self.transport.shutdown()
        super().destroy_node()


def main(args: list[str] | None = None) -> None:
    """Entry point of ``ros2 run rh5_bringup driver_node``."""
    run_node(DriverNode, args)
