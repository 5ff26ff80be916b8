"""The Python side of the C kernels (``unit_maps.c``, module ``_compiled``), where every submechanism's maths lives.

A unit is one row of constants; a table is one row (a model's maps) or every unit of the robot (RobotMapper's). The
three calls take N samples at once, so one sample is a batch of one through the same code. The extension is built
with the package (``make venv``, setup.py): there is no other implementation to fall back to.

* ``ik(table, n, q, v, a, tau, max_condition, l, ld, ldd, f, info)``: joints -> actuators (l, J v, J a + bias,
  J^-T tau); every array C-contiguous float64 or None (but q and l; a needs v).
* ``fk(table, n, l, ld, f, y_guess, y, yd, tau, info)``: actuators -> joints (closed form or Newton, J^-1 ld, J^T f).
* ``pose(table, n, y, yd, jac, bias, cond)``: J (n, m, m), bias (n, m; needs yd), condition number (n) of a one-row
  table, each where not None.

ik and fk return -1, or sample * rows + row of the first unit that failed; given ``info`` (n, rows, 2) they map
every sample and record each unit's status (ik: 0 or -1 refused; fk: Newton iterations, or a FK_* code) and detail
(ik: condition number; fk: final residual [m]).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Final

import numpy as np

from rh5_hyrodyn_mapper.kinematics._compiled import MAX_DOF, ROW_WIDTH, fk, ik, pose
from rh5_msgs_py.array_types import FloatArray

__all__ = [
    "FK_NOT_CONVERGED",
    "FK_SINGULAR",
    "FK_UNREACHABLE",
    "FK_WRONG_MODE",
    "KIND_COPY",
    "KIND_LINEAR",
    "KIND_RRPR",
    "KIND_SPRR",
    "KIND_SPU",
    "MAX_DOF",
    "ROW_WIDTH",
    "fk",
    "ik",
    "pose",
    "row",
    "table",
]


KIND_COPY: Final = 0
KIND_RRPR: Final = 1
KIND_SPU: Final = 2
KIND_SPRR: Final = 3
KIND_LINEAR: Final = 4
FK_NOT_CONVERGED: Final = -1  # Newton did not reach the tolerance
FK_WRONG_MODE: Final = -2  # Newton converged with det J of another sign than at the zero pose
FK_UNREACHABLE: Final = -3  # a closed-form length outside the assemblable range
FK_SINGULAR: Final = -4  # y found, but J(y) is singular: no joint rates


def row(kind: int, dof: int, constants: Sequence[float], joint: int = 0, actuator: int = 0) -> list[float]:
    """One unit's row: kind, dof, first joint, first actuator, then its constants (layout in ``unit_maps.h``)."""
    values = [float(kind), float(dof), float(joint), float(actuator), *(float(c) for c in constants)]
    if len(values) > ROW_WIDTH:
        raise ValueError(f"a unit row holds at most {ROW_WIDTH} values, got {len(values)}")
    return values


def table(rows: Sequence[Sequence[float]]) -> FloatArray:
    """A read-only (rows, ROW_WIDTH) table of unit rows, zero-padded; neighbouring pass-through (COPY) rows, whose
    joints and actuators both follow on, become one row (fewer rows for the 1 kHz call to walk)."""
    merged: list[list[float]] = []
    for values in rows:
        last = merged[-1] if merged else None
        if (
            last is not None
            and values[0] == last[0] == KIND_COPY
            and values[2] == last[2] + last[1]
            and values[3] == last[3] + last[1]
        ):
            last[1] += values[1]
        else:
            merged.append(list(values))
    out = np.zeros((len(merged), ROW_WIDTH))
    for k, values in enumerate(merged):
        out[k, : len(values)] = values
    out.setflags(write=False)
    return out
