"""The state publisher node: /tf of every link of RH5 from joint_states, and odom -> RH5_Root_Link.

What robot_state_publisher does, with the project's own model (rh5_hyrodyn_mapper.tf_tree): the fixed
joints' transforms go once to the latched ``/tf_static``; every ``1 / publish_rate_hz`` the newest
``joint_states`` becomes one transform per revolute joint, and the newest base pose (``base_pose_topic``) the
transform ``odom -> RH5_Root_Link``, all in one ``/tf`` message stamped with the joint states' stamp.

It is cheap by construction: the 1 kHz ``joint_states`` and the base pose are never handed to the executor
(their subscriptions sit in a callback group no executor runs, depth 1); a loop thread of the node takes only
the newest sample of each; the transforms of all 32 joints are one vectorised computation, written into a
message serialised once (rh5_hyrodyn_mapper.tf_cdr) instead of converted field by field at every publish.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from geometry_msgs.msg import TransformStamped

from rh5_hyrodyn_mapper.model import robot_model
from rh5_hyrodyn_mapper.tf_cdr import SerializedTf
from rh5_hyrodyn_mapper.tf_tree import KinematicTree
from rh5_msgs_py import interfaces
from rh5_msgs_py.conversions import JointStateCodec, to_time_msg
from rh5_msgs_py.interfaces import Topic, message_class
from rh5_msgs_py.names import JOINT_NAMES
from rh5_msgs_py.node_runtime import SuiteNode, run_node
from rh5_msgs_py.streams import NeverExecutedGroup


def _transform(parent: str, child: str, translation: np.ndarray, rotation: np.ndarray) -> TransformStamped:
    out = TransformStamped()
    out.header.frame_id, out.child_frame_id = parent, child
    t, r = out.transform.translation, out.transform.rotation
    t.x, t.y, t.z = (float(v) for v in translation)
    r.x, r.y, r.z, r.w = (float(v) for v in rotation)
    return out


class StatePublisherNode(SuiteNode):
    """Publishes the robot's link transforms on /tf and /tf_static."""

    def __init__(self) -> None:
        super().__init__(interfaces.STATE_PUBLISHER_NODE, "rh5_hyrodyn_mapper", "params/state_publisher.yaml")
        params = self.params
        model = robot_model(free_flyer=False)
        self.tree = KinematicTree(model.urdf)
        tf_type = message_class(interfaces.TF.type)
        self._codec = JointStateCodec(JOINT_NAMES, what="joint_states")
        never = NeverExecutedGroup()
        self._joint_states = self._poll(interfaces.JOINT_STATES, never)
        topic = params["base_pose_topic"]
        self._base_pose = (
            self._poll(Topic(topic, interfaces.SIM_BASE_POSE.type, interfaces.STREAM_QOS), never) if topic else None
        )
        standing = robot_model().q_standing  # the free flyer's pose when no base pose has come
        tree = self.tree
        frames = [(params["odom_frame"], tree.root), *zip(tree.parents, tree.children, strict=True)]
        self._tf = SerializedTf(tf_type, TransformStamped, frames)
        self._tf.poses[0] = standing[:7]
        self._tf.poses[1:, :3] = tree.origin_translation
        static = tf_type(
            transforms=[
                _transform(p, c, t, r)
                for p, c, t, r in zip(
                    tree.fixed_parents, tree.fixed_children, tree.fixed_translation, tree.fixed_rotation, strict=True
                )
            ]
        )
        now = self.get_clock().now().nanoseconds
        for transform in static.transforms:
            to_time_msg(now, transform.header.stamp)
        self.advertise(interfaces.TF_STATIC)(static)
        self._publish_tf = self.advertise(interfaces.TF)
        self._last_stamp: tuple[int, int] | None = None
        self._last_pose: Any = None
        # A loop thread of its own, not an executor timer: each executor wake-up rebuilds its wait set from every
        # entity of the node (~1 ms here), which at 50 Hz cost more than the transforms themselves.
        self.loop = self.start_loop(params["publish_rate_hz"], lambda _now, _period: self._publish(), "tf", 0)

    def _poll(self, topic: Topic, group: NeverExecutedGroup) -> Any:
        """A subscription whose newest message the loop takes (the executor never serves it)."""
        return self.create_subscription(
            message_class(topic.type), topic.name, lambda _msg: None, topic.qos, callback_group=group
        )

    @staticmethod
    def _newest(subscription: Any) -> Any:
        """The newest message waiting on ``subscription`` (None if none came since the last call)."""
        newest = None
        with subscription.handle:
            while (taken := subscription.handle.take_message(subscription.msg_type, False)) is not None:
                newest = taken[0]
        return newest

    def _publish(self) -> None:
        """One /tf message: the newest joint angles and base pose (nothing when neither is new)."""
        state = self._newest(self._joint_states)
        pose = self._newest(self._base_pose) if self._base_pose is not None else None
        if state is None and pose is None:
            return
        if pose is not None:
            self.seen[self._base_pose.topic_name] += 1
            p, o = pose.pose.position, pose.pose.orientation
            self._tf.poses[0] = (p.x, p.y, p.z, o.x, o.y, o.z, o.w)
        if state is not None:
            self.seen[interfaces.JOINT_STATES.name] += 1
            try:
                position, _, _ = self._codec.decode(state)
            except ValueError as err:
                self.get_logger().warning(f"joint_states ignored: {err}", throttle_duration_sec=5.0)
                return
            if position is None or not np.isfinite(position).all():
                return
            self._tf.poses[1:, 3:] = self.tree.rotations(position)
            self._last_stamp = (state.header.stamp.sec, state.header.stamp.nanosec)
        if self._last_stamp is None:
            return  # no joint angles yet: a tree without them would be a made-up pose
        self._publish_tf(self._tf.serialized(*self._last_stamp))

    def destroy_node(self) -> None:
        """Stop the loop before the subscriptions and publishers go away."""
        self.loop.stop()
        super().destroy_node()


def main(args: list[str] | None = None) -> None:
    """Entry point of ``ros2 run rh5_hyrodyn_mapper state_publisher_node``."""
    run_node(StatePublisherNode, args)
