"""Topic names, service names, message types and QoS profiles of the suite; the /diagnostics names and keys other
processes read (from :mod:`rh5_msgs_py.diagnostic_keys`).

Names are relative (no leading slash) so that a namespace given at launch moves the
whole suite; ``/diagnostics`` stays absolute as in every ROS 2 system. 1 kHz streams
are best effort with depth 1 (the newest sample is the only useful one), trajectories
and the robot description are reliable + transient local (late joiners get them).
"""

from __future__ import annotations

import importlib
from typing import Final, NamedTuple

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from rh5_msgs_py.diagnostic_keys import (  # noqa: F401  (re-exported: the /diagnostics names and keys)
    CONTROL_STATUS,
    DRIVER_STATUS,
    HARDWARE_ID,
    MAPPER_STATUS,
    PHYSICS_TASK,
    PLANNER_STATUS,
    STABILIZER_STATUS,
    ControlKeys,
    DriverKeys,
    LoopKeys,
    MapperKeys,
    Percentile,
    StabilizerKeys,
    task_name,
    task_prefix,
)

STREAM_QOS: Final = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=1,
    reliability=ReliabilityPolicy.BEST_EFFORT,
    durability=DurabilityPolicy.VOLATILE,
)
"""1 kHz streams: joint/actuator commands and states."""

LATCHED_QOS: Final = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=1,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)
"""Trajectories and the robot description: published once, kept for late joiners."""

EVENT_QOS: Final = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=10,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)
"""Low-rate reliable traffic: diagnostics, progress, evaluation data."""

TF_QOS: Final = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=100,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)
"""/tf, as tf2's transform broadcaster offers it."""

TF_STATIC_QOS: Final = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=1,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)
"""/tf_static, as tf2's static transform broadcaster offers it (late joiners get the fixed frames)."""


class Topic(NamedTuple):
    """A topic of the suite: its name, message type (``pkg/msg/Type``) and QoS."""

    name: str
    type: str
    qos: QoSProfile


ROBOT_DESCRIPTION: Final = Topic("robot_description", "std_msgs/msg/String", LATCHED_QOS)
PLANNED_TRAJECTORY: Final = Topic("planned_trajectory", "trajectory_msgs/msg/JointTrajectory", LATCHED_QOS)
PLANNED_BASE_TRAJECTORY: Final = Topic(
    "planned_base_trajectory", "trajectory_msgs/msg/MultiDOFJointTrajectory", LATCHED_QOS
)
PLANNED_WRENCH_LEFT: Final = Topic("planned_wrench/left_foot", "geometry_msgs/msg/WrenchStamped", EVENT_QOS)
PLANNED_WRENCH_RIGHT: Final = Topic("planned_wrench/right_foot", "geometry_msgs/msg/WrenchStamped", EVENT_QOS)
PLANNER_PROGRESS: Final = Topic("planner/progress", "diagnostic_msgs/msg/DiagnosticStatus", EVENT_QOS)
JOINT_COMMANDS: Final = Topic("joint_commands", "sensor_msgs/msg/JointState", STREAM_QOS)
JOINT_STATES: Final = Topic("joint_states", "sensor_msgs/msg/JointState", STREAM_QOS)
ACTUATOR_COMMANDS: Final = Topic("actuator_commands", "sensor_msgs/msg/JointState", STREAM_QOS)
ACTUATOR_STATES: Final = Topic("actuator_states", "sensor_msgs/msg/JointState", STREAM_QOS)
SIM_BASE_POSE: Final = Topic("sim/base_pose", "geometry_msgs/msg/PoseStamped", STREAM_QOS)
SIM_WRENCH_LEFT: Final = Topic("sim/wrench/left_foot", "geometry_msgs/msg/WrenchStamped", STREAM_QOS)
SIM_WRENCH_RIGHT: Final = Topic("sim/wrench/right_foot", "geometry_msgs/msg/WrenchStamped", STREAM_QOS)
CLOCK: Final = Topic("/clock", "rosgraph_msgs/msg/Clock", STREAM_QOS)
"""Simulated time, published by the physics simulation when it runs slower than real time (publish_clock)."""
DRIVER_ESTOP: Final = Topic("driver/estopped", "std_msgs/msg/Bool", LATCHED_QOS)
"""The driver's emergency-stop latch, published on every change (the stabilizer stops while it is set)."""
DIAGNOSTICS: Final = Topic("/diagnostics", "diagnostic_msgs/msg/DiagnosticArray", EVENT_QOS)
TF: Final = Topic("/tf", "tf2_msgs/msg/TFMessage", TF_QOS)
"""Every link of the robot and odom -> RH5_Root_Link (state_publisher; tf2_msgs is built by make venv)."""
TF_STATIC: Final = Topic("/tf_static", "tf2_msgs/msg/TFMessage", TF_STATIC_QOS)
"""The fixed joints' transforms, once (state_publisher)."""

ALL_TOPICS: Final[tuple[Topic, ...]] = (
    ROBOT_DESCRIPTION,
    PLANNED_TRAJECTORY,
    PLANNED_BASE_TRAJECTORY,
    PLANNED_WRENCH_LEFT,
    PLANNED_WRENCH_RIGHT,
    PLANNER_PROGRESS,
    JOINT_COMMANDS,
    JOINT_STATES,
    ACTUATOR_COMMANDS,
    ACTUATOR_STATES,
    SIM_BASE_POSE,
    SIM_WRENCH_LEFT,
    SIM_WRENCH_RIGHT,
    DRIVER_ESTOP,
    DIAGNOSTICS,
    CLOCK,
    TF,
    TF_STATIC,
)
"""Every topic the suite publishes: what the recorder records by default."""

# Services, relative to the node that offers them ("~/" = private namespace).
PLAN_SERVICE: Final = "~/plan"  # std_srvs/Trigger, planner
LOAD_SERVICE: Final = "~/load"  # std_srvs/Trigger, planner
START_SERVICE: Final = "~/start"  # std_srvs/Trigger, stabilizer
STOP_SERVICE: Final = "~/stop"  # std_srvs/Trigger, stabilizer
HOLD_SERVICE: Final = "~/hold"  # std_srvs/Trigger, stabilizer
ENABLE_SERVICE: Final = "~/enable"  # std_srvs/SetBool, driver
ESTOP_SERVICE: Final = "~/estop"  # std_srvs/Trigger, driver (latching)
RESET_ESTOP_SERVICE: Final = "~/reset_estop"  # std_srvs/Trigger, driver
RELEASE_SUPPORT_SERVICE: Final = "~/release_support"  # std_srvs/Trigger, sim_hardware (physics mode)

# Node names (also the keys of the bringup description).
PLANNER_NODE: Final = "planner"
MAPPER_NODE: Final = "mapper"
STABILIZER_NODE: Final = "stabilizer"
DRIVER_NODE: Final = "driver"
CONTROL_NODE: Final = "control"
CONTROL_STREAMS_NODE: Final = "control_streams"
"""The control process's child that publishes its 1 kHz topics (rh5_bringup.control.stream_publisher)."""
SIM_HARDWARE_NODE: Final = "sim_hardware"
RECORDER_NODE: Final = "recorder"
STATE_PUBLISHER_NODE: Final = "state_publisher"


def message_class(type_name: str) -> type:
    """The Python class of a ``pkg/msg/Type`` name, e.g. ``sensor_msgs/msg/JointState``."""
    package, kind, name = type_name.split("/")
    module = importlib.import_module(f"{package}.{kind}")
    return getattr(module, name)
