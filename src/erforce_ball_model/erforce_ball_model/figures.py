"""Paper-style figures for Sec. 5 (ER-Force ETDP 2016, Fig. 5 and Fig. 7): ``ball_figures --out DIR``.

(a) ``ball_vt.png`` (Fig. 5): speed over time of a 3.3 m/s shot. The observations come from an
    independent simulation of a sphere sliding with Coulomb friction until it rolls, then rolling
    with rolling resistance (deceleration 2.5 and 0.3 m/s^2, inertia factor I = 2/3 m r^2 so that
    the ball rolls at 0.6 v_shoot), sampled at 70 Hz with 2 mm Gaussian noise and ~5 % dropouts,
    speeds from ``BallTracker``. The line is the two-phase model fitted to the same observations
    by ``identification.fit_shots``. Later the simulator will provide the observations.
(b) ``robot_vs_ball_time.png`` (Fig. 7 for the Fig. 6 situation): ball at (-2.0, 0.0) m rolling
    to the right (+x) at 2.0 m/s; robot at rest at (-0.5, 0.3) m, a_max = 2.0 m/s^2,
    v_max = 2.0 m/s, catching with the dribbler while facing left (robot centre 0.0815 m to the
    right of the ball). Robot time and ball time over the ball's travelled distance: a short early
    window (about 0.26 m, from 1.47 m) where the robot can step into the ball's path, and the later
    catch-up point (about 3.4 m), like the paper.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

from erforce_ball_model.ball_model import BallTrajectory
from erforce_ball_model.catch_time import RobotLimits, robot_time_curve, robot_time_to_ball
from erforce_ball_model.identification import Shot, fit_shots
from erforce_ball_model.tracking import BallTracker

__all__ = ["fig6_curves", "figure_catch", "figure_vt", "main", "simulate_sphere_shot"]

FIG6_BALL_START_M = (-2.0, 0.0)
FIG6_BALL_SPEED_MPS = 2.0
FIG6_ROBOT_M = (-0.5, 0.3)
FIG6_LIMITS = RobotLimits(a_max_mps2=2.0, v_max_mps=2.0)
FIG6_FACING_RAD = math.pi


def simulate_sphere_shot(
    v_shoot_mps: float,
    duration_s: float,
    fps: float = 70.0,
    noise_m: float = 0.002,
    dropout: float = 0.05,
    pre_kick_s: float = 0.1,
    noise_seed: int = 0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Vision frames (t, x, y) and true speeds of a ball kicked along +x at t = 0.

    Integrates linear and angular velocity separately (semi-implicit Euler, 0.1 ms): while the
    contact point slips, friction mu*g slows the ball and spins it up; once v = omega*r it rolls
    with rolling resistance. Independent of the closed-form model in ``ball_model``.
    """
    rng = np.random.default_rng(noise_seed)
    mu_g, roll_decel, k_inertia, radius = 2.5, 0.3, 2.0 / 3.0, 0.0215
    dt = 1e-4
    frames = np.arange(-pre_kick_s + rng.uniform(0.0, 1.0 / fps), duration_s, 1.0 / fps)
    n_steps = math.ceil(duration_s / dt)
    v, omega, x = v_shoot_mps, 0.0, 0.0
    xs, vs = np.empty(n_steps + 1), np.empty(n_steps + 1)
    xs[0], vs[0] = 0.0, v
    for i in range(n_steps):
        if v - omega * radius > 1e-9:  # slipping
            v -= mu_g * dt
            omega += mu_g / (k_inertia * radius) * dt
            if v < omega * radius:  # overshot the no-slip point within the step: snap to it
                v = (v + k_inertia * omega * radius) / (1.0 + k_inertia)  # keeps L about the contact
                omega = v / radius
        else:
            v = max(v - roll_decel * dt, 0.0)
            omega = v / radius
        x += v * dt
        xs[i + 1], vs[i + 1] = x, v
    grid = np.arange(n_steps + 1) * dt
    x_obs = np.where(frames < 0.0, 0.0, np.interp(frames, grid, xs))
    v_true = np.where(frames < 0.0, 0.0, np.interp(frames, grid, vs))
    keep = rng.random(frames.size) >= dropout
    noise = rng.normal(0.0, noise_m, (frames.size, 2))
    return frames[keep], np.stack([x_obs + noise[:, 0], noise[:, 1]], axis=-1)[keep], v_true[keep]


