"""The ROS 2 environment every process of the suite runs in, and a machine-unique domain id.

Fast DDS discovery multicasts out of every network interface unless told otherwise, so
each process that starts ROS gets ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` unless the
operator chose a range explicitly (a real robot spanning two machines needs SUBNET).
Fast DDS keeps shared-memory segments in ``/dev/shm/fastrtps_*`` while a process runs; a clean
exit removes them, a killed process leaves them (``fastdds shm clean`` removes stale ones).
(``FASTDDS_BUILTIN_TRANSPORTS=UDPv4`` does not change that with rmw_fastrtps here: measured.)
"""

from __future__ import annotations

import errno
import os
import random
import socket
import sys
from collections.abc import Mapping, MutableMapping
from pathlib import Path

SAFE_DEFAULTS: Mapping[str, str] = {
    "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST",
    "RMW_IMPLEMENTATION": "rmw_fastrtps_cpp",
}

# ROS_DOMAIN_ID values whose DDS ports are valid on Linux (REP 2005 / design docs: 0..101).
DOMAIN_IDS = range(1, 102)
# Loopback TCP ports used as machine-wide locks, one per domain id (held while a run lives).
LOCK_PORT_BASE = 23100


def apply_safe_defaults(env: MutableMapping[str, str] | None = None) -> MutableMapping[str, str]:
    """Fill in the suite's safe ROS settings where ``env`` (default: os.environ) has none."""
    env = os.environ if env is None else env
    for key, value in SAFE_DEFAULTS.items():
        env.setdefault(key, value)
    prefix = sys.prefix
    ament = env.get("AMENT_PREFIX_PATH", "")
    if prefix not in ament.split(os.pathsep):
        # ament_index users need the venv, which holds share/ament_index of the ROS wheels.
        env["AMENT_PREFIX_PATH"] = os.pathsep.join(p for p in (ament, prefix) if p)
    return env


def suite_environment(domain_id: int, log_dir: Path, base: Mapping[str, str] | None = None) -> dict[str, str]:
    """Return the environment for a child process of one run: safe defaults, its domain and log folder.

    ``log_dir`` becomes ROS_LOG_DIR (where rcl writes its log files) unless ``base`` (default: os.environ)
    already names one: the user's choice is kept.
    """
    env = dict(os.environ if base is None else base)
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    env["ROS_DOMAIN_ID"] = str(domain_id)
    env["ROS_LOG_DIR"] = env.get("ROS_LOG_DIR") or str(log_dir)
    env["PYTHONUNBUFFERED"] = "1"
    apply_safe_defaults(env)
    return env


MAX_DOMAIN_ID = 232
"""The largest ROS_DOMAIN_ID ROS 2 accepts (its ports must fit in 16 bits); 0..101 are safe on Linux."""


def chosen_domain_id(flag: int | None, env: Mapping[str, str] | None = None) -> tuple[int | None, str]:
    """The domain a run must use and where that came from: ``flag`` (``--domain-id``), else ROS_DOMAIN_ID of
    ``env`` (default: os.environ), else None (lease a free one: ``DomainLease``).

    :raises ValueError: the value is not an integer in 0..232, with the reason.
    """
    env = os.environ if env is None else env
    if flag is not None:
        value, source = str(flag), "--domain-id"
    elif env.get("ROS_DOMAIN_ID", "").strip():
        value, source = env["ROS_DOMAIN_ID"].strip(), "ROS_DOMAIN_ID of the environment"
    else:
        return None, "leased: free on this machine"
    try:
        domain_id = int(value)
    except ValueError:
        msg = f"{source}: {value!r} is not an integer domain id (0..{MAX_DOMAIN_ID})"
        raise ValueError(msg) from None
    if not 0 <= domain_id <= MAX_DOMAIN_ID:
        msg = f"{source}: {domain_id} is outside the ROS domain ids 0..{MAX_DOMAIN_ID}"
        raise ValueError(msg)
    return domain_id, source


class DomainLease:
    """A ROS_DOMAIN_ID nobody else on this machine uses while the lease is held.

    The lock is a listening socket on 127.0.0.1, so it disappears with the process even
    after SIGKILL and two concurrent test runs can never share a domain.
    """

    def __init__(
        self, candidates: range = DOMAIN_IDS, seed: int | None = None, lock_port_base: int = LOCK_PORT_BASE
    ) -> None:
        order = list(candidates)
        random.Random(seed if seed is not None else os.getpid()).shuffle(order)
        for domain_id in order:
            sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
            try:
                sock.bind(("127.0.0.1", lock_port_base + domain_id))
                sock.listen(1)
            except OSError as err:
                sock.close()
                if err.errno != errno.EADDRINUSE:
                    raise
                continue
            self.domain_id = domain_id
            self._sock: socket.socket | None = sock
            return
        msg = f"no free ROS_DOMAIN_ID in {candidates.start}..{candidates.stop - 1}: too many concurrent runs"
        raise RuntimeError(msg)

    def release(self) -> None:
        """Give the domain id back (idempotent)."""
        if self._sock is not None:
            self._sock.close()
            self._sock = None

    def __enter__(self) -> DomainLease:
        return self

    def __exit__(self, *exc: object) -> None:
        self.release()


def fastdds_shm_segments() -> set[str]:
    """Names of Fast DDS shared-memory files in /dev/shm (left behind by killed processes)."""
    shm = Path("/dev/shm")
    if not shm.is_dir():
        return set()
    return {p.name for p in shm.iterdir() if "fastrtps" in p.name or "fast_datasharing" in p.name}
