"""Message <-> core conversions: the only place that knows both ROS messages and numpy.

Every ``*_from_msg`` returns plain floats, tuples or numpy arrays and raises ``ConversionError``
(a ValueError) with a message naming the field when a value is non-finite, out of range,
or an array has the wrong length. Every ``*_msg`` builder refuses non-finite input too,
so a node cannot publish NaN by accident.

Values our own physics produced must never make a publish raise. Per case, either the physics
limits what it can produce, or the converter saturates like a sensor at the end of its range:
- placed bodies and kicks: limited where they are set (world.place_robot / place_ball refuse
  speeds beyond the plausible limits, kicks and duties are clamped), so poses, twists and spins
  on the wire stay inside the converters' ranges;
- measured wheel speeds and motor currents (``wheel_states``): the sensor saturates
  (``joint_state_cdr(..., saturate=True)`` in the plant). A robot placed at 20 m/s while turning
  at 100 rad/s spins its wheels past the wire's range for a moment; a real encoder's speed
  reading saturates too, and the controllers only need to know the wheel is very fast.
"""

from __future__ import annotations

import functools
import math
import struct
from collections.abc import Sequence

import numpy as np
from builtin_interfaces.msg import Time
from geometry_msgs.msg import PointStamped, PoseStamped, Quaternion, Twist
from nav_msgs.msg import Odometry
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64

from erforce_interfaces.wire.contract import (
    BALL_PHASES,
    FIELD_FRAME,
    OPPONENTS,
    OURS,
    Team,
    field_joint_names,
)
from erforce_interfaces.wire.stamps import stamp_ns

#: Largest magnitude accepted for any position [m], speed [m/s] or rate [rad/s] on the wire.
#: Far beyond anything physical on an SSL field; it keeps "huge" values out of the cores.
MAX_ABS_VALUE = 1.0e3
MAX_ABS_ANGULAR = 1.0e5  # [rad, rad/s] yaw of a pose, angular velocities: a magnitude beyond this is garbage


class ConversionError(ValueError):
    """A message that the cores must not see (non-finite, absurd, or mis-shaped)."""


def finite_within(name: str, value: float, limit: float = MAX_ABS_VALUE,
                  error: type[ValueError] = ConversionError) -> float:
    """``value`` as a float; ``error`` when it is not finite or beyond +-``limit``."""
    v = float(value)
    if not math.isfinite(v):
        raise error(f"{name} is not finite ({v!r})")
    if abs(v) > limit:
        raise error(f"{name} = {v!r} is beyond the accepted magnitude {limit:g}")
    return v


_finite = finite_within  # the short name the converters below use


def _finite_array(name: str, values: Sequence[float], length: int | None, limit: float) -> np.ndarray:
    arr = np.asarray(values, dtype=float)
    if arr.ndim != 1:
        raise ConversionError(f"{name} must be a flat array")
    if length is not None and arr.size != length:
        raise ConversionError(f"{name} has {arr.size} entries, expected {length}")
    if not arr.size or np.abs(arr).max() <= limit:  # NaN and inf fail it too: then the checks below name them
        return arr
    bad = ~np.isfinite(arr)
    if bad.any():
        raise ConversionError(f"{name}[{int(np.argmax(bad))}] is not finite")
    if arr.size and np.max(np.abs(arr)) > limit:
        raise ConversionError(f"{name} has a value beyond the accepted magnitude {limit:g}")
    return arr


# ----------------------------------------------------------------------- time
def stamp_to_seconds(stamp: Time) -> float:
    _checked_stamp_ns(stamp.sec, stamp.nanosec)
    return stamp.sec + stamp.nanosec * 1e-9


def stamp_to_nanoseconds(stamp: Time) -> int:
    return _checked_stamp_ns(stamp.sec, stamp.nanosec)


def _checked_stamp_ns(sec: int, nanosec: int) -> int:
    """A stamp as nanoseconds; ConversionError for what is no time (negative, nanosec >= 1e9), on
    which rclpy's Time.from_msg raises too."""
    ns = stamp_ns(sec, nanosec)
    if ns is None:
        raise ConversionError(f"stamp {sec} s {nanosec} ns is not a valid time")
    return ns


def seconds_to_stamp(t_s: float) -> Time:
    return nanoseconds_to_stamp(_seconds_to_ns(t_s))


def _seconds_to_ns(t_s: float) -> int:
    ns = round(_finite("stamp", t_s, limit=4.0e9) * 1e9)
    if ns < 0:
        raise ConversionError(f"stamp must not be negative ({t_s!r})")
    return ns


def nanoseconds_to_stamp(ns: int) -> Time:
    sec, nanosec = _stamp_parts(ns)
    return Time(sec=sec, nanosec=nanosec)


def _stamp_parts(ns: int) -> tuple[int, int]:
    sec = ns // 1_000_000_000
    if not -(2**31) <= sec < 2**31:
        raise ConversionError(f"stamp {ns} ns does not fit builtin_interfaces/Time (int32 seconds)")
    return sec, ns % 1_000_000_000


_FIELD_FRAME_BYTES = FIELD_FRAME.encode()


def _check_frame(frame_id: str) -> None:
    """World-frame inputs must be in ``field``; an empty frame_id (a hand-typed message) is taken as it."""
    if frame_id and frame_id != FIELD_FRAME:
        raise ConversionError(f"frame_id {frame_id[:40]!r} is not {FIELD_FRAME!r}")


# --------------------------------------------------------------------- angles
def yaw_from_quaternion(q: Quaternion) -> float:
    return _yaw(q.w, q.x, q.y, q.z)


def _yaw(*wxyz: float) -> float:
    return _unit_quaternion_yaw(*(_finite(f"orientation.{n}", v, 2.0) for n, v in zip("wxyz", wxyz, strict=True)))


