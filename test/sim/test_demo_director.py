"""The demo's director takes its topics in batches and replays them in the order they were sent.

It pumps long after the messages arrived, so a light-barrier edge must still get the simulated
time of the /clock sent just before it, not the newest clock, and a catch point must pair with
the catch time sent before it.
"""

import contextlib
import os
import sys
import time
from types import SimpleNamespace

import pytest
from geometry_msgs.msg import PointStamped
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import PointCloud2
from std_msgs.msg import Bool, Float64

from erforce_interfaces.runtime.executor import DirectExecutor
from erforce_interfaces.tools.messages import point_msg
from erforce_interfaces.tools.processes import spawn_in_session, stop_process
from erforce_interfaces.tools.testing import isolated_node
from erforce_interfaces.wire import contract
from erforce_interfaces.wire.clouds import vision_robots_cdr
from erforce_interfaces.wire.conversions import nanoseconds_to_stamp, odometry_msg
from erforce_interfaces.wire.robot_config import RobotConfig
from erforce_sim.demo.demo import RECEIVER, Director

pytestmark = pytest.mark.integration


@contextlib.contextmanager
def director_and_publishers():
    """A Director on its own node, and a publisher matched to each of its subscriptions these tests feed."""
    with isolated_node("director_probe") as node:
        executor = DirectExecutor(context=node.context)
        executor.add_node(node)
        director = Director(node, RobotConfig(), executor)
        try:
            q = contract
            pubs = SimpleNamespace(
                clock=node.create_publisher(Clock, q.CLOCK.name, q.QOS_CLOCK),
                barrier=node.create_publisher(Bool, q.BALL_DETECTED.for_robot(RECEIVER), q.BALL_DETECTED.qos),
                vision=node.create_publisher(PointCloud2, q.VISION_ROBOTS.name, q.VISION_ROBOTS.qos),
                catch_time=node.create_publisher(Float64, q.CATCH_TIME.for_robot(RECEIVER), q.CATCH_TIME.qos),
                catch_point=node.create_publisher(PointStamped, q.CATCH_POINT.for_robot(RECEIVER), q.CATCH_POINT.qos),
            )
            deadline = time.monotonic() + 10.0
            while any(p.get_subscription_count() < 1 for p in vars(pubs).values()):
                assert time.monotonic() < deadline, "the director's subscriptions did not match"
                executor.spin_once(timeout_sec=0.05)
            yield director, pubs
        finally:
            director.close()


def test_a_late_pump_replays_in_send_order():
    with director_and_publishers() as (director, pubs):

        def tick(t_ns: int) -> None:
            pubs.clock.publish(Clock(clock=nanoseconds_to_stamp(t_ns)))

        tick(1_000_000_000)
        pubs.barrier.publish(Bool(data=True))  # edge at 1.00 s
        tick(1_010_000_000)
        pubs.barrier.publish(Bool(data=False))
        pubs.vision.publish(vision_robots_cdr(1.015, [], balls=[(0.0, 0.0)]))
        pubs.catch_time.publish(Float64(data=0.5))
        pubs.catch_point.publish(point_msg(1.015, (1.0, 0.0)))
        tick(1_020_000_000)
        pubs.barrier.publish(Bool(data=True))  # edge at 1.02 s
        pubs.catch_time.publish(Float64(data=0.25))  # a later frame's catch time, after the point above
        tick(1_030_000_000)

        assert director.spin_until(lambda: director.sim_ns == 1_030_000_000, 10.0, "the messages")
        assert director.barrier_edges == pytest.approx([1.00, 1.02])
        assert director.series.predictions == [(pytest.approx(1.015), 0.5)]
        assert len(director.series.catch_time_latency_s) == 1
        assert 0.0 < director.series.catch_time_latency_s[0] <= director.series.catch_point_latency_s[0]


