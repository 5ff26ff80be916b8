"""The recorder node: subscribes to every topic of the suite as serialized CDR.

At this stage it counts the messages per topic; writing them to a rosbag2-compatible
MCAP bag comes with the end-to-end experiment issue.
"""

from __future__ import annotations

from rh5_msgs_py import interfaces
from rh5_msgs_py.node_runtime import SuiteNode, run_node


class RecorderNode(SuiteNode):
    """Raw subscriptions to the recorded topics."""

    def __init__(self) -> None:
        super().__init__(interfaces.RECORDER_NODE, "rh5_bringup", "params/recorder.yaml")
        wanted = set(self.params["topics"])
        unknown = wanted - {t.name for t in interfaces.ALL_TOPICS}
        if unknown:
            msg = f"parameter topics: not topics of the suite: {sorted(unknown)}"
            raise ValueError(msg)
        for topic in interfaces.ALL_TOPICS:
            if not wanted or topic.name in wanted:
                self.subscribe(topic, raw=True)


def main(args: list[str] | None = None) -> None:
    """Entry point of ``ros2 run rh5_bringup recorder_node``."""
    run_node(RecorderNode, args)
