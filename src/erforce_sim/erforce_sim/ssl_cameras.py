"""The plant's vision as SSL-Vision: the world's vision frames split over simulated cameras.

Each ``SimCamera`` sees a rectangle of the field (quadrants overlapping by ``overlap_m`` for the
default four) and sends its part of every world frame as an ``SSL_WrapperPacket`` with its own
extra latency and its own noise; the ball in an overlap is in two cameras' frames. ``t_capture``
is the world time of the image (shifted by ``clock_offset_s``, the vision host's clock) and
``t_sent`` the time the packet leaves. Geometry (field size, camera positions, the ball model)
goes out as its own packet every ``geometry_period_s``, as SSL-Vision does.

A ball in the air (a chip) is where its camera's ray through it meets the ground, as SSL-Vision, which
takes every ball to lie on the field, reports it (``ground_point``): further from the camera than it is,
each camera by its own position, so the cameras of an overlap disagree about a flying ball.

How the cameras err is a ``CameraRealism``: ``BENCH_CAMERAS`` (the default: the world's frame with its noise and
dropouts shared by every camera, 0.5 mm more per camera, a 0.5 m overlap) or ``ERFORCE_REALISTIC`` (ER-Force's
simulator's "Realistic" preset: SSL-Vision's one detection per camera, each with its own noise and its own missed
balls, a 1 m overlap past each axis, and each camera projecting from 0.1 m off where the geometry says it is).
What each camera reports of a world frame is a ``CameraRig``'s (``detect``): the SSL packets here and the plant's
ROS vision (camera_views) take it from there, so a preset means the same on both.
"""

from __future__ import annotations

import math
import random
import socket
from dataclasses import dataclass, replace

from erforce_interfaces.runtime.param_schema import schema_defaults
from erforce_interfaces.ssl.ssl_vision import (
    SSL_VISION_INTERFACE,
    BallCandidate,
    BallModelFromVision,
    CameraFrame,
    CameraPose,
    ChipModelFromVision,
    FieldGeometry,
    RobotSighting,
    encode_frame,
    encode_geometry,
)
from erforce_interfaces.wire.robot_config import FieldConfig
from erforce_sim.ball import BallParams
from erforce_sim.sensors import VisionFrame, VisionParams

_PLANT = schema_defaults("erforce_sim", "plant")

CAMERA_HEIGHT_M = 4.0
CAMERA_NOISE_M = 0.0005  # each camera's own noise on what it sees [m]
QUADRANT_OVERLAP_M = 0.5  # the width of the band across each axis two quadrant cameras both see [m]
# ER-Force's simulator moves every camera it reports by one fixed vector: (0.3, 0.7, 0.05) normalised in its own
# axes, which are vision's turned by 90 deg (vision x = its y, vision y = -its x): (0.7, -0.3, 0.05) here
_ERFORCE_ERROR_AXES = (0.7, -0.3, 0.05)
CAMERA_POSITION_ERROR_DIRECTION = tuple(c / math.hypot(*_ERFORCE_ERROR_AXES) for c in _ERFORCE_ERROR_AXES)
FIXED_ERRORS = ("position_error", "object_offset")  # CameraRealism's fixed errors, each a field <name>_m


