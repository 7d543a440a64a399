"""Real-time factor of the DDS graph in lockstep: the plant and every robot's firmware, per robot
(velocity_controller + motor_boards in each namespace, per-robot topics) or as a team (one team_firmware
process on the team-level topics /team/wheel_states and /team/motor_duty). Robots beyond 11 are the
opponents, a team of their own (opponent_<id>, their own team_firmware on /opponent_team/...).

Each run starts real node processes in a private DDS domain (erforce_interfaces.tools.testing),
lets the plant run flat out (real_time_factor 0) for a stretch of simulated time, and
reports simulated seconds per wall second, the CPU time each process spent per tick
(from /proc, so it is measured, not estimated) and the resident memory of the whole graph and
per robot (the peak VmRSS seen).

    ./run exec python bench/bench_lockstep.py [--quick] [--robots 1 6 11 14] [--deployment team]

``--launch-runs N``: the 14-robot graph as a user starts it, N times back to back, one command each
(``erforce-launch src/erforce_sim/launch/team_sim.launch.yaml real_time_factor:=0.0 ai:=passing``, plus
``--launch-args``; ai:=passing by default: the passing game reads our 11 robots' catch times and the
interceptor the opponents' 3, so all 14 are consumed in the graph, as issue 22's target asks; ``--launch-ai
passing none`` adds the rows with our robots standing, where only the opponents' are read): per run the
real-time factor over ``--launch-sim-s`` simulated seconds after a warm-up
(``--launch-warmup-s``, and until the predictor says its compiled search is loaded: the graph starts without
warm standbys, so numba loads in the predictor's background thread first),
the ball predictor's in-node time from a vision frame to the last catch output the AI reads published
(/ball/catches, and a robot's catch_time while it has a reader) (p99 and
max over every frame of the measured stretch: the bench sets the predictor's ``timing_log_every`` when it
starts measuring and again when it stops, which logs exactly those frames; ``--window-frames N``: the worst
p99 of windows of N frames instead), CPU per tick per process and the graph's RSS; then the median and range
over the runs. The launch file's default runs both teams on the field-level lockstep topics; ``--launch-args
lockstep_topics:=team`` measures a message per team instead. ``--world`` (and one run in the table of
``./run bench``): the AI side alone, ``team_sim.launch.yaml world:=ssl``, against the stand-in world
``ssl_world.launch.yaml`` flat out, each in a DDS domain of its own and talking over loopback UDP only; the
real-time factor is the world's.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import re
import statistics
import sys
import tempfile
import time
from pathlib import Path

from rosgraph_msgs.msg import Clock
from table import bench_main, markdown_table  # bench/table.py: the shared table format

from erforce_ball_model.ball_predictor_node import COMPILED_SEARCH_LOADED
from erforce_interfaces.tools.processes import free_udp_port
from erforce_interfaces.tools.testing import RosGraph
from erforce_interfaces.wire import contract
from erforce_interfaces.wire.conversions import stamp_to_nanoseconds

REPO = Path(__file__).resolve().parents[1]
ROBOT_YAML = REPO / "src/erforce_interfaces/config/robot.yaml"
TEAM_SIM = REPO / "src/erforce_sim/launch/team_sim.launch.yaml"
SSL_WORLD = REPO / "src/erforce_sim/launch/ssl_world.launch.yaml"
PREDICTOR = "/ball_predictor"  # its node in team_sim


def _cpu_s(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _rss_mib(pid: int) -> float:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024.0
    return 0.0


TEAM_SIZE = 11  # robots beyond it are the opponents: a team of their own, as team_sim.launch.yaml has them
# deployment -> the lockstep topics of the plant and the team_firmware processes
DEPLOYMENTS = {"per_robot": "per_robot", "team": "team", "team_firmware": "per_robot"}


def measure(num_robots: int, sim_s: float, period_s: float = 0.002, deployment: str = "per_robot",
            plant_params: dict | None = None) -> dict:
    """Sim seconds per wall second, CPU per tick and RSS for ``num_robots`` controlled robots."""
    topics = DEPLOYMENTS[deployment]
    # our team, then the opponents (ids 0.. of their own), each team with its own firmware
    teams = [(contract.OURS, list(range(min(num_robots, TEAM_SIZE))))]
    if num_robots > TEAM_SIZE:
        teams.append((contract.OPPONENTS, list(range(num_robots - TEAM_SIZE))))
    with RosGraph(Path(tempfile.mkdtemp(prefix="bench-lockstep-"))) as graph:
        if deployment != "per_robot":
            for team, ids in teams:
                graph.start_node("erforce_motion", "team_firmware", name=f"{team.name}_firmware",
                                 params_file=ROBOT_YAML,
                                 params={"use_sim_time": True, "robot_ids": ids, "lockstep_topics": topics,
                                         "team": team.name, "main_board.loop_rate_hz": 1.0 / period_s,
                                         "motor_boards.loop_rate_hz": 1.0 / period_s})
        else:
            for team, ids in teams:
                for i in ids:
                    for exe in ("velocity_controller", "motor_boards"):
                        graph.start_node("erforce_motion", exe, namespace=team.namespace(i), params_file=ROBOT_YAML,
                                         params={"use_sim_time": True, "loop_rate_hz": 1.0 / period_s})
        clock_readers = len(teams) if deployment != "per_robot" else 2 * num_robots
        # a row of 11 per team on the Division A field (12 x 9 m)
        rows = [[v for i in ids for v in (-5.0 + 1.0 * (i % 11), -1.0 + 2.0 * k, 0.0)]
                for k, (_, ids) in enumerate(teams)]
        clocks = graph.subscribe("/clock", Clock, contract.QOS_CLOCK)
        # warm-up ticks, then the measured stretch; the plant ends itself after stop_after_s. It starts
        # once this probe and both nodes of every robot subscribe to /clock, so the probe sees the warm-up.
        warmup_s = 0.5
        plant = graph.start_node("erforce_sim", "plant", params_file=ROBOT_YAML, params={
            "robot_poses": rows[0], **({"opponent_poses": rows[1]} if len(rows) > 1 else {}),
            "field": "division_a", "controlled": [True], "real_time_factor": 0.0,
            "control_period_s": period_s,
            "stop_after_s": warmup_s + sim_s, "startup_timeout_s": 300.0,
            "wheel_states_readers": 2 if deployment == "per_robot" else 1,
            "lockstep_topics": topics,
            "start_clock_subscribers": clock_readers + 1, **(plant_params or {})})
        graph.probe.spin_until(lambda: clocks and stamp_to_nanoseconds(clocks[-1].clock) >= warmup_s * 1e9, 400.0,
                               "warm-up")
        t0_sim = stamp_to_nanoseconds(clocks[-1].clock) * 1e-9
        t0_wall = time.monotonic()
        pids = {f"{proc.name}/{k}": proc.pid for k, proc in enumerate(graph.processes)}
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
    per_process_us = {name: (cpu1[name] - cpu0[name]) / ticks * 1e6 for name in cpu1}
    plant_us = sum(v for k, v in per_process_us.items() if k.startswith("plant/"))
    firmware_us = sum(v for k, v in per_process_us.items() if not k.startswith("plant/"))
    firmware_processes = sum(1 for k in per_process_us if not k.startswith("plant/"))
    firmware_rss = sum(v for k, v in rss.items() if not k.startswith("plant/"))
    return {"robots": num_robots, "sim_s": sim, "wall_s": wall, "rtf": sim / wall if wall > 0 else 0.0,
            "cpu_plant_us": plant_us, "cpu_firmware_us": firmware_us, "firmware_processes": firmware_processes,
            "cpu_us_per_process": per_process_us, "rss_total_mib": sum(rss.values()),
            "rss_firmware_per_robot_mib": firmware_rss / num_robots}


ROBOT_COUNTS = (1, 6, 11, 14)  # 14: our 11 and 3 opponents, all under motion control
LABELS = {"per_robot": "per robot (velocity_controller + motor_boards each), per-robot topics",
          "team": "team_firmware per team, team topics",
          "team_firmware": "team_firmware per team, per-robot topics"}
TICK_S = 0.002


def _robots_label(n: int) -> str:
    return f"{TEAM_SIZE} + {n - TEAM_SIZE} robots" if n > TEAM_SIZE else f"{n} robot{'s' if n > 1 else ''}"


def run(quick: bool = False, robots=ROBOT_COUNTS, deployments=("per_robot", "team")) -> list[dict]:
    rows = []
    for n in robots:
        for deployment in deployments:
            r = measure(n, sim_s=1.0 if quick else 4.0, deployment=deployment)
            full = n == 14
            cpu_total = r["cpu_plant_us"] + r["cpu_firmware_us"]
            rows.append({"name": f"lockstep over DDS, {_robots_label(n)}, {LABELS[deployment]}",
                         "value": round(r["rtf"], 2), "unit": "× real time",
                         "target": "≥ 1.0× (11 + 3 robots)" if full else "—",
                         "note": f"{r['sim_s']:.1f} s simulated in {r['wall_s']:.1f} s; CPU per {TICK_S * 1e3:g} ms "
                                 f"tick: plant {r['cpu_plant_us']:.0f} µs, firmware {r['cpu_firmware_us']:.0f} µs in "
                                 f"{r['firmware_processes']} process(es) ({r['cpu_firmware_us'] / n:.0f} µs per "
                                 f"robot), all {cpu_total:.0f} µs = {cpu_total * 1e-6 / TICK_S:.2f} cores at 1×"})
            rows.append({"name": f"RSS, {_robots_label(n)}, {LABELS[deployment]}",
                         "value": round(r["rss_total_mib"]), "unit": "MiB",
                         "target": "< 2048 MiB (11 + 3 robots)" if full else "—",
                         "note": f"firmware {r['rss_firmware_per_robot_mib']:.0f} MiB per robot"})
            print(rows[-2], rows[-1], file=sys.stderr, flush=True)
    # the main job on an outside world: the stand-in SSL world flat out, the AI side apart (one run)
    rows += launch_runs(1, 3.0 if quick else 10.0, 1.0, {"ai": "passing"}, world=True)
    return rows + [fail_fast_row()]


MISSING_PREFIX = "/nonexistent/erforce-realtime"


def fail_fast_row() -> dict:
    """How soon a tool that starts team_sim.launch.yaml gives up when its nodes cannot start (every launch prefix
    names a missing file, as $(find-pkg-prefix) outside the venv did): RosGraph.spin_until's error."""
    with RosGraph(Path(tempfile.mkdtemp(prefix="bench-fail-fast-"))) as graph:
        t0 = time.monotonic()
        prefixes = ("sim_launch_prefix", "ai_launch_prefix", "predictor_launch_prefix")
        graph.start_launch(TEAM_SIM, **{"real_time_factor": "0.0", **dict.fromkeys(prefixes, MISSING_PREFIX)})
        try:  # no condition: it ends by the launch's failure (RuntimeError) or at the deadline (TimeoutError)
            graph.spin_until(lambda: False, 600.0, "the warm-up")
        except RuntimeError as exc:
            waited_s, said = time.monotonic() - t0, str(exc)
    failed = said.count(MISSING_PREFIX)
    return {"name": "team_sim.launch.yaml whose nodes cannot start: the tool's error after",
            "value": round(waited_s, 1),
            "unit": "s", "target": "< 10 s (was 600 s)",
            "note": f"RosGraph.spin_until's error, naming {MISSING_PREFIX} in {failed} process(es) that failed to "
                    f"start; load average {os.getloadavg()[0]:.1f}"}


