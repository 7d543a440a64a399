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
from typing import NamedTuple

import numpy as np
from builtin_interfaces.msg import Time
from geometry_msgs.msg import PointStamped, PoseStamped, Quaternion, Twist
from nav_msgs.msg import Odometry
from sensor_msgs.msg import JointState, PointCloud2, PointField
from std_msgs.msg import Float64, Float64MultiArray, MultiArrayDimension

from erforce_interfaces.wire.contract import (
    BALL_MODEL_PARAM_LABELS,
    BALL_MODEL_PARAM_ROWS,
    BALL_PHASES,
    BALL_TRACK_FIELDS,
    CATCH_TABLE_COLUMNS,
    CATCH_TIME_NEVER,
    FIELD_FRAME,
    OPPONENTS,
    OURS,
    TRACKED_ROBOT_COLUMNS,
    VISION_BALL_CODE,
    VISION_FIELD_COLUMNS,
    VISION_ROBOT_FIELDS,
    Team,
    field_joint_names,
)
from erforce_interfaces.wire.robot_config import FieldConfig
from erforce_interfaces.wire.stamps import stamp_ns

#: Largest magnitude accepted for any position [m], speed [m/s] or rate [rad/s] on the wire.
#: Far beyond anything physical on an SSL field; it keeps "huge" values out of the cores.
MAX_ABS_VALUE = 1.0e3
MAX_ABS_ANGULAR = 1.0e5  # [rad, rad/s] yaw of a pose, angular velocities: a magnitude beyond this is garbage


class ConversionError(ValueError):
    """A message that the cores must not see (non-finite, absurd, or mis-shaped)."""


