"""Ziegler-Nichols tuning (Sec. 4.2): inflection tangent, PT2 fit, impulse path, rule tables, YAML, figure."""

import math

import numpy as np
import pytest
import yaml

from erforce_motion.tuning import (
    TangentTimes,
    fit_pt2,
    impulse_to_step,
    plot_tuning,
    pt2_tangent_times,
    rule_gains,
    run_tuning_experiment,
    tangent_times_from_samples,
    write_gains_yaml,
)


def analytic_step(t, k, t1, t2):
    return k * (1.0 - (t1 * np.exp(-t / t1) - t2 * np.exp(-t / t2)) / (t1 - t2))


@pytest.mark.parametrize("k, t1, t2", [(2.0, 0.5, 0.1), (7.0, 0.04, 0.0004), (-1.5, 1.0, 0.9)])
def test_tangent_times_match_numeric_reading_of_the_analytic_response(k, t1, t2):
    t = np.linspace(0.0, 10 * t1, 400001)
    y = analytic_step(t, k, t1, t2)
    dy = np.gradient(y, t)
    i = int(np.argmax(dy * np.sign(k)))
    tu_num = t[i] - y[i] / dy[i]
    tg_num = k / dy[i]
    tt = pt2_tangent_times(k, t1, t2)
    assert tt.t_inflection_s == pytest.approx(t1 * t2 * math.log(t1 / t2) / (t1 - t2))
    assert tt.t_inflection_s == pytest.approx(t[i], abs=2 * (t[1] - t[0]))
    assert tt.delay_time_tu_s == pytest.approx(tu_num, rel=1e-4)
    assert tt.balance_time_tg_s == pytest.approx(tg_num, rel=1e-6)
    sampled = tangent_times_from_samples(t, y, gain=k)
    assert sampled.delay_time_tu_s == pytest.approx(tt.delay_time_tu_s, rel=1e-3)


def test_equal_time_constants_and_dead_time():
    tt = pt2_tangent_times(1.0, 0.2, 0.2, dead_time_s=0.05)
    # double pole: inflection at T, y = 1 - 2/e, slope = 1/(T e)
    assert tt.t_inflection_s == pytest.approx(0.25)
    assert tt.slope_per_s == pytest.approx(1.0 / (0.2 * math.e))
    assert tt.balance_time_tg_s == pytest.approx(0.2 * math.e)
    assert tt.delay_time_tu_s == pytest.approx(0.05 + 0.2 - (1 - 2 / math.e) * 0.2 * math.e)


def test_fit_recovers_pt2_from_noisy_samples():
    rng = np.random.default_rng(7)
    t = np.linspace(0.0, 3.0, 600)
    y = analytic_step(t, 2.5, 0.4, 0.08) + rng.normal(0.0, 0.01 * 2.5, t.size)
    fit = fit_pt2(t, y)
    assert fit.gain == pytest.approx(2.5, rel=0.02)
    assert fit.t1_s == pytest.approx(0.4, rel=0.05)
    assert fit.t2_s == pytest.approx(0.08, rel=0.15)
    assert fit.rmse == pytest.approx(0.025, rel=0.2)


def test_fit_with_dead_time_and_input_amplitude():
    t = np.linspace(0.0, 2.0, 800)
    y = 3.0 * analytic_step(np.maximum(t - 0.1, 0.0), 1.2, 0.3, 0.05)  # step of amplitude 3
    fit = fit_pt2(t, y, with_dead_time=True, input_amplitude=3.0)
    assert fit.gain == pytest.approx(1.2, rel=1e-3)
    assert fit.dead_time_s == pytest.approx(0.1, abs=2e-3)
    assert fit.t1_s == pytest.approx(0.3, rel=1e-2)


def test_impulse_response_integrates_to_the_step_response():
    k, t1, t2 = 2.0, 0.5, 0.1
    t = np.linspace(0.0, 4.0, 4001)
    impulse = 0.3 * k * (np.exp(-t / t1) - np.exp(-t / t2)) / (t1 - t2)  # impulse of area 0.3
    np.testing.assert_allclose(impulse_to_step(t, impulse, 0.3), analytic_step(t, k, t1, t2), atol=1e-5)
    result = run_tuning_experiment(lambda dt, dur: (t, impulse), input_amplitude=0.3,
                                   response_kind="impulse", with_dead_time=False)
    assert result.fit.t1_s == pytest.approx(t1, rel=1e-3)
    assert result.fit.t2_s == pytest.approx(t2, rel=1e-3)


