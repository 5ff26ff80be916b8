"""The Fast DDS shared-memory files of a process, and removing those a killed process left behind.

Fast DDS's shared-memory transport keeps, per participant, a segment ``/dev/shm/fastrtps_<id>`` and
per listening port ``fastrtps_port<n>``, each with a lock file ``<name>_el`` and a semaphore
``sem.<name>_mutex``. A process that exits cleanly removes its own; one killed with SIGKILL leaves
them (32 files after a killed suite). The launcher notes which of these files each node process
uses while it runs (:func:`shm_files_of`), and after it died removes those that no live process
maps or holds open any more, as ``fastdds shm clean`` would: a port that other participants still
use is kept.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterable
from pathlib import Path
from typing import Final

__all__ = ["SHM_DIR", "family", "in_use_shm_files", "remove_stale", "shm_files_of"]

SHM_DIR: Final = Path("/dev/shm")
_MARKERS: Final = ("fastrtps", "fast_datasharing")


def _is_fastdds(name: str) -> bool:
    return any(marker in name for marker in _MARKERS)


def shm_files_of(pid: int) -> set[str]:
    """Names of the Fast DDS files in /dev/shm that process ``pid`` maps or holds open (empty once it is gone)."""
    names: set[str] = set()
    proc = Path("/proc") / str(pid)
    with contextlib.suppress(OSError):
        for line in (proc / "maps").read_text().splitlines():
            if "/dev/shm/" in line:
                names.add(line.rsplit("/", 1)[-1].removesuffix(" (deleted)"))
    with contextlib.suppress(OSError):
        for fd in (proc / "fd").iterdir():
            with contextlib.suppress(OSError):
                target = os.readlink(fd)
                if target.startswith("/dev/shm/"):
                    names.add(target.rsplit("/", 1)[-1])
    return {name for name in names if _is_fastdds(name)}


def in_use_shm_files(exclude: Iterable[int] = ()) -> set[str]:
    """Fast DDS files in /dev/shm that some live process (of any user we can see, but ``exclude``) maps or
    holds open."""
    skip = {str(pid) for pid in exclude}
    in_use: set[str] = set()
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit() and entry.name not in skip:
            in_use |= shm_files_of(int(entry.name))
    return in_use


def family(name: str) -> set[str]:
    """A segment or port file with its lock file and semaphore."""
    base = name.removeprefix("sem.").removesuffix("_mutex").removesuffix("_el")
    return {base, f"{base}_el", f"sem.{base}_mutex"}


def remove_stale(owned: Iterable[str], *, ignore_self: bool = False) -> list[str]:
    """Remove the files of ``owned`` (with their lock files and semaphores) that no live process uses.

    ``owned`` are the files a dead process used; returns the names removed. ``ignore_self``: this
    process's own mappings do not count (its ROS context is shut down, they are leftovers).
    """
    candidates = {member for name in owned for member in family(name)}
    if not candidates:
        return []
    in_use = in_use_shm_files(exclude=[os.getpid()] if ignore_self else [])
    removed = []
    for name in sorted(candidates):
        if any(member in in_use for member in family(name)):
            continue
        path = SHM_DIR / name
        try:
            path.unlink()
        except FileNotFoundError:
            continue
        removed.append(name)
    return removed
