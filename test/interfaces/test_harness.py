"""The harness itself: messages cross DDS between processes, domains are isolated, children are reaped."""

import os
import signal
import subprocess
import sys
import textwrap
import time

import pytest
from std_msgs.msg import String

from erforce_interfaces.tools.processes import DomainLease
from erforce_interfaces.tools.testing import RosGraph
from erforce_interfaces.wire.contract import QOS_COMMAND

pytestmark = pytest.mark.integration


def test_message_crosses_dds_from_a_node_process(ros_graph):
    ros_graph.start_node("erforce_interfaces", "talker", params={"rate_hz": 20.0, "text": "ping"})
    msg = ros_graph.wait_for_message("/chatter", String, timeout_s=15.0, qos=QOS_COMMAND)
    assert msg.data.startswith("ping ")


def test_wait_for_subscribers_does_not_count_the_probes_own_reader(ros_graph):
    """A test that watches a topic it publishes on must still wait for the node under test."""
    ros_graph.subscribe("/chatter", String, QOS_COMMAND)  # the probe's own reader matches its writer
    with pytest.raises(TimeoutError):
        ros_graph.probe.wait_for_subscribers("/chatter", String, timeout_s=1.0)
    ros_graph.start_node("erforce_interfaces", "listener")
    pub = ros_graph.probe.wait_for_subscribers("/chatter", String, timeout_s=15.0)
    assert pub.get_subscription_count() == 2  # the listener and the probe's own reader


def test_a_restarted_node_is_matched_within_two_seconds(ros_graph):
    """With Fast DDS's default 3 s announcements a node that (re)started was matched only at the
    running ones' next announcement: 8 of 12 starts took 1.6-2.9 s here. The stack's profile
    (config/fastdds_localhost.xml, announcements every 0.5 s) is in the harness's environment."""
    assert ros_graph.env["FASTRTPS_DEFAULT_PROFILES_FILE"].endswith("config/fastdds_localhost.xml")
    pub = ros_graph.probe.publisher("/chatter", String, QOS_COMMAND)
    for _ in range(5):
        started = time.monotonic()
        listener = ros_graph.start_node("erforce_interfaces", "listener")
        ros_graph.probe.spin_until(lambda: pub.get_subscription_count() == 1, 10.0, "the listener matched")
        assert time.monotonic() - started < 2.0  # process start (~0.4 s) and discovery
        listener.signal(signal.SIGINT)
        ros_graph.probe.spin_until(lambda proc=listener: not proc.alive() and pub.get_subscription_count() == 0,
                                   30.0, "the listener gone")


def _dds_shared_memory(pid: int) -> list[str]:
    with open(f"/proc/{pid}/maps") as maps:
        return sorted({line.split()[-1] for line in maps if "/dev/shm/fastrtps_" in line})


def test_a_node_killed_and_restarted_hears_again_every_time_over_udp_alone(ros_graph):
    """Over Fast DDS's shared memory a restarted reader takes the dead one's port, and the running writers
    could keep writing into the old segment: matched, yet deaf for good (about one restart in ten of the
    fault tests' motor boards). The stack's nodes talk over UDP on localhost instead: no node maps a Fast DDS
    shared-memory segment, and a listener killed six times hears the running talker after each restart."""
    talker = ros_graph.start_node("erforce_interfaces", "talker", params={"rate_hz": 50.0, "text": "still-here"})
    for _ in range(6):
        listener = ros_graph.start_node("erforce_interfaces", "listener")
        listener.wait_for_output(r"I heard: still-here", 20.0)
        assert _dds_shared_memory(listener.pid) == [] and _dds_shared_memory(talker.pid) == []
        listener.signal(signal.SIGKILL)
        listener.wait_exit(10.0)


def test_two_concurrent_domains_do_not_cross_talk(tmp_path):
    with RosGraph(tmp_path / "a") as a, RosGraph(tmp_path / "b") as b:
        assert a.domain_id != b.domain_id
        a.start_node("erforce_interfaces", "talker", params={"rate_hz": 50.0, "text": "from-a"})
        b.start_node("erforce_interfaces", "talker", params={"rate_hz": 50.0, "text": "from-b"})
        got_a = a.subscribe("/chatter", String, QOS_COMMAND)
        got_b = b.subscribe("/chatter", String, QOS_COMMAND)
        a.probe.spin_until(lambda: len(got_a) >= 20, 15.0, "20 messages in domain a")
        b.probe.spin_until(lambda: len(got_b) >= 20, 15.0, "20 messages in domain b")
        a.probe.spin_for(0.5)
        b.probe.spin_for(0.5)
        assert {m.data.split()[0] for m in got_a} == {"from-a"}
        assert {m.data.split()[0] for m in got_b} == {"from-b"}