def _unit_quaternion_yaw(w: float, x: float, y: float, z: float) -> float:
    norm = math.sqrt(w * w + x * x + y * y + z * z)
    if norm < 0.5:
        raise ConversionError("orientation is not a unit quaternion")
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def quaternion_from_yaw(yaw_rad: float) -> Quaternion:
    half = 0.5 * _finite("yaw", yaw_rad, 1.0e6)
    return Quaternion(x=0.0, y=0.0, z=math.sin(half), w=math.cos(half))


# ---------------------------------------------------------------- positions
def point_from_msg(msg: PointStamped | bytes) -> tuple[float, tuple[float, float]]:
    """(stamp [s], (x, y) [m]) of a PointStamped in the field frame (floats: the predictor's hot path).
    ``msg`` may be serialized (a raw subscription's bytes; see the codec below)."""
    if isinstance(msg, bytes):
        t_s, (x, y, _z) = _decode_stamped(msg, 3, "PointStamped")
    else:
        _check_frame(msg.header.frame_id)
        t_s, point = stamp_to_seconds(msg.header.stamp), msg.point
        x, y = point.x, point.y
    return t_s, (_finite("point.x", x), _finite("point.y", y))




def pose2d_from_msg(msg: PoseStamped | bytes) -> tuple[float, np.ndarray]:
    """(stamp [s], [x, y, yaw]) of a planar PoseStamped (or its bytes, as point_from_msg)."""
    if isinstance(msg, bytes):
        t_s, (x, y, _z, qx, qy, qz, qw) = _decode_stamped(msg, 7, "PoseStamped")
        yaw = _yaw(qw, qx, qy, qz)
    else:
        _check_frame(msg.header.frame_id)
        t_s, p = stamp_to_seconds(msg.header.stamp), msg.pose.position
        x, y, yaw = p.x, p.y, yaw_from_quaternion(msg.pose.orientation)
    return t_s, np.array([_finite("position.x", x), _finite("position.y", y), yaw])




def point_cdr(t_s: float, xy: Sequence[float], frame_id: str = FIELD_FRAME) -> bytes:
    """A PointStamped serialized (for ``Publisher.publish``), checked as ``tools.messages.point_msg`` checks it."""
    x, y = xy[0], xy[1]
    if not (abs(x) <= MAX_ABS_VALUE and abs(y) <= MAX_ABS_VALUE):  # one test for the usual point (False for NaN)
        x, y = _finite("x", x), _finite("y", y)
    return _stamped_cdr(t_s, frame_id, (x, y, 0.0))


def pose2d_cdr(t_s: float, pose: Sequence[float], frame_id: str = FIELD_FRAME) -> bytes:
    """A PoseStamped serialized, checked as ``tools.messages.pose2d_msg`` checks it."""
    x, y, yaw = pose[0], pose[1], pose[2]
    if not (abs(x) <= MAX_ABS_VALUE and abs(y) <= MAX_ABS_VALUE and abs(yaw) <= 1.0e6):  # as in point_cdr
        x, y, yaw = _finite("x", x), _finite("y", y), _finite("yaw", yaw, 1.0e6)
    half = 0.5 * yaw
    return _stamped_cdr(t_s, frame_id, (x, y, 0.0, 0.0, 0.0, math.sin(half), math.cos(half)))  # no Quaternion object


# -------------------------------------------------------------------- twists
def twist_from_msg(msg: Twist, max_linear_mps: float = MAX_ABS_VALUE,
                   max_angular_radps: float = MAX_ABS_VALUE) -> np.ndarray:
    """[vx, vy, wz] of a planar Twist; non-planar components must be zero or absent."""
    vx = _finite("linear.x", msg.linear.x, max_linear_mps)
    vy = _finite("linear.y", msg.linear.y, max_linear_mps)
    wz = _finite("angular.z", msg.angular.z, max_angular_radps)
    for name, v in (("linear.z", msg.linear.z), ("angular.x", msg.angular.x), ("angular.y", msg.angular.y)):
        _finite(name, v)
    return np.array([vx, vy, wz])


def twist_msg(twist: Sequence[float]) -> Twist:
    msg = Twist()
    msg.linear.x = _finite("vx", twist[0])
    msg.linear.y = _finite("vy", twist[1])
    msg.angular.z = _finite("wz", twist[2])
    return msg


# ---------------------------------------------------------------- odometry
def odometry_msg(t_s: float, pose: Sequence[float], velocity: Sequence[float], child_frame_id: str = "",
                 frame_id: str = FIELD_FRAME, spin: Sequence[float] | None = None,
                 position_variance_m2: float | None = None, out: Odometry | None = None,
                 velocity_variance_m2ps2: float | None = None) -> Odometry:
    """Planar odometry: pose [x, y, yaw], velocity [vx, vy, wz] in the field frame.

    ``spin`` (a ball's angular velocity [wx, wy, wz]) replaces twist.angular when given.
    ``position_variance_m2`` / ``velocity_variance_m2ps2``: the variance of x and of y / of vx and of vy, on the
    pose's / twist's covariance diagonal (None: 0 there, as the rest of both covariances).
    ``out``: refill this message instead of building one (publishers that send every tick; a
    message from this function was refilled completely, but one that raised is half-filled).
    """
    msg = Odometry() if out is None else out
    msg.header.stamp = seconds_to_stamp(t_s)
    msg.header.frame_id = frame_id
    msg.child_frame_id = child_frame_id
    position = msg.pose.pose.position
    position.x = _finite("x", pose[0])
    position.y = _finite("y", pose[1])
    position.z = 0.0
    msg.pose.pose.orientation = quaternion_from_yaw(pose[2])
    twist = msg.twist.twist
    twist.linear.x = _finite("vx", velocity[0])
    twist.linear.y = _finite("vy", velocity[1])
    twist.linear.z = 0.0
    angular = twist.angular
    if spin is not None:
        angular.x = _finite("spin.x", spin[0], MAX_ABS_ANGULAR)
        angular.y = _finite("spin.y", spin[1], MAX_ABS_ANGULAR)
        angular.z = _finite("spin.z", spin[2], MAX_ABS_ANGULAR)
    else:
        angular.x = angular.y = 0.0
        angular.z = _finite("wz", velocity[2])
    for cov, variance, name in ((msg.pose.covariance, position_variance_m2, "position variance"),
                                (msg.twist.covariance, velocity_variance_m2ps2, "velocity variance")):
        cov.fill(0.0)
        if variance is not None:
            cov[0] = cov[7] = _finite(name, variance)
    return msg


