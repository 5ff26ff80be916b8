"""``rh5 experiment NAME``: plan (or reuse) a motion, play it through the whole suite on the simulated
robot, record it, and write the report.

Sequence (the paper's hardware procedure, with the simulation's crane as the lifting harness):
plan or load the cached trajectory -> start the suite with the robot hanging in the sim's support at the
motion's first pose -> the planner publishes the trajectory (``~/load``) -> enable the driver (boards hold
their pose) -> release the support, let the robot settle on its feet -> stabilizer ``~/start`` (ramp-in,
playback) -> wait until it holds the last sample, a little longer -> stop every node (the recorder closes
the bag) -> report. A progress line shows the stabilizer's state and the base height while it runs.
"""

from __future__ import annotations

import hashlib
import json
import sys
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rh5_bringup.orchestration.launcher import Bringup, load_bringup
from rh5_bringup.orchestration.service_calls import call_lifecycle, call_set_bool, call_trigger
from rh5_bringup.orchestration.session import SuiteSession, run_dir
from rh5_msgs_py import interfaces
from rh5_msgs_py.diagnostic_keys import STABILIZER_STATUS, StabilizerKeys
from rh5_msgs_py.progress import LiveLine

if TYPE_CHECKING:
    from rh5_msgs_py.trajectory_file import TrajectoryData

DEFAULT_OUTPUT_ROOT = Path("out")
SETTLE_AFTER_ENABLE_S = 0.5
"""Boards hold their pose this long before the support is released."""
SETTLE_AFTER_RELEASE_S = 1.0
"""The robot stands on its feet under the boards' hold this long before playback starts."""
FALL_HEIGHT_FRACTION = 0.6
"""The robot has fallen when the base is below this fraction of its height at release."""
PLAY_SLACK_S = 30.0
"""Ramp-in and slack on top of the trajectory's duration before the experiment times out: in simulated time
when the physics publishes it (the simulation runs slower than real time), else in wall time."""
STATUS_LOG_INTERVAL_S = 5.0
"""Written to a log rather than a terminal, the motion's status line repeats at most this often (s)."""
SIM_STALL_S = 20.0
"""The experiment also times out when the simulated time has not advanced for this long (wall time)."""


class ExperimentError(RuntimeError):
    """The experiment could not run (planning failed, a node did not come up, a service refused)."""


@dataclass(frozen=True)
class ExperimentSettings:
    """What ``rh5 experiment`` runs and where it writes."""

    motion: str
    overrides: Mapping[str, Any] = field(default_factory=dict)
    sim: str = "physics"
    output_root: Path = DEFAULT_OUTPUT_ROOT
    replan: bool = False
    hold_after_s: float = 1.0
    max_iterations: int = 200
    bringup: Path | None = None
    report: bool = True
    node_parameters: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)
    """Extra node parameters by node name (applied last)."""
    composed: bool = True
    """Driver, mapper and stabilizer in the control process (False: three processes, for development)."""
    domain_id: int | None = None
    """ROS_DOMAIN_ID of the run (None: one leased free on this machine)."""


@dataclass
class ExperimentResult:
    """Where things went and how the run ended."""

    folder: Path
    trajectory: Path
    bag: Path
    report: Path | None = None
    outcome: str = "not run"
    fell: bool = False
    exit_codes: dict[str, int] = field(default_factory=dict)


# --- the trajectory -------------------------------------------------------------------------------------------------


def trajectory_key(motion: str, overrides: Mapping[str, Any]) -> str:
    """Cache key of a planned motion: its parameters, the robot model and the cost configuration."""
    from rh5_hyrodyn_mapper.model.robot import model_hash  # noqa: PLC0415
    from rh5_planner.motions import get_motion  # noqa: PLC0415

    spec = get_motion(motion, dict(overrides))
    costs = resources.files("rh5_planner").joinpath("config/costs.yaml").read_bytes()
    blob = json.dumps({"motion": spec.parameters(), "model": model_hash()}, sort_keys=True).encode() + costs
    return hashlib.sha256(blob).hexdigest()[:12]


