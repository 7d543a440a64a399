"""Self-healing: how long the launched demo graph takes to close the loop again after one node is killed.

demo.launch.yaml runs under erforce-launch in a private DDS domain (erforce_interfaces.tools.testing);
each node type is killed (SIGKILL) in turn, ``rounds`` times, and the time from the kill until the
respawned node's output is back and every other node's output came after it (the lockstep loop went
round: test/faults/faults_support.LaunchedDemo) is reported per node type: every figure, median, max.

``--busy`` keeps one core busy with an unrelated process (a Python busy loop) during the measurement:
the target holds on a machine that does something else too. ``--breakdown`` adds where each restart's
time went, from a start-up trace of the respawned process (bench/respawn_trace/sitecustomize.py):
kill to exec (respawn delay), exec to interpreter up, imports, rclpy.init and node construction, the
first publish, and from there to the loop closed (DDS matching, the lockstep loop going round).

    ./run exec python bench/bench_respawn.py [--quick | --rounds N] [--busy] [--breakdown] [--respawn-delay S]
"""

from __future__ import annotations

import argparse
import contextlib
import os
import re
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from table import markdown_table  # bench/table.py: the shared table format

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "test" / "faults"))
from faults_support import LaunchedDemo  # the fault tests' measurement, run as a bench

from erforce_interfaces.contract import dds_profile_env
from erforce_interfaces.tools.testing import RosGraph

NODES = ("catcher", "ball_predictor", "velocity_controller", "motor_boards", "plant")
RESPAWN_DELAY_S = 0.1  # the launch files' default
TARGET_S = 3.0
TRACE_DIR = Path(__file__).resolve().parent / "respawn_trace"
# kill -> exec, exec -> interpreter up, -> node module imported, -> rclpy.init, -> node built, -> first publish,
# -> loop closed
PHASES = ("delay", "interpreter", "imports", "rclpy.init", "construction", "to first publish", "to loop closed")


@contextlib.contextmanager
def cpu_burner(on: bool):
    """A process that keeps one core busy (reaped at the end), or nothing."""
    if not on:
        yield
        return
    burner = subprocess.Popen([sys.executable, "-c", "while True: pass"])
    try:
        yield
    finally:
        burner.kill()
        burner.wait()


