"""The wire contract and the message conversions."""

import math
import re
from pathlib import Path

import numpy as np
import pytest
from geometry_msgs.msg import PointStamped, PoseStamped, Twist
from hypothesis import given
from hypothesis import strategies as st
from sensor_msgs.msg import JointState

from erforce_interfaces import contract as c
from erforce_interfaces import conversions as conv
from erforce_interfaces.robot_config import FieldConfig, RobotConfig

README = Path(__file__).resolve().parents[2] / "README.md"


def test_readme_generated_sections_are_current():
    from erforce_interfaces import docs

    text = README.read_text()
    for name in docs.SECTIONS:
        assert f"<!-- {name}:begin -->" in text, name
    assert docs.render(text) == text, (
        "README tables are stale: run `./run exec python -m erforce_interfaces.docs README.md`"
    )
    assert c.topic_table_markdown() in text


def test_topic_names_are_valid_and_unique():
    names = [t.name for t in c.TOPICS]
    assert len(names) == len(set(names))
    for name in names:
        assert re.fullmatch(r"/?[a-z][a-z0-9_]*(/[a-z][a-z0-9_]*)*", name), name


def test_per_robot_topics_resolve_under_the_robot_namespace():
    assert c.CMD_VEL.for_robot(3) == "/robot_3/cmd_vel"
    assert c.GROUND_TRUTH_ODOM.for_robot(0) == "/robot_0/ground_truth/odom"
    with pytest.raises(ValueError):
        c.CLOCK.for_robot(0)
    with pytest.raises(ValueError):
        c.robot_namespace(-1)


def test_qos_vision_is_best_effort_and_commands_reliable():
    from rclpy.qos import ReliabilityPolicy

    assert c.VISION_BALL.qos.reliability == ReliabilityPolicy.BEST_EFFORT
    assert c.VISION_POSE.qos.reliability == ReliabilityPolicy.BEST_EFFORT
    for t in (c.CMD_VEL, c.KICK, c.MOTOR_DUTY, c.WHEEL_SETPOINTS, c.SIM_SET_BALL):
        assert t.qos.reliability == ReliabilityPolicy.RELIABLE, t.name


def test_type_names_use_the_ros_interface_form():
    assert c.CMD_VEL.type_name == "geometry_msgs/msg/Twist"
    assert c.CLOCK.type_name == "rosgraph_msgs/msg/Clock"


@given(st.floats(-math.pi, math.pi))
def test_yaw_quaternion_round_trip(yaw):
    assert conv.yaw_from_quaternion(conv.quaternion_from_yaw(yaw)) == pytest.approx(yaw, abs=1e-12)


def test_stamp_round_trip_is_exact_in_nanoseconds():
    stamp = conv.nanoseconds_to_stamp(12_345_678_901)
    assert (stamp.sec, stamp.nanosec) == (12, 345_678_901)
    assert conv.stamp_to_nanoseconds(stamp) == 12_345_678_901
    assert conv.stamp_to_seconds(conv.seconds_to_stamp(1.5)) == 1.5


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf, 1e9])
def test_twist_rejects_non_finite_and_huge(bad):
    msg = Twist()
    msg.linear.y = bad
    with pytest.raises(conv.ConversionError, match="linear.y"):
        conv.twist_from_msg(msg)


def test_twist_planar_values():
    msg = conv.twist_msg([1.0, -0.5, 2.0])
    assert conv.twist_from_msg(msg).tolist() == [1.0, -0.5, 2.0]
    with pytest.raises(conv.ConversionError):
        conv.twist_msg([math.nan, 0.0, 0.0])


def test_point_and_pose_reject_nan():
    msg = PointStamped()
    msg.point.x = math.nan
    with pytest.raises(conv.ConversionError, match="point.x"):
        conv.point_from_msg(msg)
    pose = PoseStamped()
    pose.pose.orientation.w = 0.0  # zero quaternion is no orientation
    with pytest.raises(conv.ConversionError, match="quaternion"):
        conv.pose2d_from_msg(pose)


