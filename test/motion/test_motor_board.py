"""Motor-board cascade (Fig. 3): thermal limiter sequences, actuator modes, flags, plant model, bad input."""

import math

import numpy as np
import pytest

from erforce_interfaces.wire.robot_config import RobotConfig
from erforce_motion.motor_board import MotorBoard, MotorBoardConfig, ThermalCurrentLimiter, motor_board_step
from erforce_motion.plant_model import OmniRobotPlant, WheelPlant

ROBOT = RobotConfig()


def test_average_limiter_crosses_at_predicted_sample_then_drops_one_percent_per_loop():
    # 2 A constant, 10 s window at 1 kHz = 10000 samples, zero history:
    # average after k samples = 2k/10000 > 1.3  <=>  k > 6500, so the first loop over is k = 6501
    lim = ThermalCurrentLimiter(1, 1.3, window_s=10.0, loop_period_s=0.001)
    duty = np.ones(1)
    for k in range(1, 6501):
        assert lim.update(np.array([2.0]), duty)[0] == 1.0, k
    assert lim.average_current_a[0] == pytest.approx(1.3)
    expected = 1.0
    for _ in range(50):  # the duty follows the limit, so the limit falls 0.01 per loop
        expected -= 0.01
        duty = lim.update(np.array([2.0]), duty).copy()
        assert duty[0] == pytest.approx(expected)
        assert lim.over_limit[0]


def test_limit_follows_the_last_pwm_not_the_old_limit():
    lim = ThermalCurrentLimiter(1, 1.3, window_s=0.01, loop_period_s=0.001)
    for _ in range(7):  # 7 * 2 A / 10 samples = 1.4 A > 1.3 A on the 7th
        out = lim.update(np.array([2.0]), np.array([-0.3]))
    assert out[0] == pytest.approx(0.29)  # |last PWM| - 1 %


def test_recovery_rate_hand_computed():
    # window 10 samples; 2 A for 7 samples, then 0 A. averages: 0.2k up to 1.4 (k=7),
    # stays 1.4 for k=8..10 (zeros replace zeros), 1.2 at k=11 (first 2 A leaves): recovery
    # at rate 0.5/s * 1 ms = 0.0005 per loop from 0.49 (last duty 0.5 - 1 %)
    lim = ThermalCurrentLimiter(1, 1.3, window_s=0.01, loop_period_s=0.001, recovery_rate_per_s=0.5)
    last = np.array([0.5])
    seq = []
    for k in range(1, 1200):
        current = 2.0 if k <= 7 else 0.0
        seq.append(float(lim.update(np.array([current]), last)[0]))
    assert seq[5] == 1.0  # k = 6: average 1.2
    assert seq[6:10] == pytest.approx([0.49] * 4)  # k = 7..10
    assert seq[10] == pytest.approx(0.4905)
    assert seq[20] == pytest.approx(0.49 + 11 * 0.0005)
    k_full = 10 + math.ceil((1.0 - 0.49) / 0.0005)  # index at which 1.0 is reached
    assert seq[k_full - 1] < 1.0
    assert seq[k_full] == pytest.approx(1.0)
    assert seq[-1] == 1.0  # capped at 100 %


def test_i2t_mode_crosses_at_predicted_sample():
    # exact discretisation, constant 2 A: x_k = 4 (1 - a^k), a = exp(-dt/tau); over when x_k > 1.69
    lim = ThermalCurrentLimiter(1, 1.3, mode="i2t", i2t_time_constant_s=1.0, loop_period_s=0.001)
    a = math.exp(-0.001)
    k_star = math.ceil(math.log(1.0 - 1.69 / 4.0) / math.log(a))
    assert k_star == 550
    for k in range(1, k_star):
        lim.update(np.array([2.0]), np.ones(1))
        assert not lim.over_limit[0], k
    lim.update(np.array([2.0]), np.ones(1))
    assert lim.over_limit[0]