def odometry_cdr(t_s: float, pose: Sequence[float], velocity: Sequence[float], child_frame_id: str = "",
                 frame_id: str = FIELD_FRAME, spin: Sequence[float] | None = None,
                 position_variance_m2: float | None = None, z_m: float = 0.0, vz_mps: float = 0.0,
                 xyz_covariance: np.ndarray | None = None, vxyz_covariance: np.ndarray | None = None,
                 velocity_variance_m2ps2: float | None = None, yaw_variance_rad2: float | None = None,
                 yaw_rate_variance_rad2ps2: float | None = None) -> bytes:
    """``odometry_msg`` serialized (see the codec below), with the same checks; ``z_m`` and ``vz_mps`` go to
    pose.position.z and twist.linear.z (/ball/state: a chipped ball's height and vertical speed).
    ``xyz_covariance`` / ``vxyz_covariance`` (3, 3): the covariance of (x, y, z) / (vx, vy, vz), the rows and
    columns 0-2 of the pose's / twist's covariance (each replaces ``position_variance_m2``'s /
    ``velocity_variance_m2ps2``'s diagonal). ``yaw_variance_rad2`` / ``yaw_rate_variance_rad2ps2``: the last
    diagonal element of the pose's / twist's covariance (None: 0)."""
    x, y, half = _finite("x", pose[0]), _finite("y", pose[1]), 0.5 * _finite("yaw", pose[2], 1.0e6)
    qz, qw = math.sin(half), math.cos(half)  # quaternion_from_yaw's, without a message object
    vx, vy = _finite("vx", velocity[0]), _finite("vy", velocity[1])
    if spin is not None:
        angular = tuple(_finite(f"spin.{axis}", value, MAX_ABS_ANGULAR)
                        for axis, value in zip("xyz", spin[:3], strict=True))
    else:
        angular = (0.0, 0.0, _finite("wz", velocity[2]))
    variance = 0.0 if position_variance_m2 is None else _finite("position variance", position_variance_m2)
    v_variance = 0.0 if velocity_variance_m2ps2 is None else _finite("velocity variance", velocity_variance_m2ps2)
    stamp = _stamp_cdr(_seconds_to_ns(t_s))
    if xyz_covariance is None and vxyz_covariance is None:
        pose_cov = (variance, *_ZEROS[:6], variance, *_ZEROS[:28])
        twist_cov = (v_variance, *_ZEROS[:6], v_variance, *_ZEROS[:28])
    else:
        pose_cov, twist_cov = _covariance_6x6("pose", xyz_covariance, variance), _covariance_6x6(
            "twist", vxyz_covariance, v_variance)
    if yaw_variance_rad2 is not None:
        pose_cov = (*pose_cov[:35], _variance("yaw variance", yaw_variance_rad2))
    if yaw_rate_variance_rad2ps2 is not None:
        twist_cov = (*twist_cov[:35], _variance("yaw rate variance", yaw_rate_variance_rad2ps2))
    # pose (position, orientation), its 6x6 covariance, twist (linear, angular), its covariance
    return _CDR_LE + stamp + _strings_cdr((frame_id, child_frame_id)) + _odometry_doubles.pack(
        x, y, _finite("z", z_m), 0.0, 0.0, qz, qw, *pose_cov, vx, vy, _finite("vz", vz_mps), *angular, *twist_cov)


def _variance(name: str, value: float) -> float:
    """``value`` as a variance: finite and >= 0, else ConversionError naming it."""
    value = _finite(name, value)
    if value < 0.0:
        raise ConversionError(f"{name}: must be >= 0, got {value!r}")
    return value


def _covariance_6x6(name: str, linear: np.ndarray | None, planar_variance: float) -> tuple[float, ...]:
    """A pose's or twist's 6x6 covariance (row-major) with ``linear`` (3, 3) in rows and columns 0-2 (None: x and y
    with ``planar_variance``); a non-finite or negative variance raises ConversionError."""
    out = np.zeros((6, 6))
    if linear is None:
        out[0, 0] = out[1, 1] = planar_variance
    else:
        block = np.asarray(linear, dtype=float)
        if block.shape != (3, 3) or not np.isfinite(block).all() or (np.diag(block) < 0.0).any():
            raise ConversionError(f"{name} covariance: a finite (3, 3) with variances >= 0, got {linear!r}")
        out[:3, :3] = block
    return tuple(out.reshape(-1).tolist())


def odometry_height(msg: Odometry | bytes) -> tuple[float, float]:
    """(pose.position.z [m], twist.linear.z [m/s]) of an Odometry or its bytes: on /ball/state a chipped ball's
    height above its resting height and vertical speed (0, 0 on the ground)."""
    if isinstance(msg, bytes | bytearray | memoryview):
        _, v = _odometry_values(bytes(msg))
        z, vz = v[2], v[45]
    else:
        z, vz = msg.pose.pose.position.z, msg.twist.twist.linear.z
    return _finite("pose.position.z", z), _finite("twist.linear.z", vz)