def test_domain_leases_are_exclusive_across_processes(tmp_path):
    """A second test session (another process) never gets a domain this one holds."""
    held = [DomainLease(tmp_path) for _ in range(3)]
    try:
        code = textwrap.dedent(f"""
            from pathlib import Path
            from erforce_interfaces.tools.processes import DomainLease
            print(DomainLease(Path({str(tmp_path)!r})).domain_id)
        """)
        out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=30)
        other = int(out.stdout.strip())
        assert other not in {lease.domain_id for lease in held}
        assert len({lease.domain_id for lease in held}) == 3
    finally:
        for lease in held:
            lease.release()


def test_close_reaps_children_even_when_they_ignore_sigint(tmp_path):
    stubborn = (
        "import signal, time; signal.signal(signal.SIGINT, signal.SIG_IGN); print('up', flush=True); time.sleep(600)"
    )
    graph = RosGraph(tmp_path / "g")
    proc = graph.start([sys.executable, "-c", stubborn], name="stubborn")
    proc.wait_for_output("up", timeout_s=10.0)
    graph.close()
    assert proc.popen.poll() is not None
    with pytest.raises(ProcessLookupError):
        os.kill(proc.pid, 0)


BUGGY_NODE = textwrap.dedent("""\
    import sys
    from rclpy.node import Node
    from std_msgs.msg import String
    from erforce_interfaces.runtime.node_support import run_node

    class Buggy(Node):
        def __init__(self):
            super().__init__("buggy")
            self.create_subscription(String, "/buggy", self.on_text, 10)
            self.echo = self.create_publisher(String, "/buggy_echo", 10)

        def on_text(self, msg):
            if msg.data == "bad":
                raise KeyError("a bug of ours")
            self.echo.publish(msg)

    sys.exit(run_node(Buggy))
""")


def test_a_callback_fault_keeps_the_node_alive_and_fails_the_test_unless_declared(tmp_path):
    """node_support.guard_callbacks in a node process, and the harness's check: a message that raises in
    a callback is dropped with a warning and the node goes on; the fixture fails a test whose processes
    logged such a warning unless the test declared it."""
    graph = RosGraph(tmp_path / "g")
    try:
        node = graph.start([sys.executable, "-c", BUGGY_NODE], name="buggy")
        echoes = graph.subscribe("/buggy_echo", String, QOS_COMMAND)
        pub = graph.probe.wait_for_subscribers("/buggy", String, timeout_s=20.0, qos=QOS_COMMAND)
        graph.probe.spin_until(lambda: graph.probe.node.count_publishers("/buggy_echo") > 0, 20.0, "echo publisher")
        assert graph.unexpected_callback_faults() == []
        pub.publish(String(data="bad"))
        pub.publish(String(data="good"))
        graph.probe.spin_until(lambda: [m.data for m in echoes] == ["good"], 20.0, "the echo after the bad message")
        assert node.alive()
        node.wait_for_output(r"callback fault on /buggy: KeyError: 'a bug of ours' at <string>:\d+ in on_text; "
                             "message dropped", timeout_s=5.0)
        (fault,) = graph.unexpected_callback_faults()
        assert fault.startswith("buggy: ") and "KeyError" in fault
        graph.expect_callback_faults("buggy")
        assert graph.unexpected_callback_faults() == []
    finally:
        graph.close()


def test_a_wait_on_a_launch_whose_nodes_cannot_start_fails_at_once_naming_what_is_missing(ros_graph, tmp_path):
    """A tool that starts a graph (bench_lockstep --launch-runs) must not wait out its deadline for a graph
    that never comes: every command of this launch names a launch prefix that does not exist."""
    launch_file = tmp_path / "missing.launch.yaml"
    launch_file.write_text(textwrap.dedent("""\
        launch:
          - node: {pkg: erforce_interfaces, exec: talker, name: a, launch-prefix: /nonexistent/erforce-realtime}
          - node: {pkg: erforce_interfaces, exec: listener, name: b, launch-prefix: /nonexistent/erforce-realtime}
        """))
    launch = ros_graph.start_launch(launch_file)
    # at the first failure line (the second may not be written yet)
    with pytest.raises(RuntimeError, match=r"process\(es\) failed to start(.|\n)*/nonexistent/erforce-realtime"):
        ros_graph.spin_until(lambda: False, 600.0, "the graph")
    assert launch.wait_exit(30.0) != 0  # the launcher says so too


def test_a_launch_that_ends_with_an_error_fails_the_wait(ros_graph, tmp_path):
    launch_file = tmp_path / "broken.launch.yaml"
    launch_file.write_text("launch:\n  - node: {pkg: erforce_interfaces, exec: no_such_executable}\n")
    ros_graph.start_launch(launch_file)
    with pytest.raises(RuntimeError, match="ended with exit code .*\n(.|\n)*no_such_executable"):
        ros_graph.spin_until(lambda: False, 600.0, "the graph")
