"""The ball model in use is state over DDS: a_roll_mps2 set on ball_predictor changes where the catcher receives;
the chip parameters set on ball_predictor are the chip model the passing game rates its chips with.

ball_predictor (no vision: it only publishes the model in use) and robot_0's catcher run as
processes; the probe plays the predictor's other outputs for a fixed situation, over and over so
that they stay fresh: robot_0 at rest at (1.0, 0.3) facing -x, a ball at (-2, 0) already rolling
along +x at 2 m/s, and a predicted catch point (-0.5, 0.3) straight ahead of the robot.

By hand, with the catcher's defaults (a_max 4.5 m/s^2, slack 0.15 s, dribbler offset 0.0815 m):
the nearest receive point is the robot's projection on the ball's line, (1.0, 0), where the ball
has rolled 2.9185 m.
- a_roll -0.3 m/s^2: the ball stops after 2^2 / 0.6 = 6.67 m and rolls 2.9185 m in
  (2 - sqrt(4 - 0.6 * 2.9185)) / 0.3 = 1.669 s; the robot needs 2 sqrt(0.3 / 4.5) = 0.516 s,
  + 0.15 s slack: it receives at (1.0, 0), driving along field -y (robot frame +y).
- a_roll -1.0 m/s^2: the ball stops after 2^2 / 2 = 2 m, short of every point on the line beyond
  the robot's projection: no receive point, the catcher drives to the catch point, along field -x
  (robot frame +x).
"""

import math

import numpy as np
import pytest
from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
from std_msgs.msg import Bool, Float64, Float64MultiArray

from erforce_ball_model.ball_model import ChipParams
from erforce_ball_model.passing.decisions import PassConfig, chip_speed_for
from erforce_interfaces.tools.messages import float64_msg, point_msg
from erforce_interfaces.wire import contract
from erforce_interfaces.wire.conversions import (
    odometry_msg,
)
from erforce_interfaces.wire.robot_config import RobotConfig
from erforce_interfaces.wire.tables import table_from_msg, table_msg, tracked_robot_row

pytestmark = pytest.mark.integration

ROBOT_POSE = (1.0, 0.3, math.pi)
BALL = (-2.0, 0.0, 2.0, 0.0)
V_SHOOT_MPS = 2.0 / 0.6  # rolling already: v_switch = c_switch v_shoot is the current speed
CATCH_POINT = (-0.5, 0.3)


def _direction_rad(twist: Twist) -> float:
    return math.atan2(twist.linear.y, twist.linear.x)


def test_a_roll_set_on_the_predictor_moves_the_catchers_receive_point(ros_graph):
    q = contract
    ros_graph.start_node("erforce_ball_model", "ball_predictor", params={"num_robots": 1})
    ros_graph.start_node("erforce_ball_model", "catcher", namespace="robot_0")
    probe = ros_graph.probe
    commands = probe.subscribe("/robot_0/cmd_vel", Twist, q.CMD_VEL.qos)
    inputs = ((q.ODOM, q.ODOM.for_robot(0), odometry_msg(0.0, ROBOT_POSE, (0.0, 0.0, 0.0))),
              (q.BALL_STATE, q.BALL_STATE.name, odometry_msg(0.0, (*BALL[:2], 0.0), (*BALL[2:], 0.0))),
              (q.BALL_V_SHOOT, q.BALL_V_SHOOT.name, float64_msg(V_SHOOT_MPS)),
              (q.CATCH_TIME, q.CATCH_TIME.for_robot(0), float64_msg(1.0)),
              (q.CATCH_POINT, q.CATCH_POINT.for_robot(0), point_msg(0.0, CATCH_POINT)))
    pubs = [(probe.wait_for_subscribers(name, topic.msg_type, timeout_s=30.0, qos=topic.qos), msg)
            for topic, name, msg in inputs]

    def drive_until(expected_rad: float, what: str) -> None:
        """Publish the situation every 20 ms until the catcher's last commands drive towards ``expected_rad``."""
        def heading_there() -> bool:
            for pub, msg in pubs:
                pub.publish(msg)
            probe.spin_for(0.02)
            last = commands[-5:]
            return len(last) == 5 and all(
                math.hypot(t.linear.x, t.linear.y) > 0.05
                and abs(math.remainder(_direction_rad(t) - expected_rad, 2.0 * math.pi)) < 0.05 for t in last)

        probe.spin_until(heading_there, 30.0, what)

    drive_until(math.pi / 2, "the receive point (1.0, 0) with the default a_roll")
    assert probe.set_parameter("/ball_predictor", "a_roll_mps2", -1.0).successful
    commands.clear()
    drive_until(0.0, "the catch point once the ball stops short (a_roll -1.0)")


