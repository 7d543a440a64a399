"""PID: hand-computed sequences, anti-windup, derivative kick, bumpless reset, deadband, bad input."""

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from erforce_motion.pid import Pid, PidConfig


def run(pid, setpoints, measurements, dt=0.1, **kw):
    return [float(pid.step(s, m, dt, **kw)[0]) for s, m in zip(setpoints, measurements, strict=True)]


def test_pi_constant_error_hand_computed():
    # kp=2, ki=1, dt=0.1, e=1: u_k = 2 + 0.1*(k-1) (integrator advanced after the output)
    pid = Pid(PidConfig(kp=2.0, ki=1.0))
    assert run(pid, [1.0] * 4, [0.0] * 4) == pytest.approx([2.0, 2.1, 2.2, 2.3])


def test_pid_changing_measurement_hand_computed():
    # kp=2, ki=1, kd=0.5, derivative filter tau=0.1 s, dt=0.1 -> alpha = 0.1/(0.1+0.1) = 0.5
    # y = 0, 0.5, 0.8, 0.9 ; e = 1, 0.5, 0.2, 0.1
    # step1: P=2,   I=0,    d=0 (no history)                         u=2.0
    # step2: P=1,   I=0.1,  raw=-5, d=0+0.5*(-5-0)=-2.5, D=-1.25     u=-0.15
    # step3: P=0.4, I=0.15, raw=-3, d=-2.5+0.5*(-3+2.5)=-2.75, D=-1.375  u=-0.825
    # step4: P=0.2, I=0.17, raw=-1, d=-2.75+0.5*(-1+2.75)=-1.875, D=-0.9375  u=-0.5675
    pid = Pid(PidConfig(kp=2.0, ki=1.0, kd=0.5, derivative_filter_tau_s=0.1))
    out = run(pid, [1.0] * 4, [0.0, 0.5, 0.8, 0.9])
    assert out == pytest.approx([2.0, -0.15, -0.825, -0.5675])


def test_feedforward_added_before_saturation():
    pid = Pid(PidConfig(kp=1.0, output_min=-1.0, output_max=1.0))
    assert pid.step(0.2, 0.0, 0.01, feedforward=0.5)[0] == pytest.approx(0.7)
    assert pid.step(0.2, 0.0, 0.01, feedforward=5.0)[0] == pytest.approx(1.0)
    assert pid.status.saturated_high[0] and not pid.status.saturated_low[0]


def test_vectorized_channels_and_per_channel_gains():
    pid = Pid(PidConfig(kp=(1.0, 2.0, 3.0), ki=(0.0, 1.0, 0.0), n_channels=3))
    u1 = pid.step([1.0, 1.0, 1.0], [0.0, 0.0, 0.5], 0.1)
    u2 = pid.step([1.0, 1.0, 1.0], [0.0, 0.0, 0.5], 0.1)
    np.testing.assert_allclose(u1, [1.0, 2.0, 1.5])
    np.testing.assert_allclose(u2, [1.0, 2.1, 1.5])


@given(st.lists(st.floats(-5, 5), min_size=1, max_size=20), st.floats(0.001, 0.5))
def test_p_only_is_kp_times_error(errors, dt):
    pid = Pid(PidConfig(kp=3.0))
    for e in errors:
        assert pid.step(e, 0.0, dt)[0] == pytest.approx(3.0 * e)


def _windup_run(mode, kt=None):
    # saturated for 20 steps (setpoint 10 unreachable), then setpoint drops to 0.
    pid = Pid(PidConfig(kp=1.0, ki=1.0, output_min=-1.0, output_max=1.0, anti_windup=mode,
                        tracking_gain_kt=kt))
    integ = []
    for _ in range(20):
        pid.step(10.0, 0.0, 0.1)
        integ.append(pid.integrator[0])
    after = [float(pid.step(0.0, 0.5, 0.1)[0]) for _ in range(10)]
    return integ, after


def test_clamp_stops_integration_in_saturation():
    # step1: v = 10 + 0 = 10 > 1 and e > 0: blocked -> I stays 0 forever while saturated
    integ, after = _windup_run("clamp")
    assert integ == [0.0] * 20
    # recovers at once: u = kp*(0 - 0.5) + I = -0.5
    assert after[0] == pytest.approx(-0.5)


def test_back_calculation_bounds_integrator_hand_computed():
    # kt = 2: I1 = 0 + 1*10*0.1 + 2*(1-10)*0.1 = -0.8 (pulled down by the saturation excess)
    pid = Pid(PidConfig(kp=1.0, ki=1.0, output_min=-1.0, output_max=1.0,
                        anti_windup="back_calculation", tracking_gain_kt=2.0))
    pid.step(10.0, 0.0, 0.1)
    assert pid.integrator[0] == pytest.approx(-0.8)
    # I2: v = 10 - 0.8 = 9.2, u = 1 -> I = -0.8 + 1.0 + 2*(1-9.2)*0.1 = -1.44
    pid.step(10.0, 0.0, 0.1)
    assert pid.integrator[0] == pytest.approx(-1.44)


def test_anti_windup_recovers_faster_than_plain_integration():
    # plain integration: clamp mode with no output limits is the naive integrator; with an
    # integrator limit at the output limit both "anti-windup" variants must beat it
    def settle_steps(cfg):
        pid = Pid(cfg)
        y = 0.0
        for _ in range(200):  # long saturation: plant output stuck (e.g. stalled)
            pid.step(10.0, y, 0.01)
        n = 0
        while pid.step(0.0, 1.0, 0.01)[0] > 0.0 and n < 100000:  # error -1 drains the integrator
            n += 1
        return n

    naive = PidConfig(kp=1.0, ki=5.0)  # no limits: integrator grows to 100
    naive_n = settle_steps(naive)
    assert naive_n > 1000  # I = 100 drains at ki*1*dt = 0.05 per step
    for mode in ("clamp", "back_calculation"):
        n = settle_steps(PidConfig(kp=1.0, ki=5.0, output_min=-2.0, output_max=2.0, anti_windup=mode))
        assert n < naive_n / 10


