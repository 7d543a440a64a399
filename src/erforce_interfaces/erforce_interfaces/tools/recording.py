"""Record every topic of a graph into a rosbag2 bag with MCAP storage, like ``ros2 bag record -a``.

The bag is a rosbag2 directory (metadata.yaml + .mcap), so ``ros2 bag info/play`` and
Foxglove open it. Messages are taken raw (CDR bytes, no deserialization) and in batches:
the recorder does not spin an executor, it drains every subscription's DDS queue every
``POLL_PERIOD_S`` (50 ms). An executor callback per message cost ~0.2 ms of CPU here, which made
the recorder the busiest process of the demo graph; a batched take is a few microseconds.
Each message is logged at its DDS reception time (``received_timestamp``), or with
``use_sim_time`` at the newest ``/clock`` received before it (0 before the first), which
is what a recorder with a callback per message would log. Command line:
``erforce-record OUTPUT_DIR [--use-sim-time] [--duration S]``.
"""

from __future__ import annotations

import argparse
import bisect
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

from erforce_interfaces.contract import CLOCK
from erforce_interfaces.conversions import stamp_to_nanoseconds
from erforce_interfaces.executor import take_queued
from erforce_interfaces.node_support import QuietInterrupt
from erforce_interfaces.rclpy_internals import RCLError

POLL_PERIOD_S = 0.05
DISCOVERY_PERIOD_S = 0.5


def _message_class(type_name: str):
    pkg, _, name = type_name.split("/")
    return getattr(importlib.import_module(f"{pkg}.msg"), name)


class BagRecorder:
    """Subscribes to every topic as it appears; ``poll()`` writes what has arrived into ``path``."""

    def __init__(self, node: Node, path: str | Path, use_sim_time: bool = False) -> None:
        self.node = node
        self.path = Path(path)
        self._typestore = get_typestore(Stores.ROS2_JAZZY)
        self._writer = Writer(self.path, version=9, storage_plugin=StoragePlugin.MCAP)
        self._writer.open()
        self._connections: dict[str, object] = {}
        self._subscriptions: list[tuple[str, object]] = []
        # (received wall ns, simulated ns) of each /clock message: the log time of a message is
        # the simulated time of the newest clock received before it.
        self._clock_sub = (node.create_subscription(Clock, CLOCK.name, lambda _: None, CLOCK.qos)
                           if use_sim_time else None)
        self._clock_received_ns: list[int] = [0]
        self._clock_sim_ns: list[int] = [0]
        self.counts: dict[str, int] = {}
        self._closed = False
        self.discover()

    def discover(self) -> None:
        """Subscribe to the topics that appeared since the last call."""
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
            # Deep queues: they hold what arrives between two polls (and more when the recorder lags).
            qos = QoSProfile(depth=10000, reliability=ReliabilityPolicy.BEST_EFFORT if best_effort
                             else ReliabilityPolicy.RELIABLE)
            self._connections[topic] = self._writer.add_connection(topic, type_name, typestore=self._typestore)
            self.counts[topic] = 0
            sub = self.node.create_subscription(_message_class(type_name), topic, lambda _: None, qos, raw=True)
            self._subscriptions.append((topic, sub))
            self.node.get_logger().info(f"Subscribed to topic '{topic}'")  # as ros2 bag record logs it

    def poll(self) -> int:
        """Write every message that arrived since the last poll, in order of reception; returns how many."""
        if self._closed:
            return 0
        if self._clock_sub is not None:
            for msg, info in take_queued(self._clock_sub):
                self._clock_received_ns.append(info["received_timestamp"])
                self._clock_sim_ns.append(stamp_to_nanoseconds(msg.clock))
        batch = []
        for topic, sub in self._subscriptions:
            batch.extend((info["received_timestamp"], topic, data) for data, info in take_queued(sub))
        batch.sort(key=lambda item: item[0])
        for received_ns, topic, data in batch:
            if self._clock_sub is not None:
                received_ns = self._clock_sim_ns[bisect.bisect_right(self._clock_received_ns, received_ns) - 1]
            self._writer.write(self._connections[topic], received_ns, data)
            self.counts[topic] += 1
        del self._clock_received_ns[:-1], self._clock_sim_ns[:-1]  # only the newest is needed from now on
        return len(batch)

    def close(self) -> None:
        if not self._closed:
            self.poll()
            self._closed = True
            self._writer.close()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="erforce-record", description="Record all topics to a rosbag2 MCAP bag.")
    parser.add_argument("output", help="bag directory to create (must not exist)")
    parser.add_argument("--duration", type=float, default=0.0, help="stop after this many wall seconds (0: Ctrl-C)")
    parser.add_argument("--use-sim-time", action="store_true", help="log times from /clock (0 before the first)")
    args = parser.parse_args(argv)
    interrupt = QuietInterrupt()  # a forwarded second Ctrl-C must not break the bag's closing
    node = recorder = None
    try:
        rclpy.init()
        # No executor spins this node (see the module docstring), so it offers no parameter services.
        node = rclpy.create_node("erforce_record", start_parameter_services=False)
        recorder = BagRecorder(node, args.output, use_sim_time=args.use_sim_time)
        deadline = time.monotonic() + args.duration if args.duration > 0 else None
        next_discovery = time.monotonic() + DISCOVERY_PERIOD_S
        interrupt.raising = False  # from here on Ctrl-C ends the loop through rclpy.ok()
        while rclpy.ok() and (deadline is None or time.monotonic() < deadline):
            time.sleep(POLL_PERIOD_S)
            recorder.poll()
            if time.monotonic() >= next_discovery:
                next_discovery += DISCOVERY_PERIOD_S
                recorder.discover()
    except KeyboardInterrupt:
        pass
    except RCLError:
        if rclpy.ok():  # "context is invalid" under a poll or discovery: that is Ctrl-C, not a fault
            raise
    finally:
        if recorder is not None:
            recorder.close()
            total = sum(recorder.counts.values())
            print(f"recorded {total} messages on {len(recorder.counts)} topics into {args.output}")
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
        interrupt.restore()
    return 0


if __name__ == "__main__":
    sys.exit(main())
