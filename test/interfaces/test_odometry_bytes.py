"""odometry_from_msg reads an Odometry's bytes (a raw subscription's, a bag's) as it reads the message."""

import math
import struct

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from nav_msgs.msg import Odometry
from rclpy.serialization import deserialize_message, serialize_message

from erforce_interfaces.wire import conversions as conv

_text = st.text(st.characters(codec="utf-8", exclude_characters="\x00"), max_size=12)


def _outcome(msg):
    try:
        t, pose, velocity, angular = conv.odometry_from_msg(msg)
    except conv.ConversionError:
        return "rejected"
    return t, pose.tolist(), velocity.tolist(), angular.tolist()


@settings(max_examples=300, deadline=None)
@given(sec=st.integers(0, 2**31 - 1), nanosec=st.integers(0, 999_999_999), frame=_text, child=_text,
       values=st.lists(st.floats(width=64), min_size=13, max_size=13),
       covariance=st.floats(width=64))
def test_bytes_read_like_the_message_from_rclpy(sec, nanosec, frame, child, values, covariance):
    msg = Odometry()
    msg.header.stamp.sec, msg.header.stamp.nanosec, msg.header.frame_id = sec, nanosec, frame
    msg.child_frame_id = child
    p, o = msg.pose.pose.position, msg.pose.pose.orientation
    lin, ang = msg.twist.twist.linear, msg.twist.twist.angular
    (p.x, p.y, p.z, o.x, o.y, o.z, o.w, lin.x, lin.y, lin.z, ang.x, ang.y, ang.z) = values
    msg.pose.covariance[7] = msg.twist.covariance[35] = covariance
    assert _outcome(msg) == _outcome(serialize_message(msg))


def test_a_hand_built_message_reads_its_numbers():
    """Pose (1.5, -2, yaw 0.75), velocity (0.25, -0.5), spin (1, 2, 3), stamp 3.5 s."""
    data = conv.odometry_cdr(3.5, (1.5, -2.0, 0.75), (0.25, -0.5, 0.0), "robot_3/base_link", spin=(1.0, 2.0, 3.0))
    t, pose, velocity, angular = conv.odometry_from_msg(data)
    assert t == 3.5
    assert pose == pytest.approx([1.5, -2.0, 0.75], abs=1e-12)
    assert velocity.tolist() == [0.25, -0.5, 3.0]
    assert angular.tolist() == [1.0, 2.0, 3.0]


def test_truncated_or_foreign_bytes_are_a_conversion_error():
    good = conv.odometry_cdr(1.0, (0.5, 0.5, 0.1), (0.0, 0.0, 0.0), "ball")
    for cut in range(len(good)):
        with pytest.raises(conv.ConversionError):
            conv.odometry_from_msg(good[:cut])
    for bad in (b"\x00\x00" + good[2:], good[:12] + struct.pack("<I", 2**31) + good[16:]):
        with pytest.raises(conv.ConversionError):
            conv.odometry_from_msg(bad)
    nan_x = bytearray(good)
    struct.pack_into("<d", nan_x, 4 + 32, math.nan)  # pose.position.x (payload offset 32 with "field"/"ball")
    with pytest.raises(conv.ConversionError, match="position.x"):
        conv.odometry_from_msg(bytes(nan_x))
    assert np.isfinite(conv.odometry_from_msg(good)[1]).all()


def test_a_chipped_balls_height_and_vertical_speed_ride_in_position_z_and_linear_z():
    data = conv.odometry_cdr(2.0, (1.0, -0.5, 0.0), (3.0, 0.0, 0.0), child_frame_id="ball", z_m=0.4038,
                             vz_mps=1.038)
    msg = deserialize_message(data[:], Odometry)
    assert (msg.pose.pose.position.z, msg.twist.twist.linear.z) == (0.4038, 1.038)  # rclpy reads our bytes
    assert conv.odometry_height(data) == conv.odometry_height(msg) == (0.4038, 1.038)
    assert conv.odometry_height(conv.odometry_cdr(2.0, (1.0, -0.5, 0.0), (3.0, 0.0, 0.0))) == (0.0, 0.0)
    with pytest.raises(conv.ConversionError, match="vz"):
        conv.odometry_cdr(2.0, (1.0, -0.5, 0.0), (3.0, 0.0, 0.0), vz_mps=math.nan)