_CATCH_TIMES = re.compile(r"processing over (\d+) frames: .*; catch times out after: median ([0-9.]+) ms, "
                          r"p99 ([0-9.]+) ms, max ([0-9.]+) ms")
_MEASURING = 1_000_000  # timing_log_every while measuring over every frame: more than a run has
_EXECUTABLES = ("plant", "team_firmware", "ball_predictor", "team_catcher", "erforce-launch", "ssl_sim_server",
                "ssl_ball_predictor", "ssl_sim_bridge", "passing_game")


def _process_name(pid: int) -> str:
    argv = Path(f"/proc/{pid}/cmdline").read_bytes().split(b"\0")
    for arg in argv:  # a node's name tells the two teams' team_firmware apart
        if arg.startswith(b"__node:="):
            return arg.removeprefix(b"__node:=").decode(errors="replace")
    for arg in argv[:3]:
        name = Path(arg.decode(errors="replace")).name
        if name in _EXECUTABLES:
            return name
    return Path(argv[0].decode(errors="replace")).name


def launch_run(sim_s: float, warmup_s: float, launch_args: dict[str, str], window_frames: int = 0,
               world: bool = False) -> dict:
    """One start of team_sim.launch.yaml: real-time factor, the predictor's p99 to the catch times, CPU per
    tick per process, RSS. With ``world``: team_sim world:=ssl (the AI side alone) against the stand-in world
    ssl_world.launch.yaml, each in a DDS domain of its own, talking over loopback UDP; the real-time factor is
    the world's (its /clock), the AI's time the cameras' capture time."""
    with contextlib.ExitStack() as stack:
        graph = stack.enter_context(RosGraph(Path(tempfile.mkdtemp(prefix="bench-team-sim-"))))
        timed = graph
        args = {"real_time_factor": "0.0", "output": "screen", **launch_args}
        if world:
            timed = stack.enter_context(RosGraph(Path(tempfile.mkdtemp(prefix="bench-ssl-world-"))))
            ports = {name: str(free_udp_port()) for name in ("vision", "ours", "theirs", "control")}
            timed.start_launch(SSL_WORLD, real_time_factor="0.0", output="screen", ssl_vision_port=ports["vision"],
                               robot_control_port=ports["ours"], opponent_robot_control_port=ports["theirs"],
                               simulator_control_port=ports["control"])
            args.update(world="ssl", ssl_vision_port=ports["vision"], command_port=ports["ours"],
                        opponent_command_port=ports["theirs"], simulator_control_port=ports["control"])
            args.pop("real_time_factor")
        clocks = timed.subscribe("/clock", Clock, contract.QOS_CLOCK)
        launch = graph.start_launch(TEAM_SIM, **args)

        def sim_now() -> float:
            return stamp_to_nanoseconds(clocks[-1].clock) * 1e-9 if clocks else -1.0

        # spin_until of a graph: a launch whose nodes failed to start is reported at once, not after the deadline
        timed.spin_until(lambda: sim_now() >= warmup_s, 600.0, "the warm-up")
        # the predictor answers as Python until its kernels have loaded in the background (no warm standby here)
        graph.spin_until(lambda: COMPILED_SEARCH_LOADED in launch.output(), 120.0, "the compiled search")
        pids = {pid: f"{_process_name(pid)}/{pid}" for pid in graph.pids() + (timed.pids() if world else [])}
        assert graph.probe.set_parameter(PREDICTOR, "timing_log_every", window_frames or _MEASURING).successful
        log0 = len(launch.output())
        cpu0 = {pid: _cpu_s(pid) for pid in pids}
        t0_sim, t0_wall = sim_now(), time.monotonic()
        rss: dict[int, float] = {}
        while sim_now() < t0_sim + sim_s:
            for pid in pids:
                rss[pid] = max(rss.get(pid, 0.0), _rss_mib(pid))
            timed.probe.spin_for(0.2)
            if not launch.alive():
                raise RuntimeError("the launch ended:\n" + launch.output()[-3000:])
        sim, wall = sim_now() - t0_sim, time.monotonic() - t0_wall
        cpu1 = {pid: _cpu_s(pid) for pid in pids}
        assert graph.probe.set_parameter(PREDICTOR, "timing_log_every", 0).successful  # logs the open window
        graph.probe.spin_until(lambda: _CATCH_TIMES.search(launch.output()[log0:]), 30.0, "the predictor's timing")
        windows = [(int(m.group(1)), float(m.group(3)), float(m.group(4)), float(m.group(2)))
                   for m in _CATCH_TIMES.finditer(launch.output()[log0:])]
        if window_frames:  # the last window may be partial
            windows = [w for w in windows if w[0] == window_frames] or windows
    ticks = sim / TICK_S
    cpu = {pids[pid]: (cpu1[pid] - cpu0[pid]) / ticks * 1e6 for pid in pids}
    return {"rtf": sim / wall, "sim_s": sim, "wall_s": wall, "catch_p99_ms": max(w[1] for w in windows),
            "catch_max_ms": max(w[2] for w in windows),
            "catch_median_ms": statistics.median(w[3] for w in windows), "frames": sum(w[0] for w in windows),
            "windows": len(windows), "cpu_us_per_tick": cpu, "rss_total_mib": sum(rss.values()),
            "rss_mib": {pids[pid]: v for pid, v in rss.items()}}


