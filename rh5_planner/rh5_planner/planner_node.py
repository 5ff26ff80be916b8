"""The planner node: solves the selected motion with Box-FDDP and publishes the optimised trajectory.

Services (std_srvs/Trigger):

* ``~/plan`` validates the parameters (``motion``, ``motion_overrides`` as a JSON object that
  :func:`rh5_planner.motions.get_motion` accepts, ``output_dir``), solves the motion with ``max_iterations``,
  ``stop_threshold`` and ``solver_threads``, publishes the progress of every iteration on
  ``planner/progress`` and saves the trajectory file ``<output_dir>/<motion>_<timestamp>.rh5traj``. The
  answer's message is a JSON summary (motion, verified, converged, iterations, cost, stop, solve_time_s,
  knots, file, and for a published plan samples and duration_s). Converged: the plan is published (see
  :mod:`rh5_planner.publishing`) and success is true. Not converged: success is false, the message is
  ``not converged: {summary}``, the file is kept for inspection but nothing is published. Bad parameters:
  ``bad parameters: <parameter>: <reason>``. While a solve runs, another ``~/plan`` is refused with
  ``busy: planning <motion>``. Motions outside VERIFIED_MOTIONS are planned too, with ``"verified": false``.
* ``~/load`` reads ``trajectory_file`` and publishes it the same way.

Concurrency: the solve runs in a child Python process, :mod:`rh5_planner.solve_worker` (Crocoddyl holds the
GIL for a whole Box-FDDP solve, so a thread would stall the node's services for up to half a second at a time).
A worker thread of the node reads the child's progress lines, publishes them, then loads the saved file and
publishes the plan; ``~/plan`` is a coroutine that awaits the worker's result, so the node's single-threaded
executor keeps answering ``~/load``, the parameter services and further ``~/plan`` calls meanwhile. The
child ignores SIGINT (the node stops it when it is destroyed) and exits if the node dies.

At start the node publishes the first pose of the selected motion (the nominal standing pose with the
motion's knee bend and payload, :func:`rh5_planner.ocp.build_robot`, ~0.4 s) as a two-sample hold
trajectory, so that the rest of the suite has a reference; all zeros if that pose cannot be computed.
"""

from __future__ import annotations

import contextlib
import json
import math
import subprocess
import sys
import threading
import time
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path
from typing import Any, Final

import numpy as np
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.task import Future
from std_srvs.srv import Trigger

from rh5_msgs_py import interfaces
from rh5_msgs_py.conversions import Level, Status, diagnostics_to_msg, status_to_msg
from rh5_msgs_py.diagnostic_keys import PLANNER_STATUS
from rh5_msgs_py.diagnostic_tasks import task_status
from rh5_msgs_py.names import JOINT_NAMES
from rh5_msgs_py.node_runtime import SuiteNode, run_node
from rh5_msgs_py.trajectory_file import SUFFIX, TrajectoryFileError, load_trajectory

from .motions import VERIFIED_MOTIONS, MotionError, MotionSpec, get_motion
from .publishing import PlannedMessages, hold_messages, planned_messages
from .solve_worker import LINE_PREFIX

HOLD_DURATION_S: Final = 1.0
CHILD_STOP_S: Final = 2.0


@dataclass(frozen=True)
class _Job:
    """One validated ~/plan request."""

    motion: MotionSpec
    overrides: dict[str, Any]
    file: Path
    max_iterations: int
    stop_threshold: float
    nthreads: int
    rate_hz: float

    def argv(self) -> list[str]:
        job = {
            "motion": self.motion.name,
            "overrides": self.overrides,
            "file": str(self.file),
            "max_iterations": self.max_iterations,
            "stop_threshold": self.stop_threshold,
            "nthreads": self.nthreads,
        }
        return [sys.executable, "-m", "rh5_planner.solve_worker", json.dumps(job)]


class _BadParameterError(ValueError):
    def __init__(self, name: str, reason: str) -> None:
        super().__init__(f"{name}: {reason}")