def planned_trajectory(settings: ExperimentSettings) -> tuple[Path, bool]:
    """The motion's trajectory file: from the cache (out/trajectories) or solved now (a progress bar on stderr);
    returns (path, cached)."""
    cache = settings.output_root / "trajectories"
    path = cache / f"{settings.motion}-{trajectory_key(settings.motion, settings.overrides)}.npz"
    if path.exists() and not settings.replan:
        return path, True
    import crocoddyl  # noqa: F401, PLC0415 (before pinocchio, see design/crocoddyl_wheels.md)

    from rh5_planner.motions import get_motion  # noqa: PLC0415
    from rh5_planner.ocp import SolverSettings, solve  # noqa: PLC0415
    from rh5_planner.plan_cli import ProgressBar  # noqa: PLC0415

    solver = SolverSettings(max_iterations=settings.max_iterations)
    bar = ProgressBar(solver.max_iterations, solver.stop_threshold, label=f"planning {settings.motion} ")
    result = solve(get_motion(settings.motion, dict(settings.overrides)), replace(solver, callback=bar))
    bar.finish("converged" if result.converged else "NOT converged")
    if not result.converged:
        log = result.solver_log
        msg = f"{settings.motion} did not converge ({log.iterations} iterations, stop {log.stop_criterion})"
        raise ExperimentError(msg)
    cache.mkdir(parents=True, exist_ok=True)
    result.save(path)
    return path, False


# --- the suite ------------------------------------------------------------------------------------------------------


def experiment_bringup(settings: ExperimentSettings, trajectory: Path, data: TrajectoryData, bag: Path) -> Bringup:
    """The bringup of the experiment: physics (or kinematic) sim starting at the motion's first pose (``data``, the
    content of ``trajectory``), the recorder writing ``bag``, the planner loading ``trajectory``."""
    bringup = load_bringup(settings.bringup).resolved(sim=settings.sim)
    bringup = bringup.with_parameters("recorder", output=str(bag))
    bringup = bringup.with_parameters("planner", trajectory_file=str(trajectory.resolve()))
    if settings.sim == "physics":
        payload = float(data.motion.get("parameters", {}).get("payload_kg_per_hand", 0.0))
        bringup = bringup.with_parameters(
            "sim_hardware",
            initial_joint_positions=[float(v) for v in data.joint_positions()[0]],
            initial_base_xy=[float(v) for v in data.base_positions()[0, :2]],
            hand_payload_kg=payload,
        )  # /clock, playback on it and the staleness bounds: bringup.yaml's sim:=physics
    for node, parameters in settings.node_parameters.items():
        bringup = bringup.with_parameters(node, **parameters)
    return replace(bringup, composed=settings.composed)