def test_a_light_barrier_edge_gets_the_plant_time_sent_around_it_in_whatever_order_it_is_taken():
    """The plant sends a tick's /clock, then its light barriers, then its ground truth (stamped with the tick), from
    one thread. Delivery keeps no order across topics, and a loaded reader misses messages a shallow writer (/clock
    keeps one) replaced: an edge taken before the clock sent ahead of it, after clocks sent behind it, or with that
    clock missed still gets the newest simulated time sent before it, and the oldest sent after it as its bound,
    once every stamped stream has brought a message sent after it. The DDS source timestamps here are given."""
    ms = 1_000_000

    def clock(director, t_ms, sent):
        director._on_clock(Clock(clock=nanoseconds_to_stamp(t_ms * ms)), {"source_timestamp": sent})

    def ball_truth(director, t_ms, sent):
        director._on_ball_truth(odometry_msg(t_ms * 1e-3, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), "ball"),
                                {"source_timestamp": sent})

    def edge(director, sent):
        director._on_barrier(RECEIVER, Bool(data=True), {"source_timestamp": sent})
        director._on_barrier(RECEIVER, Bool(data=False), {"source_timestamp": sent + 1})

    with director_and_publishers() as (director, _pubs):
        clock(director, 990, 100)
        edge(director, 205)  # sent in the tick at 1.000 s, its clock not taken yet
        director.pump()
        assert not director.edges_settled()
        clock(director, 1000, 200)
        clock(director, 1010, 300)
        director.pump()
        clock(director, 1020, 400)
        clock(director, 1030, 500)
        edge(director, 405)  # sent in the tick at 1.020 s, taken after the clock of 1.030 s
        director.pump()
        assert director.edges_settled()
        assert director.barrier_edges == pytest.approx([1.000, 1.020])
        assert [pytest.approx(bounds) for bounds in [(1.000, 1.010), (1.020, 1.030)]] == director.barrier_edge_bounds_s

        ball_truth(director, 1035, 550)
        clock(director, 1040, 600)  # the clocks of 1.050 and 1.060 s missed
        edge(director, 805)  # sent in the tick at 1.060 s, after the ball's truth of 1.055 s
        ball_truth(director, 1055, 750)
        director.pump()
        assert not director.edges_settled()  # the truth and the clock sent after it may still come
        ball_truth(director, 1060, 810)
        director.pump()
        assert not director.edges_settled()
        clock(director, 1070, 900)
        director.pump()
        assert director.edges_settled()
        assert director.barrier_edges[-1] == pytest.approx(1.055)
        assert director.barrier_edge_bounds_s[-1] == pytest.approx((1.055, 1.060))


def test_with_ssl_arrivals_a_frame_published_after_its_catch_outputs_still_counts():
    """ssl_ball_predictor publishes a frame's /vision/robots after the frame's catch outputs: the latency starts at
    the frame's SSL arrival (by stamp) whichever of the two the director replays first."""
    with director_and_publishers() as (director, pubs):
        stamp_ns = 1_015_000_000
        arrived_ns = time.time_ns()  # the system clock, as the DDS source timestamps
        director.vision_sent_ns_of = {stamp_ns: arrived_ns}.get
        pubs.catch_time.publish(Float64(data=0.5))
        pubs.catch_point.publish(point_msg(1.015, (1.0, 0.0)))
        pubs.vision.publish(vision_robots_cdr(1.015, [], balls=[(0.0, 0.0)]))
        published_ns = time.time_ns()
        pubs.clock.publish(Clock(clock=nanoseconds_to_stamp(1_030_000_000)))

        assert director.spin_until(lambda: director.sim_ns == 1_030_000_000, 10.0, "the messages")
        assert len(director.series.catch_time_latency_s) == 1
        latency = director.series.catch_time_latency_s[0]
        assert 0.0 < latency <= (published_ns - arrived_ns) * 1e-9
        assert latency <= director.series.catch_point_latency_s[0]


def test_graph_processes_share_the_demos_session(tmp_path):
    """SCHED_IDLE ranks threads only within one autogroup (one per session): the demo's graph and
    recorder must stay in its session, each in a process group of its own for stop_process."""
    child = spawn_in_session([sys.executable, "-c", "import time; time.sleep(30)"], tmp_path / "log", idle=True)
    try:
        assert os.getsid(child.pid) == os.getsid(0)
        assert os.getpgid(child.pid) == child.pid != os.getpgrp()
        if hasattr(os, "SCHED_IDLE"):
            assert os.sched_getscheduler(child.pid) == os.SCHED_IDLE
    finally:
        stop_process(child, sigint_timeout_s=2.0)
    assert child.returncode is not None
