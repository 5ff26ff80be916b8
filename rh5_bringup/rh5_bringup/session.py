"""A running suite seen from the command line: processes, a graph observer node, Ctrl-C handling.

``rh5 up`` and ``rh5 experiment`` both start the bringup, wait until every node is in the ROS graph,
call the nodes' services, and stop every process cleanly however they end (Ctrl-C, SIGTERM, an error).
"""

from __future__ import annotations

import os
import signal
import time
from datetime import datetime
from pathlib import Path
from types import FrameType
from typing import Any

from rh5_bringup.launcher import Bringup, SuiteRun, wait_for_nodes


def run_dir(root: Path, prefix: str = "rh5") -> Path:
    """A new, time-stamped folder name under ``root``."""
    return Path(root) / datetime.now().strftime(f"{prefix}_%Y%m%d_%H%M%S_%f")


class SuiteSession:
    """Start ``bringup`` in its own ROS domain with an observer node; ``close`` stops everything.

    SIGINT/SIGTERM only set ``stop_requested`` (the nodes get their own SIGINT from ``close``), so a
    Ctrl-C in the middle of a step lets the caller finish cleanly.
    """

    def __init__(
        self, bringup: Bringup, log_dir: Path, observer_name: str = "rh5_launcher", domain_id: int | None = None
    ) -> None:
        self.bringup = bringup
        self.run = SuiteRun(bringup, log_dir, domain_id)  # None: a domain leased free on this machine
        self.stop_requested = False
        self.exit_codes: dict[str, int] = {}
        self._previous = {sig: signal.signal(sig, self._request_stop) for sig in (signal.SIGINT, signal.SIGTERM)}
        os.environ.update(self.run.env)  # the observer joins the run's domain
        import rclpy  # noqa: PLC0415 (after the environment is set)

        rclpy.init(signal_handler_options=rclpy.signals.SignalHandlerOptions.NO)
        self.node: Any = rclpy.create_node(observer_name)
        self.namespace = "/" + bringup.namespace.strip("/") if bringup.namespace else "/"

    def _request_stop(self, _signum: int, _frame: FrameType | None) -> None:
        self.stop_requested = True

    def service(self, node: str, name: str) -> str:
        """The full name of service ``name`` of ``node`` in the run's namespace."""
        return f"{self.namespace.rstrip('/')}/{node}/{name}"

    def start(self, timeout_s: float = 20.0) -> set[str]:
        """Start the nodes; return those that never appeared in the graph (empty when all are up)."""
        self.run.start()
        return wait_for_nodes(
            self.node,
            self.bringup.node_names(),
            self.namespace,
            timeout_s,
            exited=self.run.exited_nodes,
        )

    def crashed(self) -> list[str]:
        """Nodes that stopped on their own."""
        return [p.spec.name for p in self.run.exited()]

    def sleep(self, seconds: float) -> None:
        """Wait, serving the observer's subscriptions, unless a stop is requested."""
        import rclpy  # noqa: PLC0415

        deadline = time.monotonic() + seconds
        while not self.stop_requested and time.monotonic() < deadline:
            rclpy.spin_once(self.node, timeout_sec=min(0.05, max(0.0, deadline - time.monotonic())))

    def close(self) -> dict[str, int]:
        """Stop every node (newest first), the observer and ROS; restore the signal handlers. Idempotent."""
        import rclpy  # noqa: PLC0415

        if not self.exit_codes:
            try:
                self.exit_codes = self.run.stop()
            finally:
                self.node.destroy_node()
                rclpy.try_shutdown()
                for sig, handler in self._previous.items():
                    signal.signal(sig, handler)
        return self.exit_codes

    def __enter__(self) -> SuiteSession:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