class _Monitor:
    """Follows the stabilizer's state (from /diagnostics), the true base height (sim/base_pose) and the simulated
    time (/clock)."""

    def __init__(self, node: Any) -> None:
        from rh5_msgs_py.conversions import diagnostics_from_msg  # noqa: PLC0415
        from rh5_msgs_py.interfaces import message_class  # noqa: PLC0415

        self.state = "unknown"
        self.reason = ""
        self.trajectory_duration_s: float | None = None
        self.rejected = ""
        self.base_z: float | None = None
        self.sim_time_s: float | None = None
        """The simulation's last /clock [s] and when it arrived (time.monotonic)."""
        self.sim_time_arrived = 0.0
        self._from_msg = diagnostics_from_msg
        topic = interfaces.DIAGNOSTICS
        node.create_subscription(message_class(topic.type), topic.name, self._on_diagnostics, topic.qos)
        topic = interfaces.SIM_BASE_POSE
        node.create_subscription(message_class(topic.type), topic.name, self._on_pose, topic.qos)
        topic = interfaces.CLOCK
        node.create_subscription(message_class(topic.type), topic.name, self._on_clock, topic.qos)

    def _on_diagnostics(self, msg: Any) -> None:
        for status in self._from_msg(msg):
            if status.name == STABILIZER_STATUS:
                self.state = str(status.values.get(StabilizerKeys.STATE, self.state))
                self.reason = str(status.values.get(StabilizerKeys.REASON, ""))
                self.rejected = str(status.values.get(StabilizerKeys.TRAJECTORY_REJECTED, ""))
                try:
                    self.trajectory_duration_s = float(status.values.get(StabilizerKeys.TRAJECTORY_DURATION_S, "none"))
                except ValueError:
                    self.trajectory_duration_s = None

    def _on_pose(self, msg: Any) -> None:
        self.base_z = float(msg.pose.position.z)

    def _on_clock(self, msg: Any) -> None:
        self.sim_time_s = msg.clock.sec + 1e-9 * msg.clock.nanosec
        self.sim_time_arrived = time.monotonic()

    def timed_out(self, started_wall: float, started_sim: float | None, budget_s: float) -> bool:
        """Whether ``budget_s`` has passed since the start: in simulated time if the physics publishes it (or
        the simulation stalled for SIM_STALL_S), else in wall time."""
        now = time.monotonic()
        if started_sim is None or self.sim_time_s is None:
            return now - started_wall > budget_s
        return self.sim_time_s - started_sim > budget_s or now - self.sim_time_arrived > SIM_STALL_S


def _call(session: SuiteSession, node: str, service: str, progress: Callable[[str], None], **kw: Any) -> str:
    name = session.service(node, service)
    if "value" in kw:
        ok, message = call_set_bool(session.node, name, kw["value"])
    else:
        ok, message = call_trigger(session.node, name, timeout_s=kw.get("timeout_s", 10.0))
    progress(f"{node}/{service}: {message}")
    if not ok:
        msg = f"{name} refused: {message}"
        raise ExperimentError(msg)
    return message


def _activate_driver(session: SuiteSession, progress: Callable[[str], None]) -> None:
    """The driver's lifecycle activate (it configured itself at start: autostart), i.e. drive the boards."""
    name = session.service("driver", "change_state")
    ok, message = call_lifecycle(session.node, name, "activate")
    progress(f"driver/change_state: {message}")
    if not ok:
        msg = f"{name} refused: {message}"
        raise ExperimentError(msg)


