"""ssl_vision_bridge over real UDP (loopback multicast, TTL 0) and DDS: the mapping onto the contract's
topics (units, side, team, namespaces, stamps), geometry to the latched topics and into the ball
predictor, and bad input between good packets: garbage, absurd counts, NaN, a camera clock jump, a flood."""

from __future__ import annotations

import math
import re
import signal
import socket
import threading
import time
from itertools import pairwise

import pytest
from geometry_msgs.msg import PointStamped, PoseStamped
from nav_msgs.msg import Odometry
from sensor_msgs.msg import PointCloud2
from std_msgs.msg import Float64MultiArray

from erforce_interfaces.ssl.ssl_proto import ssl_vision_wrapper_pb2 as wrap
from erforce_interfaces.ssl.ssl_vision import (
    SSL_VISION_GROUP,
    BallCandidate,
    BallModelFromVision,
    CameraFrame,
    ChipModelFromVision,
    FieldGeometry,
    RobotSighting,
    encode_frame,
    encode_geometry,
)
from erforce_interfaces.wire import contract
from erforce_interfaces.wire.clouds import vision_frame_from_msg, vision_robots_cdr
from erforce_interfaces.wire.conversions import point_from_msg, pose2d_from_msg
from erforce_interfaces.wire.tables import table_from_msg, table_msg
from erforce_sim.ssl_cameras import open_multicast_sender

pytestmark = pytest.mark.integration

VISION_EPOCH_S = 1.7e9  # the vision host's clock: Unix time, far from the ROS clock of the test


def free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


class Sender:
    def __init__(self, port: int) -> None:
        self.sock = open_multicast_sender("127.0.0.1")
        self.address = (SSL_VISION_GROUP, port)
        self.frame_number = 0

    def send(self, data: bytes) -> None:
        self.sock.sendto(data, self.address)

    def frame(self, camera: int, t: float, balls=(), robots=(), clock_offset_s: float = 0.0) -> bytes:
        self.frame_number += 1
        t_capture = VISION_EPOCH_S + t + clock_offset_s
        return encode_frame(CameraFrame(camera, self.frame_number, t_capture, t_capture + 0.005,
                                        tuple(balls), tuple(robots)))


@pytest.fixture
def bridge(ros_graph):
    port = free_udp_port()
    node = ros_graph.start_node("erforce_ball_model", "ssl_vision_bridge", params={
        "port": port, "interface": "127.0.0.1", "team_color": "yellow", "defend_side": "positive_x",
        "num_robots": 4, "stats_period_s": 0.5, "publish_detections": True, "field": "division_b"})
    node.wait_for_output(r"ssl_vision_bridge: 224\.5\.23\.2", timeout_s=60.0)
    sender = Sender(port)
    yield ros_graph, node, sender
    sender.sock.close()


def collect(graph, topic, msg_type, qos):
    return graph.subscribe(topic, msg_type, qos)


