"""Issue 6, deliverable 5 "Two hosts": robot and AI computer as two network namespaces on a veth.

The robot-side nodes (robot_0's velocity_controller and motor_boards, launch/robot.launch.yaml)
run in the namespace "robot"; the rest of the demo graph (plant, ball_predictor, catcher, the
demo director and its recorder, launched by ``erforce_sim.demo.demo --no-robot-side``, which passes
``robot_side:=false`` to demo.launch.yaml) and this test's probe run in the namespace "ai". The two
are joined by a veth pair, 10.213.0.1/30 (robot) <-> 10.213.0.2/30 (ai); those addresses exist
only inside the two namespaces, and the pytest process itself sends nothing (it stays in the
host's namespace and only runs ``ip``). DDS goes over UDP only:

- a Fast DDS XML profile (default participant profile) with one UDPv4 user transport and no
  builtin transports, so no shared memory; Jazzy's Fast DDS 2.14 reads it from
  FASTRTPS_DEFAULT_PROFILES_FILE (FASTDDS_DEFAULT_PROFILES_FILE is set too, for Fast DDS 3);
- ROS_AUTOMATIC_DISCOVERY_RANGE=SUBNET and ROS_STATIC_PEERS=<the other end's address>. Checked
  here: the namespaces have no multicast route; with the UDP-only profile multicast discovery
  still crossed the veth in a quick check (Fast DDS sends multicast out of every interface), but
  static peers (unicast, as for a robot on WiFi) keep the test independent of that;
- each side gets its own DDS domain id lease (erforce_interfaces.tools.testing.RosGraph), so nothing
  else on the machine can join even by accident.

What the test checks:

1. the robot-side nodes are discovered from the ai namespace (probe, positive control), also by
   a second, fresh probe once they run (here within one 3 s announcement period of Fast DDS);
2. negative control: with the veth down, a third fresh probe in "ai" does NOT discover them within
   a window of at least 8 s and twice the second probe's discovery time, so no other path (shared
   memory, the host's loopback) connects the two sides;
3. with the veth up again, the demo plays its first two scenes, Fig. 6 and a 1.0 m/s kick by
   robot_1 towards robot_0; the demo's table says the kick was caught, and the probe independently
   sees the kick fire and robot_0's light barrier rise after it (the Fig. 6 scene is played but
   not judged here: the catch quality is the demo's own test, this one is about the transport);
4. the lockstep control traffic crossed the veth: for every tick whose motor_duty answer the probe
   received in "ai" (N, counted by stamp), the robot had received that tick's wheel_states and
   sent the duty, so the robot end's byte counters must have grown by at least N x 4 doubles in
   each direction; every DDS process maps no Fast DDS shared-memory segment; and the robot-side
   and ai-side processes really sit in their namespaces (/proc/PID/ns/net).

Teardown always runs (a fixture with finally): all processes are stopped (SIGINT, SIGTERM, SIGKILL,
then anything still carrying the graph's tag), then both namespaces are deleted, which destroys
the veth pair.

Run by hand (root, Linux; skipped otherwise, and when ``ip netns add`` is refused):

    cd /work/main && .venv/bin/python -m pytest test/two_hosts -v -s

The same setup step by step in a root shell (DOMAIN: any free domain id):

    .venv/bin/python -c "import sys, pathlib; sys.path.insert(0, 'test/two_hosts'); import test_two_hosts as t; \
        t.write_udp_only_profile(pathlib.Path('/tmp/udp_only.xml'))"
    ip netns add robot && ip netns add ai
    ip link add veth-robot netns robot type veth peer name veth-ai netns ai
    ip -n robot addr add 10.213.0.1/30 dev veth-robot && ip -n ai addr add 10.213.0.2/30 dev veth-ai
    for ns in robot ai; do ip -n $ns link set lo up; done
    ip -n robot link set veth-robot up && ip -n ai link set veth-ai up && sleep 1   # see wait_links_running
    export FASTRTPS_DEFAULT_PROFILES_FILE=/tmp/udp_only.xml ROS_AUTOMATIC_DISCOVERY_RANGE=SUBNET ROS_DOMAIN_ID=DOMAIN
    ROS_STATIC_PEERS=10.213.0.2 ip netns exec robot .venv/bin/erforce-launch \\
        src/erforce_motion/launch/robot.launch.yaml robot:=robot_0 &
    ROS_STATIC_PEERS=10.213.0.1 ip netns exec ai .venv/bin/python -m erforce_sim.demo.demo \
        --no-robot-side --scenes 2
    kill %1; ip netns del robot; ip netns del ai
"""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time
import uuid
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

