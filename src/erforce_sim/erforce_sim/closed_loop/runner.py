"""The plant's setup, and the in-process runner: the whole control loop in one Python process.

``PlantSetup`` describes a scenario (field, robots, plates, which robots have motor
boards, ball, seed, tick period); ``build_world`` turns it into a World. The plant node
builds its world the same way.

``InProcessRunner`` steps the same cores the DDS graph runs, in the same order and with
the same one-tick setpoint delay as the lockstep protocol (erforce_interfaces.lockstep):

    tick k:  sensors(t_k) -> MainBoardLoop.tick -> setpoint(t_k)  (used at tick k+1)
                          -> MotorBoardLoop.tick with setpoint(t_{k-1}) -> duty(t_k)
             world.set_duty(duty(t_k)); world.step(T)

so a lockstep DDS run and an in-process run with the same seed and commands give the
same trajectory, without DDS: for sweeps, tuning and benchmarks. No rclpy import.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from erforce_interfaces.robot_config import FieldConfig, RobotConfig
from erforce_motion.firmware import MainBoardLoop, MotorBoardLoop
from erforce_motion.motor_board import MotorBoardConfig
from erforce_motion.velocity_control import VelocityControlConfig
from erforce_sim.sensors import VisionFrame, VisionParams
from erforce_sim.world import PhysicsParams, RobotSpec, World

PLATES = ("flat", "curved")
OPPONENT_TEAM = "blue"  # our robots are RobotSpec's default team, yellow


@dataclass(frozen=True)
class PlantSetup:
    """A scenario for the plant: what is on the field at t = 0 and how the plant ticks."""

    field_preset: str = "division_b"
    robot_poses: tuple[tuple[float, float, float], ...] = ((-1.0, 0.0, 0.0),)  # x [m], y [m], yaw [rad]
    kicker_plates: tuple[str, ...] = ("curved",)  # one per robot, or one for all
    controlled: tuple[bool, ...] = (True,)  # robots with motor boards; one per robot, or one for all
    ball: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)  # x, y [m], vx, vy [m/s], rolling
    # The second team (blue, ids 0 .. M-1), under the same physics and with motion control; in the
    # world and the runner they come after our robots: index num_robots + j.
    opponent_poses: tuple[tuple[float, float, float], ...] = ()
    control_period_s: float = 0.001
    seed: int = 0
    robot: RobotConfig = field(default_factory=RobotConfig)
    physics: PhysicsParams = field(default_factory=PhysicsParams)
    vision: VisionParams = field(default_factory=VisionParams)

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
    def period_ns(self) -> int:
        return round(self.control_period_s * 1e9)

    def plate(self, i: int) -> str:
        return self.kicker_plates[0 if len(self.kicker_plates) == 1 else i]

    def is_controlled(self, i: int) -> bool:
        return bool(self.controlled[0 if len(self.controlled) == 1 else i])


def build_world(setup: PlantSetup) -> World:
    """The World of a scenario; raises ValueError (naming the body) when something is off the field."""
    specs = [
        RobotSpec(config=setup.robot, x=x, y=y, theta=yaw, robot_id=i, kicker_plate=setup.plate(i))
        for i, (x, y, yaw) in enumerate(setup.robot_poses)
    ] + [
        RobotSpec(config=setup.robot, x=x, y=y, theta=yaw, team=OPPONENT_TEAM, robot_id=j, kicker_plate="curved")
        for j, (x, y, yaw) in enumerate(setup.opponent_poses)
    ]
    world = World(
        FieldConfig.preset(setup.field_preset), specs, None, physics=setup.physics, vision=setup.vision, seed=setup.seed
    )
    x, y, vx, vy = setup.ball
    world.place_ball(x, y, vx, vy)
    return world


class InProcessRunner:
    """Plant + main boards + motor boards of the controlled robots, stepped tick by tick.

    Robots are world indices: ours 0 .. num_robots - 1, then the opponents (all controlled)."""

    def __init__(
        self,
        setup: PlantSetup,
        velocity_config: VelocityControlConfig | None = None,
        motor_config: MotorBoardConfig | None = None,
        command_timeout_s: float = 0.2,
        setpoint_timeout_s: float = 0.1,
    ) -> None:
        self.setup = setup
        self.world = build_world(setup)
        period = setup.control_period_s
        motor_config = motor_config or MotorBoardConfig(loop_period_s=period)
        self.main_boards: dict[int, MainBoardLoop] = {}
        self.motor_boards: dict[int, MotorBoardLoop] = {}
        for i in range(setup.num_robots + setup.num_opponents):
            if i >= setup.num_robots or setup.is_controlled(i):
                self.main_boards[i] = MainBoardLoop(
                    setup.robot, velocity_config or VelocityControlConfig(), period, command_timeout_s
                )
                self.motor_boards[i] = MotorBoardLoop(setup.robot, motor_config, period, setpoint_timeout_s)
        self._previous_setpoint: dict[int, tuple[float, np.ndarray]] = {}
        self.tick_index = 0
        self.vision_listeners: list[Callable[[VisionFrame], None]] = []

    @property
    def t_ns(self) -> int:
        return self.tick_index * self.setup.period_ns

    @property
    def t_s(self) -> float:
        return self.t_ns * 1e-9

    def command(self, robot: int, twist: Sequence[float]) -> None:
        """cmd_vel for a controlled robot: [vx, vy, wz] in its base_link."""
        self.main_boards[robot].command(np.asarray(twist, dtype=float))

    def tick(self) -> None:
        """One control period, exactly as the lockstep DDS graph runs it."""
        t_s = self.t_s
        world = self.world
        for i, main in self.main_boards.items():
            speeds = world.wheel_speeds_radps(i)
            currents = world.motor_currents_a(i)
            setpoint = main.tick(t_s, speeds).copy()
            motor = self.motor_boards[i]
            previous = self._previous_setpoint.get(i)
            if previous is not None:
                motor.set_setpoint(*previous)
            world.set_duty(i, motor.tick(t_s, speeds, currents))
            self._previous_setpoint[i] = (t_s, setpoint)
        world.step(self.setup.control_period_s)
        self.tick_index += 1
        if self.vision_listeners:
            for frame in world.poll_vision():
                for listener in self.vision_listeners:
                    listener(frame)

    def run(self, duration_s: float, every_tick: Callable[[InProcessRunner], None] | None = None) -> None:
        """Run whole ticks for ``duration_s`` of simulated time."""
        for _ in range(round(duration_s / self.setup.control_period_s)):
            if every_tick is not None:
                every_tick(self)
            self.tick()
