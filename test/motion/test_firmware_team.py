"""The one firmware (firmware.py) against the paper's equations worked by hand: the first ticks of the main
board (Fig. 2: shaper, PI with feedforward, inverse kinematics) and the motor boards (Fig. 3: speed PI,
current PI, actuator) of a team, the thermal limit's boxcar over its window; and the team's rows against
one-robot loops over long random runs that reach every branch (commands and their timeouts, robots whose
sensors do not arrive, loops slower than the ticks, time going backwards, the thermal PWM limit and
saturation): each row must be exactly the robot alone, with the setpoint handed over one tick later."""

import math

import numpy as np
import pytest

from erforce_interfaces.wire.robot_config import RobotConfig
from erforce_motion.firmware import (
    NOTICE_COMMAND_TIMEOUT,
    NOTICE_TIME_BACKWARDS,
    MainBoardLoop,
    MotorBoardLoop,
    TeamFirmware,
)
from erforce_motion.motor_board import MotorBoardConfig
from erforce_motion.velocity_control import VelocityControlConfig

ROBOT = RobotConfig()

CONFIGS = {
    # the defaults, with a short thermal window so that the limit bites within the run
    "default": (VelocityControlConfig(), dict(average_window_s=0.05), 0.001, 0.001),
    # every other branch: no feedforward, derivative terms, back-calculation, no traction limit and
    # no slip hold, 'i2t' thermal mode, linear actuator, a main board at half the tick rate
    "other_branches": (
        VelocityControlConfig.pid_only(kd_translation=0.05, kd_rotation=0.02, anti_windup="back_calculation",
                                       traction_limit_fraction=None, slip_hold_threshold_radps=None),
        dict(speed_kd_as_per_rad=0.01, anti_windup="back_calculation", thermal_mode="i2t",
             i2t_time_constant_s=0.05, actuator_mode="linear", peak_current_a=3.0),
        0.002, 0.001),
}


class _ScalarTeam:
    """The reference: per-robot loops stepped as team_firmware_node steps them."""

    def __init__(self, n, velocity, motor, main_period, motor_period):
        self.main = [MainBoardLoop(ROBOT, velocity, main_period, 0.05) for _ in range(n)]
        self.motor = [MotorBoardLoop(ROBOT, motor, motor_period, 0.03) for _ in range(n)]
        self.previous = [None] * n

    def tick(self, k, t, w, cur):
        setpoint = self.main[k].tick(t, w).copy()
        prev = self.previous[k]
        if prev is not None and prev[0] < t:
            self.motor[k].set_setpoint(*prev)
        duty = self.motor[k].tick(t, w, cur)
        self.previous[k] = (t, setpoint)
        return setpoint, duty


