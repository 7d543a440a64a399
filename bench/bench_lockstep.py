"""Real-time factor of the DDS graph in lockstep: plant + velocity_controller + motor_boards per robot.

Each run starts real node processes in a private DDS domain (erforce_interfaces.tools.testing),
lets the plant run flat out (real_time_factor 0) for a stretch of simulated time, and
reports simulated seconds per wall second plus the CPU time each process spent per tick
(from /proc, so it is measured, not estimated).

    ./run exec python bench/bench_lockstep.py [--quick]
"""

from __future__ import annotations

import os
import sys
import tempfile
import time
from pathlib import Path

from rosgraph_msgs.msg import Clock
from table import bench_main  # bench/table.py: the shared table format

from erforce_interfaces import contract
from erforce_interfaces.conversions import stamp_to_nanoseconds
from erforce_interfaces.tools.testing import RosGraph

ROBOT_YAML = Path(__file__).resolve().parents[1] / "src/erforce_interfaces/config/robot.yaml"


def _cpu_s(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def measure(num_robots: int, sim_s: float, period_s: float = 0.002) -> dict:
    """Sim seconds per wall second and CPU per tick for ``num_robots`` controlled robots."""
    with RosGraph(Path(tempfile.mkdtemp(prefix="bench-lockstep-"))) as graph:
        for i in range(num_robots):
            for exe in ("velocity_controller", "motor_boards"):
                graph.start_node("erforce_motion", exe, namespace=f"robot_{i}", params_file=ROBOT_YAML,
                                 params={"use_sim_time": True, "loop_rate_hz": 1.0 / period_s})
        poses = [v for i in range(num_robots) for v in (-3.0 + 1.0 * i, 0.0, 0.0)]
        clocks = graph.subscribe("/clock", Clock, contract.QOS_CLOCK)
        # warm-up ticks, then the measured stretch; the plant ends itself after stop_after_s. It starts
        # once this probe and both nodes of every robot subscribe to /clock, so the probe sees the warm-up.
        warmup_s = 0.5
        plant = graph.start_node("erforce_sim", "plant", params_file=ROBOT_YAML, params={
            "robot_poses": poses, "controlled": [True], "real_time_factor": 0.0, "control_period_s": period_s,
            "stop_after_s": warmup_s + sim_s, "startup_timeout_s": 60.0,
            "start_clock_subscribers": 2 * num_robots + 1})
        graph.probe.spin_until(lambda: clocks and stamp_to_nanoseconds(clocks[-1].clock) >= warmup_s * 1e9, 120.0,
                               "warm-up")
        t0_sim = stamp_to_nanoseconds(clocks[-1].clock) * 1e-9
        t0_wall = time.monotonic()
        pids = {proc.name + ("" if proc.name == "plant" else f"/{k}"): proc.pid
                for k, proc in enumerate(graph.processes)}
        cpu0 = {name: _cpu_s(pid) for name, pid in pids.items()}
        cpu1 = dict(cpu0)
        while plant.alive():
            cpu1 = {name: _cpu_s(pid) for name, pid in pids.items() if Path(f"/proc/{pid}").exists()}
            graph.probe.spin_for(0.05)
        wall = time.monotonic() - t0_wall
        sim = warmup_s + sim_s - t0_sim  # the plant ends itself exactly there
    ticks = max(sim / period_s, 1.0)
    per_tick_us = {}
    for name in cpu1:
        kind = name.split("/")[0]
        per_tick_us[kind] = per_tick_us.get(kind, 0.0) + (cpu1[name] - cpu0[name]) / ticks * 1e6 / (
            1 if kind == "plant" else num_robots)
    return {"robots": num_robots, "sim_s": sim, "wall_s": wall, "rtf": sim / wall if wall > 0 else 0.0,
            "cpu_us_per_tick": per_tick_us}


def run(quick: bool = False) -> list[dict]:
    rows = []
    for n in (1, 6):
        r = measure(n, sim_s=2.0 if quick else 6.0)
        cpu = ", ".join(f"{k} {v:.0f} µs" for k, v in sorted(r["cpu_us_per_tick"].items()))
        rows.append({"name": f"lockstep over DDS, {n} robot(s), 2 ms tick", "value": round(r["rtf"], 2),
                     "unit": "× real time", "target": "≥ 1× (1 robot)" if n == 1 else "—",
                     "note": f"{r['sim_s']:.1f} s simulated in {r['wall_s']:.1f} s; CPU per tick: {cpu}"})
    return rows


def main(argv: list[str] | None = None) -> int:
    return bench_main(run, __doc__.splitlines()[0], argv, quick_help="shorter runs")


if __name__ == "__main__":
    sys.exit(main())
