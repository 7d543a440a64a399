"""Issue 6, fault tests: robot_0 pushes against a field wall for 20 s of simulated time; the
motor boards' thermal rule (paper Sec. 4.1: ~10 s average current limited to 1.3 A through
the PWM limit) keeps the average current at the limit and the windings cool.

On the default carpet (traction_mu 0.8) a blocked robot's wheels slip at ~1.25 A each (the
traction force mu m g / 4 through the gear), below 1.3 A: the limit never has to act. This
test runs on a grippier carpet (traction_mu 1.5: ~2.3 A while slipping) in every node, so
the rule must engage and hold the average down.
"""

import math

import numpy as np
import pytest
import yaml
from faults_support import ROBOT_YAML, ClosedLoop
from nav_msgs.msg import Odometry

from erforce_interfaces import contract
from erforce_interfaces.conversions import odometry_msg, table_from_msg
from erforce_interfaces.robot_config import FieldConfig, RobotConfig
from erforce_motion.motor_board import MotorBoardConfig

pytestmark = pytest.mark.integration

STALL_S = 20.0
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


def test_stall_against_a_wall_keeps_the_average_current_at_the_limit(ros_graph, tmp_path):
    data = yaml.safe_load(ROBOT_YAML.read_text())
    data["/**"]["ros__parameters"]["robot"]["traction_mu"] = TRACTION_MU
    robot_yaml = tmp_path / "robot_grippy.yaml"
    robot_yaml.write_text(yaml.safe_dump(data))
    robot = RobotConfig.from_yaml(robot_yaml)
    board = MotorBoardConfig()
    field = FieldConfig.preset("division_b")

    loop = ClosedLoop(
        ros_graph, robot_yaml=robot_yaml,
        plant={"field": "division_b", "real_time_factor": 0.0, "control_period_s": TICK_S,
               "lockstep_timeout_s": 5.0},
        vc={"command_timeout_s": 1000.0}, mb={"loop_rate_hz": 1.0 / TICK_S, "status_rate_hz": 50.0},
    )
    loop.start_all()
    # touching the +x wall (field boundary + run-off), facing it
    x_touch = field.wall_half_length_m - robot.robot_radius_m - 0.001
    set_state = loop.probe.wait_for_subscribers("/robot_0/sim/set_state", Odometry)
    set_state.publish(odometry_msg(0.0, (x_touch, 0.0, 0.0), (0.0, 0.0, 0.0)))
    loop.spin_until(lambda: any("robot_0 placed" in e for e in loop.events()), 30.0, "the robot placed at the wall")
    loop.command(1.0)  # into the wall
    t_start = loop.sim_s()
    loop.spin_until(lambda: loop.sim_s() >= t_start + STALL_S, 240.0, f"{STALL_S} s of stall")

    status = [table_from_msg(m, contract.MOTOR_STATUS_COLUMNS) for m in loop.watch.kept["/robot_0/motor_status"]]
    avg = np.array([tab[:, 0] for tab in status])  # (samples, wheels)
    pwm_limit = np.array([tab[:, 1] for tab in status])
    motors = np.array([table_from_msg(m, contract.GROUND_TRUTH_MOTOR_COLUMNS)
                       for m in loop.watch.kept["/robot_0/ground_truth/motors"]])  # (samples, wheels, 3)
    truth_t = np.array([t for t, _ in loop.truth()])
    truth_x = np.array([m.pose.pose.position.x for m in loop.watch.kept["/robot_0/ground_truth/odom"]])

    # the robot stayed at the wall, pushing
    pushing = truth_t >= t_start + 0.5
    assert np.all(np.abs(truth_x[pushing] - x_touch) < 0.01)
    # the limit engaged: the average exceeded 1.3 A and the PWM limit came down
    engaged = np.flatnonzero(np.any(pwm_limit < 1.0, axis=1))
    assert engaged.size, f"PWM limit never engaged; peak average {avg.max():.3f} A"
    peak_current_a = max(board.peak_current_a, float(np.abs(motors[:, :, 0]).max()))
    tol = average_limit_tolerance_a(robot, board, peak_current_a)
    # "small": ~3 % of the limit (8 A peak: 0.030 A; the measured peak, ~9.3 A while the current
    # loop settles at the first push, gives ~0.042 A)
    assert tol < 0.05
    after = avg[engaged[0]:]
    assert after.max() <= robot.continuous_current_limit_a + tol, (
        f"10 s average {after.max():.4f} A once the limit engaged, limit {robot.continuous_current_limit_a} A "
        f"+ tolerance {tol:.4f} A")
    assert avg.max() <= robot.continuous_current_limit_a + tol
    assert avg.shape[0] >= 0.9 * STALL_S * 50.0  # motor_status at 50 Hz of sim time, all of it seen
    temperatures = motors[:, :, 1]
    assert temperatures.max() < robot.winding_max_temperature_c
    assert temperatures.min() >= robot.ambient_temperature_c - 1e-9
    loop.watch.assert_all_finite()
    assert loop.procs["motor_boards"].alive() and loop.procs["plant"].alive()
