"""The ROS-native path works here: colcon build installs every node into lib/<package>/, colcon test gates.

This is what a lab member does on a full ROS 2 Jazzy install (README, "ROS-native path"),
done with the venv's colcon so that it is checked on every CI run.
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import textwrap
from pathlib import Path
from typing import Any

import pytest

from rh5_bringup.orchestration.launcher import wait_for_nodes

REPO_ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("rh5_msgs_py", "rh5_hyrodyn_mapper", "rh5_planner", "rh5_joint_stabilizer", "rh5_bringup")
NODE_EXECUTABLES = {
    "rh5_hyrodyn_mapper": ("mapper_node", "rh5_urdf"),
    "rh5_planner": ("planner_node", "rh5-plan"),
    "rh5_joint_stabilizer": ("stabilizer_node",),
    "rh5_bringup": ("driver_node", "sim_hardware_node", "recorder_node", "rh5"),
}
COLCON = Path(sys.prefix) / "bin" / "colcon"

pytestmark = pytest.mark.slow


def _colcon(workspace: Path, *args: str, paths: list[Path]) -> subprocess.CompletedProcess[str]:
    command = [
        str(COLCON),
        "--log-base",
        str(workspace / "log"),
        *args,
        "--base-paths",
        *map(str, paths),
        "--build-base",
        str(workspace / "build"),
        "--install-base",
        str(workspace / "install"),
    ]
    env = {**os.environ, "PATH": f"{Path(sys.prefix) / 'bin'}{os.pathsep}{os.environ['PATH']}"}
    return subprocess.run(command, capture_output=True, text=True, env=env, timeout=900, check=False, cwd=workspace)


@pytest.fixture(scope="module")
def workspace(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A colcon build of the five packages, as on a full ROS 2 install."""
    ws = tmp_path_factory.mktemp("colcon_ws")
    result = _colcon(ws, "build", paths=[REPO_ROOT / p for p in PACKAGES])
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-3000:]
    return ws


def test_build_installs_package_markers_and_node_executables(workspace: Path) -> None:
    install = workspace / "install"
    for package in PACKAGES:
        assert (install / package / "share" / "ament_index" / "resource_index" / "packages" / package).is_file()
        assert (install / package / "share" / package / "package.xml").is_file()
    for package, executables in NODE_EXECUTABLES.items():
        for exe in executables:
            path = install / package / "lib" / package / exe
            assert path.is_file(), f"{path} missing: ros2 run {package} {exe} would fail"
            assert os.access(path, os.X_OK)


def test_installed_node_runs_from_the_sourced_install_space(
    workspace: Path, ros_graph: Any, ros_test_environment: dict[str, str]
) -> None:
    """``source install/setup.bash`` then the lib/<package>/<exe> that ``ros2 run`` would start."""
    exe = workspace / "install" / "rh5_bringup" / "lib" / "rh5_bringup" / "sim_hardware_node"
    script = f"source {workspace / 'install' / 'setup.bash'} && exec {exe} --ros-args -r __node:=colcon_sim"
    process = subprocess.Popen(["bash", "-c", script], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        missing = wait_for_nodes(ros_graph, {"colcon_sim"})
    finally:
        process.send_signal(signal.SIGINT)
        out, err = process.communicate(timeout=20)
    assert missing == set(), err
    assert process.returncode == 0, err
    assert "RH5_SUMMARY" in out


def test_colcon_test_passes_on_the_workspace(workspace: Path) -> None:
    result = _colcon(workspace, "test", "--return-code-on-test-failure", paths=[REPO_ROOT / p for p in PACKAGES])
    logs = "".join(path.read_text()[-3000:] for path in (workspace / "log" / "latest_test").glob("*/stdout_stderr.log"))
    assert result.returncode == 0, result.stdout[-2000:] + logs


def test_colcon_test_fails_when_a_package_test_fails(tmp_path: Path) -> None:
    """The gate is real: a package with a failing test makes colcon test return non-zero."""
    package = tmp_path / "src" / "failing_probe"
    (package / "resource").mkdir(parents=True)
    (package / "resource" / "failing_probe").write_text("")
    (package / "test").mkdir()
    (package / "failing_probe").mkdir()
    (package / "failing_probe" / "__init__.py").write_text("")
    (package / "test" / "test_fails.py").write_text("def test_fails():\n    assert 1 == 2\n")
    shutil.copy(REPO_ROOT / "rh5_msgs_py" / "setup.cfg", package / "setup.cfg")
    (package / "setup.cfg").write_text((package / "setup.cfg").read_text().replace("rh5_msgs_py", "failing_probe"))
    (package / "package.xml").write_text(
        (REPO_ROOT / "rh5_msgs_py" / "package.xml").read_text().replace("rh5_msgs_py", "failing_probe")
    )
    (package / "setup.py").write_text(
        textwrap.dedent(
            """
            from setuptools import setup
            setup(name="failing_probe", version="0.0.0", packages=["failing_probe"],
                  data_files=[("share/ament_index/resource_index/packages", ["resource/failing_probe"]),
                              ("share/failing_probe", ["package.xml"])],
                  tests_require=["pytest"])
            """
        )
    )
    assert _colcon(tmp_path, "build", paths=[package]).returncode == 0
    result = _colcon(tmp_path, "test", "--return-code-on-test-failure", paths=[package])
    assert result.returncode != 0
