"""The point-cloud topics: /vision/robots (robots and balls as one sensor_msgs/PointCloud2) and /ball/track
(the tracked ball), built and read as serialized CDR since both ride the vision path every frame.

Errors, limits and the stamp/frame checks are those of ``conversions``.
"""

from __future__ import annotations

import functools
import math
import struct
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
from sensor_msgs.msg import PointCloud2, PointField

from erforce_interfaces.wire.contract import (
    BALL_PHASES,
    BALL_TRACK_FIELDS,
    FIELD_FRAME,
    OPPONENTS,
    OURS,
    VISION_BALL_CODE,
    VISION_CAMERA_CODE,
    VISION_ROBOT_FIELDS,
    VISION_SIGHTING_CODE,
)
from erforce_interfaces.wire.conversions import (
    _CDR_LE,
    MAX_ABS_VALUE,
    ConversionError,
    _check_frame,
    _f64,
    _finite,
    _header_cdr,
    _sec_nanosec,
    _stamp,
    _u32,
    stamp_to_seconds,
)

# ------------------------------------------------------------ vision robots
# /vision/robots: a sensor_msgs/PointCloud2 with one point per robot and one per ball (team VISION_BALL_CODE, yaw
# and robot_id 0), the float64 fields VISION_ROBOT_FIELDS (x, y, z, yaw, team, robot_id) at offsets 0, 8, ..,
# little endian, height 1; the leading points (the camera's, VISION_CAMERA_CODE; the balls; the sightings,
# VISION_SIGHTING_CODE) before the robots. Its layout is constant but for the stamp, the width and the data: the
# bytes from the fields to point_step are built once and, on the way in, recognised. Rows in and out are (team,
# robot_id, x, y, yaw): Team.code, the id within the team, the pose in ``field`` [m, rad]; yaw goes out and comes
# in wrapped to [-pi, pi]. Balls and sightings in and out are (x, y) in ``field`` [m]; a camera (camera_id, x, y,
# z) in ``field`` [m], z > 0.
_ROBOT_POINT = struct.Struct(f"<{len(VISION_ROBOT_FIELDS)}d")
_MAX_CLOUD_POINTS = 1024  # a width beyond this is garbage, not a field of robots
_TEAM_CODES = (OURS.code, OPPONENTS.code)
_POINT_CODES = (VISION_BALL_CODE, *_TEAM_CODES, VISION_CAMERA_CODE, VISION_SIGHTING_CODE)
_LEADING_CODES = (VISION_BALL_CODE, VISION_CAMERA_CODE, VISION_SIGHTING_CODE)  # the points before the robots
_NO_BALLS = np.empty((0, 2))
_NO_BALLS.flags.writeable = False
_TWO_PI = 2.0 * math.pi
_MAX_ABS_YAW = 1.0e6  # [rad] yaw is wrapped on the way out and in; beyond this a float keeps no fraction of a turn


def _point_is_valid(x: float, y: float, z: float, yaw: float, team: float, robot_id: float,
                    codes: tuple[float, ...] = _POINT_CODES) -> bool:
    """Whether a /vision/robots point (x, y, z, yaw, team, robot_id) passes the reader's checks (False for NaN):
    x, y, z within MAX_ABS_VALUE (a camera above the field: z > 0), yaw within _MAX_ABS_YAW, a team of ``codes``, an
    integer id in 0.._MAX_CLOUD_POINTS. The one statement of the point check: the writer, the leading-ball reader and
    ``_robot_rows`` ask it per point (``_robot_rows`` first tests the whole array against ``_ROBOT_POINT_LIMITS``,
    the same limits in array form), and ``_point_error`` names what failed."""
    return (abs(x) <= MAX_ABS_VALUE and abs(y) <= MAX_ABS_VALUE and abs(z) <= MAX_ABS_VALUE
            and abs(yaw) <= _MAX_ABS_YAW and team in codes and 0.0 <= robot_id <= _MAX_CLOUD_POINTS
            and robot_id == int(robot_id) and (team != VISION_CAMERA_CODE or z > 0.0))


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
                      balls: Sequence[Sequence[float]] = (), camera: Sequence[float] | None = None,
                      sightings: Sequence[Sequence[float]] = ()) -> bytes:
    """A /vision/robots PointCloud2 serialized: the ``camera`` (camera_id, x, y, z) first where given, the ``balls``
    (x, y), the ``sightings`` (x, y; only with a camera), then ``rows`` of (team, robot_id, x, y, yaw), checked as
    the reader checks them (finite, positions within MAX_ABS_VALUE, a team code, an integer id, a camera above the
    field)."""
    if sightings and camera is None:
        raise ConversionError("sightings without the camera that saw them")
    leading = [] if camera is None else [(camera[1], camera[2], camera[3], 0.0, VISION_CAMERA_CODE, camera[0])]
    leading += [(x, y, 0.0, 0.0, VISION_BALL_CODE, 0.0) for x, y in balls]
    leading += [(x, y, 0.0, 0.0, VISION_SIGHTING_CODE, 0.0) for x, y in sightings]
    flat = []
    for point in leading:
        if not _point_is_valid(*point):
            _point_error(0, *point)
        flat += point
    for k, (team, robot_id, x, y, yaw) in enumerate(rows):
        if not _point_is_valid(x, y, 0.0, yaw, team, robot_id, _TEAM_CODES):
            _point_error(k, x, y, 0.0, yaw, team, robot_id, _TEAM_CODES)
        flat += (x, y, 0.0, math.remainder(yaw, _TWO_PI), team, robot_id)
    return _vision_robots_bytes(t_s, len(leading) + len(rows), struct.pack(f"<{len(flat)}d", *flat), frame_id)


