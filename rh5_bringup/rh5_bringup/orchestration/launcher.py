"""Start the suite's nodes as real processes from the bringup description, and stop them cleanly.

There is no ros2 launch wheel here, so this is the suite's own launcher: each node runs
as its console script in its own process group (a terminal's Ctrl-C reaches only the
launcher, which then stops the nodes in reverse order with SIGINT, escalating to SIGTERM
and SIGKILL), in a ROS domain reserved for the run, with its output in the run's log folder.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field, replace
from importlib import resources
from pathlib import Path
from typing import Any

import yaml

from rh5_bringup.orchestration.fastdds_shm import remove_stale, shm_files_of
from rh5_msgs_py.interfaces import CONTROL_NODE, CONTROL_STREAMS_NODE
from rh5_msgs_py.node_runtime import parse_summary
from rh5_msgs_py.parameters import load_spec
from rh5_msgs_py.ros_env import DomainLease, suite_environment

STOP_GRACE_S = 10.0


@dataclass(frozen=True)
class NodeSpec:
    """One node of the bringup description."""

    name: str
    package: str
    executable: str
    parameters: dict[str, Any] = field(default_factory=dict)
    remappings: tuple[tuple[str, str], ...] = ()
    """Topic/service renames (from, to), as ``-r from:=to`` on the command line."""
    hosts: tuple[str, ...] = ()
    """Nodes of the bringup this node's process hosts (the control process: driver, mapper, stabilizer). They
    run inside it when the bringup is composed, and on their own, without this node, when it is not."""
    essential: bool = True
    """False: when this node's process dies the rest of the suite keeps running (the recorder: the robot must
    not stop because its recording did); the launcher reports it and removes its shared memory."""
    lost_hint: str = ""
    """What to tell the user when this non-essential node died (e.g. how to recover its bag)."""


@dataclass(frozen=True)
class LaunchArgument:
    """A launch argument of the bringup: a named value that sets one parameter of one node, and for some of
    its values further parameters of other nodes (``implies``: value -> node -> parameters)."""

    name: str
    default: str
    choices: tuple[str, ...]
    node: str
    parameter: str
    description: str = ""
    implies: Mapping[str, Mapping[str, Mapping[str, Any]]] = field(default_factory=dict)


@dataclass(frozen=True)
class Bringup:
    """The suite to start: a namespace, its nodes in start order and the launch arguments."""

    namespace: str
    nodes: tuple[NodeSpec, ...]
    arguments: tuple[LaunchArgument, ...] = ()
    composed: bool = True
    """Run hosted nodes inside their host's process (the default); False: each on its own, hosts left out."""

    def processes(self) -> list[tuple[NodeSpec, tuple[NodeSpec, ...]]]:
        """The processes to start, in description order: (node whose executable runs, nodes it hosts)."""
        by_name = {n.name: n for n in self.nodes}
        hosted = {name for n in self.nodes for name in n.hosts}
        out = []
        for node in self.nodes:
            if node.hosts and self.composed:
                out.append((node, tuple(by_name[name] for name in node.hosts)))
            elif not node.hosts and not (self.composed and node.name in hosted):
                out.append((node, ()))
        return out

    def node_names(self) -> set[str]:
        """The nodes that appear in the ROS graph when this bringup runs (with the control process's stream
        publisher: until it is in the graph, an observer may not have its 1 kHz topics yet)."""
        names = {n.name for host, hosted in self.processes() for n in (host, *hosted)}
        return names | {CONTROL_STREAMS_NODE} if CONTROL_NODE in names else names

    def resolved(self, **values: str) -> Bringup:
        """A copy with every launch argument applied (``values`` override the defaults); unknown or bad values raise."""
        known = {a.name: a for a in self.arguments}
        unknown = set(values) - set(known)
        if unknown:
            msg = f"unknown launch arguments {sorted(unknown)} (have {sorted(known)})"
            raise KeyError(msg)
        bringup = self
        for argument in self.arguments:
            value = values.get(argument.name, argument.default)
            if argument.choices and value not in argument.choices:
                msg = f"launch argument {argument.name}: {value!r} is not one of {list(argument.choices)}"
                raise ValueError(msg)
            bringup = bringup.with_parameters(argument.node, **{argument.parameter: value})
            for node, parameters in argument.implies.get(value, {}).items():
                bringup = bringup.with_parameters(node, **parameters)
        return bringup

    def without(self, node_name: str) -> Bringup:
        """A copy without ``node_name`` (``rh5 up --no-record``: without the recorder); a hosted node cannot be
        left out (its host runs it)."""
        if node_name not in {n.name for n in self.nodes}:
            msg = f"no node {node_name!r} in the bringup (have {[n.name for n in self.nodes]})"
            raise KeyError(msg)
        if any(node_name in n.hosts for n in self.nodes):
            msg = f"{node_name!r} is hosted by another node's process and cannot be left out"
            raise ValueError(msg)
        nodes = tuple(n for n in self.nodes if n.name != node_name)
        arguments = tuple(a for a in self.arguments if a.node != node_name)
        return replace(self, nodes=nodes, arguments=arguments)

    def with_parameters(self, node_name: str, **parameters: Any) -> Bringup:
        """A copy in which ``node_name`` gets extra/overriding parameters."""
        if node_name not in {n.name for n in self.nodes}:
            msg = f"no node {node_name!r} in the bringup (have {[n.name for n in self.nodes]})"
            raise KeyError(msg)
        nodes = tuple(
            replace(n, parameters={**n.parameters, **parameters}) if n.name == node_name else n for n in self.nodes
        )
        return replace(self, nodes=nodes)


