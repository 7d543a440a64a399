"""ssl_vision_bridge names and counts each class of vision input it drops (ssl_vision.DROP_CLASSES): a camera's
frame whose t_capture is not after its newest one (per camera), a frame's ball candidates beyond 32 (its robots
are kept), garbage, a rejected geometry; each with its own throttled warning, so one class never hides another.
In-process on the compiled pass and on the general path, and over UDP loopback with the periodic statistics.
With camera_alignment (the default) both paths take each camera's estimated offset off its balls and robots."""

from __future__ import annotations

import contextlib
import re

import pytest
from sensor_msgs.msg import PointCloud2

from erforce_interfaces.ssl.ssl_vision import (
    SSL_VISION_GROUP,
    BallCandidate,
    CameraFrame,
    FieldGeometry,
    RobotSighting,
    encode_frame,
    encode_geometry,
)
from erforce_interfaces.tools.processes import free_udp_port
from erforce_interfaces.wire import contract
from erforce_interfaces.wire.clouds import vision_frame_from_msg

VISION_EPOCH_S = 1.7e9  # the vision host's clock
BAD_GEOMETRY = encode_geometry(FieldGeometry(0.0, 6.0, 0.3, 1.0, 0.18))  # a field 0 mm long
GARBAGE = b"\xff\xff\xff\xff\xff"


def frame(camera: int, t_s: float, balls=(), robots=()) -> bytes:
    t_capture = VISION_EPOCH_S + t_s
    return encode_frame(CameraFrame(camera, round(t_s * 1000) % 100_000, t_capture, t_capture + 0.004, tuple(balls),
                                    tuple(robots)))


def crowded_frame(camera: int, t_s: float, robots) -> bytes:
    """40 ball candidates (the ball at (0, 0) first, then 39 in a row along y = 2 m) and ``robots``."""
    balls = [BallCandidate(0.0, 0.0, 0.9)] + [BallCandidate(-2.0 + 0.1 * k, 2.0, 0.3) for k in range(39)]
    return frame(camera, t_s, balls, robots)


@contextlib.contextmanager
def recording_bridge(general_path: bool, *params: str):
    """An in-process ssl_vision_bridge whose /vision/robots bytes and warnings (key, text) are kept in lists; the
    field a preset, as for a vision source that sends no geometry (from_geometry would wait for one)."""
    import rclpy

    from erforce_ball_model.ssl_vision_bridge_node import SslVisionBridge

    args = [f"port:={free_udp_port()}", "interface:=127.0.0.1", "field:=division_b",
            f"publish_detections:={str(general_path).lower()}", *params]
    rclpy.init(args=["--ros-args", *[a for arg in args for a in ("-p", arg)]])
    node = None
    try:
        node = SslVisionBridge()
        published, warnings = [], []

        class Recording:
            def publish(self, data):
                published.append(bytes(data))

        node._robots_pub = Recording()
        node._warn.warn = lambda key, text: warnings.append((key, text))
        yield node, published, warnings
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()


@pytest.mark.parametrize("general_path", [False, True])
def test_each_drop_class_has_its_own_warning_and_counter(general_path):
    with recording_bridge(general_path) as (node, published, warnings):
        ball, ours = BallCandidate(0.0, 0.0, 0.9), RobotSighting("blue", 0, 1.0, 1.0, 0.0, 1.0)

        def send(data: bytes, t_s: float) -> None:
            node.handle_batch([data], 1000.0 + t_s + 0.005)  # received 5 ms after the capture

        t = 0.0
        for k in range(6):
            t = 0.016 * k
            send(frame(0, t, [ball], [ours]), t)
        assert published and not node.drops
        send(frame(0, t, [ball], [ours]), t + 0.001)  # the same frame again
        send(frame(0, t - 0.005, [ball], [ours]), t + 0.002)  # 5 ms older than camera 0's newest
        n = len(published)
        send(frame(1, t - 0.005, [], [ours]), t + 0.003)  # camera 1 has its own order: taken
        assert len(published) == n + 1
        t += 0.016
        theirs = RobotSighting("yellow", 4, -1.0, -1.0, 0.5, 1.0)
        send(crowded_frame(0, t, [ours, theirs]), t)
        _t, _balls, robots = vision_frame_from_msg(published[-1])
        assert sorted(robots[:, 1].tolist()) == [0.0, 4.0]  # the crowded frame's robots, both teams
        assert robots[robots[:, 1] == 4.0, 2:4].tolist() == [[-1.0, -1.0]]
        send(GARBAGE, t)
        send(BAD_GEOMETRY, t)  # right after another class's warning: still named
        t += 0.016
        send(frame(0, t - 10.0, [ball], [ours]), t)  # camera 0's clock starts again: taken, said once
        send(frame(0, t - 10.0 + 0.016, [ball], [ours]), t + 0.016)

        assert dict(node.drops) == {"t_capture_back (camera 0)": 2, "too_many_balls": 8, "garbage": 1,
                                    "geometry": 1}
        by_key = {}
        for key, text in warnings:
            by_key.setdefault(key, []).append(text)
        restart = by_key.pop("t_capture_restart (camera 0)")  # not a drop: the frame is passed on
        assert set(by_key) == set(node.drops)
        for key, texts in by_key.items():
            kind = key.split(" ")[0]
            assert all(text.startswith(f"ssl_vision_bridge: [{kind}] ") for text in texts), texts
        assert by_key["t_capture_back (camera 0)"][1].endswith(
            "5.000 ms before the camera's newest frame (the same frame again, a reordered or a stale one)")
        assert by_key["too_many_balls"] == [
            "ssl_vision_bridge: [too_many_balls] camera 0: 40 ball candidates, 8 beyond the first 32 dropped"]
        assert restart == ["ssl_vision_bridge: camera 0: t_capture went back by 9.984 s: not an old frame but the "
                           "camera's clock starting again (passed on to the time source)"]