def test_frames_become_contract_topics_and_bad_datagrams_are_named_between_good_ones(bridge):
    graph, node, sender = bridge
    q = contract
    balls = collect(graph, q.VISION_BALL.name, PointStamped, q.VISION_BALL.qos)
    ours = collect(graph, q.VISION_POSE.for_robot(3), PoseStamped, q.VISION_POSE.qos)
    theirs = collect(graph, q.opponent_topic(q.VISION_POSE, 5), PoseStamped, q.VISION_POSE.qos)
    robots = collect(graph, q.VISION_ROBOTS.name, PointCloud2, q.VISION_ROBOTS.qos)
    detections = collect(graph, q.VISION_DETECTIONS.name, Float64MultiArray, q.VISION_DETECTIONS.qos)
    # the bridge's readers exist once its publishers are matched: send until the first ball arrives
    ball = BallCandidate(1.0, 0.5, 0.9)
    ours_robot = RobotSighting("yellow", 3, -2.0, 1.0, 0.5, 1.0)
    theirs_robot = RobotSighting("blue", 5, 3.0, -1.0, -2.0, 1.0)
    k = 0
    while not balls:
        k += 1
        sender.send(sender.frame(0, k / 60.0, [ball], [ours_robot, theirs_robot]))
        graph.probe.spin_for(1 / 60.0)
        assert k < 600, node.output()[-3000:]
    bad = [
        b"\x00\x01garbage",
        sender.frame(1, k / 60.0)[:-3],  # truncated
        b"\x0a\x02\x08\x01",  # a frame without its required fields
    ]
    # 101 ball candidates away from the tracked ball: camera 1's stamps (its offset from one sample) never make
    # camera 0's next ball a late one
    absurd = wrap.SSL_WrapperPacket.FromString(sender.frame(1, k / 60.0))
    for _ in range(101):
        absurd.detection.balls.add(confidence=1.0, x=0.0, y=0.0, pixel_x=0.0, pixel_y=0.0)
    bad.append(absurd.SerializeToString())
    nan_ball = sender.frame(1, (k + 1) / 60.0, [BallCandidate(math.nan, 0.0, 0.9), BallCandidate(1e12, 0.0, 0.9)])
    bad.append(nan_ball)
    n_before = len(balls)
    for j, data in enumerate(bad):  # at the camera's pace: the vision clock runs with the ROS clock
        sender.send(data)
        sender.send(sender.frame(0, (k + 1 + j) / 60.0, [ball], [ours_robot, theirs_robot]))
        graph.probe.spin_for(1 / 60.0)
    graph.probe.spin_until(lambda: len(balls) >= n_before + len(bad), 10.0, "good frames between the bad ones")
    for text in ("not an SSL_WrapperPacket", "without required fields (detection.t_capture",
                 "[too_many_balls] camera 1: 101 ball candidates, 69 beyond the first 32 dropped",
                 "[bad_ball] camera 1: ball at (nan, 0.0) mm, confidence 0.8999999761581421 dropped; camera 1: "
                 "ball at (999999986991104.0, 0.0) mm"):
        node.wait_for_output(re.escape(text), timeout_s=10.0)

    # The other readers may match the bridge's writers later than /vision/ball's did (the opponent's
    # vision_pose writer only comes with its first sighting), and a frame's messages on different topics
    # arrive in any order: good frames go on at the camera's pace until every topic has one.
    def detection_rows(msg):
        return table_from_msg(msg, contract.VISION_DETECTION_COLUMNS)

    deadline = time.monotonic() + 10.0
    k += len(bad)
    while not (ours and theirs and robots and any(len(detection_rows(m)) for m in detections)):
        assert time.monotonic() < deadline, f"robots and detections: {len(ours)}, {len(theirs)}, {len(robots)}, " \
                                            f"{len(detections)}"
        k += 1
        sender.send(sender.frame(0, k / 60.0, [ball], [ours_robot, theirs_robot]))
        graph.probe.spin_for(1 / 60.0)

    def stamp_s(msg) -> float:
        return msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9

    # the newest ball's frame on /vision/robots (same stamp) is a message of another writer: it may come later
    graph.probe.spin_until(lambda: stamp_s(balls[-1]) in {stamp_s(m) for m in robots}, 10.0,
                           "the newest ball's frame on /vision/robots")

    # defend_side positive_x: the field turns by half a turn; metres; our team (yellow) under robot_<id>
    t, (x, y) = point_from_msg(balls[-1])
    assert (x, y) == pytest.approx((-1.0, -0.5), abs=1e-6)
    _, pose = pose2d_from_msg(ours[-1])
    assert pose.tolist() == pytest.approx([2.0, -1.0, 0.5 - math.pi], abs=1e-6)
    _, pose = pose2d_from_msg(theirs[-1])
    assert pose.tolist() == pytest.approx([-3.0, 1.0, -2.0 + math.pi], abs=1e-6)
    # the ball and both teams in one /vision/robots per camera frame: the ball's (x, y), the robots' (team code, id
    # in the team, x, y, yaw), at the frame's stamp; /vision/ball (read here) has the same ball at the same stamp
    frames = {t_s: (frame_balls.tolist(), rows.tolist()) for t_s, frame_balls, rows in map(vision_frame_from_msg,
                                                                                              robots)}
    assert frames[t][0] == [pytest.approx([-1.0, -0.5], abs=1e-6)]
    t_robots, (frame_balls, rows) = max(frames.items())
    assert frame_balls == [pytest.approx([-1.0, -0.5], abs=1e-6)]
    assert sorted(rows) == [pytest.approx([1.0, 3.0, 2.0, -1.0, 0.5 - math.pi], abs=1e-6),
                            pytest.approx([2.0, 5.0, -3.0, 1.0, -2.0 + math.pi], abs=1e-6)]
    assert abs(t_robots - time.time()) < 5.0 and robots[-1].header.frame_id == contract.FIELD_FRAME
    # stamps on the ROS clock (the test's wall clock), not on the vision clock
    assert abs(t - time.time()) < 5.0
    # the newest table of camera 0 is a good frame's; camera 1's tables: the crowded frame's first 32 balls (at the
    # origin), nothing of the frames with bad balls
    tables = [t for t in map(detection_rows, detections) if len(t)]
    table = next(t for t in reversed(tables) if t[0, 0] == 0.0)
    assert table[:, 0].tolist() == [0.0] * 3
    assert sorted(table[:, 2].tolist()) == [0.0, 1.0, 2.0]  # ball, ours, opponent
    for t in (t for t in tables if t[0, 0] == 1.0):
        assert t.shape[0] == 32 and (t[:, 4:6] == 0.0).all() and (t[:, 2] == 0.0).all()
    assert node.alive()


