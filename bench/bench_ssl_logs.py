"""SSL log benchmark: write a synthetic game from the plant, replay it flat out over loopback UDP, and
identify the ball model on a plant-written log with known parameters (issue #21 targets: replay faster than
20x real time; identification within 5 %).

Run: .venv/bin/python bench/bench_ssl_logs.py [--quick]. Prints a markdown table; `run(quick)` returns the rows.
"""

from __future__ import annotations

import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from table import bench_main  # bench/table.py: the shared table format

from erforce_ball_model import ball_fit
from erforce_interfaces.ssl.ssl_log import LogReader, MessageType
from erforce_interfaces.ssl.ssl_log_replay import replay
from erforce_sim.ball import BallParams
from erforce_sim.demo.ssl_game_log import GameConfig, write_game_log
from erforce_sim.drivetrain import GRAVITY_MPS2

_RECEIVER = """
import socket, sys
sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 32 * 2**20)
sock.bind(("127.0.0.1", 0))
print(sock.getsockname()[1], flush=True)
sock.settimeout(30.0)
count = 0
while True:
    try:
        sock.recv(65536)
    except TimeoutError:
        break
    count += 1
    sock.settimeout(1.0)
print(count, flush=True)
"""


class Receiver:
    """Counts the datagrams arriving on a loopback port, in a process of its own (as a bridge would be)."""

    def __init__(self) -> None:
        self.proc = subprocess.Popen([sys.executable, "-c", _RECEIVER], stdout=subprocess.PIPE, text=True)
        self.address = ("127.0.0.1", int(self.proc.stdout.readline()))

    def wait(self) -> int:
        out, _ = self.proc.communicate(timeout=60.0)
        return int(out.strip())


def _replay_rows(path: Path, duration_s: float) -> list[dict]:
    receiver = Receiver()
    sender = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)

    def send(_kind: int, payload: bytes) -> None:
        sender.sendto(payload, receiver.address)

    reader = LogReader(path)
    stats = replay(reader, send, speed=0.0)
    received = receiver.wait()
    sent = sum(stats.sent.values())
    vision = stats.sent.get(MessageType.VISION_2014, 0)
    return [
        {"name": f"log replay flat out, {duration_s / 60:g}-minute game: speed over real time",
         "value": stats.speedup, "unit": "x", "target": ">= 20",
         "note": f"{stats.wall_s:.2f} s for {sent} records ({vision} vision packets, 4 cameras at 60 Hz, "
                 f"12 robots) from gzip; {sent - received} of them lost on the way to the receiving process"},
    ]


def _identification_rows(duration_s: float) -> list[dict]:
    ball = BallParams(mu_slide=3.2 / GRAVITY_MPS2, mu_roll=0.42 / GRAVITY_MPS2)
    config = GameConfig(duration_s=duration_s, seed=5, ball=ball, kick_spin_ratio=-0.2)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "ident.log.gz"
        write_game_log(path, config)
        t0 = time.perf_counter()
        report = ball_fit.analyse("bench", ball_fit.track_from_log(path))
        elapsed = time.perf_counter() - t0
    true, fit = config.true_model, report.fit.params
    rel = {n: abs(getattr(fit, n) / getattr(true, n) - 1.0) for n in ("a_slide_mps2", "a_roll_mps2", "c_switch")}
    two, const = report.errors["two-phase"], report.errors["constant deceleration"]
    return [
        {"name": f"identification on a plant log with known parameters ({duration_s:g} s), worst relative error",
         "value": 100 * max(rel.values()), "unit": "%", "target": "< 5",
         "note": f"{len(report.cut.straight)} kicks; a_slide {100 * rel['a_slide_mps2']:.2f} %, "
                 f"a_roll {100 * rel['a_roll_mps2']:.2f} %, c_switch {100 * rel['c_switch']:.2f} %; "
                 f"ball_fit took {elapsed:.1f} s"},
        {"name": "prediction error at 1 s, median: two-phase vs constant deceleration",
         "value": 100 * float(np.median(two[1.0])), "unit": "cm", "target": "-",
         "note": f"constant deceleration {100 * float(np.median(const[1.0])):.1f} cm; at 2 s "
                 f"{100 * float(np.median(two[2.0])):.1f} vs {100 * float(np.median(const[2.0])):.1f} cm"},
    ]


def run(quick: bool = False) -> list[dict]:
    duration_s = 60.0 if quick else 600.0
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "game.log.gz"
        t0 = time.perf_counter()
        summary = write_game_log(path, GameConfig(duration_s=duration_s))
        write_s = time.perf_counter() - t0
        rows = [{"name": f"synthetic game written by the plant ({duration_s / 60:g} min)", "value": write_s,
                 "unit": "s", "target": "-",
                 "note": f"{summary.shots} kicks, {summary.records} records, "
                         f"{path.stat().st_size / 2**20:.1f} MiB gzip"}]
        rows += _replay_rows(path, duration_s)
    rows += _identification_rows(60.0 if quick else 120.0)
    return rows


if __name__ == "__main__":
    sys.exit(bench_main(run, __doc__.splitlines()[0]))
