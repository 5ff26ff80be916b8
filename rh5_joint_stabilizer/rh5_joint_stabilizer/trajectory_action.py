"""The stabilizer's ``~/follow_joint_trajectory`` action server (control_msgs/FollowJointTrajectory).

As joint_trajectory_controller serves it: a goal is validated when it arrives and rejected with the reason
(logged, and ERROR on /diagnostics) when it is invalid (goal_check); an accepted goal preempts the one being
executed (aborted, "preempted") and is played through the stabilizer's ramp-in and playback; feedback
(desired, actual, error) goes out at ``FEEDBACK_PERIOD_S``; a path-tolerance violation aborts and holds, the end is
judged against the goal tolerances within the goal time tolerance; a cancel holds the robot where the reference
is. Nothing here runs in the 1 kHz loop: a timer of the node's executor watches the goal, and the execute
callback waits for it without blocking the executor (it awaits a future the timer completes).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Final

from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.task import Future

from rh5_joint_stabilizer.controller import Measurement, StabilizerCore, State
from rh5_joint_stabilizer.goal_check import (
    GOAL_TOLERANCE_VIOLATED,
    INVALID_GOAL,
    PATH_TOLERANCE_VIOLATED,
    SUCCESSFUL,
    GoalRejectedError,
    Tolerances,
    check_goal,
    violations,
)
from rh5_joint_stabilizer.reference import PlannedTrajectory
from rh5_msgs_py.array_types import FloatArray
from rh5_msgs_py.conversions import to_time_msg
from rh5_msgs_py.names import JOINT_NAMES

ACTION_NAME: Final = "~/follow_joint_trajectory"
ACTION_TYPE: Final = "control_msgs/action/FollowJointTrajectory"
FEEDBACK_PERIOD_S: Final = 0.05


@dataclass
class ActiveGoal:
    """The goal being executed and what judging it needs."""

    handle: Any
    trajectory: PlannedTrajectory
    tolerances: Tolerances
    done: Future = field(default_factory=Future)
    started: bool = False
    """Whether the stabilizer has begun the ramp-in to this goal's trajectory."""
    finished_ns: int | None = None
    """Node-clock time at which playback ended (the goal tolerance is judged from then on)."""


