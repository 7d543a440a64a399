"""Executors side by side: DirectExecutor (ours), rclpy's SingleThreadedExecutor and rclpy.experimental.EventsExecutor.

Three measurements per executor, each in a private DDS domain (erforce_interfaces.tools.testing.RosGraph),
with every process spinning through ``node_support.run_node`` on the executor named by
ERFORCE_EXECUTOR (erforce_interfaces.runtime.executor.make_executor):

- spin: the executor's own ``spin()``, shut down (rclpy.shutdown) from another thread after 0.5 s,
  must return; a 20 s timeout decides (an old note said EventsExecutor's spin hung). run_node spins
  EventsExecutor by a loop of ``spin_once`` (executor.make_executor), so the rows below measure it;
- ping-pong: two processes bounce a Float64 (reliable, keep last 10) back and forth; the round
  trip's wall time (median, p99) and the CPU both processes spent per round trip (from /proc);
- lockstep: bench_lockstep's graph (plant + velocity_controller + motor_boards, 1 robot, 2 ms
  tick) flat out: simulated seconds per wall second.

    ./run exec python bench/bench_executor.py [--quick]
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
from table import bench_main  # bench/table.py: the shared table format

KINDS = ("direct", "single", "events")
NAMES = {"direct": "DirectExecutor", "single": "SingleThreadedExecutor", "events": "EventsExecutor"}
PING, PONG = "/bench/ping", "/bench/pong"


def _cpu_s(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


# ------------------------------------------------------------------ the child processes
KIND = os.environ.get("ERFORCE_EXECUTOR", "direct")


def _child(role: str, count: int) -> int:
    from rclpy.node import Node
    from std_msgs.msg import Float64

    from erforce_interfaces.runtime.node_support import run_node
    from erforce_interfaces.wire.contract import QOS_COMMAND

    class Echo(Node):
        def __init__(self) -> None:
            super().__init__("bench_echo")
            pub = self.create_publisher(Float64, PONG, QOS_COMMAND)
            self.create_subscription(Float64, PING, pub.publish, QOS_COMMAND)

    class Pinger(Node):
        """Sends the next ping from the previous pong's callback; prints the round trips as JSON."""

        def __init__(self) -> None:
            super().__init__("bench_pinger")
            self._pub = self.create_publisher(Float64, PING, QOS_COMMAND)
            self._sub = self.create_subscription(Float64, PONG, self._on_pong, QOS_COMMAND)
            self._msg, self._sent, self._rtt = Float64(), 0.0, []
            self._start = self.create_timer(0.05, self._try_start)

        def _try_start(self) -> None:
            if self._pub.get_subscription_count() and self._sub.get_publisher_count():
                self._start.cancel()
                self._ping()

        def _ping(self) -> None:
            self._sent = time.perf_counter()
            self._pub.publish(self._msg)

        def _on_pong(self, _msg) -> None:
            self._rtt.append(time.perf_counter() - self._sent)
            if len(self._rtt) == count:
                print(json.dumps({"rtt_s": self._rtt}), flush=True)
                self.context.try_shutdown()
                return
            if len(self._rtt) == count // 10:  # warm-up done: the parent starts its CPU window here
                print("measuring", flush=True)
            self._ping()

    if role == "spin":  # the executor's own spin(), as rclpy documents it; shut down from another thread
        import threading

        import rclpy
        from rclpy.executors import SingleThreadedExecutor

        from erforce_interfaces.runtime.executor import DirectExecutor

        rclpy.init()
        node = Node("bench_spin")
        ticks = []
        node.create_timer(0.05, lambda: ticks.append(1))
        if KIND == "events":
            from rclpy.experimental import EventsExecutor

            executor = EventsExecutor()
        else:
            executor = {"direct": DirectExecutor, "single": SingleThreadedExecutor}[KIND]()
        executor.add_node(node)
        threading.Timer(0.5, rclpy.try_shutdown).start()
        try:
            executor.spin()
        except Exception:  # ExternalShutdownException: returned, which is what is measured
            pass
        print(json.dumps({"timer_calls": len(ticks)}), flush=True)
        return 0
    return run_node({"echo": Echo, "ping": Pinger}[role])


# ------------------------------------------------------------------ measurements
def _start(graph, kind: str, role: str, count: int = 0):
    graph.env["ERFORCE_EXECUTOR"] = kind
    return graph.start([sys.executable, str(Path(__file__).resolve()), "--child", role, str(count)], name=role)