def odometry_from_msg(msg: Odometry | bytes) -> tuple[float, np.ndarray, np.ndarray, np.ndarray]:
    """(stamp [s], pose [x, y, yaw], velocity [vx, vy, wz], angular [wx, wy, wz]) in ``field``. ``msg`` may be
    serialized (as point_from_msg): rclpy took ~140 us to build an Odometry, its covariances included."""
    if isinstance(msg, bytes):
        return _odometry_from_cdr(msg)
    _check_frame(msg.header.frame_id)
    p = msg.pose.pose.position
    pose = np.array([_finite("pose.position.x", p.x), _finite("pose.position.y", p.y),
                     yaw_from_quaternion(msg.pose.pose.orientation)])
    lin, ang = msg.twist.twist.linear, msg.twist.twist.angular
    angular = np.array([_finite("twist.angular.x", ang.x, MAX_ABS_ANGULAR),
                        _finite("twist.angular.y", ang.y, MAX_ABS_ANGULAR),
                        _finite("twist.angular.z", ang.z, MAX_ABS_ANGULAR)])
    velocity = np.array([_finite("twist.linear.x", lin.x), _finite("twist.linear.y", lin.y), angular[2]])
    return stamp_to_seconds(msg.header.stamp), pose, velocity, angular


def ball_state_from_msg(msg: Odometry | bytes) -> tuple[float, np.ndarray, np.ndarray]:
    """A /ball/state as the ball's consumers take it: (stamp [s], [x, y], [vx, vy]) for a ball on the ground,
    (stamp, [x, y, z], [vx, vy, vz]) for one in the air: its height above its rest or its vertical speed above 0
    (odometry_height; a height below 0 is noise on the ground). chip_model.flying_ball makes the chip of it."""
    stamp, pose, velocity, _ = odometry_from_msg(msg)
    z, vz = odometry_height(msg)
    z = max(z, 0.0)
    if z > 0.0 or vz > 0.0:
        return stamp, np.array([pose[0], pose[1], z]), np.array([velocity[0], velocity[1], vz])
    return stamp, pose[:2].copy(), velocity[:2].copy()


def _odometry_values(data: bytes) -> tuple[float, tuple[float, ...]]:
    """An Odometry's bytes: the stamp [s] and the 85 doubles after both frame strings (odometry_cdr's order)."""
    try:
        sec, nanosec, p = _header_cdr(data, "Odometry")
        p += -p % 4  # child_frame_id
        p += 4 + _u32.unpack_from(data, 4 + p)[0]
        p += -p % 8
        return sec + nanosec * 1e-9, _odometry_doubles.unpack_from(data, 4 + p)
    except struct.error as exc:
        raise ConversionError(f"truncated Odometry ({exc})") from None


def _odometry_from_cdr(data: bytes) -> tuple[float, np.ndarray, np.ndarray, np.ndarray]:
    """odometry_from_msg of the bytes: the stamp, both frame strings, then the 85 doubles (odometry_cdr)."""
    t_s, v = _odometry_values(data)
    x, y, qx, qy, qz, qw, vx, vy, wx, wy, wz = v[0], v[1], v[3], v[4], v[5], v[6], v[43], v[44], v[46], v[47], v[48]
    # One check for the usual message: a sum of magnitudes is NaN or inf when any term is, and within the
    # tightest limit each term is within its own; else the per-field checks below name the bad field.
    if (abs(x) + abs(y) + abs(vx) + abs(vy) <= MAX_ABS_VALUE and abs(wx) + abs(wy) + abs(wz) <= MAX_ABS_ANGULAR
            and abs(qx) + abs(qy) + abs(qz) + abs(qw) <= 2.0):
        return (t_s, np.array([x, y, _unit_quaternion_yaw(qw, qx, qy, qz)]),
                np.array([vx, vy, wz]), np.array([wx, wy, wz]))
    pose = np.array([_finite("pose.position.x", v[0]), _finite("pose.position.y", v[1]), _yaw(v[6], v[3], v[4], v[5])])
    angular = np.array([_finite(f"twist.angular.{axis}", value, MAX_ABS_ANGULAR)
                        for axis, value in zip("xyz", v[46:49], strict=True)])
    velocity = np.array([_finite("twist.linear.x", v[43]), _finite("twist.linear.y", v[44]), angular[2]])
    return t_s, pose, velocity, angular


# ------------------------------------------------------------ joint arrays


def joint_state_from_msg(msg: JointState | bytes, num_joints: int, field: str,
                         limit: float = MAX_ABS_VALUE) -> tuple[int, np.ndarray]:
    """(stamp [ns], values) of the ``velocity``, ``effort`` or ``position`` field, checked for length
    and finiteness. ``msg`` is a JointState or its serialized form (a raw subscription's bytes).

    When names are given they must be ``wheel_0..wheel_{n-1}`` in order, so a re-ordered
    or foreign message cannot be applied to the wrong wheel.
    """
    t_ns, (values,) = _joint_fields(msg, num_joints, (field,), limit)
    return t_ns, values


def wheel_states_from_msg(msg: JointState | bytes, num_wheels: int) -> tuple[int, np.ndarray, np.ndarray]:
    """(stamp [ns], wheel speeds [rad/s], motor currents [A]) of a ``wheel_states`` message."""
    t_ns, (speeds, currents) = _joint_fields(msg, num_wheels, ("velocity", "effort"), MAX_ABS_VALUE)
    return t_ns, speeds, currents


_JOINT_FIELDS = ("position", "velocity", "effort")


