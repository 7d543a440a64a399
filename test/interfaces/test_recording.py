"""erforce-record writes a rosbag2 bag with MCAP storage that an independent reader opens, with what
``ros2 bag play`` needs to offer each topic as it was offered: the QoS profiles, the type hashes, the distro."""

import json
import struct
import sys
from pathlib import Path

import pytest
import yaml
from geometry_msgs.msg import PointStamped, PoseStamped
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_typestore
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Float64MultiArray

from erforce_interfaces.tools.recording import records_topic
from erforce_interfaces.wire import contract
from erforce_interfaces.wire.conversions import nanoseconds_to_stamp

pytestmark = pytest.mark.integration

ZERO = {"sec": 0, "nsec": 0}  # rclpy's default durations: the RMW's default
INFINITE = {"sec": 9223372036, "nsec": 854775807}  # RMW_DURATION_INFINITE, as discovery reports it


def profile(history, depth, reliability, durability, liveliness="system_default", duration=ZERO):
    """A QoS profile as rosbag2 (bag version 9) writes it, in its key order."""
    return {"history": history, "depth": depth, "reliability": reliability, "durability": durability,
            "deadline": duration, "lifespan": duration, "liveliness": liveliness,
            "liveliness_lease_duration": duration, "avoid_ros_namespace_conventions": False}


def installed_type_hash(type_name: str) -> str:
    """The hash rosidl wrote into the type description of the installed message package (share/<pkg>/msg/X.json)."""
    pkg, _, name = type_name.split("/")
    description = json.loads((Path(sys.prefix) / "share" / pkg / "msg" / f"{name}.json").read_text())
    return next(h["hash_string"] for h in description["type_hashes"] if h["type_name"] == type_name)


def mcap_channels(path: Path) -> dict[str, dict[str, str]]:
    """{topic: channel metadata} of the Channel records (opcode 0x04) at the top level of an MCAP file (its
    summary repeats them outside the chunks). Record: opcode u8, length u64; Channel: id u16, schema id u16,
    topic, encoding (strings: u32 length + UTF-8), metadata (u32 byte length, then key/value strings)."""
    data = path.read_bytes()
    assert data[:8] == b"\x89MCAP0\r\n"

    def string(pos: int) -> tuple[str, int]:
        (n,) = struct.unpack_from("<I", data, pos)
        return data[pos + 4:pos + 4 + n].decode(), pos + 4 + n

    channels, pos = {}, 8
    while pos < len(data) - 8:
        opcode, length = struct.unpack_from("<BQ", data, pos)
        body = pos + 9
        if opcode == 0x04:
            topic, p = string(body + 4)
            _, p = string(p)
            (size,) = struct.unpack_from("<I", data, p)
            p, end, metadata = p + 4, p + 4 + size, {}
            while p < end:
                key, p = string(p)
                metadata[key], p = string(p)
            channels[topic] = metadata
        pos = body + length
    return channels


def test_bag_offers_each_topic_as_it_was_offered(ros_graph, tmp_path):
    ros_graph.start_node("erforce_interfaces", "talker", params={"rate_hz": 20.0})
    probe = ros_graph.probe
    published = {  # contract topics, published with the contract's QoS (contract_publisher's)
        contract.CLOCK.name: (Clock, contract.CLOCK.qos, Clock()),
        contract.VISION_BALL.name: (PointStamped, contract.VISION_BALL.qos, PointStamped()),
        contract.VISION_POSE.for_robot(3): (PoseStamped, contract.VISION_POSE.qos, PoseStamped()),
        contract.BALL_MODEL_PARAMS.name: (Float64MultiArray, contract.BALL_MODEL_PARAMS.qos, Float64MultiArray()),
    }
    pubs = [(probe.publisher(topic, cls, qos), msg) for topic, (cls, qos, msg) in published.items()]
    bag = tmp_path / "bag"
    recorder = ros_graph.start([str(ros_graph.probe_executable("erforce-record")), str(bag)], name="record")
    for topic in [*published, "/chatter"]:
        recorder.wait_for_output(f"Subscribed to topic '{topic}'", timeout_s=60.0)
    for pub, msg in pubs:
        pub.publish(msg)
    probe.spin_for(0.5)
    recorder.signal(2)  # SIGINT: Ctrl-C
    assert recorder.wait_exit(30.0) == 0

    info = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert (info["version"], info["storage_identifier"], info["ros_distro"]) == (9, "mcap", "jazzy")
    topics = {t["topic_metadata"]["name"]: t["topic_metadata"] for t in info["topics_with_message_count"]}
    expected = {  # the contract's profiles, written out: sensor, clock, latched
        "/clock": profile("keep_last", 1, "reliable", "volatile"),
        "/vision/ball": profile("keep_last", 5, "best_effort", "volatile"),
        "/robot_3/vision_pose": profile("keep_last", 5, "best_effort", "volatile"),
        "/ball/model_params": profile("keep_last", 1, "reliable", "transient_local"),
        # outside the contract: what discovery reports of the talker's publisher (no history, no depth)
        "/chatter": profile("unknown", 0, "reliable", "volatile", "automatic", INFINITE),
    }
    channels = mcap_channels(bag / info["relative_file_paths"][0])
    for topic, qos in expected.items():
        meta = topics[topic]
        assert meta["offered_qos_profiles"] == [qos], topic  # one publisher each
        assert list(meta["offered_qos_profiles"][0]) == list(qos)  # rosbag2's key order
        assert meta["type_description_hash"] == installed_type_hash(meta["type"]), topic
        assert channels[topic]["topic_type_hash"] == meta["type_description_hash"]
        assert yaml.safe_load(channels[topic]["offered_qos_profiles"]) == [qos]
    assert installed_type_hash("std_msgs/msg/String") == topics["/chatter"]["type_description_hash"]
    assert contract.VISION_BALL.qos.depth == 5 and contract.BALL_MODEL_PARAMS.qos.depth == 1  # the table above