@dataclass(frozen=True)
class CameraRealism:
    """How the simulated SSL-Vision cameras err. SSL-Vision runs one detection per camera, so in a per-camera model
    (``shared_world_noise`` False) each camera's ball carries its own noise and is missed on its own, and the world's
    frame the cameras take is noise-free (``world_vision``); in the shared model the world's frame already carries its
    noise and dropouts (VisionSystem), the same for every camera, and each camera adds its own on top.

    ``overlap_m``: the width of the band across each field axis that two quadrant cameras both see (grSim's and
    ER-Force's overlap is how far past the axis a camera sees: half of it). ``position_error_m``: the camera that
    projects the ball stands this far off the position the geometry reports, along
    ``CAMERA_POSITION_ERROR_DIRECTION``, every camera by the same vector, fixed for the run (ER-Force: reported =
    true + error); a ball on the ground is unaffected, a flying one lands on other rays than the geometry's.
    ``object_offset_m``: each camera reports every object this far off, away from the field's centre towards the
    camera's ground point (ER-Force's ``object_position_offset``), so two cameras disagree about a ball at rest."""

    name: str
    shared_world_noise: bool
    ball_noise_m: float  # each camera's own, per axis
    robot_noise_m: float
    missing_ball_prob: float  # each camera on its own, per frame
    missing_robot_prob: float
    overlap_m: float
    position_error_m: float
    object_offset_m: float

    def __post_init__(self) -> None:
        limits = {"ball_noise_m": 0.1, "robot_noise_m": 0.1, "missing_ball_prob": 1.0, "missing_robot_prob": 1.0,
                  "overlap_m": 5.0, "position_error_m": 1.0, "object_offset_m": 0.5}
        for name, hi in limits.items():
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and 0.0 <= value <= hi):
                raise ValueError(f"CameraRealism.{name}: must be finite in [0, {hi}], got {value!r}")

    def sighting_noise_m(self, params: VisionParams) -> float:
        """The standard deviation per axis of one camera's ball on the ground, the world's vision ``params`` taken:
        the world's and the camera's own together in the shared model, the camera's own in the per-camera one."""
        own = self.ball_noise_m
        return math.hypot(params.position_noise_m, own) if self.shared_world_noise else own

    def world_vision(self, params: VisionParams) -> VisionParams:
        """The world's vision to take the cameras' frames from: ``params`` for the shared model; for the per-camera
        one without position noise and dropouts (each camera adds its own; the orientation noise stays shared)."""
        if self.shared_world_noise:
            return params
        return replace(params, position_noise_m=0.0, ball_dropout_prob=0.0, robot_dropout_prob=0.0)

    def without(self, *fixed_errors: str) -> CameraRealism:
        """The same cameras without the fixed errors named (``FIXED_ERRORS``: position_error, object_offset), named
        so: what a field whose calibration took those off would show."""
        unknown = set(fixed_errors) - set(FIXED_ERRORS)
        if unknown:
            raise ValueError(f"CameraRealism.without: {sorted(unknown)} not among {FIXED_ERRORS}")
        if not fixed_errors:
            return self
        return replace(self, name=f"{self.name} without {' and '.join(fixed_errors)}",
                       **{f"{e}_m": 0.0 for e in fixed_errors})

    def noise_free(self) -> CameraRealism:
        """The same cameras without random errors (no noise, nothing missed); their fixed errors stay."""
        return replace(self, ball_noise_m=0.0, robot_noise_m=0.0, missing_ball_prob=0.0, missing_robot_prob=0.0)

    def projecting_camera(self, pose: CameraPose) -> tuple[float, float, float]:
        """Where the camera the geometry reports at ``pose`` stands when it projects the ball."""
        e = self.position_error_m
        dx, dy, dz = CAMERA_POSITION_ERROR_DIRECTION
        return pose.x_m - e * dx, pose.y_m - e * dy, pose.z_m - e * dz

    def object_offset(self, camera_m: tuple[float, float, float]) -> tuple[float, float]:
        """What the camera at ``camera_m`` adds to every object's position: ``object_offset_m`` along its ground
        point's direction from the field's centre (less for a camera nearer the centre than that)."""
        cx, cy, _ = camera_m
        r = math.hypot(cx, cy)
        if self.object_offset_m == 0.0 or r == 0.0:
            return 0.0, 0.0
        k = min(self.object_offset_m / r, 1.0)
        return k * cx, k * cy


# today's model: the world's 2 mm (VisionParams) shared by the cameras, 0.5 mm each, 2 % of frames without the ball
BENCH_CAMERAS = CameraRealism("bench", shared_world_noise=True, ball_noise_m=CAMERA_NOISE_M,
                              robot_noise_m=CAMERA_NOISE_M, missing_ball_prob=0.0, missing_robot_prob=0.0,
                              overlap_m=QUADRANT_OVERLAP_M, position_error_m=0.0, object_offset_m=0.0)