def _await_trajectory(session: SuiteSession, monitor: _Monitor, duration_s: float, timeout_s: float = 10.0) -> None:
    """Wait until the stabilizer holds the motion's trajectory (its status says so); raise with its reason if it
    rejected it. Without this a start could play whatever trajectory the stabilizer had before."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline and not session.stop_requested:
        session.sleep(0.1)
        if monitor.rejected:
            msg = f"the stabilizer rejected the trajectory: {monitor.rejected}"
            raise ExperimentError(msg)
        if monitor.trajectory_duration_s is not None and abs(monitor.trajectory_duration_s - duration_s) < 2e-3:
            return
    msg = f"the stabilizer did not report the {duration_s:.3f} s trajectory within {timeout_s:.0f} s"
    raise ExperimentError(msg)


def _stopped(session: SuiteSession) -> str:
    """Why the experiment must stop because nodes died ("" if none did). A lost recorder would let the suite run
    on (``rh5 up`` does), but an experiment is its recording: it stops too, and says so."""
    if crashed := session.crashed():
        return f"nodes stopped on their own: {crashed}"
    if lost := session.lost():
        return f"nodes stopped on their own: {lost} (an experiment does not run on without its recording)"
    return ""


def _play(
    session: SuiteSession, settings: ExperimentSettings, duration_s: float, progress: Callable[[str], None]
) -> tuple[str, bool]:
    """Run the motion through the started suite; return (outcome, fell)."""
    monitor = _Monitor(session.node)
    _call(session, "planner", "load", progress)
    _await_trajectory(session, monitor, duration_s)
    _activate_driver(session, progress)
    session.sleep(SETTLE_AFTER_ENABLE_S)
    standing_z: float | None = None
    if settings.sim == "physics":
        _call(session, "sim_hardware", "release_support", progress)
        session.sleep(SETTLE_AFTER_RELEASE_S)
        standing_z = monitor.base_z
    _call(session, "stabilizer", "start", progress)
    started, started_sim = time.monotonic(), monitor.sim_time_s
    finished_at: float | None = None
    status = LiveLine(interval_s=STATUS_LOG_INTERVAL_S)  # live on a terminal, a line per state and 5 s in a log
    try:
        while not session.stop_requested:
            session.sleep(0.1)
            now = time.monotonic()
            low = FALL_HEIGHT_FRACTION * standing_z if standing_z is not None else None
            fell = low is not None and monitor.base_z is not None and monitor.base_z < low
            z = f", base z {monitor.base_z:.3f} m" if monitor.base_z is not None else ""
            if started_sim is not None and monitor.sim_time_s is not None:
                z = f" (simulated {monitor.sim_time_s - started_sim:5.1f} s){z}"
            status.show(f"{settings.motion}: {monitor.state:<9} {now - started:6.1f} s{z}", key=monitor.state)
            if fell:
                return "fell", True
            if stopped := _stopped(session):
                return stopped, False
            if monitor.state in ("holding", "stopped") and finished_at is None:
                finished_at = now
                if "finished" not in monitor.reason:
                    return f"stabilizer {monitor.state}: {monitor.reason}", False
            if finished_at is not None and now - finished_at >= settings.hold_after_s:
                return "completed", False
            if monitor.timed_out(started, started_sim, duration_s + PLAY_SLACK_S):
                return f"timed out in state {monitor.state}", False
        return "interrupted", False
    finally:
        if status.last:
            status.finish()


def run_experiment(settings: ExperimentSettings, progress: Callable[[str], None] = print) -> ExperimentResult:
    """Plan or reuse, run, record and report one experiment; the folder holds logs/, bag/, report/."""
    from rh5_msgs_py.trajectory_file import load_trajectory  # noqa: PLC0415

    folder = run_dir(settings.output_root / "experiments", settings.motion)
    trajectory, cached = planned_trajectory(settings)
    progress(f"trajectory: {trajectory} ({'cached' if cached else 'planned now'})")
    data = load_trajectory(trajectory)
    duration_s = float(data.times[-1])
    result = ExperimentResult(folder, trajectory, folder / "bag")
    folder.mkdir(parents=True)
    bringup = experiment_bringup(settings, trajectory, data, result.bag)
    with SuiteSession(bringup, folder / "logs", "rh5_experiment", settings.domain_id) as session:
        chosen = "leased: free on this machine" if settings.domain_id is None else "chosen"
        progress(f"experiment {settings.motion}: ROS_DOMAIN_ID={session.run.domain_id} ({chosen}), folder {folder}")
        missing = session.start()
        if missing:
            msg = (  # before closing: closing stops the nodes that are still starting
                f"never appeared in the ROS graph: {sorted(missing)} (logs in {folder / 'logs'})\n"
                f"{session.run.why_missing(missing)}"
            )
            session.close()
            raise ExperimentError(msg)
        try:
            result.outcome, result.fell = _play(session, settings, duration_s, progress)
        finally:
            sys.stderr.write("\n")
            result.exit_codes = session.close()
    progress(f"experiment {settings.motion}: {result.outcome}; node exit codes {result.exit_codes}")
    if settings.report:
        from rh5_bringup.analysis import ReportError, build_report  # noqa: PLC0415

        try:
            report = build_report(result.bag, folder / "report")
        except ReportError as err:
            progress(f"no report: {err}")
        else:
            result.report = report.folder
            for line in report.verdicts:
                progress(line)
    return result
