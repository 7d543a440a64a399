"""The firmware of many robots at once: main board and motor boards of N robots on (robots, wheels) arrays.

``TeamFirmware`` computes per robot exactly what one ``firmware.MainBoardLoop`` and one
``firmware.MotorBoardLoop`` compute (Fig. 2 and Fig. 3 of the paper: setpoint shaper, twist PID,
slip hold, speed and current PIDs, the thermal PWM limit, the command and setpoint watchdogs, the
loop rate, the reset when time goes backwards), with the main board's setpoint reaching the motor
boards one tick later as in the lockstep protocol (runner.InProcessRunner's order). The per-robot
maths is the same operations in the same order, in one numba-compiled loop over the robots that
ticked (no fastmath); only the sums of the 3x4 kinematics products may round differently from
numpy's BLAS calls, so both agree to ~1e-12 (test/motion/test_team_cores.py).

Why: as Python objects the cores cost about 0.5 ms per robot per tick (bench/NOTES.md "A team on
the graph"); here one call serves the whole team. All robots share one RobotConfig and one
configuration of each board, as a team deployment does. No rclpy import.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from erforce_interfaces.runtime.numba_support import compiled_for, numba
from erforce_interfaces.wire.robot_config import RobotConfig
from erforce_motion.firmware import _TICK_TOLERANCE_S, _check_period
from erforce_motion.kinematics import OmniKinematics
from erforce_motion.motor_board import MotorBoardConfig
from erforce_motion.pid import PidConfig
from erforce_motion.velocity_control import (
    GRAVITY_MPS2,
    VelocityControlConfig,
    VelocityController,
    wheel_force_per_accel,
)

# What a tick noticed, per robot (bit flags of main_notice / motor_notice).
NOTICE_TIME_BACKWARDS = 1
NOTICE_COMMAND_TIMEOUT = 2  # main board: no command for command_timeout_s, stopping
NOTICE_SETPOINT_TIMEOUT = 2  # motor boards: no setpoint for setpoint_timeout_s, stopping the wheels

# rows of a PID parameter table (channels along the columns)
_KP, _KI, _KD, _LO, _HI, _ILO, _IHI, _KT, _TAU, _DB = range(10)
# PID flags: deadband, derivative, integral, back-calculation, integrator limits
_F_DB, _F_D, _F_I, _F_BACK, _F_ILIM = range(5)


def _pid_tables(config: PidConfig) -> tuple[np.ndarray, np.ndarray]:
    """A PidConfig as (10, channels) parameters and the feature flags ``pid.Pid`` derives from it."""
    a = config.arrays()
    params = np.vstack([a["kp"], a["ki"], a["kd"], a["output_min"], a["output_max"], a["integrator_min"],
                        a["integrator_max"], a["tracking_gain_kt"], a["derivative_filter_tau_s"], a["deadband"]])
    flags = np.array([
        (a["deadband"] > 0.0).any(), (a["kd"] > 0.0).any(), (a["ki"] > 0.0).any(),
        config.anti_windup == "back_calculation",
        np.isfinite(a["integrator_min"]).any() or np.isfinite(a["integrator_max"]).any(),
    ], dtype=np.bool_)
    return np.ascontiguousarray(params), flags


class _PidState:
    """One PID's state for N robots: integrator, derivative filter, previous measurement, last u and v."""

    def __init__(self, n_robots: int, n_channels: int) -> None:
        shape = (n_robots, n_channels)
        self.integrator = np.zeros(shape)
        self.d_filtered = np.zeros(shape)
        self.y_prev = np.zeros(shape)
        self.have_y_prev = np.zeros(n_robots, dtype=np.bool_)
        self.u = np.zeros(shape)
        self.v = np.zeros(shape)

    def arrays(self) -> tuple[np.ndarray, ...]:
        return self.integrator, self.d_filtered, self.y_prev, self.have_y_prev, self.u, self.v


