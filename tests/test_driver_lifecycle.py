"""The managed driver: its lifecycle against the simulated boards, refusals in the wrong state, the estop.

Transitions are requested as a lifecycle manager does, through ~/change_state (by label, and once by an id the
state does not have, which rclpy itself would let end the process: rclpy#1209).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from contextlib import AbstractContextManager
from typing import Any

import pytest

from rh5_bringup.orchestration.cli import call_set_bool, call_trigger

pytestmark = pytest.mark.ros


class Manager:
    """Calls the driver's lifecycle services."""

    def __init__(self, node: Any) -> None:
        from lifecycle_msgs.srv import ChangeState, GetState

        self.node = node
        self._change = node.create_client(ChangeState, "/driver/change_state")
        self._get = node.create_client(GetState, "/driver/get_state")
        assert self._change.wait_for_service(timeout_sec=10.0)

    def _call(self, client: Any, request: Any) -> Any:
        import rclpy

        future = client.call_async(request)
        end = time.monotonic() + 15.0
        while not future.done() and time.monotonic() < end:
            rclpy.spin_once(self.node, timeout_sec=0.01)
        assert future.done(), "no answer"
        return future.result()

    def change(self, label: str = "", transition_id: int = 0) -> bool:
        from lifecycle_msgs.msg import Transition
        from lifecycle_msgs.srv import ChangeState

        request = ChangeState.Request(transition=Transition(id=transition_id, label=label))
        return bool(self._call(self._change, request).success)

    def state(self) -> str:
        from lifecycle_msgs.srv import GetState

        return str(self._call(self._get, GetState.Request()).current_state.label)


@pytest.fixture(scope="module")
def manager(ros_graph: Any, boards_and_driver: Callable[..., AbstractContextManager[Any]]) -> Iterator[Manager]:
    with boards_and_driver("driver_lifecycle", autostart="none") as run:
        yield Manager(ros_graph)
        assert run.exited() == []
    assert "Traceback" not in run.processes[1].stderr_path.read_text()


def test_unconfigured_driver_has_no_link_and_refuses_to_drive(manager: Manager) -> None:
    assert manager.state() == "unconfigured"
    ok, message = call_set_bool(manager.node, "/driver/enable", True, timeout_s=1.0)
    assert not ok
    assert "not configured" in message
    assert not manager.change("activate")  # no such transition from unconfigured
    assert manager.state() == "unconfigured"


def test_configure_fails_while_a_board_is_silent(manager: Manager) -> None:
    from test_driver_sim import set_parameters

    set_parameters(manager.node, "sim_hardware", silent_boards=["LRAnkle_Act2"])
    try:
        assert not manager.change("configure")
        assert manager.state() == "unconfigured"
    finally:
        set_parameters(manager.node, "sim_hardware", silent_boards=[])


def test_full_lifecycle_with_refusals_and_the_independent_estop(manager: Manager) -> None:
    from lifecycle_msgs.msg import Transition

    assert manager.change("configure")
    assert manager.state() == "inactive"
    assert not manager.change("configure")  # wrong state, by label
    assert not manager.change(transition_id=Transition.TRANSITION_CONFIGURE)  # ... and by id: refused, alive
    assert manager.state() == "inactive"
    assert manager.change("activate")
    assert manager.state() == "active"
    ok, message = call_trigger(manager.node, "/driver/estop")
    assert ok, message
    assert manager.state() == "active"  # the estop latches beside the lifecycle: boards hold
    ok, message = call_set_bool(manager.node, "/driver/enable", True, timeout_s=1.0)
    assert not ok
    assert "emergency stop" in message
    assert manager.change("deactivate")
    assert not manager.change("activate")  # refused while the estop is latched
    assert manager.state() == "inactive"
    assert call_trigger(manager.node, "/driver/reset_estop")[0]
    assert manager.change("activate")
    assert manager.change("deactivate")
    assert manager.change("cleanup")
    assert manager.state() == "unconfigured"
    assert manager.change("configure")  # the link opens again
    assert manager.change("shutdown")
    assert manager.state() == "finalized"
