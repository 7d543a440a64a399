"""The field_view node over DDS: its Foxglove WebSocket server forwards the graph's topics with their
ROS 2 schemas, and its page replays a recorded bag in headless Chromium (time slider, pause, speed)."""

from __future__ import annotations

import json
import math
import re
import socket
import struct
import time
from pathlib import Path

import pytest
from nav_msgs.msg import Odometry
from rclpy.serialization import deserialize_message, serialize_message
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore
from test_field_view_browser import ARTIFACTS, require_chromium
from websockets.sync.client import connect

from erforce_ball_model.passing.decisions import PassConfig, PassOption
from erforce_interfaces.wire import contract as c
from erforce_interfaces.wire.conversions import odometry_msg
from erforce_sim.demo.demo import LAUNCH_FILE
from erforce_sim.demo.passing_report import pass_choice_cdr
from erforce_sim.view.foxglove_bridge import PLOTS_TOPIC, SCENE_TOPIC, layout_json
from erforce_sim.view.headless_browser import Browser

pytestmark = pytest.mark.integration


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_the_foxglove_layout_in_the_repository_is_the_generated_one():
    path = Path(__file__).resolve().parents[2] / "src" / "erforce_sim" / "config" / "foxglove_layout.json"
    assert path.read_text() == layout_json(), (
        "regenerate: python -m erforce_sim.view.foxglove_bridge > " + str(path))
    layout = json.loads(path.read_text())
    scene = layout["content"]["items"][0]["content"]
    assert scene["panelType"] == "ThreeDee" and SCENE_TOPIC in scene["config"]["topics"]


def test_foxglove_clients_get_the_graphs_topics_as_cdr_with_ros2msg_schemas(ros_graph):
    ros_graph.start_launch(LAUNCH_FILE, real_time_factor="1.0", output="screen")
    port = free_port()
    view = ros_graph.start_node("erforce_sim", "field_view", params={"port": 0, "foxglove_port": port})
    view.wait_for_output(r"Foxglove WebSocket server at", timeout_s=60.0)
    wanted = {c.GROUND_TRUTH_BALL.name, c.CATCH_TIME.for_robot(0), SCENE_TOPIC, PLOTS_TOPIC}
    channels: dict[str, dict] = {}
    deadline = time.monotonic() + 90.0
    with connect(f"ws://127.0.0.1:{port}", subprotocols=["foxglove.sdk.v1"], open_timeout=10) as ws:
        while not wanted <= set(channels):  # the node advertises topics as it discovers them
            assert time.monotonic() < deadline, f"advertised only {sorted(channels)}"
            try:
                message = ws.recv(timeout=1.0)
            except TimeoutError:
                continue
            if isinstance(message, str) and json.loads(message)["op"] == "advertise":
                channels.update({ch["topic"]: ch for ch in json.loads(message)["channels"]})
        ball = channels[c.GROUND_TRUTH_BALL.name]
        assert (ball["encoding"], ball["schemaName"], ball["schemaEncoding"]) == (
            "cdr", "nav_msgs/msg/Odometry", "ros2msg")
        definition, _ = get_typestore(Stores.ROS2_JAZZY).generate_msgdef("nav_msgs/msg/Odometry", ros_version=2)
        assert ball["schema"] == definition and "MSG: geometry_msgs/PoseWithCovariance" in ball["schema"]
        catch_time = channels[c.CATCH_TIME.for_robot(0)]
        assert (catch_time["schemaName"], catch_time["schema"].strip()) == ("std_msgs/msg/Float64", "float64 data")
        order = [c.GROUND_TRUTH_BALL.name, SCENE_TOPIC, PLOTS_TOPIC]
        ws.send(json.dumps({"op": "subscribe", "subscriptions": [
            {"id": i, "channelId": channels[topic]["id"]} for i, topic in enumerate(order)]}))
        payloads: dict[int, bytes] = {}
        while len(payloads) < len(order):
            assert time.monotonic() < deadline, f"messages only on {sorted(payloads)}"
            message = ws.recv(timeout=10.0)
            if isinstance(message, bytes) and message[0] == 1:  # message data: opcode, subscription, log time
                subscription, _log_time = struct.unpack_from("<IQ", message, 1)
                if subscription == 2 and "ball_speed_true" not in json.loads(message[13:]):
                    continue  # a frame before the view's first ground truth has no true speed yet
                payloads.setdefault(subscription, message[13:])
    truth = deserialize_message(payloads[0], Odometry)  # the plant's bytes, as sent
    p = truth.pose.pose.position
    assert math.isfinite(p.x) and abs(p.x) < 5.0 and abs(p.y) < 4.0 and truth.header.frame_id == c.FIELD_FRAME
    plots = json.loads(payloads[2])
    assert plots["current_limit_a"] == 1.3 and plots["ball_speed_true"] >= 0.0
    assert len(payloads[1]) > 100  # a SceneUpdate (protobuf): field lines, two robots, the ball


