"""What the main board and each motor board run on every sensor tick, around the controllers.

The controllers (velocity_control, motor_board) are pure maths on one control period.
The loops here add what firmware adds: the loop rate (a loop slower than the sensor
ticks holds its last output), the command watchdog, stale-setpoint handling, and a
reset when time goes backwards (a restarted simulator). The ROS nodes and the
in-process runner both drive these loops, so the DDS graph and the in-process
simulation compute the same numbers.
"""

from __future__ import annotations

import math

import numpy as np

from erforce_interfaces.wire.robot_config import RobotConfig
from erforce_motion.motor_board import MotorBoard, MotorBoardConfig
from erforce_motion.velocity_control import CommandWatchdog, VelocityControlConfig, VelocityController

_TICK_TOLERANCE_S = 1e-6


def _check_period(loop_period_s: float) -> float:
    if not (math.isfinite(loop_period_s) and loop_period_s > 0.0):
        raise ValueError(f"loop_period_s must be finite and > 0, got {loop_period_s!r}")
    return float(loop_period_s)


class MainBoardLoop:
    """Fig. 2 on the main board: radio commands in, wheel-speed setpoints out on every tick."""

    def __init__(self, robot: RobotConfig, config: VelocityControlConfig, loop_period_s: float,
                 command_timeout_s: float) -> None:
        self.robot = robot
        self.loop_period_s = _check_period(loop_period_s)
        self.controller = VelocityController(robot, config)
        self.watchdog = CommandWatchdog(command_timeout_s)
        self._command = np.zeros(3)
        self._setpoints = np.zeros(robot.num_wheels)
        self._last_run_s: float | None = None
        self._now_s = -math.inf
        self._feed_at_first_tick = False
        self.notice: str | None = None  # what the last call noticed (for the node's log)

    @property
    def setpoints(self) -> np.ndarray:
        return self._setpoints

    def take_over(self, old: MainBoardLoop) -> None:
        """Continue where ``old`` left off (new parameters): same command, timing and motion, bumpless."""
        self._command = old._command
        self.watchdog = old.watchdog if old.watchdog.timeout_s == self.watchdog.timeout_s else self.watchdog
        self._now_s, self._last_run_s, self._setpoints = old._now_s, old._last_run_s, old._setpoints
        measured = old.controller.status.measured_twist
        self.controller.reset(self.controller.kinematics.inverse(measured))

    def command(self, twist: np.ndarray) -> None:
        """A new desired twist [vx, vy, wz] (robot frame), received at the current robot time."""
        twist = np.asarray(twist, dtype=float)
        if twist.shape != (3,) or not np.all(np.isfinite(twist)):
            raise ValueError(f"twist must be 3 finite values, got {twist!r}")
        self._command = twist
        if math.isfinite(self._now_s):
            self.watchdog.feed(self._now_s)
        else:
            self._feed_at_first_tick = True  # a command sent before the robot's first tick counts

    def stop(self) -> None:
        """Drop the current command (e.g. after a rejected message): decelerate to rest."""
        self._command = np.zeros(3)

    def tick(self, t_s: float, wheel_speeds_radps: np.ndarray) -> np.ndarray:
        """Setpoints to send to the motor boards at sensor tick ``t_s``."""
        self.notice = None
        if t_s < self._now_s:
            self.notice = f"time went backwards ({self._now_s:.6f} -> {t_s:.6f} s): controller reset"
            self.watchdog = CommandWatchdog(self.watchdog.timeout_s)
            self.controller.reset(wheel_speeds_radps)
            self._command = np.zeros(3)
            self._last_run_s = None
        self._now_s = t_s
        if self._feed_at_first_tick:
            self._feed_at_first_tick = False
            self.watchdog.feed(t_s)
        if self._last_run_s is not None and t_s - self._last_run_s < self.loop_period_s - _TICK_TOLERANCE_S:
            return self._setpoints
        dt = self.loop_period_s if self._last_run_s is None else t_s - self._last_run_s
        self._last_run_s = t_s
        desired = self._command
        if self.watchdog.expired(t_s):
            if np.any(desired != 0.0):
                self.notice = f"no command for {self.watchdog.timeout_s:g} s: stopping"
            desired = np.zeros(3)
            self._command = desired
        self._setpoints = self.controller.step(desired, wheel_speeds_radps, dt)
        return self._setpoints


class MotorBoardLoop:
    """Fig. 3 on the motor boards of one robot: setpoints and sensors in, PWM duty out."""

    def __init__(self, robot: RobotConfig, config: MotorBoardConfig, loop_period_s: float,
                 setpoint_timeout_s: float) -> None:
        self.robot = robot
        self.loop_period_s = _check_period(loop_period_s)
        if not (math.isfinite(setpoint_timeout_s) and setpoint_timeout_s > 0.0):
            raise ValueError(f"setpoint_timeout_s must be finite and > 0, got {setpoint_timeout_s!r}")
        self.setpoint_timeout_s = float(setpoint_timeout_s)
        self.board = MotorBoard(config, robot)
        self._duty = np.zeros(robot.num_wheels)
        self._last_run_s: float | None = None
        self._now_s = -math.inf
        self._setpoint = np.zeros(robot.num_wheels)
        self._setpoint_time_s = -math.inf
        self.notice: str | None = None

    @property
    def duty(self) -> np.ndarray:
        return self._duty

    def take_over(self, old: MotorBoardLoop) -> None:
        """Continue where ``old`` left off (new parameters): same setpoint, timing and output."""
        self._duty, self._now_s, self._last_run_s = old._duty, old._now_s, old._last_run_s
        self._setpoint, self._setpoint_time_s = old._setpoint, old._setpoint_time_s

    def set_setpoint(self, t_s: float, setpoint_radps: np.ndarray) -> None:
        setpoint_radps = np.asarray(setpoint_radps, dtype=float)
        if setpoint_radps.shape != (self.robot.num_wheels,) or not np.all(np.isfinite(setpoint_radps)):
            raise ValueError(f"setpoint must be {self.robot.num_wheels} finite values")
        self._setpoint = setpoint_radps
        self._setpoint_time_s = t_s

    def tick(self, t_s: float, wheel_speeds_radps: np.ndarray, currents_a: np.ndarray) -> np.ndarray:
        self.notice = None
        if t_s < self._now_s:
            self.notice = f"time went backwards ({self._now_s:.6f} -> {t_s:.6f} s): motor boards reset"
            self.board.reset()
            self._last_run_s = None
            # the old time line's setpoint is void (and would overwrite this notice with a timeout)
            self._setpoint = np.zeros(self.robot.num_wheels)
            self._setpoint_time_s = -math.inf
        self._now_s = t_s
        if self._last_run_s is not None and t_s - self._last_run_s < self.loop_period_s - _TICK_TOLERANCE_S:
            return self._duty
        dt = self.loop_period_s if self._last_run_s is None else t_s - self._last_run_s
        self._last_run_s = t_s
        setpoint = self._setpoint
        if t_s - self._setpoint_time_s > self.setpoint_timeout_s:
            if np.any(setpoint != 0.0):
                self.notice = f"no setpoint for {self.setpoint_timeout_s:g} s: stopping the wheels"
            setpoint = np.zeros(self.robot.num_wheels)
            self._setpoint = setpoint
        self._duty = self.board.step(setpoint, wheel_speeds_radps, currents_a, dt)
        return self._duty