@numba.njit(cache=True, error_model="numpy")
def _pid_step(k, prm, flags, st, sp, y, dt, ff, lo, hi, hold, out):
    """pid.Pid.step for robot k, channel by channel (every channel is independent there too).

    sp, y, ff, lo, hi: per-channel inputs; hold: freeze the integrator; writes u into out."""
    integ, dfilt, yprev, have_y, last_u, last_v = st
    use_db, use_d, use_i, back, ilim = flags[0], flags[1], flags[2], flags[3], flags[4]
    for c in range(out.shape[0]):
        e = sp[c] - y[c]
        if use_db:
            e = np.sign(e) * max(abs(e) - prm[9, c], 0.0)
        p = prm[0, c] * e
        i_now = integ[k, c]
        if use_d:
            if have_y[k]:
                raw = (yprev[k, c] - y[c]) / dt
                df = dfilt[k, c] + (dt / (prm[8, c] + dt)) * (raw - dfilt[k, c])
            else:
                df = dfilt[k, c]
            v = p + i_now + prm[2, c] * df + ff[c]
        else:
            df = 0.0
            v = p + i_now + ff[c]
        u = min(max(v, lo[c]), hi[c])
        if use_i and not hold:
            inc = (prm[1, c] * dt) * e
            if back:
                new_i = i_now + inc + (prm[7, c] * dt) * (u - v)
            else:
                if v != u and (v - u) * inc > 0.0:
                    inc = 0.0
                new_i = i_now + inc
            if ilim:
                new_i = min(max(new_i, prm[5, c]), prm[6, c])
            integ[k, c] = new_i
        if use_d:
            dfilt[k, c] = df
            yprev[k, c] = y[c]
        last_u[k, c] = u
        last_v[k, c] = v
        out[c] = u
    if use_d:
        have_y[k] = True


@numba.njit(cache=True, error_model="numpy")
def _main_reset(k, wheels, fwd, ff_on, shaper, vpid, measured, shaped, command, vel_prm):
    """VelocityController.reset(wheels) for robot k: bumpless restart from the measured motion."""
    integ, dfilt, yprev, have_y, _, _ = vpid
    n = wheels.shape[0]
    for a in range(3):
        s = 0.0
        for i in range(n):
            s += wheels[i] * fwd[a, i]
        shaper[k, a] = s
        measured[k, a] = s
        shaped[k, a] = s
        command[k, a] = s
        # Pid.reset(hold=twist, measurement=twist, setpoint=twist, ff=twist or 0): p is kp * 0
        hold_minus_p = s - vel_prm[0, a] * 0.0
        i_new = hold_minus_p - (s if ff_on else 0.0)
        integ[k, a] = min(max(i_new, vel_prm[5, a]), vel_prm[6, a])
        yprev[k, a] = s
        dfilt[k, a] = 0.0
    have_y[k] = True