def test_geometry_is_latched_and_a_clock_jump_and_a_flood_are_survived(bridge):
    graph, node, sender = bridge
    q = contract
    geometry = FieldGeometry(12.0, 9.0, 0.3, 1.8, 0.18, ball_model=BallModelFromVision(-3.0, -0.26, 0.64),
                             chip_model=ChipModelFromVision(0.42, 0.6, 0.96))
    sender.send(encode_geometry(geometry))
    node.wait_for_output(r"SSL geometry: field 12 x 9 m, ball model a_slide -3, a_roll -0.26, k_switch 0.64, chip "
                         r"model damping_z 0.42, damping_xy_first_hop 0.6, damping_xy_other_hops 0.96", timeout_s=10.0)
    # a reader that joins later still gets them (transient local)
    model = graph.wait_for_message(q.VISION_BALL_MODEL.name, Float64MultiArray, 10.0, qos=q.VISION_BALL_MODEL.qos)
    assert table_from_msg(model, contract.BALL_MODEL_PARAM_LABELS).tolist() == [[-3.0, -0.26, 0.64]]
    chip = graph.wait_for_message(q.VISION_CHIP_MODEL.name, Float64MultiArray, 10.0, qos=q.VISION_CHIP_MODEL.qos)
    assert table_from_msg(chip, contract.VISION_CHIP_MODEL_LABELS).tolist() == [[0.42, 0.6, 0.96]]
    field = graph.wait_for_message(q.VISION_FIELD.name, Float64MultiArray, 10.0, qos=q.VISION_FIELD.qos)
    assert table_from_msg(field, contract.VISION_FIELD_COLUMNS).tolist()[0][:3] == [12.0, 9.0, 0.3]

    # the ball from /vision/robots, the frame's message (nobody reads /vision/ball here: the bridge sends none)
    frames = collect(graph, q.VISION_ROBOTS.name, PointCloud2, q.VISION_ROBOTS.qos)

    def balls():  # (stamp, (x, y)) of each ball in the frames so far
        return [(t_s, tuple(xy)) for t_s, xys, _ in map(vision_frame_from_msg, frames) for xy in xys.tolist()]

    ball = [BallCandidate(0.0, 0.0, 0.9)]
    t = 0.0
    while len(balls()) < 5:
        t += 1 / 60.0
        sender.send(sender.frame(2, t, ball))
        graph.probe.spin_for(1 / 60.0)
        assert t < 10.0
    # camera 2's clock jumps forward by 100 s: refused with a warning, then followed
    stamp_before = balls()[-1][0]
    n = len(balls())
    for _ in range(30):
        t += 1 / 60.0
        sender.send(sender.frame(2, t, ball, clock_offset_s=100.0))
        graph.probe.spin_for(1 / 60.0)
    node.wait_for_output(r"camera 2: clock offset .* jumped forward", timeout_s=10.0)
    graph.probe.spin_until(lambda: len(balls()) >= n + 4, 5.0, "frames after the jump")
    # still on the ROS clock (the test's wall clock): after the frames before the jump, never after arrival
    assert stamp_before < balls()[-1][0] <= time.time()

    # a flood: 5000 datagrams at once; the node stays up and serves the next good frame
    flood = sender.frame(3, t, ball)
    for _ in range(5000):
        sender.send(flood)
    n = len(balls())
    for _ in range(100):
        t += 1 / 60.0
        sender.send(sender.frame(2, t, ball, clock_offset_s=100.0))
        graph.probe.spin_for(1 / 60.0)
        if len(balls()) > n + 3:
            break
    assert len(balls()) > n + 3
    node.wait_for_output(r"ssl_vision_bridge: \d+ datagrams", timeout_s=10.0)
    assert node.alive()
    assert all(math.isfinite(v) for _, xy in balls() for v in xy)


