"""Every node of the suite as a real process: visible in the graph, its parameters declared, clean SIGINT exit."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import threading
import time
from importlib import resources
from pathlib import Path
from typing import IO, Any

import pytest
import yaml
from rosbags.highlevel import AnyReader

from rh5_bringup.orchestration.cli import call_trigger
from rh5_bringup.orchestration.fastdds_shm import SHM_DIR, family, in_use_shm_files, shm_files_of
from rh5_bringup.orchestration.launcher import Bringup, NodeSpec, SuiteRun, load_bringup, wait_for_nodes
from rh5_bringup.recording import read_bag_info
from rh5_msgs_py import interfaces
from rh5_msgs_py.names import JOINT_NAMES
from rh5_msgs_py.node_runtime import parse_summaries
from rh5_msgs_py.parameters import load_spec

pytestmark = pytest.mark.ros

SPEC_OF_NODE = {
    "planner": ("rh5_planner", "params/planner.yaml"),
    "mapper": ("rh5_hyrodyn_mapper", "params/mapper.yaml"),
    "stabilizer": ("rh5_joint_stabilizer", "params/stabilizer.yaml"),
    "driver": ("rh5_bringup", "params/driver.yaml"),
    "control": ("rh5_bringup", "params/control.yaml"),
    "sim_hardware": ("rh5_bringup", "params/sim_hardware.yaml"),
    "recorder": ("rh5_bringup", "params/recorder.yaml"),
    "state_publisher": ("rh5_hyrodyn_mapper", "params/state_publisher.yaml"),
}
RUN_SECONDS = 2.0


def _log_dir(env: dict[str, str], name: str) -> Path:
    """Node logs of one test, inside the run's ROS_LOG_DIR (in the work tree)."""
    return Path(env["ROS_LOG_DIR"]) / name


def _call(node: Any, client: Any, request: Any, timeout_s: float = 10.0) -> Any:
    import rclpy

    assert client.wait_for_service(timeout_sec=timeout_s), f"service {client.srv_name} never appeared"
    future = client.call_async(request)
    rclpy.spin_until_future_complete(node, future, timeout_sec=timeout_s)
    assert future.done(), f"service {client.srv_name} did not answer"
    return future.result()


def _lifecycle_checks(node: Any) -> dict[str, Any]:
    """The managed driver in the control process: its state after autostart, a transition the state does not have
    (refused, by label and by id), then activate."""
    from lifecycle_msgs.msg import Transition
    from lifecycle_msgs.srv import ChangeState, GetState

    def state() -> str:
        client = node.create_client(GetState, "/driver/get_state")
        return str(_call(node, client, GetState.Request()).current_state.label)

    def change(**transition: Any) -> bool:
        client = node.create_client(ChangeState, "/driver/change_state")
        return bool(_call(node, client, ChangeState.Request(transition=Transition(**transition))).success)

    end = time.monotonic() + 10.0
    while state() != "inactive" and time.monotonic() < end:  # autostart: configure
        time.sleep(0.1)
    checks: dict[str, Any] = {"after_autostart": state()}
    checks["configure_again_by_label"] = change(label="configure")
    checks["configure_again_by_id"] = change(id=Transition.TRANSITION_CONFIGURE)
    checks["activate"] = change(label="activate")
    checks["active"] = state()
    return checks


