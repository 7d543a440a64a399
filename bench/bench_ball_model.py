"""Benchmark of the ball-model core (paper Sec. 5): query throughput, catch-time speed and accuracy.

Prints a markdown table (medians over repeats). ``--quick`` for a shorter run. ``run(quick)``
returns the rows (name, value, unit, target, note) for the top-level bench runner.

Accuracy reference: for every (ball, robot) pair a dense search samples the exact reachability
test on a 0.5 ms grid over [0, min(t_stop, t_out)] and bisects the first crossing to < 1 us.
A first window the fast search misses is binned by its width (measured on the dense grid).
"""

from __future__ import annotations

import argparse
import math
import sys
import time

import numpy as np

from erforce_ball_model.ball_model import BallTrajectory
from erforce_ball_model.catch_time import CatchKind, RobotLimits, can_reach_in_time, robot_time_to_ball
from erforce_interfaces.robot_config import FieldConfig

FIELD = FieldConfig.preset("division_b")
OFFSET_M = 0.0815
DENSE_STEP_S = 5e-4


def _random_frame(rng: np.random.Generator, num_robots: int):
    pos = rng.uniform([-4.0, -2.5], [4.0, 2.5])
    speed = rng.uniform(0.3, 6.5)
    ang = rng.uniform(0.0, 2.0 * math.pi)
    vel = speed * np.array([math.cos(ang), math.sin(ang)])
    ball = BallTrajectory(pos, vel, speed * rng.uniform(1.0, 1.7))
    robots = rng.uniform([-4.5, -3.0], [4.5, 3.0], (num_robots, 2))
    # Half of the robots near the ball's path, where catch windows (and narrow ones) occur.
    near = num_robots // 2
    along = rng.uniform(0.0, min(float(ball.stop_distance_m), 5.0), near)
    side = rng.normal(0.0, 0.6, near)
    normal = np.array([-ball.direction[1], ball.direction[0]])
    robots[:near] = pos + along[:, None] * ball.direction + side[:, None] * normal
    robot_vel = rng.normal(0.0, 0.8, (num_robots, 2))
    facing = rng.uniform(0.0, 2.0 * math.pi, num_robots)
    limits = RobotLimits(rng.uniform(1.5, 4.0, num_robots), rng.uniform(1.5, 3.5, num_robots))
    return ball, robots, robot_vel, facing, limits


def bench_queries(quick: bool) -> list[dict]:
    rng = np.random.default_rng(1)
    n_balls, n_times = (300, 300) if quick else (1000, 1000)
    balls = BallTrajectory(rng.uniform(-3, 3, (n_balls, 2)), rng.normal(0, 2, (n_balls, 2)), 4.0)
    times = np.linspace(0.0, 5.0, n_times)
    reps = []
    for _ in range(5):
        t0 = time.perf_counter()
        balls.position_at(times)
        reps.append(time.perf_counter() - t0)
    vec_rate = n_balls * n_times / float(np.median(reps))
    one = BallTrajectory([0.0, 0.0], [3.0, 1.0], 3.5)
    n_scalar = 2000 if quick else 10000
    reps = []
    for _ in range(3):
        t0 = time.perf_counter()
        for i in range(n_scalar):
            one.position_at(i * 1e-3)
        reps.append(time.perf_counter() - t0)
    scalar_rate = n_scalar / float(np.median(reps))
    return [
        dict(name="ball position queries, vectorized", value=vec_rate, unit="queries/s", target=">= 1e7",
             note=f"{n_balls} balls x {n_times} times per call"),
        dict(name="ball position queries, scalar loop", value=scalar_rate, unit="queries/s", target="-",
             note=f"speed-up {vec_rate / scalar_rate:.0f}x"),
    ]


def bench_catch_speed(quick: bool) -> list[dict]:
    rng = np.random.default_rng(2)
    frames = [_random_frame(rng, 22) for _ in range(40 if quick else 200)]
    per_frame = []
    for ball, robots, rv, facing, limits in frames:
        robot_time_to_ball(ball, robots, rv, limits, facing, field=FIELD)  # warm
        t0 = time.perf_counter()
        reps = 5
        for _ in range(reps):
            robot_time_to_ball(ball, robots, rv, limits, facing, field=FIELD)
        per_frame.append((time.perf_counter() - t0) / reps)
    ms = 1e3 * np.array(per_frame)
    return [
        dict(name="robot_time_to_ball, 22 robots/frame (median)", value=float(np.median(ms)), unit="ms",
             target="< 1", note=f"p90 {np.percentile(ms, 90):.2f} ms, {len(frames)} random frames, division B"),
    ]


