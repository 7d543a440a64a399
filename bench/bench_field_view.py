"""The field view's cost: the page's redraw rate with 22 robots in headless Chromium, and what the
field_view node costs a graph (CPU, and the ball predictor's latency with and without it).

1. Page: the view's server (erforce_sim.view.view_server) sends binary frames (as the node does) of
   a world with 22 robots (both teams), a rolling ball with its predicted path and 11 catch points at
   70 Hz; Debian's headless Chromium draws them; the page counts its redraws (requestAnimationFrame) and times each.
2. Graph: as bench_ball_predictor, a probe sends 70 Hz vision frames of shots across a division A
   field, and all 22 robots' poses, to a ball_predictor process that knows 22 robots; the latency
   is vision frame sent -> the last robot's catch_time published (DDS source timestamp), in
   alternating blocks without a field_view process and with one running, its page open (a websocket
   client that reads every frame, standing in for the browser, which may run on another computer);
   a view is started for each such block and stopped after it, and its CPU time over the block is
   read from /proc. The predictor and the view run in the bench's session, as `./run demo --view` runs
   the graph and the view: the view's threads are SCHED_IDLE, which ranks them below the graph's only
   inside one session (Linux's autogroup). The figures: the view's CPU with 22 robots (as a share of
   a core, and per frame sent), and the latency's p50 without and with the view, each the median
   (range) over the blocks. The load average goes into the notes: on a shared VM the figures move with it.

Runs in a private DDS domain (erforce_interfaces.tools.testing.RosGraph).

    python bench/bench_field_view.py [--quick]
"""

from __future__ import annotations

import math
import os
import sys
import threading
import time

import numpy as np
from std_msgs.msg import Float64
from table import bench_main  # bench/table.py: the shared table format

from erforce_interfaces.tools.processes import stop_process
from erforce_interfaces.tools.testing import RosGraph
from erforce_interfaces.wire import contract
from erforce_interfaces.wire.clouds import vision_robots_cdr
from erforce_interfaces.wire.conversions import float64_cdr, odometry_cdr, point_cdr
from erforce_interfaces.wire.robot_config import FieldConfig
from erforce_sim.view.field_view import WorldState, decode_frame_bytes
from erforce_sim.view.field_view_node import web_dir
from erforce_sim.view.headless_browser import Browser, chromium_missing
from erforce_sim.view.view_server import ViewServer

NUM_ROBOTS = 22
FPS = 70.0
FIELD = FieldConfig.preset("division_a")


# ---------------------------------------------------------------------------------- the page
def synthetic_world(t: float) -> WorldState:
    """22 robots circling, the ball rolling back and forth, catch points for our 11."""
    state = WorldState(FIELD, opponent_ids=frozenset(range(11, 22)))
    for i in range(NUM_ROBOTS):
        angle = 0.3 * t + 2 * math.pi * i / NUM_ROBOTS
        pose = (4.5 * math.cos(angle), 3.2 * math.sin(angle), angle + math.pi / 2)
        state.apply(contract.GROUND_TRUTH_ODOM.for_robot(i), odometry_cdr(t, pose, (0.5, 0.5, 0.3)))
        if i < 11:
            state.apply(contract.CATCH_TIME.for_robot(i), float64_cdr(0.5 + 0.1 * i))
            state.apply(contract.CATCH_POINT.for_robot(i), point_cdr(t, (pose[0] * 0.5, pose[1] * 0.5)))
    x = 4.0 * math.sin(0.5 * t)
    state.apply(contract.BALL_V_SHOOT.name, float64_cdr(4.0))
    state.apply(contract.GROUND_TRUTH_BALL.name, odometry_cdr(t, (x, 0.5, 0.0), (3.0, 0.2, 0.0)))
    state.apply(contract.BALL_STATE.name, odometry_cdr(t, (x, 0.5, 0.0), (3.0, 0.2, 0.0)))
    return state