# ER-Force's simulator, preset "Realistic" (robotics-erlangen/framework config/simulator-realism/Realistic.txt):
# stddev_ball_p 0.0014, stddev_robot_p 0.0013, missing_ball_detections 0.05, missing_robot_detections 0.02,
# camera_overlap 1 (past each axis), camera_position_error 0.1, object_position_offset 0.02
ERFORCE_REALISTIC = CameraRealism("erforce", shared_world_noise=False, ball_noise_m=0.0014, robot_noise_m=0.0013,
                                  missing_ball_prob=0.05, missing_robot_prob=0.02, overlap_m=2.0 * 1.0,
                                  position_error_m=0.1, object_offset_m=0.02)
CAMERA_MODELS = {m.name: m for m in (BENCH_CAMERAS, ERFORCE_REALISTIC)}
PLANT_CAMERAS = CAMERA_MODELS[_PLANT["camera_model"]]  # the plant's cameras unless its camera_model says otherwise


@dataclass(frozen=True)
class SimCamera:
    """A camera seeing the ground points in a rectangle, standing above ``nadir_m`` (None: the rectangle's centre)."""

    camera_id: int
    x_range_m: tuple[float, float]
    y_range_m: tuple[float, float]
    extra_latency_s: float
    nadir_m: tuple[float, float] | None = None

    @property
    def nadir_xy_m(self) -> tuple[float, float]:
        if self.nadir_m is not None:
            return self.nadir_m
        return 0.5 * sum(self.x_range_m), 0.5 * sum(self.y_range_m)

    def sees(self, x: float, y: float) -> bool:
        return self.x_range_m[0] <= x <= self.x_range_m[1] and self.y_range_m[0] <= y <= self.y_range_m[1]


def ground_point(x_m: float, y_m: float, z_m: float, camera_m: tuple[float, float, float]) -> tuple[float, float]:
    """Where the camera at ``camera_m`` = (cx, cy, cz) sees a ball at height ``z_m`` on the ground:
    ``c + (p - c) cz / (cz - z)`` (heights above the resting ball's centre; the ball below the camera)."""
    if z_m == 0.0:  # on the ground: exactly where it is
        return x_m, y_m
    cx, cy, cz = camera_m
    if not 0.0 <= z_m < cz:
        raise ValueError(f"ground_point: ball height {z_m!r} m must be in [0, camera height {cz!r} m)")
    s = cz / (cz - z_m)
    return cx + (x_m - cx) * s, cy + (y_m - cy) * s


def quadrant_cameras(field: FieldConfig, overlap_m: float = QUADRANT_OVERLAP_M,
                     extra_latencies_s: tuple[float, ...] = (0.0, 0.002, 0.001, 0.003)) -> tuple[SimCamera, ...]:
    """Four cameras, one per quadrant of the area inside the walls, overlapping by ``overlap_m`` across the axes;
    each stands above the centre of its rectangle at QUADRANT_OVERLAP_M whatever ``overlap_m`` (a wider overlap
    widens what a camera reports, not where it hangs)."""
    hx, hy = field.wall_half_length_m, field.wall_half_width_m

    def rectangles(overlap: float):
        h = 0.5 * overlap
        xs = ((-hx, h), (-h, hx))
        ys = ((-h, hy), (-hy, h))
        return [(x, y) for y in ys for x in xs]

    cams = []
    for i, ((xr, yr), (mx, my)) in enumerate(zip(rectangles(overlap_m), rectangles(QUADRANT_OVERLAP_M), strict=True)):
        cams.append(SimCamera(i, xr, yr, extra_latencies_s[i % len(extra_latencies_s)], (0.5 * sum(mx), 0.5 * sum(my))))
    return tuple(cams)