def launch_runs(runs: int, sim_s: float, warmup_s: float, launch_args: dict[str, str],
                window_frames: int = 0, world: bool = False) -> list[dict]:
    results = []
    for k in range(runs):
        r = launch_run(sim_s, warmup_s, launch_args, window_frames, world)
        results.append(r)
        cpu = ", ".join(f"{name.split('/')[0]} {v:.0f}" for name, v in sorted(r["cpu_us_per_tick"].items()))
        windows = f", worst of {r['windows']} windows" if window_frames else ""
        print(f"run {k + 1}/{runs}: {r['rtf']:.3f}× real time ({r['sim_s']:.1f} s in {r['wall_s']:.1f} s), vision → "
              f"catch times median {r['catch_median_ms']:.2f} ms, p99 {r['catch_p99_ms']:.2f} ms, "
              f"max {r['catch_max_ms']:.2f} ms ({r['frames']} frames"
              f"{windows}), RSS "
              f"{r['rss_total_mib']:.0f} MiB; CPU µs per tick: {cpu}; load average {os.getloadavg()[0]:.1f}",
              file=sys.stderr, flush=True)

    def spread(values, unit, digits):
        values = sorted(values)
        return (f"median {statistics.median(values):.{digits}f}{unit}, range {values[0]:.{digits}f}–"
                f"{values[-1]:.{digits}f}{unit} over {len(values)} runs")

    command = "erforce-launch src/erforce_sim/launch/team_sim.launch.yaml " + " ".join(
        f"{k}:={v}" for k, v in {"real_time_factor": "0.0", **launch_args}.items())
    ai = launch_args.get("ai", "none")
    read = f"ai:={ai}: " + ("all 14 catch times read" if ai == "passing" else "the opponents' 3 catch times read")
    if world:
        command = ("erforce-launch src/erforce_sim/launch/ssl_world.launch.yaml real_time_factor:=0.0 and, in "
                   "another DDS domain, " + command.replace("real_time_factor:=0.0", "world:=ssl"))
        read = "the stand-in SSL world, flat out, and the AI side apart (world:=ssl); " + read
    frames = (f"the worst window of {window_frames} frames per run" if window_frames else
              "per run over every frame of the measured stretch")
    per_process: dict[str, list[float]] = {}
    for r in results:
        for name, v in r["cpu_us_per_tick"].items():
            per_process.setdefault(name.split("/")[0], []).append(v)
    cpu_note = ", ".join(f"{name} {statistics.median(v):.0f} µs" for name, v in sorted(per_process.items()))
    return [
        {"name": f"14-robot graph (11 + 3 opponents + ball, lockstep over DDS, {read}), one command, real-time "
                 "factor" + (" of the world" if world else ""),
         "value": round(statistics.median(r["rtf"] for r in results), 2), "unit": "× real time",
         "target": "≥ 1.0×" if ai == "passing" else "—",
         "note": f"{spread([r['rtf'] for r in results], '×', 2)}; `{command}`; CPU per tick (median): {cpu_note}"},
        {"name": f"14-robot graph ({read}): vision → every catch output read in the graph published "
                 "(ball_predictor, in-node), p99",
         "value": round(statistics.median(r["catch_p99_ms"] for r in results), 2), "unit": "ms",
         "target": "< 3 ms" if ai == "passing" else "—",
         "note": spread([r["catch_p99_ms"] for r in results], " ms", 2) + f", {frames}; max "
                 + spread([r["catch_max_ms"] for r in results], " ms", 2)},
        {"name": f"14-robot graph ({read}): RSS of all its processes", "value": round(statistics.median(
            r["rss_total_mib"] for r in results)), "unit": "MiB", "target": "< 2048 MiB",
         "note": spread([r["rss_total_mib"] for r in results], " MiB", 0)},
    ]