def measure_page(seconds: float) -> dict:
    server = ViewServer(web_dir(), port=0)
    server.start()
    stop = threading.Event()

    def send() -> None:
        t0 = time.monotonic()
        while not stop.is_set():
            server.publish(synthetic_world(time.monotonic() - t0).frame_bytes())
            time.sleep(1.0 / FPS)

    sender = threading.Thread(target=send, daemon=True)
    sender.start()
    browser = Browser(1400, 800)
    try:
        browser.open(server.url)
        deadline = time.monotonic() + 30.0
        while not (browser.js("return window.fieldView && window.fieldView.drawn") or {}).get("robots"):
            if time.monotonic() > deadline:
                raise RuntimeError("the page drew nothing")
            time.sleep(0.1)
        time.sleep(1.0)
        frames0, t0 = browser.js("return window.fieldView.frames"), time.monotonic()
        time.sleep(seconds)
        frames1, t1 = browser.js("return window.fieldView.frames"), time.monotonic()
        drawn = browser.js("return window.fieldView.drawn")
        draw_ms = browser.js("return window.fieldView.drawMs")
    finally:
        browser.close()
        stop.set()
        server.stop()
    return {"fps": (frames1 - frames0) / (t1 - t0), "robots": drawn["robots"], "draw_ms": draw_ms}


# --------------------------------------------------------------------------------- the graph
def _shots(num_frames: int, rng: np.random.Generator) -> np.ndarray:
    """(t, x, y): the ball across the field and back, 2 m/s along a diagonal, 2 mm noise."""
    t = 1.0 + np.arange(num_frames) / FPS
    phase = (t * 2.0 / 10.0) % 2.0
    along = np.where(phase < 1.0, phase, 2.0 - phase) * 10.0 - 5.0
    xy = np.stack([along, along * 0.7], axis=-1) + rng.normal(0.0, 0.002, (num_frames, 2))
    return np.column_stack([t, xy])


def _cpu_s(pid: int) -> float:
    """CPU time of a process's live threads [s] (their sum of ``_thread_cpu_s``)."""
    return sum(_thread_cpu_s(pid).values())


def _thread_cpu_s(pid: int) -> dict[str, float]:
    """CPU time per thread name of a process [s] (threads of one name summed): the scheduler's nanosecond
    runtime (/proc/<pid>/task/<tid>/schedstat), not utime + stime, whose 10 ms ticks are a tick or two per
    thread over a block."""
    out: dict[str, float] = {}
    for tid in os.listdir(f"/proc/{pid}/task"):
        try:
            name = open(f"/proc/{pid}/task/{tid}/comm").read().strip()
            runtime_ns = int(open(f"/proc/{pid}/task/{tid}/schedstat").read().split()[0])
        except (OSError, ValueError, IndexError):  # ended meanwhile
            continue
        out[name] = out.get(name, 0.0) + runtime_ns * 1e-9
    return out


def _page_reader(url: str, stop: threading.Event, num_robots: int, robots_seen: list, frames: list) -> None:
    """A page that reads every frame (a browser stands in here; it may run on another computer): it
    parses frames only until it has seen every robot, then counts them."""
    from websockets.sync.client import connect

    with connect(url.replace("http://", "ws://") + "ws", open_timeout=10) as ws:
        while not stop.is_set():
            try:
                message = ws.recv(timeout=0.2)
            except TimeoutError:
                continue
            frames.append(len(message))
            if not robots_seen:
                robots = decode_frame_bytes(message)["robots"]
                if len(robots) >= num_robots:
                    robots_seen.append(len(robots))


