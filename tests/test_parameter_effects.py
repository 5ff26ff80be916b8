"""Every writable parameter of every node, set at run time, reaches what the node's loop or services use.

The nodes are built in this process (their loops not started where they are composed) and each writable
parameter of each spec is set through rclpy's own set_parameters, then the object that acts on it is read.
The table must cover every writable parameter of every spec: a new writable parameter without an observed
effect fails here. (tests/test_live_parameters.py shows some of the effects end to end, through processes.)
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
import yaml

from rh5_bringup.orchestration.launcher import load_bringup
from rh5_msgs_py.parameters import load_spec

pytestmark = pytest.mark.ros

Effect = tuple[Any, Callable[[Any], bool]]
"""A valid non-default value, and what must hold of the node once it is set."""


def _gains_file(tmp: Path) -> str:
    from rh5_joint_stabilizer.controller import load_gains
    from rh5_msgs_py.names import JOINT_GROUPS

    load_gains()  # the packaged file parses
    path = tmp / "gains.yaml"
    path.write_text(yaml.safe_dump({"groups": {g: {"kp": 7.0, "kd": 0.5} for g in JOINT_GROUPS}}))
    return str(path)


def effects(tmp: Path, write_trajectory: Callable[..., Path]) -> dict[str, tuple[Callable[[], Any], dict[str, Effect]]]:
    """Per node: how to build it, and per writable parameter a value and the check of its effect."""
    from rh5_bringup.hardware.driver_node import DriverNode
    from rh5_bringup.sim.hardware_node import SimHardwareNode
    from rh5_hyrodyn_mapper.mapper_node import MapperNode
    from rh5_joint_stabilizer.stabilizer_node import StabilizerNode
    from rh5_planner.planner_node import PlannerNode

    trajectory = str(write_trajectory(tmp / "test_hold.rh5traj", 1.0))

    def job(node: Any) -> Any:
        return node._job()

    def load(node: Any) -> Any:
        from std_srvs.srv import Trigger

        return node._on_load(None, Trigger.Response())

    def units(node: Any) -> list[Any]:
        return [m for m in node.core.mapper.submechanisms if hasattr(m, "tolerance")]

    return {
        "driver": (
            lambda: DriverNode(composed=True),
            {
                "command_timeout_s": (0.25, lambda n: n.core.command_timeout_ns == 250_000_000),
                # the silence rule applies while the link is open (configured); until then the value waits
                "board_silence_timeout_s": (
                    0.3,
                    lambda n: (
                        n._silence_ns == 300_000_000
                        and (not n.link.is_open or n.core.silence_timeout_ns == 300_000_000)
                    ),
                ),
            },
        ),
        "mapper": (
            lambda: MapperNode(composed=True),
            {
                "clamp_to_limits": (False, lambda n: n.core.clamp_to_limits is False),
                "max_condition_number": (1e4, lambda n: n.core.mapper.max_condition == 1e4),
                "fk_tolerance": (1e-9, lambda n: all(u.tolerance == 1e-9 for u in units(n))),
                "fk_max_iterations": (7, lambda n: all(u.max_iterations == 7 for u in units(n))),
            },
        ),
        "stabilizer": (
            lambda: StabilizerNode(composed=True),
            {
                "trajectory_file": (trajectory, lambda n: n.core.trajectory is not None),
                "gains_file": (_gains_file(tmp), lambda n: bool((n.core.gains.kp == 7.0).all())),
                "state_timeout_s": (0.2, lambda n: n.core.safety.state_timeout_ns == 200_000_000),
                "max_tracking_error_rad": (0.15, lambda n: n.core.safety.max_tracking_error == 0.15),
                "rest_velocity_rad_s": (0.12, lambda n: n.core.safety.rest_velocity == 0.12),
                "ramp_max_velocity": (0.11, lambda n: n.core.ramp_max_velocity == 0.11),
                "ramp_max_acceleration": (0.9, lambda n: n.core.ramp_max_acceleration == 0.9),
                "balance_correction": (True, lambda n: n.core.correction is n.balance is not None),
                # read at each follow_joint_trajectory goal: the defaults the next goal gets
                "path_tolerance_rad": (0.1, lambda n: bool((n.action._defaults().path == 0.1).all())),
                "goal_tolerance_rad": (0.03, lambda n: bool((n.action._defaults().goal == 0.03).all())),
                "goal_time_tolerance_s": (2.5, lambda n: n.action._defaults().goal_time_s == 2.5),
            },
        ),
        "sim_hardware": (
            SimHardwareNode,
            {
                "drop_rate": (0.01, lambda n: n.emulator.faults.drop_rate == 0.01),
                "delay_s": (0.002, lambda n: n.emulator.faults.delay_s == 0.002),
                "silent_boards": (["LLKnee_Act1"], lambda n: n.emulator.faults.silent_boards == {"LLKnee_Act1"}),
                "corrupt_crc_rate": (0.02, lambda n: n.emulator.faults.corrupt_crc_rate == 0.02),
                "sensor_noise_std": (1e-4, lambda n: n.emulator.faults.sensor_noise_std == 1e-4),
            },
        ),
        "planner": (  # read by the next ~/plan or ~/load: the job it would run shows them
            PlannerNode,
            {
                "motion": ("squat_with_5kg_weights", lambda n: job(n).motion.name == "squat_with_5kg_weights"),
                "motion_overrides": ('{"total_time_s": 3.3}', lambda n: job(n).overrides == {"total_time_s": 3.3}),
                "output_dir": (str(tmp / "plans"), lambda n: job(n).file.parent == (tmp / "plans").resolve()),
                "trajectory_file": (trajectory, lambda n: trajectory in load(n).message),
                "max_iterations": (17, lambda n: job(n).max_iterations == 17),
                "stop_threshold": (1e-5, lambda n: job(n).stop_threshold == 1e-5),
                "solver_threads": (1, lambda n: job(n).nthreads == 1),
            },
        ),
    }


@pytest.fixture(scope="module")
def table(
    tmp_path_factory: pytest.TempPathFactory, ros_graph: Any, write_joint_trajectory: Callable[..., Path]
) -> dict[str, Any]:
    return effects(tmp_path_factory.mktemp("effects"), write_joint_trajectory)


def test_the_table_covers_every_writable_parameter(table: dict[str, Any]) -> None:
    nodes = {n.name: n for n in load_bringup().nodes}
    for name, node in nodes.items():
        writable = {s.name for s in load_spec(node.package, f"params/{name}.yaml") if not s.read_only}
        assert set(table.get(name, (None, {}))[1]) == writable, name


@pytest.mark.parametrize("name", ["driver", "mapper", "stabilizer", "sim_hardware", "planner"])
def test_each_writable_parameter_acts_once_set(name: str, table: dict[str, Any]) -> None:
    from rclpy.parameter import Parameter

    build, parameters = table[name]
    node = build()
    try:
        for parameter, (value, holds) in parameters.items():
            assert not holds(node), f"{name}.{parameter}: the effect holds before the set"
            kind = Parameter.Type.STRING_ARRAY if isinstance(value, list) else None
            [result] = node.set_parameters(
                [Parameter(parameter, kind, value) if kind else Parameter(parameter, value=value)]
            )
            assert result.successful, f"{name}.{parameter}: {result.reason}"
            assert holds(node), f"{name}.{parameter} = {value!r} was accepted but did not act"
    finally:
        node.destroy_node()
