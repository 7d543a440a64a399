"""Record every topic of a graph into a rosbag2 bag with MCAP storage, like ``ros2 bag record -a``.

The bag is a rosbag2 directory (metadata.yaml + .mcap), so ``ros2 bag info/play`` and
Foxglove open it. Messages are taken raw (CDR bytes, no deserialization), which keeps
recording a kilohertz control loop cheap. Log times are wall-clock time, or with
``use_sim_time`` the newest ``/clock`` (0 before the first), as ``ros2 bag record
--use-sim-time`` logs them. Command line: ``erforce-record OUTPUT_DIR [--use-sim-time] [--duration S]``.
"""

from __future__ import annotations

import argparse
import importlib
import sys
import time
from pathlib import Path

import rclpy
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore
from rosgraph_msgs.msg import Clock

from erforce_interfaces.contract import QOS_CLOCK
from erforce_interfaces.conversions import stamp_to_nanoseconds


def _message_class(type_name: str):
    pkg, _, name = type_name.split("/")
    return getattr(importlib.import_module(f"{pkg}.msg"), name)


class BagRecorder:
    """Subscribes to every topic as it appears and writes what arrives into ``path``."""

    def __init__(self, node: Node, path: str | Path, discovery_period_s: float = 0.5,
                 use_sim_time: bool = False) -> None:
        self.node = node
        self.path = Path(path)
        self._typestore = get_typestore(Stores.ROS2_JAZZY)
        self._writer = Writer(self.path, version=9, storage_plugin=StoragePlugin.MCAP)
        self._writer.open()
        self._connections: dict[str, object] = {}
        self._subscriptions = []
        self._sim_time_ns: int | None = 0 if use_sim_time else None
        self.counts: dict[str, int] = {}
        self._closed = False
        if use_sim_time:
            node.create_subscription(Clock, "/clock", self._on_clock, QOS_CLOCK)
        self._timer = node.create_timer(discovery_period_s, self.discover)
        self.discover()

    def _on_clock(self, msg: Clock) -> None:
        self._sim_time_ns = stamp_to_nanoseconds(msg.clock)

    def discover(self) -> None:
        for topic, types in self.node.get_topic_names_and_types():
            if topic in self._connections or not types or topic.startswith("/rosout") or "parameter_events" in topic:
                continue
            type_name = types[0]
            if type_name not in self._typestore.types:
                continue  # not a standard type: nothing of ours
            publishers = self.node.get_publishers_info_by_topic(topic)
            if not publishers:
                continue
            best_effort = any(p.qos_profile.reliability == ReliabilityPolicy.BEST_EFFORT for p in publishers)
            # deep queues: a recorder running at low priority catches up later instead of dropping
            qos = QoSProfile(depth=10000, reliability=ReliabilityPolicy.BEST_EFFORT if best_effort
                             else ReliabilityPolicy.RELIABLE)
            self._connections[topic] = self._writer.add_connection(topic, type_name, typestore=self._typestore)
            self.counts[topic] = 0
            sub = self.node.create_subscription(_message_class(type_name), topic,
                                                lambda data, t=topic: self._write(t, data), qos, raw=True)
            self._subscriptions.append(sub)

    def _write(self, topic: str, data: bytes) -> None:
        if self._closed:
            return
        stamp = self._sim_time_ns if self._sim_time_ns is not None else time.time_ns()
        self._writer.write(self._connections[topic], stamp, data)
        self.counts[topic] += 1

    def close(self) -> None:
        if not self._closed:
            self._closed = True
            self._timer.cancel()
            self._writer.close()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="erforce-record", description="Record all topics to a rosbag2 MCAP bag.")
    parser.add_argument("output", help="bag directory to create (must not exist)")
    parser.add_argument("--duration", type=float, default=0.0, help="stop after this many wall seconds (0: Ctrl-C)")
    parser.add_argument("--use-sim-time", action="store_true", help="log times from /clock (0 before the first)")
    args = parser.parse_args(argv)
    rclpy.init()
    node = rclpy.create_node("erforce_record")
    recorder = BagRecorder(node, args.output, use_sim_time=args.use_sim_time)
    deadline = time.monotonic() + args.duration if args.duration > 0 else None
    try:
        while rclpy.ok() and (deadline is None or time.monotonic() < deadline):
            rclpy.spin_once(node, timeout_sec=0.1)
    except KeyboardInterrupt:
        pass
    finally:
        recorder.close()
        total = sum(recorder.counts.values())
        print(f"recorded {total} messages on {len(recorder.counts)} topics into {args.output}")
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
