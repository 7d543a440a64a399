"""SSL-Vision datagrams in and out, without ROS: decoding with checks, encoding, and the vision clock.

``decode_wrapper`` turns one UDP datagram (an ``SSL_WrapperPacket``) into plain values in the
contract's units (metres, radians, seconds), or raises ``SslDecodeError`` naming what is wrong
with it. Single bad detections (a NaN coordinate, a robot without an id) are dropped and named
in ``DecodedPacket.problems``; the rest of the frame is kept. ``encode_frame`` and
``encode_geometry`` build datagrams (the plant's simulated cameras and the tests use them).

``VisionClock`` maps a camera's ``t_capture`` (the vision host's clock) onto the receiver's
clock: per camera, the offset is the smallest ``t_receive - t_sent`` seen over a sliding window
(network and scheduling delays only ever add to it), so ``t_capture + offset`` is the capture
time on the receiver's clock. A camera whose clock jumps is noticed when its samples leave the
window's offset by more than ``jump_s`` for several packets over ``confirm_s``; then the window
restarts from the new samples (details in the class).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field
from typing import NamedTuple

from google.protobuf.message import DecodeError

from erforce_interfaces.ssl_proto import ssl_vision_wrapper_pb2 as wrapper_pb2

MM = 1e-3
TEAMS = ("blue", "yellow")
#: Our team's colour unless told otherwise (the SSL bridge's team_color, the plant's SSL output)
OUR_TEAM_COLOR = "blue"
# The league's ports: SSL-Vision on 10006; ER-Force's simulator and grSim send vision on 10020.
SSL_VISION_GROUP = "224.5.23.2"
SSL_VISION_PORT = 10006
SSL_SIMULATOR_VISION_PORT = 10020


class SslDecodeError(ValueError):
    """A datagram that is not a usable SSL_WrapperPacket; the message says why, ``kind`` what class of problem
    (for throttling warnings per kind): empty, size, garbage, missing, content, counts, camera, time."""

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


@dataclass(frozen=True)
class BallModelFromVision:
    """``SSL_BallModelStraightTwoPhase`` in the names of erforce_ball_model.BallModelParams."""

    a_slide_mps2: float
    a_roll_mps2: float
    c_switch: float


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


@dataclass
class DecodedPacket:
    frame: CameraFrame | None = None
    geometry: FieldGeometry | None = None
    problems: list[str] = field(default_factory=list)  # dropped parts of an otherwise good packet


def _time(name: str, value: float, limits: DecodeLimits) -> float:
    if not (math.isfinite(value) and 0.0 <= value <= limits.max_time_s):
        raise SslDecodeError("time", f"{name} {value!r} is not a time in [0, {limits.max_time_s:g}] s")
    return value


def _coordinate_ok(value: float, limits: DecodeLimits) -> bool:
    return math.isfinite(value) and abs(value) * MM <= limits.max_abs_coordinate_m


def decode_wrapper(data: bytes, limits: DecodeLimits = DecodeLimits()) -> DecodedPacket:
    """One datagram -> its detection frame and/or geometry; raises SslDecodeError when unusable."""
    if not data:
        raise SslDecodeError("empty", "empty datagram")
    if len(data) > limits.max_datagram_bytes:
        raise SslDecodeError("size", f"datagram of {len(data)} bytes exceeds {limits.max_datagram_bytes}")
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
    out = DecodedPacket()
    if has_detection:
        out.frame = _decode_frame(packet.detection, limits, out.problems)
    if has_geometry:
        out.geometry = _decode_geometry(packet.geometry, limits, out.problems)
    return out


def _decode_frame(det, limits: DecodeLimits, problems: list[str]) -> CameraFrame:
    camera_id = det.camera_id
    if camera_id > limits.max_camera_id:
        raise SslDecodeError("camera", f"camera_id {camera_id} exceeds {limits.max_camera_id}")
    t_capture = _time("t_capture", det.t_capture, limits)
    t_sent = _time("t_sent", det.t_sent, limits)
    n_balls, n_yellow, n_blue = len(det.balls), len(det.robots_yellow), len(det.robots_blue)
    if n_balls > limits.max_balls or max(n_yellow, n_blue) > limits.max_robots_per_team:
        raise SslDecodeError(
            "counts", f"camera {camera_id}: absurd counts ({n_balls} balls, {n_blue} blue, {n_yellow} yellow robots)"
        )
    # Per detection as few calls into the message as possible: this runs for every robot of every frame.
    # An unset optional field reads as 0, so HasField is needed only where 0 is read.
    max_mm = limits.max_abs_coordinate_m / MM
    balls = []
    for ball in det.balls:
        x, y, c, z = ball.x, ball.y, ball.confidence, ball.z  # z: 0 when absent
        if abs(x) <= max_mm and abs(y) <= max_mm and 0.0 <= c <= 1.0 and abs(z) <= max_mm:  # False for NaN
            balls.append(BallCandidate(x * MM, y * MM, c, z * MM))
        else:
            problems.append(f"camera {camera_id}: ball at ({x!r}, {y!r}) mm, confidence {c!r} dropped")
    robots = []
    max_id = limits.max_robot_id
    for team, sightings in (("blue", det.robots_blue), ("yellow", det.robots_yellow)):
        for robot in sightings:
            x, y, c, robot_id, theta = robot.x, robot.y, robot.confidence, robot.robot_id, robot.orientation
            if robot_id > max_id or (robot_id == 0 and not robot.HasField("robot_id")):
                problems.append(f"camera {camera_id}: {team} robot without a valid id dropped")
                continue
            if not (abs(x) <= max_mm and abs(y) <= max_mm and 0.0 <= c <= 1.0):
                problems.append(f"camera {camera_id}: {team} robot {robot_id} at ({x!r}, {y!r}) mm dropped")
                continue
            if theta == 0.0 and not robot.HasField("orientation"):
                theta = None
            elif not -math.pi <= theta <= math.pi:
                if math.isfinite(theta) and abs(theta) <= 100.0:
                    theta = math.remainder(theta, 2.0 * math.pi)
                else:
                    problems.append(f"camera {camera_id}: {team} robot {robot_id} orientation {theta!r} dropped")
                    theta = None
            robots.append(RobotSighting(team, robot_id, x * MM, y * MM, theta, c))
    return CameraFrame(camera_id, det.frame_number, t_capture, t_sent, tuple(balls), tuple(robots))


def _decode_geometry(geo, limits: DecodeLimits, problems: list[str]) -> FieldGeometry | None:
    f = geo.field
    sizes = (f.field_length, f.field_width, f.goal_width, f.goal_depth, f.boundary_width)
    limit_mm = limits.max_abs_coordinate_m / MM
    if not (f.field_length > 0 and f.field_width > 0 and all(0 <= s <= limit_mm for s in sizes)):
        problems.append(f"geometry dropped: field sizes {sizes} mm out of range")
        return None
    model = None
    if geo.HasField("models") and geo.models.HasField("straight_two_phase"):
        m = geo.models.straight_two_phase
        if all(math.isfinite(v) for v in (m.acc_slide, m.acc_roll, m.k_switch)) and (
            -100.0 <= m.acc_slide < m.acc_roll < 0.0 and 0.0 < m.k_switch <= 1.0
        ):
            model = BallModelFromVision(m.acc_slide, m.acc_roll, m.k_switch)
        else:
            problems.append(
                f"ball model dropped: acc_slide {m.acc_slide!r}, acc_roll {m.acc_roll!r}, k_switch {m.k_switch!r} "
                "(need acc_slide < acc_roll < 0 m/s^2, 0 < k_switch <= 1)"
            )
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
    )


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
    """A geometry-only datagram: field size, one calibration per camera (position only) and the ball model."""
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
    return packet.SerializeToString()


# --------------------------------------------------------------------------------- vision clock
class ClockJump(ValueError):
    """A frame refused because its camera's clock seems to have jumped (not yet confirmed)."""


