"""Parameters mean what they say at launch: the shipped params files start every node, and a name a node does
not have is refused (params file, -p, `rh5 experiment --param`) with the valid names, never silently dropped."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest

from rh5_bringup.orchestration.launcher import check_parameter_names, load_bringup, wait_for_nodes
from rh5_bringup.orchestration.params_files import CONFIG_DIR, main, render_params_file
from rh5_msgs_py.node_runtime import STACKS_SIGNAL

pytestmark = [pytest.mark.ros]

BIN = Path(sys.prefix) / "bin"
NODES = [node.name for node in load_bringup().nodes]


def test_committed_params_files_are_what_the_specs_render(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["--check"]) == 0, capsys.readouterr().err


def test_the_check_fails_on_a_stale_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["--dir", str(tmp_path)]) == 0
    path = tmp_path / "mapper.params.yaml"
    path.write_text(path.read_text().replace("fk_max_iterations: 20", "fk_max_iterations: 21"))
    assert main(["--check", "--dir", str(tmp_path)]) == 1
    assert "mapper.params.yaml" in capsys.readouterr().err


def _wait_until_spinning(graph: Any, name: str, timeout_s: float = 30.0) -> None:
    """Wait until node ``name`` answers a parameter request: its process spins only once every node is built (a
    node shows in the graph while it still creates its services, and a stop then can abort the process)."""
    import rclpy
    from rcl_interfaces.srv import ListParameters

    client = graph.create_client(ListParameters, f"/{name}/list_parameters")
    try:
        assert client.wait_for_service(timeout_sec=timeout_s), f"{name}: no list_parameters service"
        future = client.call_async(ListParameters.Request())
        rclpy.spin_until_future_complete(graph, future, timeout_sec=timeout_s)
        assert future.done(), f"{name} did not answer within {timeout_s} s"
    finally:
        graph.destroy_client(client)


@pytest.mark.parametrize("name", NODES)
def test_every_node_starts_with_its_shipped_params_file(name: str, ros_graph: Any, tmp_path: Path) -> None:
    node = next(n for n in load_bringup().nodes if n.name == name)
    enclave = f"/params_test_{os.getpid()}_{name}"
    params = CONFIG_DIR / f"{name}.params.yaml"
    command = [str(BIN / node.executable), "--ros-args", "--enclave", enclave, "--params-file", str(params)]
    process = subprocess.Popen(command, cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    missing = {name}
    try:
        missing = wait_for_nodes(ros_graph, {name, *node.hosts}, timeout_s=60.0, enclave=enclave)
        if not missing:
            _wait_until_spinning(ros_graph, name)
    finally:
        process.send_signal(signal.SIGINT)  # only once it is built and spinning, unless its nodes never came
        try:
            _, err = process.communicate(timeout=60)
        except subprocess.TimeoutExpired:  # stuck (CI, once): its threads' stacks, then kill it
            process.send_signal(STACKS_SIGNAL)
            time.sleep(2.0)
            process.kill()
            _, err = process.communicate()
            pytest.fail(f"{name} did not stop within 60 s of SIGINT (missing {missing}); stderr:\n{err[-6000:]}")
    assert missing == set(), err[-2000:]
    assert process.returncode == 0, err[-2000:]


def test_a_misspelt_name_in_a_params_file_stops_the_node_with_the_valid_names(tmp_path: Path) -> None:
    typo = tmp_path / "mapper.params.yaml"
    typo.write_text(render_params_file(load_bringup(), "mapper").replace("clamp_to_limits:", "clamp_to_limit:"))
    result = subprocess.run(
        [str(BIN / "mapper_node"), "--ros-args", "--params-file", str(typo)],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
        env={**os.environ},
    )
    assert result.returncode == 2, result.stderr
    assert "unknown parameter ['clamp_to_limit'] for node 'mapper'" in result.stderr
    assert "'clamp_to_limits'" in result.stderr  # the valid names are listed


def test_experiment_refuses_an_unknown_param_before_starting_anything(tmp_path: Path) -> None:
    result = subprocess.run(
        [str(BIN / "rh5"), "experiment", "fast_squats", "--out", str(tmp_path), "--param", "stabilizer.no_such=1"],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert result.returncode == 2, result.stdout + result.stderr
    assert "node 'stabilizer' has no parameter ['no_such']; valid: [" in result.stderr
    assert not (tmp_path / "experiments").exists()  # nothing planned, nothing started


@pytest.mark.parametrize("sim", ["kinematic", "physics"])
def test_the_bringup_sets_only_parameters_its_nodes_have(sim: str) -> None:
    bringup = load_bringup().resolved(sim=sim)
    check_parameter_names(bringup, {node.name: node.parameters for node in bringup.nodes})
    with pytest.raises(ValueError, match="node 'driver' has no parameter"):
        check_parameter_names(bringup, {"driver": {"command_timeout": 0.1}})
