"""The generated ROS 2 launch file says what the bringup description says (no launch wheel here: the
launch API is replaced by recorders, and the file is executed for real)."""

from __future__ import annotations

import runpy
import sys
import types
from pathlib import Path
from typing import Any

import pytest
import yaml

from rh5_bringup.orchestration import launch_files
from rh5_bringup.orchestration.launcher import load_bringup


class _Recorded:
    """Stands in for a launch action or substitution: keeps its arguments."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        self.args, self.kwargs = args, kwargs


class _LaunchConfiguration(_Recorded):
    """Stands in for launch.substitutions.LaunchConfiguration: performs to the context's value of its name."""

    def perform(self, context: dict[str, str]) -> str:
        return context[self.args[0]]


@pytest.fixture
def fake_launch_api(monkeypatch: pytest.MonkeyPatch) -> None:
    """Install minimal `launch` and `launch_ros` modules whose classes record their arguments."""
    kinds = {
        "launch": {"LaunchDescription": _Recorded},
        "launch.actions": {
            "DeclareLaunchArgument": type("DeclareLaunchArgument", (_Recorded,), {}),
            "OpaqueFunction": type("OpaqueFunction", (_Recorded,), {}),
        },
        "launch.substitutions": {"LaunchConfiguration": _LaunchConfiguration},
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


def _launch(path: Path, **values: str) -> tuple[list[Any], list[dict[str, Any]]]:
    """Execute the launch file at ``path``: its declared arguments, and the Node kwargs for ``values``."""
    actions = runpy.run_path(str(path))["generate_launch_description"]().args[0]
    declared = [a for a in actions if type(a).__name__ == "DeclareLaunchArgument"]
    (opaque,) = [a for a in actions if type(a).__name__ == "OpaqueFunction"]
    context = {d.args[0]: values.get(d.args[0], d.kwargs["default_value"]) for d in declared}
    nodes = [a.kwargs for a in opaque.kwargs["function"](context) if type(a).__name__ == "Node"]
    return declared, nodes


@pytest.mark.parametrize("sim", ["kinematic", "physics"])
def test_launch_file_starts_every_node_with_its_parameters(fake_launch_api: None, sim: str) -> None:
    """By default the control process hosts driver, mapper and stabilizer (one process, one parameter file with
    each node's parameters under its own name); separate:=true starts them on their own."""
    bringup = load_bringup()
    resolved = bringup.resolved(sim=sim)  # what `rh5 up --sim` starts
    specs = {n.name: n for n in resolved.nodes}
    declared, nodes = _launch(launch_files.LAUNCH_DIR / launch_files.LAUNCH_FILE, sim=sim)
    assert [(d.args[0], d.kwargs["default_value"]) for d in declared] == [
        *((a.name, a.default) for a in bringup.arguments),
        ("separate", "false"),
    ]
    assert len(nodes) == len(resolved.processes())
    for launched, (host, hosted) in zip(nodes, resolved.processes(), strict=True):
        assert (launched["package"], launched["executable"]) == (host.package, host.executable)
        assert launched["namespace"] == resolved.namespace
        if hosted:
            assert "name" not in launched  # a name would rename every node of the process
            (path,) = launched["parameters"]
            document = yaml.safe_load(Path(path).read_text(encoding="utf-8"))
            Path(path).unlink()
            assert document == {f"/{n.name}": {"ros__parameters": n.parameters} for n in (host, *hosted)}
        else:
            assert launched["name"] == host.name
            assert launched["remappings"] == [list(pair) for pair in host.remappings]
            assert launched["parameters"] == [host.parameters]
    assert specs["stabilizer"].parameters.get("use_sim_time", False) is (sim == "physics")  # plays on /clock
    _, separate = _launch(launch_files.LAUNCH_DIR / launch_files.LAUNCH_FILE, sim=sim, separate="true")
    assert [n["name"] for n in separate] == [n.name for n in resolved.nodes if not n.hosts]
    stabilizer = next(n for n in separate if n["name"] == "stabilizer")["parameters"][0]
    assert stabilizer == specs["stabilizer"].parameters


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
    _, (node,) = _launch(path, rate="1000")
    assert node["namespace"] == "robot1"
    assert node["remappings"] == [["joint_states", "/robot1/measured"]]
    assert node["parameters"] == [{"transport": "udp", "rate_hz": "1000"}]
    resolved = bringup.resolved(rate="1000")
    assert resolved.nodes[0].parameters == {"transport": "udp", "rate_hz": "1000"}
    with pytest.raises(ValueError, match="not one of"):
        bringup.resolved(rate="7")
    with pytest.raises(KeyError, match="unknown launch arguments"):
        bringup.resolved(sim="physics")


def test_argument_values_imply_parameters_of_other_nodes(tmp_path: Path) -> None:
    def bringup_with(implies: str) -> Path:
        path = tmp_path / "bringup.yaml"
        path.write_text(
            "arguments:\n  sim: {default: a, choices: [a, b], sets: one.mode, implies: " + implies + "}\n"
            "nodes:\n  - {name: one, package: p, executable: e}\n  - {name: two, package: p, executable: e}\n",
            encoding="utf-8",
        )
        return path

    bringup = load_bringup(bringup_with("{b: {two: {use_sim_time: true}}}"))
    assert [n.parameters for n in bringup.resolved(sim="a").nodes] == [{"mode": "a"}, {}]
    assert [n.parameters for n in bringup.resolved(sim="b").nodes] == [{"mode": "b"}, {"use_sim_time": True}]
    with pytest.raises(ValueError, match="no such node"):
        load_bringup(bringup_with("{b: {three: {x: 1}}}"))
    with pytest.raises(ValueError, match="not one of its choices"):
        load_bringup(bringup_with("{c: {two: {x: 1}}}"))
