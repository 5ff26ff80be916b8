"""rh5_bringup's layers import only downwards, and a robot PC's install holds what its two processes import (#16).

The layers, lowest first (docs/architecture.md): ``hardware`` (codec, transports, driver) and ``recording`` at the
bottom; ``control`` (the composed read -> update -> write process) and ``sim`` on ``hardware``; ``analysis``;
``orchestration`` on top. What a robot PC runs, the driver node and the control process, lives in ``hardware`` and
``control``: they must not need PyBullet, matplotlib, Crocoddyl, rosbags or the planner, and package.xml declares
those under the condition ``$RH5_DEPLOY != robot``.
"""

from __future__ import annotations

import ast
import os
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
from catkin_pkg.condition import evaluate_condition
from test_import_cycles import imports, modules
from test_package_deps import ROSDEP_KEYS

REPO = Path(__file__).resolve().parents[1]
PACKAGE = "rh5_bringup"

ALLOWED_LAYERS: dict[str, set[str]] = {
    "hardware": set(),
    "recording": set(),
    "control": {"hardware"},
    "sim": {"hardware"},
    "analysis": set(),
    "orchestration": {"hardware", "recording", "control", "sim", "analysis"},
}
"""Layer -> the other layers of rh5_bringup it may import."""
ALLOWED_PACKAGES: dict[str, set[str]] = {
    "hardware": {"rh5_msgs_py", "rh5_hyrodyn_mapper"},
    "recording": {"rh5_msgs_py"},
    "control": {"rh5_msgs_py", "rh5_hyrodyn_mapper", "rh5_joint_stabilizer"},
    "sim": {"rh5_msgs_py", "rh5_hyrodyn_mapper", "rh5_planner"},
    "analysis": {"rh5_msgs_py", "rh5_hyrodyn_mapper"},
    "orchestration": {"rh5_msgs_py", "rh5_hyrodyn_mapper", "rh5_planner", "rh5_joint_stabilizer"},
}
"""Layer -> the suite's other packages it may import."""
SUITE_PACKAGES = {"rh5_msgs_py", "rh5_hyrodyn_mapper", "rh5_planner", "rh5_joint_stabilizer"}
ROBOT_LAYERS = ("hardware", "control")
DESK_ONLY = ("pybullet", "matplotlib", "crocoddyl", "rosbags", "mcap", "zstandard", "ray", "launch", "rh5_planner")
"""Top-level modules a robot PC's processes must never import, directly or through another module."""
ROBOT_PROCESSES = ("rh5_bringup.hardware.driver_node", "rh5_bringup.control.node")


def layer_of(module: str) -> str:
    """``rh5_bringup.hardware.ndlcom.codec`` -> ``hardware``; the package's own ``__init__`` is ``root``."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else "root"


def _top_level_imports(path: Path) -> set[str]:
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            found |= {alias.name.split(".")[0] for alias in node.names}
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            found.add(node.module.split(".")[0])
    return found - set(sys.stdlib_module_names) - {"__future__", PACKAGE}


def test_every_module_is_in_a_known_layer() -> None:
    layers = {layer_of(m) for m in modules(PACKAGE)}
    assert layers - {"root"} == set(ALLOWED_LAYERS), "a new top-level module or layer: place it"


def test_layers_import_only_the_layers_below_them() -> None:
    found = modules(PACKAGE)
    wrong = []
    for module, path in found.items():
        own = layer_of(module)
        if own == "root":
            continue
        for target in imports(module, path, set(found)):
            other = layer_of(target)
            if other != own and other not in ALLOWED_LAYERS[own]:
                wrong.append(f"{module} imports {target} ({own} may import {sorted(ALLOWED_LAYERS[own]) or 'none'})")
    assert wrong == []


def test_layers_import_only_their_packages_and_robot_layers_no_desk_library() -> None:
    wrong = []
    for module, path in modules(PACKAGE).items():
        own = layer_of(module)
        if own == "root":
            continue
        used = _top_level_imports(path)
        for name in sorted((used & SUITE_PACKAGES) - ALLOWED_PACKAGES[own]):
            wrong.append(f"{module} imports {name}")
        if own in ROBOT_LAYERS:
            wrong += [f"{module} (robot PC) imports {name}" for name in sorted(used & set(DESK_ONLY))]
    assert wrong == []


def _declared(context: dict[str, str]) -> set[str]:
    root = ET.parse(REPO / PACKAGE / "package.xml").getroot()
    return {
        e.text or ""
        for tag in ("depend", "exec_depend")
        for e in root.iter(tag)
        if evaluate_condition(e.get("condition"), context)
    }


def test_robot_profile_declares_what_the_robot_layers_import_and_leaves_the_desk_out() -> None:
    robot = _declared({"RH5_DEPLOY": "robot"})
    desk = _declared({})
    used: set[str] = set()
    for module, path in modules(PACKAGE).items():
        if layer_of(module) in ROBOT_LAYERS:
            used |= _top_level_imports(path)
    keys = {ROSDEP_KEYS.get(name, name) for name in used}
    assert keys - robot == set(), "the robot profile misses what the driver or control process imports"
    left_out = desk - robot
    assert {"python3-pybullet-pip", "python3-matplotlib", "crocoddyl", "python3-rosbags-pip", "rh5_planner"} <= left_out
    assert robot < desk


_BLOCKER = """
import importlib.abc, sys
BLOCKED = set(sys.argv[1].split(","))
class Blocker(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        if name.split(".")[0] in BLOCKED:
            raise ImportError(f"{name} is not installed on a robot PC")
        return None
sys.meta_path.insert(0, Blocker())
import importlib
for module in sys.argv[2:]:
    importlib.import_module(module)
print(sorted(m for m in sys.modules if m.split(".")[0] in BLOCKED))
"""


@pytest.mark.parametrize("process", ROBOT_PROCESSES)
def test_robot_process_imports_with_the_desk_libraries_missing(process: str) -> None:
    """Import the node's module (and so everything it pulls in) in a fresh interpreter that cannot import them."""
    env = {**os.environ, "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}
    result = subprocess.run(
        [sys.executable, "-c", _BLOCKER, ",".join(DESK_ONLY), process],
        capture_output=True,
        text=True,
        timeout=120,
        env=env,
        check=False,
    )
    assert result.returncode == 0, result.stderr[-2000:]
    assert result.stdout.strip() == "[]"


def test_the_blocker_does_block() -> None:
    """The check above can fail: a module that needs a desk library fails to import under the same blocker."""
    result = subprocess.run(
        [sys.executable, "-c", _BLOCKER, ",".join(DESK_ONLY), "rh5_bringup.analysis.figures"],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert result.returncode != 0
    assert "is not installed on a robot PC" in result.stderr
