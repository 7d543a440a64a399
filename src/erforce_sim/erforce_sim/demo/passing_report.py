"""``./run demo --scenario passing``: the passing game with a report.

On the DDS graph (``run_on_graph``, the default): launch/team_sim.launch.yaml with ``ai:=passing``, our team
and the opponents placed as the in-process game places them (passing_game.setup_for), the passing_game node
playing our team and the opponents' team_catcher intercepting; a recorder (erforce-record) takes every topic
into ``bag/``, and this process prints each pass as the node publishes it (``/pass/records``) until
``--passes`` have ended. The ball path of each pass comes from ``/ground_truth/ball``.

In one process (``run``, ``--in-process``): erforce_sim.in_process.passing_game, deterministic per seed; its
bag holds the contract's topics and types: ``/clock``, ``/ground_truth/ball``, each robot's
``/robot_<id>/ground_truth/odom``, each opponent's ``/opponent_<id>/ground_truth/odom`` (100 Hz, simulated
time), one ``/sim/events`` line per kick and per pass, and the holder's choice of pass ``/pass/choice``
whenever it changes (the field view draws it when it replays the bag).

Both write report/<time>/: ``passes.png`` (every pass on the field), ``summary.md`` (one row per pass,
the totals, every interception with its predicted margin) and ``bag/``.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import re
import statistics
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

from erforce_ball_model.passing.decisions import PassConfig, PassOption
from erforce_ball_model.passing.passing_game_node import pass_choice_rows
from erforce_interfaces.wire import contract
from erforce_interfaces.wire.conversions import clock_cdr, odometry_cdr
from erforce_interfaces.wire.robot_config import FieldConfig
from erforce_interfaces.wire.tables import table_cdr
from erforce_sim.ball import BallParams
from erforce_sim.in_process.passing_game import GameConfig, PassingGame, PassRecord, plot_passes, summary

TRUTH_PERIOD_NS = 10_000_000  # 100 Hz, as the plant's ground_truth_rate_hz
TEAM_SIM_LAUNCH = Path(__file__).resolve().parents[2] / "launch" / "team_sim.launch.yaml"
SSL_WORLD_LAUNCH = TEAM_SIM_LAUNCH.with_name("ssl_world.launch.yaml")
PREDICTOR_TIMING_FRAMES = 1000  # the predictor logs its vision -> catch outputs times over this many frames
_CATCH_TIMES = re.compile(r"processing over (\d+) frames: .*; catch times out after: median ([0-9.]+) ms, "
                          r"p99 ([0-9.]+) ms")
GRAPH_START_S = 180.0  # wall time the graph may take to start (a loaded machine)
WALL_PER_PASS_S = 60.0  # and each pass to end (a pass is a few seconds of simulated time)
_NOT_WRITTEN = object()  # no /pass/choice in the bag yet (None is "no choice")


def pass_choice_cdr(choice: tuple[int, PassOption] | None, cfg: PassConfig) -> bytes:
    """/pass/choice of a passer and its chosen pass (contract.PASS_CHOICE_COLUMNS); no row for None."""
    return table_cdr(pass_choice_rows(choice, cfg), contract.PASS_CHOICE_COLUMNS)


class GameBag:
    """The game's ground truth and events into a rosbag2/MCAP bag, stamped with simulated time."""

    def __init__(self, path: Path, game: PassingGame) -> None:
        self._store = get_typestore(Stores.ROS2_JAZZY)
        self._writer = Writer(path, version=9, storage_plugin=StoragePlugin.MCAP)
        self._writer.open()
        q = contract
        add = self._add
        self._clock = add(q.CLOCK.name, q.CLOCK)
        self._ball = add(q.GROUND_TRUTH_BALL.name, q.GROUND_TRUTH_BALL)
        self._events = add(q.SIM_EVENTS.name, q.SIM_EVENTS)
        self._choice = add(q.PASS_CHOICE.name, q.PASS_CHOICE)
        self._last_choice: tuple | str | None = "none written"
        self._robots = []
        for i in range(game.n_team + game.n_opp):
            team, j = (q.OURS, i) if i < game.n_team else (q.OPPONENTS, i - game.n_team)
            self._robots.append((add(team.topic(q.GROUND_TRUTH_ODOM, j), q.GROUND_TRUTH_ODOM), team.frame(j)))
        self._last_ns = -TRUTH_PERIOD_NS

    def _add(self, name: str, topic: contract.Topic):
        return self._writer.add_connection(name, topic.type_name, typestore=self._store)

    def tick(self, game: PassingGame) -> None:
        t_ns = game.runner.t_ns
        if t_ns - self._last_ns < TRUTH_PERIOD_NS:
            return
        self._last_ns = t_ns
        t_s = t_ns * 1e-9
        w = game.world
        self._writer.write(self._clock, t_ns, clock_cdr(t_ns))
        b = w.ball_state()
        self._writer.write(self._ball, t_ns, odometry_cdr(t_s, (b.x, b.y, 0.0), (b.vx, b.vy, 0.0), "ball",
                                                          spin=(b.wx, b.wy, b.wz)))
        for i, (conn, frame) in enumerate(self._robots):
            r = w.robot_state(i)
            self._writer.write(conn, t_ns, odometry_cdr(t_s, (r.x, r.y, r.theta), (r.vx, r.vy, r.w), frame))
        choice = game.choice
        if choice != self._last_choice:
            self._writer.write(self._choice, t_ns, pass_choice_cdr(choice, game.cfg.passing))
            self._last_choice = choice

    def event(self, t_s: float, text: str) -> None:
        msg = self._store.types["std_msgs/msg/String"](data=f"t={t_s:.3f} {text}")
        self._writer.write(self._events, round(t_s * 1e9), self._store.serialize_cdr(msg, "std_msgs/msg/String"))

    def close(self) -> None:
        self._writer.close()


