"""Cubic Hermite segments: the one basis behind the planner's 1 kHz splines and the stabilizer's playback.

A segment of duration ``h`` runs from value ``p0`` with slope ``m0`` (per second) to ``p1`` with slope ``m1``; at the
normalised time ``s`` in [0, 1] its value is ``w(s) . (p0, h m0, p1, h m1)``, its time derivative
``w'(s) . (p0, h m0, p1, h m1) / h`` and its second ``w''(s) . (p0, h m0, p1, h m1) / h^2``.
"""

from __future__ import annotations

from typing import TypeVar

import numpy as np

from rh5_msgs_py.array_types import FloatArray

__all__ = ["hermite_curvature_weights", "hermite_weights"]

S = TypeVar("S", float, FloatArray)


def hermite_weights(s: S) -> tuple[FloatArray, FloatArray]:
    """The weights of (p0, h m0, p1, h m1) for the value and for its derivative by ``s``: shape (4,) for a float
    ``s`` (Python arithmetic: the stabilizer samples one instant per millisecond), (4, n) for n times."""
    s2 = s * s
    s3 = s2 * s
    value = np.array((2 * s3 - 3 * s2 + 1, s3 - 2 * s2 + s, -2 * s3 + 3 * s2, s3 - s2))
    slope = np.array((6 * s2 - 6 * s, 3 * s2 - 4 * s + 1, -6 * s2 + 6 * s, 3 * s2 - 2 * s))
    return value, slope


def hermite_curvature_weights(s: S) -> FloatArray:
    """The weights of (p0, h m0, p1, h m1) for the second derivative by ``s``, shaped as ``hermite_weights``."""
    return np.array((12 * s - 6, 6 * s - 4, -12 * s + 6, 6 * s - 2))
