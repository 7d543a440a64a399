"""A recorded game drives the predictor as if live: a log written by the plant (ssl_game_log) is played by
ssl_log_replay over loopback multicast into ssl_vision_bridge, and the ball predictor tracks its kicks and
takes the log's ball model from the geometry records."""

import socket
import subprocess
import sys

import numpy as np
import pytest
from nav_msgs.msg import Odometry
from std_msgs.msg import Float64MultiArray

from erforce_interfaces.wire import contract
from erforce_sim.ball import BallParams
from erforce_sim.demo.ssl_game_log import GameConfig, write_game_log
from erforce_sim.drivetrain import GRAVITY_MPS2

pytestmark = pytest.mark.integration


def free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def test_a_replayed_plant_log_drives_the_ball_predictor(ros_graph, tmp_path):
    ball = BallParams(mu_slide=3.0 / GRAVITY_MPS2, mu_roll=0.4 / GRAVITY_MPS2)
    config = GameConfig(duration_s=12.0, seed=2, ball=ball)
    log = tmp_path / "game.log.gz"
    summary = write_game_log(log, config)
    assert summary.shots >= 2
    port = free_udp_port()
    bridge = ros_graph.start_node("erforce_ball_model", "ssl_vision_bridge", params={
        "interface": "127.0.0.1", "port": port, "num_robots": 6})
    predictor = ros_graph.start_node("erforce_ball_model", "ball_predictor", params={"num_robots": 6})
    probe = ros_graph.probe
    states = probe.subscribe(contract.BALL_STATE.name, Odometry, contract.BALL_STATE.qos)
    model = probe.subscribe(contract.VISION_BALL_MODEL.name, Float64MultiArray, contract.VISION_BALL_MODEL.qos)
    bridge.wait_for_output("ssl_vision_bridge: 224.5.23.2:", timeout_s=30.0)
    probe.spin_until(lambda: probe.node.count_subscribers(contract.VISION_ROBOTS.name) > 0, 30.0,
                     "the ball predictor's vision subscription")

    replay = subprocess.Popen([sys.executable, "-m", "erforce_interfaces.ssl.ssl_log_replay", str(log), "--quiet",
                               "--no-referee", "--vision", f"224.5.23.2:{port}"],
                              stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        # a kick of the log (1 to 4.5 m/s) shows up in the predictor's ball state
        probe.spin_until(lambda: any(np.hypot(m.twist.twist.linear.x, m.twist.twist.linear.y) > 0.8
                                     for m in states), 30.0, "a kicked ball on /ball/state")
        # the log's geometry (the plant's true ball model) reaches the bridge's topic and the predictor
        true = summary.true_model
        want = [true.a_slide_mps2, true.a_roll_mps2, true.c_switch]
        probe.spin_until(lambda: model and np.allclose(model[-1].data, want, atol=1e-6), 30.0,
                         "the log's ball model on /vision/ball_model")
        predictor.wait_for_output(f"ball model from SSL geometry: a_slide {true.a_slide_mps2:g}, "
                                  f"a_roll {true.a_roll_mps2:g}, c_switch {true.c_switch:g}", timeout_s=30.0)
        out, _ = replay.communicate(timeout=60.0)
    finally:
        if replay.poll() is None:
            replay.kill()
            replay.wait()
    assert replay.returncode == 0, out
    assert "VISION_2014" in out