def summary_markdown(records: list[PassRecord], cfg: GameConfig, seed: int, sim_s: float, wall_s: float,
                     frame_costs_ms: np.ndarray | None, resets: int | None = 0, drops: int | None = 0,
                     where: str = "one process") -> str:
    s = summary(records, cfg.passing)
    safe = s["rated_safe"]
    lines = [
        f"# The passing game: {cfg.team_size} robots against {cfg.opponents}, seed {seed} ({where})",
        "",
        f"- passes: {s['passes']}; completed {s['completed']}, intercepted {s['intercepted']}, lost {s['lost']}",
        f"- rated safe (margin >= {cfg.passing.safe_margin_s:.2f} s): {safe}, of them completed {s['safe_completed']}"
        + (f" ({100.0 * s['safe_completed'] / safe:.0f} %)" if safe else ""),
    ]
    if resets is not None:
        why = ("" if drops is None else
               f"; {drops} time(s) because the holder lost it before kicking")
        lines.append(f"- the ball was put back at a teammate {resets} time(s) (after interceptions, losses and "
                     f"drops{why})")
    lines.append(f"- {sim_s:.1f} s simulated in {wall_s:.1f} s of wall time (real-time factor "
                 f"{sim_s / wall_s if wall_s > 0 else 0.0:.2f}; {where}; the machine's load counts)")
    if frame_costs_ms is not None and len(frame_costs_ms):
        lines.append(f"- ball predictor per vision frame, all {cfg.team_size + cfg.opponents} robots (CPU): median "
                     f"{np.median(frame_costs_ms):.3f} ms, p99 {np.percentile(frame_costs_ms, 99):.3f} ms")
    lines += [
        "",
        "| # | from | to | kick [m/s] | catch predicted [s] | actual [s] | margin [s] | rated | outcome |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in records:
        actual = "—" if r.actual_catch_s is None else f"{r.actual_catch_s:.2f}"
        margin = "∞" if np.isinf(r.margin_s) else f"{r.margin_s:+.2f}"
        outcome = r.outcome + ("" if r.caught_by in (None, f"robot_{r.receiver}") else f" by {r.caught_by}")
        lines.append(f"| {r.index} | robot_{r.passer} | robot_{r.receiver} | {r.kick_speed_mps:.2f} | "
                     f"{r.predicted_catch_s:.2f} | {actual} | {margin} | {'safe' if r.rated_safe else 'unsafe'} | "
                     f"{outcome} |")
    failed = [r for r in records if r.outcome != "completed"]
    if failed:
        lines += ["", "## Interceptions and losses", ""]
        lines += [f"- pass {r.index}: {r.line()[len(f'pass {r.index:2d}  '):]}" for r in failed]
    return "\n".join(lines) + "\n"


def run(args: argparse.Namespace) -> int:
    out = Path(args.out) / time.strftime("%Y%m%d-%H%M%S")
    out.mkdir(parents=True, exist_ok=True)
    cfg = GameConfig(team_size=args.team, opponents=args.opponents, passes=args.passes)
    bag: GameBag | None = None

    def on_pass(record: PassRecord) -> None:
        print(record.line(), flush=True)
        bag.event(record.t_kick_s + (record.actual_catch_s or 0.0), record.line())

    game = PassingGame(cfg, args.seed, on_pass=on_pass, on_tick=lambda g: bag.tick(g))
    bag = GameBag(out / "bag", game)
    print(f"passing game: {cfg.team_size} robots against {cfg.opponents}, {cfg.passes} passes, seed {args.seed}",
          flush=True)
    wall0 = time.perf_counter()
    try:
        records = game.play()
    finally:
        bag.close()
    wall = time.perf_counter() - wall0
    plot_passes(records, game.field, out / "passes.png",
                f"{cfg.team_size} v {cfg.opponents}, seed {args.seed}: true ball path of every pass")
    text = summary_markdown(records, cfg, args.seed, game.runner.t_s, wall, np.array(game.frame_costs_s) * 1e3,
                            game.resets, game.drops)
    (out / "summary.md").write_text(text)
    print("\n" + text, flush=True)
    print(f"report: {out}")
    return 0


def _flat(poses) -> str:
    return "[" + ", ".join(f"{v:.6f}" for pose in poses for v in pose) + "]"


def graph_commands(args: argparse.Namespace, cfg: GameConfig, setup) -> tuple[list[str], list[str] | None]:
    """The launch commands of the game: (the AI side, or the whole graph with our plant; the stand-in world with
    ``--world ssl``, else None). With ``--world ssl`` the two talk only over the league's protocols, on ports free
    on this machine: SSL-Vision from the world, each colour's RobotControl and the teleports to it."""
    from erforce_interfaces.tools.processes import free_udp_port

    bin_dir = Path(sys.executable).parent
    teams = [f"robot_ids:={list(range(cfg.team_size))}", f"num_robots:={cfg.team_size}",
             f"opponent_ids:={list(range(cfg.opponents))}", f"num_opponents:={cfg.opponents}",
             f"field:={cfg.field_preset}", f"seed:={args.seed}", f"real_time_factor:={args.real_time_factor}",
             "output:=screen"]
    poses = [f"robot_poses:={_flat(setup.robot_poses)}", f"opponent_poses:={_flat(setup.opponent_poses)}"]
    ai = [str(bin_dir / "erforce-launch"), str(TEAM_SIM_LAUNCH), "ai:=passing", *teams,
          f"opponents_intercept:={'true' if cfg.opponents else 'false'}",
          f"predictor_timing_log_every:={PREDICTOR_TIMING_FRAMES}"]
    if args.world == "plant":
        ai += [*poses, f"pacing:={args.pacing}"]
        if args.vision == "ssl":  # the plant's 4 cameras as SSL-Vision over loopback multicast, through the bridge
            ai += ["vision:=ssl", f"ssl_vision_port:={free_udp_port()}"]
        return ai, None
    vision, ours, theirs, control = (free_udp_port() for _ in range(4))
    world = [str(bin_dir / "erforce-launch"), str(SSL_WORLD_LAUNCH), *teams, *poses,
             f"ssl_vision_port:={vision}", f"robot_control_port:={ours}", f"opponent_robot_control_port:={theirs}",
             f"simulator_control_port:={control}"]
    if args.world_ball is not None:  # else the world's own carpet
        a_slide, a_roll, c_switch = args.world_ball
        world += [f"ball_a_slide_mps2:={a_slide}", f"ball_a_roll_mps2:={a_roll}",
                  f"kick_spin_ratio:={kick_spin_ratio_for(c_switch)}"]
    ai += ["world:=ssl", f"ssl_vision_port:={vision}", f"command_port:={ours}", f"opponent_command_port:={theirs}",
           f"simulator_control_port:={control}"]
    return ai, world


def kick_spin_ratio_for(c_switch: float) -> float:
    """The plant's kick spin w r / v that gives ``c_switch`` (erforce_sim.ball.BallParams.switch_ratio inverted)."""
    q = 1.0 / BallParams().inertia_factor
    return c_switch * (q + 1.0) - q


def predictor_timing(log_text: str) -> list[tuple[int, float, float]]:
    """(frames, median, p99 [ms]) of each of the predictor's timing lines: vision frame in -> catch outputs out."""
    return [(int(m.group(1)), float(m.group(2)), float(m.group(3))) for m in _CATCH_TIMES.finditer(log_text)]


class _Observer:
    """The director's node in one DDS domain, in a context of its own (the AI's, and the stand-in world's)."""

    def __init__(self, name: str, domain_id: int | None) -> None:
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor

        self.context = Context()
        kwargs = {} if domain_id is None else {"domain_id": domain_id}
        rclpy.init(context=self.context, signal_handler_options=rclpy.signals.SignalHandlerOptions.NO, **kwargs)
        self.node = rclpy.create_node(name, context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.clock: dict[str, tuple[float, float] | None] = {"first": None, "now": None}

    def watch_clock(self, on_time=None) -> None:
        from rosgraph_msgs.msg import Clock

        from erforce_interfaces.wire.conversions import stamp_to_seconds

        def on_clock(msg) -> None:
            t = stamp_to_seconds(msg.clock)
            if self.clock["first"] is None:
                self.clock["first"] = (t, time.monotonic())
            self.clock["now"] = (t, time.monotonic())
            if on_time is not None:
                on_time(t)

        self.node.create_subscription(Clock, contract.CLOCK.name, on_clock, contract.CLOCK.qos)

    def real_time(self) -> tuple[float, float]:
        """(simulated, wall) seconds between the first and the newest /clock seen."""
        first, now = self.clock["first"], self.clock["now"]
        return (0.0, 0.0) if first is None else (now[0] - first[0], now[1] - first[1])

    def close(self) -> None:
        import rclpy

        self.executor.shutdown(timeout_sec=1.0)
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)


def run_on_graph(args: argparse.Namespace) -> int:
    """The game on the DDS graph (module docstring); 0 once ``args.passes`` passes ended, 1 otherwise.

    With ``--world ssl`` the stand-in world (ssl_world.launch.yaml) runs as a program of its own, in a DDS
    domain of its own, and the AI side (team_sim.launch.yaml world:=ssl) sees only its SSL packets: the bag is
    what the AI side sees; the report's ball paths, placements and the world's real-time factor come from the
    world's own topics, which this director reads beside it."""
    from nav_msgs.msg import Odometry
    from std_msgs.msg import Float64MultiArray

    from erforce_ball_model.passing.passing_game_node import records_from_msg
    from erforce_interfaces.tools.processes import stop_processes
    from erforce_interfaces.wire.conversions import odometry_from_msg

    out = Path(args.out) / time.strftime("%Y%m%d-%H%M%S")
    out.mkdir(parents=True, exist_ok=True)
    cfg = GameConfig(team_size=args.team, opponents=args.opponents, passes=args.passes)
    started = _start_graph(args, cfg, out)
    outside, lease = started.world is not None, started.lease
    records: list[PassRecord] = []
    ball_path: list[tuple[float, float, float]] = []  # t, x, y of the true ball
    ai = _Observer("passing_director", None)
    truth = _Observer("passing_director_world", lease.domain_id) if outside else ai
    # The AI's time is the world's cameras' capture time, whose clock need not be the world's simulated time:
    # the report maps the world's truth onto it by the offset seen between the two /clocks.
    offsets: list[float] = []

    def on_ai_time(t_s: float) -> None:
        if truth.clock["now"] is not None and len(offsets) < 100_000:
            offsets.append(t_s - truth.clock["now"][0])

    ai.watch_clock(on_ai_time if outside else None)
    if outside:
        truth.watch_clock()
    q = contract

    def on_record(msg) -> None:
        for r in records_from_msg(msg):
            records.append(r)
            print(r.line(), flush=True)

    def on_ball(msg) -> None:
        t, pose, _, _ = odometry_from_msg(msg)
        ball_path.append((t, pose[0], pose[1]))

    ai.node.create_subscription(Float64MultiArray, q.PASS_RECORDS.name, on_record, q.PASS_RECORDS.qos)
    truth.node.create_subscription(Odometry, q.GROUND_TRUTH_BALL.name, on_ball, q.GROUND_TRUTH_BALL.qos)
    graphs = [p for p in (started.launch, started.world) if p is not None]
    observers = list({id(o): o for o in (ai, truth)}.values())
    deadline = time.monotonic() + GRAPH_START_S + cfg.passes * WALL_PER_PASS_S
    try:
        while (len(records) < cfg.passes and all(p.poll() is None for p in graphs)
               and time.monotonic() < deadline):
            for observer in observers:
                observer.executor.spin_once(timeout_sec=0.1)
    except KeyboardInterrupt:
        print("interrupted: stopping the graph", flush=True)
    finally:
        _stop_quietly(stop_processes, graphs, started.recorder, started.view, out / "record.log")
        for observer in observers:
            observer.close()
        if lease is not None:
            lease.release()
    if offsets:
        shift = statistics.median(offsets)
        ball_path = [(t + shift, x, y) for t, x, y in ball_path]
    return _report_graph_game(args, cfg, out, started.where, records, ball_path, ai.real_time(),
                              truth.real_time() if outside else None)


@dataclasses.dataclass
class _GraphProcesses:
    """What run_on_graph started: the AI side's launch, the stand-in world (``--world ssl``, else None) with the
    lease of its own DDS domain, the recorder, the field view (``--view``, else None)."""

    launch: Any
    world: Any
    lease: Any
    recorder: Any
    view: Any
    where: str  # the report's words for where the game ran


def _start_graph(args: argparse.Namespace, cfg: GameConfig, out: Path) -> _GraphProcesses:
    """Start the processes of a game on the graph (run_on_graph)."""
    from erforce_interfaces.tools.processes import DomainLease, spawn_in_session
    from erforce_sim.demo.view_process import start_field_view
    from erforce_sim.in_process.passing_game import setup_for

    ai_cmd, world_cmd = graph_commands(args, cfg, setup_for(cfg, args.seed))
    outside = world_cmd is not None
    where = "on the stand-in SSL world, apart" if outside else "on the DDS graph"
    print(f"passing game {where}: {cfg.team_size} robots against {cfg.opponents}, {cfg.passes} passes, seed "
          f"{args.seed} (log: {out / 'graph.log'})", flush=True)
    world = lease = None
    if outside:
        lease = DomainLease()
        env = {**os.environ, "ROS_DOMAIN_ID": str(lease.domain_id)}
        world = spawn_in_session(world_cmd, out / "world.log", env=env)
    launch = spawn_in_session(ai_cmd, out / "graph.log")
    bin_dir = Path(sys.executable).parent
    # The recorder at idle priority only where the graph cannot run above it: beside a world and an AI under
    # SCHED_FIFO it cannot preempt them, and at idle a flat-out world on a shared machine starved it for a whole game.
    recorder = spawn_in_session([str(bin_dir / "erforce-record"), str(out / "bag"), "--use-sim-time"],
                                out / "record.log", idle=not _fifo_allowed())
    view = start_field_view(args, out, cfg.field_preset, range(cfg.team_size)) if args.view else None
    return _GraphProcesses(launch, world, lease, recorder, view, where)


def _report_graph_game(args, cfg: GameConfig, out: Path, where: str, records: list[PassRecord],
                       ball_path: list, real_time: tuple[float, float], world_real_time) -> int:
    """The plot, the summary and the exit code of a game on the graph (run_on_graph)."""
    sim_s, wall_s = real_time
    records = [dataclasses.replace(r, ball_path=_path_of(r, ball_path, cfg)) for r in records[:cfg.passes]]
    if records:
        plot_passes(records, FieldConfig.preset(cfg.field_preset), out / "passes.png",
                    f"{cfg.team_size} v {cfg.opponents} {where}, seed {args.seed}: true ball path of every pass")
    # the passing game's placements (its log): the first starts the game, each further one is a reset
    placements = (out / "graph.log").read_text(errors="replace").count("] [passing_game]: ball placed at robot_")
    text = summary_markdown(records, cfg, args.seed, sim_s, wall_s, None, max(placements - 1, 0), None,
                            where=where)
    text += _graph_notes(out, world_real_time)
    (out / "summary.md").write_text(text)
    print("\n" + text, flush=True)
    print(f"report: {out}")
    if len(records) < cfg.passes:
        print(f"only {len(records)} of {cfg.passes} passes ended; see {out / 'graph.log'}", flush=True)
        return 1
    return 0


def _fifo_allowed() -> bool:
    """Whether this user may run threads under SCHED_FIFO (as erforce-realtime does for the graph)."""
    import threading

    allowed = []

    def probe() -> None:  # a thread of its own: the policy is per thread and ends with it
        try:
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(1))
            allowed.append(True)
        except (AttributeError, OSError):
            pass

    thread = threading.Thread(target=probe)
    thread.start()
    thread.join()
    return bool(allowed)


