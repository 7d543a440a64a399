"""ssl_ball_predictor: the SSL-Vision bridge and the ball predictor in one process. Hand-built SSL-Vision datagrams
over loopback multicast reach the bridge's receive thread, which has the predictor answer each camera frame before
the frame's /vision/robots is published. In-process: the nodes' publishers are replaced by recorders."""

from __future__ import annotations

import socket
import threading

import numpy as np
import pytest
import rclpy

from erforce_ball_model.ball_model import ChipParams
from erforce_ball_model.chip_model import ChipTrajectory
from erforce_ball_model.ssl_ball_predictor import make_nodes
from erforce_interfaces.ssl.ssl_vision import (
    SSL_VISION_GROUP,
    BallCandidate,
    CameraFrame,
    CameraPose,
    FieldGeometry,
    RobotSighting,
    encode_frame,
    encode_geometry,
)
from erforce_interfaces.wire.clouds import vision_cloud_from_msg, vision_frame_from_msg
from erforce_interfaces.wire.conversions import float64_from_msg, odometry_from_msg, odometry_height
from erforce_interfaces.wire.robot_config import FieldConfig, RobotConfig
from erforce_sim.ssl_cameras import ground_point, open_multicast_sender

# the predictor's defaults (params/ball_predictor.yaml): reaction time, robot limits
REACTION_S, A_MAX_MPS2, V_MAX_MPS = 0.1, 4.5, 2.5
FPS = 60.0


def free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def rest_to_rest_s(d_m: float) -> float:
    """Bang-bang time from rest to rest over ``d_m`` with the limits above (triangle or trapezoid profile)."""
    if d_m <= V_MAX_MPS**2 / A_MAX_MPS2:
        return 2.0 * np.sqrt(d_m / A_MAX_MPS2)
    return d_m / V_MAX_MPS + V_MAX_MPS / A_MAX_MPS2


class Recorder:
    """A publisher that notes what went out, in order, in a list shared by all recorders."""

    def __init__(self, name: str, log: list, sent: threading.Condition) -> None:
        self.name, self.log, self.sent = name, log, sent

    def publish(self, data) -> None:
        with self.sent:
            self.log.append((self.name, data))
            self.sent.notify_all()


def test_a_datagram_is_answered_with_a_catch_time_before_its_frame_is_published():
    """Our robot 0 rests at (0, 1) facing +x; a ball rests at (1, 1); camera 0 sees both, 60 frames a second (SSL
    units: mm, the encoder's). Once the bridge's tracker takes the ball, every datagram is answered on the receive
    thread with robot_0's catch time, before the bridge publishes the frame: the reaction time plus a rest-to-rest
    drive over 1 m less the dribbler offset (the robot already faces the ball)."""
    port = free_udp_port()
    rclpy.init(args=["--ros-args", "-p", f"port:={port}", "-p", "interface:=127.0.0.1", "-p", "time_source:=vision",
                     "-p", "num_robots:=1", "-p", "team_color:=yellow", "-p", "field:=division_b"])
    bridge = predictor = None
    sender = open_multicast_sender("127.0.0.1")
    try:
        bridge, predictor = make_nodes()
        log: list = []
        sent = threading.Condition()
        receive_thread = []
        robots_recorder = Recorder("robots", log, sent)
        catch_recorder = Recorder("catch_time", log, sent)
        original = catch_recorder.publish

        def catch_publish(data):
            receive_thread.append(threading.current_thread().name)
            original(data)

        catch_recorder.publish = catch_publish
        bridge._robots_pub = robots_recorder
        predictor._catch_time_pubs[0] = catch_recorder
        predictor._time_readers[0] = 1
        frames = 30
        for k in range(frames):
            t_capture = 1.0 + k / FPS
            data = encode_frame(CameraFrame(0, k + 1, t_capture, t_capture + 0.002, (BallCandidate(1.0, 1.0, 0.9),),
                                            (RobotSighting("yellow", 0, 0.0, 1.0, 0.0, 1.0),)))
            with sent:
                before = sum(1 for name, _ in log if name == "robots")
                sender.sendto(data, (SSL_VISION_GROUP, port))
                # each datagram's frame is published before the next is sent: one frame per batch, in order
                assert sent.wait_for(lambda b=before: sum(1 for name, _ in log if name == "robots") > b, 10.0), \
                    f"datagram {k} not published"
        names = [name for name, _ in log]
        assert names.count("robots") == frames
        catches = [i for i, name in enumerate(names) if name == "catch_time"]
        assert len(catches) >= frames - 8, names  # the ball is taken once the tracker confirmed it
        # each catch time goes out before the frame that carried its ball is published
        for i in catches:
            assert names[i + 1] == "robots", names
            _t_s, balls, _robots = vision_frame_from_msg(log[i + 1][1])
            assert balls.tolist() == [pytest.approx([1.0, 1.0], abs=1e-9)]
        assert set(receive_thread) == {"ssl_vision_rx"}
        expected = REACTION_S + rest_to_rest_s(1.0 - RobotConfig().dribbler_offset_m)
        times = [float64_from_msg(log[i][1]) for i in catches]
        assert times == [pytest.approx(expected, abs=1e-3)] * len(times)
    finally:
        sender.close()
        for node in (bridge, predictor):
            if node is not None:
                node.destroy_node()
        rclpy.try_shutdown()