@pytest.fixture(scope="module")
def suite(ros_graph: Any, ros_test_environment: dict[str, str]) -> Any:
    """The whole bringup running for a few seconds, then stopped with SIGINT; yields what was observed, per node
    (the control process hosts the driver, mapper and stabilizer nodes: their exit code is the process's)."""
    import rclpy
    from rcl_interfaces.srv import DescribeParameters, ListParameters
    from std_msgs.msg import String

    bringup = load_bringup().with_parameters("recorder", output=str(_log_dir(ros_test_environment, "suite") / "bag"))
    from diagnostic_msgs.msg import DiagnosticArray
    from tf2_msgs.msg import TFMessage

    descriptions: list[str] = []
    ros_graph.create_subscription(
        String, interfaces.ROBOT_DESCRIPTION.name, lambda m: descriptions.append(m.data), interfaces.LATCHED_QOS
    )
    tf: list[Any] = []
    ros_graph.create_subscription(TFMessage, "/tf", tf.append, interfaces.TF_QOS)
    ros_graph.create_subscription(TFMessage, "/tf_static", tf.append, interfaces.TF_STATIC_QOS)
    statuses: dict[str, Any] = {}
    ros_graph.create_subscription(
        DiagnosticArray, "/diagnostics", lambda m: statuses.update({s.name: s for s in m.status}), interfaces.EVENT_QOS
    )
    # The suite joins the session's domain, where the observer lives.
    run = SuiteRun(bringup, _log_dir(ros_test_environment, "suite"), int(ros_test_environment["ROS_DOMAIN_ID"]))
    observed: dict[str, Any] = {"parameters": {}, "descriptors": {}}
    with run:
        observed["missing"] = wait_for_nodes(ros_graph, bringup.node_names())
        for name, spec_source in SPEC_OF_NODE.items():
            listed = _call(
                ros_graph,
                ros_graph.create_client(ListParameters, f"/{name}/list_parameters"),
                ListParameters.Request(),
            )
            observed["parameters"][name] = set(listed.result.names)
            spec_names = [s.name for s in load_spec(*spec_source)]
            described = _call(
                ros_graph,
                ros_graph.create_client(DescribeParameters, f"/{name}/describe_parameters"),
                DescribeParameters.Request(names=spec_names),
            )
            observed["descriptors"][name] = {d.name: d for d in described.descriptors}
        observed["lifecycle"] = _lifecycle_checks(ros_graph)
        observed["start"] = call_trigger(ros_graph, "/stabilizer/start")
        end = time.monotonic() + RUN_SECONDS
        while time.monotonic() < end:
            rclpy.spin_once(ros_graph, timeout_sec=0.05)
        observed["crashed"] = [p.spec.name for p in run.exited()]
        observed["actions"] = dict(ros_graph.get_service_names_and_types())
    observed["exit_codes"] = {name: p.process.returncode for p in run.processes for name in p.names}
    observed["summaries"] = {s["node"]: s for p in run.processes for s in parse_summaries(p.output())}
    observed["stderr"] = {name: p.stderr_path.read_text() for p in run.processes for name in p.names}
    observed["descriptions"] = descriptions
    observed["tf"] = tf
    observed["diagnostics"] = statuses
    return observed


def test_every_node_appears_in_the_graph(suite: Any) -> None:
    assert suite["missing"] == set()
    assert suite["crashed"] == [], suite["stderr"]


@pytest.mark.parametrize("name", sorted(SPEC_OF_NODE))
def test_node_declares_its_spec_parameters_with_descriptions(suite: Any, name: str) -> None:
    specs = load_spec(*SPEC_OF_NODE[name])
    assert {s.name for s in specs} <= suite["parameters"][name]
    for spec in specs:
        descriptor = suite["descriptors"][name][spec.name]
        assert descriptor.description == spec.description
        assert descriptor.read_only == spec.read_only


@pytest.mark.parametrize("name", sorted(SPEC_OF_NODE))
def test_node_exits_cleanly_on_sigint_with_a_summary(suite: Any, name: str) -> None:
    assert suite["exit_codes"][name] == 0, suite["stderr"][name]
    assert suite["summaries"][name] is not None
    assert suite["summaries"][name]["node"] == name


def test_the_nodes_talk_to_each_other(suite: Any) -> None:
    """planner -> stabilizer; the control cycle publishes every stream of the loop; the recorder saw them all."""
    assert suite["start"][0], suite["start"][1]
    seen = {name: s["seen"] for name, s in suite["summaries"].items()}
    sent = {name: s["sent"] for name, s in suite["summaries"].items()}
    assert seen["stabilizer"].get("planned_trajectory", 0) >= 1
    assert sent["stabilizer"].get("joint_commands", 0) >= 10
    assert sent["mapper"].get("actuator_commands", 0) >= 10
    assert sent["driver"].get("actuator_states", 0) >= 10
    assert sent["mapper"].get("joint_states", 0) >= 10
    for topic in ("planned_trajectory", "joint_commands", "actuator_commands", "actuator_states", "joint_states"):
        assert seen["recorder"].get(topic, 0) >= 1, topic


