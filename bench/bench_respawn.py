"""Self-healing: how long the launched demo graph takes to close the loop again after one node is killed.

demo.launch.yaml runs under erforce-launch in a private DDS domain (erforce_interfaces.tools.testing);
each node type is killed (SIGKILL) in turn, ``rounds`` times, and the time from the kill until the
respawned node's output is back, every other node's output came after it (the lockstep loop went
round) and the plant's lockstep gate waits for every robot again (test/faults/faults_support.LaunchedDemo) is
reported per node type: every figure, median, max.

``--team``: the 14-robot team_sim.launch.yaml instead (plant, both teams' firmware in one process, predictor,
opponents' interceptor; the plant at normal priority, as the fault tests run it, not under ``chrt --idle``).

erforce-launch keeps a warm standby per node (imports done, waiting to be activated: README,
"Self-healing"); before each kill the bench waits until every node's standby is ready, so each figure is a
take-over by a standby. ``--no-standby`` measures fresh starts instead (erforce-launch --no-standby).

``--pause S``: instead of killing, each node is stopped (SIGSTOP) for S seconds and resumed (SIGCONT), as a
debugger or a suspended laptop does; the figure counts from the SIGCONT (no standbys: nobody dies). ``run()`` (what
``./run bench`` calls) adds those rows for a 3 s pause and the count of the demo graph's sockets outside
127.0.0.0/8 with the default discovery range.

``--standby-cost`` prints what the standbys cost instead: RSS and start CPU of each node type's standby,
and the RSS of the demo and the 14-robot team_sim graphs with their standbys, as shipped.

``--busy`` keeps one core busy with an unrelated process (a Python busy loop) during the measurement:
the target holds on a machine that does something else too. ``--breakdown`` adds where each restart's
time went, from a start-up trace of the respawned process (bench/respawn_trace/sitecustomize.py):
kill to exec (respawn delay), exec to interpreter up, imports, rclpy.init and node construction, the
first publish, and from there to the loop closed (DDS matching, the lockstep loop going round).

    ./run exec python bench/bench_respawn.py [--quick | --rounds N] [--busy] [--no-standby | --pause S] [--breakdown]
    ./run exec python bench/bench_respawn.py --standby-cost
"""

from __future__ import annotations

import argparse
import contextlib
import ipaddress
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
from faults_support import (  # the fault tests' measurement
    DEMO_LAUNCH,
    TEAM_LOOP_OUTPUTS,
    TEAM_SIM_LAUNCH,
    LaunchedDemo,
    standbys_ready,
)

from erforce_interfaces.tools.testing import RosGraph, listening_sockets, on_loopback
from erforce_interfaces.wire.contract import dds_profile_env

NODES = ("catcher", "ball_predictor", "velocity_controller", "motor_boards", "plant")
RESPAWN_DELAY_S = 0.1  # the launch files' respawn_delay (a number in each file: ros2 launch substitutes none)
TARGET_S = 3.0
PAUSE_S = 3.0  # SIGSTOP .. SIGCONT in the pause rows (issue 36)
TRACE_DIR = Path(__file__).resolve().parent / "respawn_trace"
# kill -> exec, exec -> interpreter up, -> node module imported, -> rclpy.init, -> node built, -> first publish,
# -> loop closed
PHASES = ("delay", "interpreter", "imports", "rclpy.init", "construction", "to first publish", "to loop closed")
# a warm standby: kill -> rclpy.init done (the respawn delay, "go", the init), -> node built, -> first publish, -> loop
STANDBY_PHASES = ("kill to rclpy.init done", "construction", "to first publish", "to loop closed")


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
    start = output.rfind(f"started with pid [{pid}]")  # "process started" or, for a standby, "standby started"
    found = re.findall(rf"\[{node}-\d+\] respawn-trace (\w+) ([\d.]+) ([\d.]+) {pid}$", output[start:], re.M)
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
    if t_exec < t_kill_mono:  # a warm standby, started before the kill
        marks = [t_kill_mono, t["init"], t["built"], t["publish"], t_kill_mono + heal_s]
        return {phase: b - a for phase, a, b in zip(STANDBY_PHASES, marks[:-1], marks[1:], strict=True)}
    marks = [t_kill_mono, t_exec, t["site"], t["main"], t["init"], t["built"], t["publish"], t_kill_mono + heal_s]
    found = {phase: b - a for phase, a, b in zip(PHASES, marks[:-1], marks[1:], strict=True)}
    cpu = {k: c for k, (_, c) in events.items()}
    found["CPU: start to node built"] = cpu["built"]  # the process's own CPU time (user + system)
    found["CPU: imports"] = cpu["main"] - cpu["site"]
    return found


