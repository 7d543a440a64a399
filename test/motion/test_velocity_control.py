"""Main-board velocity controller (Fig. 2): shaper, feedforward switch, closed loop, bad input."""

import math

import numpy as np
import pytest

from erforce_interfaces.wire.robot_config import RobotConfig
from erforce_motion.kinematics import OmniKinematics
from erforce_motion.motor_board import MotorBoard
from erforce_motion.plant_model import OmniRobotPlant
from erforce_motion.velocity_control import (
    SetpointShaper,
    VelocityControlConfig,
    VelocityController,
)

ROBOT = RobotConfig()
KIN = OmniKinematics.from_robot_config(ROBOT)


def test_shaper_limits_acceleration_along_the_direction_of_motion():
    sh = SetpointShaper(VelocityControlConfig(max_accel_mps2=6.0, max_speed_mps=4.0))
    # target (3, 4) m/s from rest, dt 0.1 s: |dv| <= 0.6 along (0.6, 0.8)
    vx, vy, _ = sh.step(3.0, 4.0, 0.0, 0.1)
    assert (vx, vy) == pytest.approx((0.36, 0.48))
    for _ in range(100):
        vx, vy, _ = sh.step(3.0, 4.0, 0.0, 0.1)
    # |(3,4)| = 5 > 4: scaled as a whole to (2.4, 3.2), not clipped per axis
    assert (vx, vy) == pytest.approx((2.4, 3.2))


def test_shaper_direction_change_is_a_straight_line_in_velocity_space():
    sh = SetpointShaper(VelocityControlConfig(max_accel_mps2=2.0))
    sh.reset((1.0, 0.0, 0.0))
    vx, vy, _ = sh.step(0.0, 1.0, 0.0, 0.1)  # dv = (-1, 1), |dv| limited to 0.2
    s = 0.2 / math.sqrt(2.0)
    assert (vx, vy) == pytest.approx((1.0 - s, s))


def test_shaper_angular_limits():
    sh = SetpointShaper(VelocityControlConfig(max_angular_speed_radps=10.0, max_angular_accel_radps2=60.0))
    assert sh.step(0.0, 0.0, 50.0, 0.01)[2] == pytest.approx(0.6)
    for _ in range(100):
        w = sh.step(0.0, 0.0, 50.0, 0.01)[2]
    assert w == pytest.approx(10.0)


def test_feedforward_passes_shaped_setpoint_when_tracking():
    vc = VelocityController(ROBOT, VelocityControlConfig())
    # reachable in one 10 ms step with the default limits (2 m/s^2, 8 rad/s^2: below the traction limit)
    target = (0.02, -0.012, 0.08)
    out = vc.step(target, KIN.inverse(target), 0.01)
    np.testing.assert_allclose(out, KIN.inverse(target), atol=1e-12)


def test_without_feedforward_pid_alone_builds_the_command():
    cfg = VelocityControlConfig(feedforward_enabled=False, kp_translation=2.0, ki_translation=10.0)
    vc = VelocityController(ROBOT, cfg)
    target = (0.05, 0.0, 0.0)
    # zero error: no P, integrator still 0 -> no command at all
    np.testing.assert_allclose(vc.step(target, KIN.inverse(target), 0.01), 0.0, atol=1e-12)
    vc2 = VelocityController(ROBOT, cfg)
    # at rest: command = kp * 0.05 = 0.1 m/s
    np.testing.assert_allclose(vc2.step(target, np.zeros(4), 0.01), KIN.inverse((0.1, 0.0, 0.0)), atol=1e-12)


def _closed_loop(cfg, target, seconds, dt=0.001):
    vc = VelocityController(ROBOT, cfg)
    mb = MotorBoard(robot=ROBOT)
    plant = OmniRobotPlant(ROBOT, substeps=2)
    w = np.zeros(4)
    i = np.zeros(4)
    for _ in range(round(seconds / dt)):
        sp = vc.step(target, w, dt, mb.saturated)
        w, i = plant.step(mb.step(sp, w, i, dt), dt)
    return plant.twist


@pytest.mark.parametrize("ff", [True, False])
def test_closed_loop_reaches_the_commanded_twist(ff):
    cfg = VelocityControlConfig(feedforward_enabled=ff) if ff else VelocityControlConfig(
        feedforward_enabled=False, kp_translation=2.0, ki_translation=40.0, kp_rotation=2.0, ki_rotation=40.0)
    twist = _closed_loop(cfg, (1.0, -0.5, 2.0), 0.8)
    np.testing.assert_allclose(twist, (1.0, -0.5, 2.0), atol=0.02)


def test_reset_is_bumpless():
    vc = VelocityController(ROBOT)
    w = KIN.inverse((0.8, 0.3, -1.0))
    vc.reset(w)
    np.testing.assert_allclose(vc.step((0.8, 0.3, -1.0), w, 0.001), w, atol=1e-9)


@pytest.mark.parametrize("desired, wheels, dt", [
    ((1.0, 0.0), np.zeros(4), 0.001),
    ((math.nan, 0.0, 0.0), np.zeros(4), 0.001),
    ((0.0, math.inf, 0.0), np.zeros(4), 0.001),
    ((0.0, 0.0, 0.0), np.zeros(3), 0.001),
    ((0.0, 0.0, 0.0), np.array([0.0, math.nan, 0.0, 0.0]), 0.001),
    ((0.0, 0.0, 0.0), np.zeros(4), 0.0),
    ((0.0, 0.0, 0.0), np.zeros(4), math.nan),
])
def test_bad_input_raises(desired, wheels, dt):
    with pytest.raises(ValueError):
        VelocityController(ROBOT).step(desired, wheels, dt)


@pytest.mark.parametrize("kw", [{"max_speed_mps": 0.0}, {"max_accel_mps2": math.nan}, {"ki_translation": -1.0},
                                {"kp_rotation": math.inf}, {"feedforward_enabled": 1},
                                {"anti_windup": "none"}])
def test_bad_config_raises(kw):
    with pytest.raises(ValueError):
        VelocityControlConfig(**kw)