def test_robot_description_is_latched_and_complete(suite: Any) -> None:
    assert suite["descriptions"], "no robot_description received"
    urdf = suite["descriptions"][-1]
    assert urdf.count('type="revolute"') == len(JOINT_NAMES)
    for joint in JOINT_NAMES:
        assert f'name="{joint}"' in urdf


def test_the_managed_driver_is_configured_and_refuses_a_wrong_transition(suite: Any) -> None:
    assert suite["lifecycle"] == {
        "after_autostart": "inactive",
        "configure_again_by_label": False,
        "configure_again_by_id": False,
        "activate": True,
        "active": "active",
    }


def test_tf_holds_every_link_of_the_urdf_and_the_odom_transform(suite: Any) -> None:
    import xml.etree.ElementTree as ET

    edges = {(t.header.frame_id, t.child_frame_id) for m in suite["tf"] for t in m.transforms}
    links = {link.get("name") for link in ET.fromstring(suite["descriptions"][-1]).iter("link")}
    assert links - {child for _, child in edges} == {"RH5_Root_Link"} - {child for _, child in edges}
    assert ("odom", "RH5_Root_Link") in edges


def test_robot_description_has_a_visual_for_every_link_with_mass(suite: Any) -> None:
    import xml.etree.ElementTree as ET

    root = ET.fromstring(suite["descriptions"][-1])
    massive = [link for link in root.iter("link") if float(link.find("inertial/mass").get("value")) > 0.0]
    assert [link.get("name") for link in massive if link.find("visual") is None] == []


def test_the_stabilizer_serves_follow_joint_trajectory_in_the_control_process(suite: Any) -> None:
    send_goal = "/stabilizer/follow_joint_trajectory/_action/send_goal"
    assert suite["actions"].get(send_goal) == ["control_msgs/action/FollowJointTrajectory_SendGoal"]


def test_diagnostics_have_a_status_per_component_and_task(suite: Any) -> None:
    names = set(suite["diagnostics"])
    expected = {"driver: safety", "mapper: limits", "mapper: kinematics", "stabilizer: tracking"}
    expected |= {"stabilizer: trajectory", "planner: solver", "recorder: bag", "sim_hardware: boards"}
    expected |= {"driver: board LLKnee_Act1", "rh5/driver", "rh5/stabilizer", "rh5/control"}
    assert expected <= names, sorted(names)


def test_bad_launch_parameter_is_refused_with_the_reason(ros_graph: Any, ros_test_environment: dict[str, str]) -> None:
    """The node exits with the reason on stderr; waiting for it ends once it has exited (not after the 20 s
    timeout), and the launcher says why it never appeared."""
    bad = NodeSpec("driver", "rh5_bringup", "driver_node", {"rate_hz": 0.0})
    domain = int(ros_test_environment["ROS_DOMAIN_ID"])
    with SuiteRun(Bringup("", (bad,)), _log_dir(ros_test_environment, "bad_parameter"), domain) as run:
        started = time.monotonic()
        missing = wait_for_nodes(ros_graph, {"driver"}, exited=lambda: {p.spec.name for p in run.exited()})
        run.processes[0].process.wait(timeout=15.0)
        waited = time.monotonic() - started
        why = run.why_missing({"driver"})
    proc = run.processes[0]
    assert proc.process.returncode == 2
    assert "rate_hz" in proc.stderr_path.read_text()
    # The node exists for a moment before its parameters are checked, and a busy observer may see it then (CI
    # did once): the wait ends either way, long before its 20 s timeout.
    assert missing <= {"driver"}
    assert waited < 15.0
    assert why.startswith("driver: exited with 2: cannot start: "), why
    assert "rate_hz out of range" in why