class VisionClock:
    """Per camera: vision-clock capture times -> receiver-clock stamps (see the module docstring).

    A sample more than ``jump_s`` above the window's offset is a late packet (a stall of the
    receiver or the network) or the camera's clock stepping back: the frame is stamped with the
    window's offset, right for a late packet. A sample more than ``jump_s`` below is the clock
    stepping forward or a bogus ``t_sent``: the frame is refused (``ClockJump``). Either becomes
    the new offset once ``confirm_packets`` consecutive samples agree over at least ``confirm_s``
    of receive time; a stall's backlog arrives within milliseconds and never confirms.
    """

    def __init__(self, window_s: float = 2.0, jump_s: float = 0.25, confirm_packets: int = 5,
                 confirm_s: float = 0.2) -> None:
        if not (window_s > 0.0 and jump_s > 0.0 and confirm_packets >= 1 and confirm_s >= 0.0):
            raise ValueError("VisionClock: window_s and jump_s must be > 0, confirm_packets >= 1, confirm_s >= 0")
        self.window_s = window_s
        self.jump_s = jump_s
        self.confirm_packets = confirm_packets
        self.confirm_s = confirm_s
        # per camera: samples (t_receive, offset) with increasing offsets (a monotonic queue: its
        # head is the window's minimum), and the samples of a suspected jump
        self._windows: dict[int, deque[tuple[float, float]]] = {}
        self._jumps: dict[int, list[tuple[float, float]]] = {}
        self.jumps_confirmed = 0

    def offset_s(self, camera_id: int) -> float | None:
        window = self._windows.get(camera_id)
        return window[0][1] if window else None

    def to_receiver(self, camera_id: int, t_capture_s: float, t_sent_s: float, t_receive_s: float) -> float:
        """The capture time on the receiver's clock; raises ClockJump for a frame of a suspected forward jump."""
        sample = t_receive_s - t_sent_s
        window = self._windows.get(camera_id)
        if window is None:
            window = self._windows[camera_id] = deque()
        while window and window[0][0] < t_receive_s - self.window_s:
            window.popleft()
        deviation = sample - window[0][1] if window else 0.0
        if abs(deviation) > self.jump_s:
            pending = self._jumps.setdefault(camera_id, [])
            if pending and abs(sample - pending[-1][1]) > self.jump_s:
                pending.clear()  # not one consistent jump: start counting again
            pending.append((t_receive_s, sample))
            if len(pending) >= self.confirm_packets and pending[-1][0] - pending[0][0] >= self.confirm_s:
                window.clear()
                for item in pending:
                    self._push(window, item)
                pending.clear()
                self.jumps_confirmed += 1
            elif deviation < 0.0:
                raise ClockJump(
                    f"camera {camera_id}: clock offset {sample:+.3f} s is {-deviation:.3f} s below "
                    f"{window[0][1]:+.3f} s (the camera's clock jumped forward, or a bogus t_sent); frame refused "
                    "until confirmed"
                )
        else:
            self._jumps.pop(camera_id, None)
            self._push(window, (t_receive_s, sample))
        stamp = t_capture_s + window[0][1]
        return min(stamp, t_receive_s)  # never after it arrived

    @staticmethod
    def _push(window: deque, item: tuple[float, float]) -> None:
        while window and window[-1][1] >= item[1]:
            window.pop()
        window.append(item)