def measure_graph(frames_per_block: int, pairs: int, num_robots: int = NUM_ROBOTS) -> dict:
    """Blocks of ``frames_per_block`` vision frames with no view process and with one (its page open),
    ``pairs`` of each, their order alternating; per block the latency's p50 and the view's CPU."""
    rng = np.random.default_rng(1)
    robots = rng.uniform([-5.5, -4.0], [5.5, 4.0], (num_robots, 2))
    frames = _shots(2 * pairs * (frames_per_block + 200) + 1000, rng)  # every phase; stamps increasing
    cursor = [0]
    out: dict = {"without_p50": [], "with_p50": [], "without_p99": [], "with_p99": [], "view_cpu": [],
                 "page_fps": [], "view_cpu_per_frame": [], "view_threads_per_frame": [], "predictor_without": [],
           "predictor_with": []}
    with RosGraph() as graph:
        # The predictor and the view in this process's session, as `./run demo --view` runs the graph and the view
        predictor = graph.start_node("erforce_ball_model", "ball_predictor", own_session=False,
                         params={"num_robots": num_robots, "field": "division_a", "robot_timeout_s": 3600.0})
        probe = graph.probe
        q = contract
        catch_rx: list[int] = []
        last = q.CATCH_TIME.for_robot(num_robots - 1)
        probe.node.create_subscription(Float64, last, lambda _m, info: catch_rx.append(info["source_timestamp"]),
                                       q.CATCH_TIME.qos)
        robots_pub = probe.wait_for_subscribers(q.VISION_ROBOTS.name, q.VISION_ROBOTS.msg_type, timeout_s=120.0,
                                                qos=q.VISION_ROBOTS.qos)
        readers = [s for s in probe.node.subscriptions if s.topic_name.startswith("/robot_")]
        probe.spin_until(lambda: all(s.get_publisher_count() > 0 for s in readers), 120.0, "node publishers")

        def run_phase(count: int) -> np.ndarray:
            latencies = []
            next_send = time.perf_counter()
            rows = frames[cursor[0]:cursor[0] + count]
            cursor[0] += count
            for t, x, y in rows:
                n = len(catch_rx)
                while time.perf_counter() < next_send:
                    probe.executor.spin_once(timeout_sec=max(0.0, next_send - time.perf_counter()))
                sent_ns = time.time_ns()
                robots_pub.publish(vision_robots_cdr(t, [(q.OURS.code, i, rx, ry, 0.0)
                                                         for i, (rx, ry) in enumerate(robots)], balls=[(x, y)]))
                next_send = time.perf_counter() + 1.0 / FPS
                try:
                    probe.spin_until(lambda n=n: len(catch_rx) > n, 2.0, "catch time")
                except TimeoutError:
                    continue
                latencies.append((catch_rx[n] - sent_ns) * 1e-6)
            return np.array(latencies)

        def without_view() -> None:
            cpu0 = _cpu_s(predictor.pid)
            lat = run_phase(frames_per_block)
            out["predictor_without"].append((_cpu_s(predictor.pid) - cpu0) / frames_per_block)
            out["without_p50"].append(np.median(lat))
            out["without_p99"].append(np.percentile(lat, 99))

        def with_view() -> None:
            view = graph.start_node("erforce_sim", "field_view", params={"port": 0}, own_session=False)
            url = view.wait_for_output(r"field view at (http://\S+)", timeout_s=60.0).group(1)
            stop, seen, page_frames = threading.Event(), [], []
            reader = threading.Thread(target=_page_reader, args=(url, stop, num_robots, seen, page_frames), daemon=True)
            reader.start()
            try:
                deadline = time.monotonic() + 60.0
                while not seen:  # the view has matched every robot's topics
                    if time.monotonic() > deadline:
                        raise RuntimeError(f"the view's page never showed {num_robots} robots")
                    run_phase(10)
                run_phase(20)
                cpu0, wall0, n0 = _cpu_s(view.pid), time.monotonic(), len(page_frames)
                threads0 = _thread_cpu_s(view.pid)
                predictor0 = _cpu_s(predictor.pid)
                lat = run_phase(frames_per_block)
                out["predictor_with"].append((_cpu_s(predictor.pid) - predictor0) / frames_per_block)
                wall = time.monotonic() - wall0
                cpu = _cpu_s(view.pid) - cpu0
                threads1 = _thread_cpu_s(view.pid)
                out["view_cpu"].append(cpu / wall)
                out["page_fps"].append((len(page_frames) - n0) / wall)
                sent = max(1, len(page_frames) - n0)
                out["view_cpu_per_frame"].append(cpu / sent)
                out["view_threads_per_frame"].append({name: (threads1[name] - threads0.get(name, 0.0)) / sent
                                                      for name in threads1})
                out["with_p50"].append(np.median(lat))
                out["with_p99"].append(np.percentile(lat, 99))
            finally:
                stop.set()
                reader.join(timeout=5.0)
                stop_process(view.popen)
            # the view's readers are gone before the next block
            probe.spin_until(lambda: probe.node.count_subscribers(q.BALL_CATCHES.name) == 0, 30.0, "the view gone")

        run_phase(60)  # warm-up
        for k in range(pairs):  # alternating order: this shared VM's load drifts within a minute
            for phase in ((without_view, with_view) if k % 2 == 0 else (with_view, without_view)):
                phase()
                run_phase(20)
    return out


