"""Fixed-point scaling of the boards' wire values: one quantity (`Quantity`), one board (`Scaling`), all boards
(`ScalingTable`, the arrays the batch codecs use). The numbers per board come from the board map.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Final, NamedTuple

import numpy as np

from rh5_bringup.hardware.ndlcom.errors import PayloadError

INT32_MIN: Final = -(2**31)
INT32_MAX: Final = 2**31 - 1
INT16_MIN: Final = -(2**15)
INT16_MAX: Final = 2**15 - 1


@dataclass(frozen=True, slots=True)
class Quantity:
    """Fixed-point scaling of one physical quantity: ``value = raw * lsb``, commands limited to [low, high].

    [low, high] is the board's wire range: a coarse sanity bound that catches unit and sign-convention errors
    (mm for m, deg for rad), not a joint limit. Both ends must be representable in int32 at this LSB.
    """

    lsb: float
    low: float
    high: float
    raw_low: int = field(init=False, repr=False, compare=False)
    raw_high: int = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if not (math.isfinite(self.lsb) and self.lsb > 0.0):
            raise ValueError(f"lsb must be a positive finite number, got {self.lsb!r}")
        if not (math.isfinite(self.low) and math.isfinite(self.high) and self.low < self.high):
            raise ValueError(f"range must be finite with low < high, got [{self.low!r}, {self.high!r}]")
        raw_low, raw_high = round(self.low / self.lsb), round(self.high / self.lsb)
        if raw_low < INT32_MIN or raw_high > INT32_MAX:
            raise ValueError(
                f"range [{self.low}, {self.high}] at lsb {self.lsb} does not fit int32 (+-{INT32_MAX * self.lsb:.6g})"
            )
        object.__setattr__(self, "raw_low", raw_low)
        object.__setattr__(self, "raw_high", raw_high)

    @classmethod
    def full(cls, lsb: float) -> Quantity:
        """The widest range int32 can carry at ``lsb``."""
        return cls(lsb, INT32_MIN * lsb, INT32_MAX * lsb)

    def check_raw(self, raw: int, what: str) -> float:
        """A received ``raw`` value in SI units; refuses one outside [low, high]."""
        if self.raw_low <= raw <= self.raw_high:
            return raw * self.lsb
        raise PayloadError(f"{what} = {raw * self.lsb!r} is outside the wire range [{self.low}, {self.high}]")


class Scaling(NamedTuple):
    """One board's fixed-point scaling: position (m or rad), velocity (m/s or rad/s), effort (N or Nm)."""

    position: Quantity
    velocity: Quantity
    effort: Quantity


class ScalingTable:
    """The scalings of n boards as (3, n) arrays (rows: position, velocity, effort), for the batch codecs."""

    def __init__(self, scalings: Sequence[Scaling], names: Sequence[str] | None = None) -> None:
        self.names = tuple(names) if names is not None else tuple(f"#{i}" for i in range(len(scalings)))
        if len(self.names) != len(scalings):
            raise ValueError(f"{len(self.names)} names for {len(scalings)} scalings")
        self.lsb = np.array([[q.lsb for q in s] for s in scalings], dtype=float).T.copy()
        self.low = np.array([[q.low for q in s] for s in scalings], dtype=float).T.copy()
        self.high = np.array([[q.high for q in s] for s in scalings], dtype=float).T.copy()

    def __len__(self) -> int:
        return len(self.names)


__all__ = ["INT16_MAX", "INT16_MIN", "INT32_MAX", "INT32_MIN", "Quantity", "Scaling", "ScalingTable"]