class TrajectoryActionServer:
    """FollowJointTrajectory on a stabilizer node: ``node`` gives the clock, logger and executor."""

    def __init__(
        self,
        node: Any,
        core: StabilizerCore,
        *,
        measurement: Callable[[], Measurement | None],
        velocity_limits: FloatArray,
        defaults: Callable[[], Tolerances],
        on_rejected: Callable[[str], None],
    ) -> None:
        from control_msgs.action import FollowJointTrajectory  # noqa: PLC0415 (built by make venv)

        self._node, self._core, self._measurement = node, core, measurement
        self._velocity_limits = velocity_limits
        self._defaults = defaults
        self._on_rejected = on_rejected
        self._action = FollowJointTrajectory
        self._checked: tuple[Any, tuple[PlannedTrajectory, Tolerances]] | None = None
        self._goals: dict[int, ActiveGoal] = {}
        """Accepted goals by handle id until their execute callback has returned their result."""
        self.active: ActiveGoal | None = None
        self.counts = {"accepted": 0, "rejected": 0, "succeeded": 0, "aborted": 0, "canceled": 0, "preempted": 0}
        self.last_result = ""
        self.rejection = ""
        """Why the last goal was rejected, until one is accepted."""
        self._server = ActionServer(
            node,
            FollowJointTrajectory,
            ACTION_NAME,
            execute_callback=self._execute,
            goal_callback=self._on_goal,
            handle_accepted_callback=self._on_accepted,
            cancel_callback=lambda _handle: CancelResponse.ACCEPT,
        )
        # Runs only while a goal executes: each executor wake-up costs ~1 ms here, which the 1 kHz cycle shares. On the
        # steady clock: a timer on the ROS clock wakes the executor at every step of simulated time, cancelled or not.
        self._timer = node.create_wall_timer(FEEDBACK_PERIOD_S, self._watch)
        self._timer.cancel()

    # --- goal arrival --------------------------------------------------------------------------------------------

    def _on_goal(self, request: Any) -> GoalResponse:
        now_ns = self._node.get_clock().now().nanoseconds
        try:
            trajectory, tolerances = check_goal(request, now_ns, self._velocity_limits, self._defaults())
        except GoalRejectedError as err:
            self.counts["rejected"] += 1
            self.last_result = self.rejection = f"rejected (code {err.code}): {err}"
            self._node.get_logger().error(f"follow_joint_trajectory goal rejected: {err}")
            self._on_rejected(f"follow_joint_trajectory goal (code {err.code}): {err}")
            return GoalResponse.REJECT
        self._checked = (request, (trajectory, tolerances))
        return GoalResponse.ACCEPT

    def _on_accepted(self, handle: Any) -> None:
        if self.active is not None:
            self._finish(self.active, "abort", INVALID_GOAL, "preempted by a new goal")
            self.counts["preempted"] += 1
        if self._checked is not None and self._checked[0] is handle.request:
            trajectory, tolerances = self._checked[1]
        else:  # checked again: the goal callback's result belongs to another request
            now_ns = self._node.get_clock().now().nanoseconds
            trajectory, tolerances = check_goal(handle.request, now_ns, self._velocity_limits, self._defaults())
        self._checked = None
        self.rejection = ""
        self.counts["accepted"] += 1
        ok, reason = self._core.request_play(trajectory, self._measurement())
        goal = ActiveGoal(handle, trajectory, tolerances)
        self.active = goal
        self._goals[id(handle)] = goal
        self._timer.reset()
        handle.execute()
        if not ok:
            self._finish(goal, "abort", INVALID_GOAL, reason)

    async def _execute(self, handle: Any) -> Any:
        goal = self._goals.get(id(handle))
        if goal is None:
            return self._result(INVALID_GOAL, "unknown goal")
        try:
            return await goal.done
        finally:
            self._goals.pop(id(handle), None)

    # --- watching the goal ---------------------------------------------------------------------------------------

    def _watch(self) -> None:
        goal = self.active
        if goal is None:
            return
        core = self._core
        if goal.handle.is_cancel_requested:
            core.request_hold()
            self._finish(goal, "canceled", SUCCESSFUL, "canceled: holding the reference")
        elif core.trajectory is not goal.trajectory:
            self._finish(goal, "abort", INVALID_GOAL, "another trajectory replaced it (planned_trajectory)")
        elif self._started(goal):
            measurement, command = self._measurement(), core.last_command
            if measurement is not None and command is not None:
                self._judge(goal, measurement, command.position, command.velocity)

    def _started(self, goal: ActiveGoal) -> bool:
        """Whether the stabilizer plays ``goal`` (ends it when its start was dropped)."""
        core = self._core
        if not goal.started:
            if core.state in (State.RAMP_IN, State.PLAYING):
                goal.started = True
            elif not core.start_pending:
                self._finish(goal, "abort", INVALID_GOAL, f"the stabilizer did not start it: {core.last_reason}")
        return goal.started

    def _judge(self, goal: ActiveGoal, measurement: Measurement, desired: FloatArray, velocity: FloatArray) -> None:
        """Feedback, then the path tolerance while playing, the goal tolerance once played, or why it stopped."""
        core = self._core
        error = desired - measurement.position
        self._feedback(goal, desired, velocity, measurement, error)
        if core.state in (State.RAMP_IN, State.PLAYING):
            if core.state == State.PLAYING and (over := violations(error, goal.tolerances.path)):
                core.request_hold()
                self._finish(goal, "abort", PATH_TOLERANCE_VIOLATED, f"path tolerance violated: {over}")
            return
        if core.state != State.HOLDING or core.last_reason != "trajectory finished":
            reason = core.last_reason or core.state.value
            self._finish(goal, "abort", INVALID_GOAL, f"stabilizer {core.state.value}: {reason}")
            return
        now_ns = self._node.get_clock().now().nanoseconds
        if goal.finished_ns is None:
            goal.finished_ns = now_ns
        over = violations(goal.trajectory.positions[-1] - measurement.position, goal.tolerances.goal)
        if not over:
            self._finish(goal, "succeed", SUCCESSFUL, "")
        elif now_ns - goal.finished_ns > goal.tolerances.goal_time_s * 1e9:
            self._finish(goal, "abort", GOAL_TOLERANCE_VIOLATED, f"goal tolerance violated: {over}")

    def _feedback(
        self, goal: ActiveGoal, desired: FloatArray, velocity: FloatArray, measurement: Measurement, error: FloatArray
    ) -> None:
        feedback = self._action.Feedback()
        to_time_msg(self._node.get_clock().now().nanoseconds, feedback.header.stamp)
        feedback.joint_names = list(JOINT_NAMES)
        feedback.desired.positions, feedback.desired.velocities = desired.tolist(), velocity.tolist()
        feedback.actual.positions, feedback.actual.velocities = (
            measurement.position.tolist(),
            measurement.velocity.tolist(),
        )
        feedback.error.positions = error.tolist()
        feedback.error.velocities = (velocity - measurement.velocity).tolist()
        goal.handle.publish_feedback(feedback)

    # --- ending a goal -------------------------------------------------------------------------------------------

    def _result(self, code: int, text: str) -> Any:
        result = self._action.Result()
        result.error_code, result.error_string = code, text
        return result

    def _finish(self, goal: ActiveGoal, how: str, code: int, text: str) -> None:
        """End ``goal`` (succeed, abort or canceled) with ``code`` and ``text``, once."""
        if goal.done.done():
            return
        # A stop (SIGINT, SIGTERM) shuts the context down before the node is destroyed: the goal's status can then
        # no longer be published (rcl raises), and its client sees the server go away instead.
        if goal.handle.is_active and self._node.context.ok():
            getattr(goal.handle, how)()
        key = {"succeed": "succeeded", "abort": "aborted", "canceled": "canceled"}[how]
        self.counts[key] += 1
        self.last_result = f"{key} (code {code}){': ' + text if text else ''}"
        if code == SUCCESSFUL:  # one severity per call site (rclpy refuses a change)
            self._node.get_logger().info(f"follow_joint_trajectory goal {self.last_result}")
        else:
            self._node.get_logger().warning(f"follow_joint_trajectory goal {self.last_result}")
        goal.done.set_result(self._result(code, text))
        if self.active is goal:
            self.active = None
            self._timer.cancel()

    def destroy(self) -> None:
        """Abort the goal in flight and take the server down."""
        if self.active is not None:
            self._finish(self.active, "abort", INVALID_GOAL, "the stabilizer is shutting down")
        self._server.destroy()