def main(argv: list[str] | None = None) -> int:
    if not argv and len(sys.argv) <= 1:
        return bench_main(run, __doc__.splitlines()[0], argv, quick_help="shorter runs")
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="shorter runs")
    parser.add_argument("--robots", type=int, nargs="+", default=list(ROBOT_COUNTS))
    parser.add_argument("--deployment", choices=tuple(DEPLOYMENTS), action="append",
                        help="per_robot and team by default; team_firmware: team processes on the per-robot topics")
    parser.add_argument("--launch-runs", type=int, default=0, help="instead: N runs of team_sim.launch.yaml")
    parser.add_argument("--launch-sim-s", type=float, default=10.0, help="simulated seconds measured per run")
    parser.add_argument("--launch-warmup-s", type=float, default=1.0, help="simulated seconds before measuring")
    parser.add_argument("--window-frames", type=int, default=0,
                        help="the predictor's p99 as the worst of windows of N frames (default: over every frame)")
    parser.add_argument("--world", action="store_true",
                        help="with --launch-runs: the AI side alone (team_sim world:=ssl) against the stand-in world "
                             "(ssl_world.launch.yaml, flat out), each in a DDS domain of its own")
    parser.add_argument("--launch-args", nargs="*", default=[], metavar="NAME:=VALUE",
                        help="more launch arguments, e.g. lockstep_topics:=per_robot")
    parser.add_argument("--launch-ai", nargs="+", default=["passing"], choices=("passing", "none"),
                        help="the graph's AI per set of runs (rows each; an ai:= in --launch-args wins): passing "
                             "(every catch time read: issue 22's target) by default")
    args = parser.parse_args(argv)
    if args.launch_runs:
        extra = dict(a.split(":=", 1) for a in args.launch_args)
        try:
            rows = [row for ai in (args.launch_ai if "ai" not in extra else [extra["ai"]])
                    for row in launch_runs(args.launch_runs, args.launch_sim_s, args.launch_warmup_s,
                                           {"ai": ai, **extra}, args.window_frames, args.world)]
        except RuntimeError as exc:  # the graph did not start (RosGraph.spin_until says why), or it ended
            print(f"error: {exc}", file=sys.stderr)
            return 1
        print("\n".join(markdown_table(rows)))
        return 0
    rows = run(args.quick, args.robots, tuple(args.deployment or ("per_robot", "team")))
    print("\n".join(markdown_table(rows)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