def _boot_s_of_start(pid: int) -> float:
    """When ``pid`` was exec'ed (fork: the same tick), in CLOCK_BOOTTIME seconds (10 ms resolution)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return int(fields[19]) / os.sysconf("SC_CLK_TCK")


def _trace_events(output: str, node: str, pid: int) -> dict[str, float]:
    """Wall-clock times of the respawn-trace lines of the process that started with ``pid``."""
    start = output.rfind(f"process started with pid [{pid}]")
    found = re.findall(rf"\[{node}-\d+\] respawn-trace (\w+) ([\d.]+) ([\d.]+)", output[start:])
    events: dict[str, tuple[float, float]] = {}
    for event, wall, cpu in found:
        events.setdefault(event, (float(wall), float(cpu)))
    return events


def _phases(demo: LaunchedDemo, node: str, t_kill_mono: float, heal_s: float) -> dict[str, float] | None:
    pid = demo.pid(node)
    mono_minus_wall = time.monotonic() - time.time()
    mono_minus_boot = time.monotonic() - time.clock_gettime(time.CLOCK_BOOTTIME)
    events = _trace_events(demo.launch.output(), node, pid)
    try:
        t_exec = _boot_s_of_start(pid) + mono_minus_boot
    except OSError:
        return None
    if not {"site", "main", "init", "built", "publish"} <= set(events):
        return None
    t = {k: wall + mono_minus_wall for k, (wall, _) in events.items()}
    marks = [t_kill_mono, t_exec, t["site"], t["main"], t["init"], t["built"], t["publish"], t_kill_mono + heal_s]
    found = {phase: b - a for phase, a, b in zip(PHASES, marks[:-1], marks[1:], strict=True)}
    cpu = {k: c for k, (_, c) in events.items()}
    found["CPU: start to node built"] = cpu["built"]  # the process's own CPU time (user + system)
    found["CPU: imports"] = cpu["main"] - cpu["site"]
    return found


def measure(rounds: int, breakdown: bool = False,
            respawn_delay_s: float = RESPAWN_DELAY_S) -> tuple[dict[str, list[float]], dict[str, list[dict]]]:
    # The probe that times the loop announces itself as the nodes do (the test harness's pytest_configure):
    # with Fast DDS's default of 3 s it matched a restarted catcher up to 2 s after the robot's
    # velocity controller did, and the figure was the probe's discovery, not the graph's.
    os.environ.update(dds_profile_env())
    heal_s: dict[str, list[float]] = {node: [] for node in NODES}
    phases: dict[str, list[dict]] = {node: [] for node in NODES}
    with RosGraph(Path(tempfile.mkdtemp(prefix="bench-respawn-"))) as graph:
        if breakdown:
            graph.env["PYTHONPATH"] = os.pathsep.join(p for p in (str(TRACE_DIR), graph.env.get("PYTHONPATH")) if p)
        demo = LaunchedDemo(graph, respawn_delay=f"{respawn_delay_s:g}")
        demo.wait_running()
        for _ in range(rounds):
            for node in NODES:
                t_kill = time.monotonic()
                heal_s[node].append(demo.kill_and_heal(node, respawn_delay_s, timeout_s=120.0))
                if breakdown:
                    found = _phases(demo, node, t_kill, heal_s[node][-1])
                    if found is not None:
                        phases[node].append(found)
                demo.wait_running()
    return heal_s, phases


def rows_of(heal_s: dict[str, list[float]], load: float, busy: bool,
            respawn_delay_s: float = RESPAWN_DELAY_S) -> list[dict]:
    rows = []
    for node, times in heal_s.items():
        every = ", ".join(f"{t:.2f}" for t in times)
        rows.append({"name": f"{node} killed: loop closed again{' (one core busy)' if busy else ''}",
                     "value": round(statistics.median(times), 2), "unit": "s", "target": f"≤ {TARGET_S:g}",
                     "note": f"{len(times)} runs: {every}; median {statistics.median(times):.2f}, max {max(times):.2f} "
                             f"(respawn_delay {respawn_delay_s:g} s; load average {load:.1f} at the start)"})
    return rows


def breakdown_rows(phases: dict[str, list[dict]]) -> list[dict]:
    rows = []
    for node, runs in phases.items():
        if not runs:
            continue
        for phase in (*PHASES, "CPU: imports", "CPU: start to node built"):
            values = [r[phase] for r in runs]
            rows.append({"name": f"{node}: {phase}", "value": round(statistics.median(values), 3), "unit": "s",
                         "note": f"{len(values)} runs: {', '.join(f'{v:.3f}' for v in values)}"})
    return rows


def run(quick: bool = False, busy: bool = False, breakdown: bool = False) -> list[dict]:
    load = os.getloadavg()[0]
    with cpu_burner(busy):
        heal_s, phases = measure(1 if quick else 3, breakdown)
    return rows_of(heal_s, load, busy) + (breakdown_rows(phases) if breakdown else [])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="one kill per node type (default: three)")
    parser.add_argument("--rounds", type=int, default=None, help="kills per node type")
    parser.add_argument("--busy", action="store_true", help="keep one core busy with an unrelated process meanwhile")
    parser.add_argument("--breakdown", action="store_true", help="also where each restart's time went")
    parser.add_argument("--respawn-delay", type=float, default=RESPAWN_DELAY_S, help="respawn_delay [s] of the launch")
    args = parser.parse_args(argv)
    t0 = time.perf_counter()
    load = os.getloadavg()[0]
    rounds = args.rounds or (1 if args.quick else 3)
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(1))  # reap the burner and the graph
    with cpu_burner(args.busy):
        heal_s, phases = measure(rounds, args.breakdown, args.respawn_delay)
    rows = rows_of(heal_s, load, args.busy, args.respawn_delay) + (breakdown_rows(phases) if args.breakdown else [])
    print("\n".join(markdown_table(rows)))
    print(f"\n(total {time.perf_counter() - t0:.1f} s; load average {load:.1f} at the start, "
          f"{os.getloadavg()[0]:.1f} at the end)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