def test_the_ball_predictor_takes_the_ball_model_from_ssl_geometry_unless_pinned(ros_graph):
    q = contract
    pub = ros_graph.probe.publisher(q.VISION_BALL_MODEL.name, Float64MultiArray, q.VISION_BALL_MODEL.qos)
    pub.publish(table_msg([[-4.0, -0.5, 0.7]], contract.BALL_MODEL_PARAM_LABELS, "model"))
    field_pub = ros_graph.probe.publisher(q.VISION_FIELD.name, Float64MultiArray, q.VISION_FIELD.qos)
    field_pub.publish(table_msg([[12.0, 9.0, 0.3, 1.8, 0.18]], contract.VISION_FIELD_COLUMNS, "field"))
    follows = ros_graph.start_node("erforce_ball_model", "ball_predictor", name="follows", params={"num_robots": 1})
    pinned = ros_graph.start_node("erforce_ball_model", "ball_predictor", name="pinned",
                                  params={"num_robots": 1, "use_vision_geometry": False})
    follows.wait_for_output(r"ball model from SSL geometry: a_slide -4, a_roll -0\.5, c_switch 0\.7", 60.0)
    follows.wait_for_output(r"field from SSL geometry: 12 x 9 m", 10.0)
    pinned.wait_for_output(r"ball_predictor: 1 robot", 60.0)
    ros_graph.probe.spin_for(2.0)  # the latched messages have reached both by now
    assert "from SSL geometry" not in pinned.output()

    # A parameter change keeps the geometry's field: a ball at x = 5.5 m lies inside division A (12 x 9 m)
    # and outside the parameters' division B plus its 0.5 m margin (4.5 + 0.5), which pinned rejects.
    probe = ros_graph.probe
    assert probe.set_parameter("/follows", "reaction_s", 0.15).successful
    assert probe.set_parameter("/follows", "a_slide_mps2", -2.0).successful
    states = probe.subscribe(q.BALL_STATE.name, Odometry, q.BALL_STATE.qos)
    ball_pub = probe.wait_for_subscribers(q.VISION_ROBOTS.name, PointCloud2, count=2, qos=q.VISION_ROBOTS.qos)
    deadline = time.monotonic() + 20.0
    rejected = "rejected vision/ball outside the field"
    # Resent until both have answered: our writer has matched both readers, but a reader may not have matched
    # our writer yet (matching is not symmetric) and drops what comes before; follows' answer says nothing
    # about pinned.
    for k in range(1000):
        ball_pub.publish(vision_robots_cdr(100.0 + 0.01 * k, [], balls=[(5.5, 0.0)]))
        try:
            probe.spin_until(lambda: states and rejected in pinned.output(), 0.2, "a ball state and the rejection")
            break
        except TimeoutError:
            assert time.monotonic() < deadline, ("the ball predictor dropped the SSL field on a parameter change"
                                                 if not states else f"pinned did not reject the ball at x = 5.5 m:\n"
                                                 f"{pinned.output()[-2000:]}")
    assert states[-1].pose.pose.position.x == pytest.approx(5.5, abs=0.01)


def test_a_sigint_while_datagrams_stream_in_ends_quietly(bridge):
    """The plant keeps sending while the launcher interrupts the graph: the receive thread must not warn about
    publishing into the context SIGINT has already shut down."""
    _graph, node, sender = bridge
    stop = threading.Event()

    def stream() -> None:
        t = 0.0
        while not stop.is_set():
            t += 0.01
            sender.send(sender.frame(0, t, balls=[BallCandidate(100.0 * t, 0.0, 0.9)]))
            time.sleep(0.001)  # pacing of the sender, not a wait for the node

    streamer = threading.Thread(target=stream, daemon=True)
    streamer.start()
    try:
        node.wait_for_output(r"ssl_vision_bridge: \d+ datagrams", timeout_s=30.0)  # it is handling them
        node.signal(signal.SIGINT)
        code = node.wait_exit(20.0)
    finally:
        stop.set()
        streamer.join(timeout=2.0)
    out = node.output()
    assert code == 0, out[-1500:]
    assert "batch failed" not in out and "Traceback" not in out, out[-1500:]
