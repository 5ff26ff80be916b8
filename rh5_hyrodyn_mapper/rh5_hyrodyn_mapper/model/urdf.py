"""Generate the RH5 serial-tree URDF from the project's parameter file ``rh5_parameters.yaml``.

Pure Python (no pinocchio), so nodes can publish ``robot_description`` cheaply. The output is
deterministic: the same parameters give byte-identical text, whose hash tags trajectory files.
"""

from __future__ import annotations

import argparse
import copy
import functools
import math
import re
import sys
from collections.abc import Mapping, Sequence
from importlib import resources
from pathlib import Path
from typing import Any

import yaml

from rh5_msgs_py.names import JOINT_NAMES

from .visuals import Visual, link_visuals

PARAMETER_FILE = "rh5_parameters.yaml"
_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")
_MASSLESS: Mapping[str, Any] = {"mass": 0.0, "com": (0.0, 0.0, 0.0), "inertia": (0.0,) * 6}


@functools.cache
def _parameters_text() -> str:
    """The packaged parameter file, read once per process."""
    return resources.files(__package__).joinpath(PARAMETER_FILE).read_text(encoding="utf-8")


@functools.cache
def _parsed_parameters() -> dict[str, Any]:
    return yaml.safe_load(_parameters_text())


def load_parameters() -> dict[str, Any]:
    """The robot description from ``rh5_parameters.yaml`` (parsed once; each call returns a private copy)."""
    return copy.deepcopy(_parsed_parameters())


def _num(value: Any) -> str:
    """Full-precision text of a number (shortest repr that round-trips; no ``-0.0``)."""
    x = float(value)
    if not math.isfinite(x):
        raise ValueError(f"non-finite number in the robot parameters: {value!r}")
    return repr(x + 0.0)


def _vec(values: Sequence[Any], n: int = 3) -> str:
    if len(values) != n:
        raise ValueError(f"expected {n} numbers, got {values!r}")
    return " ".join(_num(v) for v in values)


def _pair(value: Any) -> tuple[float, float]:
    """A limit given as one number (constant) or as a ``[lo, hi]`` range."""
    if isinstance(value, Sequence) and not isinstance(value, str):
        lo, hi = (float(v) for v in value)
    else:
        lo = hi = float(value)
    if not 0.0 < lo <= hi:
        raise ValueError(f"velocity/torque limit must be 0 < lo <= hi, got {value!r}")
    return lo, hi


def _check_name(name: str) -> str:
    if not _NAME.match(name):
        raise ValueError(f"invalid link/joint/frame name {name!r}")
    return name


def _origin(spec: Mapping[str, Any], indent: str) -> str:
    return f'{indent}<origin xyz="{_vec(spec["xyz"])}" rpy="{_vec(spec["rpy"])}"/>'


def _visual(visual: Visual) -> list[str]:
    if visual.shape == "box":
        shape = f'<box size="{_vec(visual.size)}"/>'
    elif visual.shape == "cylinder":
        shape = f'<cylinder radius="{_num(visual.size[0])}" length="{_num(visual.size[1])}"/>'
    else:
        shape = f'<sphere radius="{_num(visual.size[0])}"/>'
    material = "rh5_" + visual.rgba.replace(" ", "_").replace(".", "")
    return [
        "    <visual>",
        f'      <origin xyz="{_vec(visual.xyz)}" rpy="{_vec(visual.rpy)}"/>',
        f"      <geometry>{shape}</geometry>",
        f'      <material name="{material}"><color rgba="{visual.rgba}"/></material>',
        "    </visual>",
    ]


def _link(
    name: str,
    inertial: Mapping[str, Any] | None,
    collision_box: Mapping[str, Any] | None = None,
    visuals: Sequence[Visual] = (),
) -> list[str]:
    """A link; a massless frame gets an explicit zero inertial (PyBullet would otherwise assume 1 kg)."""
    body = inertial if inertial is not None else _MASSLESS
    ixx, ixy, ixz, iyy, iyz, izz = (_num(v) for v in body["inertia"])
    lines = [
        f'  <link name="{name}">',
        "    <inertial>",
        f'      <origin xyz="{_vec(body["com"])}" rpy="0.0 0.0 0.0"/>',
        f'      <mass value="{_num(body["mass"])}"/>',
        f'      <inertia ixx="{ixx}" ixy="{ixy}" ixz="{ixz}" iyy="{iyy}" iyz="{iyz}" izz="{izz}"/>',
        "    </inertial>",
    ]
    for visual in visuals:
        lines += _visual(visual)
    if collision_box is not None:
        lines += [
            "    <collision>",
            f'      <origin xyz="{_vec(collision_box["xyz"])}" rpy="0.0 0.0 0.0"/>',
            f'      <geometry><box size="{_vec(collision_box["size"])}"/></geometry>',
            "    </collision>",
        ]
    return [*lines, "  </link>"]