# The chip scene of test_passing_player.py: robot_0 holds the ball at (0, 0) facing +x, robot_1 at (3, 0) faces it,
# the opponent stands on the lane at (1.5, 0): the flat pass is unsafe, a 45 deg chip over the opponent is safe under
# the chip model below (a ball taken up to 0.11 m: it settles low enough after one hop).
GAME_POSES = {(contract.OURS, 0): (0.0, 0.0, 0.0), (contract.OURS, 1): (3.0, 0.0, math.pi),
              (contract.OPPONENTS, 0): (1.5, 0.0, math.pi)}
CHIP_PARAMS = {"chip_max_receive_height_m": 0.11, "chip_damping_z": 0.4}  # not the defaults (a ball radius, 0.566)
G_MPS2 = 9.81


def chip_kick_speed(height_m: float) -> float:
    """The 45 deg chip to robot_1 that stays below ``height_m`` from chip_settle_fraction of the ball's way to its
    dribbler, 3 - 2 x 0.0815 m, on, when only its first hop rises above it (damping_z 0.4: the second to 0.16 of
    its apex): x = v (v + sqrt(v^2 - 2 g h)) / g, so v^2 = g x^2 / (2 (x - h)), kicked at sqrt(2) v."""
    x = PassConfig().chip_settle_fraction * (3.0 - 2.0 * RobotConfig().dribbler_offset_m)
    v_squared = G_MPS2 * x * x / (2.0 * (x - height_m))
    assert 0.16 * v_squared / (2.0 * G_MPS2) < height_m
    return math.sqrt(2.0 * v_squared)


def test_the_passing_game_rates_its_chips_with_the_predictors_chip_model(ros_graph):
    q = contract
    common = {"num_robots": 2, "num_opponents": 1, "field": "division_a"}
    ros_graph.start_node("erforce_ball_model", "ball_predictor", params={**common, **CHIP_PARAMS})
    game = ros_graph.start_node("erforce_ball_model", "passing_game", params=common)
    probe = ros_graph.probe
    chip_models = probe.subscribe(q.BALL_CHIP_MODEL_PARAMS.name, Float64MultiArray, q.BALL_CHIP_MODEL_PARAMS.qos)
    choices = probe.subscribe(q.PASS_CHOICE.name, Float64MultiArray, q.PASS_CHOICE.qos)
    angles = probe.subscribe(q.KICK_ANGLE.for_robot(0), Float64, q.KICK_ANGLE.qos)
    probe.subscribe(q.SIM_SET_BALL.name, Odometry, q.SIM_SET_BALL.qos)  # a placer: the game starts
    tracked = probe.wait_for_subscribers(q.ROBOTS_TRACKED.name, Float64MultiArray, timeout_s=30.0,
                                         qos=q.ROBOTS_TRACKED.qos)
    barrier = probe.wait_for_subscribers(q.BALL_DETECTED.for_robot(0), Bool, timeout_s=30.0, qos=q.BALL_DETECTED.qos)
    probe.spin_until(lambda: chip_models, 20.0, "the predictor's chip model")
    (row,) = table_from_msg(chip_models[-1], q.BALL_CHIP_MODEL_PARAM_LABELS)
    model = dict(zip(q.BALL_CHIP_MODEL_PARAM_LABELS, row.tolist(), strict=True))
    assert (model["max_receive_height_m"], model["damping_z"]) == (0.11, 0.4)
    columns = q.PASS_CHOICE_COLUMNS
    expected = chip_kick_speed(0.11)
    defaults = chip_speed_for(PassConfig().chip_settle_fraction * (3.0 - 2.0 * RobotConfig().dribbler_offset_m), 45.0,
                              ChipParams(), 1.0, 6.5)
    assert abs(expected - defaults) > 0.2  # the default model would kick another speed

    def rows():
        return [dict(zip(columns, r.tolist(), strict=True)) for m in choices for r in table_from_msg(m, columns)]

    def chipped() -> bool:
        """The scene, again and again (fresh stamps), until a chip to robot_1 is chosen."""
        t_s = game_time[0] = game_time[0] + 0.02
        table = [tracked_robot_row(team, j, t_s, pose, (0.0, 0.0, 0.0)) for (team, j), pose in GAME_POSES.items()]
        tracked.publish(table_msg(np.array(table), q.TRACKED_ROBOT_COLUMNS))
        barrier.publish(Bool(data=True))
        probe.spin_for(0.02)
        return any(r["receiver_id"] == 1 and abs(r["kick_speed_mps"] - expected) < 1e-3 for r in rows())

    game_time = [100.0]
    probe.spin_until(chipped, 60.0, f"a chip to robot_1 kicked at {expected:.4f} m/s")
    chip = next(r for r in rows() if abs(r["kick_speed_mps"] - expected) < 1e-3)
    assert chip["kick_speed_mps"] == pytest.approx(expected, abs=1e-6) and chip["safe"] == 1.0
    assert all(abs(r["kick_speed_mps"] - chip_kick_speed(0.15)) > 1e-3 for r in rows())  # never the defaults'
    probe.spin_until(lambda: any(m.data == 45.0 for m in angles), 10.0, "the chip's kick_angle")
    assert game.alive() and "Traceback" not in game.output()
