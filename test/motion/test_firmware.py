"""The firmware loops around the controllers: loop rate, watchdog, stale setpoints, time going
backwards, and the integrator bound that prevents wind-up while the wheels cannot follow."""

import numpy as np
import pytest

from erforce_interfaces.wire.robot_config import RobotConfig
from erforce_motion.firmware import MainBoardLoop, MotorBoardLoop
from erforce_motion.kinematics import OmniKinematics
from erforce_motion.motor_board import MotorBoardConfig
from erforce_motion.velocity_control import VelocityControlConfig

ROBOT = RobotConfig()
KIN = OmniKinematics.from_robot_config(ROBOT)
ZERO = np.zeros(ROBOT.num_wheels)


def main_board(period=0.002, timeout=0.2, **cfg):
    return MainBoardLoop(ROBOT, VelocityControlConfig(**cfg), period, timeout)


def test_a_slower_loop_holds_its_output_between_runs():
    loop = main_board(period=0.004)
    loop.command(np.array([1.0, 0.0, 0.0]))
    first = loop.tick(0.000, ZERO).copy()
    held = loop.tick(0.002, ZERO)  # 2 ms later: not due, same setpoints
    np.testing.assert_array_equal(held, first)
    assert not np.array_equal(loop.tick(0.004, ZERO), first)  # due again


def test_a_command_sent_before_the_first_tick_counts_for_the_watchdog():
    loop = main_board(timeout=0.05)
    loop.command(np.array([0.5, 0.0, 0.0]))
    sp = loop.tick(1.000, ZERO)
    assert KIN.forward(sp)[0] > 0.0  # moving at the first tick, not stopped by the watchdog
    for k in range(1, 40):
        sp = loop.tick(1.000 + 0.002 * k, KIN.inverse(np.array([0.5, 0.0, 0.0])))
    assert loop.notice is None or "stopping" in loop.notice
    assert KIN.forward(sp)[0] < 0.5  # 78 ms > 50 ms timeout: braking


def test_time_going_backwards_resets_and_says_so():
    loop = main_board()
    loop.command(np.array([1.0, 0.0, 0.0]))
    for k in range(10):
        loop.tick(5.0 + 0.002 * k, ZERO)
    loop.tick(0.0, ZERO)
    assert "time went backwards" in loop.notice
    np.testing.assert_allclose(KIN.forward(loop.tick(0.002, ZERO)), 0.0, atol=1e-12)  # command dropped


def test_the_motor_board_stops_the_wheels_on_a_stale_setpoint_and_resets_on_backwards_time():
    boards = MotorBoardLoop(ROBOT, MotorBoardConfig(loop_period_s=0.002), 0.002, setpoint_timeout_s=0.01)
    boards.set_setpoint(0.0, np.full(ROBOT.num_wheels, 50.0))
    assert np.all(boards.tick(0.002, ZERO, ZERO) > 0.0)
    boards.tick(0.020, ZERO, ZERO)  # setpoint 20 ms old > 10 ms
    assert "no setpoint" in boards.notice
    boards.tick(0.010, ZERO, ZERO)
    assert "time went backwards" in boards.notice


@pytest.mark.parametrize("feedforward", [True, False])
def test_no_wind_up_while_the_wheels_do_not_follow(feedforward):
    """Motor boards dead for 5 s: the wheels stay still while 1 m/s is commanded."""
    cfg = VelocityControlConfig() if feedforward else VelocityControlConfig.pid_only()
    loop = MainBoardLoop(ROBOT, cfg, 0.002, 30.0)
    loop.command(np.array([1.0, 0.0, 0.0]))
    for k in range(2500):
        sp = loop.tick(0.002 * k, ZERO)
    vx_command = KIN.forward(sp)[0]
    if feedforward:
        # shaped 1.0 + P (kp * 1.0 error) + the bounded I: the resume can lurch to at most that
        assert vx_command == pytest.approx(1.0 + cfg.kp_translation * 1.0 + cfg.ff_integrator_limit_mps, abs=1e-6)
    else:
        # without feedforward the integrator must be able to produce the whole command
        assert vx_command == pytest.approx(cfg.command_limit_mps, abs=1e-6)


def test_integrator_bound_must_be_positive():
    with pytest.raises(ValueError, match="ff_integrator_limit_mps"):
        VelocityControlConfig(ff_integrator_limit_mps=0.0)