def _validate_tree(params: Mapping[str, Any]) -> None:
    """Every link has exactly one parent, the base none, and all hang off the base; 32 revolute joints."""
    base = params["base_link"]
    edges = [(j["parent"], j["child"]) for j in params["joints"].values()]
    edges += [(f["parent"], name) for name, f in params["frames"].items()]
    children = [c for _, c in edges]
    duplicated = {c for c in children if children.count(c) > 1}
    if duplicated or base in children:
        raise ValueError(f"links with more than one parent: {sorted(duplicated | ({base} & set(children)))}")
    known = {base, *children}
    if missing := {p for p, _ in edges} - known:
        raise ValueError(f"unknown parent links: {sorted(missing)}")
    links_without_body = set(params["links"]) - {base, *(j["child"] for j in params["joints"].values())}
    if links_without_body:
        raise ValueError(f"links not attached by any joint: {sorted(links_without_body)}")
    revolute = [n for n, j in params["joints"].items() if j["type"] == "revolute"]
    if sorted(revolute) != sorted(JOINT_NAMES):
        raise ValueError(f"revolute joints must be exactly JOINT_NAMES, got {sorted(revolute)}")
    if set(params["limits"]) != set(JOINT_NAMES):
        raise ValueError("limits must list exactly the 32 joints of JOINT_NAMES")
    if other := {j["type"] for j in params["joints"].values()} - {"revolute", "fixed"}:
        raise ValueError(f"unsupported joint types {sorted(other)}")


def generate_urdf(params: Mapping[str, Any] | None = None, *, visuals: bool = False) -> str:
    """URDF text of the serial-tree model: 32 revolute joints, fixed sensor/plate links and massless frames.

    ``params`` defaults to :func:`load_parameters`; limits get the paper's values, using the best case
    (``hi``) of a configuration-dependent velocity/torque range. ``visuals`` adds the ``<visual>`` shapes made
    from the model's own numbers (rh5_hyrodyn_mapper.model.visuals) for RViz and Foxglove; the model hash that
    tags trajectory files is that of the text without them (visuals change no dynamics).
    """
    p = load_parameters() if params is None else params
    _validate_tree(p)
    shapes = link_visuals(p) if visuals else {}
    links: Mapping[str, Any] = p["links"]
    out = [
        '<?xml version="1.0"?>',
        f"<!-- Generated by rh5_hyrodyn_mapper.model.urdf from {PARAMETER_FILE} (format {p['format_version']}).",
        "     Numbers: rh5_public_model/urdf/rh5.urdf (BSD-3-Clause) and the RH5 paper; see the parameter file. -->",
        f'<robot name="{_check_name(p["name"])}">',
        *_link(_check_name(p["base_link"]), links[p["base_link"]], visuals=shapes.get(p["base_link"], ())),
    ]
    for name, joint in p["joints"].items():
        child = _check_name(joint["child"])
        out += [
            f'  <joint name="{_check_name(name)}" type="{joint["type"]}">',
            f'    <parent link="{_check_name(joint["parent"])}"/>',
            f'    <child link="{child}"/>',
            _origin(joint, "    "),
        ]
        if joint["type"] == "revolute":
            limit = p["limits"][name]
            lower, upper = (float(v) for v in limit["position"])
            if not lower < upper:
                raise ValueError(f"{name}: position limits must satisfy lower < upper")
            out += [
                f'    <axis xyz="{_vec(joint["axis"])}"/>',
                f'    <limit lower="{_num(lower)}" upper="{_num(upper)}" effort="{_num(_pair(limit["torque"])[1])}"'
                f' velocity="{_num(_pair(limit["velocity"])[1])}"/>',
            ]
        out += ["  </joint>", *_link(child, links.get(child), visuals=shapes.get(child, ()))]
    for name, frame in p["frames"].items():
        out += [
            *_link(_check_name(name), None, frame.get("collision_box"), shapes.get(name, ())),
            f'  <joint name="{name}_joint" type="fixed">',
            f'    <parent link="{_check_name(frame["parent"])}"/>',
            f'    <child link="{name}"/>',
            _origin(frame, "    "),
            "  </joint>",
        ]
    return "\n".join([*out, "</robot>", ""])


def main(argv: Sequence[str] | None = None) -> int:
    """``rh5_urdf [-o FILE]``: write the generated URDF to FILE or stdout."""
    parser = argparse.ArgumentParser(prog="rh5_urdf", description="Write the RH5 serial-tree URDF of this project.")
    parser.add_argument("-o", "--output", type=Path, help="output file (default: stdout)")
    parser.add_argument("--no-visuals", action="store_true", help="leave out the <visual> shapes (the hashed model)")
    args = parser.parse_args(argv)
    text = generate_urdf(visuals=not args.no_visuals)
    if args.output is None:
        sys.stdout.write(text)
    else:
        args.output.write_text(text, encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
