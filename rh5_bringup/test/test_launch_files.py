"""The generated ROS 2 launch file says what the bringup description says (no launch wheel here: the
launch API is replaced by recorders, and the file is executed for real)."""

from __future__ import annotations

import runpy
import sys
import types
from pathlib import Path
from typing import Any

import pytest

from rh5_bringup import launch_files
from rh5_bringup.launcher import load_bringup


class _Recorded:
    """Stands in for a launch action or substitution: keeps its arguments."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        self.args, self.kwargs = args, kwargs


@pytest.fixture
def fake_launch_api(monkeypatch: pytest.MonkeyPatch) -> None:
    """Install minimal `launch` and `launch_ros` modules whose classes record their arguments."""
    kinds = {
        "launch": {"LaunchDescription": _Recorded},
        "launch.actions": {"DeclareLaunchArgument": type("DeclareLaunchArgument", (_Recorded,), {})},
        "launch.substitutions": {"LaunchConfiguration": type("LaunchConfiguration", (_Recorded,), {})},
        "launch_ros": {},
        "launch_ros.actions": {"Node": type("Node", (_Recorded,), {})},
    }
    for name, members in kinds.items():
        module = types.ModuleType(name)
        for attribute, value in members.items():
            setattr(module, attribute, value)
        monkeypatch.setitem(sys.modules, name, module)


def test_committed_launch_file_is_what_the_description_renders() -> None:
    assert launch_files.main(["--check"]) == 0


def test_check_fails_on_a_stale_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / launch_files.LAUNCH_FILE).write_text("# edited by hand\n", encoding="utf-8")
    assert launch_files.main(["--check", "--dir", str(tmp_path)]) == 1
    assert "is stale" in capsys.readouterr().err


def test_launch_file_starts_every_node_with_its_parameters(fake_launch_api: None) -> None:
    namespace = runpy.run_path(str(launch_files.LAUNCH_DIR / launch_files.LAUNCH_FILE))
    description = namespace["generate_launch_description"]()
    actions = description.args[0]
    declared = [a for a in actions if type(a).__name__ == "DeclareLaunchArgument"]
    nodes = [a.kwargs for a in actions if type(a).__name__ == "Node"]
    bringup = load_bringup()
    assert [(d.args[0], d.kwargs["default_value"]) for d in declared] == [
        (a.name, a.default) for a in bringup.arguments
    ]
    assert [n["name"] for n in nodes] == [n.name for n in bringup.nodes]
    for launched, spec in zip(nodes, bringup.nodes, strict=True):
        assert (launched["package"], launched["executable"]) == (spec.package, spec.executable)
        assert launched["namespace"] == bringup.namespace
        assert launched["remappings"] == [list(pair) for pair in spec.remappings]
        parameters = launched["parameters"][0]
        for key, value in spec.parameters.items():
            assert parameters[key] == value
    sim = next(n for n in nodes if n["name"] == "sim_hardware")["parameters"][0]["mode"]
    assert type(sim).__name__ == "LaunchConfiguration"
    assert sim.args == ("sim",)


def test_rendering_follows_remappings_and_arguments(fake_launch_api: None, tmp_path: Path) -> None:
    description = tmp_path / "bringup.yaml"
    description.write_text(
        "namespace: robot1\n"
        "arguments:\n  rate: {default: '500', choices: ['500', '1000'], sets: driver.rate_hz}\n"
        "nodes:\n  - {name: driver, package: rh5_bringup, executable: driver_node,\n"
        "     parameters: {transport: udp}, remappings: {joint_states: /robot1/measured}}\n",
        encoding="utf-8",
    )
    bringup = load_bringup(description)
    path = tmp_path / "x.launch.py"
    path.write_text(launch_files.render_launch_file(bringup, path.name), encoding="utf-8")
    actions = runpy.run_path(str(path))["generate_launch_description"]().args[0]
    node = next(a for a in actions if type(a).__name__ == "Node").kwargs
    assert node["namespace"] == "robot1"
    assert node["remappings"] == [["joint_states", "/robot1/measured"]]
    assert node["parameters"][0]["rate_hz"].args == ("rate",)
    resolved = bringup.resolved(rate="1000")
    assert resolved.nodes[0].parameters == {"transport": "udp", "rate_hz": "1000"}
    with pytest.raises(ValueError, match="not one of"):
        bringup.resolved(rate="7")
    with pytest.raises(KeyError, match="unknown launch arguments"):
        bringup.resolved(sim="physics")
