"""The result table of a sweep, one row per point, as CSV (``sweep.csv``), and its short text summary.

Columns: ``point``, the swept keys, then the verdict (``status``, ``converged``, ``feasible``, ``limiting`` with its
use ``limiting_use``, the jump's ``task``), the solve (``iterations``, ``solve_s``, ``cpu_s``, ``warm_from``,
``warm_started``, ``attempt``, ``host``, ``pid``), the contacts (``cop_inside``, ``friction_inside``: fractions of
the contact foot-knots), the peak use per limit kind (``peak.<kind>``) and every limit's use in joint and actuator
space (``use.<kind>.<joint or actuator>``: peak |value| / limit, 1 = at the limit, against the point's scaled
limits), last ``error``. Parquet would need pyarrow, which is not in the lock; CSV reads everywhere.
"""

from __future__ import annotations

import csv
import math
from collections import Counter
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, Final

from .point import STATUSES, use_columns

__all__ = ["columns", "summary", "write_csv"]

_VERDICT: Final = ("status", "converged", "feasible", "limiting", "limiting_use", "task")
_SOLVE: Final = ("iterations", "solve_s", "cpu_s", "warm_from", "warm_started", "attempt", "host", "pid")
_CONTACT: Final = ("cop_inside", "friction_inside")
_PEAKS: Final = tuple(f"peak.{k}" for k in ("position", "velocity", "torque", "stroke", "actuator_velocity", "force"))


def columns(keys: Sequence[str]) -> list[str]:
    """Every column, in order, for a sweep over ``keys``."""
    return ["point", *keys, *_VERDICT, *_SOLVE, *_CONTACT, *_PEAKS, *use_columns(), "error"]


def _cell(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return ""
    if isinstance(value, float):
        return f"{value:.6g}"
    return value


def write_csv(rows: Sequence[Mapping[str, Any]], keys: Sequence[str], path: str | Path) -> Path:
    """Write ``rows`` (grid order) to ``path``; missing cells stay empty."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    names = columns(keys)
    with path.open("w", newline="", encoding="utf-8") as file:
        writer = csv.DictWriter(file, fieldnames=names, extrasaction="ignore")
        writer.writeheader()
        for row in rows:
            writer.writerow({k: _cell(row.get(k, "")) for k in names})
    return path


def summary(rows: Sequence[Mapping[str, Any]]) -> str:
    """``25 points: 14 feasible, 6 over_limits, 5 not_converged; limiting: Knee act. velocity 9, ...``."""
    counts = Counter(str(r.get("status")) for r in rows)
    parts = [f"{counts[s]} {s}" for s in STATUSES if counts[s]]
    limiting = Counter(str(r.get("limiting")) for r in rows if r.get("status") != "feasible" and r.get("limiting"))
    text = f"{len(rows)} points: {', '.join(parts)}"
    if limiting:
        text += "; limiting where infeasible: " + ", ".join(f"{k} {n}" for k, n in limiting.most_common())
    return text
