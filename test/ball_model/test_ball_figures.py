"""The Sec. 5 figures are written (PNG) and quick."""

from erforce_ball_model.figures import main, simulate_sphere_shot


def test_figures_written(tmp_path):
    assert main(["--out", str(tmp_path / "figs")]) == 0
    for name in ("ball_vt.png", "robot_vs_ball_time.png"):
        data = (tmp_path / "figs" / name).read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 10_000


def test_sphere_simulation_switches_at_0_6_v_shoot():
    # Inertia factor 2/3 gives v_switch = v_shoot / (1 + 2/3) = 0.6 v_shoot (physics, not the model).
    t, _, v = simulate_sphere_shot(3.3, 3.0, noise_m=0.0, dropout=0.0)
    dv = -(v[1:] - v[:-1]) / (t[1:] - t[:-1])
    moving = (t[1:] > 0.05) & (v[1:] > 0.1)
    slide = moving & (v[1:] > 2.0)
    roll = moving & (v[:-1] < 1.97)
    assert abs(dv[slide].mean() - 2.5) < 0.05 and abs(dv[roll].mean() - 0.3) < 0.02