def test_motor_board_thermal_sequence_end_to_end():
    # measured current pinned at 2 A, huge speed setpoint: duty at the limit every loop
    mb = MotorBoard(MotorBoardConfig(actuator_mode="linear"), ROBOT, n_wheels=1)
    sp, w, i = np.array([1e3]), np.zeros(1), np.array([2.0])
    duties = [float(mb.step(sp, w, i, 0.001)[0]) for _ in range(6500)]
    assert duties[-1] == pytest.approx(1.0)  # current PID saturated at duty 1
    assert not mb.status.limit_active[0] and mb.status.saturated[0]
    after = [float(mb.step(sp, w, i, 0.001)[0]) for _ in range(30)]
    assert after == pytest.approx([1.0 - 0.01 * (j + 1) for j in range(30)])
    assert mb.status.limit_active[0] and mb.status.saturated[0]
    assert mb.status.average_current_a[0] == pytest.approx(2.0 * 6530 / 10000)


def test_actuator_modes_hand_computed():
    lin = MotorBoard(MotorBoardConfig(actuator_mode="linear"), ROBOT)
    inv = MotorBoard(MotorBoardConfig(actuator_mode="inverse_model"), ROBOT)
    assert lin.actuator(2.0, 10.0) == pytest.approx(0.94 * 2.0 / 24.0)
    # (R i + k_e * gear * w) / V = (0.94*2 + 0.036*3.6*10) / 24
    assert inv.actuator(2.0, 10.0) == pytest.approx((1.88 + 1.296) / 24.0)
    custom = MotorBoard(MotorBoardConfig(actuator_mode="linear", linear_duty_per_a=0.05), ROBOT)
    assert custom.actuator(3.0, 0.0) == pytest.approx(0.15)


def test_first_step_duty_hand_computed():
    # speed PI: kp=1.5, error 2 rad/s -> i_des = 3 A (integrator still 0);
    # current PI with i_des as feedforward: kp=0.2 * (3 - 1) + 3 = 3.4 A; linear: duty = 3.4 * 0.94/24
    mb = MotorBoard(MotorBoardConfig(actuator_mode="linear"), ROBOT, n_wheels=1)
    duty = mb.step(np.array([2.0]), np.zeros(1), np.array([1.0]), 0.001)
    assert duty[0] == pytest.approx(3.4 * 0.94 / 24.0)
    assert mb.status.desired_current_a[0] == pytest.approx(3.0)


def test_closed_loop_wheel_tracks_and_saturation_flags():
    mb = MotorBoard(robot=ROBOT, n_wheels=2)
    plant = WheelPlant(ROBOT, n_wheels=2)
    w, i = np.zeros(2), np.zeros(2)
    sp = np.array([30.0, -80.0])
    saturated_seen = np.zeros(2, dtype=bool)
    for _ in range(400):
        w, i = plant.step(mb.step(sp, w, i, 0.001), 0.001)
        saturated_seen |= mb.status.saturated
    np.testing.assert_allclose(w, sp, rtol=0.01)
    assert saturated_seen.all()  # both start at +-peak current
    assert not mb.status.saturated.any()
    assert not mb.status.limit_active.any()


def test_locked_wheel_current_is_limited_by_the_average():
    # stall at 8 A: the 10 s average crosses 1.3 A at ~1.6 s; the PWM then ramps down 1 % per
    # loop (~31 loops from duty ~0.31), which overshoots the average by about 31 ms * 4 A / 10 s
    mb = MotorBoard(robot=ROBOT, n_wheels=1)
    plant = WheelPlant(ROBOT, n_wheels=1, substeps=1)
    plant.locked[:] = True
    w, i = np.zeros(1), np.zeros(1)
    currents = []
    for _ in range(25000):
        w, i = plant.step(mb.step(np.array([100.0]), w, i, 0.001), 0.001)
        currents.append(abs(i[0]))
    assert max(currents) > 7.5  # it did drive hard at first
    padded = np.concatenate([np.zeros(9999), currents])
    avg = np.convolve(padded, np.ones(10000) / 10000, "valid")  # same zero-history boxcar
    assert avg.max() < 1.3 + 0.02
    assert np.mean(avg[12000:]) <= 1.3
    assert avg[10100] < 1.3  # the first burst leaves the window: back below the limit


