"""Issues 6 and 19, fault tests: every node's subscribed topics (contract.py) fuzzed with malformed,
non-finite, huge and empty messages, wrong array lengths and table shapes, negative, zero, far-future
and backwards stamps and foreign frame ids, while the full graph runs in lockstep. No node may crash
or stop answering, no non-finite value may appear on any topic other than the one being fuzzed at
that moment, no message may end in a node's callback guard (the harness fails the test on any), and
afterwards the graph still closes the loop. Deterministic (seeded)."""

import math
import re

import numpy as np
import pytest
from builtin_interfaces.msg import Time
from faults_support import ClosedLoop, closes_the_loop, non_finite_fields, topic_names
from geometry_msgs.msg import PointStamped, PoseStamped, Twist
from nav_msgs.msg import Odometry
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Bool, Float64, Float64MultiArray

from erforce_interfaces import contract
from erforce_interfaces.conversions import odometry_msg, stamp_to_seconds

pytestmark = pytest.mark.integration

NODES = ("plant", "velocity_controller", "motor_boards", "ball_predictor", "catcher")
BAD = (math.nan, math.inf, -math.inf, 1e300, -1e300, 1e12, -1.0, 0.0)
BURST = 25  # bad messages per topic


def subscribed_topics(node: str) -> list[tuple[str, contract.Topic]]:
    """The topics ``node`` subscribes to according to the contract (all use /clock: use_sim_time)."""
    return [(name, t) for name, t in topic_names((0,))
            if re.search(rf"\b{node}\b", t.subscribers) or (t is contract.CLOCK and node != "plant")]


def test_non_finite_fields_walks_nested_messages_arrays_and_sequences():
    odom = Odometry()
    assert non_finite_fields(odom) == []
    odom.pose.pose.orientation.w = math.nan
    odom.twist.covariance[7] = math.inf
    assert non_finite_fields(odom) == ["pose.pose.orientation.w", "twist.covariance[7]"]
    js = JointState(name=["a", "b"], velocity=[0.0, -math.inf], effort=[math.nan])
    assert non_finite_fields(js) == ["velocity[1]", "effort[0]"]
    table = Float64MultiArray(data=[1.0, 2.0, math.nan])
    assert non_finite_fields(table) == ["data[2]"]
    assert non_finite_fields(Float64(data=1e300)) == []  # huge but finite
    assert non_finite_fields(Bool(data=True)) == []


def _stamp(rng) -> Time:
    kind = rng.integers(5)
    if kind == 0:
        return Time(sec=0, nanosec=0)
    if kind == 1:
        return Time(sec=2**31 - 1, nanosec=999_999_999)  # the far future
    if kind == 2:
        return Time(sec=int(rng.integers(0, 100)), nanosec=4_000_000_000)  # nanosec out of range
    if kind == 3:
        return Time(sec=int(rng.integers(-(2**31), 0)), nanosec=0)  # negative: rclpy's Time.from_msg raises
    return Time(sec=int(rng.integers(0, 5)), nanosec=int(rng.integers(0, 1_000_000_000)))  # backwards or on


def _bad(rng) -> float:
    return float(BAD[rng.integers(len(BAD))])


def _quaternion(q, rng) -> None:
    kind = rng.integers(4)
    q.x, q.y, q.z, q.w = {0: (0.0, 0.0, 0.0, 0.0), 1: (0.0, 0.0, 0.0, 2.0), 2: (math.nan, 0.0, 0.0, 1.0),
                          3: (_bad(rng), _bad(rng), _bad(rng), _bad(rng))}[int(kind)]


