"""Constants every message family of the conversions uses."""

from __future__ import annotations

from typing import Final

NS_PER_S: Final = 1_000_000_000
_INT32_MIN: Final = -(2**31)
_INT32_MAX: Final = 2**31 - 1
_MAX_LISTED: Final = 8  # names listed in an error message before "... (+k more)"
