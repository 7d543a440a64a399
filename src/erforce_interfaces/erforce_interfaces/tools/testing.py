"""Test harness for integration tests over real DDS: isolated domains, node processes, probes.

Use it as a pytest plugin (``pytest_plugins = ["erforce_interfaces.tools.testing"]`` in a
conftest.py) and take the ``ros_graph`` fixture (or ``module_ros_graph`` / ``class_ros_graph``, one graph for
a module's or a class's tests)::

    def test_talker(ros_graph):
        ros_graph.start_node("erforce_interfaces", "talker", params={"rate_hz": 50.0})
        msg = ros_graph.wait_for_message("/chatter", String, timeout_s=10.0)

Isolation: every ``RosGraph`` claims a DDS domain id nobody else on this machine holds
(an exclusive ``flock`` on ``$TMPDIR/erforce-ros-domains/<id>.lock``, released when the
graph closes or the process dies), and restricts discovery to localhost. Two test
sessions, or two xdist workers, therefore never see each other's topics.

Callback faults: every node runs its subscription callbacks inside one guard
(node_support.guard_callbacks) that turns an exception into a warning instead of a dead node.
So that a bug of ours does not hide behind it, the ``ros_graph`` fixture fails a test whose
processes logged such a warning, unless the test declared it with ``expect_callback_faults``.

Reaping: every child gets its own process group and an environment tag. ``close()``
sends SIGINT, then SIGTERM, then SIGKILL with timeouts (each to every child at once), and finally kills
any process still carrying the tag (grandchildren of a launcher killed too early included).
"""

from __future__ import annotations

import contextlib
import ipaddress
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
import uuid
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from erforce_interfaces.tools.processes import DomainLease, stop_processes

_TAG_VAR = "ERFORCE_TEST_TAG"


@contextlib.contextmanager
def isolated_node(name: str, **node_kwargs):
    """One rclpy node in a context of its own and a private DDS domain, for in-process tests
    (``node_kwargs`` go to rclpy.create_node, e.g. ``parameter_overrides``)."""
    import rclpy
    from rclpy.context import Context

    lease = DomainLease()
    ctx = Context()
    rclpy.init(context=ctx, domain_id=lease.domain_id)
    node = rclpy.create_node(name, context=ctx, **node_kwargs)
    try:
        yield node
    finally:
        node.destroy_node()
        rclpy.try_shutdown(context=ctx)
        lease.release()


def _executable_path(name: str) -> str:
    """Console scripts live next to the interpreter in a venv."""
    candidate = Path(sys.executable).with_name(name)
    if candidate.exists():
        return str(candidate)
    found = shutil.which(name)
    if not found:
        raise FileNotFoundError(f"executable {name!r} not found next to {sys.executable} or on PATH")
    return found


@dataclass
class NodeProcess:
    """A child process with its combined output in a log file."""

    name: str
    popen: subprocess.Popen
    log_path: Path
    cmd: list[str] = field(default_factory=list)

    @property
    def pid(self) -> int:
        return self.popen.pid

    def output(self) -> str:
        return self.log_path.read_text(errors="replace") if self.log_path.exists() else ""

    def alive(self) -> bool:
        return self.popen.poll() is None

    def wait_for_output(self, pattern: str, timeout_s: float = 10.0) -> re.Match:
        deadline = time.monotonic() + timeout_s
        regex = re.compile(pattern)
        while True:
            m = regex.search(self.output())
            if m:
                return m
            if time.monotonic() > deadline:
                raise TimeoutError(f"{self.name}: no output matching {pattern!r} within {timeout_s} s; "
                                   f"output so far:\n{self.output()[-3000:]}")
            if not self.alive() and not regex.search(self.output()):
                raise RuntimeError(f"{self.name} exited with {self.popen.returncode} before printing "
                                   f"{pattern!r}; output:\n{self.output()[-3000:]}")
            time.sleep(0.02)

    def wait_exit(self, timeout_s: float) -> int:
        return self.popen.wait(timeout=timeout_s)

    def signal(self, sig: int) -> None:
        if self.alive():
            with contextlib.suppress(ProcessLookupError):
                os.kill(self.popen.pid, sig)


