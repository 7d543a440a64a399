"""The demo's report: PNG plots and a markdown summary from the series the demo gathered.

- ball_vt.png: ground-truth ball speed over time with the two-phase model the predictor
  used (its tracked v_shoot and model parameters), for the longest free roll;
- catch_prediction.png: the predicted catch time (absolute) over time vs. the actual contact;
- wheel_speeds.png and motor_currents.png (with the paper's 1.3 A limit);
- summary.md: one row per scene, the catch rate over reachable scenes, latency, real-time factor.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from erforce_ball_model.ball_model import BallModelParams, BallTrajectory
from erforce_ball_model.figures import finish_figure
from erforce_interfaces.wire.robot_config import RobotConfig


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _percentile_ms(values, q: float) -> float:
    return float(np.percentile(np.asarray(values) * 1e3, q)) if len(values) else float("nan")


def plot_ball_vt(out: Path, results, series) -> Path | None:
    """The scene whose ball rolled free the longest, observed vs. the model."""
    truth = np.array(series.ball_truth)
    if truth.size == 0:
        return None
    best = None
    for r in results:
        end = r.actual_s if r.actual_s is not None else r.t_end_s
        seg = truth[(truth[:, 0] >= r.t_start_s) & (truth[:, 0] <= end)]
        if len(seg) > 10 and (best is None or seg[-1, 0] - seg[0, 0] > best[1][-1, 0] - best[1][0, 0]):
            best = (r, seg)
    if best is None:
        return None
    r, seg = best
    plt = _plt()
    speed = np.hypot(seg[:, 3], seg[:, 4])
    t = seg[:, 0] - seg[0, 0]
    fig, ax = plt.subplots(figsize=(7, 4))
    ax.plot(t, speed, ".", ms=2, label="ball speed (ground truth, 100 Hz)")
    state = np.array([s for s in series.ball_state if seg[0, 0] + 0.1 <= s[0] <= seg[-1, 0]])
    v_shoot = [v for tv, v in series.v_shoot if seg[0, 0] + 0.1 <= tv <= seg[-1, 0]]
    params = [p for p in series.model_params if p[0] <= seg[-1, 0]]
    model = BallModelParams(*params[-1][1:4]) if params else BallModelParams()
    if len(state) and v_shoot:
        t0, x, y, vx, vy = state[0]
        traj = BallTrajectory(np.array([x, y]), np.array([vx, vy]), max(v_shoot[0], float(np.hypot(vx, vy))), model)
        tq = np.linspace(0.0, seg[-1, 0] - t0, 400)
        ax.plot(tq + (t0 - seg[0, 0]), traj.speed_at(tq), "-", lw=1.5,
                label=f"two-phase model (a_slide {model.a_slide_mps2:.2f}, a_roll {model.a_roll_mps2:.2f} m/s², "
                      f"c_switch {model.c_switch:.2f})")
    ax.set_xlabel("time since the scene started [s]")
    ax.set_ylabel("ball speed [m/s]")
    ax.set_title(f"Ball v–t: {r.scene.name}", fontsize=9)
    return finish_figure(fig, ax, out / "ball_vt.png")


def plot_catch_prediction(out: Path, results, series) -> Path | None:
    preds = np.array(series.predictions)
    if preds.size == 0:
        return None
    plt = _plt()
    fig, ax = plt.subplots(figsize=(8, 4))
    for r in results:
        sel = preds[(preds[:, 0] >= r.t_start_s) & (preds[:, 0] <= r.t_end_s) & (preds[:, 1] >= 0.0)]
        if len(sel):
            ax.plot(sel[:, 0], sel[:, 0] + sel[:, 1], ".", ms=2, color="tab:blue")
        if r.actual_s is not None:
            ax.hlines(r.actual_s, r.t_start_s, r.actual_s, colors="tab:red", lw=1)
    ax.plot([], [], ".", color="tab:blue", label="predicted catch time (observation stamp + catch_time)")
    ax.plot([], [], "-", color="tab:red", label="actual contact (light barrier)")
    ax.set_xlabel("simulation time at prediction [s]")
    ax.set_ylabel("absolute catch time [s]")
    ax.set_title("robot_0: catch-time prediction over time vs. the truth", fontsize=9)
    return finish_figure(fig, ax, out / "catch_prediction.png")


def plot_motors(out: Path, series, robot: RobotConfig) -> list[Path]:
    motors = np.array(series.motors)
    if motors.size == 0:
        return []
    plt = _plt()
    n = robot.num_wheels
    paths = []
    fig, ax = plt.subplots(figsize=(8, 3.5))
    for k in range(n):
        ax.plot(motors[:, 0], motors[:, 1 + 2 * n + k], lw=0.8, label=f"wheel_{k}")
    ax.set_xlabel("simulation time [s]")
    ax.set_ylabel("wheel speed [rad/s]")
    ax.set_title("robot_0 wheel speeds (ground truth)", fontsize=9)
    paths.append(finish_figure(fig, ax, out / "wheel_speeds.png", ncol=n))

    fig, ax = plt.subplots(figsize=(8, 3.5))
    for k in range(n):
        ax.plot(motors[:, 0], np.abs(motors[:, 1 + k]), lw=0.6, alpha=0.6, label=f"|i| wheel_{k}")
    status = np.array(series.motor_status)
    if status.size:
        for k in range(n):
            ax.plot(status[:, 0], status[:, 1 + k], lw=1.5, label=f"10 s average, wheel_{k}")
    ax.axhline(robot.continuous_current_limit_a, color="k", ls="--", lw=1,
               label=f"limit {robot.continuous_current_limit_a:g} A")
    ax.set_xlabel("simulation time [s]")
    ax.set_ylabel("motor current [A]")
    ax.set_title("robot_0 motor currents and the thermal limit", fontsize=9)
    paths.append(finish_figure(fig, ax, out / "motor_currents.png", fontsize=7, ncol=2))
    return paths


def summary_markdown(results, series, real_time_factor: float, recording: str) -> str:
    reachable = [r for r in results if r.reachable]
    caught = [r for r in reachable if r.caught]
    errors = [abs(r.error_s) for r in results if r.error_s is not None]
    rate = f"{len(caught)}/{len(reachable)} reachable scenes caught" + (
        f" ({100 * len(caught) / len(reachable):.0f} %, target >= 90 %: "
        f"{'met' if len(caught) >= 0.9 * len(reachable) else 'not met'})" if reachable else "")
    lines = [
        f"Demo summary: {rate}; real-time factor {real_time_factor:.2f} (lockstep); "
        f"vision → catch time p50 {_percentile_ms(series.catch_time_latency_s, 50):.2f} ms, "
        f"p99 {_percentile_ms(series.catch_time_latency_s, 99):.2f} ms "
        f"(→ catch point p50 {_percentile_ms(series.catch_point_latency_s, 50):.2f} ms, "
        f"p99 {_percentile_ms(series.catch_point_latency_s, 99):.2f} ms)",
        "",
        "| # | scene | predicted catch [s] | actual contact [s] | error [ms] | caught | reachable |",
        "|---|---|---|---|---|---|---|",
    ]
    for i, r in enumerate(results, 1):
        pred = "never" if r.predicted_s is None else f"{r.predicted_s - r.t_start_s:.3f}"
        act = "—" if r.actual_s is None else f"{r.actual_s - r.t_start_s:.3f}"
        err = "—" if r.error_s is None else f"{r.error_s * 1e3:+.0f}"
        lines.append(f"| {i} | {r.scene.name} | {pred} | {act} | {err} | {r.caught_text} | "
                     f"{'yes' if r.reachable else 'no'} |")
    lines += [
        "",
        "Times are seconds after the kick (or after the Fig. 6 ball was released). The prediction is the ball "
        "predictor's newest catch time for the receiver (robot_0, or the teammate that caught the ball) made "
        "at least 0.3 s before the contact (for a ball not caught: robot_0's, 0.3 s after the kick); the actual "
        "contact is that receiver's light-barrier rising edge. Reachable: caught, or the true ball path passes "
        "a point a receiver could reach in time from its start under the planning limits (robotTimeToPos, "
        "0.1 s reaction).",
        "",
        f"Median |error| over scenes with both: {np.median(errors) * 1e3:.0f} ms" if errors else "",
        f"Recording (rosbag2, MCAP storage, in bag/): {recording}",
    ]
    return "\n".join(lines) + "\n"


def write_report(out: Path, results, series, robot: RobotConfig, real_time_factor: float, recording: str) -> str:
    out.mkdir(parents=True, exist_ok=True)
    plot_ball_vt(out, results, series)
    plot_catch_prediction(out, results, series)
    plot_motors(out, series, robot)
    text = summary_markdown(results, series, real_time_factor, recording)
    (out / "summary.md").write_text(text)
    return text
