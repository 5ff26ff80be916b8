# Generated from rh5_bringup/bringup.yaml by `python -m rh5_bringup.launch_files`: do not edit by hand.
"""Launch the RH5 control suite: `ros2 launch rh5_bringup rh5.launch.py [sim:=kinematic|physics]`."""

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

NAMESPACE = ''

ARGUMENTS = {'sim': {'default': 'kinematic',
         'choices': ['kinematic', 'physics'],
         'description': 'Simulated hardware, kinematic (boards only) or physics (PyBullet floating-base RH5 '
                        'on the ground).',
         'node': 'sim_hardware',
         'parameter': 'mode'}}
"""Launch arguments: name -> default, choices, description and the node parameter each sets."""

NODES = [{'name': 'recorder',
  'package': 'rh5_bringup',
  'executable': 'recorder_node',
  'parameters': {},
  'remappings': []},
 {'name': 'sim_hardware',
  'package': 'rh5_bringup',
  'executable': 'sim_hardware_node',
  'parameters': {},
  'remappings': []},
 {'name': 'driver',
  'package': 'rh5_bringup',
  'executable': 'driver_node',
  'parameters': {'transport': 'udp', 'router_host': '127.0.0.1', 'board_silence_timeout_s': 0.05},
  'remappings': []},
 {'name': 'mapper',
  'package': 'rh5_hyrodyn_mapper',
  'executable': 'mapper_node',
  'parameters': {},
  'remappings': []},
 {'name': 'stabilizer',
  'package': 'rh5_joint_stabilizer',
  'executable': 'stabilizer_node',
  'parameters': {'state_timeout_s': 0.05},
  'remappings': []},
 {'name': 'planner',
  'package': 'rh5_planner',
  'executable': 'planner_node',
  'parameters': {},
  'remappings': []}]
"""The nodes in start order, as in bringup.yaml."""


def generate_launch_description() -> LaunchDescription:
    """Declare the arguments and one Node action per node of the bringup description."""
    actions = [
        DeclareLaunchArgument(name, default_value=a["default"], choices=a["choices"], description=a["description"])
        for name, a in ARGUMENTS.items()
    ]
    for node in NODES:
        parameters = dict(node["parameters"])
        for name, a in ARGUMENTS.items():
            if a["node"] == node["name"]:
                parameters[a["parameter"]] = LaunchConfiguration(name)
        actions.append(
            Node(
                package=node["package"],
                executable=node["executable"],
                name=node["name"],
                namespace=NAMESPACE,
                parameters=[parameters],
                remappings=node["remappings"],
                output="screen",
            )
        )
    return LaunchDescription(actions)
