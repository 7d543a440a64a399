"""Floods: 5000 messages/s for 1 s on one input of the lockstep graph; how long does the tick stall?

The graph is the plant (lockstep, real time) with robot_0's velocity_controller and motor_boards,
real node processes in a private DDS domain (erforce_interfaces.tools.testing). A separate flooder process
publishes the careless kind of message a tool sends (`erforce-topic pub -r 5000`: a well-formed
message, stamp 0) on one topic at a time, in bursts of 5 every millisecond. The probe watches
robot_0's ground truth (100 Hz of simulated time) and reports the longest wall-clock gap in which
simulated time did not advance, from 0.5 s before the flood to 2 s after it, and the real-time
factor during the flood. The target (issue 19): no stall longer than 0.5 s.

    ./run exec python bench/bench_flood.py [--quick]
"""

from __future__ import annotations

import argparse
import itertools
import os
import sys
import tempfile
import time
from pathlib import Path

from nav_msgs.msg import Odometry
from table import bench_main  # bench/table.py: the shared table format

from erforce_interfaces.tools.testing import RosGraph
from erforce_interfaces.wire import contract
from erforce_interfaces.wire.conversions import stamp_to_seconds

ROBOT_YAML = Path(__file__).resolve().parents[1] / "src/erforce_interfaces/config/robot.yaml"
RATE_HZ = 5000
BURST = 5  # messages per millisecond
TOPICS = ("/robot_0/cmd_vel", "/robot_0/wheel_states", "/robot_0/wheel_setpoints", "/robot_0/motor_duty",
          "/clock", "/robot_0/kick", "/robot_0/sim/set_state", "/sim/set_ball")
QUICK_TOPICS = ("/robot_0/cmd_vel", "/robot_0/wheel_states", "/robot_0/motor_duty", "/clock")


def _topic(name: str) -> contract.Topic:
    for t in contract.TOPICS:
        if t.name == name or (t.per_robot and t.for_robot(0) == name):
            return t
    raise KeyError(name)


def careless_message(name: str):
    """A well-formed message as a hand-typed publish gives it: zero stamp, empty frame."""
    topic = _topic(name)
    msg = topic.msg_type()
    if topic.msg_type.__name__ == "JointState":
        msg.name = [f"wheel_{i}" for i in range(4)]
        msg.velocity, msg.effort = [0.0] * 4, [0.0] * 4
    elif topic.msg_type.__name__ == "Twist":
        msg.linear.x = 0.5
    elif topic.msg_type.__name__ == "Odometry":
        msg.pose.pose.orientation.w = 1.0
    return msg


def flood(name: str, duration_s: float) -> int:
    """The flooder process: publish ``careless_message`` at RATE_HZ for ``duration_s`` once matched."""
    import rclpy

    rclpy.init()
    node = rclpy.create_node("flooder")
    topic = _topic(name)
    pub = node.create_publisher(topic.msg_type, name, topic.qos)
    deadline = time.monotonic() + 20.0
    while pub.get_subscription_count() == 0 and time.monotonic() < deadline:
        time.sleep(0.01)
    msg = careless_message(name)
    print("flooding", flush=True)
    sent, start = 0, time.monotonic()
    while (now := time.monotonic()) - start < duration_s:
        due = int((now - start) * RATE_HZ)
        while sent < due:
            pub.publish(msg)
            sent += 1
        time.sleep(BURST / RATE_HZ)
    print(f"sent {sent} in {time.monotonic() - start:.3f} s", flush=True)
    node.destroy_node()
    rclpy.shutdown()
    return 0


def longest_stall_s(samples: list[tuple[float, float]], start: float, end: float) -> float:
    """The longest wall-time gap without progress of simulated time among (wall, sim) samples in [start, end]."""
    progress = [w for (_, s_prev), (w, s) in itertools.pairwise(samples) if s > s_prev]
    inside = [start] + [w for w in progress if start <= w <= end] + [end]
    return max(b - a for a, b in itertools.pairwise(inside))


def measure(topics: tuple[str, ...], duration_s: float = 1.0) -> list[dict]:
    rows = []
    with RosGraph(Path(tempfile.mkdtemp(prefix="bench-flood-"))) as graph:
        for exe in ("velocity_controller", "motor_boards"):
            graph.start_node("erforce_motion", exe, namespace="robot_0", params_file=ROBOT_YAML,
                             params={"use_sim_time": True})
        samples: list[tuple[float, float]] = []
        graph.probe.node.create_subscription(
            Odometry, "/robot_0/ground_truth/odom",
            lambda m: samples.append((time.monotonic(), stamp_to_seconds(m.header.stamp))), contract.QOS_STATE)
        graph.start_node("erforce_sim", "plant", params_file=ROBOT_YAML, params={
            "robot_poses": [0.0, 0.0, 0.0], "real_time_factor": 1.0, "startup_timeout_s": 60.0,
            "start_clock_subscribers": 2})
        graph.probe.spin_until(lambda: samples and samples[-1][1] > 1.0, 120.0, "the loop running")
        t0 = time.monotonic()  # the same window without a flood: what this machine's load alone costs
        graph.probe.spin_for(duration_s + 2.0)
        sim = [s for w, s in samples if t0 <= w <= t0 + duration_s]
        rows.append({"name": "no flood (baseline)", "value": round(longest_stall_s(samples, t0 - 0.5, t0 + duration_s
                                                                                    + 2.0), 3),
                     "unit": "s longest stall", "target": "≤ 0.5 s",
                     "note": f"real-time factor {(sim[-1] - sim[0]) / duration_s:.2f}; load average "
                             f"{os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs"})
        for name in topics:
            flooder = graph.start([sys.executable, __file__, "--flood", name, "--duration", str(duration_s)],
                                  name=f"flood{name.replace('/', '_')}")
            graph.probe.spin_until(lambda f=flooder: "flooding" in f.output(), 60.0, "the flooder matched")
            t0 = time.monotonic()
            graph.probe.spin_for(duration_s + 2.0)
            flooder.wait_exit(10.0)
            sim_in_flood = [s for w, s in samples if t0 <= w <= t0 + duration_s]
            rtf = (sim_in_flood[-1] - sim_in_flood[0]) / duration_s if len(sim_in_flood) > 1 else 0.0
            sent = flooder.output().strip().splitlines()[-1]
            rows.append({"name": f"flood {name}", "value": round(longest_stall_s(samples, t0 - 0.5, t0 + duration_s
                                                                                  + 2.0), 3),
                         "unit": "s longest stall", "target": "≤ 0.5 s",
                         "note": f"{RATE_HZ}/s for {duration_s:g} s ({sent}); real-time factor during the flood "
                                 f"{rtf:.2f}"})
        alive = [p.name for p in graph.processes if p.alive() and not p.name.startswith("flood")]
        rows.append({"name": "nodes alive after all floods", "value": len(alive), "unit": "of 3", "target": "3",
                     "note": ", ".join(alive)})
    return rows


def run(quick: bool = False) -> list[dict]:
    return measure(QUICK_TOPICS if quick else TOPICS)


def main(argv: list[str] | None = None) -> int:
    return bench_main(run, __doc__.splitlines()[0], argv, quick_help="four topics only")


if __name__ == "__main__":
    if "--flood" in sys.argv:
        parser = argparse.ArgumentParser()
        parser.add_argument("--flood", required=True)
        parser.add_argument("--duration", type=float, default=1.0)
        args = parser.parse_args()
        os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
        sys.exit(flood(args.flood, args.duration))
    sys.exit(main())