@pytest.mark.parametrize("sim_time", [False, True])
def test_recording_of_a_running_graph(ros_graph, tmp_path, sim_time):
    """As ``ros2 bag record -a``: the talker's topic, and /rosout (the listener logs what it hears) and
    /parameter_events, which every node offers."""
    ros_graph.start_node("erforce_interfaces", "talker", params={"rate_hz": 50.0, "text": "rec"})
    ros_graph.start_node("erforce_interfaces", "listener")
    clock = ros_graph.probe.publisher("/clock", Clock, contract.QOS_CLOCK)
    bag = tmp_path / "bag"
    cmd = [str(ros_graph.probe_executable("erforce-record")), str(bag), "--duration", "3.0"]
    recorder = ros_graph.start(cmd + (["--use-sim-time"] if sim_time else []), name="record")
    recorder.wait_for_output("Subscribed to topic '/clock'", timeout_s=60.0)  # its 3 s start now
    k = 0
    while recorder.alive() and k < 600:  # a simulated clock at 20 Hz, starting at 100 s
        clock.publish(Clock(clock=nanoseconds_to_stamp(100_000_000_000 + k * 50_000_000)))
        ros_graph.probe.spin_for(0.05)
        k += 1
    assert recorder.wait_exit(30.0) == 0
    assert (bag / "metadata.yaml").exists() and list(bag.glob("*.mcap"))
    typestore = get_typestore(Stores.ROS2_JAZZY)
    with Reader(bag) as reader:
        assert "/chatter" in reader.topics
        stamps, texts = [], []
        for connection, stamp, raw in reader.messages(connections=[reader.topics["/chatter"].connections[0]]):
            stamps.append(stamp)
            texts.append(typestore.deserialize_cdr(raw, connection.msgtype).data)
    assert len(texts) >= 50 and all(t.startswith("rec ") for t in texts)  # 50 Hz for most of 3 s
    with Reader(bag) as reader:
        assert {"/rosout", "/parameter_events"} <= set(reader.topics)
        assert reader.topics["/parameter_events"].msgtype == "rcl_interfaces/msg/ParameterEvent"
        logs = [typestore.deserialize_cdr(raw, c.msgtype) for c, _, raw in
                reader.messages(connections=reader.topics["/rosout"].connections)]
    assert any(log.name == "listener" and log.msg.startswith("I heard: rec ") for log in logs)
    if sim_time:  # log times are the simulated clock (or 0 before the first)
        assert all(s == 0 or 100e9 <= s <= 100e9 + k * 50e6 for s in stamps) and max(stamps) >= 101e9
    else:
        assert min(stamps) > 1.6e18  # wall-clock nanoseconds since the epoch (after 2020)


# ros2 bag record -a on Jazzy (rosbag2_transport TopicFilter): which topics it takes, case by case
RECORDED = [
    ("/chatter", ["std_msgs/msg/String"], True, True),
    ("/rosout", ["rcl_interfaces/msg/Log"], True, True),
    ("/parameter_events", ["rcl_interfaces/msg/ParameterEvent"], True, True),
    ("/robot_0/parameter_events", ["rcl_interfaces/msg/ParameterEvent"], True, True),
    ("/chatter", ["std_msgs/msg/String"], False, False),  # only subscribed: unpublished
    ("/mixed", ["std_msgs/msg/String", "std_msgs/msg/Int32"], True, False),  # two types
    ("/mixed", ["std_msgs/msg/String", "std_msgs/msg/String"], True, True),  # one type, twice
    ("/_hidden", ["std_msgs/msg/String"], True, False),
    ("/ns/_hidden/x", ["std_msgs/msg/String"], True, False),
    ("/ns/not_hidden_", ["std_msgs/msg/String"], True, True),
    ("/talker/get_parameters/_service_event", ["rcl_interfaces/srv/GetParameters_Event"], True, True),
    ("/talker/x/_service_event", ["std_msgs/msg/String"], True, False),  # not an event type: hidden
    ("/talker/_service_event_x", ["rcl_interfaces/srv/GetParameters_Event"], True, False),
]


@pytest.mark.parametrize(("topic", "types", "published", "recorded"), RECORDED)
def test_the_topics_ros2_bag_record_a_takes(topic, types, published, recorded):
    assert records_topic(topic, types, published) is recorded