def bad_message(msg_type, rng):
    """One malformed message of ``msg_type`` with randomized bad fields."""
    if msg_type is JointState:
        n = int(rng.choice([0, 1, 3, 4, 5, 8]))
        names = [f"wheel_{i}" for i in range(4)]
        msg = JointState(header=_Header(rng))
        # empty, right, swapped, too few, foreign
        msg.name = [[], names, names[::-1], names[:2], ["x"] * n][int(rng.integers(5))]
        msg.velocity = [_bad(rng) for _ in range(n)]
        msg.effort = [_bad(rng) for _ in range(int(rng.choice([0, n, 4])))]
        msg.position = [_bad(rng) for _ in range(int(rng.integers(3)))]
        return msg
    if msg_type is Twist:
        msg = Twist()
        for part in (msg.linear, msg.angular):
            part.x, part.y, part.z = (_bad(rng) if rng.random() < 0.5 else 0.0 for _ in range(3))
        return msg
    if msg_type is Odometry:
        msg = Odometry(header=_Header(rng), child_frame_id="fuzz")
        p = msg.pose.pose.position
        p.x, p.y, p.z = _bad(rng), _bad(rng), _bad(rng)
        _quaternion(msg.pose.pose.orientation, rng)
        t = msg.twist.twist
        t.linear.x, t.linear.y, t.angular.z = _bad(rng), _bad(rng), _bad(rng)
        msg.pose.covariance = [_bad(rng) for _ in range(36)]
        return msg
    if msg_type is PoseStamped:
        msg = PoseStamped(header=_Header(rng))
        msg.pose.position.x, msg.pose.position.y = _bad(rng), _bad(rng)
        _quaternion(msg.pose.orientation, rng)
        return msg
    if msg_type is PointStamped:
        msg = PointStamped(header=_Header(rng))
        msg.point.x, msg.point.y, msg.point.z = _bad(rng), _bad(rng), _bad(rng)
        return msg
    if msg_type is Float64:
        return Float64(data=_bad(rng))
    if msg_type is Bool:
        return Bool(data=bool(rng.integers(2)))
    if msg_type is Clock:
        return Clock(clock=_stamp(rng))
    if msg_type is Float64MultiArray:  # a labelled table: right or wrong labels and sizes, bad values
        from std_msgs.msg import MultiArrayDimension

        rows, cols = int(rng.integers(0, 4)), int(rng.integers(0, 6))  # 4 columns killed the catcher
        labels = [",".join(contract.BALL_MODEL_PARAM_LABELS), "a,b", ""][int(rng.integers(3))]
        msg = Float64MultiArray()
        msg.layout.dim = [MultiArrayDimension(label=",".join(contract.BALL_MODEL_PARAM_ROWS[:max(rows, 1)]), size=rows,
                                              stride=rows * cols),
                          MultiArrayDimension(label=labels, size=cols, stride=cols)][: int(rng.integers(3))]
        msg.data = [_bad(rng) if rng.random() < 0.5 else -2.5 for _ in range(int(rng.choice([0, 3, 9, rows * cols])))]
        msg.layout.data_offset = int(rng.choice([0, 0, 1, 2**32 - 1]))
        return msg
    raise AssertionError(f"no fuzzer for {msg_type.__name__}")


def _Header(rng):
    from std_msgs.msg import Header

    return Header(stamp=_stamp(rng), frame_id=["", "field", "nonsense"][int(rng.integers(3))])


# What each node publishes: it must still publish after the fuzzing (it still answers).
OUTPUTS = {
    "plant": "/robot_0/wheel_states",
    "velocity_controller": "/robot_0/wheel_setpoints",
    "motor_boards": "/robot_0/motor_duty",
    "ball_predictor": "/ball/state",
    "catcher": "/robot_0/cmd_vel",
}


def test_fuzzed_inputs_crash_nothing_and_publish_nothing_non_finite(ros_graph):
    rng = np.random.default_rng(20160706)
    loop = ClosedLoop(
        ros_graph, with_ball_model=True,
        plant={"robot_poses": [-1.0, 0.0, 0.0], "ball": [1.0, 0.5, 0.0, 0.0], "vision_dropout": 0.0},
        catcher={"fetch_resting_ball": True, "v_max_mps": 1.0, "a_max_mps2": 2.0},
        predictor={"robot_v_max_mps": 1.0, "robot_a_max_mps2": 2.0},
    )
    loop.start_all()
    loop.spin_until(lambda: all(loop.watch.counts[t] > 0 for t in OUTPUTS.values()), 30.0, "every node publishing")

    fuzzed: dict[str, contract.Topic] = {}
    for node in NODES:
        fuzzed.update(subscribed_topics(node))
    assert len(fuzzed) >= 15
    for name, topic in fuzzed.items():
        loop.watch.paused.add(name)  # the bad messages echo back to the watch: not a node's output
        pub = loop.probe.publisher(name, topic.msg_type, topic.qos)
        for _ in range(BURST):
            pub.publish(bad_message(topic.msg_type, rng))
            loop.probe.spin_for(0.002)
        loop.spin_wall(0.3)  # let the burst arrive and be answered
        loop.watch.paused.discard(name)

    # Inside the plant's plausibility limits (20 m/s, 100 rad/s), but the wheels then spin past the wire's
    # range: the plant used to die publishing wheel_states; its wheel sensors saturate now (conversions).
    loop.probe.wait_for_subscribers("/robot_0/sim/set_state", Odometry).publish(
        odometry_msg(0.0, (0.0, 0.0, 0.0), (20.0, 0.0, 100.0)))
    loop.spin_wall(0.3)

    # still answering: every node publishes again, in the plant's current time line
    counts = {t: loop.watch.counts[t] for t in OUTPUTS.values()}
    loop.spin_until(lambda: all(loop.watch.counts[t] > counts[t] + 5 for t in counts), 30.0,
                    "every node publishing after the fuzzing")
    t_now = loop.sim_s()
    for topic in ("/ball/state", "/robot_0/odom"):
        stamp = stamp_to_seconds(loop.watch.latest[topic].header.stamp)
        assert abs(stamp - t_now) < 0.5, f"{topic} stamped {stamp:.3f} s, plant at {t_now:.3f} s"
    for node in NODES:
        proc = loop.procs[node]
        assert proc.alive(), f"{node} died:\n{proc.output()[-3000:]}"
        assert "rejected" in proc.output(), f"{node} logged no rejection: the fuzz did not reach it"
    loop.watch.assert_all_finite()
    closes_the_loop(loop)
    loop.watch.assert_all_finite()
