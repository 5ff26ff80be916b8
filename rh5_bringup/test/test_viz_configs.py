"""The shipped RViz config and Foxglove layout name topics, frames and joints the suite really has."""

from __future__ import annotations

import json
import re
from pathlib import Path

import yaml

from rh5_msgs_py import interfaces
from rh5_msgs_py.names import JOINT_NAMES

VIZ = Path(__file__).resolve().parent.parent / "viz"
TOPICS = {"/" + t.name.lstrip("/") for t in interfaces.ALL_TOPICS}


def test_rviz_config_shows_the_robot_tf_and_foot_wrenches() -> None:
    config = yaml.safe_load((VIZ / "rh5.rviz").read_text())
    displays = config["Visualization Manager"]["Displays"]
    classes = {d["Class"] for d in displays}
    assert {"rviz_default_plugins/RobotModel", "rviz_default_plugins/TF", "rviz_default_plugins/Wrench"} <= classes
    topics = {d["Topic"]["Value"] for d in displays if "Topic" in d}
    topics.add(next(d for d in displays if d["Class"].endswith("RobotModel"))["Description Topic"]["Value"])
    assert topics <= TOPICS
    assert {"/sim/wrench/left_foot", "/sim/wrench/right_foot", "/robot_description"} <= topics
    assert config["Visualization Manager"]["Global Options"]["Fixed Frame"] == "odom"


def test_foxglove_layout_plots_planned_vs_measured_joints_by_their_index() -> None:
    layout = json.loads((VIZ / "rh5_foxglove_layout.json").read_text())
    panels = layout["configById"]
    assert any(p.get("layers", {}).get("rh5", {}).get("topic") == "/robot_description" for p in panels.values())
    paths = [p for panel in panels.values() for p in panel.get("paths", [])]
    joint_paths = [p for p in paths if p["value"].startswith(("/joint_states", "/joint_commands"))]
    assert joint_paths
    for path in joint_paths:
        index = int(re.search(r"\[(\d+)\]", path["value"]).group(1))
        assert path["label"].split()[0] == JOINT_NAMES[index], path
    assert {p["value"].split(".")[0] for p in paths} <= TOPICS
    layout_ids = set(re.findall(r'"([A-Za-z0-9]+![a-z0-9]+)"', json.dumps(layout["layout"])))
    assert layout_ids == set(panels)
