"""Vision over real UDP: the plant sends SSL-Vision packets from 4 simulated cameras (loopback
multicast), ssl_vision_bridge decodes and tracks them, the ball predictor and the catcher run
from that vision alone (the plant publishes no vision topics), and robot_0 catches the Fig. 6 ball.
Both deployments: the bridge in the predictor's process (ssl_ball_predictor, the demo's default) and
in a process of its own (a team's separate vision process, over /vision/robots).
"""

import socket

import pytest

from erforce_interfaces.tools.testing import hold_the_lockstep
from erforce_interfaces.wire.robot_config import FieldConfig, RobotConfig
from erforce_sim.demo.demo import LAUNCH_FILE, Director
from erforce_sim.in_process.scenes import default_scenes

pytestmark = pytest.mark.integration

def free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


@pytest.fixture(params=["predictor", "own"])
def director(ros_graph, request):
    launch = ros_graph.start_launch(LAUNCH_FILE, real_time_factor="0.0", output="screen", vision="ssl",
                                    ssl_vision_port=str(free_udp_port()), ssl_vision_process=request.param)
    d = Director(ros_graph.probe.node, RobotConfig(), ros_graph.probe.executor,
                 graph_alive=launch.alive, graph_hint="see the launch output below")
    assert d.spin_until(d.graph_ready, 120.0, "the graph"), launch.output()[-3000:]
    hold_the_lockstep(ros_graph)
    yield d, launch, request.param
    d.close()


def test_the_fig6_ball_is_caught_from_ssl_vision(director):
    d, launch, deployment = director
    fig6 = default_scenes(FieldConfig.preset("division_b"))[0]
    assert fig6.name.startswith("Fig. 6")
    result = d.play(fig6)
    assert result.caught and result.caught_by in (None, 0), "robot_0's light barrier did not fire"
    assert result.predicted_s is not None, "no catch predicted 0.3 s before the contact"
    # in the first window: the ball, released at 2 m/s 1.5 m before robot_0, arrives after about 0.75 s
    assert 0.6 < result.actual_s - result.t_start_s < 1.0
    # the vision the predictor used came through the bridge: the plant sent none itself
    output = launch.output()
    assert "ssl_vision_bridge: 224.5.23.2:" in output
    assert "SSL geometry: field 9 x 6 m, ball model a_slide -2.5" in output  # the plant's geometry packet
    assert "batch failed" not in output and "dropped a datagram" not in output
    assert "consumer failed" not in output
    # the processes of the chosen deployment: one for both nodes, or one each
    started = {name: f"[{name}-" in output for name in ("ssl_ball_predictor", "ssl_vision_bridge", "ball_predictor")}
    assert started == {"ssl_ball_predictor": deployment == "predictor", "ssl_vision_bridge": deployment == "own",
                       "ball_predictor": deployment == "own"}