def test_joint_state_length_names_and_finiteness():
    msg = conv.joint_state_msg(5_000_000, ["wheel_0", "wheel_1", "wheel_2"], velocity=[1.0, 2.0, 3.0],
                               effort=[0.1, 0.2, 0.3])
    t_ns, speeds, currents = conv.wheel_states_from_msg(msg, 3)
    assert t_ns == 5_000_000 and speeds.tolist() == [1.0, 2.0, 3.0] and currents.tolist() == [0.1, 0.2, 0.3]
    with pytest.raises(conv.ConversionError, match="4 entries, expected 3|expected 3"):
        conv.joint_state_from_msg(JointState(velocity=[1.0, 2.0, 3.0, 4.0]), 3, "velocity")
    with pytest.raises(conv.ConversionError, match="names"):
        conv.joint_state_from_msg(JointState(name=["b", "a", "c"], velocity=[1.0, 2.0, 3.0]), 3, "velocity")
    with pytest.raises(conv.ConversionError, match=r"velocity\[1\]"):
        conv.joint_state_from_msg(JointState(velocity=[1.0, math.nan, 3.0]), 3, "velocity")
    with pytest.raises(conv.ConversionError):
        conv.joint_state_msg(0, ["wheel_0"], velocity=[math.inf])


def test_table_round_trip_and_labels():
    rows = np.array([[1.0, 0.5, 0.0, 1.0], [2.0, 1.0, 1.0, 0.0]])
    msg = conv.table_msg(rows, c.MOTOR_STATUS_COLUMNS, "wheels")
    assert msg.layout.dim[1].label == "avg_current_a,pwm_limit,saturated,limit_active"
    np.testing.assert_array_equal(conv.table_from_msg(msg, c.MOTOR_STATUS_COLUMNS), rows)
    with pytest.raises(conv.ConversionError):
        conv.table_msg(np.array([[math.nan, 0, 0, 0]]), c.MOTOR_STATUS_COLUMNS)


def test_odometry_round_trip_with_spin():
    msg = conv.odometry_msg(2.0, [1.0, -2.0, 0.5], [0.3, 0.4, 0.0], spin=[10.0, -5.0, 1.0])
    t, pose, vel, ang = conv.odometry_from_msg(msg)
    assert t == 2.0
    np.testing.assert_allclose(pose, [1.0, -2.0, 0.5])
    np.testing.assert_allclose(vel[:2], [0.3, 0.4])
    np.testing.assert_allclose(ang, [10.0, -5.0, 1.0])


def test_refilled_messages_equal_new_ones():
    """Publishers refill their messages every tick: a refill leaves nothing of the previous one."""
    odom = conv.odometry_msg(1.0, [1.0, 2.0, 0.5], [3.0, 4.0, 0.0], "ball", spin=[1.0, 2.0, 3.0],
                             position_variance_m2=0.25)
    refilled = conv.odometry_msg(2.5, [-1.0, 0.5, -1.0], [0.1, 0.2, 0.3], "robot_0", out=odom)
    assert refilled is odom
    assert odom == conv.odometry_msg(2.5, [-1.0, 0.5, -1.0], [0.1, 0.2, 0.3], "robot_0")
    point = conv.point_msg(1.0, (1.0, 2.0), frame_id="other")
    assert conv.point_msg(3.0, (4.0, 5.0), out=point) == conv.point_msg(3.0, (4.0, 5.0))
    assert conv.point_from_msg(point) == (3.0, (4.0, 5.0))
    assert all(type(v) is float for v in conv.point_from_msg(point)[1])


def test_robot_config_validation_and_yaml(tmp_path):
    cfg = RobotConfig.from_yaml(Path(__file__).resolve().parents[2] / "src/erforce_interfaces/config/robot.yaml")
    assert cfg == RobotConfig()  # the shipped file and the documented defaults agree
    assert cfg.num_wheels == 4 and cfg.wheel_names[-1] == "wheel_3"
    assert math.degrees(cfg.wheel_angles_rad[0]) == pytest.approx(60.0)
    with pytest.raises(ValueError, match="at least 3"):
        RobotConfig(wheel_angles_rad=(0.0, 1.0))
    with pytest.raises(ValueError, match="wheel_radius_m"):
        RobotConfig(wheel_radius_m=0.0)
    with pytest.raises(ValueError, match="mass_kg"):
        RobotConfig(mass_kg=math.nan)
    with pytest.raises(ValueError, match="unknown robot config keys: colour"):
        RobotConfig.from_dict({"colour": "blue"})


def test_field_presets():
    a, b = FieldConfig.preset("division_a"), FieldConfig.preset("division_b")
    assert (a.length_m, a.width_m, b.length_m, b.width_m) == (12.0, 9.0, 9.0, 6.0)
    assert a.contains(5.9, 4.4) and not a.contains(6.1, 0.0)
    with pytest.raises(ValueError, match="unknown field preset"):
        FieldConfig.preset("division_c")
