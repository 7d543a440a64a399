"""Every camera's ball reaches the ball predictor over DDS with its camera's position (docs/decisions/0035).

SSL-Vision datagrams over loopback multicast into ssl_vision_bridge; ball_predictor in the same process takes the
bridge's /vision/robots from DDS (not the in-process hand-over of ssl_ball_predictor). The geometry is written byte
by byte from the league's protobuf field numbers; the frames of two overlapping cameras of one capture each carry
the ball where that camera's ray meets the ground.
"""

from __future__ import annotations

import math
import socket
import struct
import threading
import time

import pytest
import rclpy
from rclpy.executors import SingleThreadedExecutor

from erforce_ball_model.ball_model import ChipParams
from erforce_ball_model.ball_predictor_node import BallPredictorNode
from erforce_ball_model.chip_model import ChipTrajectory
from erforce_ball_model.predictor import BallPredictor, PredictorConfig
from erforce_ball_model.ssl_vision_bridge_node import SslVisionBridge
from erforce_interfaces.ssl.ssl_vision import SSL_VISION_GROUP, BallCandidate, CameraFrame, decode_wrapper, encode_frame
from erforce_interfaces.tools.processes import DomainLease
from erforce_interfaces.wire.robot_config import FieldConfig
from erforce_sim.sensors import BallDetection as TrueBall
from erforce_sim.sensors import VisionFrame
from erforce_sim.ssl_cameras import BENCH_CAMERAS, SslCameraSplitter, open_multicast_sender, quadrant_cameras

FPS = 60.0


def free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def _f32(tag: int, value: float) -> bytes:
    return bytes([tag]) + struct.pack("<f", value)


def _sub(tag: int, payload: bytes) -> bytes:
    assert len(payload) < 128
    return bytes([tag, len(payload)]) + payload


def _calibration(camera_id: int, x_mm: float, y_mm: float, z_mm: float) -> bytes:
    """SSL_GeometryCameraCalibration: camera_id 1 (varint), focal_length 2, principal_point_x/y 3/4, distortion 5,
    q0..q3 6..9, tx/ty/tz 10..12 (fixed32 each; required), derived_camera_world_tx/ty/tz 13/14/15 (fixed32)."""
    required = b"".join(_f32((field << 3) | 5, value) for field, value in (
        (2, 400.0), (3, 390.0), (4, 290.0), (5, 0.1), (6, 0.0), (7, 1.0), (8, 0.0), (9, 0.0), (10, 0.0), (11, 0.0),
        (12, z_mm)))
    return bytes([0x08, camera_id]) + required + _f32(0x6D, x_mm) + _f32(0x75, y_mm) + _f32(0x7D, z_mm)


# Division B (the league's rules: 9 x 6 m, a 0.3 m run-off, goals 1 m wide, 0.18 m deep) in mm as varints:
# field_length 1, field_width 2, goal_width 3, goal_depth 4, boundary_width 5; two cameras above the +x half, 4 m high.
CAMERA_1_MM, CAMERA_3_MM = (2250.0, 1500.0, 4000.0), (2250.0, -1500.0, 4000.0)
FIELD_SIZE = b"\x08\xa8\x46" + b"\x10\xf0\x2e" + b"\x18\xe8\x07" + b"\x20\xb4\x01" + b"\x28\xac\x02"
GEOMETRY = (_sub(0x0A, FIELD_SIZE) + _sub(0x12, _calibration(1, *CAMERA_1_MM))
            + _sub(0x12, _calibration(3, *CAMERA_3_MM)))
# SSL_WrapperPacket.geometry = 2, its length a two-byte varint
WRAPPER_GEOMETRY = bytes([0x12, len(GEOMETRY) & 0x7F | 0x80, len(GEOMETRY) >> 7]) + GEOMETRY


def seen_from(camera_m, x: float, y: float, z: float) -> tuple[float, float]:
    """Where a camera at ``camera_m`` sees a ball at height ``z`` on the ground: along its ray, c + (p - c) cz / (cz -
    z)."""
    cx, cy, cz = camera_m
    s = cz / (cz - z)
    return cx + (x - cx) * s, cy + (y - cy) * s