def test_a_taken_port_or_a_missing_bag_is_one_clear_line_and_exit_1(ros_graph, tmp_path):
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        view = ros_graph.start_node("erforce_sim", "field_view", params={"port": port})
        assert view.wait_exit(60.0) == 1
    assert re.search(rf"cannot start: cannot serve on 127.0.0.1:{port}", view.output())
    view = ros_graph.start_node("erforce_sim", "field_view", params={"port": 0, "bag": str(tmp_path / "none")})
    assert view.wait_exit(60.0) == 1
    assert "cannot start: cannot replay" in view.output() and "Traceback" not in view.output()


PASSER_XY, RECEIVER_XY, OPPONENT_XY = (0.0, 1.0), (2.0, -1.0), (1.0, 0.5)


def write_rolling_ball_bag(path: Path) -> None:
    """The ball along x: x = t - 2 m for t from 1 to 5 s (truth every 10 ms); robot_0 at rest at (0, 1),
    robot_1 at (2, -1), opponent_0 at (1, 0.5); from 1 s the passing game's choice: robot_0 to robot_1,
    our catch 0.9 s and the opponent's 1.4 s after the kick (margin 0.5 s, safe at 0.3 s)."""
    store = get_typestore(Stores.ROS2_JAZZY)
    cfg = PassConfig(safe_margin_s=0.3)
    choice = PassOption(receiver=1, kick_speed_mps=3.0, direction_rad=-math.pi / 4, receiver_catch_s=0.9,
                        opponent_catch_s=1.4, first_opponent=0)
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        ball = writer.add_connection(c.GROUND_TRUTH_BALL.name, "nav_msgs/msg/Odometry", typestore=store)
        robots = [(writer.add_connection(name, "nav_msgs/msg/Odometry", typestore=store), xy) for name, xy in (
            (c.GROUND_TRUTH_ODOM.for_robot(0), PASSER_XY), (c.GROUND_TRUTH_ODOM.for_robot(1), RECEIVER_XY),
            (c.opponent_topic(c.GROUND_TRUTH_ODOM, 0), OPPONENT_XY))]
        writer.write(writer.add_connection(c.PASS_CHOICE.name, c.PASS_CHOICE.type_name, typestore=store),
                     round(1e9), pass_choice_cdr((0, choice), cfg))
        for k in range(401):
            t = 1.0 + 0.01 * k
            writer.write(ball, round(t * 1e9), serialize_message(odometry_msg(t, (t - 2.0, 0.0, 0.0), (1.0, 0.0, 0.0))))
            for robot, (x, y) in robots:
                writer.write(robot, round(t * 1e9), serialize_message(odometry_msg(t, (x, y, 0.0), (0.0, 0.0, 0.0))))


