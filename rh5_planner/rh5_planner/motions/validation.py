"""Validation of motion parameters: the error every invalid motion raises and the checks the motion kinds share."""

from __future__ import annotations

import math

__all__ = ["MotionError", "check_count", "check_nonnegative", "check_positive"]


class MotionError(ValueError):
    """An invalid motion name, parameter name or parameter value."""


def check_positive(name: str, value: float) -> None:
    """MotionError unless ``value`` is a positive finite number (parameter ``name``)."""
    if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
        msg = f"{name} must be a positive finite number, got {value!r}"
        raise MotionError(msg)


def check_nonnegative(name: str, value: float) -> None:
    """MotionError unless ``value`` is a non-negative finite number (parameter ``name``)."""
    if not (isinstance(value, int | float) and math.isfinite(value) and value >= 0):
        msg = f"{name} must be a non-negative finite number, got {value!r}"
        raise MotionError(msg)


def check_count(name: str, value: int, minimum: int = 1) -> None:
    """MotionError unless ``value`` is an integer (not a bool) of at least ``minimum`` (parameter ``name``)."""
    if not isinstance(value, int) or isinstance(value, bool) or value < minimum:
        msg = f"{name} must be an integer >= {minimum}, got {value!r}"
        raise MotionError(msg)
