"""N receivers on the full node graph (demo.launch.yaml receivers:=2): robot_0 and robot_2 each run a
velocity_controller, motor_boards and a catcher, and the catchers form a team in which only the robot
that can catch the ball first (robotTimeToBall, from the predictor's catch times) drives to it.

Two kicks: one straight at robot_0, one at robot_2 with robot_0 placed behind the kicker, where the
ball never comes near it. Each time the ball must be caught by the robot it was kicked at, and the
other robot must hold its place (it would otherwise run for the same ball).
"""

import math

import numpy as np
import pytest
from geometry_msgs.msg import Twist
from std_msgs.msg import Float64

from erforce_interfaces.tools.testing import hold_the_lockstep
from erforce_interfaces.wire import contract
from erforce_interfaces.wire.robot_config import FieldConfig, RobotConfig
from erforce_sim.demo.demo import LAUNCH_FILE, Director
from erforce_sim.in_process.scenes import RECEIVER, TEAMMATE_POSES, Scene, default_scenes

pytestmark = pytest.mark.integration

TEAMMATE = 2
HOLD_TOLERANCE_M = 0.1  # a robot that holds moves only when the scene places it


@pytest.fixture
def director(ros_graph):
    launch = ros_graph.start_launch(LAUNCH_FILE, real_time_factor="0.0", output="screen", receivers="2")
    d = Director(ros_graph.probe.node, RobotConfig(), ros_graph.probe.executor, graph_alive=launch.alive,
                 graph_hint="see the launch output below", receivers=2)
    assert d.spin_until(d.graph_ready, 150.0, "the graph"), launch.output()[-3000:]
    hold_the_lockstep(ros_graph, ("robot_0", "robot_2"))
    yield d
    d.close()


def travelled_m(director, robot, t_start, t_end) -> float:
    """How far a robot's ground truth moved between two times (its largest distance from where it was)."""
    if robot == RECEIVER:
        path = [(r[1], r[2]) for r in director.series.robot_truth if t_start <= r[0] <= t_end]
    else:
        path = [(r[1], r[2]) for r in director.series.teammate_truth[robot] if t_start <= r[0] <= t_end]
    assert len(path) > 10, f"no ground truth of robot_{robot}"
    p = np.array(path)
    return float(np.max(np.hypot(*(p - p[0]).T)))


def test_the_first_robot_to_the_ball_receives_and_its_teammate_holds(director):
    straight = next(s for s in default_scenes(FieldConfig.preset("division_b")) if s.name == "kick 3.0 m/s straight")
    result = director.play(straight)
    assert result.caught and result.caught_by == RECEIVER
    assert travelled_m(director, TEAMMATE, result.t_start_s, result.actual_s) < HOLD_TOLERANCE_M

    kicker, aim = (-3.0, 0.0), TEAMMATE_POSES[TEAMMATE][:2]
    yaw = math.atan2(aim[1] - kicker[1], aim[0] - kicker[0])
    to_teammate = Scene("kick 3.0 m/s at robot_2", (-3.5, 2.5, 0.0), (*kicker, yaw), None, 3.0, 6.0)
    result = director.play(to_teammate)
    assert result.caught and result.caught_by == TEAMMATE
    assert travelled_m(director, RECEIVER, result.t_start_s, result.actual_s) < HOLD_TOLERANCE_M


def test_a_catcher_outside_its_team_refuses_to_start_with_one_clear_line(ros_graph):
    proc = ros_graph.start_node("erforce_ball_model", "catcher", namespace="robot_5", params={"team_robot_ids": [0, 2]})
    assert proc.wait_exit(30.0) == 1
    out = proc.output()
    assert "cannot start: team_robot_ids [0, 2]: a team catcher runs in the namespace of one of its robots" in out
    assert "Traceback" not in out


def test_a_team_catcher_rejects_bad_teammate_catch_times_and_keeps_commanding(ros_graph):
    proc = ros_graph.start_node("erforce_ball_model", "catcher", namespace="robot_0", params={"team_robot_ids": [0, 2]})
    commands = ros_graph.subscribe("/robot_0/cmd_vel", Twist, contract.CMD_VEL.qos)
    teammate = ros_graph.probe.wait_for_subscribers(contract.CATCH_TIME.for_robot(TEAMMATE), Float64, timeout_s=20.0,
                                                    qos=contract.CATCH_TIME.qos)
    for bad in (math.nan, math.inf, -math.inf, 1e300):
        teammate.publish(Float64(data=bad))
    proc.wait_for_output(f"rejected robot_{TEAMMATE} catch_time", timeout_s=10.0)
    seen = len(commands)
    ros_graph.spin_until(lambda: len(commands) >= seen + 5, 10.0, "cmd_vel after the bad catch times")
    assert all(math.isfinite(v) for m in commands for v in (m.linear.x, m.linear.y, m.angular.z))
    assert proc.alive()
