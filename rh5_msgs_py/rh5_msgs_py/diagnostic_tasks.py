"""Per-component, per-task diagnostic statuses in diagnostic_updater's layout: ``"<node>: <task>"``.

diagnostic_updater (and the runtime monitor, rqt_robot_monitor and Foxglove's diagnostics panels that read it)
expects one status per thing that can go wrong, named after the node and the task, whose level says how it is:
OK, WARN (degraded: deadline misses, clamped commands, a slow simulation) or ERROR (not working: a silent board,
the emergency stop, a rejected trajectory). A status's message stays the same while its condition lasts (the
numbers go into its values), so a report groups the repeats into one fault.
"""

from __future__ import annotations

from collections.abc import Mapping

from rh5_msgs_py.conversions import Level, Status
from rh5_msgs_py.diagnostic_keys import HARDWARE_ID, task_name

__all__ = ["HARDWARE_ID", "Increases", "task_status"]


def task_status(node: str, task: str, level: Level, message: str, values: Mapping[str, object] | None = None) -> Status:
    """The status of ``task`` of ``node``: named ``"<node>: <task>"`` as diagnostic_updater names them."""
    return Status(task_name(node, task), level, message, dict(values or {}), HARDWARE_ID)


class Increases:
    """How much counters grew since the previous report (the first report counts from zero)."""

    def __init__(self) -> None:
        self._last: dict[str, float] = {}

    def __call__(self, key: str, value: float) -> float:
        """The growth of counter ``key`` since the last call with it."""
        grown = value - self._last.get(key, 0.0)
        self._last[key] = value
        return grown