def _pids_with_tag(tag: str) -> list[int]:
    needle = f"{_TAG_VAR}={tag}".encode()
    pids = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit() or int(entry.name) == os.getpid():
            continue
        try:
            if needle in (entry / "environ").read_bytes().split(b"\0"):
                pids.append(int(entry.name))
        except OSError:
            continue
    return pids


_TCP_LISTEN = "0A"  # the state column of /proc/net/tcp


def proc_net_address(hex_address: str) -> str:
    """/proc/net/{udp,tcp}[6]'s local address (32-bit words in host byte order) as text."""
    raw = bytes.fromhex(hex_address)
    words = b"".join(raw[k:k + 4][::-1] for k in range(0, len(raw), 4)) if socket.htonl(1) != 1 else raw
    return socket.inet_ntop(socket.AF_INET if len(raw) == 4 else socket.AF_INET6, words)


def listening_sockets(pid: int) -> list[tuple[str, str, int]]:
    """(table, local address, port) of every UDP socket and every listening TCP socket of process ``pid``
    (its socket inodes in /proc/<pid>/fd, looked up in /proc/<pid>/net/{udp,udp6,tcp,tcp6})."""
    inodes = set()
    for fd in os.listdir(f"/proc/{pid}/fd"):
        try:
            link = os.readlink(f"/proc/{pid}/fd/{fd}")
        except OSError:
            continue  # closed meanwhile
        if link.startswith("socket:["):
            inodes.add(int(link[8:-1]))
    found = []
    for table in ("udp", "udp6", "tcp", "tcp6"):
        for line in Path(f"/proc/{pid}/net/{table}").read_text().splitlines()[1:]:
            fields = line.split()
            if int(fields[9]) not in inodes or (table.startswith("tcp") and fields[3] != _TCP_LISTEN):
                continue
            address, port = fields[1].rsplit(":", 1)
            found.append((table, proc_net_address(address), int(port, 16)))
    return found


def on_loopback(address: str) -> bool:
    """127.0.0.0/8 or ::1 (also as an IPv4-mapped IPv6 address)."""
    ip = ipaddress.ip_address(address)
    ip = getattr(ip, "ipv4_mapped", None) or ip
    return ip.is_loopback


