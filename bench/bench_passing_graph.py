"""The passing game on the DDS graph (team_sim.launch.yaml ai:=passing, our plant, lockstep pacing) or in one
process, with chips in play: flat passes and chips apart, how many were rated safe, how the safe ones ended,
and the catch time as planned against the light barrier's.

    ./run exec python bench/bench_passing_graph.py --team 3 --opponents 1 --passes 40
    ./run exec python bench/bench_passing_graph.py --team 3 --opponents 1 --passes 40 --in-process
    ./run exec python bench/bench_passing_graph.py --team 3 --opponents 1 --passes 40 --flat-only  # without chips
    ./run exec python bench/bench_passing_graph.py --team 3 --opponents 1 --passing chip_step_back_m=0.5

Lockstep pacing: the simulated world waits for the graph, so the game does not depend on the machine's load
(a loaded machine only takes longer). Rows: each kind of pass and all; "late" is the light barrier minus the
planned catch time of completed passes. Below the table, every pass that was not completed or was a chip.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

from erforce_sim.plant_setup import PlantSetup
from erforce_sim.ssl_cameras import CAMERA_MODELS, FIXED_ERRORS


def game_config(team: int, opponents: int, passes: int, opponents_at: list[float] | None,
                passing: dict[str, float] | None = None, cameras=None):
    """The game; ``passing``: PassConfig fields (passing_game parameters) that are not the defaults; ``cameras``: a
    CameraRealism (None: the plant's default)."""
    import dataclasses

    from erforce_ball_model.passing.player import PlayerConfig
    from erforce_sim.in_process.passing_game import OPPONENT_POSITIONS, GameConfig

    where = OPPONENT_POSITIONS if opponents_at is None else tuple(zip(opponents_at[::2], opponents_at[1::2],
                                                                      strict=True))
    player = PlayerConfig()
    player = dataclasses.replace(player, passing=dataclasses.replace(player.passing, **(passing or {})))
    more = {} if cameras is None else {"cameras": cameras}
    return GameConfig(team_size=team, opponents=opponents, passes=passes, opponent_positions=where, player=player,
                      **more)


def passing_params_file(log_dir: Path, passing: dict[str, float]) -> Path:
    """The robot description with the passing game's parameters ``passing`` beside it, as the launch's
    robot_config: one parameter file, the node's own key beside the shared one."""
    from erforce_interfaces.wire.ament_index import find_package_share

    path = log_dir / "robot_and_passing.yaml"
    text = (find_package_share("erforce_interfaces") / "config" / "robot.yaml").read_text()
    rows = "".join(f"    {name}: {float(value)!r}\n" for name, value in passing.items())
    path.write_text(text + "\n/**/passing_game:\n  ros__parameters:\n" + rows)
    return path


def graph_records(cfg, seed: int, real_time_factor: float, vision: str = "ros",
                  passing: dict[str, float] | None = None) -> list:
    """The game's passes from /pass/records of a graph started here (passing_report's launch command)."""
    import rclpy
    from std_msgs.msg import Float64MultiArray

    from erforce_ball_model.passing.passing_game_node import records_from_msg
    from erforce_interfaces.tools.processes import DomainLease, spawn_in_session, stop_processes
    from erforce_interfaces.wire import contract
    from erforce_sim.demo.passing_report import graph_commands
    from erforce_sim.in_process.passing_game import setup_for

    team, opponents, passes = cfg.team_size, cfg.opponents, cfg.passes
    args = argparse.Namespace(seed=seed, real_time_factor=real_time_factor, world="plant", pacing="lockstep",
                              vision=vision)
    cmd, _ = graph_commands(args, cfg, setup_for(cfg, seed))
    lease = DomainLease()
    os.environ["ROS_DOMAIN_ID"] = str(lease.domain_id)
    log = Path(tempfile.mkdtemp(prefix="bench_passing_graph_")) / "graph.log"
    if passing:
        cmd.append(f"robot_config:={passing_params_file(log.parent, passing)}")
    launch = spawn_in_session(cmd, log)
    print(f"graph: {team} v {opponents}, {passes} passes, seed {seed}, domain {lease.domain_id} (log: {log})",
          file=sys.stderr, flush=True)
    context = rclpy.Context()
    rclpy.init(context=context, domain_id=lease.domain_id,
               signal_handler_options=rclpy.signals.SignalHandlerOptions.NO)
    node = rclpy.create_node("bench_passing_graph", context=context)
    executor = rclpy.executors.SingleThreadedExecutor(context=context)
    executor.add_node(node)
    records: list = []

    def on_records(msg) -> None:
        for r in records_from_msg(msg):
            records.append(r)
            print(r.line(), file=sys.stderr, flush=True)

    node.create_subscription(Float64MultiArray, contract.PASS_RECORDS.name, on_records, contract.PASS_RECORDS.qos)
    deadline = time.monotonic() + 180.0 + 60.0 * passes
    try:
        while len(records) < passes and launch.poll() is None and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.1)
    finally:
        stop_processes([launch], sigint_timeout_s=10.0)
        executor.shutdown(timeout_sec=1.0)
        node.destroy_node()
        rclpy.try_shutdown(context=context)
        lease.release()
    if len(records) < passes:
        print(f"only {len(records)} of {passes} passes ended; see {log}", file=sys.stderr)
    return records[:passes]