@pytest.mark.parametrize("general_path", [False, True])
def test_the_capture_timelines_refusals_go_under_the_same_classes(general_path):
    """time_source capture: the capture order drops an old frame before the timeline sees it; a camera's clock
    starting again is passed on, and the timeline refuses its new line as clock_jump until 5 frames span 0.2 s
    of receive time (at 30 ms apart the 8th frame: 7 x 30 ms = 0.21 s); a frame of the old line that comes in
    between is after the order's newest (the new line) but not after the timeline's: t_capture_back too."""
    with recording_bridge(general_path, "time_source:=capture") as (node, published, warnings):
        ball, ours = BallCandidate(0.0, 0.0, 0.9), RobotSighting("blue", 0, 1.0, 1.0, 0.0, 1.0)

        def send(t_s: float, t_wall_s: float) -> None:
            node.handle_batch([frame(0, t_s, [ball], [ours])], 0.0, t_wall_s)

        for k in range(6):
            send(0.03 * k, 100.0 + 0.03 * k)
        assert len(published) == 6 and not node.drops
        send(0.15 - 0.005, 100.16)  # 5 ms before the newest: the order's
        for j in range(8):
            send(0.15 - 10.0 + 0.03 * j, 100.2 + 0.03 * j)  # the camera's clock started again 10 s back
            assert len(published) == (6 if j < 7 else 7), j
            if j == 2:
                send(0.15 - 0.002, 100.2 + 0.03 * j)  # the old line once more: the timeline's
        assert dict(node.drops) == {"t_capture_back (camera 0)": 2, "clock_jump (camera 0)": 7}
        by_key = {}
        for key, text in warnings:
            by_key.setdefault(key, []).append(text)
        assert len(by_key.pop("t_capture_restart (camera 0)")) == 2  # the new line, and again after the old frame
        assert set(by_key) == set(node.drops)
        back = by_key["t_capture_back (camera 0)"]
        assert back[0].endswith("5.000 ms before the camera's newest frame (the same frame again, a reordered or a "
                                "stale one)")
        assert "2.000 ms before the camera's newest frame" in back[1]
        assert by_key["clock_jump (camera 0)"][0].startswith("ssl_vision_bridge: [clock_jump] camera 0: t_capture ")
        assert "goes back 10.000 s from its newest on the capture timeline" in by_key["clock_jump (camera 0)"][0]


