"""The report's Markdown: verdict lines first, then one table per section, figures linked by file name.

Units in the text: joint errors in mrad, linear-actuator errors and base deviation in mm, times in s
(``bag t`` counts from the bag's first message, ``tau`` is trajectory time).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Final

import numpy as np

from rh5_bringup.analysis.metrics import BASE_BAND_M, FALL_HEIGHT_FRACTION, FALL_TILT_DEG, GroupError
from rh5_bringup.analysis.results import Analysis
from rh5_msgs_py import interfaces
from rh5_msgs_py.names import JOINT_NAMES, LINEAR_ACTUATOR_NAMES

NOT_RECORDED: Final = "not recorded"
MAX_TEXT: Final = 240


def number(value: float) -> str:
    """A float for a table: 3 decimals without trailing zeros (1000 and more: none), n/a for NaN."""
    if not np.isfinite(value):
        return "n/a"
    if abs(value) >= 1000:
        return f"{value:.0f}"
    text = f"{value:.3f}".rstrip("0").rstrip(".")
    return "0" if text == "-0" else text


def _cell(value: object) -> str:
    if isinstance(value, float | np.floating):
        return number(float(value))
    return str(value).replace("|", "\\|").replace("\n", " ")


def table(header: Sequence[str], rows: Iterable[Sequence[object]]) -> list[str]:
    """A Markdown table (floats through ``number``)."""
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    lines += ["| " + " | ".join(_cell(v) for v in row) + " |" for row in rows]
    return lines


def title(bag: Path) -> str:
    """The experiment's name: the bag folder's, or its parent's when the folder is just called ``bag``."""
    bag = bag.resolve()
    return bag.parent.name if bag.name == "bag" else bag.name


def shorten(text: str, limit: int = MAX_TEXT) -> str:
    """``text`` cut to ``limit`` characters (long board lists in fault messages)."""
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _tau(analysis: Analysis, t: float) -> str:
    t0 = analysis.time_zero.t0
    return "n/a" if t0 is None else f"{t - t0:.3f}"


def _band_text() -> str:
    return ", ".join(f"{ax} [{lo * 1e3:+.0f}, {hi * 1e3:+.0f}] mm" for ax, (lo, hi) in BASE_BAND_M.items())


# --- verdicts ----------------------------------------------------------------------------------------------------


def _base_verdict(a: Analysis) -> str:
    if a.recording.base_pose is None:
        return f"**Floating base**: {NOT_RECORDED} (no {interfaces.SIM_BASE_POSE.name}: kinematic mode or real robot)"
    if a.base is None:
        why = "no planned_base_trajectory" if a.planned_base is None else "trajectory time 0 unknown"
        return f"**Floating base**: deviation not computable ({why})"
    inside = a.base.within_band()
    lo, hi = a.base.minimum * 1e3, a.base.maximum * 1e3
    ranges = ", ".join(f"{ax} [{lo[i]:+.1f}, {hi[i]:+.1f}] mm" for i, ax in enumerate("xyz"))
    if all(inside.values()):
        return f"**Floating base**: within the paper's PyBullet band ({_band_text()}) during the motion: {ranges}"
    out = ", ".join(ax for ax, ok in inside.items() if not ok)
    return f"**Floating base**: OUTSIDE the paper's PyBullet band in {out} ({_band_text()}): {ranges}"


def _fall_verdict(a: Analysis) -> str:
    if a.fall is None:
        return f"**Fell**: {NOT_RECORDED} (no base pose)"
    f = a.fall
    if not f.fell:
        return (
            f"**Fell**: no (lowest base height {f.min_height_ratio:.0%} of the {f.height_reference}, "
            f"largest tilt {f.max_tilt_deg:.1f} deg)"
        )
    assert f.t is not None
    return f"**Fell**: YES at bag t {f.t:.3f} s (tau {_tau(a, f.t)} s): {f.reason}"