def _finite(value: Any) -> Any:
    """JSON-safe number: non-finite floats become None."""
    return value if not isinstance(value, float) or math.isfinite(value) else None


def overrides_parameter(text: str) -> dict[str, Any]:
    """The ``motion_overrides`` parameter (a JSON object, as a ROS parameter string carries it) as a dict;
    _BadParameterError otherwise. The command line's ``--set key=value`` items are ``plan_cli.parse_overrides``."""
    try:
        value = json.loads(text) if text.strip() else {}
    except json.JSONDecodeError as err:
        raise _BadParameterError("motion_overrides", f"not valid JSON ({err})") from None
    if not isinstance(value, dict):
        raise _BadParameterError("motion_overrides", f"must be a JSON object, got {type(value).__name__}")
    return value


def standing_pose(motion: MotionSpec) -> tuple[np.ndarray, np.ndarray]:
    """Joints (JOINT_NAMES order) and base pose (xyz, quaternion xyzw) of ``motion``'s initial state."""
    from rh5_hyrodyn_mapper.model import q_index  # noqa: PLC0415

    from .ocp import build_robot  # noqa: PLC0415  (imports Crocoddyl: only when needed)

    robot = build_robot(motion.payload_kg_per_hand, motion.knee_bend_rad)
    q = robot.x0[: robot.model.nq]
    return q[q_index(robot.model)].copy(), q[:7].copy()