def vision_robots_points_cdr(t_s: float, points: np.ndarray, frame_id: str = FIELD_FRAME) -> bytes:
    """``vision_robots_cdr`` for points the caller has already written and checked as it checks rows: a
    float64 array (n, 6) in VISION_ROBOT_FIELDS order, yaw in [-pi, pi], the camera, ball and sightings first (a
    producer's compiled path)."""
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
    point = _LEADING_NAMES.get(team, f"robot {k}")
    for name, value, limit in (("z", z, MAX_ABS_VALUE), ("x", x, MAX_ABS_VALUE), ("y", y, MAX_ABS_VALUE),
                               ("yaw", yaw, _MAX_ABS_YAW)):
        _finite(f"{point}: {name}", value, limit)
    if team == VISION_CAMERA_CODE and team in codes and not z > 0.0:
        raise ConversionError(f"camera: z {z!r} m: a camera is above the field")
    if team not in codes:
        raise ConversionError(f"robot {k}: team {team!r} is none of {codes}")
    raise ConversionError(f"robot {k}: robot_id {robot_id!r} is no id (an integer in 0..{_MAX_CLOUD_POINTS})")


_LEADING_NAMES = {VISION_BALL_CODE: "ball", VISION_CAMERA_CODE: "camera", VISION_SIGHTING_CODE: "sighting"}


class VisionCloud(NamedTuple):
    """One /vision/robots frame: its stamp [s], balls (k, 2) and robots (n, 5) as ``vision_frame_from_msg`` has
    them, the camera that took it (``camera_id``, ``camera_m`` = its position x, y, z [m]; None: not named, its
    ball is a ground sighting) and that camera's sightings (j, 2) of instants the ball has from another camera."""

    t_s: float
    balls: np.ndarray
    robots: np.ndarray
    camera_id: int | None
    camera_m: tuple[float, float, float] | None
    sightings: np.ndarray


def vision_robots_from_msg(msg: PointCloud2 | bytes) -> tuple[float, np.ndarray]:
    """(stamp [s], rows) of /vision/robots' robots: ``vision_frame_from_msg`` without the balls."""
    t_s, _balls, rows = vision_frame_from_msg(msg)
    return t_s, rows


def vision_frame_from_msg(msg: PointCloud2 | bytes) -> tuple[float, np.ndarray, np.ndarray]:
    """(stamp [s], balls, robots) of /vision/robots: balls an (k, 2) array of (x, y), robots an (n, 5) array of
    (team, robot_id, x, y, yaw), yaw in [-pi, pi] (``vision_cloud_from_msg`` without the camera)."""
    cloud = vision_cloud_from_msg(msg)
    return cloud.t_s, cloud.balls, cloud.robots


