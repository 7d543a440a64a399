"""Issue 6, fault tests: robot_0 pushes against a field wall; the motor boards' thermal rule (paper
Sec. 4.1: ~10 s average current limited to 1.3 A through the PWM limit) keeps the average current at
the limit and the windings cool.

On the default carpet (traction_mu 0.8) a blocked robot's wheels slip at ~1.25 A each (the
traction force mu m g / 4 through the gear), below 1.3 A: the limit never has to act. These
tests run on a grippier carpet (traction_mu 1.5: ~2.3 A while slipping) in every node, so
the rule must engage and hold the average down.

The whole story, 20 s of stall (the first, hardest pushes leave the 10 s window from 10 s on), runs in
process: the lockstep DDS graph computes the same trajectory (test_team_firmware.py). Over DDS the
nodes stall for 8 s: the limit engages (at ~6 s), the motor boards report it on motor_status, and
the same bound holds while the plant, the firmware and the robot file of every node take part.
"""

import dataclasses
import math

import numpy as np
import pytest
import yaml
from faults_support import ROBOT_YAML, ClosedLoop
from nav_msgs.msg import Odometry

from erforce_interfaces.wire import contract
from erforce_interfaces.wire.conversions import odometry_msg
from erforce_interfaces.wire.robot_config import FieldConfig, RobotConfig
from erforce_interfaces.wire.tables import table_from_msg
from erforce_motion.motor_board import MotorBoardConfig
from erforce_motion.velocity_control import VelocityControlConfig
from erforce_sim.in_process.runner import InProcessRunner
from erforce_sim.plant_setup import PlantSetup

STALL_S = 20.0  # in process
DDS_STALL_S = 8.0  # the average passes 1.3 A after ~5.7 s at ~2.3 A (and sooner with the first pushes' peak)
TRACTION_MU = 1.5
TICK_S = 0.002  # plant tick = motor-board loop period (the plant default): the 10 s window is 5000 samples


def average_limit_tolerance_a(robot: RobotConfig, board: MotorBoardConfig, peak_current_a: float) -> float:
    """How far the 10 s average can overshoot 1.3 A before the paper's rule has pulled it back.

    The rule acts only once the average exceeds the limit; the average then still rises while
    the current is above it. Each loop the PWM limit drops to |last duty| - pwm_decrement, so the
    current falls by at most delta_i = pwm_decrement * V / R per loop (stalled winding; the
    electrical time constant L/R = 0.38 ms is below the loop period). Starting from at most the
    peak current, the samples added before the current is under the limit sum to at most
    i_peak * (n_drop / 2 + 1) with n_drop = i_peak / delta_i loops of the linear descent; add one
    loop for the crossing sample itself and two for the sensor-to-duty delay of the lockstep loop.
    Each sample weighs 1 / N in the boxcar of N samples.
    """
    n_window = round(board.average_window_s / TICK_S)
    delta_i = board.pwm_decrement * robot.supply_voltage_v / robot.motor_resistance_ohm
    n_drop = math.ceil(peak_current_a / delta_i)
    return peak_current_a * (n_drop / 2.0 + 1.0 + 3.0) / n_window


def x_touch_m(robot: RobotConfig) -> float:
    """robot_0's centre when it touches the +x wall (field boundary + run-off), facing it."""
    return FieldConfig.preset("division_b").wall_half_length_m - robot.robot_radius_m - 0.001


def assert_stall_held(robot: RobotConfig, stall_s: float, t_start: float, truth_t, truth_x, avg, pwm_limit,
                      currents_a, temperatures_c) -> None:
    """The robot pushed at the wall for ``stall_s``, the limit engaged and held the average at 1.3 A.

    ``avg`` and ``pwm_limit``: the motor boards' status (samples, wheels); ``currents_a`` and
    ``temperatures_c``: the plant's motor truth (samples, wheels); ``truth_t``, ``truth_x``: robot_0's."""
    board = MotorBoardConfig()
    x_touch = x_touch_m(robot)
    assert truth_t[-1] >= t_start + stall_s
    # the robot stayed at the wall, pushing
    pushing = truth_t >= t_start + 0.5
    assert np.all(np.abs(truth_x[pushing] - x_touch) < 0.01)
    # the limit engaged: the average exceeded 1.3 A and the PWM limit came down
    engaged = np.flatnonzero(np.any(pwm_limit < 1.0, axis=1))
    assert engaged.size, f"PWM limit never engaged; peak average {avg.max():.3f} A"
    peak_current_a = max(board.peak_current_a, float(np.abs(currents_a).max()))
    tol = average_limit_tolerance_a(robot, board, peak_current_a)
    # "small": ~3 % of the limit (8 A peak: 0.030 A; the measured peak, ~9.3 A while the current
    # loop settles at the first push, gives ~0.042 A)
    assert tol < 0.05
    after = avg[engaged[0]:]
    assert after.max() <= robot.continuous_current_limit_a + tol, (
        f"10 s average {after.max():.4f} A once the limit engaged, limit {robot.continuous_current_limit_a} A "
        f"+ tolerance {tol:.4f} A")
    assert avg.max() <= robot.continuous_current_limit_a + tol
    assert temperatures_c.max() < robot.winding_max_temperature_c
    assert temperatures_c.min() >= robot.ambient_temperature_c - 1e-9


