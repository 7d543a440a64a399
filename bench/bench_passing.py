"""The passing game (erforce_sim.in_process.passing_game) over seeds: how many passes rated safe complete,
interceptions, and how the receivers receive: the heading error at the light-barrier moment against the
direction of the pass the receiver then kicks, and the time from that moment to its kick.

    ./run exec python bench/bench_passing.py --seeds 1 2 3 4 5 --passes 20

One row per seed and the totals; "reception to kick" counts only passes whose receiver kicks the next
pass (no ball put back in between). The game's own floor is GameConfig.hold_min_s. Below the table, every
pass that was intercepted, lost, or rated safe and not completed, as the game explains it (PassRecord.line),
and a digest of every game's records (equal digests: the same passes, ball paths included).
"""

from __future__ import annotations

import argparse
import hashlib
import itertools
import math
import statistics
import sys
import time
from concurrent.futures import ProcessPoolExecutor


def play(seed: int, passes: int, team: int, opponents: int, receive_angle_deg: float | None) -> dict:
    from erforce_ball_model.passing.player import PlayerConfig
    from erforce_sim.in_process.passing_game import GameConfig, PassingGame, summary

    cfg = GameConfig(team_size=team, opponents=opponents, passes=passes)
    if receive_angle_deg is not None:
        cfg = GameConfig(team_size=team, opponents=opponents, passes=passes,
                         player=PlayerConfig(max_receive_angle_rad=math.radians(receive_angle_deg)))
    receptions = {}  # pass index -> (time, heading) of its receiver at the light-barrier edge
    kicks = {}  # pass index -> kick direction

    def on_tick(game) -> None:
        if game.player.passing and len(game.records) + 1 not in kicks:
            kicks[len(game.records) + 1] = game.player.choice[1].direction_rad
        if game.records and game.records[-1].index not in receptions:
            r = game.records[-1]
            if r.outcome == "completed":
                receptions[r.index] = (game.runner.t_s, game.world.robot_state(game.player.holder).theta)
            else:
                receptions[r.index] = None

    game = PassingGame(cfg, seed, on_tick=on_tick)
    t0, wall0 = time.process_time(), time.perf_counter()
    records = game.play()
    cpu, wall = time.process_time() - t0, time.perf_counter() - wall0
    notable = [r.line() for r in records
               if r.outcome != "completed" or (r.rated_safe and r.caught_by != f"robot_{r.receiver}")]
    digest = hashlib.sha256(repr(records).encode()).hexdigest()[:12]
    errors, holds, facing = [], [], []
    for r, nxt in itertools.pairwise(records):
        got = receptions.get(r.index)
        if got is None or nxt.passer != r.receiver or nxt.index not in kicks or nxt.t_kick_s < got[0]:
            continue
        errors.append(abs(math.remainder(got[1] - kicks[nxt.index], 2.0 * math.pi)))
        holds.append(nxt.t_kick_s - got[0])
        if getattr(r, "facing_target", None) is not None:  # received facing its planned next target
            facing.append((errors[-1], holds[-1]))
    s = summary(records, cfg.passing)
    return {"seed": seed, **s, "resets": game.resets, "drops": game.drops, "errors_rad": errors, "holds_s": holds,
            "facing": facing,
            "cpu_s": cpu, "sim_s": game.runner.t_s, "wall_s": wall, "notable": notable, "digest": digest}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3, 4, 5])
    parser.add_argument("--passes", type=int, default=20)
    parser.add_argument("--team", type=int, default=11)
    parser.add_argument("--opponents", type=int, default=3)
    parser.add_argument("--jobs", type=int, default=1, help="games in parallel processes")
    parser.add_argument("--receive-angle-deg", type=float, help="GameConfig.max_receive_angle_rad, in degrees")
    args = parser.parse_args(argv)
    with ProcessPoolExecutor(max_workers=args.jobs) as pool:
        runs = list(pool.map(play, args.seeds, *([x] * len(args.seeds) for x in (args.passes, args.team,
                                                                                   args.opponents,
                                                                                   args.receive_angle_deg))))
    print("| seed | passes | completed | intercepted | lost | rated safe | safe completed | drops | "
          "heading error at reception, median [deg] | reception to kick, mean [s] | "
          "of them received facing the next target: n, heading error median [deg], reception to kick mean [s] | "
          "CPU [s] | simulated [s] | real-time factor (simulated / wall) |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")

    def row(name, runs_):
        tot = {k: sum(r[k] for r in runs_) for k in ("passes", "completed", "intercepted", "lost", "rated_safe",
                                                       "safe_completed", "drops", "cpu_s", "sim_s", "wall_s")}
        errors = [e for r in runs_ for e in r["errors_rad"]]
        holds = [h for r in runs_ for h in r["holds_s"]]
        med = f"{math.degrees(statistics.median(errors)):.1f}" if errors else "—"
        hold = f"{statistics.mean(holds):.3f} (n={len(holds)})" if holds else "—"
        facing = [f for r in runs_ for f in r["facing"]]
        faced = (f"{len(facing)}, {math.degrees(statistics.median(e for e, _ in facing)):.1f}, "
                 f"{statistics.mean(h for _, h in facing):.3f}") if facing else "0"
        pct = 100.0 * tot["safe_completed"] / tot["rated_safe"] if tot["rated_safe"] else math.nan
        print(f"| {name} | {tot['passes']} | {tot['completed']} | {tot['intercepted']} | {tot['lost']} | "
              f"{tot['rated_safe']} | {tot['safe_completed']} ({pct:.0f} %) | {tot['drops']} | {med} | {hold} | "
              f"{faced} | {tot['cpu_s']:.0f} | {tot['sim_s']:.1f} | {tot['sim_s'] / tot['wall_s']:.2f} |")

    for r in runs:
        row(str(r["seed"]), [r])
    row("all", runs)
    for r in runs:
        print(f"\nseed {r['seed']}: records digest {r['digest']}")
        for line in r["notable"]:
            print(f"  {line}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