def _median_range(values, scale: float = 1.0, digits: int = 2) -> str:
    v = scale * np.asarray(values)
    return f"{np.median(v):.{digits}f} ({v.min():.{digits}f}–{v.max():.{digits}f})"


def _thread_split(g: dict) -> str:
    blocks = g["view_threads_per_frame"]
    names = sorted({n for b in blocks for n in b}, key=lambda n: -sum(b.get(n, 0.0) for b in blocks))
    parts = [f"{n} {1000.0 * np.mean([b.get(n, 0.0) for b in blocks]):.2f}" for n in names]
    return ", ".join(p for p in parts if not p.endswith(" 0.00"))


def run(quick: bool = False) -> list[dict]:
    rows = []
    if chromium_missing():
        rows.append(dict(name="page redraws with 22 robots (headless Chromium)", value="—", unit="frames/s",
                         target=">= 30", note="chromium / chromium-driver not installed"))
    else:
        page = measure_page(3.0 if quick else 8.0)
        rows += [
            dict(name="page redraws with 22 robots (headless Chromium)", value=page["fps"], unit="frames/s",
                 target=">= 30", note=f"{page['robots']} robots drawn, frames in at 70 Hz, 1400x800 window, "
                 f"one redraw {page['draw_ms']:.1f} ms; load average {os.getloadavg()[0]:.1f}"),
        ]
    pairs, block = (3, 150) if quick else (6, 350)
    g = measure_graph(block, pairs)
    note = (f"{NUM_ROBOTS} robots known, 70 Hz vision; {pairs} blocks of {block} frames each way, alternating; "
            f"load average {os.getloadavg()[0]:.1f}")
    rows += [
        dict(name=f"field_view process CPU while a page is open, {NUM_ROBOTS} robots, median (range) of the blocks",
             value=_median_range(g["view_cpu"], 100.0, 1), unit="% of a core", target="< 5",
             note=f"{np.median(g['page_fps']):.0f} frames/s to the page; /proc schedstat of its threads over the "
                  "block"),
        dict(name=f"field_view process CPU per frame sent to the page, {NUM_ROBOTS} robots, median (range)",
             value=_median_range(g["view_cpu_per_frame"], 1000.0, 2), unit="ms", target="< 1.67 (5 % at 30 frames/s)",
             note="the same blocks; less sensitive to the load than the share of a core, since a starved view "
                  "(SCHED_IDLE) sends fewer frames"),
        dict(name="field_view CPU per frame sent, by thread (mean of the blocks)", value=_thread_split(g), unit="ms",
             target="-", note="/proc/<pid>/task/*/schedstat, threads of one name summed"),
        dict(name="ball_predictor CPU per vision frame without / with the view, median (range) of the blocks",
             value=f"{_median_range(g['predictor_without'], 1e6, 0)} / {_median_range(g['predictor_with'], 1e6, 0)}",
             unit="µs", target="-", note="what the view's topics (/ball/track, /ball/catches) cost the predictor: "
             "the difference, at 70 frames/s"),
        dict(name=f"vision -> catch_time published, p50, {NUM_ROBOTS} robots, without / with the view, "
                  "median (range) of the blocks' p50",
             value=f"{_median_range(g['without_p50'])} / {_median_range(g['with_p50'])}", unit="ms",
             target="equal", note=note + "; without: no view process; with: it runs, its page open"),
        dict(name=f"vision -> catch_time published, p99, {NUM_ROBOTS} robots, without / with the view",
             value=f"{_median_range(g['without_p99'])} / {_median_range(g['with_p99'])}", unit="ms", target="-",
             note="the same blocks"),
    ]
    return rows


def main(argv: list[str] | None = None) -> int:
    return bench_main(run, __doc__.splitlines()[0], argv, quick_help="shorter phases")


if __name__ == "__main__":
    sys.exit(main())