def test_integrator_limits():
    pid = Pid(PidConfig(kp=1.0, ki=10.0, integrator_min=-0.3, integrator_max=0.3))
    for _ in range(50):
        pid.step(1.0, 0.0, 0.1)
    assert pid.integrator[0] == pytest.approx(0.3)


def test_no_derivative_kick_on_setpoint_step():
    pid = Pid(PidConfig(kp=1.0, kd=10.0))
    pid.step(0.0, 1.0, 0.01)
    u = pid.step(5.0, 1.0, 0.01)[0]  # setpoint jumps, measurement constant
    assert u == pytest.approx(4.0)  # only P: D acts on the measurement
    assert pid.status.d_term[0] == 0.0


def test_derivative_on_measurement_sign():
    pid = Pid(PidConfig(kp=1.0, kd=1.0))
    pid.step(0.0, 0.0, 0.1)
    # measurement rises by 0.2 in 0.1 s: D = -1 * 2 = -2, P = -0.2
    assert pid.step(0.0, 0.2, 0.1)[0] == pytest.approx(-2.2)


def test_bumpless_reset():
    pid = Pid(PidConfig(kp=2.0, ki=3.0, kd=0.5, output_min=-10, output_max=10, n_channels=2))
    for k in range(10):
        pid.step([1.0, -1.0], [0.1 * k, 0.0], 0.01)
    pid.reset(output_hold=[4.0, -3.0], measurement=[0.3, 0.2], setpoint=[1.0, 0.5], feedforward=[0.5, 0.0])
    u = pid.step([1.0, 0.5], [0.3, 0.2], 0.01, feedforward=[0.5, 0.0])
    np.testing.assert_allclose(u, [4.0, -3.0])


def test_reset_without_setpoint_holds_output_at_zero_error():
    pid = Pid(PidConfig(kp=2.0, ki=1.0))
    pid.reset(output_hold=1.5, measurement=2.0)
    assert pid.step(2.0, 2.0, 0.01)[0] == pytest.approx(1.5)


def test_deadband_hand_computed():
    pid = Pid(PidConfig(kp=2.0, deadband=0.1))
    assert pid.step(0.05, 0.0, 0.01)[0] == 0.0
    assert pid.step(-0.1, 0.0, 0.01)[0] == 0.0
    assert pid.step(0.3, 0.0, 0.01)[0] == pytest.approx(0.4)  # 2 * (0.3 - 0.1)
    assert pid.step(-0.3, 0.0, 0.01)[0] == pytest.approx(-0.4)


def test_dynamic_output_limits_override():
    pid = Pid(PidConfig(kp=1.0, ki=1.0, n_channels=2))
    u = pid.step([5.0, -5.0], [0.0, 0.0], 0.1, output_min=np.array([-1.0, -2.0]), output_max=np.array([1.0, 2.0]))
    np.testing.assert_allclose(u, [1.0, -2.0])
    np.testing.assert_array_equal(pid.integrator, [0.0, 0.0])  # clamp: blocked in saturation


def test_hold_integrator():
    pid = Pid(PidConfig(kp=1.0, ki=1.0, n_channels=2))
    pid.step([1.0, 1.0], [0.0, 0.0], 0.1, hold_integrator=np.array([True, False]))
    np.testing.assert_allclose(pid.integrator, [0.0, 0.1])
    pid.step([1.0, 1.0], [0.0, 0.0], 0.1, hold_integrator=True)
    np.testing.assert_allclose(pid.integrator, [0.0, 0.1])


@pytest.mark.parametrize("dt", [0.0, -0.01, math.nan, math.inf])
def test_bad_dt_raises(dt):
    pid = Pid(PidConfig(kp=1.0))
    with pytest.raises(ValueError):
        pid.step(1.0, 0.0, dt)


@pytest.mark.filterwarnings("ignore:overflow:RuntimeWarning")
@pytest.mark.parametrize("sp, y, ff", [(math.nan, 0.0, 0.0), (0.0, math.inf, 0.0), (0.0, 0.0, math.nan),
                                       (1e308, -1e308, 0.0)])
def test_non_finite_inputs_raise_and_keep_state(sp, y, ff):
    pid = Pid(PidConfig(kp=1.0, ki=1.0))
    pid.step(1.0, 0.0, 0.1)
    before = pid.integrator
    with pytest.raises(ValueError):
        pid.step(sp, y, 0.1, feedforward=ff)
    np.testing.assert_array_equal(pid.integrator, before)


def test_wrong_length_raises():
    pid = Pid(PidConfig(kp=1.0, n_channels=3))
    with pytest.raises(ValueError):
        pid.step([1.0, 2.0], 0.0, 0.1)


@pytest.mark.parametrize("kw", [
    {"kp": 0.0}, {"kp": -1.0}, {"ki": -1.0}, {"kd": -0.1}, {"kp": math.nan}, {"ki": math.inf},
    {"output_min": 1.0, "output_max": 1.0}, {"integrator_min": 2.0, "integrator_max": 1.0},
    {"output_min": math.nan}, {"anti_windup": "magic"}, {"deadband": -1.0},
    {"derivative_filter_tau_s": -1.0}, {"n_channels": 0}, {"kp": (1.0, 2.0), "n_channels": 3},
    {"tracking_gain_kt": -1.0},
])
def test_bad_config_raises(kw):
    with pytest.raises(ValueError):
        PidConfig(**kw)
