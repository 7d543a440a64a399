"""Record every topic of a graph into a rosbag2 bag with MCAP storage, like ``ros2 bag record -a``.

Which topics: those ``ros2 bag record -a`` takes on Jazzy: every topic with a publisher and a single type,
``/rosout`` and ``/parameter_events`` included, hidden ones left out but a service's introspection topic
taken; a type rosbags' Jazzy type store cannot describe is left out, as rosbag2 leaves out a type without
its package. Command line: ``erforce-record OUTPUT_DIR [--use-sim-time] [--duration S]``.

Messages are taken raw (CDR bytes) and in batches: the recorder spins no executor but drains every
subscription every ``POLL_PERIOD_S`` (50 ms), since an executor callback per message made it the busiest
process of the demo graph. Each message is logged at its DDS reception time, or with ``use_sim_time`` at
the newest ``/clock`` received before it.

The bag is what rosbag2 (Jazzy, bag version 9) writes, so ``ros2 bag info/play`` and Foxglove open it:
per topic the offered QoS profiles (the contract's for a contract topic, since discovery does not carry
history and depth) and the publisher's type hash, in metadata.yaml and in the MCAP channels.
"""

from __future__ import annotations

import argparse
import bisect
import importlib
import os
import sys
import time
from io import BytesIO
from pathlib import Path
from typing import ClassVar

import rclpy
import yaml
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.rosbag2.metadata import dump_qos_v9
from rosbags.rosbag2.storage_mcap import Channel, McapWriter, write_channel, write_string
from rosbags.typesys import Stores, get_typestore
from rosgraph_msgs.msg import Clock

from erforce_interfaces.runtime.executor import take_queued
from erforce_interfaces.runtime.node_support import QuietInterrupt
from erforce_interfaces.runtime.rclpy_internals import RCLError
from erforce_interfaces.wire.contract import CLOCK, dds_profile_env, topic_of_name
from erforce_interfaces.wire.conversions import stamp_to_nanoseconds

POLL_PERIOD_S = 0.05
DISCOVERY_PERIOD_S = 0.5


ROS_DISTRO = "jazzy"
BAG_VERSION = 9
# rosbag2's order of the keys of metadata.yaml (rosbag2_storage's metadata_io), which yaml-cpp keeps
_METADATA_KEYS = ("version", "storage_identifier", "duration", "starting_time", "message_count",
                  "topics_with_message_count", "compression_format", "compression_mode", "relative_file_paths",
                  "files", "custom_data", "ros_distro")
_TOPIC_KEYS = ("name", "type", "serialization_format", "offered_qos_profiles", "type_description_hash")
_QOS_KEYS = ("history", "depth", "reliability", "durability", "deadline", "lifespan", "liveliness",
             "liveliness_lease_duration", "avoid_ros_namespace_conventions")
_TIME_KEYS = ("sec", "nsec")
_FILE_KEYS = ("path", "starting_time", "duration", "message_count")


def _message_class(type_name: str):
    pkg, kind, name = type_name.split("/")
    return getattr(importlib.import_module(f"{pkg}.{kind}"), name)


def is_service_event_topic(topic: str, type_name: str) -> bool:
    """A service's introspection topic, as rosbag2 tells it: ``<service>/_service_event`` of a ``/srv/..._Event``."""
    return topic.endswith("/_service_event") and "/srv/" in type_name and type_name.endswith("_Event")


def records_topic(topic: str, types: list[str], published: bool) -> bool:
    """Whether ``ros2 bag record -a`` on Jazzy records ``topic`` (rosbag2_transport TopicFilter::take_topic
    with all topics and services, no include or exclude options)."""
    if len(set(types)) != 1 or not published:  # several types, or unpublished: never recorded
        return False
    hidden = any(part.startswith("_") for part in topic.split("/") if part)
    return is_service_event_topic(topic, types[0]) or not hidden


def _qos_time(duration: Duration) -> QosTime:
    sec, nsec = divmod(duration.nanoseconds, 1_000_000_000)
    return QosTime(sec, nsec)


def bag_qos(profile: QoSProfile) -> Qos:
    """An rclpy QoS profile as the bag stores it (the policies by name: rmw's strings, e.g. keep_last)."""
    return Qos(QosHistory[profile.history.name], profile.depth, QosReliability[profile.reliability.name],
               QosDurability[profile.durability.name], _qos_time(profile.deadline), _qos_time(profile.lifespan),
               QosLiveliness[profile.liveliness.name], _qos_time(profile.liveliness_lease_duration),
               profile.avoid_ros_namespace_conventions)


def offered_qos(topic: str, discovered: QoSProfile) -> QoSProfile:
    """What a publisher of ``topic`` offers: the contract's profile when it agrees with what discovery
    reports, else the discovered one."""
    contract = topic_of_name(topic)
    if contract is not None and (contract.qos.reliability, contract.qos.durability) == (
            discovered.reliability, discovered.durability):
        return contract.qos
    return discovered


def _qos_dicts(profiles: list[dict]) -> list[dict]:
    """QoS profiles as dictionaries in rosbag2's key order."""
    return [{k: {t: p[k][t] for t in _TIME_KEYS} if isinstance(p[k], dict) else p[k] for k in _QOS_KEYS}
            for p in profiles]


