"""StreamThread: 1 kHz subscriptions served by their own thread, never by the executor."""

from __future__ import annotations

import threading
import time
from typing import Any

import pytest

from rh5_msgs_py import interfaces

pytestmark = pytest.mark.ros


def test_stream_callbacks_run_in_the_stream_thread_and_not_in_the_executor(ros_graph: Any) -> None:
    import rclpy
    from sensor_msgs.msg import JointState

    from rh5_msgs_py.node_runtime import SuiteNode

    class Listener(SuiteNode):
        def __init__(self) -> None:
            super().__init__("stream_listener", "rh5_hyrodyn_mapper", "params/mapper.yaml")
            self.threads: list[str] = []
            self.subscribe_stream(
                interfaces.JOINT_STATES, lambda _m: self.threads.append(threading.current_thread().name)
            )

    node = Listener()
    executor = rclpy.executors.SingleThreadedExecutor()
    executor.add_node(node)
    publisher = ros_graph.create_publisher(JointState, interfaces.JOINT_STATES.name, interfaces.STREAM_QOS)
    try:
        deadline = time.monotonic() + 10.0
        while len(node.threads) < 50 and time.monotonic() < deadline:
            publisher.publish(JointState())
            executor.spin_once(timeout_sec=0.002)  # the executor runs, but must not be the one taking messages
        assert len(node.threads) >= 50
        assert set(node.threads) == {"stream_listener-streams"}
        assert node.seen[interfaces.JOINT_STATES.name] == len(node.threads)
        late: list[int] = []  # a stream subscribed after the thread started is served from its next wait
        node.subscribe_stream(interfaces.JOINT_COMMANDS, lambda _m: late.append(1))
        commands = ros_graph.create_publisher(JointState, interfaces.JOINT_COMMANDS.name, interfaces.STREAM_QOS)
        deadline = time.monotonic() + 10.0
        while not late and time.monotonic() < deadline:
            commands.publish(JointState())
            time.sleep(0.002)
        assert late
    finally:
        executor.remove_node(node)
        streams = node._streams
        node.destroy_node()
        ros_graph.destroy_publisher(publisher)
    assert streams is not None
    assert not streams._thread.is_alive()
    assert streams.error is None
