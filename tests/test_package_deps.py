"""Every package.xml declares what its package imports, under keys rosdep resolves (issue 15).

The keys were checked against ros/rosdistro (rosdep/python.yaml, rosdep/base.yaml and jazzy/distribution.yaml):
ROS packages resolve by their own name; Python libraries by their rosdep key, which for PyPI-only ones ends in
``-pip``. Libraries without any key (zstandard, mcap, ray) are installed by pip from constraints.txt and named in a
comment of the package.xml that needs them.
"""

from __future__ import annotations

import ast
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
PACKAGES = ("rh5_msgs_py", "rh5_hyrodyn_mapper", "rh5_planner", "rh5_joint_stabilizer", "rh5_bringup")
ROSDEP_KEYS = {
    "numpy": "python3-numpy",
    "yaml": "python3-yaml",
    "scipy": "python3-scipy",
    "matplotlib": "python3-matplotlib",
    "can": "python3-can",
    "pybullet": "python3-pybullet-pip",
    "rosbags": "python3-rosbags-pip",
    "pinocchio": "pinocchio",
    "crocoddyl": "crocoddyl",
}
"""Python module -> rosdep key, for modules that are not ROS packages of the same name."""
NO_ROSDEP_KEY = {"zstandard", "mcap", "ray"}
ROS_PACKAGES = {
    "rclpy",
    "launch",
    "launch_ros",
    "rcl_interfaces",
    "builtin_interfaces",
    "rosgraph_msgs",
    "lifecycle_msgs",
    "action_msgs",
    "std_msgs",
    "std_srvs",
    "sensor_msgs",
    "geometry_msgs",
    "trajectory_msgs",
    "diagnostic_msgs",
    "tf2_msgs",
    "control_msgs",
}


def _imports(package: str) -> set[str]:
    found: set[str] = set()
    for path in (REPO / package / package).rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Import):
                found |= {alias.name.split(".")[0] for alias in node.names}
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                found.add(node.module.split(".")[0])
    return found - set(sys.stdlib_module_names) - {"__future__"}


def _declared(package: str) -> set[str]:
    root = ET.parse(REPO / package / "package.xml").getroot()
    return {e.text or "" for tag in ("depend", "exec_depend", "build_depend") for e in root.iter(tag)}


@pytest.mark.parametrize("package", PACKAGES)
def test_every_import_is_declared_with_a_rosdep_key(package: str) -> None:
    declared = _declared(package)
    missing = []
    for module in sorted(_imports(package)):
        if module in PACKAGES or module in NO_ROSDEP_KEY:
            continue
        key = ROSDEP_KEYS.get(module, module)
        assert key in ROSDEP_KEYS.values() or key in ROS_PACKAGES, f"{package} imports {module}: no known rosdep key"
        if key not in declared:
            missing.append(key)
    assert missing == [], f"{package}/package.xml does not declare {missing}"


@pytest.mark.parametrize("package", PACKAGES)
def test_every_declared_key_is_one_rosdep_resolves(package: str) -> None:
    known = set(ROSDEP_KEYS.values()) | ROS_PACKAGES | set(PACKAGES) | {"python3-dev", "ament_python"}
    root = ET.parse(REPO / package / "package.xml").getroot()
    keys = {e.text for tag in ("depend", "exec_depend", "build_depend", "buildtool_depend") for e in root.iter(tag)}
    assert keys - known == set()


def test_packages_without_a_key_are_named_where_they_are_used() -> None:
    text = (REPO / "rh5_bringup" / "package.xml").read_text()
    assert "zstandard" in text
    assert "mcap" in text
    assert "ray" in (REPO / "rh5_planner" / "package.xml").read_text()