def _tracking_verdict(a: Analysis) -> str:
    tr = a.joint_tracking
    if tr is None:
        return f"**Tracking**: {NOT_RECORDED} (needs joint_commands and joint_states)"
    total = float(np.sqrt(np.nanmean(tr.error**2)))
    worst = max(a.joint_groups, key=lambda g: g.rms)
    return (
        f"**Tracking** (joint space, {len(tr.t)} samples): RMS {total * 1e3:.3g} mrad over all joints; "
        f"worst group {worst.group} (RMS {worst.rms * 1e3:.3g} mrad, max {worst.max_abs * 1e3:.3g} mrad, "
        f"worst joint {worst.worst})"
    )


def _fault_verdict(a: Analysis) -> str:
    if not a.recording.diagnostics and a.recording.estopped is None:
        return f"**Faults**: {NOT_RECORDED} (no /diagnostics, no driver/estopped)"
    if not a.faults:
        only = "" if a.recording.diagnostics else " (no /diagnostics recorded: only driver/estopped was checked)"
        return "**Faults**: none" + only
    first = shorten(f"{a.faults[0].source}: {a.faults[0].text}", 100)
    return f"**Faults**: {len(a.faults)} distinct (first: {first})"


def _at_most(us: float) -> str:
    """A histogram percentile, which is known up to its bucket's upper edge."""
    return "-" if np.isnan(us) else f"<= {us:.0f}"


def _loop_verdict(a: Analysis) -> str:
    """The 1 kHz loops in one line: rate, jitter, misses, latency and scheduling; and the simulation's speed."""
    parts = [
        f"{x.node} {x.rate_hz:.2f} Hz, jitter p99 {_at_most(x.run_jitter_p99_us)} us over the run "
        f"({x.jitter_p99_us:.0f} in the worst second, max {x.jitter_max_us:.0f}), {x.deadline_misses} misses"
        + (f", {x.periods_over_2ms} periods over 2 ms" if x.periods_over_2ms >= 0 else "")
        + ("" if np.isnan(x.latency_p99_us) else f", telemetry -> command p99 {x.latency_p99_us:.0f} us")
        + (f", {x.scheduling}" if x.scheduling else "")
        for x in a.loops
    ]
    speed = a.recording.sim_speed
    sim = "" if speed is None else f"; simulation {speed:.2f} x real time"
    return "**Loops**: " + ("; ".join(parts) or NOT_RECORDED) + sim


def _verdicts(a: Analysis) -> list[str]:
    """The verdict lines in markdown: base band, fall, tracking, faults, loops."""
    return [_base_verdict(a), _fall_verdict(a), _tracking_verdict(a), _fault_verdict(a), _loop_verdict(a)]


def verdict_lines(analysis: Analysis) -> list[str]:
    """The verdict lines as plain text, e.g. for a terminal."""
    return [line.replace("**", "") for line in _verdicts(analysis)]


# --- sections ----------------------------------------------------------------------------------------------------


def _group_rows(groups: Sequence[GroupError], scale: float) -> list[list[object]]:
    return [[g.group, len(g.names), g.rms * scale, g.max_abs * scale, g.worst] for g in groups]