@pytest.mark.parametrize("name", sorted(CONFIGS))
def test_each_row_of_the_team_is_the_robot_alone(name):
    velocity, motor_fields, main_period, motor_period = CONFIGS[name]
    motor = MotorBoardConfig(loop_period_s=motor_period, **motor_fields)
    n, w = 3, ROBOT.num_wheels
    rng = np.random.default_rng(7)
    ref = _ScalarTeam(n, velocity, motor, main_period, motor_period)
    team = TeamFirmware(n, ROBOT, velocity, motor, main_period, motor_period, 0.05, 0.03)
    times = np.zeros(n)
    wheels = np.zeros((n, w))
    currents = np.zeros((n, w))
    worst = 0.0
    seen = {"backwards": 0, "timeout": 0, "limited": 0, "saturated": 0, "held": 0, "noticed": 0}
    for _ in range(1500):
        for k in np.flatnonzero(rng.random(n) < 0.02):  # radio commands, some of them large
            twist = rng.normal(0.0, [1.5, 1.5, 4.0])
            ref.main[k].command(twist)
            team.command(int(k), twist)
        if rng.random() < 0.002:
            k = int(rng.integers(n))
            ref.main[k].stop()
            team.stop(k)
        active = np.flatnonzero(rng.random(n) < 0.8)  # the others' sensors did not arrive this tick
        for k in active:
            if rng.random() < 0.004:  # a restarted simulator
                times[k] = max(0.0, times[k] - rng.uniform(0.01, 0.5))
                seen["backwards"] += 1
            else:
                times[k] += 0.001 * (1 + (rng.random() < 0.05))  # now and then a tick lost
        # sensors: a wheel speed that follows the last setpoint loosely, currents that heat the motors
        wheels += 0.2 * (team.setpoints - wheels) + rng.normal(0.0, 0.5, (n, w))
        currents = 0.6 * currents + rng.normal(0.0, 3.0, (n, w))
        duty = team.tick(times[active], wheels, currents, active)
        average, saturated = team.average_current_a, team.saturated
        any_notice = False
        for k in active:
            setpoint, duty_ref = ref.tick(int(k), float(times[k]), wheels[k].copy(), currents[k].copy())
            board = ref.motor[k].board
            status = ref.main[k].controller.status
            # the largest difference of the run, relative to the size of the values (cheaper than asserting here)
            for mine, theirs in ((team.setpoints[k], setpoint), (duty[k], duty_ref),
                                 (team.pwm_limit[k], board.thermal.pwm_limit),
                                 (average[k], board.thermal.average_current_a),
                                 (team.measured_twist[k], status.measured_twist)):
                worst = max(worst, float(np.max(np.abs(mine - theirs) / (1.0 + np.abs(theirs)))))
            assert (saturated[k] == board.saturated).all()
            main_notice, motor_notice = ref.main[k].notice or "", ref.motor[k].notice or ""
            any_notice = any_notice or bool(main_notice or motor_notice)
            assert bool(team.main_notice[k] & NOTICE_TIME_BACKWARDS) == ("backwards" in main_notice)
            assert bool(team.main_notice[k] & NOTICE_COMMAND_TIMEOUT) == ("no command" in main_notice)
            assert bool(team.motor_notice[k] & NOTICE_TIME_BACKWARDS) == ("backwards" in motor_notice)
            assert bool(team.motor_notice[k] & 2) == ("no setpoint" in motor_notice)
            seen["timeout"] += "no command" in main_notice
            seen["limited"] += bool((board.thermal.pwm_limit < 1.0).any())
            seen["saturated"] += bool(board.saturated.any())
            seen["held"] += bool(status.integrator_held)
        assert team.noticed == any_notice  # the tick's flag: some robot of it noticed something
        seen["noticed"] += any_notice
    assert worst == 0.0  # the same kernels on other rows: not a rounding apart
    # the run went through the branches it is meant to compare
    assert seen["backwards"] >= 3 and seen["timeout"] >= 3 and seen["limited"] > 50 and seen["saturated"] > 50
    assert 3 <= seen["noticed"] < 1500
    if velocity.slip_hold_threshold_radps is not None:
        assert seen["held"] > 50