def in_process_records(cfg, seed: int, hint_speed: bool = True) -> list:
    import dataclasses

    from erforce_sim.in_process.passing_game import PassingGame

    cfg = dataclasses.replace(cfg, hint_speed=hint_speed)
    game = PassingGame(cfg, seed, on_pass=lambda r: print(r.line(), file=sys.stderr, flush=True))
    return game.play()


def table(records: list) -> str:
    """One row per kind of pass (flat, chip) and for all: counts, the safe ones' outcomes, catch time errors."""
    lines = ["| passes | n | rated safe | safe completed | safe intercepted | safe lost | unsafe completed | "
             "late (actual - predicted) of completed, median [range] [s] |",
             "|---|---|---|---|---|---|---|---|"]
    kinds = (("flat", lambda r: r.kick_angle_deg == 0.0), ("chip", lambda r: r.kick_angle_deg > 0.0),
             ("all", lambda r: True))
    for name, keep in kinds:
        rs = [r for r in records if keep(r)]
        safe = [r for r in rs if r.rated_safe]
        done = [r for r in safe if r.outcome == "completed"]
        share = f"{len(safe)} ({100.0 * len(safe) / len(rs):.0f} %)" if rs else "0"
        ok = f"{len(done)} ({100.0 * len(done) / len(safe):.0f} %)" if safe else "0"
        late = [r.actual_catch_s - r.predicted_catch_s for r in rs
                if r.outcome == "completed" and r.actual_catch_s is not None]
        lat = (f"{statistics.median(late):+.2f} [{min(late):+.2f}, {max(late):+.2f}]" if late else "—")
        lines.append(f"| {name} | {len(rs)} | {share} | {ok} | "
                     f"{sum(r.outcome == 'intercepted' for r in safe)} | {sum(r.outcome == 'lost' for r in safe)} | "
                     f"{sum(r.outcome == 'completed' for r in rs if not r.rated_safe)} | {lat} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--team", type=int, default=3)
    parser.add_argument("--opponents", type=int, default=1)
    parser.add_argument("--passes", type=int, default=40)
    parser.add_argument("--seeds", type=int, nargs="+", default=[1])
    parser.add_argument("--real-time-factor", type=float, default=0.0, help="0: as fast as lockstep goes")
    parser.add_argument("--opponents-at", type=float, nargs="+", metavar="X Y",
                        help="the opponents' places (x y each) instead of the game's")
    parser.add_argument("--vision", choices=("ros", "ssl"), default="ros",
                        help="ssl: the plant's cameras as SSL-Vision through the bridge (the predictor sees chips)")
    parser.add_argument("--in-process", action="store_true", help="the in-process game instead (no DDS; its "
                        "predictor sees the plant's vision:=ros cameras and our kicks as hints)")
    parser.add_argument("--hint-without-speed", action="store_true",
                        help="in process: the kick hints carry the angle only")
    parser.add_argument("--flat-only", action="store_true",
                        help="the passing game rates and plays flat passes only (chip_angle_deg 0): the safe share "
                             "without chips")
    parser.add_argument("--cameras", choices=sorted(CAMERA_MODELS), default=None,
                        help="in process: how the cameras err (erforce_sim.ssl_cameras.CAMERA_MODELS; the plant's "
                             "camera_model; default its default)")
    parser.add_argument("--without", nargs="+", choices=FIXED_ERRORS, default=[],
                        help="in process: the camera model without these fixed errors (the ROS vision takes no "
                             "object_offset)")
    parser.add_argument("--passing", nargs="+", default=[], metavar="NAME=VALUE",
                        help="passing_game parameters (PassConfig fields) that are not the defaults, e.g. "
                             "chip_step_back_m=0")
    args = parser.parse_args(argv)
    passing = {name: float(value) for name, value in (item.split("=", 1) for item in args.passing)}
    if args.flat_only:
        passing["chip_angle_deg"] = 0.0
    if (args.cameras or args.without) and not args.in_process:
        parser.error("--cameras and --without are for --in-process (on the graph: the plant's camera_model)")
    cameras = None
    if args.cameras or args.without:
        cameras = CAMERA_MODELS[args.cameras or PlantSetup.cameras.name].without(*args.without)
    cfg = game_config(args.team, args.opponents, args.passes, args.opponents_at, passing, cameras)
    records = []
    for seed in args.seeds:
        if args.in_process:
            records += in_process_records(cfg, seed, not args.hint_without_speed)
        else:
            records += graph_records(cfg, seed, args.real_time_factor, args.vision, passing)
    where = ("one process" + (", hints without speed" if args.hint_without_speed else "")
             if args.in_process else f"the DDS graph, lockstep, vision {args.vision}")
    where += ", flat passes only" if args.flat_only else ", flat passes and chips"
    where += "".join(f", {item}" for item in args.passing)
    where += f", {cameras.name} cameras" if cameras is not None else ""
    at = "" if args.opponents_at is None else f" (opponents at {args.opponents_at})"
    print(f"passing game on {where}: {args.team} v {args.opponents}{at}, seeds {args.seeds}, {args.passes} passes "
          "each")
    print(table(records))
    for r in records:
        if r.outcome != "completed" or r.kick_angle_deg > 0.0:
            print(f"  {r.line()}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