def test_the_predictor_takes_no_vision_topic_and_each_node_keeps_its_name():
    rclpy.init(args=["--ros-args", "-p", f"port:={free_udp_port()}", "-p", "interface:=127.0.0.1"])
    nodes = ()
    try:
        nodes = make_nodes()
        bridge, predictor = nodes
        assert (bridge.get_name(), predictor.get_name()) == ("ssl_vision_bridge", "ball_predictor")
        assert "/vision/robots" not in {s.topic_name for s in predictor.subscriptions}
        assert {"/vision/field", "/vision/ball_model"} <= {s.topic_name for s in predictor.subscriptions}
        # inline parameters reach both (launch keys them /**): each declares those of its own schema
        assert bridge.has_parameter("port") and not predictor.has_parameter("port")
        assert predictor.has_parameter("reaction_s") and not bridge.has_parameter("reaction_s")
    finally:
        for node in nodes:
            node.destroy_node()
        rclpy.try_shutdown()


def test_the_predictor_has_the_worlds_field_before_the_first_frame_it_answers():
    """Default parameters: the bridge waits for SSL geometry (field: from_geometry) and hands it to the predictor
    on its receive thread before the frames after it. Division A's geometry (lines at |x| = 6 m): our robot at
    x = 5.2 m, beyond Division B's 4.5 m plus the predictor's 0.5 m margin, is tracked, never judged outside."""
    port = free_udp_port()
    rclpy.init(args=["--ros-args", "-p", f"port:={port}", "-p", "interface:=127.0.0.1", "-p", "num_robots:=1"])
    nodes = ()
    sender = open_multicast_sender("127.0.0.1")
    try:
        nodes = bridge, predictor = make_nodes()
        fields, warnings, answered = [], [], threading.Condition()
        predictor._predictor._warn = lambda key, text: warnings.append(text)
        answer = predictor.answer_vision

        def sink(data: bytes) -> None:
            field = predictor._predictor.config.field
            answer(data)
            with answered:
                fields.append(field)
                answered.notify_all()

        bridge._frame_sink = sink
        frames = [encode_frame(CameraFrame(0, k + 1, 1.0 + k / FPS, 1.0 + k / FPS + 0.002,
                                           (BallCandidate(1.0, 1.0, 0.9),),
                                           (RobotSighting("blue", 0, 5.2, 1.0, 0.0, 1.0),))) for k in range(40)]
        for data in frames[:10]:  # before geometry: not used (no frame goes out to wait for)
            sender.sendto(data, (SSL_VISION_GROUP, port))
        sender.sendto(encode_geometry(FieldGeometry(12.0, 9.0, 0.3, 1.8, 0.18)), (SSL_VISION_GROUP, port))
        for data in frames[10:]:
            with answered:
                before = len(fields)
                sender.sendto(data, (SSL_VISION_GROUP, port))
                assert answered.wait_for(lambda b=before: len(fields) > b, 10.0), "a frame after the geometry"
        assert fields and set(fields) == {FieldConfig.preset("division_a")}
        assert predictor._predictor.robot_states_at(2.0, [0])[0][0] == pytest.approx(5.2, abs=0.01)
        assert warnings == []
    finally:
        sender.close()
        for node in nodes:
            node.destroy_node()
        rclpy.try_shutdown()


