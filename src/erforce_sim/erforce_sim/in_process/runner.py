"""The plant's setup, and the in-process runner: the whole control loop in one Python process.

``PlantSetup`` describes a scenario (field, robots, plates, which robots have motor
boards, ball, seed, tick period); ``build_world`` turns it into a World. The plant node
builds its world the same way.

``InProcessRunner`` steps the same cores the DDS graph runs, in the same order and with
the same one-tick setpoint delay as the lockstep protocol (erforce_interfaces.runtime.lockstep):

    tick k:  sensors(t_k) -> main board -> setpoint(t_k)  (used at tick k+1)
                          -> motor boards with setpoint(t_{k-1}) -> duty(t_k)
             world.set_duty(duty(t_k)); world.step(T)

so a lockstep DDS run and an in-process run with the same seed and commands give the
same trajectory, without DDS: for sweeps, tuning and benchmarks. The firmware of all
controlled robots is one erforce_motion.firmware.TeamFirmware (the per-robot loops'
numbers, one call per tick), and the world steps its robots together. No rclpy import.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from erforce_interfaces.runtime.param_schema import schema_defaults
from erforce_motion.firmware import TeamFirmware
from erforce_motion.motor_board import MotorBoardConfig
from erforce_motion.velocity_control import VelocityControlConfig
from erforce_sim.plant_setup import PlantSetup, build_world
from erforce_sim.sensors import VisionFrame


class InProcessRunner:
    """Plant + main boards + motor boards of the controlled robots, stepped tick by tick.

    Robots are world indices: ours 0 .. num_robots - 1, then the opponents (all controlled)."""

    def __init__(
        self,
        setup: PlantSetup,
        velocity_config: VelocityControlConfig | None = None,
        motor_config: MotorBoardConfig | None = None,
        command_timeout_s: float = schema_defaults("erforce_motion", "velocity_controller")["command_timeout_s"],
        setpoint_timeout_s: float = schema_defaults("erforce_motion", "motor_boards")["setpoint_timeout_s"],
    ) -> None:
        self.setup = setup
        self.world = build_world(setup)
        period = setup.control_period_s
        motor_config = motor_config or MotorBoardConfig(loop_period_s=period)
        # world indices of the robots with firmware; firmware row r is robot controlled[r]
        self.controlled = np.array([i for i in range(setup.num_robots + setup.num_opponents)
                                    if i >= setup.num_robots or setup.is_controlled(i)], dtype=np.int64)
        self._row = {int(i): r for r, i in enumerate(self.controlled)}
        self.firmware = TeamFirmware(
            len(self.controlled), setup.robot, velocity_config or VelocityControlConfig(), motor_config, period,
            period, command_timeout_s, setpoint_timeout_s) if len(self.controlled) else None
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
        if robot not in self._row:
            raise KeyError(f"robot {robot} has no motion control in this setup")
        self.firmware.command(self._row[robot], np.asarray(twist, dtype=float))

    def firmware_row(self, robot: int) -> int:
        """The row of a controlled robot (world index) in ``firmware``'s arrays."""
        return self._row[robot]

    def tick(self) -> None:
        """One control period, exactly as the lockstep DDS graph runs it."""
        world = self.world
        if self.firmware is not None:
            speeds, currents = world.wheel_sensors(self.controlled)
            world.set_duties(self.controlled, self.firmware.tick(self.t_s, speeds, currents))
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
