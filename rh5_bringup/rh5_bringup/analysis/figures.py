"""The report's PNG plots: tracking like the paper's figure, base deviation, per-joint errors.

Figures are drawn on their own Agg canvas, never through pyplot, so making a report changes no global
matplotlib state (backend, open figures) of the process that calls it.

Time axes are trajectory time (s since the stabilizer started playing) when that is known, else
bag time. Linear actuators are drawn in mm, joints and rotary actuators in rad.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Final

import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from rh5_bringup.analysis.markdown import number
from rh5_bringup.analysis.metrics import BASE_BAND_M
from rh5_bringup.analysis.records import JointSeries
from rh5_bringup.analysis.results import Analysis
from rh5_msgs_py.array_types import FloatArray
from rh5_msgs_py.names import JOINT_NAMES, LINEAR_ACTUATOR_NAMES

PAPER_ACTUATORS: Final = ("LLAnkle_Act1", "LLAnkle_Act2")
PAPER_JOINTS: Final = ("LLAnkleRoll", "LLAnklePitch")
"""The paper's tracking figure (exp:BalancingTracking): left ankle, actuator space (a, b), joint space (c, d)."""
MAX_PLOT_POINTS: Final = 20_000
DPI: Final = 110
REFERENCE_STYLE: Final = {"color": "tab:blue", "linestyle": "--", "linewidth": 1.2, "label": "reference"}
MEASURED_STYLE: Final = {"color": "tab:orange", "linewidth": 1.0, "label": "measured"}