class PlannerNode(SuiteNode):
    """Offers ~/plan and ~/load; publishes planned_trajectory, planned_base_trajectory, planned wrenches."""

    def __init__(self) -> None:
        super().__init__(interfaces.PLANNER_NODE, "rh5_planner", "params/planner.yaml")
        self._publish_trajectory = self.advertise(interfaces.PLANNED_TRAJECTORY)
        self._publish_base = self.advertise(interfaces.PLANNED_BASE_TRAJECTORY)
        self._publish_wrench = {
            "left": self.advertise(interfaces.PLANNED_WRENCH_LEFT),
            "right": self.advertise(interfaces.PLANNED_WRENCH_RIGHT),
        }
        self._publish_progress = self.advertise(interfaces.PLANNER_PROGRESS)
        self._publish_lock = threading.Lock()
        self._solver_status = task_status("planner", "solver", Level.OK, "idle")
        """``planner: solver`` on /diagnostics: the last plan's outcome (WARN not converged, ERROR failed)."""
        self._publish_diagnostics = self.advertise(interfaces.DIAGNOSTICS)
        self.create_wall_timer(
            1.0, lambda: self._publish_diagnostics(diagnostics_to_msg([self._solver_status], self.stamp_ns()))
        )
        self._busy: str | None = None  # motion being planned; read and written on the executor thread only
        self._child: subprocess.Popen[str] | None = None
        self._child_lock = threading.Lock()  # guards _child and _stopping between the worker and destroy_node
        self._stopping = False
        # ~/plan and the worker's "result ready" wake-up live outside the default (mutually exclusive) callback
        # group: while a ~/plan coroutine awaits its solve, the default group (~/load, parameter services) stays free.
        plan_group = ReentrantCallbackGroup()
        self._wake = self.create_guard_condition(lambda: None, callback_group=plan_group)
        self.create_service(Trigger, interfaces.PLAN_SERVICE, self._on_plan, callback_group=plan_group)
        self.create_service(Trigger, interfaces.LOAD_SERVICE, self._on_load)
        # Every writable parameter is read by the next ~/plan or ~/load (which checks the set together);
        # a motion the planner does not know is refused at once.
        read_when_used = lambda _: None  # noqa: E731
        self.apply_live(
            {
                "motion": self._check_motion,
                **dict.fromkeys(
                    (
                        "motion_overrides",
                        "output_dir",
                        "trajectory_file",
                        "max_iterations",
                        "stop_threshold",
                        "solver_threads",
                    ),
                    read_when_used,
                ),
            }
        )
        self._publish_hold()

    @staticmethod
    def _check_motion(name: str) -> None:
        try:
            get_motion(name)
        except MotionError as err:
            raise ValueError(str(err)) from None

    # ------------------------------------------------------------------------------------------
    # publishing

    def _publish_messages(self, messages: PlannedMessages) -> None:
        with self._publish_lock:
            self._publish_trajectory(messages.joint)
            self._publish_base(messages.base)
            for side, msg in messages.wrenches.items():
                self._publish_wrench[side](msg)

    def _publish_hold(self) -> None:
        joints, base = np.zeros(len(JOINT_NAMES)), np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0])
        try:
            joints, base = standing_pose(get_motion(self.params["motion"]))
        except Exception as err:  # a reference of zeros is better than none
            self.get_logger().warning(f"standing pose unavailable, holding zeros: {err}")
        stamp_ns = self.get_clock().now().nanoseconds
        self._publish_messages(hold_messages(joints, base, HOLD_DURATION_S, stamp_ns))

    def _publish_data(self, data: Any, rate_hz: float) -> PlannedMessages:
        messages = planned_messages(data, rate_hz, self.get_clock().now().nanoseconds)
        self._publish_messages(messages)
        return messages

    def _status(self, level: Level, message: str, values: dict[str, Any]) -> None:
        with self._publish_lock:
            self._publish_progress(status_to_msg(Status(PLANNER_STATUS, level, message, values)))
        text = message if level == Level.OK else ("not converged" if level == Level.WARN else "planning failed")
        self._solver_status = task_status("planner", "solver", level, text, {**values, "detail": message})

    # ------------------------------------------------------------------------------------------
    # ~/plan

    def _job(self) -> _Job:
        """The validated parameters of a solve; _BadParameterError naming the first bad one."""
        params = self.params
        overrides = overrides_parameter(params["motion_overrides"])
        try:
            motion = get_motion(params["motion"])
        except MotionError as err:
            raise _BadParameterError("motion", str(err)) from None
        try:
            motion = get_motion(params["motion"], overrides)
        except (MotionError, TypeError, ValueError) as err:
            raise _BadParameterError("motion_overrides", str(err)) from None
        output_dir = Path(params["output_dir"]).expanduser().resolve()
        try:
            output_dir.mkdir(parents=True, exist_ok=True)
        except OSError as err:
            raise _BadParameterError("output_dir", str(err)) from None
        stamp = datetime.now().strftime("%Y%m%d_%H%M%S_%f")[:-3]
        return _Job(
            motion=motion,
            overrides=overrides,
            file=output_dir / f"{motion.name}_{stamp}{SUFFIX}",
            max_iterations=int(params["max_iterations"]),
            stop_threshold=float(params["stop_threshold"]),
            nthreads=int(params["solver_threads"]),
            rate_hz=float(params["publish_rate_hz"]),
        )

    async def _on_plan(self, _request: Any, response: Any) -> Any:
        if self._busy is not None:
            response.success, response.message = False, f"busy: planning {self._busy}"
            return response
        try:
            job = self._job()
        except _BadParameterError as err:
            response.success, response.message = False, f"bad parameters: {err}"
            return response
        self._busy = job.motion.name
        try:
            done = Future()
            threading.Thread(target=self._plan_worker, args=(job, done), name="planner-solve", daemon=True).start()
            response.success, response.message = await done
        finally:
            self._busy = None
        return response

    def _plan_worker(self, job: _Job, done: Future) -> None:
        outcome = (False, "planner stopped")
        try:
            outcome = self._plan(job)
        except Exception as err:  # reported to the caller, never lost in a thread
            outcome = (False, f"planner failed: {type(err).__name__}: {err}")
        finally:
            done.set_result(outcome)
            if not self._stopping:
                with contextlib.suppress(Exception):  # the node is being destroyed: nobody waits
                    self._wake.trigger()

    def _plan(self, job: _Job) -> tuple[bool, str]:
        """Solve in the child process, publishing progress; then publish the plan if it converged."""
        name = job.motion.name
        base_values = {"motion": name, "max_iterations": job.max_iterations, "stop_threshold": job.stop_threshold}
        self._status(Level.OK, f"planning {name}", {**base_values, "iteration": 0})
        started = time.monotonic()
        with self._child_lock:
            if self._stopping:
                return False, "planner stopped"
            child = subprocess.Popen(job.argv(), stdout=subprocess.PIPE, stdin=subprocess.DEVNULL, text=True)
            self._child = child
        log: dict[str, Any] | None = None
        error = ""
        assert child.stdout is not None
        for line in child.stdout:
            if not line.startswith(LINE_PREFIX):
                continue
            entry = json.loads(line[len(LINE_PREFIX) :])
            if "progress" in entry:
                iteration, cost, stop = entry["progress"]
                self._status(
                    Level.OK,
                    f"planning {name}: iteration {iteration}",
                    {**base_values, "iteration": iteration, "cost": cost, "stop": stop},
                )
            elif "result" in entry:
                log = entry["result"]
            elif "error" in entry:
                error = entry["error"]
        code = child.wait()
        with self._child_lock:
            self._child = None
        if self._stopping:
            return False, "planner stopped"
        if log is None:
            message = f"solver failed: {error or f'exit code {code}'}"
            self._status(Level.ERROR, message, base_values)
            return False, message
        summary: dict[str, Any] = {
            "motion": name,
            "verified": name in VERIFIED_MOTIONS,
            "converged": bool(log["converged"]),
            "iterations": int(log["iterations"]),
            "cost": _finite(log["cost"]),
            "stop": _finite(log["stop_criterion"]),
            "solve_time_s": round(float(log["solve_time_s"]), 3),
            "wall_time_s": round(time.monotonic() - started, 3),
            "knots": int(log["knots"]),
            "file": str(job.file),
        }
        if job.overrides:
            summary["overrides"] = job.overrides
        values = {**base_values, **{k: summary[k] for k in ("iterations", "cost", "stop", "converged")}}
        if not summary["converged"]:
            text = json.dumps(summary)
            self._status(Level.WARN, f"{name}: not converged", values)
            return False, f"not converged: {text}"
        messages = self._publish_data(load_trajectory(job.file), job.rate_hz)
        summary["samples"], summary["duration_s"] = messages.samples, round(messages.duration_s, 6)
        self._status(Level.OK, f"{name}: converged, published {messages.samples} samples", values)
        return True, json.dumps(summary)

    # ------------------------------------------------------------------------------------------
    # ~/load

    def _on_load(self, _request: Any, response: Any) -> Any:
        path = self.params["trajectory_file"]
        if not path:
            response.success, response.message = False, "parameter trajectory_file is empty"
            return response
        try:
            data = load_trajectory(path)
        except (OSError, TrajectoryFileError) as err:
            response.success, response.message = False, str(err)
            return response
        messages = self._publish_data(data, float(self.params["publish_rate_hz"]))
        response.success = True
        response.message = (
            f"published {messages.samples} samples ({messages.duration_s:.3f} s, {len(data.times)} knots) from {path}"
        )
        return response

    # ------------------------------------------------------------------------------------------

    def destroy_node(self) -> None:
        """Stop a running solve (SIGTERM, then SIGKILL) before the node goes."""
        with self._child_lock:
            self._stopping = True
            child = self._child
        if child is not None and child.poll() is None:
            child.terminate()
            try:
                child.wait(timeout=CHILD_STOP_S)
            except subprocess.TimeoutExpired:
                child.kill()
                child.wait()
        super().destroy_node()


def main(args: list[str] | None = None) -> None:
    """Entry point of ``ros2 run rh5_planner planner_node``."""
    run_node(PlannerNode, args)
