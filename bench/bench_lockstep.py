"""Real-time factor of the DDS graph in lockstep: the plant and every robot's firmware, per robot
(velocity_controller + motor_boards in each namespace) or as a team (one team_firmware process).

Each run starts real node processes in a private DDS domain (erforce_interfaces.tools.testing),
lets the plant run flat out (real_time_factor 0) for a stretch of simulated time, and
reports simulated seconds per wall second, the CPU time each kind of process spent per tick
(from /proc, so it is measured, not estimated; firmware per robot) and the resident memory
of the whole graph and per robot (VmRSS at the end of the run).

    ./run exec python bench/bench_lockstep.py [--quick] [--robots 1 6 11 14] [--deployment team]
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

from rosgraph_msgs.msg import Clock
from table import bench_main, markdown_table  # bench/table.py: the shared table format

from erforce_interfaces import contract
from erforce_interfaces.conversions import stamp_to_nanoseconds
from erforce_interfaces.tools.testing import RosGraph

ROBOT_YAML = Path(__file__).resolve().parents[1] / "src/erforce_interfaces/config/robot.yaml"


def _cpu_s(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _rss_mib(pid: int) -> float:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024.0
    return 0.0


def measure(num_robots: int, sim_s: float, period_s: float = 0.002, deployment: str = "per_robot") -> dict:
    """Sim seconds per wall second, CPU per tick and RSS for ``num_robots`` controlled robots."""
    with RosGraph(Path(tempfile.mkdtemp(prefix="bench-lockstep-"))) as graph:
        if deployment == "team":
            graph.start_node("erforce_motion", "team_firmware", params_file=ROBOT_YAML, params={
                "use_sim_time": True, "robot_ids": list(range(num_robots)),
                "main_board.loop_rate_hz": 1.0 / period_s, "motor_boards.loop_rate_hz": 1.0 / period_s})
        else:
            for i in range(num_robots):
                for exe in ("velocity_controller", "motor_boards"):
                    graph.start_node("erforce_motion", exe, namespace=f"robot_{i}", params_file=ROBOT_YAML,
                                     params={"use_sim_time": True, "loop_rate_hz": 1.0 / period_s})
        clock_readers = 1 if deployment == "team" else 2 * num_robots
        # a row of 11 per team on the Division A field (12 x 9 m)
        poses = [v for i in range(num_robots) for v in (-5.0 + 1.0 * (i % 11), -1.0 + 2.0 * (i // 11), 0.0)]
        clocks = graph.subscribe("/clock", Clock, contract.QOS_CLOCK)
        # warm-up ticks, then the measured stretch; the plant ends itself after stop_after_s. It starts
        # once this probe and both nodes of every robot subscribe to /clock, so the probe sees the warm-up.
        warmup_s = 0.5
        plant = graph.start_node("erforce_sim", "plant", params_file=ROBOT_YAML, params={
            "robot_poses": poses, "field": "division_a", "controlled": [True], "real_time_factor": 0.0,
            "control_period_s": period_s,
            "stop_after_s": warmup_s + sim_s, "startup_timeout_s": 300.0,
            "wheel_states_readers": 1 if deployment == "team" else 2,
            "start_clock_subscribers": clock_readers + 1})
        graph.probe.spin_until(lambda: clocks and stamp_to_nanoseconds(clocks[-1].clock) >= warmup_s * 1e9, 400.0,
                               "warm-up")
        t0_sim = stamp_to_nanoseconds(clocks[-1].clock) * 1e-9
        t0_wall = time.monotonic()
        pids = {proc.name + ("" if proc.name == "plant" else f"/{k}"): proc.pid
                for k, proc in enumerate(graph.processes)}
        cpu0 = {name: _cpu_s(pid) for name, pid in pids.items()}
        cpu1 = dict(cpu0)
        rss = {}
        while plant.alive():
            try:
                cpu1 = {name: _cpu_s(pid) for name, pid in pids.items() if Path(f"/proc/{pid}").exists()}
                for name, pid in pids.items():  # the peak seen (an exited process reads 0)
                    rss[name] = max(rss.get(name, 0.0), _rss_mib(pid))
            except OSError:  # the plant ended between the check and the read
                pass
            graph.probe.spin_for(0.05)
        wall = time.monotonic() - t0_wall
        sim = warmup_s + sim_s - t0_sim  # the plant ends itself exactly there
    ticks = max(sim / period_s, 1.0)
    per_tick_us = {}
    for name in cpu1:
        kind = name.split("/")[0]
        per_tick_us[kind] = per_tick_us.get(kind, 0.0) + (cpu1[name] - cpu0[name]) / ticks * 1e6 / (
            1 if kind == "plant" else num_robots)
    firmware_rss = sum(v for k, v in rss.items() if k != "plant")
    return {"robots": num_robots, "sim_s": sim, "wall_s": wall, "rtf": sim / wall if wall > 0 else 0.0,
            "cpu_us_per_tick": per_tick_us, "rss_total_mib": sum(rss.values()),
            "rss_firmware_per_robot_mib": firmware_rss / num_robots}


ROBOT_COUNTS = (1, 6, 11, 14)  # 14: our 11 and 3 opponents, all under motion control


def run(quick: bool = False, robots=ROBOT_COUNTS, deployments=("per_robot", "team")) -> list[dict]:
    rows = []
    for n in robots:
        for deployment in deployments:
            r = measure(n, sim_s=1.0 if quick else 4.0, deployment=deployment)
            cpu = ", ".join(f"{k} {v:.0f} µs" for k, v in sorted(r["cpu_us_per_tick"].items()))
            label = "per robot" if deployment == "per_robot" else "team_firmware"
            rows.append({"name": f"lockstep over DDS, {n} robot(s), {label}, 2 ms tick", "value": round(r["rtf"], 2),
                         "unit": "× real time", "target": "≥ 1× (14 robots)" if n == 14 else "—",
                         "note": f"{r['sim_s']:.1f} s simulated in {r['wall_s']:.1f} s; CPU per tick: {cpu} "
                                 f"(firmware per robot); RSS {r['rss_total_mib']:.0f} MiB in all, firmware "
                                 f"{r['rss_firmware_per_robot_mib']:.0f} MiB per robot"})
            print(rows[-1], file=sys.stderr, flush=True)
    return rows


def main(argv: list[str] | None = None) -> int:
    if not argv and len(sys.argv) <= 1:
        return bench_main(run, __doc__.splitlines()[0], argv, quick_help="shorter runs")
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="shorter runs")
    parser.add_argument("--robots", type=int, nargs="+", default=list(ROBOT_COUNTS))
    parser.add_argument("--deployment", choices=("per_robot", "team"), action="append")
    args = parser.parse_args(argv)
    rows = run(args.quick, args.robots, tuple(args.deployment or ("per_robot", "team")))
    print("\n".join(markdown_table(rows)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
