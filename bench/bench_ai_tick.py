"""In-process split of the passing game's and the interceptor's per-tick Python (issue #22): what the
``passing_game`` and ``team_catcher`` (press_lanes) nodes spend besides rmw, measured without the graph.

    ./run exec python bench/bench_ai_tick.py --passes 10 --seeds 1 2 3

Part 1 plays erforce_sim.in_process.passing_game (11 + 3 robots, the same cores as the graph's nodes) and
times every call of PassingPlayer.tick / on_robot / on_ball / on_catch and PressingTeam.tick / on_odom /
on_other_robot / on_ball (perf_counter_ns, summed per seed and divided by the 2 ms control ticks). The
records' digest per seed must not change with an optimisation (same decisions for the same inputs).
Part 2 times the table parsers the two nodes run per vision frame on a 14-row /ball/catches and
/robots/tracked table (CDR bytes, as the nodes take them), and one rclpy Clock.now.
Part 3 times one evaluate_passes (the passer's rating: 10 candidates, 3 opponents, the receiver search) over
random fields, with the opponents' body blocks (block_radius_m, as the player rates) and without.
``--evaluate-only`` runs part 3 alone.
"""

from __future__ import annotations

import argparse
import hashlib
import statistics
import time
import timeit
from collections import defaultdict


def timed(cls, name: str, sums: dict) -> None:
    fn = getattr(cls, name)
    key = f"{cls.__name__}.{name}"

    def wrapper(*args, **kwargs):
        t0 = time.perf_counter_ns()
        try:
            return fn(*args, **kwargs)
        finally:
            sums[key][0] += time.perf_counter_ns() - t0
            sums[key][1] += 1

    setattr(cls, name, wrapper)
    return fn


def play(seed: int, passes: int) -> tuple[dict, int, str]:
    from erforce_ball_model.passing.player import PassingPlayer, PressingTeam
    from erforce_sim.in_process.passing_game import GameConfig, PassingGame

    sums: dict = defaultdict(lambda: [0, 0])
    originals = []
    for cls, names in ((PassingPlayer, ("tick", "on_robot", "on_ball", "on_catch", "check")),
                       (PressingTeam, ("tick", "on_odom", "on_other_robot", "on_ball", "on_catch_time"))):
        for name in names:
            originals.append((cls, name, timed(cls, name, sums)))
    try:
        game = PassingGame(GameConfig(passes=passes), seed)
        records = game.play()
        ticks = game.runner.tick_index
    finally:
        for cls, name, fn in originals:
            setattr(cls, name, fn)
    digest = hashlib.sha256(repr(records).encode()).hexdigest()[:12]
    return dict(sums), ticks, digest


def parsers(repeat: int) -> dict[str, float]:
    import numpy as np

    from erforce_ball_model.passing.player import new_poses
    from erforce_interfaces.wire import contract
    from erforce_interfaces.wire.tables import (
        catches_from_msg,
        table_cdr,
        tracked_robot_row,
        tracked_robots_cdr,
        tracked_robots_from_msg,
    )

    rng = np.random.default_rng(0)
    robots = [(contract.OURS, i) for i in range(11)] + [(contract.OPPONENTS, j) for j in range(3)]
    catches = table_cdr([(team.code, j, *rng.uniform(-3, 3, 5), float(rng.uniform(0.1, 2)), *rng.uniform(-3, 3, 2))
                         for team, j in robots], contract.CATCH_TABLE_COLUMNS)
    tracked = tracked_robots_cdr([tracked_robot_row(team, j, 100.0 + 0.001 * k, rng.uniform(-3, 3, 3),
                                                    rng.uniform(-1, 1, 3)) for k, (team, j) in enumerate(robots)])
    index = {(team.code, j): k for k, (team, j) in enumerate(robots)}
    rows = tracked_robots_from_msg(tracked)

    def all_new():
        return new_poses(rows, index, [None] * len(robots))

    cases = {
        "catches_from_msg (ours, 14 rows)": lambda: catches_from_msg(catches, contract.OURS),
        "catches_from_msg (opponents, 14 rows)": lambda: catches_from_msg(catches, contract.OPPONENTS),
        "tracked_robots_from_msg (14 rows)": lambda: tracked_robots_from_msg(tracked),
        "new_poses (14 rows, all new)": all_new,
    }
    try:
        import rclpy
        from rclpy.clock import Clock, ClockType

        clock = Clock(clock_type=ClockType.ROS_TIME)
        cases["rclpy Clock.now (ROS time)"] = lambda: clock.now().nanoseconds * 1e-9
        del rclpy
    except ImportError:
        pass
    out = {}
    for name, fn in cases.items():
        runs = [min(timeit.repeat(fn, number=200, repeat=5)) / 200 for _ in range(repeat)]
        out[name] = statistics.median(runs) * 1e6
    return out


