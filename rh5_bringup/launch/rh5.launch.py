# Generated from rh5_bringup/bringup.yaml by `python -m rh5_bringup.launch_files`: do not edit by hand.
"""Launch the RH5 control suite: `ros2 launch rh5_bringup rh5.launch.py [sim:=kinematic|physics]`."""

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
         'implies': {'physics': {'sim_hardware': {'publish_clock': True},
                                 'stabilizer': {'use_sim_time': True,
                                                'playback_clock': 'ros',
                                                'rest_velocity_rad_s': 0.25,
                                                'state_timeout_s': 0.5},
                                 'driver': {'board_silence_timeout_s': 0.5, 'command_timeout_s': 0.5}}}}}
"""Launch arguments: name -> default, choices, description, the node parameter each sets, and the further
parameters some of its values imply (value -> node -> parameters)."""

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


def _nodes(context) -> list:
    """One Node action per node of the bringup description, with the launch arguments' values applied."""
    values = {name: LaunchConfiguration(name).perform(context) for name in ARGUMENTS}
    actions = []
    for node in NODES:
        parameters = dict(node["parameters"])
        for name, a in ARGUMENTS.items():
            if a["node"] == node["name"]:
                parameters[a["parameter"]] = values[name]
            parameters.update(a["implies"].get(values[name], {}).get(node["name"], {}))
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
    return actions


def generate_launch_description() -> LaunchDescription:
    """Declare the arguments; the nodes are made once their values are known."""
    declared = [
        DeclareLaunchArgument(name, default_value=a["default"], choices=a["choices"], description=a["description"])
        for name, a in ARGUMENTS.items()
    ]
    return LaunchDescription([*declared, OpaqueFunction(function=_nodes)])