@numba.njit(cache=True, error_model="numpy")
def _team_tick(active, t, wheels, currents, period_main, period_motor, tol, cmd_timeout, sp_timeout,
               main_state, vel_prm, vel_flags, shaper_prm, force_rows, kin, motor_state, speed_prm, speed_flags,
               current_prm, current_flags, thermal_prm, actuator_prm, main_notice, motor_notice):
    """One sensor tick for the robots ``active`` (times t, sensors in rows of wheels/currents); see TeamFirmware.
    Returns whether any of them noticed something (a main_notice or motor_notice flag set)."""
    (command_in, now_main, last_run_main, has_run_main, feed_first, has_fed, last_feed, setpoints, shaper,
     measured, shaped, twist_cmd, held, prev_sp, prev_t, has_prev) = main_state[0]
    vpid = main_state[1]
    (sp_motor, sp_time, now_motor, last_run_motor, has_run_motor, duty, i_des, i_cmd, ring, ring_index, ring_sum,
     i2, pwm_limit, at_full, over_limit) = motor_state[0]
    spid = motor_state[1]
    cpid = motor_state[2]
    jac, fwd, slip_proj = kin
    v_max, a_max, w_max, aw_max, f_lim, use_force, ff_on, slip_thr, use_slip = shaper_prm
    (limit_a, window_n, pwm_dec, recovery, i2t_mode, i2t_alpha, thermal_dt) = thermal_prm
    inverse, k_lin, r_over_v, v_over_r, emf_k = actuator_prm
    n = wheels.shape[1]
    zero3 = np.zeros(3)
    zero_n = np.zeros(n)
    lo3, hi3 = vel_prm[3], vel_prm[4]
    cmd3 = np.empty(3)
    i_lo = np.empty(n)
    i_hi = np.empty(n)
    out_i = np.empty(n)
    emf = np.empty(n)
    noticed = False
    for idx in range(active.shape[0]):
        k = active[idx]
        ts = t[idx]
        w = wheels[k]
        cur = currents[k]
        # ---------------------------------------------------------------- main board (MainBoardLoop.tick)
        main_notice[k] = 0
        if ts < now_main[k]:
            main_notice[k] |= 1
            has_fed[k] = False
            _main_reset(k, w, fwd, ff_on, shaper, vpid, measured, shaped, twist_cmd, vel_prm)
            for a in range(3):
                command_in[k, a] = 0.0
            has_run_main[k] = False
        now_main[k] = ts
        if feed_first[k]:
            feed_first[k] = False
            has_fed[k] = True
            last_feed[k] = ts
        if not (has_run_main[k] and ts - last_run_main[k] < period_main - tol):
            dt = period_main if not has_run_main[k] else ts - last_run_main[k]
            last_run_main[k] = ts
            has_run_main[k] = True
            if not has_fed[k] or ts - last_feed[k] > cmd_timeout:
                if command_in[k, 0] != 0.0 or command_in[k, 1] != 0.0 or command_in[k, 2] != 0.0:
                    main_notice[k] |= 2
                for a in range(3):
                    command_in[k, a] = 0.0
            # VelocityController.step
            for a in range(3):
                s = 0.0
                for i in range(n):
                    s += fwd[a, i] * w[i]
                measured[k, a] = s
            vx, vy, wz = command_in[k, 0], command_in[k, 1], command_in[k, 2]
            speed = math.hypot(vx, vy)
            if speed > v_max:
                f = v_max / speed
                vx *= f
                vy *= f
            dx = vx - shaper[k, 0]
            dy = vy - shaper[k, 1]
            dv = math.hypot(dx, dy)
            dv_max = a_max * dt
            if dv > dv_max:
                f = dv_max / dv
                dx *= f
                dy *= f
            wz = min(max(wz, -w_max), w_max)
            dw_max = aw_max * dt
            dw = min(max(wz - shaper[k, 2], -dw_max), dw_max)
            if use_force:
                peak = 0.0
                for i in range(force_rows.shape[0]):
                    peak = max(peak, abs(force_rows[i, 0] * dx + force_rows[i, 1] * dy + force_rows[i, 2] * dw))
                peak = peak / dt
                if peak > f_lim:
                    f = f_lim / peak
                    dx *= f
                    dy *= f
                    dw *= f
            shaper[k, 0] += dx
            shaper[k, 1] += dy
            shaper[k, 2] += dw
            for a in range(3):
                shaped[k, a] = shaper[k, a]
            hold = False
            if use_slip:
                sq = 0.0
                for i in range(n):
                    r = 0.0
                    for j in range(n):
                        r += slip_proj[i, j] * w[j]
                    sq += r * r
                if math.sqrt(sq) > slip_thr:
                    hold = True
            held[k] = hold
            _pid_step(k, vel_prm, vel_flags, vpid, shaped[k], measured[k], dt, shaped[k] if ff_on else zero3,
                      lo3, hi3, hold, cmd3)
            for a in range(3):
                twist_cmd[k, a] = cmd3[a]
            for i in range(n):
                s = 0.0
                for a in range(3):
                    s += jac[i, a] * cmd3[a]
                setpoints[k, i] = s
        # ------------------------------------------- the setpoint of the previous tick reaches the motor boards
        if has_prev[k] and prev_t[k] < ts:
            for i in range(n):
                sp_motor[k, i] = prev_sp[k, i]
            sp_time[k] = prev_t[k]
        # ---------------------------------------------------------------- motor boards (MotorBoardLoop.tick)
        motor_notice[k] = 0
        if ts < now_motor[k]:
            motor_notice[k] |= 1
            for pid in (spid, cpid):
                pid[0][k, :] = 0.0  # Pid.reset(): integrator 0, derivative history forgotten
                pid[1][k, :] = 0.0
                pid[3][k] = False
            for i in range(n):
                duty[k, i] = 0.0
                i_des[k, i] = 0.0
                i_cmd[k, i] = 0.0
                sp_motor[k, i] = 0.0
            has_run_motor[k] = False
            sp_time[k] = -np.inf
        now_motor[k] = ts
        if not (has_run_motor[k] and ts - last_run_motor[k] < period_motor - tol):
            dt = period_motor if not has_run_motor[k] else ts - last_run_motor[k]
            last_run_motor[k] = ts
            has_run_motor[k] = True
            if ts - sp_time[k] > sp_timeout:
                nonzero = False
                for i in range(n):
                    if sp_motor[k, i] != 0.0:
                        nonzero = True
                    sp_motor[k, i] = 0.0
                if nonzero:
                    motor_notice[k] |= 2
            # MotorBoard.step
            _pid_step(k, speed_prm, speed_flags, spid, sp_motor[k], w, dt, zero_n, speed_prm[3], speed_prm[4],
                      False, out_i)
            for i in range(n):
                i_des[k, i] = out_i[i]
            # ThermalCurrentLimiter.update (its dt is the configured loop period)
            any_over = False
            if i2t_mode:
                for i in range(n):
                    a_abs = abs(cur[i])
                    i2[k, i] += i2t_alpha * (a_abs * a_abs - i2[k, i])
                    over_limit[k, i] = i2[k, i] > limit_a * limit_a
                    any_over = any_over or over_limit[k, i]
            else:
                j = ring_index[k]
                for i in range(n):
                    a_abs = abs(cur[i])
                    ring_sum[k, i] += a_abs - ring[k, j, i]
                    ring[k, j, i] = a_abs
                j += 1
                if j == window_n:
                    j = 0
                    for i in range(n):
                        s = 0.0
                        for q in range(window_n):
                            s += ring[k, q, i]
                        ring_sum[k, i] = s
                ring_index[k] = j
                for i in range(n):
                    over_limit[k, i] = ring_sum[k, i] / window_n > limit_a
                    any_over = any_over or over_limit[k, i]
            if any_over:
                for i in range(n):
                    if over_limit[k, i]:
                        pwm_limit[k, i] = max(abs(duty[k, i]) - pwm_dec, 0.0)
                    else:
                        pwm_limit[k, i] = min(pwm_limit[k, i] + recovery * thermal_dt, 1.0)
                at_full[k] = False
            elif not at_full[k]:
                full = True
                for i in range(n):
                    pwm_limit[k, i] = min(pwm_limit[k, i] + recovery * thermal_dt, 1.0)
                    full = full and pwm_limit[k, i] >= 1.0
                at_full[k] = full
            for i in range(n):
                lim = pwm_limit[k, i]
                if inverse:
                    emf[i] = emf_k * w[i]
                    i_hi[i] = (lim - emf[i]) * v_over_r
                    i_lo[i] = (-lim - emf[i]) * v_over_r
                else:
                    i_hi[i] = lim / k_lin
                    i_lo[i] = -i_hi[i]
            _pid_step(k, current_prm, current_flags, cpid, i_des[k], cur, dt, i_des[k], i_lo, i_hi, False, out_i)
            for i in range(n):
                i_cmd[k, i] = out_i[i]
                d = r_over_v * out_i[i] + emf[i] if inverse else k_lin * out_i[i]
                lim = pwm_limit[k, i]
                duty[k, i] = min(max(d, -lim), lim)
        for i in range(n):
            prev_sp[k, i] = setpoints[k, i]
        prev_t[k] = ts
        has_prev[k] = True
        noticed = noticed or main_notice[k] != 0 or motor_notice[k] != 0
    return noticed