class Graph:
    """ssl_vision_bridge and ball_predictor (its /vision/robots from DDS) in one process and one executor, with the
    predictor's calls of its core recorded and the bridge's published frames counted."""

    def __init__(self, port: int, defend_side: str = "negative_x") -> None:
        self.lease = DomainLease()
        rclpy.init(args=["--ros-args", "-p", f"port:={port}", "-p", "interface:=127.0.0.1", "-p",
                         "time_source:=vision", "-p", "num_robots:=1", "-p", f"defend_side:={defend_side}", "-p",
                         "field:=division_b"], domain_id=self.lease.domain_id)
        self.nodes = []
        self.predictor = BallPredictorNode()
        self.nodes.append(self.predictor)
        self.bridge = SslVisionBridge()
        self.nodes.insert(0, self.bridge)  # destroyed first: its receive thread stops
        self.calls: list[tuple] = []  # ("frame" | "sighting", t_s, x, y, camera_m, the frame's answer)
        self.published = self.answered = 0
        self.changed = threading.Condition()
        core = self.predictor._predictor
        ball_frame, ball_sighting = core.ball_frame, core.ball_sighting

        def frame(t_s, x, y, **kwargs):
            answer = ball_frame(t_s, x, y, **kwargs)
            self.calls.append(("frame", t_s, x, y, kwargs.get("camera_m"), answer))
            return answer

        def sighting(t_s, x, y, camera_m):
            ball_sighting(t_s, x, y, camera_m)
            self.calls.append(("sighting", t_s, x, y, camera_m, None))

        core.ball_frame, core.ball_sighting = frame, sighting
        # the predictor answers a frame's robots last (_frame_rest), also of frames queued behind the one it woke for
        publish_frame, frame_rest = self.bridge._publish_frame, self.predictor._frame_rest

        def published(data):
            publish_frame(data)
            with self.changed:
                self.published += 1

        def answered(start, msg, leading):
            frame_rest(start, msg, leading)
            with self.changed:
                self.answered += 1
                self.changed.notify_all()

        self.bridge._publish_frame, self.predictor._frame_rest = published, answered
        self.executor = SingleThreadedExecutor()
        for node in self.nodes:
            self.executor.add_node(node)
        self.spinning = threading.Thread(target=self.executor.spin, daemon=True)
        self.spinning.start()
        self.sender = open_multicast_sender("127.0.0.1")
        self.address = (SSL_VISION_GROUP, port)

    def send(self, datagrams: list[bytes]) -> None:
        """Send a capture's datagrams and wait until the predictor answered every frame the bridge published."""
        before = self.bridge.stats["datagrams"]
        for data in datagrams:
            self.sender.sendto(data, self.address)
        deadline = time.monotonic() + 10.0
        while self.bridge.stats["datagrams"] < before + len(datagrams):
            assert time.monotonic() < deadline, "the bridge did not take the datagrams"
            time.sleep(0.001)
        with self.changed:
            assert self.changed.wait_for(lambda: self.answered >= self.published, 10.0), \
                f"the predictor answered {self.answered} of {self.published} frames"

    def close(self) -> None:
        self.sender.close()
        self.executor.shutdown(timeout_sec=1.0)
        for node in self.nodes:
            node.destroy_node()
        rclpy.try_shutdown()
        self.lease.release()


@pytest.mark.parametrize("defend_side", ["negative_x", "positive_x"])
def test_the_predictor_takes_every_cameras_ball_with_the_cameras_position(defend_side):
    """Cameras 1 and 3 (at (2.25, +-1.5, 4) m) both see a ball on y = 0, first at rest at (1.2, 0), then chipped
    along +x at 2 m/s and 2 m/s up, each where its own ray meets the ground; camera 1's frame of a capture goes first.
    Once the bridge's tracker took the ball (3 frames), every capture reaches the predictor twice: camera 1's ball
    as the ball's frame with camera 1's position, camera 3's as a sighting at the same stamp with camera 3's (both
    half turned when we defend +x, as the balls are)."""
    port = free_udp_port()
    graph = Graph(port, defend_side)
    try:
        graph.send([WRAPPER_GEOMETRY])
        sign = 1.0 if defend_side == "negative_x" else -1.0
        cameras = {camera_id: (sign * x / 1e3, sign * y / 1e3, z / 1e3)
                   for camera_id, (x, y, z) in ((1, CAMERA_1_MM), (3, CAMERA_3_MM))}
        t_kick, captures = 1.3, 36
        seen = {}  # capture time -> {camera id: the ball as sent, in the field frame}
        for k in range(captures):
            t = 1.0 + k / FPS
            tau = max(t - t_kick, 0.0)
            x, y, z = 1.2 + 2.0 * tau, 0.0, 2.0 * tau - 0.5 * 9.81 * tau * tau
            seen[t] = {}
            datagrams = []
            for camera_id in (1, 3):
                gx, gy = seen_from(tuple(v / 1e3 for v in (CAMERA_1_MM if camera_id == 1 else CAMERA_3_MM)),
                                   x, y, max(z, 0.0))
                seen[t][camera_id] = (sign * gx, sign * gy)
                datagrams.append(encode_frame(CameraFrame(camera_id, k + 1, t, t + 0.002,
                                                          (BallCandidate(gx, gy, 0.9),), ())))
            graph.send(datagrams)
        frames = [c for c in graph.calls if c[0] == "frame"]
        sightings = [c for c in graph.calls if c[0] == "sighting"]
        # from the capture whose ball the tracker first took (once it confirmed it), every capture, twice
        first = round((frames[0][1] - 1.0) * FPS)
        assert first <= 3
        assert [c[1] for c in frames] == pytest.approx([1.0 + k / FPS for k in range(first, captures)], abs=1e-9)
        assert [c[1] for c in sightings] == pytest.approx([1.0 + k / FPS for k in range(first, captures)], abs=1e-9)
        assert graph.calls[0][0] == "frame" and all(
            a[0] == "frame" and b[0] == "sighting" and a[1] == b[1] for a, b in zip(graph.calls[::2],
                                                                                   graph.calls[1::2], strict=True))
        for kind, camera_id, calls in (("frame", 1, frames), ("sighting", 3, sightings)):
            for _, t, x, y, camera_m, _answer in calls:
                assert camera_m == pytest.approx(cameras[camera_id], abs=1e-6), (kind, t)
                want = min(seen, key=lambda s, t=t: abs(s - t))
                assert (x, y) == pytest.approx(seen[want][camera_id], abs=1e-5), (kind, t)  # float32 mm on the wire
        # the chip flies high enough for the two rays to tell: the predictor reports it in the air
        assert any(c[5] is not None and c[5].chip is not None for c in frames)
    finally:
        graph.close()