def _path_of(record: PassRecord, ball_path: list, cfg: GameConfig) -> tuple:
    end = record.t_kick_s + (record.actual_catch_s if record.actual_catch_s is not None
                             else cfg.player.pass_timeout_s)
    return tuple((x, y) for t, x, y in ball_path if record.t_kick_s <= t <= end)


def _stop_quietly(stop_processes, graphs, recorder, view, recorder_log: Path) -> None:
    """The graph first (each launch with its nodes, at once), then the observers, with Ctrl-C ignored meanwhile
    so that nothing is left running. A recorder still importing (it starts at idle priority, and a flat-out
    world can hold it off) gets SIGTERM: SIGINT would end its imports with a KeyboardInterrupt traceback."""
    import signal

    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        stop_processes(graphs, sigint_timeout_s=10.0)
        if recorder.poll() is None and not recorder_log.read_text(errors="replace").strip():
            recorder.terminate()
        stop_processes([p for p in (recorder, view) if p is not None], sigint_timeout_s=20.0)
    finally:
        signal.signal(signal.SIGINT, previous)


def _graph_notes(out: Path, world_real_time: tuple[float, float] | None) -> str:
    """The summary's lines on time: the predictor's vision -> catch outputs times and the world's pace."""
    lines = []
    timing = predictor_timing((out / "graph.log").read_text(errors="replace"))
    if timing:
        frames = sum(n for n, _, _ in timing)
        p99 = sorted(p for _, _, p in timing)
        lines.append(f"- ball predictor, vision frame in -> catch outputs out (in-node): p99 {min(p99):.2f}-"
                     f"{max(p99):.2f} ms (median of windows {statistics.median(p99):.2f} ms) over {len(timing)} "
                     f"windows of {PREDICTOR_TIMING_FRAMES} frames ({frames} frames)")
    if world_real_time is not None and world_real_time[1] > 0:
        sim, wall = world_real_time
        lines.append(f"- the stand-in world: {sim:.1f} s simulated in {wall:.1f} s of wall time (its real-time factor "
                     f"{sim / wall:.2f}); the AI's time above is the cameras' capture time")
    return ("\n" + "\n".join(lines) + "\n") if lines else ""