def _joint_fields(msg: JointState | bytes, num_joints: int, fields: Sequence[str],
                  limit: float) -> tuple[int, list[np.ndarray]]:
    for field in fields:
        if field not in _JOINT_FIELDS:
            raise ValueError(f"unknown JointState field {field!r}")
    if isinstance(msg, bytes | bytearray | memoryview):
        t_ns, names, arrays = _decode_joint_state(msg)
        found = dict(zip(_JOINT_FIELDS, arrays, strict=True))
    else:
        t_ns, names = stamp_to_nanoseconds(msg.header.stamp), list(msg.name)
        found = {field: getattr(msg, field) for field in fields}
    if names and names != [f"wheel_{i}" for i in range(num_joints)]:
        raise ConversionError(f"joint names {names} are not wheel_0..wheel_{num_joints - 1}")
    return t_ns, [_checked_values(field, found[field], num_joints, limit) for field in fields]


def _checked_values(name: str, values: Sequence[float], length: int, limit: float) -> np.ndarray:
    return np.array(_checked_floats(name, values, length, limit))


def _checked_floats(name: str, values: Sequence[float], length: int, limit: float) -> list[float]:
    """The values as floats: exactly ``length`` of them, finite and within +-limit (plain Python:
    for a handful of values it is several times faster than numpy)."""
    values = values.tolist() if isinstance(values, np.ndarray) else [float(v) for v in values]
    if len(values) != length:
        raise ConversionError(f"{name} has {len(values)} entries, expected {length}")
    for i, v in enumerate(values):
        if not -limit <= v <= limit:  # also false for NaN
            if not math.isfinite(v):
                raise ConversionError(f"{name}[{i}] is not finite")
            raise ConversionError(f"{name} has a value beyond the accepted magnitude {limit:g}")
    return values


# ------------------------------------------------- joint arrays, serialized
# The lockstep topics (one JointState per robot and tick, 500 Hz) are published and taken in
# their serialized form: on this machine building a JointState and letting rclpy convert it
# cost more than the motor-board maths it carries. The wire format is what rmw_fastrtps writes
# (plain CDR, little endian, doubles aligned to 8 bytes from the start of the payload), so any
# ROS 2 subscriber or publisher of sensor_msgs/JointState talks to these nodes unchanged;
# test_contract.py checks both directions against rclpy.serialization.
_CDR_LE = b"\x00\x01\x00\x00"  # encapsulation header: CDR, little endian
_MAX_JOINTS = 1024  # a count beyond this is garbage, not a robot
_u32 = struct.Struct("<I")
_stamp = struct.Struct("<iI")


def _stamp_cdr(t_ns: int) -> bytes:
    return _stamp.pack(*_stamp_parts(int(t_ns)))


def joint_state_cdr(t_ns: int, names: Sequence[str], *, velocity: Sequence[float] | None = None,
                    effort: Sequence[float] | None = None, saturate: bool = False) -> bytes:
    """A JointState serialized (for ``Publisher.publish``), checked as ``tools.messages.joint_state_msg``. ``saturate``:
    finite values beyond the accepted magnitude are clipped to it instead of refused (a sensor's range)."""
    parts = [_CDR_LE, _stamp_cdr(t_ns), _cdr_names(tuple(names))]
    offset = 8 + len(parts[2])
    for name, values in (("position", None), ("velocity", velocity), ("effort", effort)):
        if values is None:
            parts.append(_u32.pack(0))
            offset += 4
            continue
        if saturate:
            values = [min(max(float(v), -MAX_ABS_VALUE), MAX_ABS_VALUE) if math.isfinite(v) else v for v in values]
        values = _checked_floats(name, values, len(names), MAX_ABS_VALUE)
        n = len(values)
        pad = -(offset + 4) % 8 if n else 0
        parts.append(_u32.pack(n) + bytes(pad) + struct.pack(f"<{n}d", *values))
        offset += 4 + pad + 8 * n
    return b"".join(parts)


@functools.lru_cache(maxsize=64)
def _cdr_names(names: tuple[str, ...]) -> bytes:
    """frame_id (empty) and the name sequence, from offset 8 of the payload (after the stamp)."""
    out = bytearray(_u32.pack(1) + b"\x00")
    out += bytes(-len(out) % 4) + _u32.pack(len(names))
    for name in names:
        raw = name.encode() + b"\x00"
        out += bytes(-(8 + len(out)) % 4) + _u32.pack(len(raw)) + raw
    out += bytes(-(8 + len(out)) % 4)
    return bytes(out)


# ------------------------------------------- team-level joint arrays, serialized
# One JointState per tick for many robots of a team (contract: /team/wheel_states, /team/motor_duty), joints
# ``robot_<id>/wheel_<k>`` (``team``: contract.Team; the opponents' ``opponent_<id>/wheel_<k>``). Values travel
# as (robots, wheels) arrays; the names block is the same from tick to tick, so it is built once per robot set
# and, on the way in, recognised by its bytes.
def team_joint_state_cdr(t_ns: int, robot_ids: Sequence[int], wheel_names: Sequence[str], *,
                         velocity: np.ndarray | None = None, effort: np.ndarray | None = None,
                         saturate: bool = False, team: Team = OURS) -> bytes:
    """A team-level JointState serialized: ``velocity`` / ``effort`` are (robots, wheels) arrays, rows in
    ``robot_ids`` order, checked like ``joint_state_cdr`` (``saturate``: a sensor's range)."""
    ids = robot_ids if type(robot_ids) is tuple else tuple(int(i) for i in robot_ids)
    heads, n = _team_layout(ids, tuple(wheel_names), velocity is not None, effort is not None, team)
    return _joint_arrays_cdr(t_ns, heads, n, velocity, effort, saturate)