def measure(rounds: int, breakdown: bool = False, standby: bool = True, team: bool = False,
            pause_s: float = 0.0) -> tuple[dict[str, list[float]], dict[str, list[dict]]]:
    """Heal times per node type: from the kill, or with ``pause_s`` from the SIGCONT after a pause that long
    (no standby is used then: nobody dies)."""
    # The probe that times the loop announces itself as the nodes do (the test harness's pytest_configure):
    # with Fast DDS's default of 3 s it matched a restarted catcher up to 2 s after the robot's
    # velocity controller did, and the figure was the probe's discovery, not the graph's.
    os.environ.update(dds_profile_env())
    nodes = tuple(TEAM_LOOP_OUTPUTS) if team else NODES
    heal_s: dict[str, list[float]] = {node: [] for node in nodes}
    phases: dict[str, list[dict]] = {node: [] for node in nodes}
    with RosGraph(Path(tempfile.mkdtemp(prefix="bench-respawn-"))) as graph:
        if breakdown:
            graph.env["PYTHONPATH"] = os.pathsep.join(p for p in (str(TRACE_DIR), graph.env.get("PYTHONPATH")) if p)
        if team:  # the 14-robot graph as shipped
            demo = LaunchedDemo(graph, TEAM_SIM_LAUNCH, TEAM_LOOP_OUTPUTS, standby=standby)
        else:
            demo = LaunchedDemo(graph, standby=standby)
        demo.wait_running()
        for _ in range(rounds):
            for node in nodes:
                if pause_s:
                    heal_s[node].append(demo.pause_and_heal(node, pause_s, timeout_s=120.0))
                    demo.wait_running()
                    continue
                if standby:
                    demo.wait_standbys_ready()
                    demo.wait_running()
                t_kill = time.monotonic()
                heal_s[node].append(demo.kill_and_heal(node, RESPAWN_DELAY_S, timeout_s=120.0))
                if breakdown:
                    found = _phases(demo, node, t_kill, heal_s[node][-1])
                    if found is not None:
                        phases[node].append(found)
                demo.wait_running()
    return heal_s, phases


def _rss_mib(pid: int, field: str = "VmRSS:", file: str = "status") -> float:
    for line in Path(f"/proc/{pid}/{file}").read_text().splitlines():
        if line.startswith(field):
            return int(line.split()[1]) / 1024
    return 0.0


def _pss_mib(pid: int) -> float:
    """Proportional set size: shared pages (libraries, the same files mapped) divided among their users."""
    return _rss_mib(pid, "Pss:", "smaps_rollup")


