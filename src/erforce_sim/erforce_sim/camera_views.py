"""The plant's ROS vision (``vision_output`` ros) as its cameras see the world: which camera took the ball where.

The cameras are the plant's SSL cameras, one ``ssl_cameras.CameraRig`` (its layout at the places ``field_geometry``
gives them in the SSL geometry, its ``CameraRealism``), so both outputs have one camera model: what each camera
reports of a world frame is the rig's ``detect``, the SSL-Vision packets' and these views' alike. The camera whose
SSL frame would arrive first (the least extra latency) and reports the ball takes it, as the SSL bridge takes a
capture's ball from the first camera that brings it; the others' views are sightings. Each robot is where the first
camera that reports it puts it (the ROS path has one robot set per world frame). ``/vision/robots`` carries each
view with its camera's reported position (docs/decisions/0035), so a chip detector reads a ball in the air on
either world.

A realism with a per-camera object offset is refused: on the SSL path the bridge's camera alignment takes the
offsets off (camera_alignment), the ROS path has no such stage and one robot set per world frame to learn them from.

No rclpy import.
"""

from __future__ import annotations

from dataclasses import dataclass

from erforce_interfaces.runtime.param_schema import schema_defaults
from erforce_interfaces.wire.robot_config import FieldConfig
from erforce_sim.sensors import RobotDetection, VisionFrame
from erforce_sim.ssl_cameras import PLANT_CAMERAS, CameraDetections, CameraRealism, CameraRig

_PLANT = schema_defaults("erforce_sim", "plant")


@dataclass(frozen=True)
class BallView:
    """One camera's view of the ball: ``camera`` (camera_id, x, y, z) its reported position in ``field`` [m], as the
    frame's camera point carries it; x_m, y_m where it saw the ball on the ground [m]."""

    camera: tuple[int, float, float, float]
    x_m: float
    y_m: float


@dataclass(frozen=True)
class FrameViews:
    """A world frame as the ROS path publishes it: ``balls`` the ball's views, the one that takes it first (empty:
    no camera reports it); ``robots`` each robot once, as the first camera that reports it sees it."""

    balls: tuple[BallView, ...]
    robots: tuple[RobotDetection, ...]


class CameraViews:
    """Per world frame, the views of the rig's cameras (module docstring)."""

    def __init__(self, rig: CameraRig) -> None:
        r = rig.realism
        if r.object_offset_m > 0.0:
            raise ValueError(f"CameraViews: camera model {r.name!r} has a per-camera object offset "
                             f"({r.object_offset_m:g} m) that only the SSL bridge's camera alignment takes off; the "
                             "ROS vision has no alignment: use a model without it, or the SSL vision")
        self.rig = rig
        by_latency = sorted(range(len(rig.cameras)), key=lambda k: rig.cameras[k].extra_latency_s)  # stable: by id
        self._order = tuple(by_latency)

    @classmethod
    def quadrants(cls, field: FieldConfig, realism: CameraRealism = PLANT_CAMERAS,
                  seed: int = _PLANT["seed"]) -> CameraViews:
        """The plant's four quadrant cameras as ``realism`` makes them err."""
        return cls(CameraRig.quadrants(field, realism, seed=seed))

    def frame_views(self, frame: VisionFrame,
                    detections: tuple[CameraDetections, ...] | None = None) -> FrameViews:
        """``frame`` as the cameras report it; ``detections``: the rig's of this frame when the SSL output took them
        already (``rig.detect``), so both outputs show one camera model's one draw."""
        detections = self.rig.detect(frame) if detections is None else detections
        reported = self.rig.reported_cameras
        balls = tuple(BallView(reported[k], b.x_m, b.y_m) for k in self._order for b in detections[k][0][:1])
        seen = {}
        for k in self._order:
            for s in detections[k][1]:
                seen.setdefault((s.team, s.robot_id), s)
        robots = tuple(RobotDetection(d.team, d.robot_id, s.x_m, s.y_m, d.theta)
                       for d in frame.robots if (s := seen.get((d.team, d.robot_id))) is not None)
        return FrameViews(balls, robots)
