"""The ball model in use is state over DDS: a_roll_mps2 set on ball_predictor changes where the catcher receives.

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

import pytest
from geometry_msgs.msg import Twist

from erforce_interfaces.tools.messages import float64_msg, point_msg
from erforce_interfaces.wire import contract
from erforce_interfaces.wire.conversions import (
    odometry_msg,
)

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
