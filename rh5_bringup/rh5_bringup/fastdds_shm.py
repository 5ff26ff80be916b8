"""The Fast DDS shared-memory files of a process, and removing those a killed process left behind.

Fast DDS's shared-memory transport keeps, per participant, a segment ``/dev/shm/fastrtps_<id>`` and
per listening port ``fastrtps_port<n>``, each with a lock file ``<name>_el`` and a semaphore
``sem.<name>_mutex``. A process that exits cleanly removes its own; one killed with SIGKILL leaves
them (32 files after a killed suite). The launcher notes which of these files each node process
uses while it runs (:func:`shm_files_of`), and after it died removes what it owned (as ``fastdds
shm clean`` would) and, once no live process uses them, the other participants' ports it kept
referenced (:func:`remove_stale`). The ``fastrtps_port70xx`` ports are taken machine-wide, one per
participant, first free first: a dead participant's one is soon reused by another run.
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


def remove_stale(used: Iterable[str], *, ignore_self: bool = False) -> list[str]:
    """Remove the stale files among ``used`` (the files dead processes used), each with its lock file and
    semaphore; returns the names removed.

    A segment or port whose lock file ``<name>_el`` is among ``used`` was owned by a dead process: it is
    stale once no live process holds that lock, even if peers still map it (unlinking leaves their mappings
    intact; left in place, a participant that later takes the port over inherits the dead process's
    references and can never remove it, as ``fastdds shm clean`` also assumes). Any other file, a port of
    some other participant, is stale once no live process maps or holds it. ``ignore_self``: this process's
    own mappings do not count (its ROS context is shut down, they are leftovers).
    """
    used = set(used)
    owned = {name.removesuffix("_el") for name in used if name.endswith("_el")}
    candidates = {member for name in used for member in family(name)}
    if not candidates:
        return []
    in_use = in_use_shm_files(exclude=[os.getpid()] if ignore_self else [])
    removed = []
    for name in sorted(candidates):
        base = name.removeprefix("sem.").removesuffix("_mutex").removesuffix("_el")
        busy = f"{base}_el" in in_use if base in owned else bool(family(name) & in_use)
        if busy:
            continue
        try:
            (SHM_DIR / name).unlink()
        except FileNotFoundError:
            continue
        removed.append(name)
    return removed