def test_rule_tables_textbook_numbers():
    # K = 2, Tu = 0.5, Tg = 5 -> Tg/(K Tu) = 5
    tt = TangentTimes(0.0, 0.0, 0.4, 0.5, 5.0, 2.0)
    expect = {
        ("zn", "P"): (5.0, 0.0, 0.0),
        ("zn", "PI"): (4.5, 4.5 / (3.33 * 0.5), 0.0),
        ("zn", "PID"): (6.0, 6.0, 1.5),  # Tn = 2 Tu = 1, Tv = 0.5 Tu = 0.25
        ("chr_0", "P"): (1.5, 0.0, 0.0),
        ("chr_0", "PI"): (1.75, 1.75 / 6.0, 0.0),  # Tn = 1.2 Tg
        ("chr_0", "PID"): (3.0, 0.6, 0.75),  # Tn = Tg, Tv = 0.5 Tu
        ("chr_20", "P"): (3.5, 0.0, 0.0),
        ("chr_20", "PI"): (3.0, 0.6, 0.0),  # Tn = Tg
        ("chr_20", "PID"): (4.75, 4.75 / 6.75, 4.75 * 0.235),  # Tn = 1.35 Tg, Tv = 0.47 Tu
    }
    for (rule, structure), (kp, ki, kd) in expect.items():
        g = rule_gains(tt, rule, structure)
        assert (g.kp, g.ki, g.kd) == pytest.approx((kp, ki, kd)), (rule, structure)


def test_rule_bad_input():
    tt = TangentTimes(0.0, 0.0, 0.4, 0.5, 5.0, 2.0)
    with pytest.raises(ValueError):
        rule_gains(tt, "cohen_coon")
    with pytest.raises(ValueError):
        rule_gains(tt, "zn", "PD")
    with pytest.raises(ValueError):
        rule_gains(TangentTimes(0.0, 0.0, 0.4, -0.5, 5.0, 2.0))


def test_default_experiment_matches_the_motor_physics():
    r = run_tuning_experiment(duration_s=0.3)
    # K = R/(k_e gear) per ampere (the linear actuator applies R*i volts), less a little friction
    k_ideal = 0.94 / (0.036 * 3.6)
    assert 0.95 * k_ideal < r.fit.gain < k_ideal
    # T1 = J R / (gear^2 eta k_t k_e) with the lumped load inertia
    j = 2.0e-5 + 3.6**2 * 1.35e-5 + 2.6 * 0.0275**2 / 4
    assert r.fit.t1_s == pytest.approx(j * 0.94 / (3.6**2 * 0.9 * 0.036**2), rel=0.05)
    assert r.fit.dead_time_s == pytest.approx(0.001, abs=3e-4)  # the one-period loop delay
    assert r.gains["chr_0"]["PI"].kp > 0


def test_bad_series_raise():
    t = np.linspace(0, 1, 50)
    with pytest.raises(ValueError):
        fit_pt2(t, np.ones(49))
    with pytest.raises(ValueError):
        fit_pt2(t[::-1], np.ones(50))
    y = np.ones(50)
    y[3] = math.nan
    with pytest.raises(ValueError):
        fit_pt2(t, y)
    with pytest.raises(ValueError):
        impulse_to_step(t, np.ones(50), 0.0)
    with pytest.raises(ValueError):
        pt2_tangent_times(1.0, -0.1, 0.2)
    with pytest.raises(ValueError):
        run_tuning_experiment(lambda dt, dur: (t, t), response_kind="ramp")


def test_write_gains_yaml(tmp_path):
    path = write_gains_yaml(tmp_path / "gains.yaml", "motor_boards",
                            {"speed_kp_a_per_radps": 1.76, "speed_ki_a_per_rad": np.float64(33.5)})
    text = path.read_text()
    assert text.startswith("motor_boards:\n  ros__parameters:\n    speed_kp_a_per_radps: 1.76\n")
    assert yaml.safe_load(text) == {
        "motor_boards": {"ros__parameters": {"speed_kp_a_per_radps": 1.76, "speed_ki_a_per_rad": 33.5}}}
    with pytest.raises(ValueError):
        write_gains_yaml(tmp_path / "x.yaml", "bad name", {"a": 1.0})
    with pytest.raises(ValueError):
        write_gains_yaml(tmp_path / "x.yaml", "node", {"a": math.nan})


def test_plot_writes_png(tmp_path):
    t = np.linspace(0.0, 3.0, 300)
    r = run_tuning_experiment(lambda dt, dur: (t, analytic_step(t, 1.0, 0.4, 0.1)), input_amplitude=1.0)
    out = plot_tuning(r, tmp_path / "fig4.png")
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
