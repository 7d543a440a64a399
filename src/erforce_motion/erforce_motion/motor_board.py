"""Motor-board cascade with the thermal current limit, paper Sec. 4.1 / Fig. 3.

Per wheel (all wheels of a robot in one vectorized object):

    speed PID   (wheel speed error [rad/s]      -> desired current i_des [A], limited to +-peak_current_a)
    current PID (current error, i_des as feedforward -> current command i_cmd [A])
    actuator    (i_cmd -> PWM duty in [-limit, limit]):
        'linear':        duty = k * i_cmd                      (the paper's linear factor; k = R/V by default)
        'inverse_model': duty = (R i_cmd + k_e gear w_wheel)/V (the paper's planned inverse DC-motor model)

The current PID knows the PWM limit: its output limits are the currents that the actuator
maps onto +-limit, so its anti-windup works while the thermal limit bites.

Thermal protection exactly as the paper describes it (`ThermalCurrentLimiter`):
the motor current magnitude |i| is averaged over ~10 s; on every loop run in which the
average exceeds 1.3 A the PWM limit becomes |last PWM| - 1 % (of full scale), i.e. it is
lowered again each loop; once the average is at or below 1.3 A the limit rises at
`pwm_recovery_rate_per_s` (fraction of full scale per second) back to 100 %.
The average is an exact boxcar over the last N = round(10 s / loop period) loop samples,
kept in a ring buffer with a running sum; the history before start counts as zero current
(motor at rest), so with a constant 2 A the average is 2 A * k / N after k samples.
The optional 'i2t' mode replaces the boxcar by a first-order filter of i^2 (time constant
= winding thermal time constant) compared with I_cont^2; the PWM rule is the same.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np

from erforce_interfaces.wire.robot_config import RobotConfig
from erforce_motion.pid import AntiWindup, Pid, PidConfig

ActuatorMode = Literal["linear", "inverse_model"]
ThermalMode = Literal["average", "i2t"]


@dataclass(frozen=True)
class MotorBoardConfig:
    """Gains and limits of Fig. 3. None = from RobotConfig.

    Defaults, for a 1 kHz loop on plant_model: the speed PI starts from the
    Chien-Hrones-Reswick 0 % PI of `tuning.run_tuning_experiment()` (kp 1.76 A/(rad/s),
    ki 33.5 A/rad; plain ZN gives kp 4.5, ki 1105, far too aggressive at 1 kHz) and was then
    trimmed empirically, as the paper recommends, to kp 1.5, ki 15 (the PI zero caused
    overshoot): 0 -> 50 rad/s settles in ~40 ms with < 0.5 % overshoot. The current PI
    (kp 0.2, ki 200/s, i.e. ki*dt = 0.2) only corrects the actuator model: one sample of
    delay, and the electrical time constant L/R ~ 0.4 ms is below the loop period.
    """

    speed_kp_a_per_radps: float = 1.5
    speed_ki_a_per_rad: float = 15.0
    speed_kd_as_per_rad: float = 0.0
    speed_derivative_tau_s: float = 0.002
    peak_current_a: float = 8.0
    current_kp: float = 0.2
    current_ki_per_s: float = 200.0
    anti_windup: AntiWindup = "clamp"
    actuator_mode: ActuatorMode = "inverse_model"
    linear_duty_per_a: float | None = None  # default R / V_supply
    thermal_mode: ThermalMode = "average"
    average_window_s: float = 10.0
    loop_period_s: float = 0.001  # sets the boxcar length N
    average_current_limit_a: float | None = None  # default RobotConfig.continuous_current_limit_a
    pwm_decrement: float = 0.01  # 1 % of full scale per loop run while over the limit
    pwm_recovery_rate_per_s: float = 0.2
    i2t_time_constant_s: float | None = None  # default RobotConfig.winding_thermal_time_constant_s

    def __post_init__(self) -> None:
        for name in (
            "speed_kp_a_per_radps", "peak_current_a", "current_kp", "average_window_s", "loop_period_s",
            "pwm_decrement", "pwm_recovery_rate_per_s", "linear_duty_per_a", "average_current_limit_a",
            "i2t_time_constant_s",
        ):
            v = getattr(self, name)
            if v is None:
                continue
            if not (math.isfinite(v) and v > 0.0):
                raise ValueError(f"{name}: must be finite and > 0, got {v!r}")
        for name in ("speed_ki_a_per_rad", "speed_kd_as_per_rad", "speed_derivative_tau_s", "current_ki_per_s"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0.0):
                raise ValueError(f"{name}: must be finite and >= 0, got {v!r}")
        if self.actuator_mode not in ("linear", "inverse_model"):
            raise ValueError(f"actuator_mode: 'linear' or 'inverse_model', got {self.actuator_mode!r}")
        if self.thermal_mode not in ("average", "i2t"):
            raise ValueError(f"thermal_mode: 'average' or 'i2t', got {self.thermal_mode!r}")
        if self.pwm_decrement > 1.0:
            raise ValueError(f"pwm_decrement: must be <= 1, got {self.pwm_decrement}")
        if self.average_window_s < self.loop_period_s:
            raise ValueError("average_window_s must be >= loop_period_s")


class ThermalCurrentLimiter:
    """The paper's PWM limit from the ~10 s average current (see module docstring).

    One ``update`` per loop run of ``loop_period_s`` (the one tick length it knows):

    >>> limiter = ThermalCurrentLimiter(1, current_limit_a=1.3, window_s=0.01, loop_period_s=0.001)
    >>> for _ in range(10):  # 2 A for 10 ms: the 10 ms average reaches the limit
    ...     limit = limiter.update(np.array([2.0]), last_duty=np.array([0.5]))
    >>> limit.round(2).tolist()  # lowered below the last duty by pwm_decrement
    [0.49]
    """

    def __init__(
        self,
        n_wheels: int,
        current_limit_a: float,
        window_s: float = 10.0,
        loop_period_s: float = 0.001,
        pwm_decrement: float = 0.01,
        recovery_rate_per_s: float = 0.2,
        mode: ThermalMode = "average",
        i2t_time_constant_s: float = 29.0,
    ) -> None:
        for name, v in (("current_limit_a", current_limit_a), ("window_s", window_s),
                        ("loop_period_s", loop_period_s), ("pwm_decrement", pwm_decrement),
                        ("recovery_rate_per_s", recovery_rate_per_s),
                        ("i2t_time_constant_s", i2t_time_constant_s)):
            if not (math.isfinite(v) and v > 0.0):
                raise ValueError(f"{name}: must be finite and > 0, got {v!r}")
        if mode not in ("average", "i2t"):
            raise ValueError(f"mode: 'average' or 'i2t', got {mode!r}")
        if n_wheels < 1:
            raise ValueError(f"n_wheels: must be >= 1, got {n_wheels}")
        self.n_wheels = n_wheels
        self.current_limit_a = float(current_limit_a)
        self.loop_period_s = float(loop_period_s)
        self.window_samples = max(1, round(window_s / loop_period_s))
        self.pwm_decrement = float(pwm_decrement)
        self.recovery_rate_per_s = float(recovery_rate_per_s)
        self.mode = mode
        self.i2t_time_constant_s = float(i2t_time_constant_s)
        self._ring = np.zeros((self.window_samples, n_wheels))
        self._index = 0
        self._sum = np.zeros(n_wheels)
        self._i2 = np.zeros(n_wheels)  # filtered i^2 in 'i2t' mode
        self.pwm_limit = np.ones(n_wheels)
        self._at_full = True
        self.over_limit = np.zeros(n_wheels, dtype=bool)

    @property
    def average_current_a(self) -> np.ndarray:
        """Boxcar mean of |i| over the window ('average'), or sqrt of the filtered i^2 ('i2t')."""
        if self.mode == "i2t":
            return np.sqrt(self._i2)
        return self._sum / self.window_samples

    def update(self, measured_current_a, last_duty) -> np.ndarray:
        """Feed one loop sample; returns the PWM limit in [0, 1] for this loop run (a view, do not keep)."""
        dt_s = self.loop_period_s
        a = np.abs(measured_current_a)
        if self.mode == "average":
            k = self._index
            self._sum += a - self._ring[k]
            self._ring[k] = a
            k += 1
            if k == self.window_samples:
                k = 0
                self._sum = self._ring.sum(axis=0)  # drop accumulated rounding once per window
            self._index = k
            over = self._sum / self.window_samples > self.current_limit_a
        else:
            self._i2 += (1.0 - math.exp(-dt_s / self.i2t_time_constant_s)) * (a * a - self._i2)
            over = self._i2 > self.current_limit_a * self.current_limit_a
        self.over_limit = over
        if over.any():
            lowered = np.maximum(np.abs(last_duty) - self.pwm_decrement, 0.0)
            raised = np.minimum(self.pwm_limit + self.recovery_rate_per_s * dt_s, 1.0)
            self.pwm_limit = np.where(over, lowered, raised)
            self._at_full = False
        elif not self._at_full:  # skipped in the common case: nothing to raise
            self.pwm_limit = np.minimum(self.pwm_limit + self.recovery_rate_per_s * dt_s, 1.0)
            self._at_full = bool((self.pwm_limit >= 1.0).all())
        return self.pwm_limit


@dataclass(frozen=True)
class MotorBoardStatus:
    """Per-wheel flags and signals after the last step."""

    duty: np.ndarray
    desired_current_a: np.ndarray
    current_command_a: np.ndarray
    pwm_limit: np.ndarray
    average_current_a: np.ndarray
    saturated: np.ndarray  # speed loop at +-peak current, or duty at the PWM limit
    limit_active: np.ndarray  # thermal PWM limit below 100 %


class MotorBoard:
    """Fig. 3 for all wheels of one robot: step(speed setpoints, speeds, currents, dt) -> PWM duties."""

    def __init__(self, config: MotorBoardConfig | None = None, robot: RobotConfig | None = None,
                 n_wheels: int | None = None) -> None:
        self.config = c = config if config is not None else MotorBoardConfig()
        self.robot = r = robot if robot is not None else RobotConfig()
        n = self.n_wheels = n_wheels if n_wheels is not None else r.num_wheels
        self._speed_pid = Pid(PidConfig(
            kp=c.speed_kp_a_per_radps, ki=c.speed_ki_a_per_rad, kd=c.speed_kd_as_per_rad,
            derivative_filter_tau_s=c.speed_derivative_tau_s,
            output_min=-c.peak_current_a, output_max=c.peak_current_a,
            anti_windup=c.anti_windup, n_channels=n,
        ))
        self._current_pid = Pid(PidConfig(
            kp=c.current_kp, ki=c.current_ki_per_s, anti_windup=c.anti_windup, n_channels=n,
        ))
        self.thermal = ThermalCurrentLimiter(
            n,
            c.average_current_limit_a if c.average_current_limit_a is not None else r.continuous_current_limit_a,
            window_s=c.average_window_s,
            loop_period_s=c.loop_period_s,
            pwm_decrement=c.pwm_decrement,
            recovery_rate_per_s=c.pwm_recovery_rate_per_s,
            mode=c.thermal_mode,
            i2t_time_constant_s=(c.i2t_time_constant_s if c.i2t_time_constant_s is not None
                                 else r.winding_thermal_time_constant_s),
        )
        self._inverse = c.actuator_mode == "inverse_model"
        self._k_lin = c.linear_duty_per_a if c.linear_duty_per_a is not None else (
            r.motor_resistance_ohm / r.supply_voltage_v)
        self._r_over_v = r.motor_resistance_ohm / r.supply_voltage_v
        self._v_over_r = r.supply_voltage_v / r.motor_resistance_ohm
        # back-EMF voltage per wheel rad/s, as a duty fraction
        self._emf_duty_per_radps = r.motor_torque_constant_nm_per_a * r.gear_ratio / r.supply_voltage_v
        self._duty = np.zeros(n)
        self._i_des = np.zeros(n)
        self._i_cmd = np.zeros(n)

    def actuator(self, current_command_a, wheel_speed_radps) -> np.ndarray:
        """Desired current -> unclipped PWM duty, in the configured mode."""
        if self._inverse:
            return self._r_over_v * np.asarray(current_command_a) + self._emf_duty_per_radps * np.asarray(
                wheel_speed_radps)
        return self._k_lin * np.asarray(current_command_a)

    def step(self, speed_setpoint_radps, measured_speed_radps, measured_current_a, dt_s: float) -> np.ndarray:
        """One loop run; returns the PWM duty per wheel in [-1, 1] (new array)."""
        if not (0.0 < dt_s < math.inf):
            raise ValueError(f"dt_s: must be finite and > 0, got {dt_s!r}")
        n = self.n_wheels
        sp = np.asarray(speed_setpoint_radps, dtype=float)
        w = np.asarray(measured_speed_radps, dtype=float)
        i_meas = np.asarray(measured_current_a, dtype=float)
        if sp.shape != (n,) or w.shape != (n,) or i_meas.shape != (n,):
            raise ValueError(
                f"need {n} values each, got shapes {sp.shape}, {w.shape}, {i_meas.shape}")
        # Finite checks before any state changes: the current here, setpoint and speed inside
        # the speed PID (which raises before it changes its state).
        if not np.isfinite(i_meas).all():
            raise ValueError(f"measured_current_a: must be finite, got {i_meas!r}")
        i_des = self._speed_pid.step(sp, w, dt_s)
        limit = self.thermal.update(i_meas, self._duty)
        if self._inverse:
            emf = self._emf_duty_per_radps * w
            i_hi = (limit - emf) * self._v_over_r
            i_lo = (-limit - emf) * self._v_over_r
        else:
            i_hi = limit / self._k_lin
            i_lo = -i_hi
        i_cmd = self._current_pid.step(i_des, i_meas, dt_s, i_des, i_lo, i_hi)
        if self._inverse:
            duty = self._r_over_v * i_cmd + emf
        else:
            duty = self._k_lin * i_cmd
        np.clip(duty, -limit, limit, out=duty)  # only rounding can leave the range here
        self._duty = duty
        self._i_des = i_des
        self._i_cmd = i_cmd
        return duty.copy()

    def reset(self) -> None:
        """Controllers back to rest (the thermal history is kept: the motor is still warm)."""
        self._speed_pid.reset()
        self._current_pid.reset()
        self._duty = np.zeros(self.n_wheels)
        self._i_des = np.zeros(self.n_wheels)
        self._i_cmd = np.zeros(self.n_wheels)

    @property
    def saturated(self) -> np.ndarray:
        """Per wheel: speed loop at +-peak current, or duty at the PWM limit (feed to the velocity loop)."""
        return self._speed_pid.saturated | (np.abs(self._duty) >= self.thermal.pwm_limit - 1e-12)

    @property
    def status(self) -> MotorBoardStatus:
        limit = self.thermal.pwm_limit.copy()
        return MotorBoardStatus(
            duty=self._duty.copy(),
            desired_current_a=self._i_des.copy(),
            current_command_a=self._i_cmd.copy(),
            pwm_limit=limit,
            average_current_a=self.thermal.average_current_a,
            saturated=self.saturated,
            limit_active=limit < 1.0,
        )
