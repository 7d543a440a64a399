"""Simulator core benchmark: physics step cost, real-time factor, kick deviation table (paper Sec. 2.2), chip flight.

Run: .venv/bin/python bench/bench_sim.py [--quick]. Prints a markdown table; `run(quick)` returns the rows.
"""

from __future__ import annotations

import math
import statistics
import sys
import time
import tracemalloc

import numpy as np
from table import bench_main  # bench/table.py: the shared table format

from erforce_interfaces.wire.robot_config import FieldConfig, RobotConfig
from erforce_sim.ball import BallState
from erforce_sim.drivetrain import GRAVITY_MPS2
from erforce_sim.in_process.runner import InProcessRunner
from erforce_sim.kicker import deviation_table
from erforce_sim.plant_setup import PlantSetup
from erforce_sim.world import World
from erforce_sim.world_types import PhysicsParams, RobotSpec

FIELD = FieldConfig.preset("division_a")
CONTROL_DT_S = 0.001


def _layout(n_robots: int) -> list[tuple[float, float]]:
    """Up to 6 on a diagonal (as before), more on a grid of 11 per row (two teams of Division A)."""
    if n_robots <= 6:
        return [(-4.0 + 1.5 * k, -2.0 + 0.8 * k) for k in range(n_robots)]
    return [(-5.0 + 1.0 * (k % 11), -3.5 + 1.4 * (k // 11)) for k in range(n_robots)]


def _runner(n_robots: int) -> InProcessRunner:
    """Every robot under motion control (runner.InProcessRunner, 1 kHz control, default 10 kHz physics)."""
    poses = tuple((x, y, 0.3 * k) for k, (x, y) in enumerate(_layout(n_robots)))
    runner = InProcessRunner(PlantSetup(field_preset="division_a", robot_poses=poses, control_period_s=CONTROL_DT_S))
    for k in range(n_robots):
        runner.command(k, (0.5, 0.2, 0.5))
    return runner


def _runner_real_time_factor(n_robots: int, sim_s: float) -> tuple[float, float]:
    """(real-time factor by the wall clock, by the process's CPU time) of the in-process simulator."""
    runner = _runner(n_robots)
    runner.run(0.01)  # the compiled kernels load from numba's cache on the first call
    t, cpu = time.perf_counter(), time.process_time()
    runner.run(sim_s)
    return sim_s / (time.perf_counter() - t), sim_s / (time.process_time() - cpu)


def _runner_bytes_per_robot(n_robots: int) -> float:
    """Python heap (numpy arrays included) the runner holds per robot: (n robots - 1 robot) / (n - 1)."""
    held = []
    for n in (1, n_robots):
        tracemalloc.start()
        runner = _runner(n)
        runner.run(0.005)
        held.append(tracemalloc.get_traced_memory()[0])
        tracemalloc.stop()
        del runner
    return (held[1] - held[0]) / (n_robots - 1)


def _rss_mib() -> float:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * 4096 / 2**20


def _world(n_robots: int, substep_hz: float, dribbling: bool = False) -> World:
    specs = [RobotSpec(x=x, y=y, theta=0.3 * k, robot_id=k) for k, (x, y) in enumerate(_layout(n_robots))]
    w = World(FIELD, specs, BallState(1.0, 3.0, 2.0, -0.5), physics=PhysicsParams(substep_hz=substep_hz), seed=1)
    rng = np.random.default_rng(0)
    for k in range(n_robots):
        w.set_duty(k, rng.uniform(-0.3, 0.3, 4))
    if dribbling:  # ball on robot 0's dribbler: the contact path runs every substep
        cfg = RobotConfig()
        w.place_ball(-4.0 + cfg.dribbler_offset_m, -2.0)
        w.set_duty(0, [0.05, 0.05, -0.05, -0.05])
        w.set_dribbler(0, True)
    return w


def _step_cost_us(n_robots: int, substep_hz: float, steps: int, dribbling: bool = False) -> float:
    w = _world(n_robots, substep_hz, dribbling)
    times = []
    for _ in range(steps):
        t = time.perf_counter()
        w.step(CONTROL_DT_S)
        times.append(time.perf_counter() - t)
    return statistics.median(times) * 1e6


def _real_time_factor(n_robots: int, substep_hz: float, sim_s: float) -> float:
    w = _world(n_robots, substep_hz)
    steps = round(sim_s / CONTROL_DT_S)
    robots = np.arange(n_robots)
    duty = np.array([w.duty(k) for k in range(n_robots)])
    t = time.perf_counter()
    for _ in range(steps):
        w.wheel_sensors(robots)  # the control calls of all robots per period, like the runner
        w.set_duties(robots, duty)
        w.step(CONTROL_DT_S)
        w.poll_vision()
    return sim_s / (time.perf_counter() - t)


def _run_for(w: World, duration_s: float) -> None:
    n = math.ceil(duration_s / 0.05)
    for _ in range(n):
        w.step(duration_s / n)


def _chip_errors_m(speed_mps: float, angle_deg: float) -> tuple[float, float]:
    """(apex, first touchdown) of a chip in the world against the projectile of its launch (no drag):
    the height at half the flight time, and the ground point 0.1 ms before the touchdown, carried on."""
    cfg = RobotConfig()
    w = World(FIELD, [RobotSpec(x=-1.0)], BallState(-1.0 + cfg.dribbler_offset_m, 0.0), seed=0)
    w.kick(0, speed_mps, angle_deg=angle_deg)
    b = w.ball_state()
    t_flight = 2.0 * b.vz / GRAVITY_MPS2
    _run_for(w, 0.5 * t_flight)
    apex_error = abs(w.ball_state().z - b.vz**2 / (2.0 * GRAVITY_MPS2))
    _run_for(w, 0.5 * t_flight - 1e-4)
    s = w.ball_state()
    touchdown = (s.x + s.vx * 1e-4, s.y + s.vy * 1e-4)
    return apex_error, math.dist(touchdown, (b.x + b.vx * t_flight, b.y + b.vy * t_flight))


def run(quick: bool = False) -> list[dict]:
    steps = 300 if quick else 2000
    sim_s = 1.0 if quick else 5.0
    rows: list[dict] = []
    hz = PhysicsParams().substep_hz
    for n in (1, 6):
        rows.append(
            dict(
                name=f"step cost, {n} robot(s) + ball, 1 ms at {hz / 1000:.0f} kHz",
                value=round(_step_cost_us(n, hz, steps), 1),
                unit="us",
                target="",
                note="median, contact-free bodies",
            )
        )
    rows.append(
        dict(
            name=f"step cost, 1 robot dribbling the ball, {hz / 1000:.0f} kHz",
            value=round(_step_cost_us(1, hz, steps, dribbling=True), 1),
            unit="us",
            target="",
            note="median, contacts checked every substep",
        )
    )
    for n in (1, 6, 22):
        rows.append(
            dict(
                name=f"real-time factor, {n} robot(s) + ball, {hz / 1000:.0f} kHz substeps",
                value=round(_real_time_factor(n, hz, sim_s), 1),
                unit="x",
                target=">= 20" if n == 1 else "",
                note=f"{sim_s:.0f} s simulated, 1 kHz control calls",
            )
        )
    wall, cpu = _runner_real_time_factor(22, sim_s)
    rows.append(
        dict(
            name=f"in-process simulator, 22 robots, {hz / 1000:.0f} kHz physics, under motion control",
            value=round(wall, 2),
            unit="x real time",
            target=">= 5",
            note=f"runner.InProcessRunner, main board and motor boards of every robot at 1 kHz (TeamFirmware); "
                 f"{sim_s:.0f} s simulated, wall clock",
        )
    )
    rows.append(
        dict(
            name="the same, by CPU time",
            value=round(cpu, 2),
            unit="x real time",
            target="",
            note="simulated time / process CPU time (what a shared machine does not distort)",
        )
    )
    rows.append(
        dict(
            name="memory per robot, in-process simulator",
            value=round(_runner_bytes_per_robot(22) / 1024, 1),
            unit="KiB",
            target="",
            note=f"Python heap incl. numpy (tracemalloc), (22 robots - 1 robot) / 21; this process's RSS "
                 f"{_rss_mib():.0f} MiB in all",
        )
    )
    rows.append(
        dict(
            name="real-time factor, 1 robot + ball, 20 kHz substeps",
            value=round(_real_time_factor(1, 20000.0, sim_s), 1),
            unit="x",
            target="",
            note="PhysicsParams(substep_hz=20000)",
        )
    )
    launches = [(v, a) for v in ((1.0, 3.5, 6.0) if quick else (1.0, 2.0, 3.0, 4.0, 5.0, 6.0))
                for a in ((30.0, 45.0, 60.0) if quick else (30.0, 40.0, 50.0, 60.0))]
    errors = np.array([_chip_errors_m(v, a) for v, a in launches]) * 1000.0
    rows.append(
        dict(
            name="chip flight against the projectile: apex / first touchdown, worst",
            value=f"{errors[:, 0].max():.2g} / {errors[:, 1].max():.2g}",
            unit="mm",
            target="<= 1 / <= 1",
            note=f"{len(launches)} chips, 1-6 m/s, 30-60 deg, from a robot's chip plate, 10 kHz substeps",
        )
    )
    for offset, flat, curved in deviation_table(np.round(np.arange(0.0, 0.0351, 0.005), 4)):
        rows.append(
            dict(
                name=f"kick deviation at {offset * 100:.1f} cm, flat / curved",
                value=f"{flat:.2f} / {curved:.2e}",
                unit="deg",
                target="flat ~12 at 3 cm; curved < 1",
                note="plate tilt model",
            )
        )
    return rows


def main(argv: list[str] | None = None) -> int:
    return bench_main(run, __doc__.splitlines()[0], argv, quick_help="fewer samples")


if __name__ == "__main__":
    sys.exit(main())