from erforce_interfaces.tools.testing import NodeProcess, RosGraph, show_outputs_if_failed

pytestmark = [pytest.mark.integration, pytest.mark.root]

REPO = Path(__file__).resolve().parents[2]
ROBOT_LAUNCH = REPO / "src" / "erforce_motion" / "launch" / "robot.launch.yaml"
PROBE = Path(__file__).resolve().with_name("graph_probe.py")

ROBOT_IP, AI_IP, PREFIX_LEN = "10.213.0.1", "10.213.0.2", 30
ROBOT_DEV, AI_DEV = "veth-robot", "veth-ai"
ROBOT_NODES = ("/robot_0/motor_boards", "/robot_0/velocity_controller")
WHEEL_PAYLOAD_BYTES = 4 * 8  # 4 wheels x one float64: the least a duty or wheel-state message carries
NEGATIVE_WINDOW_S = 8.0  # > two of Fast DDS's 3 s participant announcement periods
ROBOT_SIDE = re.compile(r"velocity_controller|motor_boards|robot\.launch\.yaml")
KICK_ROW = re.compile(r"^\s*2 kick 1\.0 m/s straight.*\s(yes|no)\s*$", re.MULTILINE)


def write_udp_only_profile(path: Path) -> Path:
    """Fast DDS XML: the default participant uses one UDPv4 transport and no builtin (SHM) ones."""
    path.write_text(
        """<?xml version="1.0" encoding="UTF-8"?>
<dds xmlns="http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles">
  <profiles>
    <transport_descriptors>
      <transport_descriptor>
        <transport_id>udpv4_only</transport_id>
        <type>UDPv4</type>
      </transport_descriptor>
    </transport_descriptors>
    <participant profile_name="udpv4_only_participant" is_default_profile="true">
      <rtps>
        <userTransports>
          <transport_id>udpv4_only</transport_id>
        </userTransports>
        <useBuiltinTransports>false</useBuiltinTransports>
      </rtps>
    </participant>
  </profiles>
</dds>
"""
    )
    return path


def _ip(*args: str, check: bool = True) -> subprocess.CompletedProcess:
    result = subprocess.run(["ip", *args], capture_output=True, text=True, timeout=20)
    if check and result.returncode != 0:
        raise RuntimeError(f"ip {' '.join(args)} failed ({result.returncode}): {result.stderr.strip()}")
    return result


def netns_unavailable_reason() -> str | None:
    """Why this machine cannot run the test, or None."""
    if not sys.platform.startswith("linux"):
        return "network namespaces are Linux only"
    if os.geteuid() != 0:
        return "needs root: creates two network namespaces and a veth pair (run the suite as root)"
    if shutil.which("ip") is None:
        return "iproute2's `ip` is not installed"
    name = f"erf2h-check-{os.getpid()}-{uuid.uuid4().hex[:6]}"
    result = subprocess.run(["ip", "netns", "add", name], capture_output=True, text=True, timeout=20)
    if result.returncode != 0:
        return f"`ip netns add` is not permitted here: {result.stderr.strip() or result.returncode}"
    subprocess.run(["ip", "netns", "del", name], capture_output=True, timeout=20)
    return None


