"""Issue 36: with the default discovery range (LOCALHOST) the graph listens on this computer only.

The demo graph as launched with SSL vision (the plant's cameras, ssl_vision_bridge in its own process, the
ball predictor, a receiver), the field view, ssl_vision_bridge with its default interface and ssl_sim_bridge
in both protocols: every UDP socket and every listening TCP socket of every process is bound to an address
in 127.0.0.0/8 (read from /proc: each process's socket inodes in /proc/<pid>/net/{udp,udp6,tcp,tcp6}).
A socket bound to a multicast group is SSL-Vision's, not DDS's: the group was joined on the interface its
node's ``interface`` parameter names, which must be loopback (the default included).
"""

from __future__ import annotations

import ipaddress
import socket
from pathlib import Path

import pytest
from faults_support import DEMO_LAUNCH, LaunchedDemo

from erforce_interfaces.tools.testing import listening_sockets, on_loopback, proc_net_address

pytestmark = pytest.mark.integration


def test_address_decoding_of_proc_net():
    # /proc/net/udp on a little-endian host: 127.0.0.1 is 0100007F; udp6's ::1 the last word 01000000
    assert proc_net_address("0100007F" if socket.htonl(1) != 1 else "7F000001") == "127.0.0.1"
    assert proc_net_address("00000000000000000000000001000000" if socket.htonl(1) != 1 else "0" * 31 + "1") == "::1"
    assert on_loopback("127.0.0.1") and on_loopback("127.3.2.1") and on_loopback("::1")
    assert on_loopback("::ffff:127.0.0.1")
    assert not on_loopback("0.0.0.0") and not on_loopback("192.0.2.2") and not on_loopback("::")


def _node_name(pid: int) -> str:
    """The node's name from its command line (``__node:=``), else its executable's name."""
    argv = [a.decode() for a in Path(f"/proc/{pid}/cmdline").read_bytes().split(b"\0") if a]
    named = [a.split(":=", 1)[1] for a in argv if a.startswith("__node:=")]
    return named[-1] if named else Path(argv[1] if len(argv) > 1 and "python" in argv[0] else argv[0]).name


def _free_port(kind: int) -> int:
    with socket.socket(socket.AF_INET, kind) as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def test_every_socket_of_the_graph_is_on_loopback(ros_graph):
    vision_port = _free_port(socket.SOCK_DGRAM)
    demo = LaunchedDemo(ros_graph, DEMO_LAUNCH, standby=False, vision="ssl", ssl_vision_process="own",
                        ssl_vision_port=str(vision_port))
    ros_graph.start_node("erforce_sim", "field_view", params={"port": 0, "use_sim_time": True})
    # the defaults but the ports: nothing of another test on this machine is reached
    ros_graph.start_node("erforce_ball_model", "ssl_vision_bridge", name="ssl_vision_bridge_default",
                         params={"port": _free_port(socket.SOCK_DGRAM)})
    for protocol in ("ssl", "grsim"):
        ros_graph.start_node("erforce_sim", "ssl_sim_bridge", name=f"ssl_sim_bridge_{protocol}",
                             params={"protocol": protocol, "command_port": _free_port(socket.SOCK_DGRAM),
                                     "control_port": 0, "grsim_status_port": _free_port(socket.SOCK_DGRAM)})
    demo.wait_running()
    nodes = ("plant", "ssl_vision_bridge", "ball_predictor", "field_view", "ssl_vision_bridge_default",
             "ssl_sim_bridge_ssl", "ssl_sim_bridge_grsim")
    ros_graph.spin_until(lambda: set(nodes) <= set(ros_graph.probe.node.get_node_names()), 60.0,
                         "every node in the graph")

    dds_ports = range(7400 + 250 * ros_graph.domain_id, 7400 + 250 * (ros_graph.domain_id + 1))
    by_node: dict[str, list[tuple[str, str, int]]] = {}
    for pid in ros_graph.pids():
        try:
            by_node.setdefault(f"{_node_name(pid)}/{pid}", []).extend(listening_sockets(pid))
        except (FileNotFoundError, ProcessLookupError):
            continue  # ended meanwhile (chrt, a launcher's helper)
    outside, groups = [], []
    for node, sockets in by_node.items():
        for table, address, port in sockets:
            if ipaddress.ip_address(address).is_multicast:
                groups.append((node.split("/")[0], address, port))
            elif not on_loopback(address):
                outside.append(f"{node}: {table} {address}:{port}")
    assert not outside, "sockets outside 127.0.0.0/8:\n" + "\n".join(outside)

    # The check saw the sockets it is about: every node's DDS participant (its ports of this domain), and
    # the two SSL-Vision listeners.
    for name in nodes:
        mine = [s for node, sockets in by_node.items() if node.split("/")[0] == name for s in sockets]
        assert any(port in dds_ports for _, _, port in mine), f"{name}: no DDS socket found: {mine}"
    assert sorted(g[0] for g in groups) == ["ssl_vision_bridge", "ssl_vision_bridge_default"], groups
    for name, _, _ in groups:
        interface = ros_graph.probe.get_parameter(f"/{name}", "interface")
        assert on_loopback(interface), f"{name} joined SSL-Vision's group on {interface}"
