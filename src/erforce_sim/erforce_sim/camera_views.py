"""The plant's ROS vision (``vision_output`` ros) as its cameras see the ball: which camera took it where.

The cameras are the plant's SSL cameras (ssl_cameras: ``quadrant_cameras`` at the places ``field_geometry`` gives
them in the SSL geometry), so both outputs have one camera layout. Each camera sees a world frame's ball where its
ray through the ball meets the ground (``ground_point``), when that point lies in its rectangle, with its own noise
(``CAMERA_NOISE_M``) on top of the world frame's, as the SSL cameras do. The camera whose SSL frame would arrive
first (the least extra latency) takes the ball, as the SSL bridge takes a capture's ball from the first camera
that brings it; the others' views are sightings. ``/vision/robots`` carries each view with its camera's position
(docs/decisions/0035), so a chip detector reads a ball in the air on either world.

No rclpy import.
"""

from __future__ import annotations

import random
from dataclasses import dataclass

from erforce_interfaces.runtime.param_schema import schema_defaults
from erforce_interfaces.wire.robot_config import FieldConfig
from erforce_sim.sensors import BallDetection
from erforce_sim.ssl_cameras import CAMERA_NOISE_M, SimCamera, field_geometry, ground_point, quadrant_cameras

_PLANT = schema_defaults("erforce_sim", "plant")


@dataclass(frozen=True)
class BallView:
    """One camera's view of the ball: ``camera`` (camera_id, x, y, z) its position in ``field`` [m], as the frame's
    camera point carries it; x_m, y_m where it saw the ball on the ground [m]."""

    camera: tuple[int, float, float, float]
    x_m: float
    y_m: float


class CameraViews:
    """Per world frame's ball, the views of the cameras that see it (module docstring); seeded, so runs repeat."""

    def __init__(self, field: FieldConfig, cameras: tuple[SimCamera, ...] | None = None,
                 camera_noise_m: float = CAMERA_NOISE_M, seed: int = _PLANT["seed"]) -> None:
        cameras = quadrant_cameras(field) if cameras is None else cameras
        poses = field_geometry(field, cameras, None).cameras
        first = sorted(range(len(cameras)), key=lambda k: cameras[k].extra_latency_s)  # stable: by id on a tie
        self.cameras = tuple((cameras[k], (poses[k].camera_id, poses[k].x_m, poses[k].y_m, poses[k].z_m))
                             for k in first)
        self.camera_noise_m = camera_noise_m
        self._rng = random.Random(seed)

    def ball_views(self, ball: BallDetection) -> list[BallView]:
        """The views of ``ball`` of every camera that sees it, the one that takes the ball first; empty when none
        does (its projection outside every camera's rectangle, or the ball as high as the cameras)."""
        views = []
        gauss, noise = self._rng.gauss, self.camera_noise_m
        for cam, camera in self.cameras:
            if ball.z >= camera[3]:  # above the camera's image plane: not in its view
                continue
            x, y = ground_point(ball.x, ball.y, ball.z, camera[1:])
            if cam.sees(x, y):
                views.append(BallView(camera, x + gauss(0.0, noise), y + gauss(0.0, noise)))
        return views
