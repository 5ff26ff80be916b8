"""The bringup description and the command lines the launcher builds from it (no processes)."""

from __future__ import annotations

import sys
from dataclasses import replace
from pathlib import Path

import pytest

from rh5_bringup.orchestration.cli import build_parser, main
from rh5_bringup.orchestration.launcher import (
    NodeSpec,
    composed_command,
    composed_parameters,
    load_bringup,
    node_command,
)
from rh5_msgs_py.parameters import load_spec

PACKAGE_OF_SPEC = {
    "planner": "rh5_planner",
    "mapper": "rh5_hyrodyn_mapper",
    "stabilizer": "rh5_joint_stabilizer",
    "driver": "rh5_bringup",
    "control": "rh5_bringup",
    "sim_hardware": "rh5_bringup",
    "recorder": "rh5_bringup",
    "state_publisher": "rh5_hyrodyn_mapper",
}


def test_packaged_bringup_starts_the_control_process_by_default() -> None:
    bringup = load_bringup()
    assert [n.name for n in bringup.nodes] == [
        "recorder", "sim_hardware", "control", "driver", "mapper", "stabilizer", "state_publisher", "planner"
    ]  # fmt: skip
    processes = [(host.name, [n.name for n in hosted]) for host, hosted in bringup.processes()]
    assert processes == [
        ("recorder", []), ("sim_hardware", []), ("control", ["driver", "mapper", "stabilizer"]),
        ("state_publisher", []), ("planner", [])
    ]  # fmt: skip
    separate = replace(bringup, composed=False)
    assert [host.name for host, hosted in separate.processes() if not hosted] == [
        "recorder", "sim_hardware", "driver", "mapper", "stabilizer", "state_publisher", "planner"
    ]  # fmt: skip
    assert bringup.node_names() == {n.name for n in bringup.nodes} | {"control_streams"}  # the stream publisher
    assert separate.node_names() == bringup.node_names() - {"control", "control_streams"}


def test_a_composed_process_gets_each_nodes_parameters_under_its_name(tmp_path: Path) -> None:
    bringup = load_bringup().with_parameters("driver", command_timeout_s=0.5).with_parameters("control", rate_hz=500.0)
    ((host, hosted),) = [(h, n) for h, n in bringup.processes() if n]
    document = composed_parameters((host, *hosted), "robot1")
    assert document["/robot1/driver"]["ros__parameters"]["command_timeout_s"] == 0.5
    assert document["/robot1/control"]["ros__parameters"] == {"rate_hz": 500.0, "cpu_affinity": [-1]}
    command = composed_command(host, hosted, tmp_path / "p.yaml", "robot1")
    assert command[0] == str(Path(sys.prefix) / "bin" / "control_node")
    assert "__node:=control" not in " ".join(command)  # the process's nodes keep their own names
    assert command[-2:] == ["--params-file", str(tmp_path / "p.yaml")]
    description = tmp_path / "bringup.yaml"
    description.write_text("nodes:\n  - {name: a, package: p, executable: e, hosts: [b]}\n", encoding="utf-8")
    with pytest.raises(ValueError, match="not a node of the bringup"):
        load_bringup(description)


def test_bringup_parameters_are_declared_and_valid_in_the_node_specs() -> None:
    for node in load_bringup().nodes:
        specs = {s.name: s for s in load_spec(PACKAGE_OF_SPEC[node.name], f"params/{node.name}.yaml")}
        for key, value in node.parameters.items():
            assert key in specs, f"{node.name}: {key} is not a declared parameter"
            assert specs[key].check(value) == ""


def test_node_command_renames_namespaces_and_sets_parameters() -> None:
    spec = NodeSpec("driver", "rh5_bringup", "driver_node", {"rate_hz": 500.0, "silent_boards": ["a", "b"]})
    command = node_command(spec, "robot1")
    assert command[0] == str(Path(sys.prefix) / "bin" / "driver_node")
    assert command[1:5] == ["--ros-args", "-r", "__node:=driver", "-r"]
    assert "__ns:=/robot1" in command
    assert "rate_hz:=500.0" in command
    assert 'silent_boards:=["a", "b"]' in command


def test_with_parameters_overrides_one_node_only() -> None:
    bringup = load_bringup().with_parameters("sim_hardware", mode="physics")
    assert {n.name: n.parameters.get("mode") for n in bringup.nodes}["sim_hardware"] == "physics"
    with pytest.raises(KeyError, match="no node 'nope'"):
        bringup.with_parameters("nope", x=1)


def test_cli_rejects_a_non_positive_duration(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["up", "--duration", "0"]) == 2
    assert "--duration must be positive" in capsys.readouterr().err
    assert build_parser().parse_args(["up", "--sim", "physics"]).sim == "physics"


def test_node_command_carries_remappings_before_parameters() -> None:
    spec = NodeSpec("mapper", "rh5_hyrodyn_mapper", "mapper_node", {"a": 1}, (("joint_states", "/other/states"),))
    command = node_command(spec)
    assert command[command.index("joint_states:=/other/states") - 1] == "-r"
    assert command.index("joint_states:=/other/states") < command.index("a:=1")


def test_cli_sim_choice_sets_the_sim_hardware_mode() -> None:
    modes = {n.name: n.parameters.get("mode") for n in load_bringup().resolved(sim="physics").nodes}
    assert modes["sim_hardware"] == "physics"


def test_experiment_refuses_an_output_root_that_is_a_file(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    out = tmp_path / "out"
    out.write_text("")
    assert main(["experiment", "fast_squats", "--out", str(out)]) == 2
    assert f"--out {out}: not a folder" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("argv", "reason"),
    [
        (["experiment", "moonwalk"], "unknown motion 'moonwalk'"),
        (["experiment", "fast_squats", "--set", "n_squats"], "expected key=value"),
        (["experiment", "fast_squats", "--set", "depth=3"], "unknown parameters ['depth']"),
        (["experiment", "fast_squats", "--param", "nobody.x=1"], "no nodes ['nobody']"),
        (["experiment", "fast_squats", "--param", "driver=1"], "expected NODE.KEY=VALUE"),
    ],
)
def test_experiment_rejects_bad_input_before_starting_anything(
    argv: list[str], reason: str, capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    assert main([*argv, "--out", str(tmp_path)]) == 2
    assert reason in capsys.readouterr().err
    assert not any(tmp_path.iterdir())  # nothing planned, nothing started


def test_only_the_recorder_may_die_without_stopping_the_suite() -> None:
    bringup = load_bringup()
    assert {n.name for n in bringup.nodes if not n.essential} == {"recorder"}
    assert "rh5 bag recover" in next(n for n in bringup.nodes if n.name == "recorder").lost_hint


def test_without_leaves_one_node_out_but_never_a_hosted_one() -> None:
    bringup = load_bringup()
    unrecorded = bringup.without("recorder")
    assert "recorder" not in unrecorded.node_names()
    assert unrecorded.node_names() == bringup.node_names() - {"recorder"}
    assert [spec.name for spec, _ in unrecorded.processes()] == [
        "sim_hardware",
        "control",
        "state_publisher",
        "planner",
    ]
    with pytest.raises(ValueError, match="hosted"):
        bringup.without("driver")
    with pytest.raises(KeyError, match="no node"):
        bringup.without("nope")
    assert build_parser().parse_args(["up", "--no-record"]).no_record


def test_bag_subcommands_refuse_a_folder_that_is_not_a_bag(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    for command in ("info", "recover"):
        assert main(["bag", command, str(tmp_path)]) == 2
        assert f"rh5 bag {command}: {tmp_path}: " in capsys.readouterr().err