def vision_cloud_from_msg(msg: PointCloud2 | bytes) -> VisionCloud:
    """The VisionCloud of a /vision/robots message. ``msg`` may be serialized (as point_from_msg). A cloud with
    other fields, a point with a non-finite or huge value, an unknown team, a fractional id, a camera not above the
    field, two cameras or sightings without one is refused as a whole (ConversionError)."""
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
    values = values.reshape(-1, len(VISION_ROBOT_FIELDS))
    rows = _robot_rows(values)
    is_robot = rows[:, 0] >= _TEAM_CODES[0]
    is_robot &= rows[:, 0] <= _TEAM_CODES[1]
    if is_robot.all():  # robots alone: no camera, no ball
        return VisionCloud(t_s, _NO_BALLS, rows, None, None, _NO_BALLS)
    codes = rows[:, 0]
    cameras = values[codes == VISION_CAMERA_CODE]
    if len(cameras) > 1:
        raise ConversionError(f"{len(cameras)} camera points: a frame is one camera's")
    sightings = rows[codes == VISION_SIGHTING_CODE][:, 2:4]
    if len(sightings) and not len(cameras):
        raise ConversionError("sightings without the camera that saw them")
    camera_id, camera_m = (None, None) if not len(cameras) else (int(cameras[0, 5]), tuple(cameras[0, :3].tolist()))
    return VisionCloud(t_s, rows[codes == VISION_BALL_CODE][:, 2:4], rows[is_robot], camera_id, camera_m,
                       sightings if len(sightings) else _NO_BALLS)


class LeadingPoints(NamedTuple):
    """A frame's points before its robots: stamp [s], balls [(x, y)], the camera's position (x, y, z) [m] or None,
    and its sightings [(x, y)] (see VisionCloud)."""

    t_s: float
    balls: list[tuple[float, float]]
    camera_m: tuple[float, float, float] | None
    sightings: list[tuple[float, float]]


def vision_leading_points(data: bytes) -> LeadingPoints | None:
    """The leading points of a serialized /vision/robots (the camera, the balls and the sightings are written
    before the robots), read at their fixed offsets without decoding the robots: a reader that answers the ball
    first decodes the rest afterwards. The cloud's layout must be /vision/robots' and each leading point must pass
    ``vision_cloud_from_msg``'s checks (one camera at most, sightings only with it); otherwise None (decode the
    whole frame: it names the fault). The robot points are not checked here."""
    try:
        t_s, layout, at = _cloud_from_cdr(data)
        _check_robot_cloud(*layout)
    except ConversionError:
        return None
    balls, sightings, camera = [], [], None
    for k in range(layout[1]):
        x, y, z, _yaw, team, _robot_id = point = _ROBOT_POINT.unpack_from(data, at + k * _ROBOT_POINT.size)
        if team not in _LEADING_CODES:
            break
        if not _point_is_valid(*point):
            return None
        if team == VISION_BALL_CODE:
            balls.append((x, y))
        elif team == VISION_SIGHTING_CODE:
            sightings.append((x, y))
        elif camera is None:
            camera = (x, y, z)
        else:
            return None  # two cameras
    if sightings and camera is None:
        return None
    return LeadingPoints(t_s, balls, camera, sightings)


def vision_ball_after_robot(data: bytes) -> bool:
    """Whether a serialized /vision/robots has a leading point (a ball, camera or sighting) after a robot point
    (another writer's order), read from the points' team fields alone; False when the cloud is not /vision/robots'
    layout (decoding it names the fault)."""
    try:
        _t_s, layout, at = _cloud_from_cdr(data)
        _check_robot_cloud(*layout)
    except ConversionError:
        return False
    step, team_at = _ROBOT_POINT.size, 8 * VISION_ROBOT_FIELDS.index("team")
    robot_seen = False
    for k in range(layout[1]):
        leading = _f64.unpack_from(data, at + k * step + team_at)[0] in _LEADING_CODES
        if leading and robot_seen:
            return True
        robot_seen = robot_seen or not leading
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
#: below: integers, not negative, so the team is one of _POINT_CODES, which are 0..4; a camera's z separately)
_ROBOT_POINT_LIMITS = np.array([MAX_ABS_VALUE, MAX_ABS_VALUE, MAX_ABS_VALUE, _MAX_ABS_YAW, max(_POINT_CODES),
                                _MAX_CLOUD_POINTS])


def _robot_rows(values: np.ndarray) -> np.ndarray:
    """(team, robot_id, x, y, yaw) of the cloud's points (x, y, z, yaw, team, robot_id), checked."""
    codes = values[:, 4:]
    # a few whole-array tests (each false for NaN): ranges, then integer team and id, team and id >= 0
    if not ((np.abs(values) <= _ROBOT_POINT_LIMITS).all() and (codes == np.floor(codes)).all()
            and (codes >= (VISION_BALL_CODE, 0.0)).all()
            and (values[:, 2] > 0.0)[codes[:, 0] == VISION_CAMERA_CODE].all()):
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


