"""A running suite seen from the command line: processes, a graph observer node, Ctrl-C handling.

``rh5 up`` and ``rh5 experiment`` both start the bringup, wait until every node is in the ROS graph,
call the nodes' services, and stop every process cleanly however they end (Ctrl-C, SIGTERM, an error).
"""

from __future__ import annotations

import os
import signal
import sys
import time
from collections.abc import Callable
from datetime import datetime
from pathlib import Path
from types import FrameType
from typing import Any

from rh5_bringup.orchestration.fastdds_shm import release_observer_files, shm_files_of
from rh5_bringup.orchestration.launcher import Bringup, NodeProcess, SuiteRun, wait_for_nodes


def run_dir(root: Path, prefix: str = "rh5") -> Path:
    """A new, time-stamped folder name under ``root``."""
    return Path(root) / datetime.now().strftime(f"{prefix}_%Y%m%d_%H%M%S_%f")


OBSERVER_RELEASE_S = 5.0
"""How long closing waits for the observer's Fast DDS files to be released (its transport threads end)."""


def _to_stderr(text: str) -> None:
    print(f"rh5: {text}", file=sys.stderr, flush=True)


class SuiteSession:
    """Start ``bringup`` in its own ROS domain with an observer node; ``close`` stops everything.

    SIGINT/SIGTERM only set ``stop_requested`` (the nodes get their own SIGINT from ``close``), so a
    Ctrl-C in the middle of a step lets the caller finish cleanly. A node that is not essential (the
    recorder) may die without stopping the suite: :meth:`crashed` leaves it out, reports it once through
    :attr:`report` and removes the Fast DDS shared memory it left; :meth:`lost` names such nodes, for a
    caller that cannot go on without them.
    """

    report: Callable[[str], None] = staticmethod(_to_stderr)
    """Where a lost non-essential node is reported (stderr)."""
    shm_refresh_s: float = 5.0
    """How often :meth:`crashed` notes the processes' shared-memory files again."""

    def __init__(
        self, bringup: Bringup, log_dir: Path, observer_name: str = "rh5_launcher", domain_id: int | None = None
    ) -> None:
        self.bringup = bringup
        self.run = SuiteRun(bringup, log_dir, domain_id)  # None: a domain leased free on this machine
        self.stop_requested = False
        self.exit_codes: dict[str, int] = {}
        self._reported: set[str] = set()
        self._shm_noted_at: float | None = None
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
        missing = wait_for_nodes(
            self.node,
            self.bringup.node_names(),
            self.namespace,
            timeout_s,
            exited=self.run.exited_nodes,
        )
        self.run.note_shared_memory()
        self._shm_noted_at = time.monotonic()
        return missing

    def crashed(self) -> list[str]:
        """Essential nodes that stopped on their own (the suite must stop). A non-essential one that stopped is
        reported once, with its shared memory removed; the others keep running."""
        now = time.monotonic()
        if self._shm_noted_at is not None and now - self._shm_noted_at >= self.shm_refresh_s:
            self.run.note_shared_memory()
            self._shm_noted_at = now
        exited = self.run.exited()
        for proc in exited:
            if not proc.spec.essential and proc.spec.name not in self._reported:
                self._reported.add(proc.spec.name)
                self._report_lost(proc)
        return [p.spec.name for p in exited if p.spec.essential]

    def lost(self) -> list[str]:
        """Non-essential nodes that stopped on their own (the suite runs on without them)."""
        return [p.spec.name for p in self.run.exited() if not p.spec.essential]

    def _report_lost(self, proc: NodeProcess) -> None:
        removed = self.run.clean_up_after(proc)
        last = proc.last_error()
        cleaned = f" (removed {len(removed)} stale Fast DDS shared-memory files)" if removed else ""
        lines = [
            f"{proc.spec.name} stopped on its own (exit {proc.process.returncode}); the other nodes keep running"
            + cleaned
        ]
        if last:
            lines.append(f"  its last log line: {last}")
        if proc.spec.lost_hint:
            lines.append(f"  {proc.spec.lost_hint}")
        self.report("\n".join(lines))

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
                mapped = shm_files_of(os.getpid())
                context = self.node.context
                self.node.destroy_node()
                rclpy.try_shutdown()
                context.destroy()  # the observer's participant ends now, not whenever the context is collected
                self.run.removed_shm += release_observer_files(os.getpid(), mapped, OBSERVER_RELEASE_S)
                self.run.remove_stale_shared_memory()  # after a killed node: the observer's own port, now it ended
                if self.run.killed() and self.run.removed_shm:
                    self.report(f"removed {len(self.run.removed_shm)} Fast DDS shared-memory files the nodes left")
                for sig, handler in self._previous.items():
                    signal.signal(sig, handler)
        return self.exit_codes

    def __enter__(self) -> SuiteSession:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
