"""Write docs/parameters.md from the nodes' parameter specs (run after editing a params/*.yaml).

The specs are the single source: tests/test_docs.py fails when the file is out of date.
"""

from __future__ import annotations

import sys
from pathlib import Path

from rh5_msgs_py.parameters import load_spec, markdown_table

NODE_SPECS = (
    ("planner", "rh5_planner", "planner_node"),
    ("mapper", "rh5_hyrodyn_mapper", "mapper_node"),
    ("stabilizer", "rh5_joint_stabilizer", "stabilizer_node"),
    ("control", "rh5_bringup", "control_node"),
    ("driver", "rh5_bringup", "driver_node"),
    ("sim_hardware", "rh5_bringup", "sim_hardware_node"),
    ("recorder", "rh5_bringup", "recorder_node"),
)
TARGET = Path(__file__).resolve().parents[1] / "docs" / "parameters.md"


def render() -> str:
    """The whole document."""
    parts = [
        "# Node parameters",
        "",
        "Generated from `<package>/<package>/params/<node>.yaml` by `tools/write_parameter_docs.py`; do not edit.",
        "Set them at launch (`--ros-args -p name:=value`, `--params-file rh5_bringup/config/<node>.params.yaml`,",
        "or the bringup description) or, unless read-only, at run time, where they act from the node's next cycle.",
        "A value outside its range or choices, or one the node cannot use, is refused with the reason; a name the",
        "node does not have stops it at launch (exit code 2, with the valid names).",
    ]
    for node, package, executable in NODE_SPECS:
        parts += ["", f"## {node} (`ros2 run {package} {executable}`)", ""]
        parts.append(markdown_table(load_spec(package, f"params/{node}.yaml")))
    return "\n".join(parts) + "\n"


def main() -> int:
    """Write the file, or with --check report whether it is current (exit 1 if not)."""
    text = render()
    if "--check" in sys.argv:
        return 0 if TARGET.read_text(encoding="utf-8") == text else 1
    TARGET.write_text(text, encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
