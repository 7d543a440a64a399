"""Main-board robot velocity controller, paper Sec. 4.1 / Fig. 2.

    desired twist (robot frame, from the AI over radio)
        -> setpoint shaper (speed and acceleration limits that keep the direction of motion)
        -> PID on the twist error, measured twist = forward kinematics of the measured wheel speeds
        -> command twist = [shaped setpoint as feedforward, switchable] + PID output
        -> inverse kinematics -> wheel speed setpoints for the motor boards (Fig. 3).

`feedforward_enabled=False` is the paper's current design (the PID alone produces the
commanded velocity, so it needs its integral); `True` is the paper's "next step": the
shaped setpoint is passed through and the PID only corrects.
`CommandWatchdog` is the pure logic that stops the robot when commands stop arriving.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from erforce_interfaces.robot_config import RobotConfig
from erforce_motion.kinematics import OmniKinematics
from erforce_motion.pid import AntiWindup, Pid, PidConfig


@dataclass(frozen=True)
class VelocityControlConfig:
    """Limits and gains of the main-board loop.

    Defaults (tuned on plant_model at 1 kHz with the default motor boards, bench/bench_motion.py):
    feedforward on, PI kp 1, ki 5/s per axis: the feedforward does the work, the PI only
    corrects. Pass the motor boards' saturation flags to `step` (wheels_saturated) or the
    integrator winds up while the wheels are current-limited. `pid_only()` is the
    feedforward-free design with kp 2, ki 40/s.
    """

    max_speed_mps: float = 4.0
    max_accel_mps2: float = 6.0  # below the traction limit mu*g ~ 7.8 m/s^2
    max_angular_speed_radps: float = 10.0
    max_angular_accel_radps2: float = 60.0
    feedforward_enabled: bool = True
    kp_translation: float = 1.0  # (m/s) per (m/s)
    ki_translation: float = 5.0  # 1/s
    kd_translation: float = 0.0
    kp_rotation: float = 1.0
    ki_rotation: float = 5.0
    kd_rotation: float = 0.0
    derivative_filter_tau_s: float = 0.005
    command_limit_mps: float = 5.0  # PID output (incl. feedforward) per axis
    command_limit_radps: float = 15.0
    anti_windup: AntiWindup = "clamp"

    def __post_init__(self) -> None:
        for name in (
            "max_speed_mps", "max_accel_mps2", "max_angular_speed_radps", "max_angular_accel_radps2",
            "kp_translation", "kp_rotation", "command_limit_mps", "command_limit_radps",
        ):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0.0):
                raise ValueError(f"{name}: must be finite and > 0, got {v!r}")
        for name in (
            "ki_translation", "kd_translation", "ki_rotation", "kd_rotation", "derivative_filter_tau_s",
        ):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0.0):
                raise ValueError(f"{name}: must be finite and >= 0, got {v!r}")
        if not isinstance(self.feedforward_enabled, bool):
            raise ValueError("feedforward_enabled: must be a bool")
        if self.anti_windup not in ("clamp", "back_calculation"):
            raise ValueError(f"anti_windup: 'clamp' or 'back_calculation', got {self.anti_windup!r}")

    @classmethod
    def pid_only(cls, **overrides) -> VelocityControlConfig:
        """The paper's current design (no feedforward) with PI gains tuned for it on plant_model."""
        values = {"feedforward_enabled": False, "kp_translation": 2.0, "ki_translation": 40.0,
                  "kp_rotation": 2.0, "ki_rotation": 40.0}
        values.update(overrides)
        return cls(**values)

    def pid_config(self) -> PidConfig:
        lim = (self.command_limit_mps, self.command_limit_mps, self.command_limit_radps)
        return PidConfig(
            kp=(self.kp_translation, self.kp_translation, self.kp_rotation),
            ki=(self.ki_translation, self.ki_translation, self.ki_rotation),
            kd=(self.kd_translation, self.kd_translation, self.kd_rotation),
            output_min=tuple(-x for x in lim),
            output_max=lim,
            anti_windup=self.anti_windup,
            derivative_filter_tau_s=self.derivative_filter_tau_s,
            n_channels=3,
        )


class SetpointShaper:
    """Speed and acceleration limits on a twist that keep the direction of translation.

    The translational part is limited as a 2-vector: a too fast command is scaled as a
    whole, and the change per step is limited in magnitude (|dv| <= a_max dt), so the
    shaped velocity moves along a straight line toward the target, never per axis.
    The rotation is limited separately.
    """

    def __init__(self, config: VelocityControlConfig) -> None:
        self._v_max = config.max_speed_mps
        self._a_max = config.max_accel_mps2
        self._w_max = config.max_angular_speed_radps
        self._aw_max = config.max_angular_accel_radps2
        self._vx = self._vy = self._wz = 0.0

    @property
    def state(self) -> tuple[float, float, float]:
        return (self._vx, self._vy, self._wz)

    def reset(self, twist=(0.0, 0.0, 0.0)) -> None:
        vx, vy, wz = (float(v) for v in twist)
        if not all(math.isfinite(v) for v in (vx, vy, wz)):
            raise ValueError("reset twist must be finite")
        self._vx, self._vy, self._wz = vx, vy, wz

    def step(self, vx: float, vy: float, wz: float, dt_s: float) -> tuple[float, float, float]:
        speed = math.hypot(vx, vy)
        if speed > self._v_max:
            k = self._v_max / speed
            vx *= k
            vy *= k
        dx = vx - self._vx
        dy = vy - self._vy
        dv = math.hypot(dx, dy)
        dv_max = self._a_max * dt_s
        if dv > dv_max:
            k = dv_max / dv
            dx *= k
            dy *= k
        self._vx += dx
        self._vy += dy
        wz = min(max(wz, -self._w_max), self._w_max)
        dw_max = self._aw_max * dt_s
        self._wz += min(max(wz - self._wz, -dw_max), dw_max)
        return self._vx, self._vy, self._wz


