"""Identification of a_slide, a_roll, c_switch from shots (paper Sec. 5.2)."""

import numpy as np
import pytest
from ballmodel_sim import observe, simulate

from erforce_ball_model.identification import (
    Shot,
    ShotAccumulator,
    fit_recording,
    fit_shots,
    load_csv,
    main,
    split_shots,
)

TRUE = dict(a_slide=3.0, a_roll=0.4, c_switch=0.65)  # magnitudes; not the model defaults


def make_recording(speeds, seed=0):
    """One recording: the ball rests, is kicked, stops, is kicked again (from where it lies)."""
    rng = np.random.default_rng(seed)
    events, t_k = [], 0.3
    for v in speeds:
        ang = rng.uniform(0, 2 * np.pi)
        events.append((t_k, (v * np.cos(ang), v * np.sin(ang))))
        t_stop = (v - TRUE["c_switch"] * v) / TRUE["a_slide"] + TRUE["c_switch"] * v / TRUE["a_roll"]
        t_k += t_stop + 0.5
    t, pos, _ = simulate(events, t_k, **TRUE)
    ft, xy, _ = observe(t, pos, fps=70.0, noise_m=0.002, dropout=0.03, seed=seed)
    return ft, xy


@pytest.fixture(scope="module")
def recording():
    return make_recording([2.0, 3.3, 4.5, 6.0], seed=1)


def test_fit_recovers_parameters_within_reported_uncertainty(recording):
    ft, xy = recording
    res = fit_recording(ft, xy[:, 0], xy[:, 1])
    assert res.num_shots == 4
    p = res.params
    assert abs(p.a_slide_mps2 + TRUE["a_slide"]) <= 3 * res.a_slide_std
    assert abs(p.a_roll_mps2 + TRUE["a_roll"]) <= 3 * res.a_roll_std
    assert abs(p.c_switch - TRUE["c_switch"]) <= 3 * res.c_switch_std
    # the uncertainty is informative, not huge
    assert res.a_slide_std < 0.1 and res.a_roll_std < 0.01 and res.c_switch_std < 0.01
    assert res.rms_residual_m == pytest.approx(0.002, rel=0.2)  # the vision noise


def test_single_shot_fit():
    ft, xy = make_recording([3.3], seed=2)
    shots = split_shots(ft, xy[:, 0], xy[:, 1])
    assert len(shots) == 1
    res = fit_shots(shots)
    assert abs(res.params.c_switch - TRUE["c_switch"]) <= 3 * res.c_switch_std + 1e-3


def test_online_accumulator_collects_each_shot(recording):
    ft, xy = recording
    acc = ShotAccumulator()
    for ti, (x, y) in zip(ft, xy, strict=True):
        acc.add(ti, x, y)
    acc.finish()
    assert len(acc.shots) == 4
    for shot in acc.shots:  # each shot starts at rest, before the kick
        assert np.hypot(*(shot.xy_m[1] - shot.xy_m[0])) < 0.01
    assert acc.fit().params.a_roll_mps2 == pytest.approx(-TRUE["a_roll"], abs=0.02)
    assert acc.add(ft[-1], 0.0, 0.0).name == "REJECTED_TIME"


def test_cli_prints_fit(tmp_path, capsys, recording):
    ft, xy = recording
    path = tmp_path / "shots.csv"
    rows = "\n".join(f"{t:.6f},{x:.6f},{y:.6f}" for t, (x, y) in zip(ft, xy, strict=True))
    path.write_text("t,x,y\n" + rows + "\n")
    t, x, y = load_csv(path)
    np.testing.assert_allclose(t, ft, atol=1e-6)
    np.testing.assert_allclose(np.stack([x, y], axis=-1), xy, atol=1e-6)
    assert main([str(path)]) == 0
    out = capsys.readouterr().out
    assert "a_slide" in out and "+-" in out and "c_switch" in out


def test_cli_errors(tmp_path, capsys):
    bad = tmp_path / "bad.csv"
    bad.write_text("t,x,y\n0,0,0\nfoo,1,2\n")
    assert main([str(bad)]) == 1
    assert main([str(tmp_path / "missing.csv")]) == 1
    still = tmp_path / "still.csv"
    still.write_text("\n".join(f"{0.014 * i},0.0,0.0" for i in range(50)))
    assert main([str(still)]) == 1
    assert "no complete shot" in capsys.readouterr().err


def test_bad_input():
    t = np.arange(10) * 0.014
    xy = np.zeros((10, 2))
    with pytest.raises(ValueError):
        Shot(t[:5], xy[:5])  # too few
    with pytest.raises(ValueError):
        Shot(t, xy[:9])  # lengths differ
    with pytest.raises(ValueError):
        Shot(t[::-1], xy)  # time backwards
    bad = xy.copy()
    bad[3, 0] = np.nan
    with pytest.raises(ValueError):
        Shot(t, bad)
    with pytest.raises(ValueError):
        fit_shots([])
    with pytest.raises(ValueError):
        split_shots(t, xy[:, 0], xy[:5, 1])