def _qos_yaml(profiles: list[Qos]) -> str:
    """The QoS profiles as rosbag2 serializes them into an MCAP channel's metadata (a YAML sequence)."""
    return yaml.safe_dump(_qos_dicts(dump_qos_v9(profiles)), sort_keys=False, default_flow_style=False).strip()


def _rosbag2_metadata(info: dict) -> dict:
    """rosbags' bag information with rosbag2's key order and our distro."""
    info = {**info, "ros_distro": ROS_DISTRO,
            "files": [{k: f[k] for k in _FILE_KEYS} for f in info["files"]],
            "topics_with_message_count": [
                {"topic_metadata": {k: _qos_dicts(t["topic_metadata"][k]) if k == "offered_qos_profiles"
                                    else t["topic_metadata"][k] for k in _TOPIC_KEYS},
                 "message_count": t["message_count"]} for t in info["topics_with_message_count"]]}
    return {k: info[k] for k in _METADATA_KEYS}


class _McapStorage(McapWriter):
    """rosbags' MCAP storage with what rosbag2 also writes: the type hash in each channel's metadata
    (``topic_type_hash``), and ``ros_distro`` in the bag information inside the file."""

    def add_connection(self, connection, offered_qos_profiles: str) -> None:
        metadata = BytesIO()
        for key, value in (("offered_qos_profiles", _qos_yaml(connection.ext.offered_qos_profiles)),
                           ("topic_type_hash", connection.digest)):
            write_string(metadata, key)
            write_string(metadata, value)
        self.channels.append(Channel(connection.id, connection.msgtype, connection.topic,
                                     connection.ext.serialization_format, metadata.getvalue()))
        self.channel_stats[connection.id] = 0
        write_channel(self.chunk.bio, self.channels[-1], self.schemas)

    def close(self, version: int, metadata: str) -> None:
        info = _rosbag2_metadata(yaml.safe_load(metadata))
        super().close(version, yaml.safe_dump(info, sort_keys=False, default_flow_style=False).strip())


class _BagWriter(Writer):
    STORAGE_PLUGINS: ClassVar = {**Writer.STORAGE_PLUGINS, StoragePlugin.MCAP: _McapStorage}

    def close(self) -> None:
        super().close()
        info = yaml.safe_load(self.metapath.read_text())["rosbag2_bagfile_information"]
        text = yaml.safe_dump({"rosbag2_bagfile_information": _rosbag2_metadata(info)}, sort_keys=False,
                              default_flow_style=False)
        tmp = self.metapath.with_suffix(".yaml.tmp")
        tmp.write_text(text)
        tmp.replace(self.metapath)


class BagRecorder:
    """Subscribes to every topic as it appears; ``poll()`` writes what has arrived into ``path``."""

    def __init__(self, node: Node, path: str | Path, use_sim_time: bool = False) -> None:
        self.node = node
        self.path = Path(path)
        self._typestore = get_typestore(Stores.ROS2_JAZZY)
        self._writer = _BagWriter(self.path, version=BAG_VERSION, storage_plugin=StoragePlugin.MCAP)
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
            if topic in self._connections:
                continue
            publishers = self.node.get_publishers_info_by_topic(topic)
            if not records_topic(topic, types, bool(publishers)) or types[0] not in self._typestore.types:
                continue
            type_name = types[0]
            best_effort = any(p.qos_profile.reliability == ReliabilityPolicy.BEST_EFFORT for p in publishers)
            # Deep queues: they hold what arrives between two polls (and more when the recorder lags).
            qos = QoSProfile(depth=10000, reliability=ReliabilityPolicy.BEST_EFFORT if best_effort
                             else ReliabilityPolicy.RELIABLE)
            # The type hash of the publisher's type support, as rosbag2 takes it (rosbags computes the
            # same from the definition, for a publisher that reports none).
            type_hash = next((str(p.topic_type_hash) for p in publishers if p.topic_type_hash.version > 0),
                             self._typestore.hash_rihs01(type_name))
            msgdef, _ = self._typestore.generate_msgdef(type_name, ros_version=2)
            self._connections[topic] = self._writer.add_connection(
                topic, type_name, msgdef=msgdef, rihs01=type_hash,
                offered_qos_profiles=[bag_qos(offered_qos(topic, p.qos_profile)) for p in publishers])
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
        os.environ.update(dds_profile_env())  # the nodes' DDS settings: on LOCALHOST, sockets on loopback only
        rclpy.init()
        # No executor spins this node (see the module docstring), so it offers no parameter services.
        node = rclpy.create_node("erforce_record", start_parameter_services=False)
        recorder = BagRecorder(node, args.output, use_sim_time=args.use_sim_time)
        deadline = time.monotonic() + args.duration if args.duration > 0 else None
        next_discovery = time.monotonic() + DISCOVERY_PERIOD_S
        # From here on Ctrl-C ends the loop through rclpy.ok() (at most one poll later): no exception
        # can break a message half written into the bag.
        interrupt.raising = False
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