class RosGraph:
    """Node processes plus an in-process probe node, all in one private DDS domain."""

    def __init__(self, workdir: Path | None = None, lease: DomainLease | None = None) -> None:
        self.lease = lease or DomainLease()
        self.domain_id = self.lease.domain_id
        self.workdir = Path(workdir or tempfile.mkdtemp(prefix="erforce-graph-"))
        self.workdir.mkdir(parents=True, exist_ok=True)
        self.tag = uuid.uuid4().hex
        self.env = dict(os.environ)
        self.env.update({
            "ROS_DOMAIN_ID": str(self.domain_id),
            "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST",
            "PYTHONUNBUFFERED": "1",
            "RCUTILS_COLORIZED_OUTPUT": "0",
            _TAG_VAR: self.tag,
        })
        self.env.pop("ROS_STATIC_PEERS", None)
        from erforce_interfaces.wire.contract import dds_profile_env

        self.env.update(dds_profile_env(self.env))  # a restarted node is matched within ~1 s
        self.processes: list[NodeProcess] = []
        self._launches: list[NodeProcess] = []
        self._launch_checked: dict[int, int] = {}  # launch pid -> bytes of its output checked by launch_failure
        self._launch_failed: list[str] = []  # the FAILED_TO_START lines found there
        self._probe = None
        self._counter = 0
        self._expected_faults: set[str] | None = set()  # process names; None: any

    # ------------------------------------------------------------ processes
    def start(self, cmd: Sequence[str], name: str | None = None, env: dict[str, str] | None = None,
              own_session: bool = True) -> NodeProcess:
        """Start ``cmd`` in a session of its own, or with ``own_session`` False in this process's session
        (in a process group of its own), as the demo starts the graph and its observers: Linux ranks
        threads by scheduling priority only inside one session (autogroup)."""
        self._counter += 1
        name = name or f"{Path(cmd[0]).name}-{self._counter}"
        log_path = self.workdir / f"{self._counter:02d}-{re.sub(r'[^A-Za-z0-9_.-]', '_', name)}.log"
        full_env = dict(self.env)
        full_env.update(env or {})
        log = open(log_path, "wb")
        popen = subprocess.Popen(list(cmd), stdout=log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                                 env=full_env, start_new_session=own_session,
                                 process_group=None if own_session else 0)
        log.close()
        proc = NodeProcess(name=name, popen=popen, log_path=log_path, cmd=list(cmd))
        self.processes.append(proc)
        return proc

    def start_node(self, package: str, executable: str, *, name: str | None = None,
                   namespace: str | None = None, params: dict[str, Any] | None = None,
                   params_file: str | Path | None = None, remaps: dict[str, str] | None = None,
                   use_sim_time: bool = False, extra_args: Sequence[str] = (), own_session: bool = True) -> NodeProcess:
        """Start one node the way ``ros2 run`` / ``ros2 launch`` would (``own_session``: see ``start``)."""
        del package  # executables are console scripts of the package's distribution
        cmd = [_executable_path(executable), *extra_args, "--ros-args"]
        if name:
            cmd += ["-r", f"__node:={name}"]
        if namespace:
            cmd += ["-r", f"__ns:=/{namespace.strip('/')}"]
        all_params = dict(params or {})
        if use_sim_time:
            all_params["use_sim_time"] = True
        if all_params:
            path = self.workdir / f"params-{self._counter + 1}-{name or executable}.yaml"
            path.write_text(yaml.safe_dump({"/**": {"ros__parameters": all_params}}))
            cmd += ["--params-file", str(path)]
        if params_file:
            cmd += ["--params-file", str(params_file)]
        for src, dst in (remaps or {}).items():
            cmd += ["-r", f"{src}:={dst}"]
        return self.start(cmd, name=name or executable, own_session=own_session)

    def start_launch(self, launch_file: str | Path, *options: str, standby: bool = False,
                     **launch_args: Any) -> NodeProcess:
        """``erforce-launch [options] FILE name:=value ...``. Without warm standbys unless ``standby``: each
        costs its node's imports in CPU (bench_respawn.py --standby-cost), which a test that kills no node
        would pay for nothing; the tests that kill nodes (test/faults, LaunchedDemo) run them as shipped."""
        options = (*options, *(() if standby else ("--no-standby",)))
        cmd = [_executable_path("erforce-launch"), *options, str(launch_file)]
        cmd += [f"{k}:={v}" for k, v in launch_args.items()]
        proc = self.start(cmd, name=f"launch-{Path(launch_file).stem}")
        self._launches.append(proc)
        return proc

    def launch_failure(self) -> str | None:
        """Why a launch this graph started cannot bring its graph up, or None: it could not run a node's
        command (erforce-launch's ``FAILED_TO_START`` lines, each naming what is missing) or it ended with an
        error. ``spin_until`` raises it at once instead of waiting for its deadline."""
        from erforce_interfaces.tools.launcher import FAILED_TO_START

        for proc in self._launches:
            checked = self._launch_checked.get(proc.pid, 0)
            with contextlib.suppress(FileNotFoundError), open(proc.log_path, "rb") as log:
                log.seek(checked)
                new = log.read()
                new = new[:new.rfind(b"\n") + 1]  # whole lines only: the rest is read next time
                self._launch_checked[proc.pid] = checked + len(new)
                self._launch_failed.extend(f"{proc.name}: {line.strip()}" for line in
                                           new.decode(errors="replace").splitlines() if FAILED_TO_START in line)
        if self._launch_failed:
            return f"{len(self._launch_failed)} process(es) failed to start:\n" + "\n".join(self._launch_failed[:10])
        for proc in self._launches:
            if not proc.alive() and proc.popen.returncode != 0:
                return f"{proc.name} ended with exit code {proc.popen.returncode}:\n{proc.output()[-3000:]}"
        return None

    @staticmethod
    def probe_executable(name: str) -> str:
        """Path of a console script of the stack (next to this interpreter)."""
        return _executable_path(name)

    def pids(self) -> list[int]:
        """Every live process started by this graph, grandchildren included."""
        return _pids_with_tag(self.tag)

    def expect_callback_faults(self, *names: str) -> None:
        """Declare that this test provokes callback faults (node_support.CALLBACK_FAULT) in the named
        processes (their ``NodeProcess.name``), or, without names, in any."""
        if not names:
            self._expected_faults = None
        elif self._expected_faults is not None:
            self._expected_faults.update(names)

    def unexpected_callback_faults(self) -> list[str]:
        """The callback-fault warnings logged by processes the test did not declare (see above)."""
        from erforce_interfaces.runtime.node_support import CALLBACK_FAULT

        if self._expected_faults is None:
            return []
        return [f"{proc.name}: {line.strip()}" for proc in self.processes if proc.name not in self._expected_faults
                for line in proc.output().splitlines() if CALLBACK_FAULT in line]

    # ---------------------------------------------------------------- probe
    @property
    def probe(self):
        """An rclpy node in this graph's domain, in its own context (created on first use)."""
        if self._probe is None:
            self._probe = _Probe(self.domain_id)
        return self._probe

    def wait_for_message(self, topic: str, msg_type: type, timeout_s: float = 10.0, qos=None,
                         predicate: Callable[[Any], bool] | None = None):
        return self.probe.wait_for_message(topic, msg_type, timeout_s, qos, predicate)

    def subscribe(self, topic: str, msg_type: type, qos=None) -> list:
        return self.probe.subscribe(topic, msg_type, qos)

    def spin_until(self, condition: Callable[[], bool], timeout_s: float, what: str = "condition") -> None:
        """The probe's ``spin_until``; raises RuntimeError as soon as a launch of this graph failed
        (``launch_failure``)."""
        next_check = [0.0]

        def done() -> bool:
            if time.monotonic() >= next_check[0]:  # a few times a second: it reads the launches' new output
                next_check[0] = time.monotonic() + 0.2
                failure = self.launch_failure()
                if failure is not None:
                    raise RuntimeError(f"waiting for {what}: {failure}")
            return condition()

        self.probe.spin_until(done, timeout_s, what)

    # -------------------------------------------------------------- teardown
    def close(self) -> None:
        stop_processes([proc.popen for proc in reversed(self.processes)])
        for pid in _pids_with_tag(self.tag):
            with contextlib.suppress(ProcessLookupError, PermissionError):
                os.kill(pid, signal.SIGKILL)
        if self._probe is not None:
            self._probe.close()
            self._probe = None
        self.lease.release()

    def __enter__(self) -> RosGraph:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def hold_the_lockstep(graph: RosGraph, robots: Sequence[str] = ("robot_0",), wait_s: float = 10.0) -> None:
    """Make a launched lockstep graph wait for a starved node instead of taking it for dead, for tests that kill
    none and expect the deterministic run: each robot's motor_boards waits up to ``wait_s`` of wall time for its
    velocity controller's setpoint (``setpoint_wait_s``, 0.05 s by default) and the plant twice that for the
    boards (``lockstep_timeout_s``, 2 s). Past those the boards go on with an old setpoint and stop the wheels
    0.1 s of robot time later, and the plant drives a silent board's robot with zero duty: on a loaded machine,
    where the demo's simulated world runs at SCHED_IDLE, the catching robot then stood still or turned off the
    ball's line."""
    for robot in robots:
        result = graph.probe.set_parameter(f"/{robot}/motor_boards", "setpoint_wait_s", wait_s, timeout_s=60.0)
        if not result.successful:
            raise RuntimeError(f"/{robot}/motor_boards refused setpoint_wait_s {wait_s}: {result.reason}")
    result = graph.probe.set_parameter("/plant", "lockstep_timeout_s", 2.0 * wait_s, timeout_s=60.0)
    if not result.successful:
        raise RuntimeError(f"/plant refused lockstep_timeout_s {2.0 * wait_s}: {result.reason}")


