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

from collections.abc import Callable, Sequence

import numpy as np

from erforce_motion.firmware import MainBoardLoop, MotorBoardLoop
from erforce_motion.motor_board import MotorBoardConfig
from erforce_motion.velocity_control import VelocityControlConfig
from erforce_sim.sensors import VisionFrame
from erforce_sim.world import PlantSetup, build_world


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