def field_geometry(field: FieldConfig, cameras: tuple[SimCamera, ...],
                   ball_model: BallModelFromVision | None,
                   chip_model: ChipModelFromVision | None = None) -> FieldGeometry:
    """What SSL-Vision's geometry packet says of ``field`` seen by ``cameras``, each above its nadir at
    CAMERA_HEIGHT_M (the goal's size as the league's divisions have it), and of the ball."""
    return FieldGeometry(
        length_m=field.length_m, width_m=field.width_m, boundary_m=field.boundary_m,
        goal_width_m=1.0 if field.length_m < 10.0 else 1.8, goal_depth_m=0.18, ball_model=ball_model,
        cameras=tuple(CameraPose(c.camera_id, *c.nadir_xy_m, CAMERA_HEIGHT_M) for c in cameras),
        chip_model=chip_model,
    )


def chip_model_of(ball: BallParams) -> ChipModelFromVision:
    """The fixed-loss chip model of the simulator's ball, as its geometry packet says it: the floor's restitution;
    a ball chipped without spin that stops slipping at its first bounce keeps 1 / (1 + I / (m r^2)) of its
    horizontal speed, and rolls on from then (1.0)."""
    return ChipModelFromVision(ball.floor_restitution, 1.0 / (1.0 + ball.inertia_factor), 1.0)


CameraDetections = tuple[tuple[BallCandidate, ...], tuple[RobotSighting, ...]]  # one camera's balls and robots


class CameraRig:
    """The simulated cameras as ``realism`` makes them err, and what each reports of a world frame (``detect``): the
    one model of both vision outputs (the SSL-Vision packets, SslCameraSplitter; the plant's ROS frames,
    camera_views.CameraViews), so a preset means the same on either. ``cameras`` are the field's rectangles, each
    seeing the ground points its projecting camera gives; the geometry reports them at their nominal places
    (``reported_cameras``), the projection uses where they stand (``projecting_cameras``). Seeded: runs repeat."""

    def __init__(self, cameras: tuple[SimCamera, ...], field: FieldConfig, realism: CameraRealism = PLANT_CAMERAS,
                 seed: int = _PLANT["seed"], ball_model: BallModelFromVision | None = None,
                 chip_model: ChipModelFromVision | None = None) -> None:
        self.cameras = cameras
        self.realism = realism
        self._rng = random.Random(seed)
        self.geometry = field_geometry(field, cameras, ball_model, chip_model)
        self.reported_cameras = tuple((p.camera_id, p.x_m, p.y_m, p.z_m) for p in self.geometry.cameras)
        self.projecting_cameras = tuple(realism.projecting_camera(pose) for pose in self.geometry.cameras)
        self._offsets = tuple(realism.object_offset(c) for c in self.projecting_cameras)

    @classmethod
    def quadrants(cls, field: FieldConfig, realism: CameraRealism = PLANT_CAMERAS, **kwargs) -> CameraRig:
        """Four quadrant cameras overlapping as ``realism`` says."""
        return cls(quadrant_cameras(field, realism.overlap_m), field, realism, **kwargs)

    def _missed(self, prob: float) -> bool:
        return prob > 0.0 and self._rng.random() < prob  # no draw at 0: the shared model's noise stays as it was

    def detect(self, frame: VisionFrame) -> tuple[CameraDetections, ...]:
        """Each camera's (balls, robots) of ``frame``, in the order of ``cameras``: a ball where the projecting
        camera's ray through it meets the ground, when that point is in the camera's rectangle and the ball below
        the camera; a robot when it stands in the rectangle; each unless missed, with the camera's own noise per
        axis and its object offset."""
        out = []
        r, gauss = self.realism, self._rng.gauss
        for cam, projector, (ox, oy) in zip(self.cameras, self.projecting_cameras, self._offsets, strict=True):
            balls = []
            for b in frame.balls:
                if b.z >= projector[2]:  # as high as the camera: not in its image
                    continue
                x, y = ground_point(b.x, b.y, b.z, projector)
                if cam.sees(x, y) and not self._missed(r.missing_ball_prob):
                    balls.append(BallCandidate(x + gauss(0.0, r.ball_noise_m) + ox,
                                               y + gauss(0.0, r.ball_noise_m) + oy, 0.9))
            robots = tuple(
                RobotSighting(d.team, d.robot_id, d.x + gauss(0.0, r.robot_noise_m) + ox,
                              d.y + gauss(0.0, r.robot_noise_m) + oy, d.theta, 1.0)
                for d in frame.robots if cam.sees(d.x, d.y) and not self._missed(r.missing_robot_prob)
            )
            out.append((tuple(balls), robots))
        return tuple(out)


