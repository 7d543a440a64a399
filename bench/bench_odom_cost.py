"""What a robot's odom costs on the graph per message: the ball predictor's build and publish (odometry_cdr,
then publish of the bytes, with a reader matched) and a sampled reader's take, decode and feed (a
team_catcher on DirectExecutor, as passing_game and the opponents' interceptor read odom). What taking the
robots' poses from /ball/catches instead could save at most.

A probe publishes 14 robots' odom per frame at the vision rate (``--fps``) to a team_catcher that reads
all 14; the publish cost is timed in the probe, the reader's from /proc (its CPU while odom flows minus
its CPU while idle, per message).

    ./run exec python bench/bench_odom_cost.py [--seconds 5] [--fps 70]
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

from nav_msgs.msg import Odometry

from erforce_interfaces.tools.testing import RosGraph
from erforce_interfaces.wire import contract
from erforce_interfaces.wire.conversions import odometry_cdr

ROBOTS = 14


def _cpu_s(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def measure(seconds: float, fps: float) -> dict:
    with RosGraph(Path(tempfile.mkdtemp(prefix="bench-odom-"))) as graph:
        reader = graph.start_node("erforce_ball_model", "team_catcher", params={"robot_ids": list(range(ROBOTS))})
        pubs = [graph.probe.wait_for_subscribers(contract.ODOM.for_robot(i), Odometry, timeout_s=30.0,
                                                 qos=contract.ODOM.qos) for i in range(ROBOTS)]
        graph.probe.spin_for(2.0)  # the reader's start settles
        cpu0 = _cpu_s(reader.pid)
        graph.probe.spin_for(seconds)
        idle_s = (_cpu_s(reader.pid) - cpu0) / seconds  # CPU seconds per second without odom
        publish_s, sent = 0.0, 0
        cpu0, t0 = _cpu_s(reader.pid), time.monotonic()
        frame = 0
        while time.monotonic() - t0 < seconds:
            t_s = frame / fps
            start = time.perf_counter()
            for i, pub in enumerate(pubs):
                pub.publish(odometry_cdr(t_s, (0.1 * i, 1.0, 0.5), (0.2, -0.1, 0.3),
                                         child_frame_id=f"robot_{i}/base_link"))
            publish_s += time.perf_counter() - start
            sent += ROBOTS
            frame += 1
            next_at = t0 + frame / fps
            while time.monotonic() < next_at:
                graph.probe.spin_for(max(0.0, min(0.005, next_at - time.monotonic())))
        wall = time.monotonic() - t0
        busy_s = (_cpu_s(reader.pid) - cpu0) / wall
        assert reader.alive()
    return {"publish_us": publish_s / sent * 1e6, "read_us": (busy_s - idle_s) * wall / sent * 1e6,
            "messages": sent, "rate_hz": sent / wall}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=5.0)
    parser.add_argument("--fps", type=float, default=70.0)
    parser.add_argument("--runs", type=int, default=3)
    args = parser.parse_args(argv)
    for k in range(args.runs):
        r = measure(args.seconds, args.fps)
        print(f"run {k + 1}/{args.runs}: odom build + publish {r['publish_us']:.1f} µs per message, a sampled "
              f"reader's take + decode + feed {r['read_us']:.1f} µs per message ({r['messages']} messages at "
              f"{r['rate_hz']:.0f}/s); load average {os.getloadavg()[0]:.1f}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