class _Probe:
    def __init__(self, domain_id: int) -> None:
        import rclpy
        from rclpy.context import Context

        from erforce_interfaces.runtime.executor import (
            DirectExecutor,  # spun by hand; serves callbacks that take the info
        )

        self.context = Context()
        rclpy.init(context=self.context, domain_id=domain_id)
        self.node = rclpy.create_node(f"test_probe_{os.getpid()}", context=self.context)
        self.executor = DirectExecutor(context=self.context)
        self.executor.add_node(self.node)
        self._publishers: dict[tuple[str, type], Any] = {}

    def spin_until(self, condition: Callable[[], bool], timeout_s: float, what: str = "condition") -> None:
        deadline = time.monotonic() + timeout_s
        while not condition():
            if time.monotonic() > deadline:
                raise TimeoutError(f"{what} not reached within {timeout_s} s")
            self.executor.spin_once(timeout_sec=0.02)

    def spin_for(self, duration_s: float) -> None:
        deadline = time.monotonic() + duration_s
        while time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=min(0.02, max(0.0, deadline - time.monotonic())))

    def subscribe(self, topic: str, msg_type: type, qos=None) -> list:
        from erforce_interfaces.wire.contract import QOS_STATE

        received: list = []
        self.node.create_subscription(msg_type, topic, received.append, qos or QOS_STATE)
        return received

    def wait_for_message(self, topic: str, msg_type: type, timeout_s: float, qos=None,
                         predicate: Callable[[Any], bool] | None = None):
        received = self.subscribe(topic, msg_type, qos)
        match: list = []

        def found() -> bool:
            while received:
                msg = received.pop(0)
                if predicate is None or predicate(msg):
                    match.append(msg)
                    return True
            return False

        self.spin_until(found, timeout_s, f"a message on {topic}")
        return match[0]

    def publisher(self, topic: str, msg_type: type, qos=None):
        from erforce_interfaces.wire.contract import QOS_COMMAND

        key = (topic, msg_type)
        if key not in self._publishers:
            self._publishers[key] = self.node.create_publisher(msg_type, topic, qos or QOS_COMMAND)
        return self._publishers[key]

    def wait_for_subscribers(self, topic: str, msg_type: type, count: int = 1, timeout_s: float = 10.0,
                             qos=None) -> Any:
        """The probe's publisher on ``topic`` once ``count`` readers of other nodes have matched it.

        The probe's own readers of the topic (a test watching it) match its writer too and are not
        counted: counting them let a test publish before the node under test had been discovered,
        which here sometimes takes over a second.
        """
        pub = self.publisher(topic, msg_type, qos)
        own = sum(1 for sub in self.node.subscriptions if sub.topic_name == pub.topic_name)
        self.spin_until(lambda: pub.get_subscription_count() - own >= count, timeout_s,
                        f"{count} subscriber(s) on {topic} besides the probe's own {own}")
        return pub

    def set_parameter(self, node_name: str, name: str, value: Any, timeout_s: float = 10.0):
        """Set one parameter of a remote node (``/robot_0/motor_boards``); returns SetParametersResult."""
        from rcl_interfaces.srv import SetParameters
        from rclpy.parameter import Parameter

        client = self.node.create_client(SetParameters, f"{node_name}/set_parameters")
        try:
            self.spin_until(client.service_is_ready, timeout_s, f"{node_name}/set_parameters")
            request = SetParameters.Request(parameters=[Parameter(name, value=value).to_parameter_msg()])
            future = client.call_async(request)
            self.spin_until(future.done, timeout_s, f"{node_name}/set_parameters answer")
            return future.result().results[0]
        finally:
            self.node.destroy_client(client)

    def get_parameter(self, node_name: str, name: str, timeout_s: float = 10.0):
        """The current value of a remote node's parameter (Python value)."""
        from rcl_interfaces.srv import GetParameters
        from rclpy.parameter import parameter_value_to_python

        client = self.node.create_client(GetParameters, f"{node_name}/get_parameters")
        try:
            self.spin_until(client.service_is_ready, timeout_s, f"{node_name}/get_parameters")
            future = client.call_async(GetParameters.Request(names=[name]))
            self.spin_until(future.done, timeout_s, f"{node_name}/get_parameters answer")
            return parameter_value_to_python(future.result().values[0])
        finally:
            self.node.destroy_client(client)

    def close(self) -> None:
        import rclpy

        self.executor.shutdown(timeout_sec=1.0)
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)