def _new_figure(width: float, height: float) -> Figure:
    fig = Figure(figsize=(width, height), layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def _thin(n: int) -> slice:
    return slice(None, None, max(1, n // MAX_PLOT_POINTS))


def _time_axis(analysis: Analysis) -> tuple[float, str]:
    t0 = analysis.time_zero.t0
    return (t0, "trajectory time [s]") if t0 is not None else (0.0, "bag time [s]")


def _unit(name: str) -> tuple[float, str]:
    return (1e3, "mm") if name in LINEAR_ACTUATOR_NAMES else (1.0, "rad")


def _series_pair(analysis: Analysis, name: str) -> tuple[JointSeries | None, JointSeries | None, str]:
    rec = analysis.recording
    if name in JOINT_NAMES:
        return rec.joint_commands, rec.joint_states, "joint"
    return rec.actuator_commands, rec.actuator_states, "actuator"


def _rms_text(analysis: Analysis, name: str, space: str) -> str:
    result = analysis.joint_tracking if space == "joint" else analysis.actuator_tracking
    if result is None or name not in result.names:
        return ""
    unit = "mm" if name in LINEAR_ACTUATOR_NAMES else "mrad"
    i = result.column(name)
    return f"RMS {number(result.rms[i] * 1e3)} {unit}, max {number(result.max_abs[i] * 1e3)} {unit}"


def _plot_tracking(ax: Axes, analysis: Analysis, name: str) -> None:
    reference, measured, space = _series_pair(analysis, name)
    origin, xlabel = _time_axis(analysis)
    scale, unit = _unit(name)
    drawn = False
    for series, style in ((reference, REFERENCE_STYLE), (measured, MEASURED_STYLE)):
        col = None if series is None else series.index(name)
        if series is None or col is None:
            continue
        cut = _thin(len(series.t))
        ax.plot(series.t[cut] - origin, series.position[cut, col] * scale, **style)
        drawn = True
    if not drawn:
        missing = f"{space}_commands / {space}_states not recorded"
        ax.text(0.5, 0.5, missing, ha="center", va="center", transform=ax.transAxes, color="gray")
    if analysis.window is not None:
        lo, hi = analysis.window
        ax.axvspan(lo - origin, hi - origin, color="0.93", zorder=0)
    rms = _rms_text(analysis, name, space)
    ax.set_title(f"{name}" + (f"  ({rms})" if rms else ""), fontsize=9)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(f"position [{unit}]")
    ax.grid(True, alpha=0.3)
    if drawn:
        ax.legend(fontsize=8, loc="best")


def tracking_figure(analysis: Analysis, path: Path, names: Sequence[str], columns: int = 2) -> Path:
    """Reference vs measured position of ``names`` (joints or actuators), ``columns`` per row."""
    rows = max(1, -(-len(names) // columns))
    fig = _new_figure(5.2 * columns, 3.2 * rows)
    axes = np.atleast_1d(fig.subplots(rows, columns, squeeze=False)).ravel()
    for ax, name in zip(axes, names, strict=False):
        _plot_tracking(ax, analysis, name)
    for ax in axes[len(names) :]:
        ax.set_visible(False)
    fig.suptitle("Tracking: reference vs measured (shaded: played trajectory)", fontsize=10)
    fig.savefig(path, dpi=DPI)
    return path


def paper_tracking_figure(analysis: Analysis, path: Path) -> Path:
    """The paper's tracking figure: LLAnkle_Act1/2 (actuator space) over LLAnkleRoll/Pitch (joint space)."""
    return tracking_figure(analysis, path, PAPER_ACTUATORS + PAPER_JOINTS)


def _deviation_axes(fig: Figure, curves: Mapping[str, tuple[FloatArray, FloatArray]]) -> Sequence[Axes]:
    """Three stacked axes (x, y, z in mm over trajectory time) with the paper's bands and each curve
    (label -> (times [s], (M, 3) deviation [m])); legends and titles are the caller's."""
    axes = fig.subplots(3, 1, sharex=True)
    for i, (ax, axis) in enumerate(zip(axes, "xyz", strict=True)):
        lo, hi = BASE_BAND_M[axis]
        ax.axhspan(
            lo * 1e3, hi * 1e3, color="tab:green", alpha=0.12, label=f"paper band [{lo * 1e3:+.0f}, {hi * 1e3:+.0f}] mm"
        )
        for label, (times, deviation) in curves.items():
            cut = _thin(len(times))
            ax.plot(times[cut], deviation[cut, i] * 1e3, linewidth=1.0, label=label.format(axis=axis))
        ax.set_ylabel(f"{axis} [mm]")
        ax.grid(True, alpha=0.3)
    axes[-1].set_xlabel("trajectory time [s]")
    return axes


def base_figure(analysis: Analysis, path: Path) -> Path | None:
    """Floating-base deviation x/y/z (mm) over trajectory time with the paper's bands; None if not computable."""
    base = analysis.base
    if base is None:
        return None
    fig = _new_figure(8.0, 7.0)
    for ax in _deviation_axes(fig, {"{axis} deviation": (base.tau, base.deviation)}):
        ax.axvline(base.motion_end, color="0.5", linestyle=":", linewidth=1.0, label="end of motion")
        _mark_fall(ax, analysis)
        ax.legend(fontsize=8, loc="best")
    fig.suptitle("Floating base: measured minus planned position", fontsize=10)
    fig.savefig(path, dpi=DPI)
    return path


def replay_figure(curves: Mapping[str, tuple[FloatArray, FloatArray]], path: Path, title: str) -> Path:
    """Base deviation x/y/z (mm) of several in-process replays (label -> (times [s], (M, 3) deviation [m])) over
    trajectory time, with the paper's bands (bench/walk_pybullet.py)."""
    fig = _new_figure(8.0, 7.0)
    for ax in _deviation_axes(fig, curves):
        ax.legend(fontsize=8, loc="best")
    fig.suptitle(title, fontsize=10)
    fig.savefig(path, dpi=DPI)
    return path


def _mark_fall(ax: Axes, analysis: Analysis) -> None:
    fall = analysis.fall
    if fall is None or not fall.fell or fall.t is None:
        return
    origin, _ = _time_axis(analysis)
    ax.axvline(fall.t - origin, color="tab:red", linewidth=1.5, label="fell")


def error_bars_figure(analysis: Analysis, path: Path) -> Path | None:
    """RMS and max |error| of every joint over the played trajectory (mrad); None without joint tracking."""
    result = analysis.joint_tracking
    if result is None:
        return None
    x = np.arange(len(result.names))
    fig = _new_figure(11.0, 4.0)
    ax = fig.subplots()
    rms: FloatArray = result.rms * 1e3
    peak: FloatArray = result.max_abs * 1e3
    ax.bar(x - 0.2, rms, width=0.4, label="RMS")
    ax.bar(x + 0.2, peak, width=0.4, label="max |error|")
    ax.set_xticks(x, result.names, rotation=70, fontsize=7)
    ax.set_ylabel("joint tracking error [mrad]")
    ax.grid(True, axis="y", alpha=0.3)
    ax.legend(fontsize=8)
    fig.savefig(path, dpi=DPI)
    return path