def finish_figure(fig, ax, path: Path, **legend) -> Path:
    """Grid, legend (``legend``: its keyword arguments, fontsize 8 unless given), tight layout; the figure saved
    as a 120 dpi PNG at ``path`` and closed. The figures' and reports' common end."""
    import matplotlib.pyplot as plt

    ax.grid(alpha=0.3)
    ax.legend(**{"fontsize": 8, **legend})
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def figure_vt(out: Path) -> Path:
    import matplotlib.pyplot as plt

    t, xy, _ = simulate_sphere_shot(3.3, 6.0)
    tracker = BallTracker()
    speeds = []
    for ti, (xi, yi) in zip(t, xy, strict=True):
        tracker.update(ti, xi, yi)
        speeds.append(float(np.hypot(*tracker.velocity_mps)))
    fit = fit_shots([Shot(t, xy)])
    p = fit.params
    model = BallTrajectory([0.0, 0.0], [3.3, 0.0], 3.3, p)
    t_model = np.linspace(0.0, min(6.0, float(model.stop_time_s)), 400)
    fig, ax = plt.subplots(figsize=(7, 4))
    ax.plot(t, speeds, ".", ms=3, color="tab:gray", label="observed (tracker, 70 Hz, 2 mm noise)")
    ax.plot(t_model, model.speed_at(t_model), "r-", lw=2, label="two-phase model (fitted)")
    ax.axvline(float(model.switch_time_s), color="r", ls=":", lw=1)
    ax.set_xlabel("time since kick [s]")
    ax.set_ylabel("ball speed [m/s]")
    ax.set_title(
        f"3.3 m/s shot: a_slide={p.a_slide_mps2:.2f}±{fit.a_slide_std:.2f}, "
        f"a_roll={p.a_roll_mps2:.3f}±{fit.a_roll_std:.3f} m/s², c_switch={p.c_switch:.3f}",
        fontsize=9,
    )
    return finish_figure(fig, ax, out / "ball_vt.png")


def fig6_curves(num: int = 1500) -> dict:
    """Robot time and ball time over the ball's travelled distance for the Fig. 6 situation."""
    ball = BallTrajectory(FIG6_BALL_START_M, [FIG6_BALL_SPEED_MPS, 0.0], FIG6_BALL_SPEED_MPS / 0.6)
    dist = np.linspace(0.0, float(ball.stop_distance_m), num)
    t_ball = ball.time_to_distance(dist)
    t_robot = robot_time_curve(ball, t_ball, FIG6_ROBOT_M, (0.0, 0.0), FIG6_LIMITS, facing_rad=FIG6_FACING_RAD,
                               dribbler_offset_m=0.0815)
    catch = robot_time_to_ball(ball, FIG6_ROBOT_M, (0.0, 0.0), FIG6_LIMITS, FIG6_FACING_RAD, unbounded=True,
                               dribbler_offset_m=0.0815)
    return {"ball": ball, "dist": dist, "t_ball": t_ball, "t_robot": t_robot, "catch": catch}


def figure_catch(out: Path) -> Path:
    import matplotlib.pyplot as plt

    c = fig6_curves()
    dist, t_ball, t_robot = c["dist"], c["t_ball"], c["t_robot"]
    t_catch = c["catch"].time_s
    d_catch = float(c["ball"].distance_at(t_catch))
    fig, ax = plt.subplots(figsize=(7, 4))
    ax.plot(dist, t_ball, label="ball time", color="tab:blue")
    ax.plot(dist, t_robot, label="robot time (robotTimeToPos)", color="tab:orange")
    ax.fill_between(dist, 0, t_ball.max(), where=t_robot <= t_ball, color="tab:green", alpha=0.2,
                    label="robot first (catch possible)")
    ax.axvline(d_catch, color="k", ls="--", lw=1, label=f"robotTimeToBall: {t_catch:.3f} s at {d_catch:.2f} m")
    ax.set_xlabel("distance travelled by the ball [m]")
    ax.set_ylabel("time [s]")
    ax.set_ylim(0, min(8.0, float(t_ball.max())))
    ax.set_title(
        "Fig. 6/7: ball (-2.0, 0) → +x at 2.0 m/s rolling; robot at rest (-0.5, 0.3),\n"
        "a_max 2.0 m/s², v_max 2.0 m/s, facing left, dribbler offset 0.0815 m",
        fontsize=9,
    )
    return finish_figure(fig, ax, out / "robot_vs_ball_time.png", loc="upper left")


def main(argv: list[str] | None = None) -> int:
    import matplotlib

    matplotlib.use("Agg")
    parser = argparse.ArgumentParser(prog="ball_figures", description="Sec. 5 figures as PNG")
    parser.add_argument("--out", default="figures", help="output folder (default ./figures)")
    args = parser.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    for path in (figure_vt(out), figure_catch(out)):
        print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())

