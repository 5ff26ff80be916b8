"""Joint names: checked once, then an index that orders any message's joints like the caller's list."""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from functools import lru_cache
from typing import Final

import numpy as np
from numpy.typing import NDArray

from ._common import _MAX_LISTED


def _listing(names: Sequence[str]) -> str:
    shown = ", ".join(names[:_MAX_LISTED])
    more = len(names) - _MAX_LISTED
    return f"[{shown}{f', ... (+{more} more)' if more > 0 else ''}]"


def _unique_names(names: Iterable[str], what: str) -> tuple[str, ...]:
    out = tuple(names)
    if len(set(out)) != len(out):
        dups = sorted({n for n in out if out.count(n) > 1})
        msg = f"{what}: duplicate joint names {_listing(dups)}"
        raise ValueError(msg)
    return out


class JointNameIndex:
    """Maps the joint order of incoming messages onto one fixed order, caching one index per message order.

    ``index(msg_names)`` returns None when the order already matches (the fast path: one tuple
    comparison) and otherwise an index array ``idx`` with ``values_in_our_order = msg_values[idx]``.
    """

    _CACHE_SIZE: Final = 16

    def __init__(self, names: Iterable[str], *, allow_extra: bool = False, what: str = "message") -> None:
        self.names: Final = _unique_names(names, what)
        self.allow_extra: Final = allow_extra
        self.what: Final = what
        self._cache: dict[tuple[str, ...], tuple[NDArray[np.intp], ...]] = {}

    def index(self, msg_names: Sequence[str]) -> NDArray[np.intp] | None:
        """Index array from the message's order into ours, None if identical; ValueError naming bad joints."""
        entry = self._entry(msg_names)
        return None if entry is None else entry[0]

    def _entry(self, msg_names: Sequence[str]) -> tuple[NDArray[np.intp], ...] | None:
        """None for the same order, else the index into 1, 2 and 3 concatenated fields (flat, for one gather)."""
        key = msg_names if type(msg_names) is tuple else tuple(msg_names)
        if key == self.names:
            return None
        entry = self._cache.get(key)
        if entry is None:
            idx = self._build(key)
            entry = tuple((np.arange(rows)[:, None] * len(key) + idx).ravel() for rows in (1, 2, 3))
            if len(self._cache) >= self._CACHE_SIZE:
                self._cache.clear()
            self._cache[key] = entry
        return entry

    def _build(self, key: tuple[str, ...]) -> NDArray[np.intp]:
        position = {name: i for i, name in enumerate(key)}
        if len(position) != len(key):
            _unique_names(key, self.what)
        missing = [n for n in self.names if n not in position]
        wanted = set(self.names)
        unknown = [] if self.allow_extra else [n for n in key if n not in wanted]
        if missing or unknown:
            parts = []
            if missing:
                parts.append(f"missing joints {_listing(missing)}")
            if unknown:
                parts.append(f"unknown joints {_listing(unknown)}")
            msg = f"{self.what}: joint names do not match the expected {len(self.names)} joints: {'; '.join(parts)}"
            raise ValueError(msg)
        return np.array([position[n] for n in self.names], dtype=np.intp)


@lru_cache(maxsize=64)
def _name_index(names: tuple[str, ...], allow_extra: bool, what: str) -> JointNameIndex:
    return JointNameIndex(names, allow_extra=allow_extra, what=what)