def test_stall_against_a_wall_keeps_the_average_current_at_the_limit_in_process():
    robot = dataclasses.replace(RobotConfig.from_yaml(ROBOT_YAML), traction_mu=TRACTION_MU)
    runner = InProcessRunner(
        PlantSetup(field_preset="division_b", robot_poses=((x_touch_m(robot), 0.0, 0.0),),
                   ball=(-2.0, 2.0, 0.0, 0.0), control_period_s=TICK_S, robot=robot),
        VelocityControlConfig(), MotorBoardConfig(loop_period_s=TICK_S), command_timeout_s=1000.0)
    runner.command(0, (1.0, 0.0, 0.0))  # into the wall
    samples = []

    def record(r: InProcessRunner) -> None:
        state = r.world.robot_state(0)
        samples.append((r.t_s, state.x, r.firmware.average_current_a[0].copy(), r.firmware.pwm_limit[0].copy(),
                        np.array(state.currents_a), np.array(state.winding_temperatures_c)))

    runner.run(STALL_S + TICK_S, record)
    t, x, avg, pwm_limit, currents, temperatures = (np.array(column) for column in zip(*samples, strict=True))
    assert_stall_held(robot, STALL_S, 0.0, t, x, avg, pwm_limit, currents, temperatures)
    # the first pushes left the window (from 10 s on) and the average still held: the rule acted again
    assert np.any(pwm_limit[t > 10.5] < 1.0)


@pytest.mark.integration
def test_stall_against_a_wall_keeps_the_average_current_at_the_limit(ros_graph, tmp_path):
    data = yaml.safe_load(ROBOT_YAML.read_text())
    data["/**"]["ros__parameters"]["robot"]["traction_mu"] = TRACTION_MU
    robot_yaml = tmp_path / "robot_grippy.yaml"
    robot_yaml.write_text(yaml.safe_dump(data))
    robot = RobotConfig.from_yaml(robot_yaml)

    loop = ClosedLoop(
        ros_graph, robot_yaml=robot_yaml,
        plant={"field": "division_b", "real_time_factor": 0.0, "control_period_s": TICK_S,
               "lockstep_timeout_s": 5.0},
        vc={"command_timeout_s": 1000.0}, mb={"loop_rate_hz": 1.0 / TICK_S, "status_rate_hz": 50.0},
    )
    loop.start_all()
    set_state = loop.probe.wait_for_subscribers("/robot_0/sim/set_state", Odometry)
    set_state.publish(odometry_msg(0.0, (x_touch_m(robot), 0.0, 0.0), (0.0, 0.0, 0.0)))
    loop.spin_until(lambda: any("robot_0 placed" in e for e in loop.events()), 30.0, "the robot placed at the wall")
    loop.command(1.0)  # into the wall
    t_start = loop.sim_s()
    loop.spin_until(lambda: loop.sim_s() >= t_start + DDS_STALL_S, 240.0, f"{DDS_STALL_S} s of stall")

    status = [table_from_msg(m, contract.MOTOR_STATUS_COLUMNS) for m in loop.watch.kept["/robot_0/motor_status"]]
    avg = np.array([tab[:, 0] for tab in status])  # (samples, wheels)
    pwm_limit = np.array([tab[:, 1] for tab in status])
    motors = np.array([table_from_msg(m, contract.GROUND_TRUTH_MOTOR_COLUMNS)
                       for m in loop.watch.kept["/robot_0/ground_truth/motors"]])  # (samples, wheels, 3)
    truth_t = np.array([t for t, _ in loop.truth()])
    truth_x = np.array([m.pose.pose.position.x for m in loop.watch.kept["/robot_0/ground_truth/odom"]])
    assert_stall_held(robot, DDS_STALL_S, t_start, truth_t, truth_x, avg, pwm_limit, motors[:, :, 0], motors[:, :, 1])
    assert avg.shape[0] >= 0.9 * DDS_STALL_S * 50.0  # motor_status at 50 Hz of sim time, all of it seen
    loop.watch.assert_all_finite()
    assert loop.procs["motor_boards"].alive() and loop.procs["plant"].alive()