def spin_returns(kind: str) -> tuple[float, int]:
    """Seconds from the process start until ``spin()`` returned after rclpy.shutdown at 0.5 s (inf: still
    spinning after 20 s, then killed), and how often a 50 ms timer ran meanwhile (-1: unknown)."""
    from erforce_interfaces.tools.testing import RosGraph

    with RosGraph() as graph:
        t0 = time.monotonic()
        proc = _start(graph, kind, "spin")
        try:
            proc.popen.wait(timeout=20.0)
        except subprocess.TimeoutExpired:
            return math.inf, -1  # RosGraph's close ends it (SIGINT, SIGTERM, then SIGKILL)
        elapsed = time.monotonic() - t0
        lines = [line for line in proc.log_path.read_text().splitlines() if line.startswith("{")]
        return elapsed, (json.loads(lines[-1])["timer_calls"] if lines else -1)


def ping_pong(kind: str, count: int) -> dict:
    from erforce_interfaces.tools.testing import RosGraph

    with RosGraph() as graph:
        echo = _start(graph, kind, "echo")
        pinger = _start(graph, kind, "ping", count)
        deadline = time.monotonic() + 120.0
        while "measuring" not in pinger.log_path.read_text():
            if time.monotonic() > deadline or pinger.popen.poll() is not None:
                raise RuntimeError(f"{kind}: ping-pong did not start: {pinger.log_path.read_text()[-2000:]}")
            time.sleep(0.01)
        pids = (echo.popen.pid, pinger.popen.pid)
        cpu0 = sum(_cpu_s(p) for p in pids)
        cpu1 = cpu0
        while pinger.popen.poll() is None:
            if time.monotonic() > deadline:
                raise RuntimeError(f"{kind}: ping-pong did not finish")
            try:
                cpu1 = sum(_cpu_s(p) for p in pids)  # the pinger's last reading before it exits
            except OSError:
                break
            time.sleep(0.005)
        lines = [line for line in pinger.log_path.read_text().splitlines() if line.startswith("{")]
    rtt = np.array(json.loads(lines[-1])["rtt_s"])
    measured = rtt[count // 10:]
    return {"rtt_median_us": 1e6 * float(np.median(measured)), "rtt_p99_us": 1e6 * float(np.percentile(measured, 99)),
            "cpu_us_per_round_trip": 1e6 * (cpu1 - cpu0) / measured.size}


def lockstep(kind: str, sim_s: float) -> dict:
    import bench_lockstep

    previous = os.environ.get("ERFORCE_EXECUTOR")
    os.environ["ERFORCE_EXECUTOR"] = kind  # RosGraph copies the environment for its node processes
    try:
        return bench_lockstep.measure(1, sim_s)
    finally:
        if previous is None:
            os.environ.pop("ERFORCE_EXECUTOR", None)
        else:
            os.environ["ERFORCE_EXECUTOR"] = previous


def run(quick: bool = False) -> list[dict]:
    count, sim_s = (1000, 2.0) if quick else (3000, 6.0)
    rows = []
    for kind in KINDS:
        name = NAMES[kind]
        spin_s, timer_calls = spin_returns(kind)
        rows.append(dict(name=f"{name}: spin() returns after rclpy.shutdown", value=round(spin_s, 2), unit="s",
                         target="returns", note=f"from the process start, shutdown 0.5 s after spin() began; "
                         f"inf = still spinning after 20 s; a 50 ms timer ran {timer_calls} times"
                         if timer_calls >= 0 else "inf = still spinning after 20 s (then killed)"))
        pp = ping_pong(kind, count)
        rows.append(dict(name=f"{name}: ping-pong round trip, median", value=round(pp["rtt_median_us"]), unit="µs",
                         target="-", note=f"p99 {pp['rtt_p99_us']:.0f} µs; {count - count // 10} round trips"))
        rows.append(dict(name=f"{name}: ping-pong CPU per round trip", value=round(pp["cpu_us_per_round_trip"]),
                         unit="µs", target="-", note="both processes, from /proc"))
        ls = lockstep(kind, sim_s)
        cpu = ", ".join(f"{k} {v:.0f} µs" for k, v in sorted(ls["cpu_us_per_tick"].items()))
        rows.append(dict(name=f"{name}: lockstep, 1 robot, 2 ms tick", value=round(ls["rtf"], 2),
                         unit="× real time", target="-",
                         note=f"{ls['sim_s']:.1f} s simulated in {ls['wall_s']:.1f} s; CPU per tick: {cpu}"))
    return rows


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == ["--child"]:
        return _child(argv[1], int(argv[2]))
    return bench_main(run, __doc__.splitlines()[0], argv, quick_help="fewer round trips, shorter lockstep runs")


if __name__ == "__main__":
    sys.exit(main())