def _cpu_s(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")  # utime + stime


GRAPHS = (("demo", DEMO_LAUNCH), ("team_sim (14 robots)", TEAM_SIM_LAUNCH))


def standby_cost() -> list[dict]:
    """Each graph as shipped until every process has a ready standby: RSS of the processes and their standbys,
    and the standbys' CPU (imports and warm-up: what each costs a machine once per start and respawn)."""
    os.environ.update(dds_profile_env())
    rows = []
    for graph_name, launch_file in GRAPHS:
        with RosGraph(Path(tempfile.mkdtemp(prefix="bench-standby-"))) as graph:
            launch = graph.start_launch(launch_file, standby=True, output="screen")
            graph.spin_until(lambda launch=launch: standbys_ready(launch.output()), 600.0, "every standby ready")
            out = launch.output()
            pids = {kind: {label: int(pid) for label, pid in re.findall(
                        rf"\[(\S+-\d+)\]: {kind} started with pid \[(\d+)\]", out)}
                    for kind in ("process", "standby")}
            rss = {kind: {label: _rss_mib(pid) for label, pid in found.items()} for kind, found in pids.items()}
            pss = {kind: sum(_pss_mib(pid) for pid in found.values()) for kind, found in pids.items()}
            cpu = {label: _cpu_s(pid) for label, pid in pids["standby"].items()}
        for label in sorted(rss["standby"]):
            rows.append({"name": f"{graph_name}: {label} standby, RSS", "value": round(rss["standby"][label]),
                         "unit": "MiB", "note": f"its running process {rss['process'][label]:.0f} MiB; the standby's "
                                                f"CPU to ready {cpu[label]:.2f} s"})
        total_active, total_standby = sum(rss["process"].values()), sum(rss["standby"].values())
        rows.append({"name": f"{graph_name}: RSS with standbys", "value": round(total_active + total_standby),
                     "unit": "MiB", "note": f"{len(rss['process'])} processes {total_active:.0f} MiB + "
                                            f"{len(rss['standby'])} standbys {total_standby:.0f} MiB; PSS "
                                            f"{pss['process']:.0f} + {pss['standby']:.0f} MiB; CPU of all standbys "
                                            f"{sum(cpu.values()):.1f} s (at the moment the last one was ready)"})
    return rows


def rows_of(heal_s: dict[str, list[float]], load: float, busy: bool, standby: bool = True,
            pause_s: float = 0.0) -> list[dict]:
    rows = []
    how = "from a warm standby" if standby else "fresh start"
    what = f"paused {pause_s:g} s: loop closed again after SIGCONT" if pause_s else f"killed: loop closed again, {how}"
    for node, times in heal_s.items():
        every = ", ".join(f"{t:.2f}" for t in times)
        rows.append({"name": f"{node} {what}{' (one core busy)' if busy else ''}",
                     "value": round(statistics.median(times), 2), "unit": "s", "target": f"≤ {TARGET_S:g}",
                     "note": f"{len(times)} runs: {every}; median {statistics.median(times):.2f}, max {max(times):.2f} "
                             f"({'' if pause_s else f'respawn_delay {RESPAWN_DELAY_S:g} s; '}load average {load:.1f} "
                             "at the start)"})
    return rows


def breakdown_rows(phases: dict[str, list[dict]]) -> list[dict]:
    rows = []
    for node, runs in phases.items():
        if not runs:
            continue
        for phase in runs[0]:
            values = [r[phase] for r in runs if phase in r]
            rows.append({"name": f"{node}: {phase}", "value": round(statistics.median(values), 3), "unit": "s",
                         "note": f"{len(values)} runs: {', '.join(f'{v:.3f}' for v in values)}"})
    return rows


def run(quick: bool = False, busy: bool = False, breakdown: bool = False) -> list[dict]:
    load = os.getloadavg()[0]
    with cpu_burner(busy):
        heal_s, phases = measure(1 if quick else 3, breakdown)
        paused_s, _ = measure(1 if quick else 3, standby=False, pause_s=PAUSE_S)
    return (rows_of(heal_s, load, busy) + rows_of(paused_s, load, busy, standby=False, pause_s=PAUSE_S)
            + [sockets_row()] + (breakdown_rows(phases) if breakdown else []))


def sockets_row() -> dict:
    """Where the demo graph as shipped listens (discovery LOCALHOST, the default): its UDP sockets and listening TCP
    sockets outside 127.0.0.0/8, over every process; a socket bound to a multicast group (SSL's) counts by its own
    node's interface parameter, so not here (test/faults/test_fault_sockets.py checks both)."""
    os.environ.update(dds_profile_env())
    with RosGraph(Path(tempfile.mkdtemp(prefix="bench-sockets-"))) as graph:
        demo = LaunchedDemo(graph, standby=False)
        demo.wait_running()
        found = [(pid, s) for pid in graph.pids() for s in _sockets_of(pid)]
    outside = [f"{pid}: {table} {address}:{port}" for pid, (table, address, port) in found
               if not on_loopback(address) and not ipaddress.ip_address(address).is_multicast]
    return {"name": "demo graph: sockets outside 127.0.0.0/8 (default discovery range)", "value": len(outside),
            "unit": "count", "target": "0",
            "note": f"{len(found)} UDP and listening TCP sockets in {len({pid for pid, _ in found})} processes"
                    + (f"; {', '.join(outside[:3])}" if outside else "")}


def _sockets_of(pid: int) -> list[tuple[str, str, int]]:
    try:
        return listening_sockets(pid)
    except OSError:  # ended meanwhile
        return []


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="one kill per node type (default: three)")
    parser.add_argument("--rounds", type=int, default=None, help="kills per node type")
    parser.add_argument("--busy", action="store_true", help="keep one core busy with an unrelated process meanwhile")
    parser.add_argument("--no-standby", action="store_false", dest="standby",
                        help="respawn by fresh starts (erforce-launch --no-standby), not from warm standbys")
    parser.add_argument("--standby-cost", action="store_true",
                        help="print the standbys' RSS and CPU in the demo and team_sim graphs instead")
    parser.add_argument("--breakdown", action="store_true",
                        help="also where each restart's time went")
    parser.add_argument("--pause", type=float, default=0.0, metavar="S",
                        help="instead of killing: SIGSTOP each node for S seconds, then SIGCONT; the time is counted "
                             "from the SIGCONT (no standbys: nobody dies)")
    parser.add_argument("--team", action="store_true",
                        help="the 14-robot team_sim.launch.yaml instead of demo.launch.yaml")
    args = parser.parse_args(argv)
    t0 = time.perf_counter()
    load = os.getloadavg()[0]
    rounds = args.rounds or (1 if args.quick else 3)
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(1))  # reap the burner and the graph
    if args.standby_cost:
        print("\n".join(markdown_table(standby_cost())))
        print(f"\n(total {time.perf_counter() - t0:.1f} s; load average {load:.1f} at the start)")
        return 0
    with cpu_burner(args.busy):
        heal_s, phases = measure(rounds, args.breakdown, args.standby and not args.pause, args.team, args.pause)
    rows = rows_of(heal_s, load, args.busy, args.standby and not args.pause, args.pause)
    rows += breakdown_rows(phases) if args.breakdown else []
    print("\n".join(markdown_table(rows)))
    print(f"\n(total {time.perf_counter() - t0:.1f} s; load average {load:.1f} at the start, "
          f"{os.getloadavg()[0]:.1f} at the end)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
