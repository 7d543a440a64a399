"""Issues 6 and 19, fault tests: every node's subscribed topics (contract.py) fuzzed with malformed,
non-finite, huge and empty messages, wrong array lengths and table shapes, negative, zero, far-future
and backwards stamps and foreign frame ids, while the full graph runs in lockstep. No node may crash
or stop answering, no non-finite value may appear on any topic other than the one being fuzzed at
that moment, no message may end in a node's callback guard (the harness fails the test on any), and
afterwards the graph still closes the loop. Deterministic (seeded)."""

import math

import numpy as np
import pytest
from faults_support import BURST, ClosedLoop, bad_message, closes_the_loop, non_finite_fields, subscribed_topics
from nav_msgs.msg import Odometry
from sensor_msgs.msg import JointState
from std_msgs.msg import Bool, Float64, Float64MultiArray

from erforce_interfaces import contract
from erforce_interfaces.conversions import odometry_msg, stamp_to_seconds

pytestmark = pytest.mark.integration

NODES = ("plant", "velocity_controller", "motor_boards", "ball_predictor", "catcher")


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
