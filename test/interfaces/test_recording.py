"""erforce-record writes a rosbag2 bag with MCAP storage that an independent reader opens."""

import pytest
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_typestore
from rosgraph_msgs.msg import Clock

from erforce_interfaces import contract
from erforce_interfaces.conversions import nanoseconds_to_stamp

pytestmark = pytest.mark.integration


@pytest.mark.parametrize("sim_time", [False, True])
def test_recording_of_a_running_graph(ros_graph, tmp_path, sim_time):
    ros_graph.start_node("erforce_interfaces", "talker", params={"rate_hz": 50.0, "text": "rec"})
    clock = ros_graph.probe.publisher("/clock", Clock, contract.QOS_CLOCK)
    bag = tmp_path / "bag"
    cmd = [str(ros_graph.probe_executable("erforce-record")), str(bag), "--duration", "3.0"]
    recorder = ros_graph.start(cmd + (["--use-sim-time"] if sim_time else []), name="record")
    for k in range(60):  # 3 s of a simulated clock at 20 Hz, starting at 100 s
        clock.publish(Clock(clock=nanoseconds_to_stamp(100_000_000_000 + k * 50_000_000)))
        ros_graph.probe.spin_for(0.05)
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
    if sim_time:  # log times are the simulated clock: within its 100..103 s (or 0 before the first)
        assert all(s == 0 or 100e9 <= s <= 103e9 for s in stamps) and max(stamps) >= 101e9
    else:
        assert min(stamps) > 1.6e18  # wall-clock nanoseconds since the epoch (after 2020)
