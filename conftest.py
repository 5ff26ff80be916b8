"""Session-wide test rules: every ROS process of a test run is local, in its own domain, logs in the tree.

The environment is set before anything can start ROS, for the pytest process and every
child it spawns; at the end the run must have left no child process and no Fast DDS
shared-memory segment behind.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path

import pytest

from rh5_msgs_py.ros_env import DomainLease, fastdds_shm_segments, suite_environment

REPO_ROOT = Path(__file__).resolve().parent
SHARED_DIR = REPO_ROOT.parent / "shared"


def _child_pids() -> list[int]:
    """Live (non-zombie) processes whose parent is this pytest process."""
    me, children = os.getpid(), []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
        except OSError:
            continue
        fields = stat.rsplit(")", 1)[1].split()
        if int(fields[1]) == me and fields[0] != "Z":
            children.append(int(entry.name))
    return children


@pytest.fixture(scope="session", autouse=True)
def ros_test_environment() -> Iterator[dict[str, str]]:
    """LOCALHOST discovery, a machine-unique ROS_DOMAIN_ID and ROS_LOG_DIR under .ros/ for the whole run."""
    shm_before = fastdds_shm_segments()
    with DomainLease() as lease:
        log_dir = REPO_ROOT / ".ros" / "log" / f"pytest_{os.getpid()}"
        env = suite_environment(lease.domain_id, log_dir)
        saved = dict(os.environ)
        os.environ.update(env)
        try:
            yield env
        finally:
            os.environ.clear()
            os.environ.update(saved)
    leftovers = _child_pids()
    new_segments = fastdds_shm_segments() - shm_before
    assert not leftovers, f"the test run left processes behind: {leftovers}"
    assert not new_segments, f"the test run left Fast DDS shared memory behind: {sorted(new_segments)}"


@pytest.fixture(scope="session")
def ros_graph(ros_test_environment: dict[str, str]) -> Iterator[object]:
    """An rclpy node in the pytest process, in the run's domain, to observe and call the suite."""
    import rclpy
    from rclpy.signals import SignalHandlerOptions

    from rh5_bringup.orchestration.fastdds_shm import release_observer_files, shm_files_of

    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node("pytest_observer")
    try:
        yield node
    finally:
        mapped = shm_files_of(os.getpid())
        context = node.context
        node.destroy_node()
        rclpy.try_shutdown()
        context.destroy()
        # the observer lived through the whole run: every node that exited before it left its port mapped here
        release_observer_files(os.getpid(), mapped, 5.0)


@pytest.fixture(scope="session")
def shared_dir() -> Path:
    """The ../shared reference material; tests that compare against it skip when it is absent."""
    if not SHARED_DIR.is_dir():
        pytest.skip(f"{SHARED_DIR} is not present")
    return SHARED_DIR