# ------------------------------------------------------------- pytest plugin
def show_outputs_if_failed(graph: RosGraph, request) -> None:
    """After a failed test (``request`` of a pytest fixture), the tail of each process's output on stderr."""
    report = getattr(request.node, "rep_call", None)
    if report is not None and report.failed:
        show_outputs(graph)


def show_outputs(graph: RosGraph) -> None:
    """The tail of each process's output on stderr."""
    for proc in graph.processes:
        sys.stderr.write(f"\n----- output of {proc.name} ({' '.join(proc.cmd)}) -----\n")
        sys.stderr.write(proc.output()[-4000:])


try:
    import pytest
except ImportError:  # pragma: no cover - the harness is also usable without pytest
    pytest = None

if pytest is not None:

    def pytest_configure(config) -> None:
        """The probes in this process use the stack's DDS profile too (Fast DDS reads it once, at the
        process's first participant): a new node is matched quickly only if both sides announce often."""
        from erforce_interfaces.wire.contract import dds_profile_env

        os.environ.update(dds_profile_env())

    @pytest.fixture
    def ros_graph(tmp_path: Path, request) -> Iterator[RosGraph]:
        """A private DDS domain with its node processes; logs are shown when the test fails."""
        graph = RosGraph(workdir=tmp_path / "graph")
        try:
            yield graph
        finally:
            graph.close()
            show_outputs_if_failed(graph, request)
        report = getattr(request.node, "rep_call", None)
        faults = graph.unexpected_callback_faults()
        if faults and report is not None and report.passed:
            pytest.fail("a node dropped a message in its callback guard (a bug, or bad input the test does not "
                        "declare with ros_graph.expect_callback_faults):\n" + "\n".join(faults[:20]), pytrace=False)

    def _shared_ros_graph(tmp_path_factory, request, fixture: str) -> Iterator[RosGraph]:
        """One ``ros_graph`` for the tests of a wider scope (``fixture`` names it in the messages)."""
        graph = RosGraph(workdir=tmp_path_factory.mktemp("graph"))
        failed_before = request.session.testsfailed
        try:
            yield graph
        finally:
            graph.close()
            failed = request.session.testsfailed > failed_before
            if failed:
                show_outputs(graph)
        faults = graph.unexpected_callback_faults()
        if faults and not failed:
            pytest.fail("a node dropped a message in its callback guard (a bug, or bad input the tests do not "
                        f"declare with {fixture}.expect_callback_faults):\n" + "\n".join(faults[:20]),
                        pytrace=False)

    @pytest.fixture(scope="module")
    def module_ros_graph(tmp_path_factory, request) -> Iterator[RosGraph]:
        """One ``ros_graph`` for every test of a module that takes it, for tests that share one started graph
        (it costs seconds to tens of seconds to start) and leave it as the next test can use it. Logs are
        shown when a test of the module failed; undeclared callback faults fail the module's last test."""
        yield from _shared_ros_graph(tmp_path_factory, request, "module_ros_graph")

    @pytest.fixture(scope="class")
    def class_ros_graph(tmp_path_factory, request) -> Iterator[RosGraph]:
        """``module_ros_graph`` for the tests of one class: a module whose tests need two different graphs
        groups them in two classes, and only one graph runs at a time (the first closes after its class)."""
        yield from _shared_ros_graph(tmp_path_factory, request, "class_ros_graph")

    @pytest.hookimpl(tryfirst=True, hookwrapper=True)
    def pytest_runtest_makereport(item, call):
        outcome = yield
        rep = outcome.get_result()
        setattr(item, "rep_" + rep.when, rep)