def field_joint_state_cdr(t_ns: int, robot_ids: tuple[Sequence[int], Sequence[int]], wheel_names: Sequence[str], *,
                          velocity: np.ndarray | None = None, effort: np.ndarray | None = None,
                          saturate: bool = False) -> bytes:
    """A field-level JointState serialized (contract: /field/wheel_states, /field/motor_duty): ``robot_ids`` is
    (our ids, the opponents' ids); ``velocity`` / ``effort`` are (robots, wheels) arrays, our rows first, then
    the opponents', each in its ids' order; checked like ``team_joint_state_cdr``."""
    ours, theirs = robot_ids
    ids = (ours if type(ours) is tuple else tuple(int(i) for i in ours),
           theirs if type(theirs) is tuple else tuple(int(i) for i in theirs))
    heads, n = _field_layout(ids, tuple(wheel_names), velocity is not None, effort is not None)
    return _joint_arrays_cdr(t_ns, heads, n, velocity, effort, saturate)


def _joint_arrays_cdr(t_ns: int, heads: tuple[bytes, bytes], n: int, velocity: np.ndarray | None,
                      effort: np.ndarray | None, saturate: bool) -> bytes:
    parts = [_CDR_LE, _stamp_cdr(t_ns)]
    for name, values, head in (("velocity", velocity, heads[0]), ("effort", effort, heads[1])):
        parts.append(head)
        if values is None:
            continue
        arr = np.asarray(values, dtype=float).reshape(-1)
        if arr.size != n:
            raise ConversionError(f"{name} has {arr.size} entries, expected {n}")
        if n and not np.abs(arr).max() <= MAX_ABS_VALUE:  # one test for the usual values (False for NaN)
            if saturate:
                arr = np.where(np.isfinite(arr), np.clip(arr, -MAX_ABS_VALUE, MAX_ABS_VALUE), arr)
            _check_array(name, arr, MAX_ABS_VALUE)
        parts.append(arr.astype("<f8", copy=False).tobytes())
    return b"".join(parts)


@functools.lru_cache(maxsize=16)
def _team_layout(robot_ids: tuple[int, ...], wheel_names: tuple[str, ...], velocity: bool,
                 effort: bool, team: Team) -> tuple[tuple[bytes, bytes], int]:
    """The constant bytes of a team JointState before its velocity values (names, the empty position
    sequence, the velocity count and padding) and before its effort values (their count and padding),
    and the number of joints. An absent field is an empty sequence."""
    _check_increasing(robot_ids)
    return _joint_layout(team.joint_names(robot_ids, wheel_names), velocity, effort)


@functools.lru_cache(maxsize=16)
def _field_layout(robot_ids: tuple[tuple[int, ...], tuple[int, ...]], wheel_names: tuple[str, ...], velocity: bool,
                  effort: bool) -> tuple[tuple[bytes, bytes], int]:
    """As ``_team_layout`` for a field-level JointState: our robots' joints, then the opponents'."""
    for ids in robot_ids:
        _check_increasing(ids)
    return _joint_layout(field_joint_names(robot_ids, wheel_names), velocity, effort)


def _check_increasing(robot_ids: tuple[int, ...]) -> None:
    if len(set(robot_ids)) != len(robot_ids) or list(robot_ids) != sorted(robot_ids):
        raise ConversionError(f"robot ids {list(robot_ids)} are not distinct and increasing")


def _joint_layout(names: tuple[str, ...], velocity: bool, effort: bool) -> tuple[tuple[bytes, bytes], int]:
    names_cdr = _cdr_names(names)
    n = len(names)
    heads = [names_cdr + _u32.pack(0), b""]
    offset = 8 + len(heads[0])  # payload offset of the velocity count
    for k, present in enumerate((velocity, effort)):
        count = n if present else 0
        pad = bytes(-(offset + 4) % 8) if count else b""
        heads[k] += _u32.pack(count) + pad
        offset += 4 + len(pad) + 8 * count
    return (heads[0], heads[1]), n


def _check_array(name: str, arr: np.ndarray, limit: float) -> None:
    inside = np.abs(arr) <= limit  # false for NaN too
    if not inside.all():
        k = int(np.argmin(inside))
        if not math.isfinite(arr[k]):
            raise ConversionError(f"{name}[{k}] is not finite")
        raise ConversionError(f"{name} has a value beyond the accepted magnitude {limit:g}")