@pytest.mark.parametrize(("defend_side", "packet_per_camera"), [("negative_x", False), ("positive_x", False),
                                                                  ("negative_x", True)])
def test_a_chip_is_in_the_air_on_ball_state_from_one_cameras_frames(defend_side, packet_per_camera):
    """The geometry gives each camera's position; each frame the bridge hands the predictor names its camera
    (half turned with the field when we defend +x), whose chip detector reconstructs the flight from the curve one
    camera sees. The cameras' calibrations come in one geometry packet, or each in its own (as grSim sends them:
    camera 1's first, so the packet last received does not name it).
    Camera 1 at (2, 1.5, 4) m sees a ball kicked at 2 m/s sideways and 3 m/s up from (1, 0.5) m (SSL-Vision's
    frame; a robot stands in every frame), noise-free, 60 frames a second after 0.5 s at rest: /ball/state carries
    its height, matching the projectile z = 3 t - 9.81 t^2 / 2 within 2 cm, before the first touchdown (0.61 s)."""
    port = free_udp_port()
    rclpy.init(args=["--ros-args", "-p", f"port:={port}", "-p", "interface:=127.0.0.1", "-p", "time_source:=vision",
                     "-p", "num_robots:=1", "-p", f"defend_side:={defend_side}"])
    nodes = ()
    sender = open_multicast_sender("127.0.0.1")
    try:
        nodes = bridge, predictor = make_nodes()
        cameras, states, answered = [], [], threading.Condition()
        answer = predictor.answer_vision

        def sink(data: bytes) -> None:
            answer(data)
            with answered:
                cameras.append(vision_cloud_from_msg(data).camera_m)
                answered.notify_all()

        bridge._frame_sink = sink
        predictor._state_pub = Recorder("state", states, threading.Condition())
        camera = (2.0, 1.5, 4.0)
        poses = (CameraPose(1, *camera), CameraPose(0, -2.0, -1.5, 4.0))
        for group in ((pose,) for pose in poses) if packet_per_camera else (poses,):
            sender.sendto(encode_geometry(FieldGeometry(9.0, 6.0, 0.3, 1.0, 0.18, cameras=group)),
                          (SSL_VISION_GROUP, port))
        t_kick = 1.5
        chip = ChipTrajectory((1.0, 0.5, 0.0), (0.0, 2.0, 3.0), ChipParams())
        for k in range(int(0.55 * FPS) + int((t_kick - 1.0) * FPS)):
            t = 1.0 + k / FPS
            x, y, z = chip.position_at(max(t - t_kick, 0.0)).tolist()
            gx, gy = ground_point(x, y, z, camera)
            with answered:
                before = len(cameras)
                sender.sendto(encode_frame(CameraFrame(1, k + 1, t, t + 0.002, (BallCandidate(gx, gy, 0.9),),
                                                        (RobotSighting("blue", 0, -1.0, -1.0, 0.0, 1.0),))),
                              (SSL_VISION_GROUP, port))
                assert answered.wait_for(lambda b=before: len(cameras) > b, 10.0), f"frame {k} not answered"
        sign = 1.0 if defend_side == "negative_x" else -1.0  # the field frame: SSL-Vision's half turned
        assert cameras == [pytest.approx((sign * 2.0, sign * 1.5, 4.0), abs=1e-6)] * len(cameras)
        in_air = [(odometry_from_msg(m)[0], odometry_height(m)[0]) for _, m in states if odometry_height(m)[0] > 0.0]
        assert in_air, "no state in the air"
        for t, z in in_air:
            dt = t - t_kick
            assert z == pytest.approx(3.0 * dt - 0.5 * 9.81 * dt * dt, abs=0.02)
        assert in_air[0][0] - t_kick < 2.0 * 3.0 / 9.81
        assert max(z for _, z in in_air) > 0.2
    finally:
        sender.close()
        for node in nodes:
            node.destroy_node()
        rclpy.try_shutdown()