def _dense_reference(ball, robots, rv, facing, limits):
    """First crossing per robot by dense sampling + bisection; also the first window's width."""
    t_stop = float(ball.stop_time_s)
    t_max = min(t_stop, float(ball.time_to_leave_field(FIELD)))
    grid = np.arange(0.0, t_max, DENSE_STEP_S)
    grid = np.append(grid, t_max)
    start = robots + OFFSET_M * np.stack([np.cos(facing), np.sin(facing)], axis=-1)
    bp = ball.position_at(grid)
    a = limits.a_max_mps2[:, None]
    v = limits.v_max_mps[:, None]
    ok = can_reach_in_time(bp[None] - start[:, None], rv[:, None], grid[None], a, v)
    n = robots.shape[0]
    t_ref = np.full(n, np.inf)
    width = np.zeros(n)
    for r in range(n):
        idx = np.flatnonzero(ok[r])
        if idx.size == 0:
            continue
        k = idx[0]
        if k == 0:
            t_ref[r] = 0.0
        else:
            lo, hi = grid[k - 1], grid[k]
            for _ in range(30):
                mid = 0.5 * (lo + hi)
                good = can_reach_in_time(ball.position_at(mid) - start[r], rv[r], mid, a[r, 0], v[r, 0])
                lo, hi = (lo, mid) if good else (mid, hi)
            t_ref[r] = hi
        gaps = np.flatnonzero(~ok[r, k:])
        width[r] = (gaps[0] if gaps.size else grid.size - k) * DENSE_STEP_S
    return t_ref, width


def bench_catch_accuracy(quick: bool) -> list[dict]:
    rng = np.random.default_rng(3)
    num_frames = 60 if quick else 460  # x 22 robots: 1,320 / 10,120 scenarios
    bins = {"<5 ms": 0, "5-10 ms": 0, "10-20 ms": 0, ">=20 ms": 0}
    errors, scenarios, with_window = [], 0, 0
    for _ in range(num_frames):
        ball, robots, rv, facing, limits = _random_frame(rng, 22)
        res = robot_time_to_ball(ball, robots, rv, limits, facing, field=FIELD, dribbler_offset_m=OFFSET_M)
        t_ref, width = _dense_reference(ball, robots, rv, facing, limits)
        scenarios += robots.shape[0]
        moving = res.kind == CatchKind.MOVING
        for r in range(robots.shape[0]):
            if not np.isfinite(t_ref[r]):
                continue
            with_window += 1
            if moving[r] and res.time_s[r] <= t_ref[r] + 1e-3:
                errors.append(res.time_s[r] - t_ref[r])
                continue
            w = width[r]
            key = "<5 ms" if w < 5e-3 else "5-10 ms" if w < 1e-2 else "10-20 ms" if w < 2e-2 else ">=20 ms"
            bins[key] += 1
    err = np.abs(np.array(errors)) * 1e3
    rows = [
        dict(name="catch-time scenarios (robot x ball)", value=scenarios, unit="count", target=">= 10000",
             note=f"{with_window} with a catch window; dense reference {DENSE_STEP_S * 1e3:g} ms + bisection"),
    ]
    for key, count in bins.items():
        rows.append(dict(name=f"missed first windows, width {key}", value=count, unit="count",
                         target="0" if key == ">=20 ms" else "-", note="grid step 10 ms"))
    rows.append(dict(name="catch-time error vs dense search, max", value=float(err.max()), unit="ms",
                     target="< 1", note=f"p99 {np.percentile(err, 99):.4f} ms over {err.size} found windows"))
    return rows


def run(quick: bool = False) -> list[dict]:
    return bench_queries(quick) + bench_catch_speed(quick) + bench_catch_accuracy(quick)


def _fmt(value) -> str:
    if isinstance(value, int | np.integer):
        return str(int(value))
    if abs(value) >= 1e5:
        return f"{value:.3g}"
    return f"{value:.4g}"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer repeats and scenarios")
    args = parser.parse_args(argv)
    t0 = time.perf_counter()
    rows = run(args.quick)
    print("| benchmark | value | unit | target | note |")
    print("|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['name']} | {_fmt(r['value'])} | {r['unit']} | {r['target']} | {r['note']} |")
    print(f"\n(total {time.perf_counter() - t0:.1f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
