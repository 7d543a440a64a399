"""SSL-Vision datagrams in and out, without ROS: decoding with checks and encoding.

``decode_wrapper`` turns one UDP datagram (an ``SSL_WrapperPacket``) into plain values in the
contract's units (metres, radians, seconds), or raises ``SslDecodeError`` naming what is wrong
with it. Single bad detections (a NaN coordinate, a robot without an id), ball candidates beyond
``max_balls`` and a bad geometry or ball model are dropped and named in ``DecodedPacket.problems``,
each with its class (``DROP_CLASSES``); the rest of the frame is kept. A detection-only datagram is read
and checked (wire format, required fields, ranges) in one compiled pass over its bytes into arrays
(``DetectionArrays``), because building the protobuf runtime's Python objects per robot cost more than
the rest of a datagram's path (docs/decisions/0013); anything else (geometry, a datagram the pass declines)
goes through the runtime, which names what is wrong. ``DecodedPacket.frame`` gives the detections
as named tuples. ``encode_frame`` and
``encode_geometry`` build datagrams (the plant's simulated cameras and the tests use them).

The time of frames (the vision clock, CaptureOrder, the capture timeline) is in ``ssl.vision_time``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
from google.protobuf.message import DecodeError

from erforce_interfaces.runtime.numba_support import numba
from erforce_interfaces.ssl.ssl_proto import ssl_vision_wrapper_pb2 as wrapper_pb2

MM = 1e-3
TEAMS = ("blue", "yellow")
#: Our team's colour unless told otherwise (the SSL bridge's team_color, the plant's SSL output)
OUR_TEAM_COLOR = "blue"
# The league's ports: SSL-Vision on 10006; ER-Force's simulator and grSim send vision on 10020.
SSL_VISION_GROUP = "224.5.23.2"
SSL_VISION_PORT = 10006
SSL_SIMULATOR_VISION_PORT = 10020
#: The interface multicast vision leaves and is joined by unless told otherwise: this host only.
SSL_VISION_INTERFACE = "127.0.0.1"


#: The classes of vision input a receiver drops, each named in its warnings and counted on its own: whole
#: datagrams (SslDecodeError.kind), parts of a datagram (Problem.kind), whole frames (CaptureOrder, the
#: vision clock, floods) and what the bridge cannot publish.
DROP_CLASSES = {
    "empty": "an empty datagram",
    "size": "a datagram larger than a UDP datagram can be",
    "garbage": "not an SSL_WrapperPacket (truncated or garbage)",
    "missing": "a packet without its required fields",
    "content": "a packet with neither detection nor geometry",
    "counts": "a frame with more robots per team than there are ids",
    "camera": "a frame with a camera id beyond the limit",
    "time": "a frame whose t_capture or t_sent is not a time",
    "bad_ball": "a ball candidate with a non-finite or absurd position or confidence",
    "bad_robot_id": "a robot without a valid id",
    "bad_robot_place": "a robot with a non-finite or absurd position or confidence",
    "bad_orientation": "a robot's non-finite or absurd orientation (the robot is kept without it)",
    "too_many_balls": "ball candidates beyond max_balls in one frame (the frame's robots are kept)",
    "geometry": "a geometry packet with absurd field sizes",
    "ball_model": "a geometry packet's ball model that is not one",
    "t_capture_back": "a camera's frame whose t_capture is not after that camera's newest frame (CaptureOrder)",
    "clock_jump": "a camera's frame while its clock seems to have jumped, not yet confirmed (the vision clock's "
                  "offset; a new line of t_capture on the capture timeline: a restart, a step ahead)",
    "no_geometry": "a camera frame before the world's SSL geometry (field: from_geometry; said once at start)",
    "bad_stamp": "a frame whose stamp on the receiver's clock is not a time",
    "superseded": "a camera's frame left for a newer one of the same camera in a flood",
    "no_orientation": "a robot without orientation (not published)",
    "unpublishable": "a frame whose message cannot be built",
}


class SslDecodeError(ValueError):
    """A datagram that is not a usable SSL_WrapperPacket; the message says why, ``kind`` its class in
    DROP_CLASSES (for a warning and a counter per class): empty, size, garbage, missing, content, counts,
    camera, time."""

    def __init__(self, kind: str, message: str) -> None:
        super().__init__(message)
        self.kind = kind


@dataclass(frozen=True)
class DecodeLimits:
    """What a sane packet stays within; anything beyond is an attack, a bug or another protocol."""

    max_datagram_bytes: int = 65_507
    max_camera_id: int = 31
    max_balls: int = 32
    max_robots_per_team: int = 32
    max_robot_id: int = 31
    max_abs_coordinate_m: float = 30.0
    max_time_s: float = 1e10  # seconds since the epoch until about 2286


class BallCandidate(NamedTuple):  # named tuples: cheaper to build than frozen dataclasses, per detection
    x_m: float
    y_m: float
    confidence: float
    z_m: float = 0.0  # height, when the packet has one (simulators' chipped balls); 0 otherwise


class RobotSighting(NamedTuple):
    team: str  # "blue" | "yellow"
    robot_id: int
    x_m: float
    y_m: float
    theta_rad: float | None  # None when the packet has no orientation
    confidence: float


class CameraFrame(NamedTuple):
    camera_id: int
    frame_number: int
    t_capture_s: float  # vision clock
    t_sent_s: float  # vision clock
    balls: tuple[BallCandidate, ...]
    robots: tuple[RobotSighting, ...]


# Columns of DetectionArrays: one row per ball candidate / robot sighting, in the contract's units.
BALL_COLUMNS = ("x_m", "y_m", "confidence", "z_m")
ROBOT_COLUMNS = ("team", "robot_id", "x_m", "y_m", "theta_rad", "confidence")  # team: index in TEAMS; theta NaN: none


class DetectionArrays(NamedTuple):
    """A camera frame as two float arrays (rows: BALL_COLUMNS, ROBOT_COLUMNS; robots blue first, then yellow)."""

    camera_id: int
    frame_number: int
    t_capture_s: float  # vision clock
    t_sent_s: float  # vision clock
    balls: np.ndarray
    robots: np.ndarray

    def frame(self) -> CameraFrame:
        balls = tuple(BallCandidate(*row) for row in self.balls.tolist())
        robots = tuple(
            RobotSighting(TEAMS[int(team)], int(robot_id), x, y, None if math.isnan(theta) else theta, c)
            for team, robot_id, x, y, theta, c in self.robots.tolist()
        )
        return CameraFrame(self.camera_id, self.frame_number, self.t_capture_s, self.t_sent_s, balls, robots)


@dataclass(frozen=True)
class BallModelFromVision:
    """``SSL_BallModelStraightTwoPhase`` in the names of erforce_ball_model.BallModelParams."""

    a_slide_mps2: float
    a_roll_mps2: float
    c_switch: float


@dataclass(frozen=True)
class ChipModelFromVision:
    """``SSL_BallModelChipFixedLoss`` in the names of erforce_ball_model.ChipParams (the fractions of the vertical
    speed and of the horizontal velocity a chipped ball keeps at each bounce)."""

    damping_z: float
    damping_xy_first_hop: float
    damping_xy_other_hops: float


@dataclass(frozen=True)
class CameraPose:
    camera_id: int
    x_m: float
    y_m: float
    z_m: float


@dataclass(frozen=True)
class FieldGeometry:
    length_m: float
    width_m: float
    boundary_m: float
    goal_width_m: float
    goal_depth_m: float
    penalty_area_depth_m: float | None = None
    penalty_area_width_m: float | None = None
    ball_model: BallModelFromVision | None = None
    cameras: tuple[CameraPose, ...] = ()
    chip_model: ChipModelFromVision | None = None


class Problem(NamedTuple):
    """A dropped part of an otherwise good packet: its class (a DROP_CLASSES key), what and how many."""

    kind: str
    text: str
    count: int = 1


@dataclass
class DecodedPacket:
    detection: DetectionArrays | None = None
    geometry: FieldGeometry | None = None
    problems: list[Problem] = field(default_factory=list)  # dropped parts of an otherwise good packet

    @property
    def frame(self) -> CameraFrame | None:
        """The detections as named tuples (built on each call; the bridge reads ``detection``)."""
        return None if self.detection is None else self.detection.frame()


def _coordinate_ok(value: float, limits: DecodeLimits) -> bool:
    return math.isfinite(value) and abs(value) * MM <= limits.max_abs_coordinate_m


def decode_wrapper(data: bytes, limits: DecodeLimits = DecodeLimits()) -> DecodedPacket:
    """One datagram -> its detection frame and/or geometry; raises SslDecodeError when unusable."""
    if not data:
        raise SslDecodeError("empty", "empty datagram")
    if len(data) > limits.max_datagram_bytes:
        raise SslDecodeError("size", f"datagram of {len(data)} bytes exceeds {limits.max_datagram_bytes}")
    out = DecodedPacket()
    detection = _decode_frame(data, limits, out.problems, declined_ok=True)
    if detection is not None:  # the usual datagram: one camera frame, nothing else
        out.detection = detection
        return out
    packet = wrapper_pb2.SSL_WrapperPacket()
    try:
        packet.ParseFromString(data)
    except DecodeError:
        raise SslDecodeError("garbage", f"not an SSL_WrapperPacket ({len(data)} bytes: truncated or garbage)") from None
    if not packet.IsInitialized():
        missing = ", ".join(packet.FindInitializationErrors()[:4])
        raise SslDecodeError("missing", f"SSL_WrapperPacket without required fields ({missing})")
    has_detection, has_geometry = packet.HasField("detection"), packet.HasField("geometry")
    if not (has_detection or has_geometry):
        raise SslDecodeError("content", "SSL_WrapperPacket with neither detection nor geometry")
    if has_detection:
        out.detection = _decode_frame(data, limits, out.problems)
    if has_geometry:
        out.geometry = _decode_geometry(packet.geometry, limits, out.problems)
    return out


def _decode_frame(data: bytes, limits: DecodeLimits, problems: list[Problem],
                  declined_ok: bool = False) -> DetectionArrays | None:
    """The detection frame of a datagram; None (with ``declined_ok``) when the compiled pass declines it:
    a geometry part, no detection, anything the pass does not read as a valid detection-only datagram."""
    max_balls, max_robots = limits.max_balls, limits.max_robots_per_team
    out = np.empty(detection_rows_size(max_balls, max_robots))
    status, n_balls_kept, n_robots_kept, n_rejected, geometry = detection_rows(
        data, out, max_balls, max_robots, limits.max_abs_coordinate_m / MM, limits.max_robot_id,
        limits.max_camera_id, limits.max_time_s)
    if geometry and declined_ok:
        return None
    if status:
        if status == _DECLINED:
            if declined_ok:
                return None
            # the runtime parsed it, so the pass has a bug: say so rather than use a part
            raise SslDecodeError("garbage", "detection frame not readable by the compiled pass")
        _frame_error(status, out, limits)
    at = 8  # the parts of out: see detection_rows
    balls = out[at:at + 4 * n_balls_kept].reshape(n_balls_kept, 4)
    at += 4 * max_balls
    robots = out[at:at + 6 * n_robots_kept].reshape(n_robots_kept, 6)
    camera_id = int(out[3])
    if n_rejected or out[4] != n_balls_kept:  # out[4]: the ball candidates in the bytes
        rejected = out[at + 12 * max_robots:][:7 * n_rejected].reshape(n_rejected, 7)
        named = int(np.count_nonzero(rejected[:, 0] == _REJECT_BALL))
        excess = int(out[4]) - n_balls_kept - named
        if excess > 0:
            problems.append(Problem("too_many_balls", f"camera {camera_id}: {int(out[4])} ball candidates, "
                                                      f"{excess} beyond the first {max_balls} dropped", excess))
        _sort_out(camera_id, robots, rejected, problems)
    return DetectionArrays(camera_id, int(out[0]), float(out[1]), float(out[2]), balls, robots)


_DECLINED, _BAD_CAMERA, _BAD_T_CAPTURE, _BAD_T_SENT, _BAD_COUNTS = range(1, 6)  # detection_rows' status


def _frame_error(status: int, out: np.ndarray, limits: DecodeLimits) -> None:
    _frame_number, t_capture, t_sent, camera_id, _n_balls, n_blue, n_yellow = out[:7].tolist()
    camera_id = int(camera_id)
    if status == _BAD_CAMERA:
        raise SslDecodeError("camera", f"camera_id {camera_id} exceeds {limits.max_camera_id}")
    if status in (_BAD_T_CAPTURE, _BAD_T_SENT):
        name, value = ("t_capture", t_capture) if status == _BAD_T_CAPTURE else ("t_sent", t_sent)
        raise SslDecodeError("time", f"{name} {value!r} is not a time in [0, {limits.max_time_s:g}] s")
    raise SslDecodeError("counts", f"camera {camera_id}: absurd robot counts ({int(n_blue)} blue, {int(n_yellow)} "
                                   f"yellow; at most {limits.max_robots_per_team} per team)")


def detection_rows_size(max_balls: int, max_robots: int) -> int:
    return 8 + 4 * max_balls + 12 * max_robots + 7 * (max_balls + 2 * max_robots)


_REJECT_BALL, _REJECT_ID, _REJECT_PLACE, _REJECT_THETA = range(4)


def _sort_out(camera_id: int, robots: np.ndarray, rejected: np.ndarray, problems: list[Problem]) -> None:
    """Name the detections the pass dropped; fix or drop the orientations it left (rare: plain Python)."""
    for kind, team_index, robot_id, x, y, value, row in rejected.tolist():
        team = TEAMS[int(team_index)]
        if kind == _REJECT_BALL:
            problems.append(Problem("bad_ball", f"camera {camera_id}: ball at ({x!r}, {y!r}) mm, confidence "
                                                f"{value!r} dropped"))
        elif kind == _REJECT_ID:
            problems.append(Problem("bad_robot_id", f"camera {camera_id}: {team} robot without a valid id dropped"))
        elif kind == _REJECT_PLACE:
            problems.append(Problem("bad_robot_place", f"camera {camera_id}: {team} robot {int(robot_id)} at "
                                                       f"({x!r}, {y!r}) mm dropped"))
        elif math.isfinite(value) and abs(value) <= 100.0:  # an orientation beyond [-pi, pi]: turned back
            robots[int(row), 4] = math.remainder(value, 2.0 * math.pi)
        else:
            problems.append(Problem("bad_orientation", f"camera {camera_id}: {team} robot {int(robot_id)} "
                                                       f"orientation {value!r} dropped"))
            robots[int(row), 4] = math.nan


# ------------------------------------------------------------------ the compiled pass over the bytes
# Protobuf wire format: a key varint (field number << 3 | wire type), then the value: 0 varint,
# 1 eight bytes, 2 a length varint and that many bytes, 5 four bytes, 3/4 start/end of a group.
# A field with another wire type than its declaration's is an unknown field (the runtime does the
# same), a message field seen twice is merged (scalars: the last one; repeated: appended).
# Field numbers: SSL_WrapperPacket detection 1; SSL_DetectionFrame frame_number 1, t_capture 2,
# t_sent 3, camera_id 4, balls 5, robots_yellow 6, robots_blue 7; SSL_DetectionBall confidence 1,
# x 3, y 4, z 5; SSL_DetectionRobot confidence 1, robot_id 2, x 3, y 4, orientation 5.
@numba.njit(cache=True, error_model="numpy")
def _varint(buf, i, end):
    """(value, index after it); index -1 when the bytes end first or it runs over 10 bytes."""
    value = np.uint64(0)
    shift = np.uint64(0)
    while i < end and shift < 70:
        b = buf[i]
        i += 1
        value |= np.uint64(b & 0x7F) << shift
        if b < 0x80:
            return value, i
        shift += np.uint64(7)
    return value, -1


@numba.njit(cache=True, error_model="numpy")
def _skip(buf, i, end, key):
    """Index after the value of this key (a group: up to its matching end), or -1 (as the runtime: a
    bad wire type, field number 0, a group ended by another number, bytes ending first)."""
    groups = np.empty(16, np.uint64)  # the open groups' field numbers
    depth = 0
    while True:
        wire, number = key & np.uint64(7), key >> np.uint64(3)
        if number == 0:
            return -1
        if wire == 0:
            _, i = _varint(buf, i, end)
        elif wire == 1:
            i = i + 8 if i + 8 <= end else -1
        elif wire == 5:
            i = i + 4 if i + 4 <= end else -1
        elif wire == 2:
            n, i = _varint(buf, i, end)
            i = i + int(n) if i >= 0 and n <= np.uint64(end - i) else -1
        elif wire == 3 and depth < len(groups):
            groups[depth] = number
            depth += 1
        elif wire == 4 and depth > 0 and groups[depth - 1] == number:
            depth -= 1
        else:
            return -1
        if i < 0 or depth == 0:
            return i
        if i >= end:
            return -1
        key, i = _varint(buf, i, end)
        if i < 0:
            return -1


@numba.njit(cache=True, error_model="numpy")
def _scalar(buf, i, scratch, n):
    for k in range(n):
        scratch[k] = buf[i + k]
    return scratch.view(np.float32)[0] if n == 4 else scratch.view(np.float64)[0]


@numba.njit(cache=True, error_model="numpy")
def _sub_fields(buf, i, end, scratch, values, present):
    """Fields 1..8 of a ball or robot message: floats (fixed32) and robot_id (varint, field 2) into values."""
    while i < end:
        key, i = _varint(buf, i, end)
        if i < 0:
            return -1
        number, wire = int(key >> np.uint64(3)), int(key & np.uint64(7))
        if wire == 5 and 1 <= number <= 8 and number != 2 and i + 4 <= end:
            values[number] = _scalar(buf, i, scratch, 4)
            present[number] = True
            i += 4
        elif wire == 0 and number == 2:
            value, i = _varint(buf, i, end)
            values[2] = float(value & np.uint64(0xFFFFFFFF))
            present[2] = True
        else:
            i = _skip(buf, i, end, key)
        if i < 0:
            return -1
    return i


@numba.njit(cache=True, error_model="numpy")
def detection_rows(buf, out, max_balls, max_robots, max_mm, max_id, max_camera, max_time):
    """One pass over an SSL_WrapperPacket's bytes into ``out`` (``detection_rows_size`` doubles); returns
    (status, balls kept, robots kept, rejected, geometry part seen). Status 0: a valid detection frame
    (ball candidates beyond max_balls left out: the count in the bytes says how many); _DECLINED: bytes
    the runtime should judge (not the wire format, required fields missing, no detection); else the frame's
    first check that failed (_frame_error).

    out: frame_number, t_capture, t_sent, camera_id; the counts of balls, blue and yellow robots in
    the bytes; at 8 the valid balls (DetectionArrays' columns, metres), at 8 + 4 max_balls the valid
    robots (blue, then yellow; at most max_robots per team), after 2 max_robots of them the rejected
    detections as rows [kind, team, robot_id, x, y, value, robot row] for _sort_out (at most max_balls of
    them balls: a robot's always has room).
    (Arrays in, numbers out: numba boxes each returned array for about 1.5 us.)
    """
    out[:8] = 0.0
    counts = np.zeros(5, np.int64)  # kept balls, blue, yellow; rejected detections, of them balls
    scratch = np.zeros(8, np.uint8)
    values = np.zeros(9)
    present = np.zeros(9, np.bool_)
    frame_fields = np.zeros(5, np.bool_)  # frame_number, t_capture, t_sent, camera_id seen (1..4)
    declined = geometry = False
    end = len(buf)
    i = 0
    while 0 <= i < end:  # the wrapper: only detection (1) is read here
        key, i = _varint(buf, i, end)
        if i < 0:
            break
        if key == np.uint64(2 << 3 | 2):
            geometry = True  # the runtime's part
        if key != np.uint64(1 << 3 | 2):
            i = _skip(buf, i, end, key)
            continue
        frame_fields[0] = True
        n, i = _varint(buf, i, end)
        if i < 0 or n > np.uint64(end - i):
            i = -1
            break
        det_end = i + int(n)
        i, frame_declined = _detection_frame(buf, i, det_end, out, counts, max_balls, max_robots, max_mm, max_id,
                                             scratch, values, present, frame_fields)
        declined = declined or frame_declined
        if i < 0:
            break
        i = det_end
    _pack_yellow_rows(out, counts, max_balls, max_robots)
    if i < 0 or declined or not frame_fields.all():
        status = 1  # _DECLINED
    elif out[3] > max_camera:
        status = 2
    elif not (np.isfinite(out[1]) and 0.0 <= out[1] <= max_time):
        status = 3
    elif not (np.isfinite(out[2]) and 0.0 <= out[2] <= max_time):
        status = 4
    elif out[5] > max_robots or out[6] > max_robots:
        status = 5
    else:
        status = 0
    return status, counts[0], counts[1] + counts[2], counts[3], geometry


@numba.njit(cache=True, error_model="numpy", inline="always")  # into detection_rows
def _detection_frame(buf, i, det_end, out, counts, max_balls, max_robots, max_mm, max_id, scratch, values, present,
                     frame_fields):
    """The fields of an SSL_DetectionFrame (detection_rows); (index after them or -1, a detection lacked a
    required field)."""
    declined = False
    while 0 <= i < det_end:
        key, i = _varint(buf, i, det_end)
        if i < 0:
            break
        number, wire = int(key >> np.uint64(3)), int(key & np.uint64(7))
        if wire == 0 and (number == 1 or number == 4):
            value, i = _varint(buf, i, det_end)
            out[0 if number == 1 else 3] = float(value & np.uint64(0xFFFFFFFF))
            frame_fields[number] = True
        elif wire == 1 and (number == 2 or number == 3) and i + 8 <= det_end:
            out[number - 1] = _scalar(buf, i, scratch, 8)
            frame_fields[number] = True
            i += 8
        elif wire == 2 and 5 <= number <= 7:
            n, i = _varint(buf, i, det_end)
            if i < 0 or n > np.uint64(det_end - i):
                return -1, declined
            sub_end = i + int(n)
            values[:] = 0.0
            present[:] = False
            if _sub_fields(buf, i, sub_end, scratch, values, present) < 0:
                return -1, declined
            i = sub_end
            if not (present[1] and present[3] and present[4] and present[6] and present[7]):
                declined = True  # a required field missing: the runtime names it
            team = 0 if number != 6 else 1  # TEAMS: blue, yellow (a ball: 0)
            if number == 5:
                kind = _keep_ball(out, counts, max_balls, max_mm, values)
            else:
                kind = _keep_robot(out, counts, max_balls, max_robots, max_mm, max_id, team, values, present)
            if kind >= 0:
                _note_rejected(out, counts, max_balls, max_robots, kind, number == 5, team, values)
        else:
            i = _skip(buf, i, det_end, key)
    return i, declined


@numba.njit(cache=True, error_model="numpy", inline="always")  # into detection_rows
def _keep_ball(out, counts, max_balls, max_mm, values):
    """Count a ball detection and keep it in the next ball row while there is room; its reject kind if
    invalid (else -1)."""
    out[4] += 1.0
    c, x, y, z = values[1], values[3], values[4], values[5]
    if not (abs(x) <= max_mm and abs(y) <= max_mm and 0.0 <= c <= 1.0 and abs(z) <= max_mm):
        return 0  # _REJECT_BALL
    if counts[0] < max_balls:
        row = 8 + 4 * counts[0]
        out[row], out[row + 1], out[row + 2], out[row + 3] = x * 1e-3, y * 1e-3, c, z * 1e-3
        counts[0] += 1
    return -1


@numba.njit(cache=True, error_model="numpy", inline="always")  # into detection_rows
def _keep_robot(out, counts, max_balls, max_robots, max_mm, max_id, team, values, present):
    """Count a robot detection of ``team`` (0 blue, 1 yellow) and keep it in its team's next row while there
    is room (yellow's after blue's room: _pack_yellow_rows moves them); its reject kind if invalid or its
    orientation beyond [-pi, pi] (else -1)."""
    out[5 + team] += 1.0
    c, x, y = values[1], values[3], values[4]
    if values[2] > max_id or not present[2]:
        return 1  # _REJECT_ID
    if not (abs(x) <= max_mm and abs(y) <= max_mm and 0.0 <= c <= 1.0):
        return 2  # _REJECT_PLACE
    if counts[1 + team] >= max_robots:
        return -1
    row = 8 + 4 * max_balls + 6 * (team * max_robots + counts[1 + team])
    theta = values[5] if present[5] else np.nan
    out[row], out[row + 1], out[row + 2] = team, values[2], x * 1e-3
    out[row + 3], out[row + 4], out[row + 5] = y * 1e-3, theta, c
    counts[1 + team] += 1
    if present[5] and not -np.pi <= theta <= np.pi:
        return 3  # _REJECT_THETA: _sort_out turns it back or drops it
    return -1


@numba.njit(cache=True, error_model="numpy", inline="always")  # into detection_rows
def _note_rejected(out, counts, max_balls, max_robots, kind, is_ball, team, values):
    """A rejected detection's row [kind, team, robot_id, x, y, value, robot row] for _sort_out, while there is
    room (at most max_balls of them balls: a robot's always has room)."""
    if counts[3] >= max_balls + 2 * max_robots or (is_ball and counts[4] >= max_balls):
        return
    if is_ball:
        counts[4] += 1
    row = 8 + 4 * max_balls + 12 * max_robots + 7 * counts[3]
    out[row], out[row + 1], out[row + 2], out[row + 3], out[row + 4] = kind, team, values[2], values[3], values[4]
    out[row + 5] = values[5] if kind == 3 else values[1]
    out[row + 6] = team * max_robots + counts[1 + team] - 1 if kind == 3 else -1.0
    counts[3] += 1


@numba.njit(cache=True, error_model="numpy", inline="always")  # into detection_rows
def _pack_yellow_rows(out, counts, max_balls, max_robots):
    """Move the yellow robots' rows right behind the blue ones (and their orientations' rejected rows with them)."""
    at_robots = 8 + 4 * max_balls
    n_blue, n_yellow = counts[1], counts[2]
    yellow = at_robots + 6 * max_robots
    for k in range(6 * n_yellow):  # forwards: the target lies before the source
        out[at_robots + 6 * n_blue + k] = out[yellow + k]
    at_rejected = at_robots + 12 * max_robots
    for k in range(counts[3]):  # an orientation's row: where its robot is now
        row = at_rejected + 7 * k
        if out[row] == 3.0 and out[row + 1] == 1.0:
            out[row + 6] += n_blue - max_robots


def _decode_geometry(geo, limits: DecodeLimits, problems: list[Problem]) -> FieldGeometry | None:
    f = geo.field
    sizes = (f.field_length, f.field_width, f.goal_width, f.goal_depth, f.boundary_width)
    limit_mm = limits.max_abs_coordinate_m / MM
    if not (f.field_length > 0 and f.field_width > 0 and all(0 <= s <= limit_mm for s in sizes)):
        problems.append(Problem("geometry", f"geometry dropped: field sizes {sizes} mm out of range"))
        return None
    model, chip = _decode_models(geo, problems)
    cameras = []
    for calib in geo.calib:
        pos = (calib.derived_camera_world_tx, calib.derived_camera_world_ty, calib.derived_camera_world_tz)
        if calib.HasField("derived_camera_world_tz") and all(_coordinate_ok(v, limits) for v in pos):
            cameras.append(CameraPose(calib.camera_id, *(v * MM for v in pos)))

    def optional_mm(name: str) -> float | None:
        if not f.HasField(name):
            return None
        value = getattr(f, name) * MM
        return value if 0.0 <= value <= limits.max_abs_coordinate_m else None

    return FieldGeometry(
        length_m=f.field_length * MM,
        width_m=f.field_width * MM,
        boundary_m=f.boundary_width * MM,
        goal_width_m=f.goal_width * MM,
        goal_depth_m=f.goal_depth * MM,
        penalty_area_depth_m=optional_mm("penalty_area_depth"),
        penalty_area_width_m=optional_mm("penalty_area_width"),
        ball_model=model,
        cameras=tuple(cameras),
        chip_model=chip,
    )


def _decode_models(geo, problems: list[Problem]) -> tuple[BallModelFromVision | None, ChipModelFromVision | None]:
    """The geometry's ball models (each optional); one out of range is dropped and named."""
    if not geo.HasField("models"):
        return None, None
    model = chip = None
    if geo.models.HasField("straight_two_phase"):
        m = geo.models.straight_two_phase
        if all(math.isfinite(v) for v in (m.acc_slide, m.acc_roll, m.k_switch)) and (
            -100.0 <= m.acc_slide < m.acc_roll < 0.0 and 0.0 < m.k_switch <= 1.0
        ):
            model = BallModelFromVision(m.acc_slide, m.acc_roll, m.k_switch)
        else:
            problems.append(Problem(
                "ball_model", f"ball model dropped: acc_slide {m.acc_slide!r}, acc_roll {m.acc_roll!r}, k_switch "
                              f"{m.k_switch!r} (need acc_slide < acc_roll < 0 m/s^2, 0 < k_switch <= 1)"
            ))
    if geo.models.HasField("chip_fixed_loss"):
        c = geo.models.chip_fixed_loss
        xy = (c.damping_xy_first_hop, c.damping_xy_other_hops)
        # damping_z below 1: a ball that kept its whole vertical speed would hop for ever
        if 0.0 <= c.damping_z < 1.0 and all(0.0 <= v <= 1.0 for v in xy):
            chip = ChipModelFromVision(c.damping_z, *xy)
        else:
            problems.append(Problem(
                "ball_model", f"chip model dropped: damping_z {c.damping_z!r}, damping_xy_first_hop {xy[0]!r}, "
                              f"damping_xy_other_hops {xy[1]!r} (need damping_z in [0, 1), the others in [0, 1])"
            ))
    return model, chip


# ------------------------------------------------------------------------------------ encoding
def encode_frame(frame: CameraFrame) -> bytes:
    """A detection-only datagram (metres in, millimetres on the wire; pixel coordinates 0)."""
    packet = wrapper_pb2.SSL_WrapperPacket()
    det = packet.detection
    det.frame_number = frame.frame_number
    det.t_capture = frame.t_capture_s
    det.t_sent = frame.t_sent_s
    det.camera_id = frame.camera_id
    for ball in frame.balls:
        b = det.balls.add(confidence=ball.confidence, x=ball.x_m / MM, y=ball.y_m / MM, pixel_x=0.0, pixel_y=0.0)
        if ball.z_m:
            b.z = ball.z_m / MM
    for robot in frame.robots:
        team = det.robots_blue if robot.team == "blue" else det.robots_yellow
        r = team.add(confidence=robot.confidence, robot_id=robot.robot_id, x=robot.x_m / MM, y=robot.y_m / MM,
                     pixel_x=0.0, pixel_y=0.0)
        if robot.theta_rad is not None:
            r.orientation = robot.theta_rad
    return packet.SerializeToString()


def encode_geometry(geometry: FieldGeometry, focal_length_px: float = 500.0) -> bytes:
    """A geometry-only datagram: field size, one calibration per camera (position only) and the ball models."""
    packet = wrapper_pb2.SSL_WrapperPacket()
    f = packet.geometry.field
    f.field_length = round(geometry.length_m / MM)
    f.field_width = round(geometry.width_m / MM)
    f.goal_width = round(geometry.goal_width_m / MM)
    f.goal_depth = round(geometry.goal_depth_m / MM)
    f.boundary_width = round(geometry.boundary_m / MM)
    if geometry.penalty_area_depth_m is not None:
        f.penalty_area_depth = round(geometry.penalty_area_depth_m / MM)
    if geometry.penalty_area_width_m is not None:
        f.penalty_area_width = round(geometry.penalty_area_width_m / MM)
    for cam in geometry.cameras:
        # Looking straight down: the rotation field->camera is a half turn about x (q1 = 1).
        packet.geometry.calib.add(
            camera_id=cam.camera_id, focal_length=focal_length_px, principal_point_x=0.0, principal_point_y=0.0,
            distortion=0.0, q0=0.0, q1=1.0, q2=0.0, q3=0.0, tx=-cam.x_m / MM, ty=cam.y_m / MM, tz=cam.z_m / MM,
            derived_camera_world_tx=cam.x_m / MM, derived_camera_world_ty=cam.y_m / MM,
            derived_camera_world_tz=cam.z_m / MM,
        )
    if geometry.ball_model is not None:
        m = packet.geometry.models.straight_two_phase
        m.acc_slide = geometry.ball_model.a_slide_mps2
        m.acc_roll = geometry.ball_model.a_roll_mps2
        m.k_switch = geometry.ball_model.c_switch
    if geometry.chip_model is not None:
        c = packet.geometry.models.chip_fixed_loss
        c.damping_xy_first_hop = geometry.chip_model.damping_xy_first_hop
        c.damping_xy_other_hops = geometry.chip_model.damping_xy_other_hops
        c.damping_z = geometry.chip_model.damping_z
    return packet.SerializeToString()
