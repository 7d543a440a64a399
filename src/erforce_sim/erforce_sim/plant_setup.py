"""A scenario for the plant (`PlantSetup`: what is on the field at t = 0 and how the plant ticks) and the
`World` it builds (`build_world`). Shared by the plant node, the in-process runner and the scenes.

No rclpy import.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from erforce_interfaces.runtime.param_schema import schema_defaults
from erforce_interfaces.ssl.ssl_vision import OUR_TEAM_COLOR
from erforce_interfaces.ssl.ssl_vision import TEAMS as SSL_TEAMS
from erforce_interfaces.wire.robot_config import FIELD_PRESET, FieldConfig, RobotConfig
from erforce_sim.ball import BallParams
from erforce_sim.sensors import VisionParams
from erforce_sim.ssl_cameras import PLANT_CAMERAS, CameraRealism
from erforce_sim.world import World
from erforce_sim.world_types import PhysicsParams, RobotSpec

PLATES = ("flat", "curved")
# The in-process runner's tick, when a PlantSetup names none: 1 kHz. Not the lockstep tick over DDS
# (lockstep.TICK_PERIOD_S, the plant node's control_period_s), which the node graph pays per message; the plant
# node always sets its own.
IN_PROCESS_TICK_PERIOD_S = 0.001
_PLANT = schema_defaults("erforce_sim", "plant")


@dataclass(frozen=True)
class PlantSetup:
    """A scenario for the plant: what is on the field at t = 0 and how the plant ticks."""

    field_preset: str = FIELD_PRESET
    robot_poses: tuple[tuple[float, float, float], ...] = ((-1.0, 0.0, 0.0),)  # x [m], y [m], yaw [rad]
    kicker_plates: tuple[str, ...] = ("curved",)  # one per robot, or one for all
    controlled: tuple[bool, ...] = (True,)  # robots with motor boards; one per robot, or one for all
    ball: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)  # x, y [m], vx, vy [m/s], rolling
    # The second team (ids 0 .. M-1, the other colour), under the same physics and with motion control; in
    # the world and the runner they come after our robots: index num_robots + j.
    opponent_poses: tuple[tuple[float, float, float], ...] = ()
    our_color: str = OUR_TEAM_COLOR  # SSL team colour of our robots (what vision reports them as)
    control_period_s: float = IN_PROCESS_TICK_PERIOD_S
    seed: int = _PLANT["seed"]
    robot: RobotConfig = field(default_factory=RobotConfig)
    physics: PhysicsParams = field(default_factory=PhysicsParams)
    vision: VisionParams = field(default_factory=VisionParams)
    # how the cameras err (ssl_cameras.CameraRealism); a per-camera model takes the world's frames without the
    # position noise and dropouts of ``vision`` (CameraRealism.world_vision) and draws its own per camera
    cameras: CameraRealism = PLANT_CAMERAS
    ball_params: BallParams = field(default_factory=BallParams)

    def __post_init__(self) -> None:
        FieldConfig.preset(self.field_preset)
        n = len(self.robot_poses)
        if n < 1:
            raise ValueError("robot_poses: need at least one robot")
        for pose in self.robot_poses + self.opponent_poses:
            if len(pose) != 3 or not all(math.isfinite(v) for v in pose):
                raise ValueError(f"robot_poses: each pose is 3 finite values (x, y, yaw), got {pose!r}")
        for name in ("kicker_plates", "controlled"):
            values = getattr(self, name)
            if len(values) not in (1, n):
                raise ValueError(f"{name}: give 1 value or one per robot ({n}), got {len(values)}")
        for plate in self.kicker_plates:
            if plate not in PLATES:
                raise ValueError(f"kicker_plates: each must be one of {PLATES}, got {plate!r}")
        if self.our_color not in SSL_TEAMS:
            raise ValueError(f"our_color: must be one of {SSL_TEAMS}, got {self.our_color!r}")
        if len(self.ball) != 4 or not all(math.isfinite(v) for v in self.ball):
            raise ValueError(f"ball: 4 finite values (x, y, vx, vy), got {self.ball!r}")
        if not (math.isfinite(self.control_period_s) and 1e-4 <= self.control_period_s <= 0.05):
            raise ValueError(f"control_period_s must be in [0.0001, 0.05] s, got {self.control_period_s!r}")
        period_ns = self.control_period_s * 1e9
        if abs(period_ns - round(period_ns)) > 1e-3:
            raise ValueError("control_period_s must be a whole number of nanoseconds")

    @property
    def num_robots(self) -> int:
        return len(self.robot_poses)

    @property
    def num_opponents(self) -> int:
        return len(self.opponent_poses)

    @property
    def opponent_color(self) -> str:
        return SSL_TEAMS[1 - SSL_TEAMS.index(self.our_color)]

    def team_of(self, i: int) -> tuple[bool, int]:
        """(an opponent?, its id in its team) of world index ``i``: ours first, then the opponents."""
        if not 0 <= i < self.num_robots + self.num_opponents:
            raise ValueError(f"robot index must be in [0, {self.num_robots + self.num_opponents - 1}], got {i!r}")
        return (False, i) if i < self.num_robots else (True, i - self.num_robots)

    @property
    def period_ns(self) -> int:
        return round(self.control_period_s * 1e9)

    def plate(self, i: int) -> str:
        return self.kicker_plates[0 if len(self.kicker_plates) == 1 else i]

    def is_controlled(self, i: int) -> bool:
        """Robot ``i`` (world index) has motor boards; the opponents always have."""
        if i >= self.num_robots:
            return True
        return bool(self.controlled[0 if len(self.controlled) == 1 else i])


def build_world(setup: PlantSetup) -> World:
    """The World of a scenario; raises ValueError (naming the body) when something is off the field."""
    specs = [
        RobotSpec(config=setup.robot, x=x, y=y, theta=yaw, team=setup.our_color, robot_id=i,
                  kicker_plate=setup.plate(i))
        for i, (x, y, yaw) in enumerate(setup.robot_poses)
    ] + [
        RobotSpec(config=setup.robot, x=x, y=y, theta=yaw, team=setup.opponent_color, robot_id=j,
                  kicker_plate="curved")
        for j, (x, y, yaw) in enumerate(setup.opponent_poses)
    ]
    world = World(
        FieldConfig.preset(setup.field_preset), specs, None, physics=setup.physics, ball_params=setup.ball_params,
        vision=setup.cameras.world_vision(setup.vision), seed=setup.seed,
    )
    x, y, vx, vy = setup.ball
    world.place_ball(x, y, vx, vy)
    return world