@pytest.mark.parametrize("args", [
    (np.zeros(3), np.zeros(4), np.zeros(4), 0.001),
    (np.zeros(4), np.zeros(4), np.array([0, 0, math.nan, 0]), 0.001),
    (np.zeros(4), np.array([0, math.inf, 0, 0]), np.zeros(4), 0.001),
    (np.array([math.nan, 0, 0, 0]), np.zeros(4), np.zeros(4), 0.001),
    (np.zeros(4), np.zeros(4), np.zeros(4), 0.0),
    (np.zeros(4), np.zeros(4), np.zeros(4), -1.0),
])
def test_bad_input_raises_and_keeps_thermal_state(args):
    mb = MotorBoard(robot=ROBOT)
    mb.step(np.ones(4), np.zeros(4), np.full(4, 3.0), 0.001)
    before = mb.status.average_current_a
    with pytest.raises(ValueError):
        mb.step(*args)
    np.testing.assert_array_equal(mb.status.average_current_a, before)


def test_a_robot_with_bad_input_stops_alone_in_a_team_step():
    """motor_board_step on two robots' rows, robot 1's setpoint NaN: robot 0 steps as a board of its own
    does, robot 1's outputs and thermal history stay as they were, and the step reports the failure."""
    team, alone = MotorBoard(robot=ROBOT, n_robots=2), MotorBoard(robot=ROBOT)
    sp = np.array([[10.0, -5.0, 3.0, 0.0], [math.nan, 0.0, 0.0, 0.0]])
    w, i = np.zeros((2, 4)), np.full((2, 4), 0.5)
    rows, dt = np.array([0, 1], dtype=np.int64), np.full(2, 0.001)
    assert not motor_board_step(rows, team.args, sp, w, i, dt)
    np.testing.assert_array_equal(team.duty[0], alone.step(sp[0], w[0], i[0], 0.001))
    np.testing.assert_array_equal(team.duty[1], np.zeros(4))
    np.testing.assert_array_equal(team.thermal.average_currents_a()[1], np.zeros(4))
    np.testing.assert_array_equal(team.thermal.average_currents_a()[0], alone.thermal.average_current_a)


@pytest.mark.parametrize("kw", [{"speed_kp_a_per_radps": 0.0}, {"current_ki_per_s": -1.0},
                                {"actuator_mode": "pwm"}, {"thermal_mode": "magic"},
                                {"pwm_decrement": 1.5}, {"average_window_s": math.nan},
                                {"linear_duty_per_a": -0.1}, {"peak_current_a": math.inf}])
def test_bad_config_raises(kw):
    with pytest.raises(ValueError):
        MotorBoardConfig(**kw)


def test_plant_locked_wheel_current_exact():
    # locked: i(dt) = V d / R * (1 - exp(-dt R / L)) for any number of substeps
    for substeps in (1, 7):
        p = WheelPlant(ROBOT, n_wheels=1, substeps=substeps)
        p.locked[:] = True
        _, i = p.step(np.array([0.5]), 0.0002)
        assert i[0] == pytest.approx(24 * 0.5 / 0.94 * (1 - math.exp(-0.0002 * 0.94 / 0.36e-3)))


def test_plant_free_wheel_steady_speed_near_no_load_speed():
    p = WheelPlant(ROBOT, n_wheels=1)
    for _ in range(1000):
        w, _i = p.step(np.array([0.5]), 0.001)
    no_load = 0.5 * 24 / (0.036 * 3.6)  # back-EMF equals the applied voltage
    assert 0.97 * no_load < w[0] < no_load  # friction takes a little


def test_robot_plant_symmetric_drive_moves_straight():
    p = OmniRobotPlant(ROBOT)
    duty = -0.1 * np.sin(np.asarray(ROBOT.wheel_angles_rad))  # the vx pattern of the Rojas matrix
    for _ in range(300):
        p.step(duty, 0.001)
    assert p.twist[0] > 0.3
    assert abs(p.twist[1]) < 1e-9 and abs(p.twist[2]) < 1e-9


def test_plant_bad_input_raises():
    p = WheelPlant(ROBOT, n_wheels=2)
    for duty, dt in ((np.zeros(3), 0.001), (np.array([0.0, math.nan]), 0.001), (np.zeros(2), 0.0)):
        with pytest.raises(ValueError):
            p.step(duty, dt)
    with pytest.raises(ValueError):
        WheelPlant(ROBOT, load_inertia_kgm2=-1.0)
    with pytest.raises(ValueError):
        OmniRobotPlant(ROBOT, substeps=0)