def evaluate(fields: int) -> dict[str, tuple[float, float, float]]:
    """evaluate_passes on ``fields`` random fields (11 + 3 robots, moving): median, min and max CPU ms per call."""
    import numpy as np

    from erforce_ball_model.ball_model import BallModelParams, ChipParams
    from erforce_ball_model.catch_time import CatchSearch, RobotLimits
    from erforce_ball_model.passing.decisions import PassConfig, evaluate_passes
    from erforce_interfaces.wire.robot_config import BALL_RADIUS_M, FieldConfig, RobotConfig

    robot, field, cfg, params = RobotConfig(), FieldConfig.preset("division_b"), PassConfig(), BallModelParams()
    searches = [CatchSearch(n, RobotLimits(), dribbler_offset_m=robot.dribbler_offset_m, field=field)
                for n in (14, 4)]
    rng = np.random.default_rng(0)
    cases = [(rng.uniform((-4.0, -2.5), (4.0, 2.5), (11, 2)), rng.uniform(-1.0, 1.0, (11, 2)),
              rng.uniform((-4.0, -2.5), (4.0, 2.5), (3, 2)), rng.uniform(-1.5, 1.5, (3, 2))) for _ in range(fields)]
    out = {}
    for name, radius in (("evaluate_passes, catches only", 0.0),
                         ("evaluate_passes, with body blocks", robot.robot_radius_m + BALL_RADIUS_M)):
        ms = []
        for k, (team, team_vel, opp, opp_vel) in enumerate(cases):
            args = (team[0], team, team_vel, opp, opp_vel, range(1, 11), searches[0], params, cfg,
                    robot.dribbler_offset_m)
            kwargs = {"receiver_search": searches[1], "from_passer_centre": True, "block_radius_m": radius,
                      "chip_params": ChipParams()}  # the predictor's chip model at its defaults: chips rated too
            if k == 0:
                evaluate_passes(*args, **kwargs)  # compiles or loads what the first call needs
            t0 = time.process_time()  # CPU time: the machine may be shared
            evaluate_passes(*args, **kwargs)
            ms.append((time.process_time() - t0) * 1e3)
        out[name] = (statistics.median(ms), min(ms), max(ms))
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    ap.add_argument("--passes", type=int, default=10)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--fields", type=int, default=200, help="random fields for evaluate_passes (part 3)")
    ap.add_argument("--evaluate-only", action="store_true", help="part 3 alone")
    args = ap.parse_args()
    if args.evaluate_only:
        return _print_evaluate(args.fields)
    per_tick: dict[str, list[float]] = defaultdict(list)
    per_call: dict[str, list[float]] = defaultdict(list)
    for seed in args.seeds:
        sums, ticks, digest = play(seed, args.passes)
        print(f"seed {seed}: {ticks} control ticks, records digest {digest}")
        for key, (ns, calls) in sums.items():
            per_tick[key].append(ns / ticks / 1e3)
            per_call[key].append(ns / max(calls, 1) / 1e3)
    print("\nper 2 ms control tick (median over seeds, range) and per call:")
    for key in sorted(per_tick, key=lambda k: -statistics.median(per_tick[k])):
        t, c = per_tick[key], per_call[key]
        print(f"  {key:34s} {statistics.median(t):7.1f} us/tick ({min(t):.1f}-{max(t):.1f})   "
              f"{statistics.median(c):7.1f} us/call")
    print("\nparsers, one call (median of repeats of min-of-5 x 200 calls):")
    for name, us in parsers(args.repeat).items():
        print(f"  {name:40s} {us:7.1f} us")
    return _print_evaluate(args.fields)


def _print_evaluate(fields: int) -> int:
    print(f"\nevaluate_passes, one call over {fields} random fields (CPU, median, range):")
    for name, (med, lo, hi) in evaluate(fields).items():
        print(f"  {name:40s} {med:7.3f} ms ({lo:.3f}-{hi:.3f})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
