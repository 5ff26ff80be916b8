"""Generate ROS 2 params files (``ros__parameters``) for every node of the suite from its parameter spec.

A node's spec (``params/<node>.yaml`` in its package, rh5_msgs_py.parameters) says what each parameter is;
it is not a params file. The files written here are: ``rh5_bringup/config/<node>.params.yaml``, every
parameter at its default with its description as a comment, for

    mapper_node --ros-args --params-file rh5_bringup/config/mapper.params.yaml

(installed to share/rh5_bringup/config). The control process's file also holds the driver, mapper and
stabilizer it hosts. ``python -m rh5_bringup.orchestration.params_files --check`` (run by the tests) fails when a
committed file differs from what the specs render.
"""

from __future__ import annotations

import sys
from pathlib import Path

import yaml

from rh5_bringup.orchestration.generated_files import generated_files_main
from rh5_bringup.orchestration.launcher import Bringup, NodeSpec, load_bringup
from rh5_msgs_py.parameters import ParamSpec, load_spec

CONFIG_DIR = Path(__file__).resolve().parents[2] / "config"
"""rh5_bringup/config in the source tree (installed to share/rh5_bringup/config by setup.py)."""
WIDTH = 116


def _value(spec: ParamSpec) -> str:
    """The default as a one-line YAML value."""
    return yaml.safe_dump(spec.default, default_flow_style=True, width=10_000).strip().removesuffix("\n...")


def _comment(text: str, indent: str) -> list[str]:
    """``text`` as comment lines of at most WIDTH characters."""
    lines, line = [], ""
    for word in text.split():
        if line and len(indent) + 2 + len(line) + 1 + len(word) > WIDTH:
            lines.append(line)
            line = word
        else:
            line = f"{line} {word}" if line else word
    return [f"{indent}# {piece}" for piece in [*lines, line] if piece]


def _section(node: NodeSpec) -> list[str]:
    """``<node>: ros__parameters:`` with every parameter of its spec at its default."""
    out = [f"{node.name}:", "  ros__parameters:"]
    for spec in load_spec(node.package, f"params/{node.name}.yaml"):
        limits = f" Range {list(spec.range)}." if spec.range else ""
        limits += f" One of {list(spec.choices)}." if spec.choices else ""
        limits += " Read-only: set at launch only." if spec.read_only else ""
        out += _comment(f"{spec.description}{limits}", "    ")
        if spec.is_array and not spec.default:  # rcl's YAML parser cannot type an empty list
            out.append(f"    # {spec.name}: []  (empty by default: list values here, or leave it out)")
        else:
            out.append(f"    {spec.name}: {_value(spec)}")
    return out


def render_params_file(bringup: Bringup, name: str) -> str:
    """The params file of node ``name`` (with the nodes its process hosts)."""
    nodes = {n.name: n for n in bringup.nodes}
    host = nodes[name]
    executable = f"{host.executable} --ros-args --params-file {name}.params.yaml"
    lines = [
        f"# Parameters of the {name} node{' and the nodes it hosts' if host.hosts else ''}, at their defaults.",
        "# Generated from the parameter specs by `python -m rh5_bringup.orchestration.params_files`: edit a copy.",
        f"# Use: {executable}",
    ]
    for node in (host, *(nodes[h] for h in host.hosts)):
        lines += _section(node)
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    """Write (or with --check, verify) rh5_bringup/config/<node>.params.yaml for every node of the bringup."""
    bringup = load_bringup()
    return generated_files_main(
        "rh5_bringup.orchestration.params_files",
        __doc__.splitlines()[0],
        CONFIG_DIR,
        lambda folder: {folder / f"{n.name}.params.yaml": render_params_file(bringup, n.name) for n in bringup.nodes},
        argv,
    )


if __name__ == "__main__":
    sys.exit(main())
