"""The paper's planning figures as PNGs (matplotlib Figure objects rendered by Agg: no display, no pyplot state).

* :func:`plot_cop`: the CoP of each foot over time (crosses) against the allowed region, the 200 x 80 mm sole
  scaled to the configured fraction (dashed; the paper's "50 % foot coverage", fig:walkCoP), plus a top view of
  the sole with every CoP.
* :func:`plot_joints`: joint positions, velocities and torques against their limits (dashed), one column per
  joint of a symmetric pair (left solid, right dotted), by default the leg joints (fig:walkWeights_jointSpace).
  For the joints driven by one linear actuator (Hip3, knee) the configuration-dependent velocity and torque limits
  along the trajectory (actuator limit through the mechanism's transmission ratio) are drawn dash-dotted: the
  paper's figure could only show the joint table's constant values.
* :func:`plot_actuators`: the use of every linear actuator's stroke, velocity and force (Table I; 1 = at the
  limit) along the 1 kHz trajectory the planner publishes, one panel per kind and one line per actuator type, the
  worst of its actuators at each sample (issue 14: a plan with the actuator limits stays below 1).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from matplotlib.figure import Figure
from matplotlib.patches import Rectangle

from rh5_hyrodyn_mapper.kinematics.base import KinematicsError
from rh5_hyrodyn_mapper.mapping import robot_mapper
from rh5_hyrodyn_mapper.model import joint_limits
from rh5_msgs_py.array_types import FloatArray
from rh5_msgs_py.names import ACTUATOR_INDEX, JOINT_GROUPS, JOINT_INDEX, SUBMECHANISMS
from rh5_msgs_py.trajectory_file import NQ, TrajectoryData

from .feet import FOOT_SIZE_M
from .limit_scale import JOINT_KINDS, LimitScale, side_free_name

if TYPE_CHECKING:
    from matplotlib.axes import Axes

__all__ = ["LEG_JOINTS", "configuration_limits", "plot_actuators", "plot_cop", "plot_joints"]


LEG_JOINTS = JOINT_GROUPS["left_leg"] + JOINT_GROUPS["right_leg"]
_FOOT_LABELS = ("LF", "RF")
_FOOT_COLOURS = ("tab:blue", "tab:red")
_UNITS = {"position": "rad", "velocity": "rad/s", "torque": "Nm"}


def plot_cop(data: TrajectoryData, path: str | Path, *, cop_fraction: float = 0.5) -> Path:
    """CoP x and y of each foot in its sole frame over time, and a top view of the sole, against the allowed
    rectangle (``cop_fraction`` of each side of the 200 x 80 mm sole). Knots without contact are not drawn."""
    path = Path(path)
    times = np.asarray(data.times)
    cop = np.asarray(data.cop)
    contact = np.asarray(data.contact_phases, dtype=bool)
    half = 0.5 * cop_fraction * np.array(FOOT_SIZE_M)
    fig = Figure(figsize=(11, 5.5), layout="constrained")
    grid = fig.add_gridspec(2, 2, width_ratios=(2.2, 1))
    axes_time = [fig.add_subplot(grid[0, 0]), fig.add_subplot(grid[1, 0])]
    top = fig.add_subplot(grid[:, 1])
    for axis, ax in enumerate(axes_time):
        for foot in range(2):
            inside = contact[:, foot]
            ax.plot(
                times[inside],
                1e3 * cop[inside, foot, axis],
                "x",
                color=_FOOT_COLOURS[foot],
                label=_FOOT_LABELS[foot],
                markersize=5,
            )
        for sign in (-1, 1):
            ax.axhline(sign * 1e3 * half[axis], color="k", linestyle="--", linewidth=1)
            ax.axhline(sign * 1e3 * 0.5 * FOOT_SIZE_M[axis], color="0.6", linewidth=1)
        ax.set_ylabel(f"CoP {'xy'[axis]} [mm]")
        ax.grid(alpha=0.3)
    axes_time[0].legend(loc="upper right")
    axes_time[0].set_title(
        f"{data.motion.get('name', '')}: CoP per foot, allowed region {100 * cop_fraction:g} % (dashed), sole (grey)"
    )
    axes_time[1].set_xlabel("time [s]")
    length, width = 1e3 * np.array(FOOT_SIZE_M)
    top.add_patch(Rectangle((-length / 2, -width / 2), length, width, fill=False, edgecolor="0.6"))
    top.add_patch(
        Rectangle(
            (-1e3 * half[0], -1e3 * half[1]), 2e3 * half[0], 2e3 * half[1], fill=False, edgecolor="k", linestyle="--"
        )
    )
    for foot in range(2):
        inside = contact[:, foot]
        top.plot(
            1e3 * cop[inside, foot, 0],
            1e3 * cop[inside, foot, 1],
            "x",
            color=_FOOT_COLOURS[foot],
            label=_FOOT_LABELS[foot],
            markersize=5,
        )
    top.set_xlim(-0.6 * length, 0.6 * length)
    top.set_ylim(-0.6 * length, 0.6 * length)
    top.set_aspect("equal")
    top.set_xlabel("x [mm] (forward)")
    top.set_ylabel("y [mm]")
    top.set_title("sole frame, top view")
    top.grid(alpha=0.3)
    fig.savefig(path, dpi=110)
    return path


_SINGLE_ACTUATOR_JOINTS = {s.joints[0]: s.actuators[0] for s in SUBMECHANISMS if s.kind == "1-RRPR"}


def configuration_limits(q: FloatArray) -> dict[str, dict[str, FloatArray]]:
    """Velocity and torque limits along ``q`` (N, 32) of the joints driven by one linear actuator (Hip3, knee):
    actuator velocity / |dl/dq| and actuator force x |dl/dq|. Empty if the mapping fails."""
    mapper = robot_mapper()
    joints = list(_SINGLE_ACTUATOR_JOINTS)
    unit = np.zeros_like(q)
    unit[:, [JOINT_INDEX[j] for j in joints]] = 1.0  # one joint per mechanism: the rates do not interact
    try:
        rates = mapper.to_actuators(q, unit).velocity
    except (KinematicsError, ValueError):
        return {}
    out = {}
    for joint in joints:
        a = ACTUATOR_INDEX[_SINGLE_ACTUATOR_JOINTS[joint]]
        ratio = np.abs(np.asarray(rates)[:, a])
        with np.errstate(divide="ignore"):
            limits = mapper.limits
            out[joint] = {"velocity": limits.velocity_max[a] / ratio, "torque": limits.force_max[a] * ratio}
    return out


def _columns(joints: Sequence[str]) -> list[list[str]]:
    """Joints grouped by their side-free name, in first-seen order (a symmetric pair shares a column)."""
    groups: dict[str, list[str]] = {}
    for joint in joints:
        if joint not in JOINT_INDEX:
            msg = f"unknown joint {joint!r}"
            raise ValueError(msg)
        groups.setdefault(side_free_name(joint), []).append(joint)
    return list(groups.values())


def plot_joints(
    data: TrajectoryData,
    path: str | Path,
    *,
    joints: Sequence[str] = LEG_JOINTS,
    scale: LimitScale | None = None,
) -> Path:
    """Positions, velocities and torques of ``joints`` over time against their limits (dashed; scaled by
    ``scale`` when given). Torques are drawn as the zero-order hold the integrator applied."""
    path = Path(path)
    scale = scale or LimitScale()
    limits = joint_limits()
    times = np.asarray(data.times)
    values = {
        "position": np.asarray(data.joint_positions()),
        "velocity": np.asarray(data.joint_velocities()),
        "torque": np.asarray(data.controls),
    }
    lo, hi = np.asarray(limits.position_lower), np.asarray(limits.position_upper)
    mid, half = 0.5 * (lo + hi), 0.5 * (hi - lo) * scale.factors("position")
    bounds = {
        "position": (mid - half, mid + half),
        "velocity": (
            -np.asarray(limits.velocity_max) * scale.factors("velocity"),
            np.asarray(limits.velocity_max) * scale.factors("velocity"),
        ),
        "torque": (
            -np.asarray(limits.torque_max) * scale.factors("torque"),
            np.asarray(limits.torque_max) * scale.factors("torque"),
        ),
    }
    columns = _columns(joints)
    dependent = configuration_limits(values["position"])
    fig = Figure(figsize=(2.6 * len(columns) + 1, 7), layout="constrained")
    axes = fig.subplots(3, len(columns), sharex=True, squeeze=False)
    for col, group in enumerate(columns):
        for row, kind in enumerate(JOINT_KINDS):
            ax: Axes = axes[row, col]
            for n, joint in enumerate(group):
                j = JOINT_INDEX[joint]
                style = "-" if n == 0 else ":"
                if kind == "torque":
                    series = values[kind][:, j]
                    t = times[: len(series) + 1]
                    ax.step(t, np.append(series, series[-1])[: len(t)], where="post", linestyle=style, label=joint)
                else:
                    ax.plot(times, values[kind][:, j], style, label=joint)
            j0 = JOINT_INDEX[group[0]]
            for bound in bounds[kind]:
                ax.axhline(bound[j0], color="k", linestyle="--", linewidth=1)
            if group[0] in dependent and kind in dependent[group[0]]:
                limit = dependent[group[0]][kind] * scale.factors(kind)[j0]
                for sign in (-1, 1):
                    ax.plot(
                        times,
                        sign * limit,
                        color="0.45",
                        linestyle="-.",
                        linewidth=1,
                        label="config.-dependent" if sign > 0 else None,
                    )
            ax.grid(alpha=0.3)
            if col == 0:
                ax.set_ylabel(f"{kind} [{_UNITS[kind]}]")
            if row == 0:
                ax.set_title(side_free_name(group[0]))
                ax.legend(fontsize=7, loc="best")
            if row == len(JOINT_KINDS) - 1:
                ax.set_xlabel("time [s]")
    fig.suptitle(
        f"{data.motion.get('name', '')}: joint space against the limits (dashed; dash-dotted: configuration-dependent)"
    )
    fig.savefig(path, dpi=100)
    return path


def plot_actuators(data: TrajectoryData, path: str | Path, *, reference: TrajectoryData | None = None) -> Path:
    """Stroke, velocity and force use of the linear actuators at 1 kHz (worst actuator of each type per sample),
    against 1 = the Table I limit; ``reference`` (e.g. the same motion planned with the paper's cost set) is drawn
    thin and grey for comparison."""
    from .actuator_bounds import parallel_units  # noqa: PLC0415
    from .actuator_constraints import LINEAR_ACTUATORS, actuator_usage  # noqa: PLC0415
    from .interpolation import interpolate  # noqa: PLC0415

    path = Path(path)
    types: dict[str, list[int]] = {}
    for unit in parallel_units():
        label = unit.name[2:] if unit.name[:2] in ("LL", "LR", "AL", "AR") else unit.name
        types.setdefault(label, []).extend(LINEAR_ACTUATORS.index(a) for a in unit.actuators)

    def usage(source: TrajectoryData) -> tuple[FloatArray, dict[str, FloatArray]]:
        fine = interpolate(source, joints_only=True)
        q, v = fine.states[:, 7:NQ], fine.states[:, NQ + 6 :]
        return fine.times, actuator_usage(q, v, fine.controls)

    fig = Figure(figsize=(11, 7), layout="constrained")
    axes = fig.subplots(3, 1, sharex=True)
    colours = dict(zip(types, ("tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple"), strict=False))
    runs = [(reference, True), (data, False)] if reference is not None else [(data, False)]
    for source, grey in runs:
        times, use = usage(source)
        for ax, kind in zip(axes, ("stroke", "velocity", "force"), strict=True):
            for label, columns in types.items():
                worst = use[kind][:, columns].max(axis=1)
                style = {"color": "0.6", "lw": 0.8} if grey else {"color": colours[label], "lw": 1.2, "label": label}
                ax.plot(times[: len(worst)], worst, **style)
    for ax, kind in zip(axes, ("stroke", "velocity", "force"), strict=True):
        ax.axhline(1.0, color="k", ls="--", lw=1.0)
        ax.set_ylabel(f"{kind} use")
        ax.set_ylim(bottom=0.0)
        ax.grid(alpha=0.3)
    fig.legend(*axes[0].get_legend_handles_labels(), fontsize=8, ncol=5, loc="outside lower center")  # off the traces
    note = " (grey: reference plan)" if reference is not None else ""
    axes[0].set_title(f"{data.motion.get('name', '?')}: linear actuators against Table I at 1 kHz{note}")
    axes[-1].set_xlabel("time [s]")
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    return path
