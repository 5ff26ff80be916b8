"""One status line that is a live line on a terminal and a short log in a file.

On a terminal the line is redrawn in place (``\\r``). Written to a file or a pipe, a log would otherwise
get one endless line, so there it becomes one line per change of ``key`` (a new step) and at most one
line every ``interval_s`` in between.
"""

from __future__ import annotations

import math
import sys
import time
from typing import IO


class LiveLine:
    """A status line on ``stream`` (default stderr): redrawn on a terminal, throttled lines in a log."""

    def __init__(self, stream: IO[str] | None = None, interval_s: float = 1.0) -> None:
        self.stream = sys.stderr if stream is None else stream
        self.interval_s = interval_s
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self.last = ""
        self._last_write = -math.inf
        self._key: object = None

    def show(self, text: str, key: object = None) -> None:
        """Show ``text``; in a log, write it when ``key`` differs from the last line's or ``interval_s`` passed."""
        self.last = text
        now = time.monotonic()
        if self.tty:
            self.stream.write("\r" + text + "\x1b[K")  # clear the rest of a longer previous line
        elif key != self._key or now - self._last_write >= self.interval_s:
            self.stream.write(text + "\n")
            self._last_write = now
        else:
            return
        self._key = key
        self.stream.flush()

    def finish(self, text: str | None = None) -> None:
        """End the line with ``text`` (default: the last one shown), complete on its own line in a log too."""
        text = self.last if text is None else text
        self.stream.write(("\r" + text + "\x1b[K" if self.tty else text) + "\n")
        self.stream.flush()
        self.last, self._key, self._last_write = "", None, -math.inf
