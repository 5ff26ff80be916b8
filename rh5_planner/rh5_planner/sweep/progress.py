"""The sweep's progress line: points done, running and failed, elapsed time and ETA.

``sweep [##########..............] 12/30 done, 2 running, 1 failed, 4:05 elapsed, ETA 6:10`` on a terminal,
redrawn in place (rh5_msgs_py.progress.LiveLine); in a log one line per finished point and at most one every
``interval_s`` in between.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from typing import IO

from rh5_msgs_py.progress import LiveLine

from .engine import Running, SweepState

__all__ = ["SweepProgress", "clock"]


def clock(seconds: float | None) -> str:
    """``3725`` -> ``1:02:05``, ``65`` -> ``1:05``; ``--`` for unknown."""
    if seconds is None:
        return "--"
    total = round(max(0.0, seconds))
    hours, rest = divmod(total, 3600)
    minutes, secs = divmod(rest, 60)
    return f"{hours}:{minutes:02d}:{secs:02d}" if hours else f"{minutes}:{secs:02d}"


class SweepProgress:
    """Callable for :func:`rh5_planner.sweep.engine.run_sweep`'s ``on_progress``."""

    def __init__(
        self, stream: IO[str] | None = None, *, label: str = "sweep", width: int = 24, interval_s: float = 10.0
    ):
        self.label = label
        self.width = width
        self._line = LiveLine(stream, interval_s)

    def text(self, state: SweepState, now: float | None = None) -> str:
        """The progress line for ``state``."""
        now = time.time() if now is None else now
        filled = round(self.width * state.finished / max(1, state.total))
        return (
            f"{self.label} [{'#' * filled}{'.' * (self.width - filled)}] {state.finished}/{state.total} done, "
            f"{state.running} running, {state.failed} failed, {clock(now - state.started)} elapsed, "
            f"ETA {clock(state.eta_s(now))}"
        )

    def __call__(self, state: SweepState, running: Mapping[str, Running]) -> None:
        """Show the line; a new line in a log whenever a point finished."""
        del running
        self._line.show(self.text(state), key=state.finished)

    def finish(self, message: str) -> None:
        """End the line with ``message``."""
        self._line.finish(f"{self._line.last}  {message}" if self._line.last else f"{self.label}: {message}")
