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
"""

from __future__ import annotations

import random
import socket
from dataclasses import dataclass

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
from erforce_sim.sensors import VisionFrame

_PLANT = schema_defaults("erforce_sim", "plant")

CAMERA_HEIGHT_M = 4.0
CAMERA_NOISE_M = 0.0005  # each camera's own noise on what it sees [m]


@dataclass(frozen=True)
class SimCamera:
    camera_id: int
    x_range_m: tuple[float, float]
    y_range_m: tuple[float, float]
    extra_latency_s: float

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


def quadrant_cameras(field: FieldConfig, overlap_m: float = 0.5,
                     extra_latencies_s: tuple[float, ...] = (0.0, 0.002, 0.001, 0.003)) -> tuple[SimCamera, ...]:
    """Four cameras, one per quadrant of the area inside the walls, overlapping by ``overlap_m`` across the axes."""
    hx, hy, h = field.wall_half_length_m, field.wall_half_width_m, 0.5 * overlap_m
    xs = ((-hx, h), (-h, hx))
    ys = ((-h, hy), (-hy, h))
    cams = []
    for i, (yr, xr) in enumerate((y, x) for y in ys for x in xs):
        cams.append(SimCamera(i, xr, yr, extra_latencies_s[i % len(extra_latencies_s)]))
    return tuple(cams)


def field_geometry(field: FieldConfig, cameras: tuple[SimCamera, ...],
                   ball_model: BallModelFromVision | None,
                   chip_model: ChipModelFromVision | None = None) -> FieldGeometry:
    """What SSL-Vision's geometry packet says of ``field`` seen by ``cameras``, each above the centre of its
    rectangle at CAMERA_HEIGHT_M (the goal's size as the league's divisions have it), and of the ball."""
    return FieldGeometry(
        length_m=field.length_m, width_m=field.width_m, boundary_m=field.boundary_m,
        goal_width_m=1.0 if field.length_m < 10.0 else 1.8, goal_depth_m=0.18, ball_model=ball_model,
        cameras=tuple(CameraPose(c.camera_id, 0.5 * sum(c.x_range_m), 0.5 * sum(c.y_range_m), CAMERA_HEIGHT_M)
                      for c in cameras),
        chip_model=chip_model,
    )


def chip_model_of(ball: BallParams) -> ChipModelFromVision:
    """The fixed-loss chip model of the simulator's ball, as its geometry packet says it: the floor's restitution;
    a ball chipped without spin that stops slipping at its first bounce keeps 1 / (1 + I / (m r^2)) of its
    horizontal speed, and rolls on from then (1.0)."""
    return ChipModelFromVision(ball.floor_restitution, 1.0 / (1.0 + ball.inertia_factor), 1.0)


class SslCameraSplitter:
    """World vision frames -> per-camera SSL datagrams with release times (world clock); each robot in its
    team's colour, as the world has it (PlantSetup.our_color)."""

    def __init__(self, cameras: tuple[SimCamera, ...], field: FieldConfig, ball_model: BallModelFromVision | None,
                 latency_s: float = 0.015, camera_noise_m: float = CAMERA_NOISE_M,
                 clock_offset_s: float = 0.0, seed: int = _PLANT["seed"],
                 chip_model: ChipModelFromVision | None = None) -> None:
        self.cameras = cameras
        self.latency_s = latency_s
        self.camera_noise_m = camera_noise_m
        self.clock_offset_s = clock_offset_s
        self._rng = random.Random(seed)
        self._frame_numbers = [0] * len(cameras)
        self.geometry = field_geometry(field, cameras, ball_model, chip_model)

    def geometry_packet(self) -> bytes:
        return encode_geometry(self.geometry)

    def packets(self, frame: VisionFrame) -> list[tuple[float, bytes]]:
        """(release time, datagram) per camera for one world frame; the world frame's latency is the base."""
        out = []
        gauss, noise = self._rng.gauss, self.camera_noise_m
        t_capture = frame.t_capture_s + self.clock_offset_s
        for k, (cam, pose) in enumerate(zip(self.cameras, self.geometry.cameras, strict=True)):
            seen = (ground_point(b.x, b.y, b.z, (pose.x_m, pose.y_m, pose.z_m)) for b in frame.balls)
            balls = tuple(
                BallCandidate(x + gauss(0.0, noise), y + gauss(0.0, noise), 0.9) for x, y in seen if cam.sees(x, y)
            )
            robots = tuple(
                RobotSighting(r.team, r.robot_id, r.x + gauss(0.0, noise), r.y + gauss(0.0, noise), r.theta, 1.0)
                for r in frame.robots if cam.sees(r.x, r.y)
            )
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