def test_runtime_parameter_change_is_validated(ros_graph: Any, ros_test_environment: dict[str, str]) -> None:
    from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
    from rcl_interfaces.srv import SetParameters

    bringup = load_bringup()
    only_driver = Bringup("", tuple(n for n in bringup.nodes if n.name == "driver"))
    with SuiteRun(
        only_driver, _log_dir(ros_test_environment, "set_parameter"), int(ros_test_environment["ROS_DOMAIN_ID"])
    ):
        assert wait_for_nodes(ros_graph, {"driver"}) == set()
        client = ros_graph.create_client(SetParameters, "/driver/set_parameters")

        def set_timeout(value: float) -> Any:
            value_msg = ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=value)
            request = SetParameters.Request(parameters=[Parameter(name="command_timeout_s", value=value_msg)])
            return _call(ros_graph, client, request).results[0]

        rejected = set_timeout(-1.0)
        accepted = set_timeout(0.05)
    assert not rejected.successful
    assert "command_timeout_s" in rejected.reason
    assert accepted.successful


# --- a dead recorder does not stop the robot ------------------------------------------------------------------------


class _Lines:
    """The lines a child process writes to one pipe, collected by a thread."""

    def __init__(self, stream: IO[str]) -> None:
        self.lines: list[str] = []
        self._thread = threading.Thread(target=self._read, args=(stream,), daemon=True)
        self._thread.start()

    def _read(self, stream: IO[str]) -> None:
        for line in stream:
            self.lines.append(line.rstrip("\n"))

    @property
    def text(self) -> str:
        return "\n".join(self.lines)

    def wait_for(self, needle: str, alive: subprocess.Popen[str], timeout_s: float) -> None:
        deadline = time.monotonic() + timeout_s
        while needle not in self.text:
            assert alive.poll() is None, f"rh5 up ended (exit {alive.returncode}) before {needle!r}:\n{self.text}"
            assert time.monotonic() < deadline, f"no {needle!r} within {timeout_s} s:\n{self.text}"
            time.sleep(0.1)

    def join(self) -> None:
        self._thread.join(timeout=10)


def _children(pid: int) -> dict[int, str]:
    """Live child processes of ``pid``: their command lines."""
    out = {}
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
            command = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode()
        except OSError:
            continue
        if int(fields[1]) == pid and fields[0] != "Z":
            out[int(entry.name)] = command
    return out


def _wait_for_recorded(bag: Path, topic: str, alive: subprocess.Popen[str], timeout_s: float = 30.0) -> int:
    """Until whole chunks of the recording in progress hold messages of ``topic``; returns how many."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        assert alive.poll() is None, "rh5 up ended"
        if bag.is_dir() and any(bag.glob("*.mcap")):
            count = {t.name: t.count for t in read_bag_info(bag).topics}.get(topic, 0)
            if count:
                return count
        time.sleep(0.2)
    pytest.fail(f"no {topic} in the bag's whole chunks within {timeout_s} s")


def _bringup_file(folder: Path, bag: Path) -> Path:
    """The packaged bringup with the recorder writing ``bag`` and the simulated boards on a free UDP port (the
    default port may be taken by another run on this machine)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    document = yaml.safe_load(
        resources.files("rh5_bringup.orchestration").joinpath("bringup.yaml").read_text(encoding="utf-8")
    )
    extra = {"recorder": {"output": str(bag)}, "sim_hardware": {"listen_port": port}, "driver": {"router_port": port}}
    for node in document["nodes"]:
        node["parameters"] = {**(node.get("parameters") or {}), **extra.get(node["name"], {})}
    path = folder / "bringup.yaml"
    path.write_text(yaml.safe_dump(document), encoding="utf-8")
    return path


