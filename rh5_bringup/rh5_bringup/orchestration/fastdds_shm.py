"""The Fast DDS shared-memory files of a process, and removing those a killed process left behind.

Fast DDS's shared-memory transport keeps, per participant, a segment ``/dev/shm/fastrtps_<id>`` and
per listening port ``fastrtps_port<n>``, each with a lock file ``<name>_el`` and a semaphore
``sem.<name>_mutex``. A process that exits cleanly removes its own; one killed with SIGKILL leaves
them (32 files after a killed suite). The launcher notes which of these files each node process
uses while it runs (:func:`shm_files_of`), and after one died removes every file of theirs that no
live participant owns any more (:func:`remove_stale`, as ``fastdds shm clean``): what the killed
process owned at once, and the other participants' ports it kept referenced as soon as their owners
exit. That is urgent: the ``fastrtps_port70xx`` ports are taken machine-wide, first free first, so
another run's next participant would take such a port over and leak it in turn.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import time
from collections.abc import Iterable
from pathlib import Path
from typing import Final

__all__ = [
    "SHM_DIR",
    "family",
    "in_use_shm_files",
    "owned_shm_files",
    "release_observer_files",
    "remove_stale",
    "shm_files_of",
    "wait_until_released",
]

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


def owned_shm_files(pid: int) -> set[str]:
    """The segments and ports process ``pid`` owns: those whose lock file ``<name>_el`` it holds."""
    return {name.removesuffix("_el") for name in shm_files_of(pid) if name.endswith("_el")}


def wait_until_released(pid: int, timeout_s: float) -> bool:
    """Wait until process ``pid`` holds no Fast DDS file any more (its participants' transport threads
    ended), at most ``timeout_s``; True if it did."""
    deadline = time.monotonic() + timeout_s
    while shm_files_of(pid):
        if time.monotonic() >= deadline:
            return False
        time.sleep(0.05)
    return True


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


def _remove_family(base: str) -> list[str]:
    """Remove one segment or port with its lock file and semaphore if no live participant owns it.

    Fast DDS's owner holds an exclusive ``flock`` on ``<base>_el`` while it lives. Taking that lock
    here (creating the file if it is gone) proves there is none, and holding it while unlinking keeps
    a new participant from taking the port over meanwhile: it would inherit the dead process's
    references and could never remove the files either.
    """
    lock_path = SHM_DIR / f"{base}_el"
    try:
        fd = os.open(lock_path, os.O_RDWR | os.O_CREAT, 0o644)
    except OSError:
        return []
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            return []  # a live participant owns it
        removed = []
        for name in (base, f"sem.{base}_mutex", f"{base}_el"):
            try:
                (SHM_DIR / name).unlink()
            except FileNotFoundError:
                continue
            removed.append(name)
        return removed
    finally:
        os.close(fd)


def remove_stale(used: Iterable[str]) -> list[str]:
    """Remove the segments and ports among ``used`` (the files dead processes used) that no live participant
    owns, each with its lock file and semaphore, as ``fastdds shm clean`` does; returns the names removed.

    Files that peers still map are removed too when their owner is gone: unlinking leaves the peers'
    mappings intact, and nothing listens on such a port any more.
    """
    bases = {name.removeprefix("sem.").removesuffix("_mutex").removesuffix("_el") for name in used}
    present = {base for base in bases if any((SHM_DIR / name).exists() for name in family(base))}
    return [name for base in sorted(present) for name in _remove_family(base)]


def release_observer_files(pid: int, mapped: Iterable[str], timeout_s: float) -> list[str]:
    """After an observer node of process ``pid`` was destroyed: remove the files it had ``mapped`` that no live
    participant owns and no other process maps; returns the names removed.

    Fast DDS leaves an exiting participant's port in place while a peer holds a reference to it, so every node
    that exited before a long-lived observer left its port mapped there. Nothing may remove them while the
    observer lives (a node that later takes such a port must share the file the observer writes to); once its
    transport threads ended (waited for up to ``timeout_s``), they go. Files another process still maps, such as
    a test's observer, stay.
    """
    wait_until_released(pid, timeout_s)
    in_use = in_use_shm_files()
    return remove_stale({name for name in mapped if not family(name) & in_use})