def test_a_flat_balls_variances_ride_on_the_pose_and_twist_diagonals():
    """/ball/state of a ball on the ground: the filter's variance of x and y at pose.covariance 0 and 7 (row-major
    (x, y, z, rot x, rot y, rot z)), of vx and vy at twist.covariance 0 and 7; a message refilled says the new ones."""
    data = conv.odometry_cdr(2.0, (1.0, -0.5, 0.0), (3.0, 0.0, 0.0), "ball", position_variance_m2=4e-6,
                             velocity_variance_m2ps2=0.0283)
    msg = deserialize_message(data, Odometry)
    assert np.array_equal(np.reshape(msg.pose.covariance, (6, 6)), np.diag([4e-6, 4e-6, 0.0, 0.0, 0.0, 0.0]))
    assert np.array_equal(np.reshape(msg.twist.covariance, (6, 6)), np.diag([0.0283, 0.0283, 0.0, 0.0, 0.0, 0.0]))
    assert conv.odometry_msg(2.0, (1.0, -0.5, 0.0), (3.0, 0.0, 0.0), "ball", out=msg) == deserialize_message(
        conv.odometry_cdr(2.0, (1.0, -0.5, 0.0), (3.0, 0.0, 0.0), "ball"), Odometry)
    assert not any(msg.twist.covariance)


def test_a_chips_covariances_ride_in_rows_and_columns_0_to_2():
    xyz = np.array([[4e-6, 1e-6, 3e-4], [1e-6, 5e-6, 2e-5], [3e-4, 2e-5, 0.0225]])  # z: 0.15 m standard error
    vxyz = np.diag([0.01, 0.02, 1.5**2])
    data = conv.odometry_cdr(2.0, (1.0, -0.5, 0.0), (3.0, 0.0, 0.0), "ball", z_m=0.3, vz_mps=2.0,
                             position_variance_m2=9.0, xyz_covariance=xyz, vxyz_covariance=vxyz,
                             velocity_variance_m2ps2=7.0)
    msg = deserialize_message(data, Odometry)
    pose, twist = np.reshape(msg.pose.covariance, (6, 6)), np.reshape(msg.twist.covariance, (6, 6))
    assert pose[2, 2] == 0.0225 and twist[2, 2] == 2.25  # row-major (x, y, z, rot x, rot y, rot z): z at 14
    assert msg.pose.covariance[14] == 0.0225 and msg.pose.covariance[2] == 3e-4 == msg.pose.covariance[12]
    assert np.array_equal(pose[:3, :3], xyz) and np.array_equal(twist[:3, :3], vxyz)
    assert not pose[3:].any() and not pose[:, 3:].any() and not twist[3:].any()
    for bad in (np.full((3, 3), math.nan), -np.eye(3), np.eye(2)):
        with pytest.raises(conv.ConversionError, match="pose covariance"):
            conv.odometry_cdr(2.0, (1.0, -0.5, 0.0), (3.0, 0.0, 0.0), xyz_covariance=bad)


def test_a_robots_yaw_and_yaw_rate_variances_ride_last_on_each_diagonal():
    data = conv.odometry_cdr(2.0, (1.0, -0.5, 0.3), (0.2, 0.0, 1.0), "robot_0/base_link", position_variance_m2=4e-6,
                             velocity_variance_m2ps2=0.03, yaw_variance_rad2=9e-5, yaw_rate_variance_rad2ps2=1.8)
    msg = deserialize_message(data, Odometry)
    assert (msg.pose.covariance[0], msg.pose.covariance[7], msg.pose.covariance[35]) == (4e-6, 4e-6, 9e-5)
    assert (msg.twist.covariance[0], msg.twist.covariance[7], msg.twist.covariance[35]) == (0.03, 0.03, 1.8)
    assert np.count_nonzero(msg.pose.covariance) == np.count_nonzero(msg.twist.covariance) == 3
    for bad in (-1e-6, math.nan, math.inf):
        with pytest.raises(conv.ConversionError, match="yaw rate variance"):
            conv.odometry_cdr(2.0, (1.0, -0.5, 0.3), (0.2, 0.0, 1.0), yaw_rate_variance_rad2ps2=bad)
