"""Generate the ROS 2 launch files of the suite from the one bringup description.

``rh5 up`` reads orchestration/bringup.yaml directly; full ROS 2 installs use
``ros2 launch rh5_bringup rh5.launch.py sim:=physics``, whose file is rendered here from the same
description (nodes, parameters, remappings, namespace, launch arguments), so the two cannot drift
apart: ``python -m rh5_bringup.orchestration.launch_files --check`` (run by the tests) fails when the committed
file differs from what the description renders.
"""

from __future__ import annotations

import pprint
import sys
from pathlib import Path

from rh5_bringup.orchestration.generated_files import generated_files_main
from rh5_bringup.orchestration.launcher import Bringup, load_bringup

LAUNCH_DIR = Path(__file__).resolve().parents[2] / "launch"
"""rh5_bringup/launch in the source tree (installed to share/rh5_bringup/launch by setup.py)."""

LAUNCH_FILE = "rh5.launch.py"

_TEMPLATE = '''\
# Generated from orchestration/bringup.yaml by `python -m rh5_bringup.orchestration.launch_files`: do not edit by hand.
"""Launch the RH5 control suite:
`ros2 launch rh5_bringup {file_name}{argument_usage}`.

separate:=true runs the driver, mapper and stabilizer as three processes instead of the control process.
"""

import tempfile

import yaml
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

NAMESPACE = {namespace!r}

ARGUMENTS = {arguments}
"""Launch arguments: name -> default, choices, description, the node parameter each sets, and the further
parameters some of its values imply (value -> node -> parameters)."""

NODES = {nodes}
"""The nodes in start order, as in bringup.yaml. A node with ``hosts`` runs those nodes in its own process (the
control process); with separate:=true they run on their own instead, and the host is left out."""


def _parameters(context) -> dict:
    """Each node's parameters with the launch arguments' values applied."""
    values = {{name: LaunchConfiguration(name).perform(context) for name in ARGUMENTS}}
    out = {{}}
    for node in NODES:
        parameters = dict(node["parameters"])
        for name, a in ARGUMENTS.items():
            if a["node"] == node["name"]:
                parameters[a["parameter"]] = values[name]
            parameters.update(a["implies"].get(values[name], {{}}).get(node["name"], {{}}))
        out[node["name"]] = parameters
    return out


def _full_name(name: str) -> str:
    return f"/{{NAMESPACE.strip('/')}}/{{name}}" if NAMESPACE.strip("/") else f"/{{name}}"


def _nodes(context) -> list:
    """One Node action per process: the hosted nodes inside their host's unless separate:=true."""
    parameters = _parameters(context)
    separate = LaunchConfiguration("separate").perform(context).lower() in ("true", "1", "yes")
    hosted = {{name for node in NODES for name in node["hosts"]}}
    actions = []
    for node in NODES:
        if node["hosts"] and not separate:
            names = [node["name"], *node["hosts"]]
            document = {{_full_name(n): {{"ros__parameters": parameters[n]}} for n in names}}
            with tempfile.NamedTemporaryFile("w", suffix=".yaml", prefix=node["name"] + "_", delete=False) as f:
                yaml.safe_dump(document, f)
            remaps = [
                (f"{{n['name']}}:{{src}}", dst) for n in NODES if n["name"] in names for src, dst in n["remappings"]
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
'''


def _literal(value: object) -> str:
    """A deterministic Python literal, indented to sit after ``NAME = ``."""
    return pprint.pformat(value, width=110, sort_dicts=False)


def render_launch_file(bringup: Bringup, file_name: str = LAUNCH_FILE) -> str:
    """The launch file's text for ``bringup``."""
    arguments = {
        a.name: {
            "default": a.default,
            "choices": list(a.choices),
            "description": a.description,
            "node": a.node,
            "parameter": a.parameter,
            "implies": {value: {node: dict(p) for node, p in by_node.items()} for value, by_node in a.implies.items()},
        }
        for a in bringup.arguments
    }
    nodes = [
        {
            "name": n.name,
            "package": n.package,
            "executable": n.executable,
            "parameters": dict(n.parameters),
            "remappings": [list(pair) for pair in n.remappings],
            "hosts": list(n.hosts),
        }
        for n in bringup.nodes
    ]
    usage = "".join(f" [{a.name}:={'|'.join(a.choices) or a.default}]" for a in bringup.arguments)
    return _TEMPLATE.format(
        file_name=file_name,
        argument_usage=usage,
        namespace=bringup.namespace,
        arguments=_literal(arguments),
        nodes=_literal(nodes),
    )


def main(argv: list[str] | None = None) -> int:
    """Write (or with --check, verify) rh5_bringup/launch/rh5.launch.py."""
    return generated_files_main(
        "rh5_bringup.orchestration.launch_files",
        __doc__.splitlines()[0],
        LAUNCH_DIR,
        lambda folder: {folder / LAUNCH_FILE: render_launch_file(load_bringup())},
        argv,
    )


if __name__ == "__main__":
    sys.exit(main())
