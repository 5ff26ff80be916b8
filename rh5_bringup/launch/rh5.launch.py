# Generated from orchestration/bringup.yaml by `python -m rh5_bringup.orchestration.launch_files`: do not edit by hand.
"""Launch the RH5 control suite:
`ros2 launch rh5_bringup rh5.launch.py [sim:=kinematic|physics] [driver_autostart:=none|configure|activate]`.

separate:=true runs the driver, mapper and stabilizer as three processes instead of the control process.
"""

import tempfile

import yaml
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

NAMESPACE = ''

ARGUMENTS = {'sim': {'default': 'kinematic',
         'choices': ['kinematic', 'physics'],
         'description': 'Simulated hardware, kinematic (boards only) or physics (PyBullet floating-base RH5 '
                        'on the ground).',
         'node': 'sim_hardware',
         'parameter': 'mode',
         'implies': {'physics': {'sim_hardware': {'publish_clock': True, 'use_sim_time': True},
                                 'stabilizer': {'use_sim_time': True,
                                                'playback_clock': 'ros',
                                                'rest_velocity_rad_s': 0.25,
                                                'state_timeout_s': 0.5},
                                 'driver': {'use_sim_time': True,
                                            'board_silence_timeout_s': 0.5,
                                            'command_timeout_s': 0.5},
                                 'control': {'use_sim_time': True},
                                 'mapper': {'use_sim_time': True},
                                 'recorder': {'use_sim_time': True},
                                 'state_publisher': {'use_sim_time': True},
                                 'planner': {'use_sim_time': True}}}},
 'driver_autostart': {'default': 'configure',
                      'choices': ['none', 'configure', 'activate'],
                      'description': 'Lifecycle transitions the driver makes by itself once started (none, '
                                     'configure or activate).',
                      'node': 'driver',
                      'parameter': 'autostart',
                      'implies': {}}}
"""Launch arguments: name -> default, choices, description, the node parameter each sets, and the further
parameters some of its values imply (value -> node -> parameters)."""

NODES = [{'name': 'recorder',
  'package': 'rh5_bringup',
  'executable': 'recorder_node',
  'parameters': {},
  'remappings': [],
  'hosts': []},
 {'name': 'sim_hardware',
  'package': 'rh5_bringup',
  'executable': 'sim_hardware_node',
  'parameters': {'cpu_affinity': [0]},
  'remappings': [],
  'hosts': []},
 {'name': 'control',
  'package': 'rh5_bringup',
  'executable': 'control_node',
  'parameters': {'cpu_affinity': [-1]},
  'remappings': [],
  'hosts': ['driver', 'mapper', 'stabilizer']},
 {'name': 'driver',
  'package': 'rh5_bringup',
  'executable': 'driver_node',
  'parameters': {'transport': 'udp', 'router_host': '127.0.0.1', 'board_silence_timeout_s': 0.05},
  'remappings': [],
  'hosts': []},
 {'name': 'mapper',
  'package': 'rh5_hyrodyn_mapper',
  'executable': 'mapper_node',
  'parameters': {},
  'remappings': [],
  'hosts': []},
 {'name': 'stabilizer',
  'package': 'rh5_joint_stabilizer',
  'executable': 'stabilizer_node',
  'parameters': {'state_timeout_s': 0.05},
  'remappings': [],
  'hosts': []},
 {'name': 'state_publisher',
  'package': 'rh5_hyrodyn_mapper',
  'executable': 'state_publisher_node',
  'parameters': {},
  'remappings': [],
  'hosts': []},
 {'name': 'planner',
  'package': 'rh5_planner',
  'executable': 'planner_node',
  'parameters': {},
  'remappings': [],
  'hosts': []}]
"""The nodes in start order, as in bringup.yaml. A node with ``hosts`` runs those nodes in its own process (the
control process); with separate:=true they run on their own instead, and the host is left out."""


def _parameters(context) -> dict:
    """Each node's parameters with the launch arguments' values applied."""
    values = {name: LaunchConfiguration(name).perform(context) for name in ARGUMENTS}
    out = {}
    for node in NODES:
        parameters = dict(node["parameters"])
        for name, a in ARGUMENTS.items():
            if a["node"] == node["name"]:
                parameters[a["parameter"]] = values[name]
            parameters.update(a["implies"].get(values[name], {}).get(node["name"], {}))
        out[node["name"]] = parameters
    return out


def _full_name(name: str) -> str:
    return f"/{NAMESPACE.strip('/')}/{name}" if NAMESPACE.strip("/") else f"/{name}"


def _nodes(context) -> list:
    """One Node action per process: the hosted nodes inside their host's unless separate:=true."""
    parameters = _parameters(context)
    separate = LaunchConfiguration("separate").perform(context).lower() in ("true", "1", "yes")
    hosted = {name for node in NODES for name in node["hosts"]}
    actions = []
    for node in NODES:
        if node["hosts"] and not separate:
            names = [node["name"], *node["hosts"]]
            document = {_full_name(n): {"ros__parameters": parameters[n]} for n in names}
            with tempfile.NamedTemporaryFile("w", suffix=".yaml", prefix=node["name"] + "_", delete=False) as f:
                yaml.safe_dump(document, f)
            remaps = [
                (f"{n['name']}:{src}", dst) for n in NODES if n["name"] in names for src, dst in n["remappings"]
            ]
            actions.append(
                Node(
                    package=node["package"],
                    executable=node["executable"],
                    namespace=NAMESPACE,
                    parameters=[f.name],
                    remappings=remaps,
                    output="screen",
                )
            )
        elif not node["hosts"] and (separate or node["name"] not in hosted):
            actions.append(
                Node(
                    package=node["package"],
                    executable=node["executable"],
                    name=node["name"],
                    namespace=NAMESPACE,
                    parameters=[parameters[node["name"]]],
                    remappings=node["remappings"],
                    output="screen",
                )
            )
    return actions


def generate_launch_description() -> LaunchDescription:
    """Declare the arguments; the nodes are made once their values are known."""
    declared = [
        DeclareLaunchArgument(name, default_value=a["default"], choices=a["choices"], description=a["description"])
        for name, a in ARGUMENTS.items()
    ]
    declared.append(
        DeclareLaunchArgument(
            "separate",
            default_value="false",
            choices=["false", "true"],
            description="Run the control process's nodes (driver, mapper, stabilizer) as separate processes.",
        )
    )
    return LaunchDescription([*declared, OpaqueFunction(function=_nodes)])
