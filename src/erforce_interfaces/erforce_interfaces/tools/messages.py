"""rclpy message builders for tests, benches and tools.

The nodes build the contract's hot messages as CDR bytes (erforce_interfaces.wire.conversions); these
build the same messages as rclpy objects, checked the same way, for a test that publishes through
rclpy or compares the bytes with rclpy's own serialization.
"""

from __future__ import annotations

from collections.abc import Sequence

from geometry_msgs.msg import Point, PointStamped, Pose, PoseStamped
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64

from erforce_interfaces.wire.contract import FIELD_FRAME
from erforce_interfaces.wire.conversions import (
    MAX_ABS_VALUE,
    _finite,
    _finite_array,
    nanoseconds_to_stamp,
    quaternion_from_yaw,
    seconds_to_stamp,
)


def point_msg(t_s: float, xy: Sequence[float], frame_id: str = FIELD_FRAME,
              out: PointStamped | None = None) -> PointStamped:
    """``out``: refill this message instead of building one (as in odometry_msg)."""
    msg = PointStamped() if out is None else out
    msg.header.stamp = seconds_to_stamp(t_s)
    msg.header.frame_id = frame_id
    point = msg.point
    point.x = _finite("x", xy[0])
    point.y = _finite("y", xy[1])
    point.z = 0.0
    return msg


def pose2d_msg(t_s: float, pose: Sequence[float], frame_id: str = FIELD_FRAME) -> PoseStamped:
    msg = PoseStamped()
    msg.header.stamp = seconds_to_stamp(t_s)
    msg.header.frame_id = frame_id
    msg.pose = Pose(position=Point(x=_finite("x", pose[0]), y=_finite("y", pose[1]), z=0.0),
                    orientation=quaternion_from_yaw(pose[2]))
    return msg


def joint_state_msg(t_ns: int, names: Sequence[str], *, velocity: Sequence[float] | None = None,
                    effort: Sequence[float] | None = None) -> JointState:
    msg = JointState()
    msg.header.stamp = nanoseconds_to_stamp(int(t_ns))
    msg.name = list(names)
    if velocity is not None:
        msg.velocity = _finite_array("velocity", velocity, len(names), MAX_ABS_VALUE).tolist()
    if effort is not None:
        msg.effort = _finite_array("effort", effort, len(names), MAX_ABS_VALUE).tolist()
    return msg


def float64_msg(value: float, limit: float = MAX_ABS_VALUE) -> Float64:
    return Float64(data=_finite("data", value, limit))