def load_bringup(path: Path | None = None) -> Bringup:
    """Read the bringup description (default: the packaged rh5_bringup/bringup.yaml)."""
    if path is None:
        text = resources.files(__package__).joinpath("bringup.yaml").read_text(encoding="utf-8")
    else:
        text = Path(path).read_text(encoding="utf-8")
    document = yaml.safe_load(text)
    nodes = tuple(
        NodeSpec(
            n["name"],
            n["package"],
            n["executable"],
            dict(n.get("parameters") or {}),
            tuple((str(src), str(dst)) for src, dst in (n.get("remappings") or {}).items()),
            tuple(str(name) for name in n.get("hosts") or ()),
            bool(n.get("essential", True)),
            str(n.get("lost_hint", "")),
        )
        for n in document["nodes"]
    )
    arguments = tuple(
        LaunchArgument(
            name,
            str(a["default"]),
            tuple(str(c) for c in a.get("choices") or ()),
            *str(a["sets"]).split(".", 1),
            description=str(a.get("description", "")),
            implies={
                str(value): {str(node): dict(parameters) for node, parameters in (by_node or {}).items()}
                for value, by_node in (a.get("implies") or {}).items()
            },
        )
        for name, a in (document.get("arguments") or {}).items()
    )
    bringup = Bringup(str(document.get("namespace") or ""), nodes, arguments)
    names = {n.name for n in nodes}
    for node in nodes:
        unknown = sorted(set(node.hosts) - names)
        if unknown or node.name in node.hosts:
            msg = f"node {node.name} hosts {list(node.hosts)}: {unknown or 'itself'} not a node of the bringup"
            raise ValueError(msg)
    for argument in arguments:
        if argument.node not in names:
            msg = f"launch argument {argument.name} sets {argument.node}.{argument.parameter}: no such node"
            raise ValueError(msg)
        for value, by_node in argument.implies.items():
            if argument.choices and value not in argument.choices:
                msg = f"launch argument {argument.name} implies parameters for {value!r}, not one of its choices"
                raise ValueError(msg)
            unknown = sorted(set(by_node) - names)
            if unknown:
                msg = f"launch argument {argument.name}={value} implies parameters of {unknown}: no such node"
                raise ValueError(msg)
    return bringup


def parameter_names(node: NodeSpec) -> set[str]:
    """The parameters ``node`` declares: those of its spec file (``params/<name>.yaml`` in its package,
    rh5_msgs_py.parameters) and rclpy's ``use_sim_time``."""
    return {spec.name for spec in load_spec(node.package, f"params/{node.name}.yaml")} | {"use_sim_time"}


def check_parameter_names(bringup: Bringup, parameters: Mapping[str, Mapping[str, Any]]) -> None:
    """Refuse parameters for nodes the bringup does not run, or names those nodes do not have.

    :raises ValueError: naming what is unknown and what is valid.
    """
    nodes = {n.name: n for n in bringup.nodes}
    if unknown_nodes := sorted(set(parameters) - set(nodes)):
        msg = f"no nodes {unknown_nodes} in the bringup (have {sorted(nodes)})"
        raise ValueError(msg)
    for name, values in parameters.items():
        valid = parameter_names(nodes[name])
        if unknown := sorted(set(values) - valid):
            msg = f"node {name!r} has no parameter{'s' if len(unknown) > 1 else ''} {unknown}; valid: {sorted(valid)}"
            raise ValueError(msg)


def node_command(node: NodeSpec, namespace: str = "") -> list[str]:
    """The command line that starts ``node`` (its console script with --ros-args)."""
    command = [str(Path(sys.prefix) / "bin" / node.executable), "--ros-args", "-r", f"__node:={node.name}"]
    if namespace:
        command += ["-r", f"__ns:=/{namespace.strip('/')}"]
    for source, target in node.remappings:
        command += ["-r", f"{source}:={target}"]
    for key, value in node.parameters.items():
        command += ["-p", f"{key}:={json.dumps(value)}"]  # JSON is YAML flow style, which --ros-args parses
    return command