def test_commands_for_many_robots_at_once_feed_each_watchdog():
    velocity = VelocityControlConfig(traction_limit_fraction=None)
    team = TeamFirmware(3, ROBOT, velocity, MotorBoardConfig(), 0.001, 0.001, 0.0505, 0.1)
    zeros = np.zeros((3, ROBOT.num_wheels))
    team.tick(0.0, zeros, zeros, [0])  # robot 0 has a time, 1 and 2 not yet
    team.commands(np.array([0, 1]), np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]))
    team.tick(0.001, zeros, zeros)
    # both commanded robots move off: the shaper's first step is a_max * dt along the command
    np.testing.assert_allclose(team.shaped_twist[0], [6.0 * 0.001, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(team.shaped_twist[1], [0.0, 6.0 * 0.001, 0.0], atol=1e-12)
    np.testing.assert_array_equal(team.shaped_twist[2], [0.0, 0.0, 0.0])
    stopped_at = {}
    for k in range(2, 60):  # no further command: the watchdog stops each robot 50.5 ms after its feed
        team.tick(0.001 * k, zeros, zeros)
        for robot in (0, 1):
            if team.main_notice[robot] & NOTICE_COMMAND_TIMEOUT:
                stopped_at[robot] = k
    # robot 0 was fed at its time 0.0; robot 1 had no time yet, so its first tick (0.001) fed it
    assert stopped_at == {0: 51, 1: 52}
    np.testing.assert_array_equal(team.command_twist, np.zeros((3, 3)))


def test_bad_sensors_raise_and_change_nothing():
    team = TeamFirmware(2, ROBOT, VelocityControlConfig(), MotorBoardConfig(), 0.001, 0.001, 0.05, 0.1)
    zeros = np.zeros((2, ROBOT.num_wheels))
    bad = zeros.copy()
    bad[1, 2] = math.nan
    with pytest.raises(ValueError, match="finite"):
        team.tick(0.0, bad, zeros)
    assert not np.isfinite(team.main.now_s).any()
    team.tick(0.0, bad, zeros, [0])  # a NaN in a row that did not tick is not read
    with pytest.raises(ValueError, match="twist"):
        team.command(0, [1.0, math.inf, 0.0])


def test_new_parameters_take_over_as_the_per_robot_loops_do():
    """A parameter change mid-run (team_firmware's on_change): TeamFirmware.take_over against
    MainBoardLoop.take_over and MotorBoardLoop.take_over, robot by robot."""
    motor = MotorBoardConfig(average_window_s=0.05)
    ref = _ScalarTeam(2, VelocityControlConfig(), motor, 0.001, 0.001)
    team = TeamFirmware(2, ROBOT, VelocityControlConfig(), motor, 0.001, 0.001, 0.05, 0.03)
    rng = np.random.default_rng(3)
    wheels = np.zeros((2, ROBOT.num_wheels))
    currents = np.zeros((2, ROBOT.num_wheels))
    worst = driven = 0.0
    for step in range(1, 401):
        if step % 20 == 1:  # the radio keeps commanding
            for k in range(2):
                ref.main[k].command(np.array([1.0, -0.5, 2.0]))
                team.command(k, [1.0, -0.5, 2.0])
        if step == 200:  # new gains; the old loops hand over
            velocity = VelocityControlConfig(kp_translation=0.5, ki_translation=8.0)
            new_ref = _ScalarTeam(2, velocity, motor, 0.001, 0.001)
            new_ref.previous = ref.previous
            for k in range(2):
                new_ref.main[k].take_over(ref.main[k])
                new_ref.motor[k].take_over(ref.motor[k])
            ref = new_ref
            new_team = TeamFirmware(2, ROBOT, velocity, motor, 0.001, 0.001, 0.05, 0.03)
            new_team.take_over(team)
            team = new_team
        t = 0.001 * step
        wheels += 0.2 * (team.setpoints - wheels) + rng.normal(0.0, 0.3, wheels.shape)
        currents = 0.6 * currents + rng.normal(0.0, 0.3, currents.shape)  # below the thermal limit
        duty = team.tick(t, wheels, currents)
        driven = max(driven, float(np.abs(duty).max()))
        for k in range(2):
            setpoint, duty_ref = ref.tick(k, t, wheels[k].copy(), currents[k].copy())
            worst = max(worst, float(np.max(np.abs(duty[k] - duty_ref))),
                        float(np.max(np.abs(team.setpoints[k] - setpoint) / (1.0 + np.abs(setpoint)))))
    assert worst < 1e-9
    assert driven > 0.05  # the robots were driven


# ---------------------------------------------------------------- the paper's equations, worked by hand

DT = 0.001
R_OVER_V = ROBOT.motor_resistance_ohm / ROBOT.supply_voltage_v


def wheel_speeds(twist):
    """Inverse kinematics written out: wheel i at angle a_i rolls at (-sin a_i vx + cos a_i vy + d wz) / r."""
    vx, vy, wz = twist
    return np.array([(-math.sin(a) * vx + math.cos(a) * vy + ROBOT.wheel_distance_m * wz) / ROBOT.wheel_radius_m
                     for a in ROBOT.wheel_angles_rad])


def test_first_ticks_of_a_team_follow_fig_2_and_fig_3():
    """Robot 0 commanded 1 m/s forward, robot 1 -2 rad/s, from rest, sensors at rest (wheels held)."""
    velocity = VelocityControlConfig(traction_limit_fraction=None)  # kp 0.3, ki 5/s, feedforward on
    motor = MotorBoardConfig()  # speed PI kp 1.5, ki 15; current PI kp 0.2, ki 200/s; inverse-model actuator
    team = TeamFirmware(2, ROBOT, velocity, motor, DT, DT, 0.2, 0.1)
    team.commands(np.array([0, 1]), np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -2.0]]))
    zeros = np.zeros((2, ROBOT.num_wheels))
    duty = team.tick(0.0, zeros, zeros).copy()
    # tick 1. shaper: |dv| <= a_max dt = 6 mm/s, |dw| <= 60 rad/s^2 * dt; PI: v = kp e + 0 + feedforward
    np.testing.assert_allclose(team.shaped_twist, [[0.006, 0.0, 0.0], [0.0, 0.0, -0.06]], rtol=1e-12)
    cmd_1 = np.array([[0.006 * 1.3, 0.0, 0.0], [0.0, 0.0, -0.06 * 1.3]])
    np.testing.assert_allclose(team.twist_command, cmd_1, rtol=1e-12, atol=1e-15)
    for k in range(2):
        np.testing.assert_allclose(team.setpoints[k], wheel_speeds(cmd_1[k]), rtol=1e-12, atol=1e-15)
    np.testing.assert_array_equal(duty, 0.0)  # the motor boards have no setpoint yet (it arrives next tick)
    first_setpoints = team.setpoints.copy()
    duty = team.tick(DT, zeros, zeros).copy()
    # tick 2. the integrator holds ki dt e = 5 * 0.001 * e1; the error is the new shaped twist
    cmd_2 = np.array([[0.012 * 1.3 + 5.0 * DT * 0.006, 0.0, 0.0], [0.0, 0.0, -0.12 * 1.3 - 5.0 * DT * 0.06]])
    np.testing.assert_allclose(team.twist_command, cmd_2, rtol=1e-12, atol=1e-15)
    # motor boards with tick 1's setpoint: i_des = 1.5 e (integrator empty), i_cmd = 0.2 (i_des - 0) + i_des,
    # duty = R/V i_cmd (no back-EMF at rest)
    i_des = 1.5 * first_setpoints
    np.testing.assert_allclose(team.desired_current_a, i_des, rtol=1e-12)
    np.testing.assert_allclose(duty, R_OVER_V * 1.2 * i_des, rtol=1e-12, atol=1e-15)


def test_the_thermal_limit_lowers_the_pwm_below_the_last_duty_once_the_average_is_over():
    """The paper: |i| averaged over the window; over 1.3 A the PWM limit is |last PWM| - 1 %."""
    motor = MotorBoardConfig(average_window_s=0.01)  # a boxcar of N = 10 samples
    team = TeamFirmware(1, ROBOT, VelocityControlConfig(), motor, DT, DT, 10.0, 10.0)
    team.command(0, [2.0, 0.0, 0.0])
    stalled = np.zeros((1, ROBOT.num_wheels))
    hot = np.full((1, ROBOT.num_wheels), 2.0)  # 2 A in every winding
    for k in range(1, 12):
        last = team.duty.copy()
        team.tick(DT * k, stalled, hot)
        average = 2.0 * min(k, 10) / 10  # history before the start counts as zero current
        np.testing.assert_allclose(team.average_current_a, average, rtol=1e-12)
        if average > 1.3:  # from the 7th sample on
            np.testing.assert_allclose(team.pwm_limit, np.maximum(np.abs(last) - 0.01, 0.0), rtol=1e-12)
            assert (np.abs(team.duty) <= team.pwm_limit).all()
        else:
            np.testing.assert_array_equal(team.pwm_limit, 1.0)