@dataclass(frozen=True)
class VelocityControlStatus:
    shaped_twist: np.ndarray
    measured_twist: np.ndarray
    command_twist: np.ndarray
    saturated: np.ndarray  # per twist axis


class VelocityController:
    """Fig. 2: desired robot twist + measured wheel speeds -> wheel speed setpoints [rad/s]."""

    def __init__(self, robot: RobotConfig | None = None, config: VelocityControlConfig | None = None) -> None:
        self.robot = robot if robot is not None else RobotConfig()
        self.config = config if config is not None else VelocityControlConfig()
        self.kinematics = OmniKinematics.from_robot_config(self.robot)
        self._n = self.kinematics.num_wheels
        self._j = np.array(self.kinematics.wheel_matrix)
        self._f = np.array(self.kinematics.forward_matrix)
        self._shaper = SetpointShaper(self.config)
        self._pid = Pid(self.config.pid_config())
        self._ff = self.config.feedforward_enabled
        self._measured = np.zeros(3)
        self._shaped = np.zeros(3)
        self._command = np.zeros(3)
        self._wheels = np.zeros(self._n)

    def step(self, desired_twist, measured_wheel_speeds_radps, dt_s: float, wheels_saturated=False) -> np.ndarray:
        """One control period; returns the wheel speed setpoints [rad/s] (new array, length n).

        wheels_saturated (bool or per-wheel flags from the motor boards' status) holds the
        twist integrator while any wheel cannot follow, so the outer loop does not wind up.
        """
        if not (0.0 < dt_s < math.inf):
            raise ValueError(f"dt_s: must be finite and > 0, got {dt_s!r}")
        if len(desired_twist) != 3:
            raise ValueError(f"desired_twist: need 3 values (vx, vy, wz), got {len(desired_twist)}")
        vx, vy, wz = float(desired_twist[0]), float(desired_twist[1]), float(desired_twist[2])
        if not math.isfinite(vx + vy + wz):
            raise ValueError(f"desired_twist: must be finite, got {tuple(desired_twist)!r}")
        w = np.asarray(measured_wheel_speeds_radps, dtype=float)
        if w.shape != (self._n,):
            raise ValueError(f"measured_wheel_speeds_radps: need {self._n} values, got shape {w.shape}")
        np.dot(self._f, w, out=self._measured)  # NaN in w surfaces in the PID's finite check
        shaped = self._shaper.step(vx, vy, wz, dt_s)
        self._shaped[0], self._shaped[1], self._shaped[2] = shaped
        hold = bool(np.any(wheels_saturated))
        cmd = self._pid.step(self._shaped, self._measured, dt_s, self._shaped if self._ff else 0.0,
                             hold_integrator=hold)
        self._command = cmd
        return self._j @ cmd

    def reset(self, measured_wheel_speeds_radps=None) -> None:
        """Bumpless (re)start from the measured motion (or from rest when None)."""
        if measured_wheel_speeds_radps is None:
            twist = np.zeros(3)
        else:
            twist = self.kinematics.forward(measured_wheel_speeds_radps)
        self._shaper.reset(twist)
        self._pid.reset(output_hold=twist, measurement=twist, setpoint=twist,
                        feedforward=twist if self._ff else 0.0)
        self._measured[:] = twist
        self._shaped[:] = twist
        self._command = twist.copy()

    @property
    def status(self) -> VelocityControlStatus:
        return VelocityControlStatus(
            shaped_twist=self._shaped.copy(),
            measured_twist=self._measured.copy(),
            command_twist=np.array(self._command, dtype=float),
            saturated=self._pid.status.saturated,
        )


class CommandWatchdog:
    """Stop when commands stop: `expired(now)` is True before the first command and once
    more than `timeout_s` has passed since the last `feed(now)`. Time must not go backwards."""

    def __init__(self, timeout_s: float) -> None:
        if not (math.isfinite(timeout_s) and timeout_s > 0.0):
            raise ValueError(f"timeout_s: must be finite and > 0, got {timeout_s!r}")
        self.timeout_s = float(timeout_s)
        self._last_feed_s: float | None = None
        self._latest_s = -math.inf

    def _check_time(self, now_s: float) -> None:
        if not math.isfinite(now_s):
            raise ValueError(f"now_s: must be finite, got {now_s!r}")
        if now_s < self._latest_s:
            raise ValueError(f"time went backwards: {now_s} < {self._latest_s}")
        self._latest_s = now_s

    def feed(self, now_s: float) -> None:
        self._check_time(now_s)
        self._last_feed_s = now_s

    def expired(self, now_s: float) -> bool:
        self._check_time(now_s)
        return self._last_feed_s is None or now_s - self._last_feed_s > self.timeout_s
