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

Written once, as compiled kernels on the rows (robots) of (robots, wheels) arrays (``thermal_update``,
``motor_board_step``): ``ThermalCurrentLimiter`` and ``MotorBoard`` hold the state of ``n_robots``
robots, and firmware.py's loops call the same kernels for one robot or a team.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np

from erforce_interfaces.runtime.numba_support import compiled_for, numba
from erforce_interfaces.runtime.param_schema import schema_defaults
from erforce_interfaces.wire.robot_config import RobotConfig
from erforce_motion.pid import DEFAULT_ANTI_WINDUP, AntiWindup, PidConfig, PidState, pid_reset, pid_step, pid_tables

_DEFAULTS = schema_defaults("erforce_motion", "motor_boards")

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

    speed_kp_a_per_radps: float = _DEFAULTS["speed_kp_a_per_radps"]
    speed_ki_a_per_rad: float = _DEFAULTS["speed_ki_a_per_rad"]
    speed_kd_as_per_rad: float = _DEFAULTS["speed_kd_as_per_rad"]
    speed_derivative_tau_s: float = _DEFAULTS["speed_derivative_tau_s"]
    peak_current_a: float = _DEFAULTS["peak_current_a"]
    current_kp: float = _DEFAULTS["current_kp"]
    current_ki_per_s: float = _DEFAULTS["current_ki_per_s"]
    anti_windup: AntiWindup = DEFAULT_ANTI_WINDUP
    actuator_mode: ActuatorMode = _DEFAULTS["actuator_mode"]
    linear_duty_per_a: float | None = None  # default R / V_supply
    thermal_mode: ThermalMode = _DEFAULTS["thermal_mode"]
    average_window_s: float = _DEFAULTS["average_window_s"]
    loop_period_s: float = 0.001  # sets the boxcar length N
    average_current_limit_a: float | None = None  # default RobotConfig.continuous_current_limit_a
    pwm_decrement: float = _DEFAULTS["pwm_decrement"]  # 1 % of full scale per loop run while over the limit
    pwm_recovery_rate_per_s: float = _DEFAULTS["pwm_recovery_rate_per_s"]
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

    ``pwm_limits`` and ``over_limits`` hold ``n_robots`` rows; ``update``, ``pwm_limit``, ``over_limit``
    and ``average_current_a`` are robot 0.
    """

    def __init__(
        self,
        n_wheels: int,
        current_limit_a: float,
        window_s: float = 10.0,
        loop_period_s: float = 0.001,
        pwm_decrement: float = _DEFAULTS["pwm_decrement"],
        recovery_rate_per_s: float = _DEFAULTS["pwm_recovery_rate_per_s"],
        mode: ThermalMode = "average",
        i2t_time_constant_s: float = 29.0,
        n_robots: int = 1,
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
        self.n_wheels, self.mode = n_wheels, mode
        self.window_samples = max(1, round(window_s / loop_period_s))
        shape = (n_robots, n_wheels)
        # the boxcar: window_samples x wheels per robot (the one big array; none in 'i2t' mode)
        self._ring = np.zeros((n_robots, 0 if mode == "i2t" else self.window_samples, n_wheels))
        self._ring_index = np.zeros(n_robots, dtype=np.int64)
        # the running boxcar sum, the filtered i^2 ('i2t' mode) and the PWM limits, in one array
        self._values = np.zeros((3, *shape))
        self._sum, self._i2, self.pwm_limits = self._values
        self.pwm_limits[:] = 1.0
        self._at_full = np.ones(n_robots, dtype=np.bool_)
        self.over_limits = np.zeros(shape, dtype=np.bool_)
        self.params = (float(current_limit_a), self.window_samples, float(pwm_decrement), float(recovery_rate_per_s),
                       mode == "i2t", 1.0 - math.exp(-loop_period_s / i2t_time_constant_s), float(loop_period_s))
        self.state = (self._ring, self._ring_index, self._values, self._at_full, self.over_limits)
        self._row = np.zeros(1, dtype=np.int64)
        self._update = compiled_for(thermal_update, self._row, self.params, self.state, np.zeros((1, n_wheels)),
                                    np.zeros((1, n_wheels)))

    @property
    def pwm_limit(self) -> np.ndarray:
        return self.pwm_limits[0]

    @property
    def over_limit(self) -> np.ndarray:
        return self.over_limits[0]

    def average_currents_a(self) -> np.ndarray:
        """Per robot and wheel: the boxcar mean of |i| over the window ('average'), or sqrt of the filtered i^2."""
        return np.sqrt(self._i2) if self.mode == "i2t" else self._sum / self.window_samples

    @property
    def average_current_a(self) -> np.ndarray:
        return self.average_currents_a()[0]

    def update(self, measured_current_a, last_duty) -> np.ndarray:
        """Feed one loop sample; returns the PWM limit in [0, 1] for this loop run (a view, do not keep)."""
        self._update(self._row, self.params, self.state,
                     np.ascontiguousarray(np.abs(measured_current_a), dtype=float).reshape(1, self.n_wheels),
                     np.ascontiguousarray(last_duty, dtype=float).reshape(1, self.n_wheels))
        return self.pwm_limits[0]


@numba.njit(cache=True, error_model="numpy")
def thermal_update(rows, prm, st, current, last_duty):
    """ThermalCurrentLimiter's update for each robot k in rows: one loop sample of its wheels' currents
    current[k] [A] and the last duties last_duty[k]."""
    limit_a, window_n, pwm_dec, recovery, i2t_mode, i2t_alpha, dt = prm
    ring, ring_index, values, at_full, over = st
    ring_sum, i2, pwm_limit = values[0], values[1], values[2]
    n = current.shape[1]
    for k in rows:
        any_over = False
        if i2t_mode:
            for i in range(n):
                i2[k, i] += i2t_alpha * (current[k, i] * current[k, i] - i2[k, i])
                over[k, i] = i2[k, i] > limit_a * limit_a
                any_over = any_over or over[k, i]
        else:
            j = ring_index[k]
            for i in range(n):
                a = abs(current[k, i])
                ring_sum[k, i] += a - ring[k, j, i]
                ring[k, j, i] = a
            j += 1
            if j == window_n:  # drop accumulated rounding once per window
                j = 0
                for i in range(n):
                    s = 0.0
                    for q in range(window_n):
                        s += ring[k, q, i]
                    ring_sum[k, i] = s
            ring_index[k] = j
            for i in range(n):
                over[k, i] = ring_sum[k, i] / window_n > limit_a
                any_over = any_over or over[k, i]
        if any_over:
            for i in range(n):
                if over[k, i]:
                    pwm_limit[k, i] = max(abs(last_duty[k, i]) - pwm_dec, 0.0)
                else:
                    pwm_limit[k, i] = min(pwm_limit[k, i] + recovery * dt, 1.0)
            at_full[k] = False
        elif not at_full[k]:  # skipped in the common case: nothing to raise
            full = True
            for i in range(n):
                pwm_limit[k, i] = min(pwm_limit[k, i] + recovery * dt, 1.0)
                full = full and pwm_limit[k, i] >= 1.0
            at_full[k] = full


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
    """Fig. 3 for all wheels of a robot: step(speed setpoints, speeds, currents, dt) -> PWM duties.

    Holds the state of ``n_robots`` robots (rows of ``duty``, ``desired_current_a``, ``current_command_a``,
    ``thermal``) for ``motor_board_step``; ``step``, ``reset``, ``saturated`` and ``status`` act on robot 0.
    """

    def __init__(self, config: MotorBoardConfig | None = None, robot: RobotConfig | None = None,
                 n_wheels: int | None = None, n_robots: int = 1) -> None:
        self.config = c = config if config is not None else MotorBoardConfig()
        self.robot = r = robot if robot is not None else RobotConfig()
        n = self.n_wheels = n_wheels if n_wheels is not None else r.num_wheels
        speed = pid_tables(PidConfig(
            kp=c.speed_kp_a_per_radps, ki=c.speed_ki_a_per_rad, kd=c.speed_kd_as_per_rad,
            derivative_filter_tau_s=c.speed_derivative_tau_s,
            output_min=-c.peak_current_a, output_max=c.peak_current_a,
            anti_windup=c.anti_windup, n_channels=n,
        ))
        current = pid_tables(PidConfig(kp=c.current_kp, ki=c.current_ki_per_s, anti_windup=c.anti_windup,
                                       n_channels=n))
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
            n_robots=n_robots,
        )
        self._inverse = c.actuator_mode == "inverse_model"
        self._k_lin = c.linear_duty_per_a if c.linear_duty_per_a is not None else (
            r.motor_resistance_ohm / r.supply_voltage_v)
        self._r_over_v = r.motor_resistance_ohm / r.supply_voltage_v
        # back-EMF voltage per wheel rad/s, as a duty fraction
        self._emf_duty_per_radps = r.motor_torque_constant_nm_per_a * r.gear_ratio / r.supply_voltage_v
        actuator = (self._inverse, float(self._k_lin), self._r_over_v,
                    r.supply_voltage_v / r.motor_resistance_ohm, self._emf_duty_per_radps)
        shape = (n_robots, n)
        self.outputs = np.zeros((3, *shape))  # one array: each array a kernel call is passed costs it an unpacking
        self.duty, self.desired_current_a, self.current_command_a = self.outputs
        self.speed_pid, self.current_pid = PidState(n_robots, n), PidState(n_robots, n)
        state = (self.outputs, self.speed_pid.arrays(), self.current_pid.arrays())
        # per robot: 5 scratch rows, then the speed loop's output limits; an integrator hold that is never set
        scratch = np.zeros((7, n_robots, n))
        scratch[5], scratch[6] = speed[0][3], speed[0][4]
        work = (scratch, np.zeros(shape, dtype=np.bool_))
        self.args = (speed, current, self.thermal.params, self.thermal.state, actuator, state, work)
        self._row, self._dt = np.zeros(1, dtype=np.int64), np.zeros(1)
        wheels = np.zeros((1, n))
        self._step = compiled_for(motor_board_step, self._row, self.args, wheels, wheels, wheels, self._dt)
        self._reset = compiled_for(motor_board_reset, 0, self.args)

    def actuator(self, current_command_a, wheel_speed_radps) -> np.ndarray:
        """Desired current -> unclipped PWM duty, in the configured mode (as ``motor_board_step`` maps it)."""
        if self._inverse:
            return self._r_over_v * np.asarray(current_command_a) + self._emf_duty_per_radps * np.asarray(
                wheel_speed_radps)
        return self._k_lin * np.asarray(current_command_a)

    def step(self, speed_setpoint_radps, measured_speed_radps, measured_current_a, dt_s: float) -> np.ndarray:
        """One loop run; returns the PWM duty per wheel in [-1, 1] (new array)."""
        if not (0.0 < dt_s < math.inf):
            raise ValueError(f"dt_s: must be finite and > 0, got {dt_s!r}")
        n = self.n_wheels
        sp = np.ascontiguousarray(speed_setpoint_radps, dtype=float)
        w = np.ascontiguousarray(measured_speed_radps, dtype=float)
        i_meas = np.ascontiguousarray(measured_current_a, dtype=float)
        if sp.shape != (n,) or w.shape != (n,) or i_meas.shape != (n,):
            raise ValueError(
                f"need {n} values each, got shapes {sp.shape}, {w.shape}, {i_meas.shape}")
        if not np.isfinite(i_meas).all():
            raise ValueError(f"measured_current_a: must be finite, got {i_meas!r}")
        self._dt[0] = dt_s
        if not self._step(self._row, self.args, sp[None], w[None], i_meas[None], self._dt):
            raise ValueError(f"speed setpoint and measured speed must be finite, got {sp!r} and {w!r}")
        return self.duty[0].copy()

    def reset(self) -> None:
        """Controllers back to rest (the thermal history is kept: the motor is still warm)."""
        self._reset(0, self.args)

    def saturated_rows(self) -> np.ndarray:
        """Per robot and wheel: speed loop at +-peak current, or duty at the PWM limit (feed to the velocity loop)."""
        return (self.speed_pid.v != self.speed_pid.u) | (np.abs(self.duty) >= self.thermal.pwm_limits - 1e-12)

    @property
    def saturated(self) -> np.ndarray:
        """``saturated_rows`` of robot 0."""
        return self.saturated_rows()[0]

    @property
    def status(self) -> MotorBoardStatus:
        limit = self.thermal.pwm_limit.copy()
        return MotorBoardStatus(
            duty=self.duty[0].copy(),
            desired_current_a=self.desired_current_a[0].copy(),
            current_command_a=self.current_command_a[0].copy(),
            pwm_limit=limit,
            average_current_a=self.thermal.average_current_a,
            saturated=self.saturated,
            limit_active=limit < 1.0,
        )


@numba.njit(cache=True, error_model="numpy")
def motor_board_step(rows, args, sp, w, current, dt):
    """MotorBoard's step for each robot k in rows: wheel speed setpoints sp[k], speeds w[k] and currents
    current[k] -> duty[k], in dt[k].

    Returns False when a robot's speed loop inputs are not finite: that robot goes no further."""
    speed, cur_pid, thermal_prm, thermal, (inverse, k_lin, r_over_v, v_over_r, emf_k), state, work = args
    (outputs, spid, cpid), (scratch, hold) = state, work
    duty, i_des, i_cmd = outputs[0], outputs[1], outputs[2]
    zero, i_lo, i_hi, emf, out = scratch[0], scratch[1], scratch[2], scratch[3], scratch[4]
    speed_lo, speed_hi = scratch[5], scratch[6]
    all_ok = pid_step(rows, speed[0], speed[1], spid, sp, w, dt, zero, speed_lo, speed_hi, hold, out)
    go = rows if all_ok else rows[spid[1][1][rows]]
    n = w.shape[1]
    for k in go:
        for i in range(n):
            i_des[k, i] = out[k, i]
    thermal_update(go, thermal_prm, thermal, current, duty)
    pwm_limit = thermal[2][2]
    for k in go:
        for i in range(n):  # the current loop's output limits are the currents the actuator maps onto +-limit
            lim = pwm_limit[k, i]
            if inverse:
                emf[k, i] = emf_k * w[k, i]
                i_hi[k, i] = (lim - emf[k, i]) * v_over_r
                i_lo[k, i] = (-lim - emf[k, i]) * v_over_r
            else:
                i_hi[k, i] = lim / k_lin
                i_lo[k, i] = -i_hi[k, i]
    pid_step(go, cur_pid[0], cur_pid[1], cpid, i_des, current, dt, i_des, i_lo, i_hi, hold, out)
    for k in go:
        for i in range(n):
            i_cmd[k, i] = out[k, i]
            d = r_over_v * out[k, i] + emf[k, i] if inverse else k_lin * out[k, i]
            lim = pwm_limit[k, i]
            duty[k, i] = min(max(d, -lim), lim)  # only rounding can leave the range here
    return all_ok


@numba.njit(cache=True, error_model="numpy")
def motor_board_reset(k, args):
    """MotorBoard's reset of robot k: controllers and outputs to rest, the thermal history kept."""
    speed, cur_pid, state, zero = args[0], args[1], args[5], args[6][0][0][k]
    outputs, spid, cpid = state
    pid_reset(k, speed[0], speed[1], spid, zero, zero, zero, zero, False, False)
    pid_reset(k, cur_pid[0], cur_pid[1], cpid, zero, zero, zero, zero, False, False)
    outputs[:, k, :] = 0.0
