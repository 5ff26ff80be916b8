"""The control process: driver, mapper and stabilizer in one process, run by one real-time 1 kHz cycle.

Layer: imports ``hardware``, the mapper and the stabilizer; its topics are published by a child process
(``stream_publisher``) so that publishing never blocks the cycle.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from rh5_msgs_py.lazy_exports import lazy_exports

if TYPE_CHECKING:
    from .cycle import STAGES, ControlCycle, CycleSample
    from .node import ControlNode, control_process

_EXPORTS = {
    **dict.fromkeys(("STAGES", "ControlCycle", "CycleSample"), "cycle"),
    **dict.fromkeys(("ControlNode", "control_process"), "node"),
}
__all__ = ["STAGES", "ControlCycle", "ControlNode", "CycleSample", "control_process"]
__getattr__ = lazy_exports(__name__, _EXPORTS)