def wait_links_running(links, timeout_s: float = 10.0) -> None:
    """Wait until each (namespace, device) has operstate UP.

    Fast DDS lists the interfaces once, when a participant is created. Participants started at
    once after ``ip link set up`` sometimes (2 of 8 tries) never found the other side and had no
    socket on the veth address; after this wait (and also with the robot side 3 s ahead) every
    try found it. The kernel reports carrier asynchronously (linkwatch), hence the wait.
    """
    deadline = time.monotonic() + timeout_s
    for ns, dev in links:
        while json.loads(_ip("-n", ns, "-j", "link", "show", "dev", dev).stdout)[0].get("operstate") != "UP":
            if time.monotonic() > deadline:
                raise TimeoutError(f"{dev} in {ns} did not come up within {timeout_s} s")
            time.sleep(0.05)


@dataclass
class TwoHosts:
    """Two namespaces joined by a veth pair, and a RosGraph that owns every process in them."""

    robot_ns: str
    ai_ns: str
    graph: RosGraph
    workdir: Path
    profile: Path

    def env_for(self, ns: str) -> dict[str, str]:
        peer = AI_IP if ns == self.robot_ns else ROBOT_IP
        return {
            "RMW_IMPLEMENTATION": "rmw_fastrtps_cpp",
            "FASTRTPS_DEFAULT_PROFILES_FILE": str(self.profile),  # Fast DDS 2.x (Jazzy)
            "FASTDDS_DEFAULT_PROFILES_FILE": str(self.profile),  # Fast DDS 3.x
            "ROS_AUTOMATIC_DISCOVERY_RANGE": "SUBNET",
            "ROS_STATIC_PEERS": peer,
            "ROS_LOG_DIR": str(self.workdir / "ros_log"),
        }

    def start_in(self, ns: str, cmd: list[str], name: str) -> NodeProcess:
        return self.graph.start(["ip", "netns", "exec", ns, *cmd], name=name, env=self.env_for(ns))

    def probe_nodes(self, expected: tuple[str, ...], within_s: float) -> dict:
        proc = self.start_in(self.ai_ns, [sys.executable, str(PROBE), "nodes", "--expect", ",".join(expected),
                                          "--within", str(within_s)], name="probe-nodes")
        proc.wait_exit(timeout_s=within_s + 30.0)
        lines = [line for line in proc.output().splitlines() if line.startswith("{")]
        assert lines, f"probe printed no result:\n{proc.output()[-3000:]}"
        return json.loads(lines[-1])

    def set_link(self, up: bool) -> None:
        _ip("-n", self.ai_ns, "link", "set", AI_DEV, "up" if up else "down")
        _ip("-n", self.robot_ns, "link", "set", ROBOT_DEV, "up" if up else "down")
        if up:
            wait_links_running(((self.robot_ns, ROBOT_DEV), (self.ai_ns, AI_DEV)))

    def robot_link_stats(self) -> dict:
        """stats64 of the robot's veth end: {"rx": {"bytes", "packets", ...}, "tx": {...}}."""
        out = _ip("-n", self.robot_ns, "-s", "-j", "link", "show", "dev", ROBOT_DEV).stdout
        return json.loads(out)[0]["stats64"]

    def netns_inode(self, ns: str) -> int:
        return os.stat(f"/run/netns/{ns}").st_ino


