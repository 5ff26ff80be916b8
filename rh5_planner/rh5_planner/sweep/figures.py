"""Figures of a sweep: the feasibility heat map, the limiting-factor map and the minimal actuator specification.

* ``feasibility.png``: per point the use of its most-used required limit (1 = at the limit; colour bar), with the
  verdict in the cell (a tick: feasible; a cross: over a limit; ``nc``: not converged; ``low``: the jump stayed
  below 90 % of its height; ``err``: failed).
* ``limiting.png``: per point the limiting factor (the required limit used most), one colour per limit.
* ``minimal_<key>.png`` for every limit axis (``knee:velocity``): the smallest factor on that limit that made the
  motion feasible, along the first other axis (one line per value of a third), in Table I units for the linear
  actuators (mm/s, N, stroke mm), the paper's heuristic applied along a parameter.

The first axis of the sweep runs along x, the second along y; further axes give one panel per value combination.
Limit axes read in Table I units where the joints have linear actuators (``x3`` of the knee velocity is 420 mm/s).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, Final

import numpy as np

from .grid import SPEED_KEY, Grid

__all__ = ["axis_label", "feasibility_map", "limiting_map", "minimal_spec", "minimal_specification", "write_figures"]

_MARK: Final = {
    "feasible": "\u2713",
    "over_limits": "\u2717",
    "not_converged": "nc",
    "task_missed": "low",
    "failed": "err",
}
_KEY: Final = (
    "\u2713 feasible   \u2717 over a required limit   nc not converged   low: jump below 90 % of its height   "
    "err: failed"
)
_UNITS: Final = (
    ("_kg_per_hand", "kg per hand", 1.0),
    ("_m_s", "m/s", 1.0),
    ("_rad", "rad", 1.0),
    ("_cm", "cm", 1.0),
    ("_m", "m", 1.0),
    ("_s", "s", 1.0),
)
_KIND_UNIT: Final = {
    "velocity": ("velocity", "mm/s", 1e3),
    "torque": ("force", "N", 1.0),
    "position": ("stroke", "mm", 1e3),
}


def actuator_base(key: str) -> tuple[str, float, str] | None:
    """For a limit key ``pattern:kind`` whose joints are driven by linear actuators: (label, Table I value at x1 in
    display units, unit), e.g. ``("Knee actuator velocity", 140.0, "mm/s")``; None otherwise. Stroke is the half
    range the factor widens."""
    from ..actuator_bounds import parallel_units  # noqa: PLC0415
    from ..limit_scale import match_joints  # noqa: PLC0415

    pattern, _, kind = key.rpartition(":")
    joints = set(match_joints(pattern))
    units = [u for u in parallel_units() if joints & set(u.joints)]
    if not units:
        return None
    unit = units[0]
    what, text, to_display = _KIND_UNIT[kind]
    limits = unit.limits
    if kind == "velocity":
        value = float(limits.velocity_max[0])
    elif kind == "torque":
        value = float(limits.force_max[0])
    else:
        value = 0.5 * float(limits.length_max[0] - limits.length_min[0])
    name = unit.name[2:] if unit.name[:2] in ("LL", "LR", "AL", "AR") else unit.name
    return f"{name} actuator {what}", value * to_display, text


def axis_label(key: str) -> str:
    """Readable axis title with its unit: ``payload_kg_per_hand`` -> ``payload [kg per hand]``,
    ``knee:velocity`` -> ``Knee actuator velocity [mm/s] (x1 = Table I, 140 mm/s)``."""
    if ":" in key:
        base = actuator_base(key)
        pattern, _, kind = key.rpartition(":")
        if base is None:
            return f"{pattern} {kind} limit [x joint limit]"
        label, value, unit = base
        return f"{label} [{unit}]\n(x1 = Table I, {value:g} {unit})"
    if key == SPEED_KEY:
        return "average speed [m/s]"
    for suffix, unit, _ in _UNITS:
        if key.endswith(suffix):
            return f"{key[: -len(suffix)].replace('_', ' ')} [{unit}]"
    return key.replace("_", " ")


def _ticks(key: str, values: Sequence[float]) -> list[str]:
    base = actuator_base(key) if ":" in key else None
    if base is None:
        return [f"x{v:g}" if ":" in key else f"{v:g}" for v in values]
    return [f"{v * base[1]:.0f}\nx{v:g}" for v in values]


def _panels(grid: Grid) -> list[dict[str, float]]:
    """Value combinations of the axes beyond the first two (one panel each)."""
    rest = grid.axes[2:]
    return [
        dict(zip([a.key for a in rest], combo, strict=True)) for combo in itertools.product(*(a.values for a in rest))
    ]


def _matrix(
    grid: Grid, rows: Mapping[tuple[float, ...], Mapping[str, Any]], field: str, fixed: Mapping[str, float]
) -> list[list[Any]]:
    """(len(y), len(x)) cells of ``field``; the y axis is a single row for a one-axis sweep."""
    x_axis = grid.axes[0]
    y_values: Sequence[float | None] = grid.axes[1].values if len(grid.axes) > 1 else (None,)
    out = []
    for y in y_values:
        line = []
        for x in x_axis.values:
            values = [x] + ([y] if y is not None else []) + [fixed[a.key] for a in grid.axes[2:]]
            row = rows.get(tuple(values), {})
            line.append(row.get(field))
        out.append(line)
    return out


def _by_values(grid: Grid, rows: Sequence[Mapping[str, Any]]) -> dict[tuple[float, ...], Mapping[str, Any]]:
    return {tuple(float(r[k]) for k in grid.keys): r for r in rows if all(k in r for k in grid.keys)}


def _figure(grid: Grid, title: str):  # type: ignore[no-untyped-def]
    import matplotlib  # noqa: PLC0415

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415

    panels = _panels(grid)
    n = len(panels)
    cols = min(3, n)
    nrows = math.ceil(n / cols)
    nx = len(grid.axes[0].values)
    ny = len(grid.axes[1].values) if len(grid.axes) > 1 else 1
    width = min(16.0, max(7.5, 0.9 * nx * cols + 2.5))
    height = min(12.0, max(3.0, 0.7 * ny * nrows + 2.2))
    fig, axes = plt.subplots(nrows, cols, figsize=(width, height), squeeze=False, constrained_layout=True)
    for extra in axes.flat[n:]:
        extra.set_visible(False)
    fig.suptitle(title)
    return fig, list(axes.flat[:n]), panels


def _decorate(ax: Any, grid: Grid, fixed: Mapping[str, float]) -> None:
    x_axis = grid.axes[0]
    ax.set_xticks(range(len(x_axis.values)), _ticks(x_axis.key, x_axis.values))
    ax.set_xlabel(axis_label(x_axis.key))
    if len(grid.axes) > 1:
        y_axis = grid.axes[1]
        ax.set_yticks(range(len(y_axis.values)), _ticks(y_axis.key, y_axis.values))
        ax.set_ylabel(axis_label(y_axis.key))
    else:
        ax.set_yticks([])
    if fixed:
        ax.set_title(", ".join(f"{axis_label(k)} = {v:g}" for k, v in fixed.items()), fontsize=9)


def _title(grid: Grid, what: str) -> str:
    return f"{grid.motion}: {what} ({grid.size} points)"


def feasibility_map(grid: Grid, rows: Sequence[Mapping[str, Any]], path: str | Path) -> Path:
    """The feasibility heat map (see the module docstring)."""
    from matplotlib.colors import TwoSlopeNorm  # noqa: PLC0415

    by_values = _by_values(grid, rows)
    uses = [float(r["limiting_use"]) for r in rows if isinstance(r.get("limiting_use"), int | float)]
    finite = [u for u in uses if math.isfinite(u)]
    vmax = max([1.5, *finite]) if finite else 1.5
    norm = TwoSlopeNorm(vmin=0.0, vcenter=1.0, vmax=vmax)
    fig, axes, panels = _figure(grid, _title(grid, "feasibility and highest limit use"))
    image = None
    for ax, fixed in zip(axes, panels, strict=True):
        use = np.array(
            [
                [float(v) if isinstance(v, int | float) else np.nan for v in line]
                for line in _matrix(grid, by_values, "limiting_use", fixed)
            ]
        )
        status = _matrix(grid, by_values, "status", fixed)
        image = ax.imshow(use, cmap="RdYlGn_r", norm=norm, origin="lower", aspect="auto")
        for (iy, ix), value in np.ndenumerate(use):
            mark = _MARK.get(str(status[iy][ix]), "")
            text = f"{mark}\n{value:.2f}" if math.isfinite(value) else mark or "?"
            ax.text(ix, iy, text, ha="center", va="center", fontsize=8)
        _decorate(ax, grid, fixed)
    if image is not None:
        bar = fig.colorbar(image, ax=axes, shrink=0.9)
        bar.set_label("highest use of a required limit (1 = at the limit)")
    fig.supxlabel(_KEY, fontsize=8)
    return _save(fig, path)


def limiting_map(grid: Grid, rows: Sequence[Mapping[str, Any]], path: str | Path) -> Path:
    """The limiting-factor map (see the module docstring)."""
    import matplotlib.pyplot as plt  # noqa: PLC0415
    from matplotlib.colors import ListedColormap  # noqa: PLC0415
    from matplotlib.patches import Patch  # noqa: PLC0415

    by_values = _by_values(grid, rows)
    labels = sorted({str(r.get("limiting") or "none") for r in rows})
    index = {label: i for i, label in enumerate(labels)}
    colours = plt.get_cmap("tab10" if len(labels) <= 10 else "tab20").colors[: len(labels)]
    cmap = ListedColormap(colours)
    fig, axes, panels = _figure(grid, _title(grid, "limiting factor, the required limit used most"))
    for ax, fixed in zip(axes, panels, strict=True):
        names = _matrix(grid, by_values, "limiting", fixed)
        status = _matrix(grid, by_values, "status", fixed)
        codes = np.array(
            [[index[str(n or "none")] if n is not None else np.nan for n in line] for line in names], dtype=float
        )
        ax.imshow(codes, cmap=cmap, vmin=-0.5, vmax=len(labels) - 0.5, origin="lower", aspect="auto")
        for (iy, ix), _ in np.ndenumerate(codes):
            ax.text(ix, iy, _MARK.get(str(status[iy][ix]), ""), ha="center", va="center", fontsize=9)
        _decorate(ax, grid, fixed)
    handles = [Patch(facecolor=colours[i], label=label) for label, i in index.items()]
    fig.legend(
        handles=handles, loc="outside lower center", ncols=min(4, len(handles)), title="limiting factor", fontsize=8
    )
    return _save(fig, path)


def minimal_specification(
    grid: Grid, rows: Sequence[Mapping[str, Any]], spec_key: str
) -> list[tuple[dict[str, float], float | None]]:
    """For every combination of the other axes: the smallest ``spec_key`` factor with a feasible plan (None: none
    of the swept factors made it feasible)."""
    others = [a for a in grid.axes if a.key != spec_key]
    out = []
    for combo in itertools.product(*(a.values for a in others)):
        fixed = dict(zip([a.key for a in others], combo, strict=True))
        feasible = [
            float(r[spec_key])
            for r in rows
            if r.get("status") == "feasible" and all(float(r[k]) == v for k, v in fixed.items())
        ]
        out.append((fixed, min(feasible) if feasible else None))
    return out


def minimal_spec(grid: Grid, rows: Sequence[Mapping[str, Any]], spec_key: str, path: str | Path) -> Path:
    """The minimal ``spec_key`` along the first other axis (one line per value of the remaining ones)."""
    import matplotlib  # noqa: PLC0415

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415

    spec_axis = next(a for a in grid.axes if a.key == spec_key)
    others = [a for a in grid.axes if a.key != spec_key]
    base = actuator_base(spec_key)
    scale = base[1] if base else 1.0
    fig, ax = plt.subplots(figsize=(7.0, 4.5), constrained_layout=True)
    table = minimal_specification(grid, rows, spec_key)
    top = max(spec_axis.values) * scale
    if others:
        along = others[0]
        groups: dict[tuple[tuple[str, float], ...], list[tuple[float, float | None]]] = {}
        for fixed, minimum in table:
            rest = tuple((k, v) for k, v in fixed.items() if k != along.key)
            groups.setdefault(rest, []).append((fixed[along.key], minimum))
        along_base = actuator_base(along.key) if ":" in along.key else None
        along_scale = along_base[1] if along_base else 1.0
        for rest, line in groups.items():
            xs = np.array([x * along_scale for x, _ in line])
            ys = np.array([np.nan if m is None else m * scale for _, m in line])
            label = ", ".join(f"{axis_label(k)} = {v:g}" for k, v in rest) or "feasible from"
            ax.plot(xs, ys, marker="o", label=label)
            none = np.isnan(ys)
            if none.any():
                ax.scatter(xs[none], np.full(none.sum(), top), marker="^", color="k", zorder=3)
        ax.set_xlabel(axis_label(along.key) if along_base is None else f"{along_base[0]} [{along_base[2]}]")
    else:
        _, minimum = table[0]
        ax.bar([0], [np.nan if minimum is None else minimum * scale])
        ax.set_xticks([])
    ax.axhline(top, color="k", lw=0.6, ls=":")
    if any(minimum is None for _, minimum in table):
        ax.annotate(
            "\u25b2 none of the swept values", (0.99, 0.99), xycoords="axes fraction", ha="right", va="top", fontsize=8
        )
    ylabel = f"minimal {base[0]} [{base[2]}]" if base else f"minimal {spec_key} factor"
    ax.set_ylabel(ylabel)
    ax.set_ylim(0, top * 1.08)
    if base:
        twin = ax.secondary_yaxis("right", functions=(lambda y: y / scale, lambda f: f * scale))
        twin.set_ylabel("x Table I")
    ax.grid(alpha=0.3)
    if others and len(ax.get_legend_handles_labels()[0]) > 1:
        ax.legend(fontsize=8)
    ax.set_title(f"{grid.motion}: minimal {base[0] if base else spec_key} for a feasible plan")
    return _save(fig, path)


def _save(fig: Any, path: str | Path) -> Path:
    import matplotlib.pyplot as plt  # noqa: PLC0415

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def file_key(key: str) -> str:
    """A file-name form of an axis key: ``knee:velocity`` -> ``knee_velocity``."""
    return "".join(c if c.isalnum() or c in "-_." else "_" for c in key)


def write_figures(grid: Grid, rows: Sequence[Mapping[str, Any]], folder: str | Path) -> list[Path]:
    """Every figure of the sweep into ``folder``."""
    folder = Path(folder)
    written = [
        feasibility_map(grid, rows, folder / "feasibility.png"),
        limiting_map(grid, rows, folder / "limiting.png"),
    ]
    for axis in grid.axes:
        if axis.is_limit:
            written.append(minimal_spec(grid, rows, axis.key, folder / f"minimal_{file_key(axis.key)}.png"))
    return written