def _tracking_section(a: Analysis, figures: Mapping[str, str]) -> list[str]:
    lines = ["## Tracking", ""]
    if a.window is not None:
        lines.append(
            f"Errors (measured - reference) over the played trajectory, tau 0 to {a.window[1] - a.window[0]:.3f} s."
        )
    else:
        lines.append("Trajectory time unknown: errors over every sample with both reference and measurement.")
    lines.append("")
    if "tracking" in figures:
        lines += [f"![Tracking of the left ankle as in the paper]({figures['tracking']})", ""]
    lines += ["### Joint space", ""]
    if a.joint_groups:
        lines += table(["group", "joints", "RMS [mrad]", "max [mrad]", "worst joint"], _group_rows(a.joint_groups, 1e3))
    else:
        lines.append(f"{NOT_RECORDED} (joint_commands and joint_states are both needed).")
    lines += ["", "### Actuator space (linear actuators)", ""]
    if a.actuator_groups:
        lines += table(
            ["group", "actuators", "RMS [mm]", "max [mm]", "worst actuator"], _group_rows(a.actuator_groups, 1e3)
        )
    else:
        lines.append(f"{NOT_RECORDED} (actuator_commands and actuator_states are both needed).")
    if "errors" in figures:
        lines += ["", f"![RMS and max error per joint]({figures['errors']})"]
    if a.extra:
        lines += ["", "### Requested joints", ""]
        if "extra" in figures:
            lines += [f"![Requested joints]({figures['extra']})", ""]
        lines += table(["name", "RMS", "max", "unit"], [_extra_row(a, n) for n in a.extra])
    return [*lines, ""]


def _extra_row(a: Analysis, name: str) -> list[object]:
    result = a.joint_tracking if name in JOINT_NAMES else a.actuator_tracking
    if result is None or name not in result.names:
        return [name, NOT_RECORDED, "", ""]
    i = result.column(name)
    unit = "mm" if name in LINEAR_ACTUATOR_NAMES else "mrad"
    return [name, float(result.rms[i] * 1e3), float(result.max_abs[i] * 1e3), unit]


def _base_section(a: Analysis, figures: Mapping[str, str]) -> list[str]:
    lines = ["## Floating base", ""]
    if a.base is None:
        lines += [_base_verdict(a).replace("**Floating base**: ", "Deviation: "), ""]
    else:
        b = a.base
        lines += [
            "Measured base position (sim/base_pose) minus the planned base position at the same trajectory time, "
            f"during the motion (tau 0 to {b.motion_end:.3f} s). Paper (PyBullet, joint-space PD, planned walk): "
            "about +-10 mm in x and y and +5 mm in z.",
            "",
        ]
        if "base" in figures:
            lines += [f"![Floating-base deviation]({figures['base']})", ""]
        inside = b.within_band()
        rows = [
            [
                ax,
                b.rms[i] * 1e3,
                b.minimum[i] * 1e3,
                b.maximum[i] * 1e3,
                f"[{lo * 1e3:+.0f}, {hi * 1e3:+.0f}]",
                "yes" if inside[ax] else "NO",
            ]
            for i, (ax, (lo, hi)) in enumerate(BASE_BAND_M.items())
        ]
        lines += table(["axis", "RMS [mm]", "min [mm]", "max [mm]", "band [mm]", "within"], rows)
        start = b.at_start * 1e3
        lines += [
            "",
            "Offset at tau 0 (simulated vs planned start): "
            + ", ".join(f"{ax} {v:+.1f}" for ax, v in zip("xyz", start, strict=True))
            + " mm.",
        ]
    lines += [
        "",
        f"Fall check (base below {FALL_HEIGHT_FRACTION:.0%} of the planned height, else of the initial height, "
        f"or tilted beyond {FALL_TILT_DEG:.0f} deg, at any time): " + _fall_verdict(a).replace("**Fell**: ", ""),
        "",
    ]
    return lines


