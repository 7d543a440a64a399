"""The in-process runner: the closed loop on the physical plant, at the DDS graph's 2 ms tick and at 1 kHz."""

import math

import numpy as np
import pytest

from erforce_motion.motor_board import MotorBoardConfig
from erforce_sim.in_process.runner import InProcessRunner
from erforce_sim.plant_setup import PlantSetup


def run_step(period_s: float, command, duration_s: float = 1.2):
    setup = PlantSetup(robot_poses=((0.0, 0.0, 0.0),), ball=(3.0, 2.0, 0.0, 0.0), control_period_s=period_s)
    runner = InProcessRunner(setup, motor_config=MotorBoardConfig(loop_period_s=period_s), command_timeout_s=30.0)
    runner.command(0, command)
    t, v = [], []
    for _ in range(round(duration_s / period_s)):
        runner.tick()
        s = runner.world.robot_state(0)
        c, sn = math.cos(s.theta), math.sin(s.theta)
        t.append(runner.t_s)
        v.append((c * s.vx + sn * s.vy, -sn * s.vx + c * s.vy, s.w))  # robot frame, like cmd_vel
    return np.array(t), np.array(v), runner


def settle_time(t, v, target, band=0.02):
    err = np.max(np.abs(v - target), axis=1) / np.max(np.abs(target))
    outside = np.flatnonzero(err > band)
    return t[outside[-1] + 1] if outside.size else 0.0


@pytest.mark.parametrize("command", [(1.0, 0.5, 0.0), (2.0, 0.0, 0.0), (0.0, 0.0, 4.0)])
def test_a_2ms_tick_behaves_like_1khz(command):
    target = np.array(command)
    t1, v1, _ = run_step(0.001, command)
    t2, v2, r2 = run_step(0.002, command)
    np.testing.assert_allclose(v2[-50:].mean(axis=0), target, atol=0.01)  # reaches the command
    assert v2[-100:].std(axis=0).max() < 0.005  # no ripple
    assert settle_time(t2, v2, target) == pytest.approx(settle_time(t1, v1, target), abs=0.02)
    assert r2.world.all_finite()


def test_the_runner_tick_count_and_time():
    _, _, runner = run_step(0.002, (0.5, 0.0, 0.0), duration_s=0.1)
    assert runner.tick_index == 50 and runner.t_ns == 100_000_000
    assert runner.world.t_s == pytest.approx(0.1)