def fully_qualified(name: str, namespace: str = "") -> str:
    """A node's name with its namespace, as parameter files and the graph name it: /ns/name."""
    return f"/{namespace.strip('/')}/{name}" if namespace.strip("/") else f"/{name}"


def composed_parameters(nodes: Iterable[NodeSpec], namespace: str = "") -> dict[str, Any]:
    """The parameter file of a process hosting several nodes: each node's parameters under its full name."""
    return {fully_qualified(n.name, namespace): {"ros__parameters": dict(n.parameters)} for n in nodes}


def composed_command(host: NodeSpec, hosted: tuple[NodeSpec, ...], params_file: Path, namespace: str = "") -> list[str]:
    """The command line of a process hosting several nodes: the host's executable, its nodes keep their names
    (so no __node remap), parameters per node from ``params_file``, remappings per node."""
    command = [str(Path(sys.prefix) / "bin" / host.executable), "--ros-args"]
    if namespace:
        command += ["-r", f"__ns:=/{namespace.strip('/')}"]
    for node in (host, *hosted):
        for source, target in node.remappings:
            command += ["-r", f"{node.name}:{source}:={target}"]
    return [*command, "--params-file", str(params_file)]


@dataclass
class NodeProcess:
    """A started node: its process and where its output goes."""

    spec: NodeSpec
    process: subprocess.Popen[bytes]
    stdout_path: Path
    stderr_path: Path
    hosted: tuple[NodeSpec, ...] = ()
    shm_files: set[str] = field(default_factory=set)
    """The Fast DDS shared-memory files the process was seen using (removed if it dies without doing so)."""

    @property
    def names(self) -> tuple[str, ...]:
        """The nodes this process runs."""
        return (self.spec.name, *(n.name for n in self.hosted))

    def output(self) -> str:
        """What the node printed on stdout so far."""
        return self.stdout_path.read_text(encoding="utf-8", errors="replace")

    def summary(self) -> dict[str, Any] | None:
        """The node's exit summary (what it saw and sent), once it has stopped."""
        return parse_summary(self.output())

    def last_error(self, max_chars: int = 300) -> str:
        """The last line the node wrote on stderr (a node that cannot start says why there), shortened."""
        try:
            lines = self.stderr_path.read_text(encoding="utf-8", errors="replace").strip().splitlines()
        except OSError:
            return ""
        last = lines[-1].strip() if lines else ""
        return last if len(last) <= max_chars else last[: max_chars - 3] + "..."