@pytest.mark.parametrize("general_path", [False, True])
def test_a_frames_vision_robots_goes_out_before_its_vision_ball(general_path):
    """What the predictor reads goes out first: /vision/robots, then the tool topic /vision/ball (with a
    reader), on the compiled pass and on the general path (publish_detections). In-process: datagrams
    handed to the node's batch handler, its two publishers recording."""
    import rclpy

    from erforce_ball_model.ssl_vision_bridge_node import SslVisionBridge

    rclpy.init(args=["--ros-args", "-p", f"port:={free_udp_port()}", "-p", "interface:=127.0.0.1",
                     "-p", f"publish_detections:={str(general_path).lower()}", "-p", "field:=division_b"])
    node = None
    try:
        node = SslVisionBridge()
        sent = []

        class Recording:
            def __init__(self, topic):
                self.topic = topic

            def publish(self, data):
                sent.append(self.topic)

        node._robots_pub, node._ball_pub = Recording("robots"), Recording("ball")
        node._ball_readers[0] = 1
        sender = Sender(0)
        per_datagram = []
        for k in range(12):  # a ball rolling along x, seen by camera 0 with one robot of ours (yellow)
            sent.clear()
            data = sender.frame(0, 0.016 * k, balls=[BallCandidate(-1.0 + 0.02 * k, 0.5, 0.9)],
                                robots=[RobotSighting("yellow", 0, 1.0, 1.0, 0.0, 1.0)])
            node.handle_batch([data], 1.0 + 0.016 * k)
            per_datagram.append(list(sent))
        sender.sock.close()
        with_ball = [order for order in per_datagram if "ball" in order]
        assert len(with_ball) >= 8, per_datagram  # the ball is taken once its hypothesis is confirmed
        assert all(order == ["robots", "ball"] for order in with_ball), per_datagram
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()


def test_the_field_comes_from_the_world_nothing_is_judged_before_its_geometry(ros_graph):
    """field: from_geometry (the default). Before geometry the bridge says once that it waits and publishes nothing;
    after Division A's geometry (lines at |x| = 6 m) a ball at x = 5.3 m, beyond Division B's 4.5 m plus the
    tracker's 0.5 m margin, is the ball; so is a robot of ours at x = 5.2 m, and the predictor judges it inside."""
    port = free_udp_port()
    bridge = ros_graph.start_node("erforce_ball_model", "ssl_vision_bridge", params={
        "port": port, "interface": "127.0.0.1", "num_robots": 1, "stats_period_s": 0.5})
    predictor = ros_graph.start_node("erforce_ball_model", "ball_predictor", params={
        "num_robots": 1, "field": "from_geometry"})
    bridge.wait_for_output(r"ssl_vision_bridge: 224\.5\.23\.2", timeout_s=60.0)
    predictor.wait_for_output(r"ball_predictor: 1 robot", timeout_s=60.0)
    probe = ros_graph.probe
    robots = probe.subscribe(contract.VISION_ROBOTS.name, PointCloud2, contract.VISION_ROBOTS.qos)
    states = probe.subscribe(contract.BALL_STATE.name, Odometry, contract.BALL_STATE.qos)
    sender = Sender(port)
    ball, robot = BallCandidate(5.3, 0.0, 0.9), RobotSighting("blue", 0, 5.2, 1.0, 0.0, 1.0)
    try:
        for k in range(60):
            sender.send(sender.frame(0, k / 60.0, [ball], [robot]))
            probe.spin_for(1 / 60.0)
        bridge.wait_for_output(r"ssl_vision_bridge: \d+ datagrams", timeout_s=10.0)  # it has handled them
        assert not robots
        sender.send(encode_geometry(FieldGeometry(12.0, 9.0, 0.3, 1.8, 0.18)))
        bridge.wait_for_output(r"SSL geometry: field 12 x 9 m", timeout_s=10.0)
        predictor.wait_for_output(r"field from SSL geometry: 12 x 9 m", timeout_s=10.0)
        k = 60
        while not (states and any(vision_frame_from_msg(m)[1].size for m in robots)):
            k += 1
            sender.send(sender.frame(0, k / 60.0, [ball], [robot]))
            probe.spin_for(1 / 60.0)
            assert k < 600, bridge.output()[-2000:]
    finally:
        sender.sock.close()
    _t_s, balls, rows = vision_frame_from_msg(robots[-1])
    assert balls.tolist() == [pytest.approx([5.3, 0.0], abs=1e-6)]
    assert [row[2:4] for row in rows.tolist()] == [pytest.approx([5.2, 1.0], abs=1e-6)]  # team, id, x, y, yaw
    assert states[-1].pose.pose.position.x == pytest.approx(5.3, abs=0.01)
    for node in (bridge, predictor):
        out = node.output()
        assert out.count("waiting for SSL geometry") == 1, out[-2000:]
        assert "outside the field" not in out, out[-2000:]