def _timing_section(a: Analysis) -> list[str]:
    lines = ["## Loop timing", ""]
    if a.loops:
        lines += table(
            [
                "node", "reports", "rate [Hz]", "jitter p99 [us] (run)", "jitter p99 [us] (worst s)",
                "jitter max [us]", "deadline misses", "periods > 2 ms", "cycle p99 [us]",
                "telemetry -> command p99 [us]", "scheduling",
            ],
            [
                [
                    x.node, x.reports, x.rate_hz, _at_most(x.run_jitter_p99_us), x.jitter_p99_us, x.jitter_max_us,
                    x.deadline_misses, x.periods_over_2ms if x.periods_over_2ms >= 0 else "-", x.cycle_p99_us,
                    x.latency_p99_us, x.scheduling or "-",
                ]
                for x in a.loops
            ],
        )  # fmt: skip
        lines += [
            "",
            "Jitter is |period - nominal period|. Run: over every period of the run, from the loop's histogram "
            "(the upper edge of the bucket holding the 99th percentile); worst s: the largest p99 of a one-second "
            "report. Telemetry -> command: from the read that took the boards' telemetry to the command frames "
            "computed from it, in the same cycle. Scheduling: SCHED_FIFO when the OS granted real-time priority "
            "(README, 'Real-time').",
        ]
    else:
        lines.append(f"Loop diagnostics {NOT_RECORDED}.")
    if a.recording.sim_speed is not None:
        lines += ["", f"Simulation speed: {a.recording.sim_speed:.3f} x real time (simulated s per wall-clock s)."]
    lines += [
        "",
        "Recorded streams, rates and periods on the wall clock the loops ran on (gaps include messages the "
        "best-effort recording dropped):",
        "",
    ]
    lines += table(
        ["topic", "messages", "rate [Hz]", "period p50 [ms]", "period p99 [ms]", "max gap [ms]", "times from"],
        [
            [s.topic, s.count, s.rate_hz, s.period_p50_ms, s.period_p99_ms, s.max_gap_ms, s.time_source]
            for s in a.streams
        ],
    )
    return [*lines, ""]


def _faults_section(a: Analysis) -> list[str]:
    lines = ["## Faults", ""]
    if a.faults:
        lines += table(
            ["first bag t [s]", "tau [s]", "last bag t [s]", "source", "reports", "what"],
            [
                [f"{f.first_t:.3f}", _tau(a, f.first_t), f"{f.last_t:.3f}", f.source, f.count, shorten(f.text)]
                for f in a.faults
            ],
        )
    else:
        text = _fault_verdict(a).replace("**Faults**: ", "")
        lines.append(text[:1].upper() + text[1:] + ".")
    if a.transitions:
        lines += ["", "Stabilizer state machine (from its 1 Hz diagnostics):", ""]
        lines += table(
            ["bag t [s]", "tau [s]", "state", "reason"],
            [[f"{tr.t:.3f}", _tau(a, tr.t), tr.state, tr.reason] for tr in a.transitions],
        )
    return [*lines, ""]


def render(analysis: Analysis, figures: Mapping[str, str]) -> str:
    """The whole report; ``figures`` maps 'tracking', 'base', 'errors', 'extra' to PNG file names."""
    a = analysis
    rec = a.recording
    tz = a.time_zero
    lines = [
        f"# Experiment report: {title(rec.path)}",
        "",
        f"Bag `{rec.path}`: {rec.duration_s:.3f} s, {sum(rec.topic_counts.values())} messages.",
        "",
        "## Verdict",
        "",
        *[
            f"- {v}"
            for v in (_base_verdict(a), _fall_verdict(a), _tracking_verdict(a), _fault_verdict(a), _loop_verdict(a))
        ],
        "",
        "## Trajectory time",
        "",
        f"tau = 0 at bag t {tz.t0:.3f} s, found from {tz.method}."
        if tz.t0 is not None
        else f"tau = 0 is unknown ({tz.method.removeprefix('unknown: ')}).",
    ]
    if tz.residual is not None:
        lines.append(f"Mean |joint_commands - planned_trajectory| after alignment: {tz.residual * 1e3:.3g} mrad.")
    lines += ["", *_tracking_section(a, figures), *_base_section(a, figures), *_timing_section(a), *_faults_section(a)]
    lines += ["## Recorded topics", ""]
    lines += table(["topic", "messages"], sorted(rec.topic_counts.items()))
    if a.notes:
        lines += ["", "## Notes", "", *[f"- {n}" for n in a.notes]]
    return "\n".join(lines) + "\n"