def test_the_page_replays_a_bag_with_slider_pause_and_speed(ros_graph, tmp_path):
    require_chromium()
    write_rolling_ball_bag(tmp_path / "bag")
    view = ros_graph.start_node("erforce_sim", "field_view", params={"port": 0, "bag": str(tmp_path / "bag")})
    url = view.wait_for_output(r"field view at (http://\S+)", timeout_s=60.0).group(1)
    browser = Browser(1400, 800)
    try:
        browser.open(url)

        def drawn_when(condition, what: str, timeout_s: float = 20.0) -> dict:
            deadline = time.monotonic() + timeout_s
            while True:
                drawn = browser.js("return window.fieldView && window.fieldView.drawn")
                if drawn and condition(drawn):
                    return drawn
                assert time.monotonic() < deadline, f"never drew {what}; last: {drawn}"
                time.sleep(0.05)

        def check_ball(drawn: dict) -> None:
            assert drawn["ball_world"][0] == pytest.approx(drawn["ball_t"] - 2.0, abs=1e-6)

        drawn = drawn_when(lambda d: d["replay"] and d["robots"] == 3 and d["pass"], "the bag")  # plays at once, 1x
        check_ball(drawn)
        # the passing game's choice: an arrow from the passer to the receiver, its margin, the opponent ringed
        pass_drawn = drawn["pass"]
        assert (pass_drawn["passer"], pass_drawn["receiver"], pass_drawn["safe"]) == (0, 1, True)
        assert pass_drawn["text"] == "pass 0 → 1: margin +0.50 s (safe ≥ 0.30 s)"
        assert pass_drawn["from_px"] == pytest.approx(drawn["robot_px"]["0"], abs=1e-6)
        assert pass_drawn["to_px"] == pytest.approx(drawn["robot_px"]["1"], abs=1e-6)
        assert pass_drawn["opponent_px"] == pytest.approx(drawn["robot_px"]["o0"], abs=1e-6)
        # and where it is drawn: a quarter of the way from the passer (clear of robots, ball and label) has its colour
        image = browser.screenshot()
        (fx, fy), (tx, ty) = pass_drawn["from_px"], pass_drawn["to_px"]
        left, top = browser.js("const r = document.getElementById('field').getBoundingClientRect();"
                               "return [r.left, r.top];")
        r, g, b = image.getpixel((round(left + fx + 0.25 * (tx - fx)), round(top + fy + 0.25 * (ty - fy))))[:3]
        assert g > 200 and r < 120 and b < 170, (r, g, b)  # #4dff88
        browser.js("document.getElementById('play').click()")  # pause
        time.sleep(0.3)
        paused = browser.js("return window.fieldView.drawn.t")
        time.sleep(0.7)
        assert browser.js("return window.fieldView.drawn.t") == paused
        # the slider jumps back and forth
        for t in (4.25, 1.5, 3.0):
            browser.js("const s = document.getElementById('slider'); s.value = arguments[0];"
                       "s.dispatchEvent(new Event('input'));", t)
            check_ball(drawn_when(lambda d, t=t: abs(d["t"] - t) < 0.006, f"the bag at {t} s"))
        ARTIFACTS.mkdir(parents=True, exist_ok=True)
        browser.screenshot().save(ARTIFACTS / "field_view_replay.png")
        # 4x from 1 s: a second of wall time plays about four of the bag
        browser.js("const s = document.getElementById('slider'); s.value = 1.0; s.dispatchEvent(new Event('input'));"
                   "const v = document.getElementById('speed'); v.value = '4'; v.dispatchEvent(new Event('change'));")
        drawn_when(lambda d: abs(d["t"] - 1.0) < 0.006, "the bag at 1 s")
        start_wall = time.monotonic()
        browser.js("document.getElementById('play').click()")
        time.sleep(1.0)
        t_now = browser.js("return window.fieldView.drawn.t")
        rate = (t_now - 1.0) / (time.monotonic() - start_wall)
        assert 2.5 < rate < 4.5, rate
        check_ball(browser.js("return window.fieldView.drawn"))
    finally:
        browser.close()
