"""tune_motor: the paper's Ziegler-Nichols experiment (Sec. 4.2, Fig. 4) on the simulated lifted wheel."""

import math

import numpy as np
import pytest
import yaml

from erforce_interfaces.wire.robot_config import RobotConfig
from erforce_motion.motor_boards_node import SCHEMA
from erforce_motion.tuning import pt2_tangent_times
from erforce_sim.in_process.tuning_experiment import (
    MOTOR_BOARDS_NODE_KEY,
    lifted_wheel_response,
    main,
    motor_time_constants,
    run_on_sim,
)

ROBOT = RobotConfig()
SPECS = SCHEMA.by_name
LOOP_S = 0.001


def _independent_constants():
    """tau_m from the motor-shaft view: J_shaft R / (eta k_t k_e), J_shaft = J_wheel / G^2 + J_rotor."""
    g = ROBOT.gear_ratio
    j_shaft = ROBOT.wheel_inertia_kgm2 / g**2 + ROBOT.motor_rotor_inertia_kgm2
    kt = ke = ROBOT.motor_torque_constant_nm_per_a
    tau_m = j_shaft * ROBOT.motor_resistance_ohm / (ROBOT.gear_efficiency * kt * ke)
    tau_e = ROBOT.motor_inductance_h / ROBOT.motor_resistance_ohm
    gain = ROBOT.motor_resistance_ohm / (ke * g)  # steady wheel speed per desired A, duty = (R/V) i
    return tau_m, tau_e, gain


def test_closed_form_constants_match_the_shaft_view():
    tau_m, tau_e, gain = _independent_constants()
    tc = motor_time_constants(ROBOT)
    assert tc.mechanical_s == pytest.approx(tau_m, rel=1e-12)
    assert tc.electrical_s == pytest.approx(tau_e, rel=1e-12)
    assert tc.gain_radps_per_a == pytest.approx(gain, rel=1e-12)
    assert tc.pt2_t1_s + tc.pt2_t2_s == pytest.approx(tau_m, rel=1e-12)  # sum and product of the poles
    assert tc.pt2_t1_s * tc.pt2_t2_s == pytest.approx(tau_m * tau_e, rel=1e-12)
    assert 10e-3 < tau_m < 14e-3  # 12.1 ms for the default drive train


@pytest.fixture(scope="module")
def step_result():
    return run_on_sim(response="step", duration_s=0.1)


def test_step_fit_agrees_with_the_motor_constants(step_result):
    tau_m, tau_e, gain = _independent_constants()
    fit = step_result.fit
    # Coulomb friction (1.5 mN m = 0.046 A at the shaft) lowers the final speed of a 2 A step by ~2 %
    assert fit.gain == pytest.approx(gain, rel=0.05) and fit.gain < gain
    # the PT2 of the model has T1 + T2 = tau_m exactly and T1 T2 = tau_m tau_e
    assert fit.t1_s + fit.t2_s == pytest.approx(tau_m, rel=0.05)
    assert fit.t2_s == pytest.approx(tau_e, rel=0.25)  # only ~0.4 samples long: loosely resolved
    # the duty is applied one loop period after the command
    assert fit.dead_time_s == pytest.approx(LOOP_S, abs=0.3 * LOOP_S)
    tc = motor_time_constants(ROBOT)
    model = pt2_tangent_times(gain, tc.pt2_t1_s, tc.pt2_t2_s, LOOP_S)
    assert step_result.times.balance_time_tg_s == pytest.approx(model.balance_time_tg_s, rel=0.10)
    assert step_result.times.delay_time_tu_s == pytest.approx(model.delay_time_tu_s, abs=0.3 * LOOP_S)


def _check_params_file(path):
    data = yaml.safe_load(path.read_text())
    params = data[MOTOR_BOARDS_NODE_KEY]["ros__parameters"]
    assert {"speed_kp_a_per_radps", "speed_ki_a_per_rad", "speed_kd_as_per_rad"} <= set(params)
    for name, value in params.items():
        assert isinstance(value, float) and math.isfinite(value)
        assert SPECS[name].check(value) is None, (name, value)
    assert params["speed_kp_a_per_radps"] > 0.0 and params["speed_ki_a_per_rad"] > 0.0
    return params


def test_command_writes_params_file_and_figure(tmp_path, capsys):
    assert main(["--out", str(tmp_path), "--rule", "chr_0", "--duration", "0.1"]) == 0
    params = _check_params_file(tmp_path / "motor_boards_chr_0_pi.yaml")
    assert params["speed_kd_as_per_rad"] == 0.0
    png = tmp_path / "tuning_fig4_step.png"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "Tu=" in capsys.readouterr().out


def test_impulse_zn_pid_gains_are_in_range(tmp_path):
    assert main(["--out", str(tmp_path), "--response", "impulse", "--rule", "zn", "--structure", "PID",
                 "--duration", "0.1"]) == 0
    params = _check_params_file(tmp_path / "motor_boards_zn_pid.yaml")
    assert params["speed_kd_as_per_rad"] > 0.0 and params["speed_derivative_tau_s"] > 0.0


def test_impulse_sees_the_braking_dynamics():
    # after the pulse the wheel back-drives the gear: wheel torque G k_t i / eta, so the decay has
    # tau_m * eta^2 (9.8 ms), and Coulomb friction stops it a little earlier still
    tau_m, _, _ = _independent_constants()
    res = run_on_sim(response="impulse", duration_s=0.1)
    t_sum = res.fit.t1_s + res.fit.t2_s
    assert 0.6 * tau_m < t_sum < ROBOT.gear_efficiency**2 * tau_m * 1.05


def test_raw_response_is_zero_before_the_input_and_rises_after():
    t, y, size = lifted_wheel_response(duration_s=0.01)
    assert size == 2.0 and y[0] == 0.0 and y[1] == 0.0  # applied at the second loop period
    assert np.all(np.diff(y[1:]) > 0.0)
    assert t[-1] == pytest.approx(0.01)


@pytest.mark.parametrize("kw", [{"response": "ramp"}, {"amplitude_a": 100.0}, {"amplitude_a": math.nan},
                                {"duration_s": -1.0}, {"loop_period_s": 0.0}, {"wheel": 7}])
def test_bad_input_raises(kw):
    with pytest.raises(ValueError):
        lifted_wheel_response(**kw)