class TeamFirmware:
    """Main board + motor boards of ``n_robots`` robots (rows 0 .. n_robots - 1), ticked together.

    Per robot, ``tick`` does what the runner does with one MainBoardLoop and one MotorBoardLoop:
    the main board's setpoint of this tick is used by the motor boards at the robot's next tick.
    ``command`` / ``stop`` are the radio side; ``tick`` takes the robots whose sensors arrived.
    """

    def __init__(self, n_robots: int, robot: RobotConfig, velocity_config: VelocityControlConfig,
                 motor_config: MotorBoardConfig, main_period_s: float, motor_period_s: float,
                 command_timeout_s: float, setpoint_timeout_s: float) -> None:
        if not isinstance(n_robots, int) or n_robots < 1:
            raise ValueError(f"n_robots: must be an int >= 1, got {n_robots!r}")
        for name, v in (("command_timeout_s", command_timeout_s), ("setpoint_timeout_s", setpoint_timeout_s)):
            if not (math.isfinite(v) and v > 0.0):
                raise ValueError(f"{name}: must be finite and > 0, got {v!r}")
        # the scalar controller checks the configuration (speed limit within the motors' reach etc.)
        controller = VelocityController(robot, velocity_config)
        self.n_robots = n = n_robots
        self.robot, self.velocity_config, self.motor_config = robot, velocity_config, motor_config
        self.main_period_s = _check_period(main_period_s)
        self.motor_period_s = _check_period(motor_period_s)
        self.command_timeout_s, self.setpoint_timeout_s = float(command_timeout_s), float(setpoint_timeout_s)
        self.num_wheels = w = robot.num_wheels
        self.kinematics = OmniKinematics.from_robot_config(robot)
        self.max_setpoint_radps = controller.max_setpoint_radps
        kin = self.kinematics
        self._kin = (np.ascontiguousarray(kin.wheel_matrix), np.ascontiguousarray(kin.forward_matrix),
                     np.ascontiguousarray(kin.slip_projector))
        vc = velocity_config
        self._vel_prm, self._vel_flags = _pid_tables(vc.pid_config())
        use_force = vc.traction_limit_fraction is not None
        self._force_rows = np.ascontiguousarray(wheel_force_per_accel(robot)) if use_force else np.zeros((0, 3))
        f_lim = (vc.traction_limit_fraction * robot.traction_mu * robot.mass_kg * GRAVITY_MPS2
                 / robot.num_wheels
                 if use_force else math.inf)
        self._shaper_prm = (float(vc.max_speed_mps), float(vc.max_accel_mps2), float(vc.max_angular_speed_radps),
                            float(vc.max_angular_accel_radps2), float(f_lim), use_force, vc.feedforward_enabled,
                            float(vc.slip_hold_threshold_radps or 0.0), vc.slip_hold_threshold_radps is not None)
        # main board state
        self.command_twist = np.zeros((n, 3))  # the radio command each robot follows
        self._now_main = np.full(n, -math.inf)
        self._last_run_main = np.zeros(n)
        self._has_run_main = np.zeros(n, dtype=np.bool_)
        self._feed_first = np.zeros(n, dtype=np.bool_)
        self._has_fed = np.zeros(n, dtype=np.bool_)
        self._last_feed = np.zeros(n)
        self.setpoints = np.zeros((n, w))  # the main boards' last wheel speed setpoints [rad/s]
        self._shaper = np.zeros((n, 3))
        self.measured_twist = np.zeros((n, 3))
        self.shaped_twist = np.zeros((n, 3))
        self.twist_command = np.zeros((n, 3))  # PID output incl. feedforward
        self.integrator_held = np.zeros(n, dtype=np.bool_)
        self._prev_sp = np.zeros((n, w))
        self._prev_t = np.zeros(n)
        self._has_prev = np.zeros(n, dtype=np.bool_)
        self._vpid = _PidState(n, 3)
        # motor board state
        mc = motor_config
        speed = PidConfig(kp=mc.speed_kp_a_per_radps, ki=mc.speed_ki_a_per_rad, kd=mc.speed_kd_as_per_rad,
                          derivative_filter_tau_s=mc.speed_derivative_tau_s, output_min=-mc.peak_current_a,
                          output_max=mc.peak_current_a, anti_windup=mc.anti_windup, n_channels=w)
        current = PidConfig(kp=mc.current_kp, ki=mc.current_ki_per_s, anti_windup=mc.anti_windup, n_channels=w)
        self._speed_prm, self._speed_flags = _pid_tables(speed)
        self._current_prm, self._current_flags = _pid_tables(current)
        limit_a = (mc.average_current_limit_a if mc.average_current_limit_a is not None
                   else robot.continuous_current_limit_a)
        tau = mc.i2t_time_constant_s if mc.i2t_time_constant_s is not None else robot.winding_thermal_time_constant_s
        self.window_samples = max(1, round(mc.average_window_s / mc.loop_period_s))
        self._i2t = mc.thermal_mode == "i2t"
        self._thermal_prm = (float(limit_a), self.window_samples, float(mc.pwm_decrement),
                             float(mc.pwm_recovery_rate_per_s),
                             self._i2t, 1.0 - math.exp(-mc.loop_period_s / tau), float(mc.loop_period_s))
        k_lin = mc.linear_duty_per_a if mc.linear_duty_per_a is not None else (
            robot.motor_resistance_ohm / robot.supply_voltage_v)
        self._actuator_prm = (mc.actuator_mode == "inverse_model", float(k_lin),
                              robot.motor_resistance_ohm / robot.supply_voltage_v,
                              robot.supply_voltage_v / robot.motor_resistance_ohm,
                              robot.motor_torque_constant_nm_per_a * robot.gear_ratio / robot.supply_voltage_v)
        self._sp_motor = np.zeros((n, w))
        self._sp_time = np.full(n, -math.inf)
        self._now_motor = np.full(n, -math.inf)
        self._last_run_motor = np.zeros(n)
        self._has_run_motor = np.zeros(n, dtype=np.bool_)
        self.duty = np.zeros((n, w))  # the motor boards' last PWM duties
        self.desired_current_a = np.zeros((n, w))
        self.current_command_a = np.zeros((n, w))
        # the 10 s boxcar: window_samples x wheels per robot (the one big array; none in 'i2t' mode)
        self._ring = np.zeros((n, 0 if self._i2t else self.window_samples, w))
        self._ring_index = np.zeros(n, dtype=np.int64)
        self._ring_sum = np.zeros((n, w))
        self._i2 = np.zeros((n, w))
        self.pwm_limit = np.ones((n, w))
        self._at_full = np.ones(n, dtype=np.bool_)
        self.over_limit = np.zeros((n, w), dtype=np.bool_)
        self._spid = _PidState(n, w)
        self._cpid = _PidState(n, w)
        self.main_notice = np.zeros(n, dtype=np.int64)
        self.motor_notice = np.zeros(n, dtype=np.int64)
        self.noticed = False  # some robot of the last tick has a notice flag set
        self._all = np.arange(n, dtype=np.int64)
        self._main_state = (self.command_twist, self._now_main, self._last_run_main, self._has_run_main,
                            self._feed_first, self._has_fed, self._last_feed, self.setpoints, self._shaper,
                            self.measured_twist, self.shaped_twist, self.twist_command, self.integrator_held,
                            self._prev_sp, self._prev_t, self._has_prev)
        self._motor_state = (self._sp_motor, self._sp_time, self._now_motor, self._last_run_motor,
                             self._has_run_motor, self.duty, self.desired_current_a, self.current_command_a,
                             self._ring, self._ring_index, self._ring_sum, self._i2, self.pwm_limit, self._at_full,
                             self.over_limit)

        self._kernel_args = (
            self.main_period_s, self.motor_period_s, _TICK_TOLERANCE_S, self.command_timeout_s, self.setpoint_timeout_s,
            (self._main_state, self._vpid.arrays()), self._vel_prm, self._vel_flags, self._shaper_prm,
            self._force_rows, self._kin, (self._motor_state, self._spid.arrays(), self._cpid.arrays()),
            self._speed_prm, self._speed_flags, self._current_prm, self._current_flags, self._thermal_prm,
            self._actuator_prm, self.main_notice, self.motor_notice)
        # Load the compiled kernel now (numba's disk cache; a compile after a code change), not at the first
        # sensor tick: a node answers its first lockstep tick in time. tick passes exactly these types
        # (C-contiguous int64 rows, float64 times and sensors) to the compiled function.
        self._kernel = compiled_for(_team_tick, np.zeros(0, dtype=np.int64), np.zeros(0), self.duty, self.duty,
                                    *self._kernel_args)

    # ------------------------------------------------------------------ radio side
    def command(self, robot: int, twist) -> None:
        """A new desired twist [vx, vy, wz] (robot frame) for one robot, received at its current time."""
        arr = np.asarray(twist, dtype=float)
        if arr.shape != (3,) or not np.all(np.isfinite(arr)):
            raise ValueError(f"twist must be 3 finite values, got {twist!r}")
        self.command_twist[robot] = arr
        now = self._now_main[robot]
        if math.isfinite(now):
            self._has_fed[robot] = True
            self._last_feed[robot] = now
        else:
            self._feed_first[robot] = True  # a command sent before the robot's first tick counts

    def commands(self, robots: np.ndarray, twists: np.ndarray) -> None:
        """``command`` for many robots at once: twists (len(robots), 3), all finite."""
        robots = np.asarray(robots, dtype=np.int64)
        twists = np.asarray(twists, dtype=float)
        if twists.shape != (robots.shape[0], 3) or not np.isfinite(twists).all():
            raise ValueError(f"twists: need ({robots.shape[0]}, 3) finite values, got shape {twists.shape}")
        self.command_twist[robots] = twists
        now = self._now_main[robots]
        started = np.isfinite(now)
        self._has_fed[robots[started]] = True
        self._last_feed[robots[started]] = now[started]
        self._feed_first[robots[~started]] = True

    def stop(self, robot: int) -> None:
        """Drop a robot's current command (e.g. after a rejected message): decelerate to rest."""
        self.command_twist[robot] = 0.0

    def forget_setpoint(self, robot: int) -> None:
        """A new time line for this robot: the setpoint of the old one does not reach its motor boards."""
        self._has_prev[robot] = False

    # ------------------------------------------------------------------ sensor ticks
    def tick(self, t_s: float | np.ndarray, wheel_speeds_radps: np.ndarray, currents_a: np.ndarray,
             robots: Sequence[int] | np.ndarray | None = None) -> np.ndarray:
        """A sensor tick of ``robots`` (None: all) at times ``t_s`` (one for all, or one per robot).

        wheel_speeds_radps, currents_a: (n_robots, wheels); only the rows of ``robots`` are read.
        Returns ``duty`` (n_robots, wheels), updated in the rows of ``robots`` (the array is reused:
        copy what you keep). ``setpoints``, ``main_notice`` and ``motor_notice`` are updated likewise, and
        ``noticed`` says whether any of these robots' notice flags is set.
        Raises ValueError (changing nothing) for non-finite sensors or times.
        """
        if robots is None:
            active = self._all
            rows_w, rows_i = wheel_speeds_radps, currents_a
        else:
            active = np.asarray(robots, dtype=np.int64)
            if active.ndim != 1 or (active.size and not 0 <= active.min() <= active.max() < self.n_robots):
                raise ValueError(f"robots: need row indices in [0, {self.n_robots - 1}], got {robots!r}")
            active = np.ascontiguousarray(active)
            rows_w, rows_i = wheel_speeds_radps[active], currents_a[active]
        if isinstance(t_s, float | int):
            t = np.full(active.shape, float(t_s))
        else:
            t = np.ascontiguousarray(np.broadcast_to(np.asarray(t_s, dtype=float), active.shape))
        w = np.ascontiguousarray(wheel_speeds_radps, dtype=float)
        cur = np.ascontiguousarray(currents_a, dtype=float)
        shape = (self.n_robots, self.num_wheels)
        if w.shape != shape or cur.shape != shape:
            raise ValueError(f"sensors: need {shape} arrays, got {w.shape} and {cur.shape}")
        if not (np.isfinite(t).all() and np.isfinite(rows_w).all() and np.isfinite(rows_i).all()):
            raise ValueError("tick: times, wheel speeds and currents must be finite")
        self.noticed = self._kernel(active, t, w, cur, *self._kernel_args)
        return self.duty

    # ------------------------------------------------------------------ status
    @property
    def average_current_a(self) -> np.ndarray:
        """Per robot and wheel: the thermal limiter's average current (boxcar mean, or sqrt of i^2 in 'i2t')."""
        if self._i2t:
            return np.sqrt(self._i2)
        return self._ring_sum / self.window_samples

    @property
    def saturated(self) -> np.ndarray:
        """Per robot and wheel: speed loop at +-peak current, or duty at the PWM limit (MotorBoard.saturated)."""
        return (self._spid.v != self._spid.u) | (np.abs(self.duty) >= self.pwm_limit - 1e-12)

    def notices(self, robot: int) -> list[str]:
        """What the last tick of this robot noticed, in the words of the per-robot loops."""
        out = []
        m, b = int(self.main_notice[robot]), int(self.motor_notice[robot])
        if m & NOTICE_TIME_BACKWARDS:
            out.append("time went backwards: controller reset")
        if m & NOTICE_COMMAND_TIMEOUT:
            out.append(f"no command for {self.command_timeout_s:g} s: stopping")
        if b & NOTICE_TIME_BACKWARDS:
            out.append("time went backwards: motor boards reset")
        if b & NOTICE_SETPOINT_TIMEOUT:
            out.append(f"no setpoint for {self.setpoint_timeout_s:g} s: stopping the wheels")
        return out

    def take_over(self, old: TeamFirmware) -> None:
        """Continue where ``old`` (same robots, other parameters) left off, as MainBoardLoop.take_over and
        MotorBoardLoop.take_over do: same commands, timing, setpoints and duties; controllers restarted
        bumplessly from the measured motion; the motor boards' controllers and thermal history start afresh."""
        if old.n_robots != self.n_robots or old.num_wheels != self.num_wheels:
            raise ValueError("take_over: the old firmware has other robots or wheels")
        self.command_twist[:] = old.command_twist
        if old.command_timeout_s == self.command_timeout_s:
            self._has_fed[:], self._last_feed[:] = old._has_fed, old._last_feed
        for mine, theirs in ((self._now_main, old._now_main), (self._last_run_main, old._last_run_main),
                             (self._has_run_main, old._has_run_main), (self.setpoints, old.setpoints),
                             (self._prev_sp, old._prev_sp), (self._prev_t, old._prev_t),
                             (self._has_prev, old._has_prev), (self.duty, old.duty), (self._now_motor, old._now_motor),
                             (self._last_run_motor, old._last_run_motor), (self._has_run_motor, old._has_run_motor),
                             (self._sp_motor, old._sp_motor), (self._sp_time, old._sp_time)):
            mine[:] = theirs
        wheels = old.measured_twist @ self._kin[0].T
        for k in range(self.n_robots):
            _main_reset(k, wheels[k], self._kin[1], self._shaper_prm[6], self._shaper, self._vpid.arrays(),
                        self.measured_twist, self.shaped_twist, self.twist_command, self._vel_prm)