class SuiteRun:
    """A running suite: processes, their domain and log folder. Use as a context manager."""

    def __init__(self, bringup: Bringup, log_dir: Path, domain_id: int | None = None) -> None:
        self.bringup = bringup
        self.log_dir = Path(log_dir)
        self._lease = DomainLease() if domain_id is None else None
        self.domain_id = self._lease.domain_id if self._lease is not None else domain_id
        self.env = suite_environment(self.domain_id, self.log_dir)
        self.processes: list[NodeProcess] = []
        self.removed_shm: list[str] = []
        """Fast DDS shared-memory files removed after killed nodes."""

    def start(self) -> None:
        """Start every node in description order."""
        self.log_dir.mkdir(parents=True, exist_ok=True)
        namespace = self.bringup.namespace
        for spec, hosted in self.bringup.processes():
            stdout_path = self.log_dir / f"{spec.name}.out"
            stderr_path = self.log_dir / f"{spec.name}.err"
            if hosted:
                params_file = self.log_dir / f"{spec.name}.params.yaml"
                params_file.write_text(
                    yaml.safe_dump(composed_parameters((spec, *hosted), namespace)), encoding="utf-8"
                )
                command = composed_command(spec, hosted, params_file, namespace)
            else:
                command = node_command(spec, namespace)
            with stdout_path.open("wb") as out, stderr_path.open("wb") as err:
                process = subprocess.Popen(
                    command,
                    stdout=out,
                    stderr=err,
                    stdin=subprocess.DEVNULL,
                    env=self.env,
                    start_new_session=True,
                )
            self.processes.append(NodeProcess(spec, process, stdout_path, stderr_path, hosted))

    def exited(self) -> list[NodeProcess]:
        """Processes that have stopped on their own."""
        return [p for p in self.processes if p.process.poll() is not None]

    def note_shared_memory(self) -> None:
        """Note which Fast DDS shared-memory files each running process and its children (the control process's
        stream publisher) use (see :meth:`clean_up_after`)."""
        for proc in self.processes:
            if proc.process.poll() is None:
                for pid in (proc.process.pid, *_descendants(proc.process.pid)):
                    proc.shm_files |= shm_files_of(pid)

    def clean_up_after(self, proc: NodeProcess) -> list[str]:
        """Remove the shared-memory files a dead process left that no live process uses; returns their names."""
        if proc.process.poll() is None:
            msg = f"{proc.spec.name} is still running"
            raise RuntimeError(msg)
        removed = remove_stale(proc.shm_files)
        self.removed_shm += removed
        return removed

    def killed(self) -> bool:
        """Whether a node process ended by a signal (it left its Fast DDS shared memory)."""
        return any(p.process.returncode is not None and p.process.returncode < 0 for p in self.processes)

    def remove_stale_shared_memory(self) -> list[str]:
        """If a node was killed: remove the shared memory of every node that no live participant owns any more
        (a killed process never drops its references to the other participants' ports, so they stay even
        after their owners exit cleanly). Returns the names removed."""
        if not self.killed():
            return []
        removed = remove_stale(set().union(*(p.shm_files for p in self.processes)))
        self.removed_shm += removed
        return removed

    def exited_nodes(self) -> set[str]:
        """Nodes whose process has stopped."""
        return {name for p in self.exited() for name in p.names}

    def why_missing(self, names: Iterable[str]) -> str:
        """Why nodes never appeared in the ROS graph, one per line: the exit code and last stderr line of those
        that stopped (a bad parameter, an import error), else that they are still starting."""
        by_name = {name: p for p in self.processes for name in p.names}
        lines = []
        for name in sorted(names):
            proc = by_name.get(name)
            if proc is None:
                lines.append(f"{name}: not started")
            elif (code := proc.process.poll()) is not None:
                lines.append(f"{name}: exited with {code}: {proc.last_error() or 'nothing on stderr'}")
            else:
                lines.append(f"{name}: still running but not in the graph (log {proc.stderr_path})")
        return "\n".join(lines)

    def stop(self, grace_s: float = STOP_GRACE_S) -> dict[str, int]:
        """Stop every node, newest first: SIGINT, then SIGTERM and SIGKILL after ``grace_s``. Idempotent.
        Then removes the shared memory a killed node left (:meth:`remove_stale_shared_memory`)."""
        for proc in reversed(self.processes):
            if proc.process.poll() is None:
                proc.process.send_signal(signal.SIGINT)
        deadline = time.monotonic() + grace_s
        for proc in self.processes:
            for sig in (signal.SIGTERM, signal.SIGKILL):
                if self._wait(proc, max(0.1, deadline - time.monotonic())):
                    break
                os.killpg(proc.process.pid, sig)
                deadline = time.monotonic() + 2.0
            proc.process.wait()
        self.remove_stale_shared_memory()
        if self._lease is not None:
            self._lease.release()
        return {name: p.process.returncode for p in self.processes for name in p.names}

    def _wait(self, proc: NodeProcess, timeout_s: float) -> bool:
        """Wait up to ``timeout_s`` for ``proc`` to exit; True if it did. After a node was killed, whatever the
        others leave is removed as soon as each exits (before another run's participant takes a port over)."""
        deadline = time.monotonic() + timeout_s
        exited = len(self.exited())
        while proc.process.poll() is None:
            if time.monotonic() >= deadline:
                return False
            time.sleep(0.02)
            if len(self.exited()) != exited:
                exited = len(self.exited())
                self.remove_stale_shared_memory()
        return True

    def __enter__(self) -> SuiteRun:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()


def _descendants(pid: int) -> list[int]:
    """The processes ``pid`` started, and theirs (empty once it is gone)."""
    found, pending = [], [pid]
    while pending:
        parent = pending.pop()
        try:
            tasks = list(Path(f"/proc/{parent}/task").iterdir())
        except OSError:
            continue
        for task in tasks:
            try:
                children = [int(c) for c in (task / "children").read_text().split()]
            except OSError:
                continue
            found += children
            pending += children
    return found


def wait_for_nodes(
    graph_node: Any,
    names: set[str],
    namespace: str = "/",
    timeout_s: float = 20.0,
    exited: Callable[[], set[str]] | None = None,
    *,
    enclave: str | None = None,
) -> set[str]:
    """Wait until every node in ``names`` is visible in the ROS graph; return those that never appeared.
    ``exited`` (names of nodes whose process stopped) ends the wait early once every missing node has stopped;
    ``enclave`` counts only nodes of that enclave (``--ros-args --enclave``), not another process's namesakes."""
    import rclpy  # noqa: PLC0415 (the launcher imports ROS only when it observes the graph)

    deadline = time.monotonic() + timeout_s
    missing = set(names)
    while missing and time.monotonic() < deadline:
        rclpy.spin_once(graph_node, timeout_sec=0.1)
        visible = {
            name
            for name, ns, node_enclave in graph_node.get_node_names_and_namespaces_with_enclaves()
            if ns == namespace and enclave in (None, node_enclave)
        }
        missing = names - visible
        if missing and exited is not None and missing <= exited():
            break
    return missing