@pytest.mark.integration
def test_drops_over_udp_are_named_and_counted_in_the_statistics(ros_graph):
    """The compiled pass (the bridge's default configuration) over loopback multicast."""
    from erforce_sim.ssl_cameras import open_multicast_sender

    port = free_udp_port()
    node = ros_graph.start_node("erforce_ball_model", "ssl_vision_bridge", params={
        "port": port, "interface": "127.0.0.1", "team_color": "yellow", "stats_period_s": 0.5,
        "field": "division_b"})  # a source without geometry
    node.wait_for_output(r"ssl_vision_bridge: 224\.5\.23\.2", timeout_s=60.0)
    q = contract
    frames = ros_graph.subscribe(q.VISION_ROBOTS.name, PointCloud2, q.VISION_ROBOTS.qos)
    sock = open_multicast_sender("127.0.0.1")
    try:
        ours = RobotSighting("yellow", 1, 0.5, 0.5, 0.0, 1.0)
        k = 0
        while not frames:  # until the reader is matched
            k += 1
            sock.sendto(frame(0, k / 60.0, [], [ours]), (SSL_VISION_GROUP, port))
            ros_graph.probe.spin_for(1 / 60.0)
            assert k < 600, node.output()[-3000:]
        t = k / 60.0
        crowded_robot = RobotSighting("yellow", 2, 2.0, -1.5, 1.0, 1.0)
        for data in (frame(0, t, [], [ours]), crowded_frame(1, t, [crowded_robot]), GARBAGE, BAD_GEOMETRY):
            sock.sendto(data, (SSL_VISION_GROUP, port))
        for text in (r"\[t_capture_back\] camera 0: frame with t_capture .* 0\.000 ms before",
                     r"\[too_many_balls\] camera 1: 40 ball candidates, 8 beyond the first 32 dropped",
                     r"\[garbage\] dropped a datagram", r"\[geometry\] geometry dropped: field sizes"):
            node.wait_for_output(text, timeout_s=10.0)

        def crowded_robot_published() -> bool:
            return any(any(row[1] == 2.0 and row[2:4] == pytest.approx([2.0, -1.5]) for row in rows.tolist())
                       for _t, _b, rows in map(vision_frame_from_msg, frames))

        ros_graph.probe.spin_until(crowded_robot_published, 10.0, "the crowded frame's robot on /vision/robots")
        stats = re.escape("dropped by class: garbage 1, geometry 1, t_capture_back (camera 0) 1, too_many_balls 8") + (
            r"; tracker: \d+ late balls, \d+ false candidates, \d+ ball switches")
        for _ in range(200):  # good frames until a statistics line comes
            k += 1
            sock.sendto(frame(0, k / 60.0, [], [ours]), (SSL_VISION_GROUP, port))
            ros_graph.probe.spin_for(1 / 60.0)
            if re.search(stats, node.output()):
                break
        node.wait_for_output(stats, timeout_s=1.0)
        assert node.alive()
    finally:
        sock.close()


@pytest.mark.parametrize("general_path", [False, True])
def test_camera_alignment_takes_each_cameras_offset_off_its_balls_and_robots(general_path):
    """camera_alignment (default true), on the compiled pass and on the general path: two cameras report the same
    robots 2 cm apart along x (camera 0 at -1 cm, camera 1 at +1 cm); a ball at rest at (0.1, 0.5) that both see
    comes out of the bridge at 0.1 from either camera, where the raw reports say 0.09 and 0.11, and so do the
    robots, at their true places. The offsets the bridge learnt are each camera's, less their mean."""
    with recording_bridge(general_path) as (node, published, warnings):
        assert node._alignment is not None and node._fast == (not general_path)
        offsets = {0: -0.01, 1: 0.01}
        robots = [("blue", 0, 0.2, 1.0), ("blue", 1, -0.3, -1.0), ("yellow", 2, 0.0, 2.0)]
        t = 0.0
        for k in range(60):
            t = k / 70.0
            for camera, dx in offsets.items():
                seen = [RobotSighting(team, rid, x + dx, y, 0.0, 1.0) for team, rid, x, y in robots]
                node.handle_batch([frame(camera, t, [BallCandidate(0.1 + dx, 0.5, 0.9)], seen)], 1000.0 + t + 0.005)
        for camera, dx in offsets.items():
            assert node._alignment.offset_m(camera) == pytest.approx((dx, 0.0), abs=2e-4)  # SSL's 1 mm steps
        balls = [vision_frame_from_msg(data)[1] for data in published[-2:]]
        assert all(len(b) for b in balls)
        for b in balls:
            assert b[0][0] == pytest.approx(0.1, abs=2e-4) and b[0][1] == pytest.approx(0.5, abs=2e-4)
        for data in published[-2:]:
            rows = vision_frame_from_msg(data)[2]
            assert sorted(rows[:, 1].tolist()) == [0.0, 1.0, 2.0]
            for _team, rid, x, y in robots:
                assert rows[rows[:, 1] == rid, 2:4].tolist()[0] == pytest.approx([x, y], abs=2e-4)
        assert not warnings