@pytest.fixture
def two_hosts(tmp_path: Path, request) -> Iterator[TwoHosts]:
    reason = netns_unavailable_reason()
    if reason:
        pytest.skip(reason)
    token = f"{os.getpid()}-{uuid.uuid4().hex[:6]}"
    robot_ns, ai_ns = f"erf2h-{token}-robot", f"erf2h-{token}-ai"
    graph = None
    created: list[str] = []
    try:
        for ns in (robot_ns, ai_ns):
            _ip("netns", "add", ns)
            created.append(ns)
        # Both ends are created directly inside the namespaces: nothing appears in the host's.
        _ip("link", "add", ROBOT_DEV, "netns", robot_ns, "type", "veth", "peer", "name", AI_DEV, "netns", ai_ns)
        _ip("-n", robot_ns, "addr", "add", f"{ROBOT_IP}/{PREFIX_LEN}", "dev", ROBOT_DEV)
        _ip("-n", ai_ns, "addr", "add", f"{AI_IP}/{PREFIX_LEN}", "dev", AI_DEV)
        for ns, dev in ((robot_ns, ROBOT_DEV), (ai_ns, AI_DEV)):
            _ip("-n", ns, "link", "set", "lo", "up")
            _ip("-n", ns, "link", "set", dev, "up")
        wait_links_running(((robot_ns, ROBOT_DEV), (ai_ns, AI_DEV)))
        graph = RosGraph(workdir=tmp_path / "graph")
        graph.env.pop("ROS_LOCALHOST_ONLY", None)
        yield TwoHosts(robot_ns, ai_ns, graph, tmp_path, write_udp_only_profile(tmp_path / "udp_only.xml"))
    finally:
        if graph is not None:
            graph.close()
            show_outputs_if_failed(graph, request)
        for ns in created:
            _ip("netns", "del", ns, check=False)
        leftover = set(_ip("netns", "list", check=False).stdout.split()) & set(created)
        assert not leftover, f"network namespaces not deleted: {leftover}"