def in_process_and_graph_frames(chip: ChipTrajectory, t_kick: float, seconds: float):
    """The quadrant cameras' datagrams of ``chip`` (noise-free) per capture at 60 Hz: the geometry first."""
    field = FieldConfig.preset("division_b")
    splitter = SslCameraSplitter(quadrant_cameras(field), field, None, realism=BENCH_CAMERAS.noise_free())
    captures = []
    for k in range(int(seconds * FPS)):
        t = 1.0 + k / FPS
        x, y, z = chip.position_at(max(t - t_kick, 0.0)).tolist()
        frame = VisionFrame(k, t, t + 0.01, (TrueBall(x, y, z),), ())
        captures.append((t, [data for _release, data in sorted(splitter.packets(frame), key=lambda p: p[0])]))
    return splitter, captures


def test_a_chip_in_two_cameras_is_detected_on_the_graph_when_the_in_process_predictor_detects_it():
    """The same datagrams of a chip along the overlap of the quadrant cameras 1 and 3 (y = 0), noise-free: the
    in-process path (each capture's first camera's ball to ball_frame, the others' to ball_sighting, as
    bench/bench_chip.py) and the graph (bridge, /vision/robots over DDS, the predictor node) report the chip first
    at the same capture, with the same height, which the two cameras' rays give: the true height within 1 cm."""
    chip = ChipTrajectory((1.0, 0.0, 0.0), (2.5, 0.0, 2.5), ChipParams())  # 3.5 m/s at 45 deg: apex 0.32 m
    t_kick = 1.4 + 0.3 / FPS
    splitter, captures = in_process_and_graph_frames(chip, t_kick, 0.8)
    field = FieldConfig.preset("division_b")
    cameras = {c.camera_id: (c.x_m, c.y_m, c.z_m) for c in splitter.geometry.cameras}
    predictor = BallPredictor(PredictorConfig(num_robots=1, field=field))
    in_process = None
    for t, datagrams in captures:
        sightings = [(b[0], b[1], cameras[det.camera_id]) for det in (decode_wrapper(d).detection for d in datagrams)
                     for b in det.balls.tolist()]
        answer = None
        for i, (x, y, camera) in enumerate(sightings):
            if i == 0:
                answer = predictor.ball_frame(t, x, y, camera_m=camera)
            else:
                predictor.ball_sighting(t, x, y, camera)
        if answer is not None and answer.chip is not None:
            in_process = (t, answer.chip.position_m.tolist()[2])
            break
    assert in_process is not None, "the in-process predictor never saw the chip"
    assert in_process[1] == pytest.approx(chip.position_at(in_process[0] - t_kick).tolist()[2], abs=0.01)
    port = free_udp_port()
    graph = Graph(port)
    try:
        graph.send([splitter.geometry_packet()])
        for t, datagrams in captures:
            graph.send(datagrams)
            if t >= in_process[0]:
                break
        first = next(((c[1], c[5].chip.position_m.tolist()[2]) for c in graph.calls
                      if c[0] == "frame" and c[5] is not None and c[5].chip is not None), None)
        assert first is not None, "the graph's predictor never saw the chip"
        assert first[0] == pytest.approx(in_process[0], abs=1e-9)
        assert first[1] == pytest.approx(in_process[1], abs=1e-6)
        assert not math.isnan(first[1])
    finally:
        graph.close()
