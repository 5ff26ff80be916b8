"""LiveLine: one redrawn line on a terminal; in a log, one line per step and at most one per interval."""

from __future__ import annotations

import io

from rh5_msgs_py.progress import LiveLine


class Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_on_a_terminal_the_line_is_redrawn_in_place() -> None:
    stream = Terminal()
    line = LiveLine(stream)
    for i in range(50):
        line.show(f"step {i}", key=i // 10)
    line.finish()
    text = stream.getvalue()
    assert text.count("\r") == 51
    assert text.count("\n") == 1
    assert text.endswith("step 49\x1b[K\n")


def test_in_a_log_there_is_one_line_per_step_and_no_carriage_return() -> None:
    stream = io.StringIO()
    line = LiveLine(stream, interval_s=3600.0)
    for i in range(50):
        line.show(f"step {i}", key=i // 10)  # five steps of ten updates each
    line.finish("done")
    lines = stream.getvalue().splitlines()
    assert "\r" not in stream.getvalue()
    assert lines == ["step 0", "step 10", "step 20", "step 30", "step 40", "done"]


def test_in_a_log_a_long_step_repeats_at_the_interval() -> None:
    stream = io.StringIO()
    line = LiveLine(stream, interval_s=0.0)
    for i in range(3):
        line.show(f"tick {i}", key="same")
    assert stream.getvalue().splitlines() == ["tick 0", "tick 1", "tick 2"]