def _finite(name: str, value: float, limit: float = MAX_ABS_VALUE) -> float:
    v = float(value)
    if not math.isfinite(v):
        raise ConversionError(f"{name} is not finite ({v!r})")
    if abs(v) > limit:
        raise ConversionError(f"{name} = {v!r} exceeds the accepted magnitude {limit:g}")
    return v


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
                 position_variance_m2: float | None = None, out: Odometry | None = None) -> Odometry:
    """Planar odometry: pose [x, y, yaw], velocity [vx, vy, wz] in the field frame.

    ``spin`` (a ball's angular velocity [wx, wy, wz]) replaces twist.angular when given.
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
    cov = msg.pose.covariance
    cov.fill(0.0)
    if position_variance_m2 is not None:
        cov[0] = cov[7] = _finite("position variance", position_variance_m2)
    return msg


def odometry_cdr(t_s: float, pose: Sequence[float], velocity: Sequence[float], child_frame_id: str = "",
                 frame_id: str = FIELD_FRAME, spin: Sequence[float] | None = None,
                 position_variance_m2: float | None = None, z_m: float = 0.0, vz_mps: float = 0.0) -> bytes:
    """``odometry_msg`` serialized (see the codec below), with the same checks; ``z_m`` and ``vz_mps`` go to
    pose.position.z and twist.linear.z (/ball/state: a chipped ball's height and vertical speed)."""
    x, y, half = _finite("x", pose[0]), _finite("y", pose[1]), 0.5 * _finite("yaw", pose[2], 1.0e6)
    qz, qw = math.sin(half), math.cos(half)  # quaternion_from_yaw's, without a message object
    vx, vy = _finite("vx", velocity[0]), _finite("vy", velocity[1])
    if spin is not None:
        angular = tuple(_finite(f"spin.{axis}", value, MAX_ABS_ANGULAR)
                        for axis, value in zip("xyz", spin[:3], strict=True))
    else:
        angular = (0.0, 0.0, _finite("wz", velocity[2]))
    variance = 0.0 if position_variance_m2 is None else _finite("position variance", position_variance_m2)
    stamp = _stamp_cdr(_seconds_to_ns(t_s))
    # pose (position, orientation), its 6x6 covariance, twist (linear, angular), its covariance
    return _CDR_LE + stamp + _strings_cdr((frame_id, child_frame_id)) + _odometry_doubles.pack(
        x, y, _finite("z", z_m), 0.0, 0.0, qz, qw, variance, *_ZEROS[:6], variance, *_ZEROS[:28], vx, vy,
        _finite("vz", vz_mps), *angular, *_ZEROS)


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


# ------------------------------------------------------------ vision robots
# /vision/robots: a sensor_msgs/PointCloud2 with one point per robot and one per ball (team VISION_BALL_CODE, yaw
# and robot_id 0, written first), the float64 fields VISION_ROBOT_FIELDS (x, y, z, yaw, team, robot_id) at offsets
# 0, 8, .., little endian, height 1. Its layout is constant but for the stamp, the width and the data: the bytes
# from the fields to point_step are built once and, on the way in, recognised. Rows in and out are (team,
# robot_id, x, y, yaw): Team.code, the id within the team, the pose in ``field`` [m, rad]; yaw goes out and comes
# in wrapped to [-pi, pi]. Balls in and out are (x, y) in ``field`` [m].
_ROBOT_POINT = struct.Struct(f"<{len(VISION_ROBOT_FIELDS)}d")
_MAX_CLOUD_POINTS = 1024  # a width beyond this is garbage, not a field of robots
_TEAM_CODES = (OURS.code, OPPONENTS.code)
_POINT_CODES = (VISION_BALL_CODE, *_TEAM_CODES)
_NO_BALLS = np.empty((0, 2))
_NO_BALLS.flags.writeable = False
_TWO_PI = 2.0 * math.pi
_MAX_ABS_YAW = 1.0e6  # [rad] yaw is wrapped on the way out and in; beyond this a float keeps no fraction of a turn


def _point_is_valid(x: float, y: float, z: float, yaw: float, team: float, robot_id: float,
                    codes: tuple[float, ...] = _POINT_CODES) -> bool:
    """Whether a /vision/robots point (x, y, z, yaw, team, robot_id) passes the reader's checks (False for NaN):
    x, y, z within MAX_ABS_VALUE, yaw within _MAX_ABS_YAW, a team of ``codes``, an integer id in
    0.._MAX_CLOUD_POINTS. The one statement of the point check: the writer, the leading-ball reader and
    ``_robot_rows`` ask it per point (``_robot_rows`` first tests the whole array against ``_ROBOT_POINT_LIMITS``,
    the same limits in array form), and ``_point_error`` names what failed."""
    return (abs(x) <= MAX_ABS_VALUE and abs(y) <= MAX_ABS_VALUE and abs(z) <= MAX_ABS_VALUE
            and abs(yaw) <= _MAX_ABS_YAW and team in codes and 0.0 <= robot_id <= _MAX_CLOUD_POINTS
            and robot_id == int(robot_id))


def _float64_fields_cdr(names: Sequence[str]) -> bytes:
    """A cloud of float64 ``names`` from its fields sequence through point_step; it starts 4-aligned, and
    nothing in it needs more."""
    out = bytearray(_u32.pack(len(names)))
    for k, name in enumerate(names):
        raw = name.encode() + b"\x00"
        out += bytes(-len(out) % 4) + _u32.pack(len(raw)) + raw
        out += bytes(-len(out) % 4) + _u32.pack(8 * k) + bytes((PointField.FLOAT64,))
        out += bytes(-len(out) % 4) + _u32.pack(1)
    out += b"\x00"  # is_bigendian
    return bytes(out + bytes(-len(out) % 4) + _u32.pack(8 * len(names)))


_ROBOT_FIELDS_CDR = _float64_fields_cdr(VISION_ROBOT_FIELDS)


def vision_robots_cdr(t_s: float, rows: Sequence[Sequence[float]], frame_id: str = FIELD_FRAME,
                      balls: Sequence[Sequence[float]] = ()) -> bytes:
    """A /vision/robots PointCloud2 serialized: the ``balls`` (x, y) first, then ``rows`` of (team, robot_id, x, y,
    yaw), checked as the reader checks them (finite, positions within MAX_ABS_VALUE, a team code, an integer id)."""
    flat = []
    for x, y in balls:
        ball = (x, y, 0.0, 0.0, VISION_BALL_CODE, 0.0)
        if not _point_is_valid(*ball):
            _point_error(0, *ball)
        flat += ball
    for k, (team, robot_id, x, y, yaw) in enumerate(rows):
        if not _point_is_valid(x, y, 0.0, yaw, team, robot_id, _TEAM_CODES):
            _point_error(k, x, y, 0.0, yaw, team, robot_id, _TEAM_CODES)
        flat += (x, y, 0.0, math.remainder(yaw, _TWO_PI), team, robot_id)
    return _vision_robots_bytes(t_s, len(balls) + len(rows), struct.pack(f"<{len(flat)}d", *flat), frame_id)


def vision_robots_points_cdr(t_s: float, points: np.ndarray, frame_id: str = FIELD_FRAME) -> bytes:
    """``vision_robots_cdr`` for points the caller has already written and checked as it checks rows: a
    float64 array (n, 6) in VISION_ROBOT_FIELDS order, yaw in [-pi, pi], the ball first (a producer's compiled
    path)."""
    return _vision_robots_bytes(t_s, len(points), points.astype("<f8", copy=False).tobytes(), frame_id)


class VisionRobotsTemplate(NamedTuple):
    """/vision/robots' bytes before its points with the stamp, width and sizes zero, and where those go: for a
    producer that writes the whole message in a compiled pass (stamp: int32 sec at 4, uint32 nanosec at 8;
    width, row_step and the data's length: uint32; the points from ``len(head)``, then is_dense 1)."""

    head: bytes
    width_at: int
    sizes_at: int


@functools.lru_cache(maxsize=8)
def vision_robots_template(frame_id: str = FIELD_FRAME) -> VisionRobotsTemplate:
    head = _vision_robots_bytes(0.0, 0, b"", frame_id)[:-1]
    width_at = len(_stamp_head(0.0) + _frame_cdr(frame_id)) + 4
    return VisionRobotsTemplate(head, width_at, len(head) - 8)


def _vision_robots_bytes(t_s: float, n: int, data: bytes, frame_id: str) -> bytes:
    size = n * _ROBOT_POINT.size
    return b"".join((_stamp_head(t_s), _frame_cdr(frame_id), struct.pack("<II", 1, n), _ROBOT_FIELDS_CDR,
                     struct.pack("<II", size, size), data, b"\x01"))


@functools.lru_cache(maxsize=8)
def _frame_cdr(frame_id: str) -> bytes:
    """frame_id from payload offset 8, padded to 4 (a uint32 follows)."""
    raw = frame_id.encode() + b"\x00"
    return _u32.pack(len(raw)) + raw + bytes(-len(raw) % 4)


def _stamp_head(t_s: float) -> bytes:
    """The encapsulation and the stamp."""
    return _CDR_LE + _stamp.pack(*_sec_nanosec(t_s))


def _point_error(k: int, x, y, z, yaw, team, robot_id, codes: tuple[float, ...] = _POINT_CODES) -> None:
    """Raise the ConversionError that names why point ``k`` fails ``_point_is_valid``."""
    point = "ball" if team == VISION_BALL_CODE else f"robot {k}"
    for name, value, limit in (("z", z, MAX_ABS_VALUE), ("x", x, MAX_ABS_VALUE), ("y", y, MAX_ABS_VALUE),
                               ("yaw", yaw, _MAX_ABS_YAW)):
        _finite(f"{point}: {name}", value, limit)
    if team not in codes:
        raise ConversionError(f"robot {k}: team {team!r} is none of {codes}")
    raise ConversionError(f"robot {k}: robot_id {robot_id!r} is no id (an integer in 0..{_MAX_CLOUD_POINTS})")


def vision_robots_from_msg(msg: PointCloud2 | bytes) -> tuple[float, np.ndarray]:
    """(stamp [s], rows) of /vision/robots' robots: ``vision_frame_from_msg`` without the balls."""
    t_s, _balls, rows = vision_frame_from_msg(msg)
    return t_s, rows


def vision_frame_from_msg(msg: PointCloud2 | bytes) -> tuple[float, np.ndarray, np.ndarray]:
    """(stamp [s], balls, robots) of /vision/robots: balls an (k, 2) array of (x, y), robots an (n, 5) array of
    (team, robot_id, x, y, yaw), yaw in [-pi, pi]. ``msg`` may be serialized (as point_from_msg). A cloud with
    other fields, a point with a non-finite or huge value, an unknown team or a fractional id is refused as a
    whole (ConversionError)."""
    if isinstance(msg, bytes | bytearray | memoryview):
        data = bytes(msg)
        t_s, layout, at = _cloud_from_cdr(data)
        _check_robot_cloud(*layout)
        values = np.frombuffer(data, "<f8", layout[1] * len(VISION_ROBOT_FIELDS), at)
    else:
        _check_frame(msg.header.frame_id)
        t_s = stamp_to_seconds(msg.header.stamp)
        _check_robot_cloud(msg.height, msg.width, [(f.name, f.offset, f.datatype, f.count) for f in msg.fields],
                           msg.is_bigendian, msg.point_step, msg.row_step, len(msg.data))
        values = np.frombuffer(bytes(msg.data), "<f8")
    rows = _robot_rows(values.reshape(-1, len(VISION_ROBOT_FIELDS)))
    is_ball = rows[:, 0] == VISION_BALL_CODE
    if not is_ball.any():
        return t_s, _NO_BALLS, rows
    return t_s, rows[is_ball][:, 2:4], rows[~is_ball]


def vision_leading_balls(data: bytes) -> tuple[float, list[tuple[float, float]]] | None:
    """(stamp [s], balls) of a serialized /vision/robots from its leading ball points alone (the ball is written
    first), read at their fixed offsets without decoding the robots: a reader that answers the ball first
    decodes the rest afterwards. The cloud's layout must be /vision/robots' and each ball point must pass
    ``vision_frame_from_msg``'s checks; otherwise None (decode the whole frame: it names the fault). The robot
    points are not checked here."""
    try:
        t_s, layout, at = _cloud_from_cdr(data)
        _check_robot_cloud(*layout)
    except ConversionError:
        return None
    balls = []
    for k in range(layout[1]):
        x, y, z, yaw, team, robot_id = _ROBOT_POINT.unpack_from(data, at + k * _ROBOT_POINT.size)
        if team != VISION_BALL_CODE:
            break
        if not _point_is_valid(x, y, z, yaw, team, robot_id):
            return None
        balls.append((x, y))
    return t_s, balls


def vision_ball_after_robot(data: bytes) -> bool:
    """Whether a serialized /vision/robots has a ball point after a robot point (another writer's order), read
    from the points' team fields alone; False when the cloud is not /vision/robots' layout (decoding it names
    the fault)."""
    try:
        _t_s, layout, at = _cloud_from_cdr(data)
        _check_robot_cloud(*layout)
    except ConversionError:
        return False
    step, team_at = _ROBOT_POINT.size, 8 * VISION_ROBOT_FIELDS.index("team")
    robot_seen = False
    for k in range(layout[1]):
        is_ball = _f64.unpack_from(data, at + k * step + team_at)[0] == VISION_BALL_CODE
        if is_ball and robot_seen:
            return True
        robot_seen = robot_seen or not is_ball
    return False


_ROBOT_FIELDS = [(name, 8 * k, PointField.FLOAT64, 1) for k, name in enumerate(VISION_ROBOT_FIELDS)]


def _check_robot_cloud(height: int, width: int, fields: list | None, is_bigendian: bool, point_step: int,
                       row_step: int, size: int) -> None:
    """A cloud's layout must be /vision/robots' (fields None: known to be)."""
    if fields is not None and fields != _ROBOT_FIELDS:
        raise ConversionError(f"point fields {','.join(f[0] for f in fields)[:80]} are not "
                              f"{','.join(VISION_ROBOT_FIELDS)} (float64 each)")
    step = _ROBOT_POINT.size
    if is_bigendian or point_step != step or width > _MAX_CLOUD_POINTS or (width and height != 1) \
            or row_step != width * step or size != width * step:
        raise ConversionError(f"a robot cloud of {height} x {width} points, {point_step}-byte points, {size} bytes "
                              f"of data{', big endian' if is_bigendian else ''}: expected one little-endian row of "
                              f"{step}-byte points")


def _cloud_from_cdr(data: bytes, known_fields_cdr: bytes = _ROBOT_FIELDS_CDR) -> tuple[float, tuple, int]:
    """(stamp [s], (height, width, fields or None, is_bigendian, point_step, row_step, data size), file offset
    of the data) of a serialized PointCloud2. Fields are None when they are the expected ones as
    ``_float64_fields_cdr`` writes them (recognised by their bytes, ``known_fields_cdr``); another writer's
    padding, or other fields, are read one by one."""
    try:
        sec, nanosec, p = _header_cdr(data, "PointCloud2")
        p += -p % 4
        height, width = struct.unpack_from("<II", data, 4 + p)
        p += 8
        if data.startswith(known_fields_cdr, 4 + p):
            fields, is_bigendian, p = None, False, p + len(known_fields_cdr) - 4
        else:
            fields, p = _point_fields_cdr(data, p)
            is_bigendian = data[4 + p] != 0
            p += 1
            p += -p % 4
        point_step, row_step, size = struct.unpack_from("<III", data, 4 + p)
        p += 12
    except (struct.error, IndexError) as exc:
        raise ConversionError(f"truncated PointCloud2 ({exc})") from None
    if 4 + p + size + 1 > len(data):  # the data, then is_dense
        raise ConversionError(f"truncated PointCloud2 ({size} bytes of data in {len(data)})")
    return sec + nanosec * 1e-9, (height, width, fields, is_bigendian, point_step, row_step, size), 4 + p


def _point_fields_cdr(data: bytes, p: int) -> tuple[list[tuple[str, int, int, int]], int]:
    """The PointField sequence at payload offset ``p`` and the offset after it (struct.error when cut short)."""
    (count,) = _u32.unpack_from(data, 4 + p)
    if count > 64:
        raise ConversionError(f"{count} point fields")
    p += 4
    fields = []
    for _ in range(count):
        p += -p % 4
        (length,) = _u32.unpack_from(data, 4 + p)
        if length < 1 or 8 + p + length > len(data):
            raise ConversionError("a point field name runs past the message")
        name = data[8 + p : 7 + p + length].decode("utf-8", "replace")
        p += 4 + length
        p += -p % 4
        offset, datatype = struct.unpack_from("<IB", data, 4 + p)
        p += 5
        p += -p % 4
        fields.append((name, offset, datatype, _u32.unpack_from(data, 4 + p)[0]))
        p += 4
    return fields, p


#: per field of a point: the largest magnitude ``_point_is_valid`` accepts (the team and the id are checked further
#: below: integers, not negative, so the team is one of _POINT_CODES)
_ROBOT_POINT_LIMITS = np.array([MAX_ABS_VALUE, MAX_ABS_VALUE, MAX_ABS_VALUE, _MAX_ABS_YAW, max(_POINT_CODES),
                                _MAX_CLOUD_POINTS])


def _robot_rows(values: np.ndarray) -> np.ndarray:
    """(team, robot_id, x, y, yaw) of the cloud's points (x, y, z, yaw, team, robot_id), checked."""
    codes = values[:, 4:]
    # a few whole-array tests (each false for NaN): ranges, then integer team and id, team and id >= 0
    if not ((np.abs(values) <= _ROBOT_POINT_LIMITS).all() and (codes == np.floor(codes)).all()
            and (codes >= (VISION_BALL_CODE, 0.0)).all()):
        for k, point in enumerate(values.tolist()):
            if not _point_is_valid(*point):
                _point_error(k, *point)
    rows = values[:, (4, 5, 0, 1, 3)]
    yaw = rows[:, 4]
    yaw -= _TWO_PI * np.round(yaw / _TWO_PI)
    return rows


# ------------------------------------------------------------ ball track
# /ball/track: a PointCloud2 of one point, the float64 fields BALL_TRACK_FIELDS at offsets 0, 8, .., little endian,
# built and recognised as /vision/robots is.
_TRACK_FIELDS_CDR = _float64_fields_cdr(BALL_TRACK_FIELDS)
_TRACK_FIELDS = [(name, 8 * k, PointField.FLOAT64, 1) for k, name in enumerate(BALL_TRACK_FIELDS)]
_TRACK_POINT_SIZE = 8 * len(BALL_TRACK_FIELDS)
_PHASE_INDEX = {phase: float(k) for k, phase in enumerate(BALL_PHASES)}


class BallTrack(NamedTuple):
    """One /ball/track message: the filtered ball, v_shoot, the observation, phase and uncertain flag."""

    t_s: float
    x_m: float
    y_m: float
    vx_mps: float
    vy_mps: float
    v_shoot_mps: float
    seen_x_m: float
    seen_y_m: float
    phase: str  # one of BALL_PHASES
    uncertain: bool
    z_m: float = 0.0  # height of a chipped ball in the air (as /ball/state)


def ball_track_cdr(track: BallTrack, frame_id: str = FIELD_FRAME) -> bytes:
    """A /ball/track PointCloud2 serialized, checked as the reader checks it (finite, within MAX_ABS_VALUE,
    a phase of BALL_PHASES)."""
    phase = _PHASE_INDEX.get(track.phase)
    if phase is None:
        raise ConversionError(f"phase {track.phase!r} is none of {', '.join(BALL_PHASES)}")
    values = [_finite(name, value) for name, value in zip(BALL_TRACK_FIELDS[3:8], track[3:8], strict=True)]
    return b"".join((_stamp_head(track.t_s), _frame_cdr(frame_id), struct.pack("<II", 1, 1), _TRACK_FIELDS_CDR,
                     struct.pack("<II10d", _TRACK_POINT_SIZE, _TRACK_POINT_SIZE, _finite("x", track.x_m),
                                 _finite("y", track.y_m), _finite("z", track.z_m), *values, phase,
                                 1.0 if track.uncertain else 0.0),
                     b"\x01"))


def ball_track_from_msg(msg: PointCloud2 | bytes) -> BallTrack:
    """The BallTrack of a /ball/track message (or its bytes, as point_from_msg); a cloud of other fields or
    another size, a non-finite or huge value, an unknown phase or an uncertain flag other than 0/1 is refused
    (ConversionError)."""
    if isinstance(msg, bytes | bytearray | memoryview):
        data = bytes(msg)
        t_s, (height, width, fields, is_bigendian, point_step, row_step, size), at = \
            _cloud_from_cdr(data, _TRACK_FIELDS_CDR)
    else:
        _check_frame(msg.header.frame_id)
        t_s = stamp_to_seconds(msg.header.stamp)
        height, width, is_bigendian, point_step, row_step = (msg.height, msg.width, msg.is_bigendian, msg.point_step,
                                                            msg.row_step)
        fields = [(f.name, f.offset, f.datatype, f.count) for f in msg.fields]
        data, at, size = bytes(msg.data), 0, len(msg.data)
    if fields is not None and fields != _TRACK_FIELDS:
        raise ConversionError(f"point fields {','.join(f[0] for f in fields)[:80]} are not "
                              f"{','.join(BALL_TRACK_FIELDS)} (float64 each)")
    if (height, width, is_bigendian, point_step, row_step, size) != (1, 1, False, _TRACK_POINT_SIZE,
                                                                     _TRACK_POINT_SIZE, _TRACK_POINT_SIZE):
        raise ConversionError(f"a ball track of {height} x {width} points, {point_step}-byte points, {size} bytes "
                              f"of data: expected one little-endian {_TRACK_POINT_SIZE}-byte point")
    x, y, z, vx, vy, v_shoot, seen_x, seen_y, phase, uncertain = struct.unpack_from("<10d", data, at)
    if not all(abs(v) <= MAX_ABS_VALUE for v in (x, y, z, vx, vy, v_shoot, seen_x, seen_y)):  # False for NaN
        for name, value in zip(BALL_TRACK_FIELDS, (x, y, z, vx, vy, v_shoot, seen_x, seen_y), strict=False):
            _finite(name, value)
    if phase not in _PHASE_INDEX.values() or uncertain not in (0.0, 1.0):
        raise ConversionError(f"phase {phase!r} (an index of BALL_PHASES) or uncertain {uncertain!r} (1/0) "
                              "out of range")
    return BallTrack(t_s, x, y, vx, vy, v_shoot, seen_x, seen_y, BALL_PHASES[int(phase)], uncertain == 1.0, z)


# ------------------------------------------------------------ scalar & tables


def float64_cdr(value: float, limit: float = MAX_ABS_VALUE) -> bytes:
    """A Float64 serialized, checked as ``tools.messages.float64_msg`` checks it."""
    return _CDR_LE + _f64.pack(_finite("data", value, limit))


def float64_from_msg(msg: Float64 | bytes, limit: float = MAX_ABS_VALUE) -> float:
    """The value of a Float64 (or its bytes, as point_from_msg)."""
    if isinstance(msg, bytes):
        if len(msg) < 12 or msg[:2] != _CDR_LE[:2]:
            raise ConversionError("not a little-endian CDR Float64")
        return _finite("data", _f64.unpack_from(msg, 4)[0], limit)
    return _finite("data", msg.data, limit)


TABLE_LIMIT = 1.0e9  # the magnitude a table's values may have (one with stamps: TRACKED_TABLE_LIMIT)
TRACKED_TABLE_LIMIT = float(2**31 - 1)  # /robots/tracked: a stamp's seconds, as builtin_interfaces/Time's int32


def table_msg(rows: np.ndarray, column_labels: Sequence[str], row_label: str = "rows",
              limit: float = TABLE_LIMIT) -> Float64MultiArray:
    """A 2-D table (rows x labelled columns) as a Float64MultiArray with a self-describing layout.

    The column dimension's label lists the column names separated by commas, so
    ``erforce-topic echo`` output can be read without this module.
    """
    table = np.atleast_2d(np.asarray(rows, dtype=float))
    if table.shape[1] != len(column_labels):
        raise ConversionError(f"table has {table.shape[1]} columns, expected {len(column_labels)}")
    _finite_array("table", table.ravel(), None, limit)
    msg = Float64MultiArray()
    n_rows, n_cols = table.shape
    msg.layout.dim = [
        MultiArrayDimension(label=row_label, size=n_rows, stride=n_rows * n_cols),
        MultiArrayDimension(label=",".join(column_labels), size=n_cols, stride=n_cols),
    ]
    msg.data = table.ravel().tolist()
    return msg


def table_cdr(rows: Sequence[Sequence[float]], column_labels: Sequence[str], row_label: str = "rows",
              limit: float = TABLE_LIMIT) -> bytes:
    """``table_msg`` serialized, with the same checks (rows: a list of equal-length rows)."""
    columns = tuple(column_labels)
    if any(len(row) != len(columns) for row in rows):
        raise ConversionError(f"table rows must have {len(columns)} columns")
    flat = _checked_floats("table", [v for row in rows for v in row], len(rows) * len(columns), limit)
    return _CDR_LE + _table_layout_cdr(row_label, len(rows), columns) + struct.pack(f"<{len(flat)}d", *flat)


@functools.lru_cache(maxsize=64)
def _table_layout_cdr(row_label: str, n_rows: int, columns: tuple[str, ...]) -> bytes:
    """Float64MultiArray up to its doubles: the two dimensions, data_offset 0 and the data count."""
    n_cols = len(columns)
    out = bytearray(_u32.pack(2))
    for label, size, stride in ((row_label, n_rows, n_rows * n_cols), (",".join(columns), n_cols, n_cols)):
        raw = label.encode() + b"\x00"
        out += bytes(-len(out) % 4) + _u32.pack(len(raw)) + raw
        out += bytes(-len(out) % 4) + _u32.pack(size) + _u32.pack(stride)
    out += bytes(-len(out) % 4) + _u32.pack(0) + _u32.pack(n_rows * n_cols)
    return bytes(out + (bytes(-len(out) % 8) if n_rows * n_cols else b""))


def _multi_array_parts(msg: Float64MultiArray | bytes) -> tuple[list[tuple[str, int]], int, Sequence[float]]:
    """(label, size) of each dimension, data_offset and the data of a Float64MultiArray or of its CDR bytes
    (read in place: rclpy's deserialization of a 200-value table cost as much as the rest of its use)."""
    if not isinstance(msg, bytes):
        return [(d.label, d.size) for d in msg.layout.dim], msg.layout.data_offset, msg.data
    try:
        if msg[:2] != _CDR_LE[:2]:
            raise ConversionError("not a little-endian CDR Float64MultiArray")
        body = memoryview(msg)[4:]  # CDR aligns relative to the end of the encapsulation header
        (n_dims,), at = _u32.unpack_from(body, 0), 4
        if n_dims > 8:
            raise ConversionError(f"a table with {n_dims} dimensions")
        dims = []
        for _ in range(n_dims):
            (length,) = _u32.unpack_from(body, at)
            label = bytes(body[at + 4:at + 4 + length]).rstrip(b"\x00").decode()
            at += 4 + length
            at += -at % 4
            size, _stride = struct.unpack_from("<II", body, at)
            dims.append((label, size))
            at += 8
        data_offset, count = struct.unpack_from("<II", body, at)
        at += 8
        at += -at % 8 if count else 0
        if not 0 <= len(body) - (at + 8 * count) < 8:  # serializers may pad the end
            raise ConversionError(f"a table of {count} values in {len(body) - at} bytes")
        return dims, data_offset, np.frombuffer(body, dtype="<f8", count=count, offset=at)
    except (struct.error, UnicodeDecodeError, ValueError) as exc:
        if isinstance(exc, ConversionError):
            raise
        raise ConversionError(f"malformed Float64MultiArray: {exc}") from None


def table_from_msg(msg: Float64MultiArray | bytes, column_labels: Sequence[str],
                   num_rows: int | None = None, limit: float = TABLE_LIMIT) -> np.ndarray:
    """The rows x columns table of a ``table_msg`` (or its CDR bytes); its shape is checked against the
    labels (and ``num_rows`` when given), not taken from the message."""
    dims, data_offset, values = _multi_array_parts(msg)
    if len(dims) != 2 or dims[1][0] != ",".join(column_labels):
        raise ConversionError(f"expected a table with columns {','.join(column_labels)}")
    n_rows, n_cols = dims[0][1], dims[1][1]
    if n_cols != len(column_labels):
        raise ConversionError(f"table has {n_cols} columns, its labels name {len(column_labels)}")
    if num_rows is not None and n_rows != num_rows:
        raise ConversionError(f"table has {n_rows} rows, expected {num_rows}")
    if data_offset != 0:
        raise ConversionError(f"table data_offset is {data_offset}, expected 0")
    data = _finite_array("data", values, n_rows * n_cols, limit)
    return data.reshape(n_rows, n_cols)


def field_from_msg(msg: Float64MultiArray | bytes) -> FieldConfig:
    """The field of ``/vision/field`` (one row of VISION_FIELD_COLUMNS); ValueError (or ConversionError) when it
    is no field."""
    length_m, width_m, boundary_m, *_ = table_from_msg(msg, VISION_FIELD_COLUMNS, num_rows=1)[0].tolist()
    return FieldConfig(length_m, width_m, boundary_m)


def model_in_use_from_msg(msg: Float64MultiArray | bytes) -> tuple[float, float, float]:
    """(a_slide_mps2, a_roll_mps2, c_switch) of the model in use on ``/ball/model_params``: a table whose
    rows are the first one or all of ``BALL_MODEL_PARAM_ROWS`` (in_use, then a fit once there is one)."""
    table = table_from_msg(msg, BALL_MODEL_PARAM_LABELS)
    rows = _multi_array_parts(msg)[0][0][0].split(",")
    if len(rows) != len(table) or rows != list(BALL_MODEL_PARAM_ROWS[:len(rows)]):
        raise ConversionError(f"rows labelled {rows}, expected the first of {','.join(BALL_MODEL_PARAM_ROWS)}")
    a_slide, a_roll, c_switch = table[0].tolist()
    return a_slide, a_roll, c_switch


# ------------------------------------------------------------ /ball/catches
_CATCH_TIME_COLUMN = CATCH_TABLE_COLUMNS.index("catch_time_s")
_CATCH_X_COLUMN = CATCH_TABLE_COLUMNS.index("catch_x_m")
_MAX_ROBOT_ID = 1.0e6


class Catch(NamedTuple):
    """One robot's row of /ball/catches as its per-robot ``catch_time`` and ``catch_point`` carry it."""

    robot_id: int
    catch_time_s: float  # CATCH_TIME_NEVER: never
    point_m: tuple[float, float] | None  # None with a catch time of never: no catch_point goes out then


def check_catch_ids(team_and_id: np.ndarray, table: str = "/ball/catches") -> None:
    """The team and robot_id columns of a /ball/catches table (or another ``table`` with those columns; finite): a
    Team's code and a whole id >= 0 in each row (ConversionError otherwise)."""
    teams, ids = team_and_id[:, 0], team_and_id[:, 1]
    if not ((ids >= 0.0) & (ids <= _MAX_ROBOT_ID) & (ids == np.floor(ids))).all():
        raise ConversionError(f"robot ids of {table} must be whole numbers >= 0")
    if not ((teams == OURS.code) | (teams == OPPONENTS.code)).all():
        raise ConversionError(f"the team column of {table} must be a contract.Team code")


def _catches_plain(rows: list, code: float) -> list[Catch] | None:
    """catches_from_msg's answer for a table's rows (lists of floats, finite) when they pass every one of its
    checks, in one pass of plain Python (numpy's calls cost more than the work on 14 rows); None when a check
    fails, for the checks one by one, which name what failed."""
    teams, limit, never = (OURS.code, OPPONENTS.code), MAX_ABS_VALUE, CATCH_TIME_NEVER
    t_col, x_col = _CATCH_TIME_COLUMN, _CATCH_X_COLUMN
    out = []
    for row in rows:
        team, robot_id = row[0], row[1]
        if not (team in teams and 0.0 <= robot_id <= _MAX_ROBOT_ID and robot_id == int(robot_id)):
            return None
        if team == code:
            t = row[t_col]
            if not -limit <= t <= limit:
                return None
            point = None
            if t != never:
                point = (row[x_col], row[x_col + 1])
                if not (-limit <= point[0] <= limit and -limit <= point[1] <= limit):
                    return None
            out.append(Catch(int(robot_id), t, point))
    return out


def catches_from_msg(msg: Float64MultiArray | bytes, team: Team) -> list[Catch]:
    """The catches of ``team``'s robots in a /ball/catches table (or its CDR bytes), in the table's order, with
    the checks of ``float64_from_msg`` and ``point_from_msg`` on each value. A table that is not one
    (columns, shape, a non-finite value, a team or robot id that is none) raises ConversionError."""
    table = table_from_msg(msg, CATCH_TABLE_COLUMNS)
    if not len(table):
        return []
    plain = _catches_plain(table.tolist(), team.code)
    if plain is not None:
        return plain
    check_catch_ids(table[:, :2])
    out = []
    t_col, x_col = _CATCH_TIME_COLUMN, _CATCH_X_COLUMN
    for row in table[table[:, 0] == team.code].tolist():
        t = _finite("catch_time_s", row[t_col])
        point = None if t == CATCH_TIME_NEVER else (_finite("catch_x_m", row[x_col]),
                                                    _finite("catch_y_m", row[x_col + 1]))
        out.append(Catch(int(row[1]), t, point))
    return out


# ------------------------------------------------------------ /robots/tracked
class TrackedRobot(NamedTuple):
    """One row of /robots/tracked: what the robot's odom carries (odometry_from_msg's stamp, pose, velocity)."""

    team: float  # Team.code
    robot_id: int
    stamp_s: float
    pose: tuple[float, float, float]  # x [m], y [m], yaw [rad] in ``field``
    velocity: tuple[float, float, float]  # vx, vy [m/s] in ``field``, yaw rate [rad/s]


def tracked_robot_row(team: Team, robot_id: int, t_s: float, pose, velocity) -> tuple[float, ...]:
    """The row of TRACKED_ROBOT_COLUMNS for one robot, with odometry_cdr's checks (ConversionError)."""
    sec, nanosec = _stamp_parts(_seconds_to_ns(t_s))
    x, y, yaw = (_finite("pose.position.x", pose[0]), _finite("pose.position.y", pose[1]),
                 _finite("yaw", pose[2], MAX_ABS_ANGULAR))
    vx, vy, wz = (_finite("twist.linear.x", velocity[0]), _finite("twist.linear.y", velocity[1]),
                  _finite("twist.angular.z", velocity[2]))
    return (team.code, float(robot_id), float(sec), float(nanosec), x, y, yaw, vx, vy, wz)


def tracked_robots_cdr(rows: Sequence[Sequence[float]]) -> bytes:
    """/robots/tracked serialized from rows of ``tracked_robot_row``."""
    return table_cdr(rows, TRACKED_ROBOT_COLUMNS, limit=TRACKED_TABLE_LIMIT)


def tracked_robots_from_msg(msg: Float64MultiArray | bytes) -> list[TrackedRobot]:
    """The rows of a /robots/tracked table (or its CDR bytes), in the table's order, the stamp as
    stamp_to_seconds gives it. A table that is not one (columns, shape, a non-finite value, a team or robot id
    that is none, a stamp that is no time, a value past odometry_from_msg's limits) raises ConversionError."""
    table = table_from_msg(msg, TRACKED_ROBOT_COLUMNS, limit=TRACKED_TABLE_LIMIT)
    if not len(table):
        return []
    rows = _tracked_plain(table.tolist())
    if rows is None:
        _check_tracked(table)
        rows = [TrackedRobot(team, int(robot_id), int(sec) + int(nanosec) * 1e-9, (x, y, yaw), (vx, vy, wz))
                for team, robot_id, sec, nanosec, x, y, yaw, vx, vy, wz in table.tolist()]
    return rows


def _tracked_plain(rows: list) -> list[TrackedRobot] | None:
    """tracked_robots_from_msg's answer for a table's rows (lists of floats, finite) when they pass every check
    of ``_check_tracked``, in one pass of plain Python (numpy's calls cost more than the work on 14 rows); None
    when a check fails, for those checks, which name what failed."""
    teams, m, big = (OURS.code, OPPONENTS.code), MAX_ABS_VALUE, MAX_ABS_ANGULAR
    out = []
    for team, robot_id, sec, nanosec, x, y, yaw, vx, vy, wz in rows:
        if not (team in teams and 0.0 <= robot_id <= _MAX_ROBOT_ID and robot_id == int(robot_id)
                and sec >= 0.0 and sec == int(sec) and 0.0 <= nanosec < 1.0e9 and nanosec == int(nanosec)
                and -m <= x <= m and -m <= y <= m and -m <= vx <= m and -m <= vy <= m
                and -big <= yaw <= big and -big <= wz <= big):
            return None
        out.append(TrackedRobot(team, int(robot_id), int(sec) + int(nanosec) * 1e-9, (x, y, yaw), (vx, vy, wz)))
    return out


def _check_tracked(table: np.ndarray) -> None:
    """The checks of tracked_robots_from_msg one by one (ConversionError naming the first that fails)."""
    check_catch_ids(table[:, :2], "/robots/tracked")
    sec, nanosec = table[:, 2], table[:, 3]
    if not ((sec >= 0.0) & (sec == np.floor(sec)) & (nanosec >= 0.0) & (nanosec < 1.0e9)
            & (nanosec == np.floor(nanosec))).all():
        raise ConversionError("a stamp of /robots/tracked is not a valid time")
    if (np.abs(table[:, [4, 5, 7, 8]]) > MAX_ABS_VALUE).any() or (np.abs(table[:, [6, 9]]) > MAX_ABS_ANGULAR).any():
        raise ConversionError(f"a pose or velocity of /robots/tracked exceeds the accepted magnitude "
                              f"({MAX_ABS_VALUE:g}; {MAX_ABS_ANGULAR:.0e} for yaw and yaw rate)")