def test_rh5_up_no_record_runs_the_suite_without_the_recorder(tmp_path: Path) -> None:
    bag = tmp_path / "bag"
    command = [str(Path(sys.prefix) / "bin" / "rh5"), "up", "--no-record", "--duration", "2"]
    command += ["--bringup", str(_bringup_file(tmp_path, bag)), "--log-dir", str(tmp_path / "log")]
    done = subprocess.run(command, capture_output=True, text=True, timeout=120, check=False)
    assert done.returncode == 0, done.stderr
    assert (
        "8 nodes running: control, control_streams, driver, mapper, planner, sim_hardware, stabilizer, state_publisher"
        in done.stdout
    )
    assert "recorder" not in done.stdout
    assert not bag.exists()


def test_the_suite_runs_on_when_the_recorder_is_killed(tmp_path: Path) -> None:
    """`rh5 up` as a user runs it, with the recorder SIGKILLed once every node is up: `rh5 up` reports it, removes
    the recorder's Fast DDS shared memory and keeps every other node running until it is stopped (Ctrl-C), when
    they all exit cleanly; the recorder's bag is then made complete by `rh5 bag recover`."""
    bag = tmp_path / "bag"
    rh5 = str(Path(sys.prefix) / "bin" / "rh5")
    command = [rh5, "up", "--duration", "120", "--bringup", str(_bringup_file(tmp_path, bag))]
    command += ["--log-dir", str(tmp_path / "log")]
    up = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert up.stdout is not None
    assert up.stderr is not None
    out, err = _Lines(up.stdout), _Lines(up.stderr)
    try:
        out.wait_for("nodes running", up, timeout_s=60.0)
        children = _children(up.pid)
        (recorder,) = [pid for pid, cmd in children.items() if "/recorder_node " in cmd]
        owned = shm_files_of(recorder)
        on_disk = _wait_for_recorded(bag, "/joint_states", up)
        os.kill(recorder, signal.SIGKILL)
        err.wait_for("recorder stopped on its own (exit -9); the other nodes keep running", up, timeout_s=30.0)
        owned_bases = {name.removesuffix("_el") for name in owned if name.endswith("_el")}
        in_use = in_use_shm_files()  # a 70xx port may already serve a new participant of another run
        kept = {base for base in owned_bases if (SHM_DIR / base).exists() and f"{base}_el" not in in_use}
        time.sleep(3.0)  # the suite runs on
        assert up.poll() is None, err.text
        alive = _children(up.pid)
        assert set(alive) == set(children) - {recorder}, (alive, children)
        up.send_signal(signal.SIGINT)
        up.wait(timeout=60)
    finally:
        if up.poll() is None:
            up.kill()
            up.wait()
        out.join()
        err.join()
    assert owned, "the recorder used Fast DDS shared memory"
    assert len(owned_bases) >= 2, sorted(owned)  # its segment and its ports
    assert not kept, f"what the dead recorder owned was removed at once: {sorted(kept)}"
    left = {name for name in owned if (SHM_DIR / name).exists()}
    unused = {name for name in left if not family(name) & in_use_shm_files()}  # another run's files may stay
    assert not unused, f"files the dead recorder used that no live process uses were left: {sorted(unused)}"
    assert "stopped on their own:" not in err.text, "the suite was not stopped because of the recorder"
    assert "its bag keeps every chunk written so far" in err.text
    exits = dict(line.split(" exit ") for line in out.lines if " exit " in line)
    exits = {name.strip(): int(code) for name, code in exits.items()}
    assert exits.pop("recorder") == -signal.SIGKILL
    assert set(exits) == {
        "sim_hardware",
        "control",
        "state_publisher",
        "planner",
    }  # control hosts the driver, mapper and stabilizer
    assert all(code == 0 for code in exits.values()), out.text
    assert up.returncode == 1, "a node died: rh5 up says so in its exit code"
    recovered = subprocess.run([rh5, "bag", "recover", str(bag)], capture_output=True, text=True, check=False)
    assert recovered.returncode == 0, recovered.stderr
    with AnyReader([bag]) as reader:
        counts = {c.topic: c.msgcount for c in reader.connections}
        assert sum(1 for _ in reader.messages()) == sum(counts.values())
    assert counts["/joint_states"] >= on_disk > 0, "every chunk complete at the kill is read back"
