"""The whole robot's maps of one sample through the C kernels (``_compiled.c``), for the 1 kHz control cycle.

The submechanisms' Python float paths stay the reference and the fallback: :class:`CompiledMaps` packs
each unit's constants into one row of a table once, maps the common calls of the cycle (joint position,
velocity and torque to actuator space; actuator readings with a warm start to joint space) in one C call,
and returns None whenever a unit needs Python to decide (a refusal with its reason, a cold start, an
unknown unit kind). Without the built extension (a source tree never installed) it is simply absent.
"""

from __future__ import annotations

from typing import Final

import numpy as np

from rh5_hyrodyn_mapper.kinematics.ankle_sprr import Ankle2SPRR1U
from rh5_hyrodyn_mapper.kinematics.base import FloatArray, SubmechanismModel
from rh5_hyrodyn_mapper.kinematics.lambda_rrpr import Lambda1RRPR
from rh5_hyrodyn_mapper.kinematics.serial import LinearTransmission
from rh5_hyrodyn_mapper.kinematics.spu import Platform2SPU1U

try:
    from rh5_hyrodyn_mapper.kinematics import _compiled
except ImportError:  # not built: RobotMapper keeps its Python path
    _compiled = None

__all__ = ["AVAILABLE", "CompiledMaps"]

AVAILABLE: Final = _compiled is not None
_KIND: Final = {Lambda1RRPR: 1, Platform2SPU1U: 2, Ankle2SPRR1U: 3, LinearTransmission: 4}
_WIDTH: Final = 32


def _row(model: SubmechanismModel, joint: int, actuator: int) -> list[float] | None:
    """One unit's row (see ``_compiled.c``), or None for a kind the kernels do not know."""
    kind = _KIND.get(type(model))
    if kind is None:
        return None
    head = [float(kind), float(model.dof), float(joint), float(actuator)]
    if isinstance(model, Lambda1RRPR):
        return [*head, model.phi0, model._k0, model._k1, model._r12, model.sign, model.moment_arm_max]
    if isinstance(model, (Platform2SPU1U, Ankle2SPRR1U)):
        newton = [model._mode, model.tolerance, float(model.max_iterations), model.max_step]
        legs = [value for leg in model._legs for value in leg]
        return [*head, *model._l0_floats, *model._jinv0, *newton, *legs]
    m = model.dof
    if m > 3:
        return None
    square = np.zeros((2, 3, 3))
    square[0, :m, :m], square[1, :m, :m] = model.matrix, model.inverse_matrix
    return [*head, *square.ravel().tolist(), model.condition_number]


class CompiledMaps:
    """The table of one RobotMapper's units and the two C calls over it."""

    def __init__(self, table: FloatArray) -> None:
        self.table = table

    @classmethod
    def build(
        cls,
        blocks: list[tuple[SubmechanismModel, int, int]],
        copies: list[tuple[int, int]],
    ) -> CompiledMaps | None:
        """From the units ``(model, first joint, first actuator)`` and the pass-through ``(joint, actuator)``
        pairs; None when the extension is missing or a unit is of a kind the kernels do not know."""
        if _compiled is None:
            return None
        rows = [[0.0, 1.0, float(j), float(a)] for j, a in copies]
        for model, joint, actuator in blocks:
            row = _row(model, joint, actuator)
            if row is None:
                return None
            rows.append(row)
        table = np.zeros((len(rows), _compiled.ROW_WIDTH))
        for k, row in enumerate(rows):
            table[k, : len(row)] = row
        table.setflags(write=False)
        return cls(table)

    def to_actuators(
        self, q: FloatArray, v: FloatArray, tau: FloatArray, max_condition: float
    ) -> tuple[FloatArray, FloatArray, FloatArray] | None:
        """(l, l_dot, f) of one joint sample (32 each), or None: let the Python path map (and refuse) it."""
        l, ld, f = np.empty(_WIDTH), np.empty(_WIDTH), np.empty(_WIDTH)
        c = np.ascontiguousarray
        if _compiled.ik(self.table, c(q), c(v), c(tau), max_condition, l, ld, f) >= 0:
            return None
        return l, ld, f

    def to_joints(
        self, l: FloatArray, ld: FloatArray, f: FloatArray, q_guess: FloatArray
    ) -> tuple[FloatArray, FloatArray, FloatArray] | None:
        """(q, v, tau) of one actuator sample warm-started at ``q_guess``, or None: let the Python path map it."""
        q, v, tau = np.empty(_WIDTH), np.empty(_WIDTH), np.empty(_WIDTH)
        c = np.ascontiguousarray
        if _compiled.fk(self.table, c(l), c(ld), c(f), c(q_guess), q, v, tau) >= 0:
            return None
        return q, v, tau
