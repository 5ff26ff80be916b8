"""Everything a report shows, computed once from a Recording: the input of the figures and the Markdown."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TypeVar

from rh5_bringup.analysis.metrics import (
    ACTUATOR_GROUPS,
    BaseDeviation,
    FallCheck,
    Fault,
    GroupError,
    LoopTiming,
    StreamTiming,
    Tracking,
    Transition,
    base_deviation,
    detect_fall,
    faults,
    group_errors,
    is_stabilizer_status,
    loop_timing,
    stabilizer_transitions,
    stream_timing,
    tracking,
)
from rh5_bringup.analysis.records import JointSeries, PlannedBase, PlannedJoints, Recording, ReportError
from rh5_bringup.analysis.timeline import TimeZero, trajectory_time_zero
from rh5_msgs_py.names import ACTUATOR_NAMES, JOINT_GROUPS, JOINT_NAMES

_Planned = TypeVar("_Planned", PlannedJoints, PlannedBase)


@dataclass
class Analysis:
    """The report's numbers; a None field is a section whose inputs were not recorded (see ``notes``)."""

    recording: Recording
    time_zero: TimeZero
    planned_joints: PlannedJoints | None
    planned_base: PlannedBase | None
    window: tuple[float, float] | None
    joint_tracking: Tracking | None
    actuator_tracking: Tracking | None
    joint_groups: list[GroupError]
    actuator_groups: list[GroupError]
    base: BaseDeviation | None
    fall: FallCheck | None
    loops: list[LoopTiming]
    streams: list[StreamTiming]
    faults: list[Fault]
    transitions: list[Transition]
    extra: tuple[str, ...] = ()
    notes: list[str] = field(default_factory=list)


def check_names(names: Sequence[str]) -> tuple[str, ...]:
    """The requested extra joints/actuators, checked against the suite's names (ReportError if unknown)."""
    unknown = [n for n in names if n not in JOINT_NAMES and n not in ACTUATOR_NAMES]
    if unknown:
        msg = f"unknown joint or actuator names {unknown}; joints: {', '.join(JOINT_NAMES)}; actuators: " + ", ".join(
            a for a in ACTUATOR_NAMES if a not in JOINT_NAMES
        )
        raise ReportError(msg)
    return tuple(dict.fromkeys(names))


def _latest_before(items: Sequence[_Planned], t: float | None) -> _Planned | None:
    """The last message received by ``t`` (the first one if all came later; the last one if t is None)."""
    if not items:
        return None
    if t is None:
        return items[-1]
    before = [m for m in items if m.t <= t]
    return before[-1] if before else items[0]


def planned_base_for(
    bases: Sequence[PlannedBase], planned: PlannedJoints | None, t0: float | None
) -> PlannedBase | None:
    """The planned_base_trajectory published with ``planned`` (the planner sends both together, with the same
    duration): the last one of that duration, else the last received by ``t0``. Receive times alone can mislead:
    a large message reaches the recorder late under load, after the planner's earlier 2-sample hold."""
    if planned is not None and len(planned.times):
        duration = float(planned.times[-1])
        same = [b for b in bases if len(b.times) and abs(float(b.times[-1]) - duration) < 1e-6]
        if same:
            return same[-1]
    return _latest_before(bases, t0)


def _tracked(
    reference: JointSeries | None, measured: JointSeries | None, window: tuple[float, float] | None
) -> Tracking | None:
    if reference is None or measured is None:
        return None
    return tracking(reference, measured, window)


def analyse(recording: Recording, extra: Sequence[str] = ()) -> Analysis:
    """Compute every section of the report from ``recording``."""
    rec = recording
    notes = list(rec.notes)
    transitions = stabilizer_transitions(rec.diagnostics)
    reports = [d.t for d in rec.diagnostics if is_stabilizer_status(d.name)]
    first_playing = next((tr.t for tr in transitions if tr.state == "playing"), None)
    planned = _latest_before(rec.planned_joints, first_playing)
    time_zero = trajectory_time_zero(transitions, reports, rec.joint_commands, planned)
    t0 = time_zero.t0
    planned_base = planned_base_for(rec.planned_base, planned, t0)
    window = None
    if t0 is not None and planned is not None and len(planned.times):
        window = (t0, t0 + float(planned.times[-1]))
    if len(rec.planned_joints) > 1:
        notes.append(
            f"{len(rec.planned_joints)} planned_trajectory messages: the report compares with the last one received "
            "before playback started (the last one if playback never started)"
        )
    if time_zero.episodes > 1:
        notes.append(f"the stabilizer started playing {time_zero.episodes} times; the report covers the first")
    joint_tr = _tracked(rec.joint_commands, rec.joint_states, window)
    act_tr = _tracked(rec.actuator_commands, rec.actuator_states, window)
    base = None
    fall = None
    if rec.base_pose is not None and len(rec.base_pose.t):
        if planned_base is not None and t0 is not None:
            base = base_deviation(rec.base_pose, planned_base, t0)
        fall = detect_fall(rec.base_pose, planned_base, t0)
    streams = [
        stream_timing(s)
        for s in (rec.joint_commands, rec.joint_states, rec.actuator_commands, rec.actuator_states, rec.base_pose)
        if s is not None
    ]
    return Analysis(
        recording=rec,
        time_zero=time_zero,
        planned_joints=planned,
        planned_base=planned_base,
        window=window,
        joint_tracking=joint_tr,
        actuator_tracking=act_tr,
        joint_groups=group_errors(joint_tr, JOINT_GROUPS) if joint_tr is not None else [],
        actuator_groups=group_errors(act_tr, ACTUATOR_GROUPS) if act_tr is not None else [],
        base=base,
        fall=fall,
        loops=loop_timing(rec.diagnostics),
        streams=streams,
        faults=faults(rec.diagnostics, rec.estopped),
        transitions=transitions,
        extra=tuple(extra),
        notes=notes,
    )