class SslCameraSplitter:
    """World vision frames -> per-camera SSL datagrams with release times (world clock); each robot in its
    team's colour, as the world has it (PlantSetup.our_color). What each camera sees is a CameraRig's, built
    from ``cameras``, ``field``, ``realism`` and ``seed`` (or shared with the ROS output: ``on_rig``); the frames
    should come from ``realism.world_vision``'s VisionSystem."""

    def __init__(self, cameras: tuple[SimCamera, ...], field: FieldConfig, ball_model: BallModelFromVision | None,
                 latency_s: float = 0.015, realism: CameraRealism = BENCH_CAMERAS,
                 clock_offset_s: float = 0.0, seed: int = _PLANT["seed"],
                 chip_model: ChipModelFromVision | None = None) -> None:
        self._take(CameraRig(cameras, field, realism, seed, ball_model, chip_model), latency_s, clock_offset_s)

    @classmethod
    def on_rig(cls, rig: CameraRig, latency_s: float, clock_offset_s: float = 0.0) -> SslCameraSplitter:
        """The packets of ``rig``'s cameras (its geometry, its detections)."""
        splitter = cls.__new__(cls)
        splitter._take(rig, latency_s, clock_offset_s)
        return splitter

    def _take(self, rig: CameraRig, latency_s: float, clock_offset_s: float) -> None:
        self.rig = rig
        self.cameras, self.realism = rig.cameras, rig.realism
        self.geometry, self.projecting_cameras = rig.geometry, rig.projecting_cameras
        self.latency_s = latency_s
        self.clock_offset_s = clock_offset_s
        self._frame_numbers = [0] * len(self.cameras)

    @classmethod
    def quadrants(cls, field: FieldConfig, ball_model: BallModelFromVision | None,
                  realism: CameraRealism = BENCH_CAMERAS, **kwargs) -> SslCameraSplitter:
        """Four quadrant cameras overlapping as ``realism`` says."""
        return cls(quadrant_cameras(field, realism.overlap_m), field, ball_model, realism=realism, **kwargs)

    def geometry_packet(self) -> bytes:
        return encode_geometry(self.geometry)

    def packets(self, frame: VisionFrame,
                detections: tuple[CameraDetections, ...] | None = None) -> list[tuple[float, bytes]]:
        """(release time, datagram) per camera for one world frame; the world frame's latency is the base.
        ``detections``: the rig's of this frame when another output took them already (``rig.detect``)."""
        out = []
        detections = self.rig.detect(frame) if detections is None else detections
        t_capture = frame.t_capture_s + self.clock_offset_s
        for k, (cam, (balls, robots)) in enumerate(zip(self.cameras, detections, strict=True)):
            self._frame_numbers[k] += 1
            release = frame.t_capture_s + self.latency_s + cam.extra_latency_s
            packet = CameraFrame(cam.camera_id, self._frame_numbers[k], t_capture,
                                 release + self.clock_offset_s, balls, robots)
            out.append((release, encode_frame(packet)))
        return out


def open_multicast_sender(interface: str = SSL_VISION_INTERFACE, ttl: int = 0) -> socket.socket:
    """A UDP socket sending multicast out of ``interface`` only; TTL 0 keeps it on this host. It is bound to
    ``interface``: unbound, the first send would bind it to every address (0.0.0.0) of the host."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM, socket.IPPROTO_UDP)
    sock.bind((interface, 0))
    sock.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_IF, socket.inet_aton(interface))
    sock.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_TTL, ttl)
    sock.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_LOOP, 1)
    sock.setblocking(False)
    return sock