def test_capture_time_becomes_the_stamps_and_clock_whatever_the_worlds_pace(ros_graph):
    """time_source capture: a world at half the wall clock's pace, two cameras whose clocks differ by 0.3 s.
    The stamps are camera 0's capture times (it founds the timeline), camera 1's land on them once measured,
    /clock follows the capture time (never back, at most clock_period_s behind), and holds while vision stops."""
    from rosgraph_msgs.msg import Clock

    port = free_udp_port()
    node = ros_graph.start_node("erforce_ball_model", "ssl_vision_bridge", params={
        "port": port, "interface": "127.0.0.1", "time_source": "capture", "clock_period_s": 0.01,
        "field": "division_b"})  # this sender sends no geometry
    node.wait_for_output(r"stamps: capture", timeout_s=60.0)
    sender = Sender(port)
    q = contract
    clocks = ros_graph.subscribe(q.CLOCK.name, Clock, q.CLOCK.qos)
    frames = ros_graph.subscribe(q.VISION_ROBOTS.name, PointCloud2, q.VISION_ROBOTS.qos)
    period_s = 1.0 / 120.0  # 60 frames a wall second, half a world second
    sent = []  # camera 0's capture times

    def send(k: int) -> None:
        t = k * period_s
        sender.send(sender.frame(0, t, robots=[RobotSighting("blue", 3, -2.0, 1.0, 0.5, 1.0)]))
        sender.send(sender.frame(1, t, robots=[RobotSighting("blue", 7, 2.0, 1.0, 0.5, 1.0)], clock_offset_s=0.3))
        sent.append(VISION_EPOCH_S + t)
        ros_graph.probe.spin_for(1 / 60.0)

    k = 0
    while len(clocks) < 3 or k < 90:  # 1.5 s: camera 1 is measured over 30 frames
        k += 1
        send(k)
        assert k < 600, node.output()[-3000:]
    # vision stops (0.5 s of wall time), then goes on where the world is 2 s later
    n_before, held = len(clocks), sent[-1]
    ros_graph.probe.spin_for(0.5)
    assert len(clocks) == n_before
    k += 240  # 2 s of world time
    for _ in range(60):
        k += 1
        send(k)
    ros_graph.probe.spin_until(lambda: clocks and clock_s(clocks[-1]) == pytest.approx(sent[-1], abs=0.0105),
                               10.0, "/clock at the last capture time")

    values = [clock_s(m) for m in clocks]
    assert all(b > a for a, b in pairwise(values))  # never back, never repeated
    assert all(math.isfinite(v) for v in values)
    # /clock says a frame's capture time: camera 0's, or camera 1's as measured (within 2 ms); held during the
    # gap, then on by the capture time
    captured = set(sent)
    off = [(v - VISION_EPOCH_S, min(captured, key=lambda c: abs(v - c)) - VISION_EPOCH_S) for v in values
           if min(abs(v - c) for c in captured) >= 2e-3]
    assert not off, off
    assert not any(held + 2e-3 < v < held + 2.0 - 2e-3 for v in values)
    stamps_by_robot: dict[int, list[float]] = {3: [], 7: []}
    for t_s, _balls, rows in map(vision_frame_from_msg, frames):
        for row in rows.tolist():
            stamps_by_robot[int(row[1])].append(t_s)
    # camera 0's frames: its capture times (to the resolution of a double at 1.7e9 s)
    assert stamps_by_robot[3] and all(min(abs(t - c) for c in captured) < 1e-6 for t in stamps_by_robot[3])
    # camera 1's, measured (its clock 0.3 s ahead): at camera 0's time of the same capture after 30 frames
    late = stamps_by_robot[7][-60:]
    assert late and all(min(abs(t - c) for c in captured) < 2e-3 for t in late)
    assert node.alive()
    sender.sock.close()


def clock_s(msg) -> float:
    return msg.clock.sec + msg.clock.nanosec * 1e-9