def team_robot_ids_of(names: Sequence[str], num_wheels: int, team: Team = OURS) -> tuple[int, ...]:
    """The robot ids of a team-level JointState's joint names; raises ConversionError unless the names are
    ``<team prefix><id>/wheel_0 .. wheel_{n-1}`` per robot, ids increasing."""
    if len(names) % num_wheels:
        raise ConversionError(f"{len(names)} joint names are not {num_wheels} wheels per robot")
    ids: list[int] = []
    for r in range(len(names) // num_wheels):
        first = names[r * num_wheels]
        head, _, _ = first.partition("/")
        prefix = team.prefix
        digits = head[len(prefix):]
        if not head.startswith(prefix) or not digits.isascii() or not digits.isdigit():
            raise ConversionError(f"joint name {first[:40]!r} is not {prefix}<id>/wheel_<k>")
        robot = int(digits)
        expected = [f"{head}/wheel_{k}" for k in range(num_wheels)]
        if list(names[r * num_wheels : (r + 1) * num_wheels]) != expected or (ids and robot <= ids[-1]):
            raise ConversionError(f"joint names of {head[:40]} are not {expected[0]}..wheel_{num_wheels - 1} "
                                  "in increasing robot order")
        ids.append(robot)
    return tuple(ids)


def field_robot_ids_of(names: Sequence[str], num_wheels: int) -> tuple[tuple[int, ...], tuple[int, ...]]:
    """(our robot ids, the opponents' robot ids) of a field-level JointState's joint names; raises
    ConversionError unless the names are our robots' (``team_robot_ids_of``), then the opponents'."""
    split = len(names)
    for k in range(0, len(names), num_wheels):  # the first robot that is not ours starts the opponents
        if not names[k].startswith(OURS.prefix):
            split = k
            break
    return team_robot_ids_of(names[:split], num_wheels, OURS), team_robot_ids_of(names[split:], num_wheels, OPPONENTS)


# (team prefix or "field", names block from payload offset 8) -> (robot ids, its length); a few entries: one per
# sender
_team_names_seen: dict[tuple[str, bytes], tuple[tuple, int]] = {}
_FIELD_KEY = "field"


def team_joint_state_from_msg(msg: JointState | bytes, num_wheels: int, fields: Sequence[str],
                              limit: float = MAX_ABS_VALUE, team: Team = OURS,
                              ) -> tuple[int, tuple[int, ...], list[np.ndarray]]:
    """(stamp [ns], robot ids, one (robots, wheels) array per field) of a team-level JointState, checked
    for names (of ``team``'s robots), lengths and finiteness like ``joint_state_from_msg``."""
    return _joint_arrays_from_msg(msg, num_wheels, fields, limit, team.prefix,
                                  lambda names: team_robot_ids_of(names, num_wheels, team), len)


def field_joint_state_from_msg(msg: JointState | bytes, num_wheels: int, fields: Sequence[str],
                               limit: float = MAX_ABS_VALUE,
                               ) -> tuple[int, tuple[tuple[int, ...], tuple[int, ...]], list[np.ndarray]]:
    """(stamp [ns], (our robot ids, the opponents'), one (robots, wheels) array per field, our rows first) of a
    field-level JointState, checked like ``team_joint_state_from_msg``."""
    return _joint_arrays_from_msg(msg, num_wheels, fields, limit, _FIELD_KEY,
                                  lambda names: field_robot_ids_of(names, num_wheels),
                                  lambda ids: len(ids[0]) + len(ids[1]))


def _joint_arrays_from_msg(msg, num_wheels: int, fields: Sequence[str], limit: float, key: str, ids_of,
                           num_robots) -> tuple[int, tuple, list[np.ndarray]]:
    for field in fields:
        if field not in _JOINT_FIELDS:
            raise ValueError(f"unknown JointState field {field!r}")
    if not isinstance(msg, bytes | bytearray | memoryview):
        ids = ids_of(list(msg.name))
        arrays = {f: np.asarray(getattr(msg, f), dtype=float) for f in fields}
        t_ns = stamp_to_nanoseconds(msg.header.stamp)
    else:
        t_ns, ids, arrays = _decode_team_joint_state(bytes(msg), fields, key, ids_of)
    robots = num_robots(ids)
    n = robots * num_wheels
    out = []
    for field in fields:
        arr = arrays[field]
        if arr.size != n:
            raise ConversionError(f"{field} has {arr.size} entries, expected {n}")
        _check_array(field, arr, limit)
        out.append(arr.reshape(robots, num_wheels))
    return t_ns, ids, out


def _decode_team_joint_state(data: bytes, fields: Sequence[str], key: str,
                             ids_of) -> tuple[int, tuple, dict[str, np.ndarray]]:
    if data[:2] != _CDR_LE[:2]:
        raise ConversionError("not a little-endian CDR JointState")
    known = next(((block, seen) for (k, block), seen in _team_names_seen.items()
                  if k == key and data.startswith(block, 12)), None)
    if known is None:  # a new sender: decode it all, and remember its names block if it is ours (empty frame_id)
        t_ns, names, values = _decode_joint_state(data)
        ids = ids_of(names)
        block = _cdr_names(tuple(names))
        if data.startswith(block, 12):
            if len(_team_names_seen) >= 8:
                _team_names_seen.clear()
            _team_names_seen[(key, block)] = (ids, len(block))
        found = dict(zip(_JOINT_FIELDS, values, strict=True))
        return t_ns, ids, {f: found[f] for f in fields}
    block, (ids, _) = known
    try:
        t_ns = _checked_stamp_ns(*_stamp.unpack_from(data, 4))
        arrays = dict(zip(_JOINT_FIELDS, _joint_value_arrays(data, 8 + len(block)), strict=True))
    except struct.error as exc:
        raise ConversionError(f"truncated JointState ({exc})") from None
    return t_ns, ids, {f: arrays[f] for f in fields}


# The stamped messages sent often (PointStamped, PoseStamped, Odometry, Clock) and Float64 likewise:
# on the ball predictor's path and in the plant's every tick rclpy's message objects cost more than
# the maths (a PointStamped took 139 us to take as a message and 26 us as bytes, medians in the demo).
# Layout: the stamp, the header's strings (length, characters, NUL), padding so that the doubles start
# at a multiple of 8 from the payload start, then the doubles (Point: x y z; Pose: x y z, qx qy qz qw;
# Odometry: pose, its 6x6 covariance, twist, its covariance).
_f64 = struct.Struct("<d")
_odometry_doubles = struct.Struct("<85d")
_ZEROS = (0.0,) * 36


@functools.lru_cache(maxsize=64)
def _strings_cdr(strings: tuple[str, ...]) -> bytes:
    """Strings that follow the stamp (from payload offset 8), padded so that doubles come next."""
    out = bytearray()
    for text in strings:
        raw = text.encode() + b"\x00"
        out += bytes(-(8 + len(out)) % 4) + _u32.pack(len(raw)) + raw
    return bytes(out + bytes(-(8 + len(out)) % 8))


@functools.lru_cache(maxsize=64)
def _stamped_layout(frame_id: str, num_doubles: int) -> tuple[struct.Struct, bytes]:
    """The whole message as one Struct (encapsulation, stamp, frame_id, doubles): one pack per message."""
    strings = _strings_cdr((frame_id,))
    return struct.Struct(f"<4siI{len(strings)}s{num_doubles}d"), strings


def _stamped_cdr(t_s: float, frame_id: str, values: tuple[float, ...]) -> bytes:
    layout, strings = _stamped_layout(frame_id, len(values))
    return layout.pack(_CDR_LE, *_sec_nanosec(t_s), strings, *values)


def _sec_nanosec(t_s: float) -> tuple[int, int]:
    """A stamp's (sec, nanosec), checked (ConversionError)."""
    if 0.0 <= t_s < 2.0e9:  # the usual stamp: the checks of _seconds_to_ns and _stamp_parts in one (False for NaN)
        ns = round(float(t_s) * 1e9)
        return ns // 1_000_000_000, ns % 1_000_000_000
    return _stamp_parts(_seconds_to_ns(t_s))


def clock_cdr(t_ns: int) -> bytes:
    """A rosgraph_msgs/Clock at ``t_ns`` serialized (the plant sends one per tick)."""
    return _CDR_LE + _stamp_cdr(t_ns)


def _decode_stamped(data: bytes, num_doubles: int, what: str) -> tuple[float, tuple[float, ...]]:
    """(stamp [s], the doubles after the header) of a serialized Header + doubles message."""
    try:
        sec, nanosec, p = _header_cdr(data, what)
        p += -p % 8
        values = struct.unpack_from(f"<{num_doubles}d", data, 4 + p)
    except struct.error as exc:
        raise ConversionError(f"truncated {what} ({exc})") from None
    return sec + nanosec * 1e-9, values


def _header_cdr(data: bytes, what: str) -> tuple[int, int, int]:
    """(sec, nanosec, payload offset after frame_id) of a serialized message that starts with a Header,
    whose stamp and frame (``field`` or empty) are checked (struct.error when the message ends early)."""
    if data[:2] != _CDR_LE[:2]:
        raise ConversionError(f"not a little-endian CDR {what}")
    sec, nanosec = _stamp.unpack_from(data, 4)
    length = _u32.unpack_from(data, 12)[0]
    frame = data[16 : 15 + length]  # without its NUL
    if frame and frame != _FIELD_FRAME_BYTES:
        _check_frame(frame.decode("utf-8", "replace"))
    _checked_stamp_ns(sec, nanosec)
    return sec, nanosec, 12 + length


def _decode_joint_state(data: bytes) -> tuple[int, list[str], list[np.ndarray]]:
    """(stamp [ns], names, (position, velocity, effort)) of a serialized JointState."""
    data = bytes(data)
    if data[:2] != _CDR_LE[:2]:
        raise ConversionError("not a little-endian CDR JointState")
    # p: offset in the payload, which starts after the 4-byte encapsulation header (CDR aligns to it)
    try:
        sec, nanosec = _stamp.unpack_from(data, 4)
        p = 12 + _u32.unpack_from(data, 12)[0]  # frame_id is not used
        p += -p % 4
        count = _u32.unpack_from(data, 4 + p)[0]
        if count > _MAX_JOINTS:
            raise ConversionError(f"{count} joint names")
        p += 4
        names = []
        for _ in range(count):
            p += -p % 4
            length = _u32.unpack_from(data, 4 + p)[0]
            if length < 1 or 8 + p + length > len(data):
                raise ConversionError("a joint name runs past the message")
            names.append(data[8 + p : 7 + p + length].decode("utf-8", "replace"))
            p += 4 + length
        arrays = _joint_value_arrays(data, p)
    except struct.error as exc:
        raise ConversionError(f"truncated JointState ({exc})") from None
    return _checked_stamp_ns(sec, nanosec), names, arrays


def _joint_value_arrays(data: bytes, p: int) -> list[np.ndarray]:
    """The position, velocity and effort sequences of a serialized JointState whose names end at payload
    offset ``p`` (struct.error when the message ends early)."""
    arrays = []
    for _ in _JOINT_FIELDS:
        p += -p % 4
        count = _u32.unpack_from(data, 4 + p)[0]
        if count > _MAX_JOINTS:
            raise ConversionError(f"{count} joint values")
        p += 4
        if count:
            p += -p % 8
            if 4 + p + 8 * count > len(data):
                raise ConversionError("joint values run past the message")
            arrays.append(np.frombuffer(data, "<f8", count, 4 + p).astype(float))
            p += 8 * count
        else:
            arrays.append(np.empty(0))
    return arrays


# ------------------------------------------------------------ scalar & tables


def float64_cdr(value: float, limit: float = MAX_ABS_VALUE) -> bytes:
    """A Float64 serialized, checked as ``tools.messages.float64_msg`` checks it."""
    return _CDR_LE + _f64.pack(_finite("data", value, limit))


def ball_phase_from_msg(msg) -> str:
    """The phase a /ball/phase String names (one of contract.BALL_PHASES)."""
    if msg.data not in BALL_PHASES:
        raise ConversionError(f"phase {msg.data[:40]!r} is none of {', '.join(BALL_PHASES)}")
    return msg.data


def float64_from_msg(msg: Float64 | bytes, limit: float = MAX_ABS_VALUE) -> float:
    """The value of a Float64 (or its bytes, as point_from_msg)."""
    if isinstance(msg, bytes):
        if len(msg) < 12 or msg[:2] != _CDR_LE[:2]:
            raise ConversionError("not a little-endian CDR Float64")
        return _finite("data", _f64.unpack_from(msg, 4)[0], limit)
    return _finite("data", msg.data, limit)


