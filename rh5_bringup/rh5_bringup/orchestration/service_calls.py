"""Service calls that retry while a node refuses or is not up yet: std_srvs Trigger and SetBool, lifecycle
transitions. Shared by the ``rh5`` command line and the experiment runner."""

from __future__ import annotations

import time
from typing import Any


def call_trigger(node: Any, service: str, timeout_s: float = 10.0) -> tuple[bool, str]:
    """Call a std_srvs/Trigger service, retrying while it refuses, until it succeeds or time runs out."""
    from std_srvs.srv import Trigger  # noqa: PLC0415

    return _call_until_success(node, Trigger, service, Trigger.Request(), timeout_s)


def call_set_bool(node: Any, service: str, value: bool, timeout_s: float = 10.0) -> tuple[bool, str]:
    """Call a std_srvs/SetBool service, retrying while it refuses, until it succeeds or time runs out."""
    from std_srvs.srv import SetBool  # noqa: PLC0415

    return _call_until_success(node, SetBool, service, SetBool.Request(data=value), timeout_s)


def call_lifecycle(node: Any, service: str, label: str, timeout_s: float = 15.0) -> tuple[bool, str]:
    """Request the lifecycle transition ``label`` through a managed node's ``change_state`` service ``service``
    (by label: an id the state lacks would end an rclpy node, rclpy#1209), retrying while it is refused (e.g. the
    node still configures itself), until it succeeds or time runs out."""
    import rclpy  # noqa: PLC0415
    from lifecycle_msgs.msg import Transition  # noqa: PLC0415
    from lifecycle_msgs.srv import ChangeState  # noqa: PLC0415

    client = node.create_client(ChangeState, service)
    deadline = time.monotonic() + timeout_s
    try:
        while time.monotonic() < deadline:
            if not client.wait_for_service(timeout_sec=0.2):
                continue
            future = client.call_async(ChangeState.Request(transition=Transition(label=label)))
            rclpy.spin_until_future_complete(node, future, timeout_sec=max(0.1, deadline - time.monotonic()))
            if future.done() and future.result().success:
                return True, f"{label}: done"
            time.sleep(0.2)
        return False, f"{label}: refused or not answered within {timeout_s:g} s"
    finally:
        node.destroy_client(client)


def _call_until_success(node: Any, kind: Any, service: str, request: Any, timeout_s: float) -> tuple[bool, str]:
    import rclpy  # noqa: PLC0415

    client = node.create_client(kind, service)
    deadline = time.monotonic() + timeout_s
    answer = (False, f"{service} not available")
    try:
        while time.monotonic() < deadline:
            if not client.wait_for_service(timeout_sec=0.2):
                continue
            future = client.call_async(request)
            rclpy.spin_until_future_complete(node, future, timeout_sec=max(0.1, deadline - time.monotonic()))
            if future.done():
                answer = (future.result().success, future.result().message)
                if answer[0]:
                    return answer
            time.sleep(0.2)
        return answer
    finally:
        node.destroy_client(client)