def _maps(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/maps").read_text()
    except OSError:
        return ""


def _cmdline(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
    except OSError:
        return ""


def _netns_of(pid: int) -> int | None:
    try:
        return os.stat(f"/proc/{pid}/ns/net").st_ino
    except OSError:
        return None


def _watch_records(proc: NodeProcess) -> list[dict]:
    return [json.loads(line) for line in proc.output().splitlines() if line.startswith("{")]


def test_demo_catches_a_kick_with_the_robot_on_another_host(two_hosts: TwoHosts) -> None:
    t0 = time.monotonic()
    h = two_hosts
    h.start_in(h.robot_ns, [str(Path(sys.executable).with_name("erforce-launch")), str(ROBOT_LAUNCH), "robot:=robot_0"],
               name="robot-side")

    # 1. positive control: the robot's nodes are seen from the ai namespace over the veth, first
    # while they start up, then by a fresh probe (the same situation as the negative control's)
    found = h.probe_nodes(ROBOT_NODES, within_s=30.0)
    assert not found["missing"], f"robot-side nodes not discovered over the veth: {found}"
    found = h.probe_nodes(ROBOT_NODES, within_s=10.0)
    assert not found["missing"], f"a fresh probe did not discover the robot-side nodes: {found}"
    discovery_s = found["elapsed_s"]

    # 2. negative control: veth down, a fresh probe must not find them in many discovery times
    h.set_link(up=False)
    try:
        window_s = max(NEGATIVE_WINDOW_S, 2 * discovery_s)
        cut = h.probe_nodes(ROBOT_NODES, within_s=window_s)
        assert cut["missing"] == sorted(ROBOT_NODES), f"robot-side nodes seen with the veth down: {cut}"
        assert cut["elapsed_s"] >= window_s - 0.5  # the probe really listened for the whole window
    finally:
        h.set_link(up=True)

    # 3. the demo (robot side left out) in the ai namespace, watched by an independent probe
    watch = h.start_in(h.ai_ns, [sys.executable, str(PROBE), "watch", "--robot", "0"], name="probe-watch")
    watch.wait_for_output(r'"kind": "ready"', timeout_s=30.0)
    stats_before = h.robot_link_stats()
    demo = h.start_in(h.ai_ns, [sys.executable, "-m", "erforce_sim.demo.demo", "--scenario", "scenes",
                                "--no-robot-side", "--scenes", "2",
                                "--out", str(h.workdir / "report")], name="demo")

    dds_pids_checked: dict[int, str] = {}
    deadline = time.monotonic() + 150.0
    while demo.alive() and time.monotonic() < deadline:
        if not dds_pids_checked and any(r.get("kind") == "kick" for r in _watch_records(watch)):
            # mid-run, every process of the two graphs is up: none may use Fast DDS shared memory
            for pid in h.graph.pids():
                maps = _maps(pid)
                if "libfastrtps" in maps:
                    dds_pids_checked[pid] = _cmdline(pid)
                    assert "/dev/shm/fastrtps_" not in maps, f"process {pid} uses DDS shared memory: {_cmdline(pid)}"
                    ns = h.robot_ns if ROBOT_SIDE.search(_cmdline(pid)) else h.ai_ns
                    assert _netns_of(pid) == h.netns_inode(ns), f"{_cmdline(pid)} is not in namespace {ns}"
        time.sleep(0.2)
    assert not demo.alive(), f"demo did not finish within 150 s:\n{demo.output()[-3000:]}"
    stats_after = h.robot_link_stats()
    watch.signal(signal.SIGINT)
    watch.wait_exit(timeout_s=10.0)

    out = demo.output()
    # exit code 1 only means the demo's overall score (all scenes) is low; a crash prints no report
    assert demo.popen.returncode in (0, 1) and "report: " in out, f"demo failed:\n{out[-4000:]}"
    row = KICK_ROW.search(out)
    assert row is not None, f"the kick scene was not played:\n{out[-4000:]}"
    assert row.group(1) == "yes", f"the kick was not caught:\n{row.group(0)}"

    # the probe's own view: robot_1's kick fired, then robot_0's light barrier rose
    records = _watch_records(watch)
    fired = [r for r in records if r["kind"] == "kick" and "robot_1 kick" in r["text"] and r["text"].endswith("fired")]
    assert fired, f"no fired kick seen by the probe: {records}"
    t_kick = fired[-1]["sim_s"]
    rises = [r for r in records if r["kind"] == "barrier" and r["value"] and r["sim_s"] > t_kick]
    assert rises, f"robot_0's light barrier did not rise after the kick at t={t_kick:.3f} s: {records}"

    # 4. the lockstep loop crossed the veth: both directions carried at least one duty payload per tick
    for name in ("velocity_controller", "motor_boards", "plant", "ball_predictor", "catcher",
                 "erforce_sim.demo.demo"):
        assert any(name in cmd for cmd in dds_pids_checked.values()), f"{name} not checked: {dds_pids_checked}"
    end = [r for r in records if r["kind"] == "end"]
    assert end, f"the probe did not report its duty count: {records[-3:]}"
    sim_s, duty_ticks = end[0]["sim_s"], end[0]["duty_ticks"]
    assert duty_ticks > 100, f"the probe saw only {duty_ticks} duty answers from robot_0"
    min_bytes = duty_ticks * WHEEL_PAYLOAD_BYTES
    sent = stats_after["tx"]["bytes"] - stats_before["tx"]["bytes"]
    received = stats_after["rx"]["bytes"] - stats_before["rx"]["bytes"]
    print(f"\ntwo hosts: discovery {discovery_s:.2f} s, negative window {window_s:.1f} s, sim {sim_s:.2f} s, "
          f"{duty_ticks} duty answers seen, "
          f"robot veth sent {sent / 1e6:.2f} MB received {received / 1e6:.2f} MB, "
          f"wall {time.monotonic() - t0:.1f} s")
    assert sent >= min_bytes, f"robot sent {sent} B over the veth, less than {min_bytes:.0f} B of duty payload"
    assert received >= min_bytes, f"robot received {received} B over the veth, less than {min_bytes:.0f} B"
    print("\n".join(line for line in out.splitlines() if re.match(r"^\s*(#|\d+) ", line)))
