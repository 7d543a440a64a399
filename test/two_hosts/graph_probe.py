"""The probe of test_two_hosts.py: a small rclpy process run inside the "ai" network namespace.

The pytest process itself stays in the host's namespace, where DDS must not talk, so everything
that listens to the graph runs as its own process under ``ip netns exec``:

    graph_probe.py nodes --expect /robot_0/motor_boards,/robot_0/velocity_controller --within 20
        waits until all expected nodes are discovered or the time is up, then prints one JSON
        line {"seen": [...], "missing": [...], "elapsed_s": ...};
    graph_probe.py watch --robot 0
        until SIGINT/SIGTERM, prints one JSON line per kick event on /sim/events and per change of
        /robot_<id>/ball_detected (the light barrier), each with the simulated time of /clock; at
        the end one line with the number of distinct ticks answered on /robot_<id>/motor_duty that
        reached this namespace (a best-effort reader: a lower bound).
"""

from __future__ import annotations

import argparse
import json
import signal
import sys
import time

import rclpy
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Bool, String

from erforce_interfaces.wire import contract
from erforce_interfaces.wire.conversions import stamp_to_nanoseconds, stamp_to_seconds


def _emit(record: dict) -> None:
    print(json.dumps(record), flush=True)


def discovered_nodes(node) -> set[str]:
    return {f"{ns.rstrip('/')}/{name}" for name, ns in node.get_node_names_and_namespaces()}


def run_nodes(node, executor, expected: set[str], within_s: float) -> int:
    seen: set[str] = set()
    start = time.monotonic()
    while time.monotonic() - start < within_s:
        executor.spin_once(timeout_sec=0.05)
        seen |= discovered_nodes(node)
        if expected <= seen:
            break
    _emit({"seen": sorted(seen), "missing": sorted(expected - seen), "elapsed_s": time.monotonic() - start})
    return 0


def run_watch(node, executor, robot_id: int) -> int:
    sim = {"t_s": -1.0}
    barrier: dict[str, bool | None] = {"value": None}

    def on_clock(msg: Clock) -> None:
        sim["t_s"] = stamp_to_seconds(msg.clock)

    def on_event(msg: String) -> None:
        if "kick" in msg.data:
            _emit({"kind": "kick", "sim_s": sim["t_s"], "text": msg.data})

    def on_barrier(msg: Bool) -> None:
        if bool(msg.data) != barrier["value"]:
            barrier["value"] = bool(msg.data)
            _emit({"kind": "barrier", "sim_s": sim["t_s"], "value": bool(msg.data)})

    node.create_subscription(Clock, contract.CLOCK.name, on_clock, contract.QOS_CLOCK)
    node.create_subscription(String, contract.SIM_EVENTS.name, on_event, contract.SIM_EVENTS.qos)
    node.create_subscription(Bool, contract.BALL_DETECTED.for_robot(robot_id), on_barrier,
                             contract.BALL_DETECTED.qos)
    # best effort: counting must not slow down the lockstep loop with a second reliable reader
    duty_ticks: set[int] = set()
    node.create_subscription(JointState, contract.MOTOR_DUTY.for_robot(robot_id),
                             lambda m: duty_ticks.add(stamp_to_nanoseconds(m.header.stamp)),
                             QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=50,
                                        reliability=ReliabilityPolicy.BEST_EFFORT))
    stop = {"now": False}
    signal.signal(signal.SIGTERM, lambda *_: stop.update(now=True))
    _emit({"kind": "ready"})
    try:
        while not stop["now"]:
            executor.spin_once(timeout_sec=0.05)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    _emit({"kind": "end", "sim_s": sim["t_s"], "duty_ticks": len(duty_ticks)})
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="mode", required=True)
    nodes = sub.add_parser("nodes", help="wait for nodes to be discovered")
    nodes.add_argument("--expect", required=True, help="comma-separated full node names")
    nodes.add_argument("--within", type=float, required=True, help="seconds to wait at most")
    watch = sub.add_parser("watch", help="print kick events and light-barrier changes")
    watch.add_argument("--robot", type=int, default=0)
    args = parser.parse_args(argv)

    rclpy.init()
    node = rclpy.create_node(f"two_hosts_probe_{args.mode}")
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    try:
        if args.mode == "nodes":
            return run_nodes(node, executor, set(filter(None, args.expect.split(","))), args.within)
        return run_watch(node, executor, args.robot)
    finally:
        executor.shutdown(timeout_sec=1.0)
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == "__main__":
    sys.exit(main())
