"""The ROS environment rules: LOCALHOST discovery, unique domain ids, logs in the tree."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from rh5_msgs_py.ros_env import DomainLease, apply_safe_defaults, suite_environment


def test_safe_defaults_fill_gaps_but_keep_explicit_choices() -> None:
    env = apply_safe_defaults({"ROS_AUTOMATIC_DISCOVERY_RANGE": "SUBNET"})
    assert env["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "SUBNET"
    assert env["RMW_IMPLEMENTATION"] == "rmw_fastrtps_cpp"
    assert apply_safe_defaults({})["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST"


def test_suite_environment_forces_localhost_domain_and_log_dir(tmp_path: Path) -> None:
    env = suite_environment(42, tmp_path, base={"ROS_AUTOMATIC_DISCOVERY_RANGE": "SUBNET"})
    assert env["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST"
    assert env["ROS_DOMAIN_ID"] == "42"
    assert env["ROS_LOG_DIR"] == str(tmp_path)


def test_domain_leases_are_unique_until_released() -> None:
    # A private lock-port space: the test run's own lease (and a concurrent run's) must not interfere.
    candidates, private = range(90, 93), {"lock_port_base": 41000 + os.getpid() % 1000}
    leases = [DomainLease(candidates, seed=1, **private) for _ in candidates]
    assert len({lease.domain_id for lease in leases}) == 3
    with pytest.raises(RuntimeError, match="no free ROS_DOMAIN_ID"):
        DomainLease(candidates, **private)
    leases[0].release()
    leases[0].release()  # idempotent
    again = DomainLease(candidates, **private)
    assert again.domain_id == leases[0].domain_id
    for lease in [again, *leases[1:]]:
        lease.release()
