"""Issue 19, fault tests: bad time in a running graph, per node. Negative, zero, far-future and backwards
``/clock`` messages and input stamps are dropped with a warning by every node that reads them (the one
rule of erforce_interfaces.wire.stamps, applied by node_support), nothing dies, nothing non-finite comes out,
and the graph closes the loop afterwards: the catcher still drives robot_0 to the ball."""

import struct

import numpy as np
import pytest
from faults_support import ClosedLoop, bad_times, closes_the_loop
from nav_msgs.msg import Odometry
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState, PointCloud2, PointField
from std_msgs.msg import Float64MultiArray, MultiArrayDimension

from erforce_interfaces.wire import contract

pytestmark = pytest.mark.integration

NODES = ("plant", "velocity_controller", "motor_boards", "ball_predictor", "catcher")
SIM_TIME_NODES = ("velocity_controller", "motor_boards", "ball_predictor", "catcher")


def test_bad_clocks_and_stamps_are_dropped_by_every_node_and_the_loop_still_closes(ros_graph):
    loop = ClosedLoop(
        ros_graph, with_ball_model=True, exclude=("/clock",),  # the watch's own /clock would see the bad ones
        plant={"robot_poses": [-1.0, 0.0, 0.0], "ball": [1.5, 1.5, 0.0, 0.0], "vision_dropout": 0.0,
               "start_clock_subscribers": 4},
        catcher={"fetch_resting_ball": True, "v_max_mps": 1.0, "a_max_mps2": 2.0},
        predictor={"robot_v_max_mps": 1.0, "robot_a_max_mps2": 2.0},
    )
    loop.start_all()
    outputs = ("/robot_0/wheel_setpoints", "/robot_0/motor_duty", "/ball/state", "/robot_0/cmd_vel")
    loop.spin_until(lambda: all(loop.watch.counts[t] > 0 for t in outputs), 30.0, "every node publishing")
    probe = loop.probe

    def send(topic, msg_type, messages, qos, readers=1):
        pub = probe.wait_for_subscribers(topic, msg_type, readers, timeout_s=20.0, qos=qos)
        for msg in messages:
            pub.publish(msg)
            loop.spin_wall(0.05)  # /clock readers keep only the newest: one at a time

    send("/clock", Clock, [Clock(clock=t) for t in bad_times(loop.sim_s())], contract.QOS_CLOCK, 4)

    def joint_states(names, field):
        out = []
        for t in bad_times(loop.sim_s()):
            msg = JointState(name=list(names))
            msg.header.stamp = t
            setattr(msg, field, [0.0] * len(names))
            if field == "velocity":
                msg.effort = [0.0] * len(names)
            out.append(msg)
        return out

    wheels = [f"wheel_{i}" for i in range(4)]
    loop.watch.paused.update({"/robot_0/wheel_states", "/robot_0/wheel_setpoints", "/robot_0/motor_duty",
                              "/robot_0/odom", "/vision/robots", "/ball/model_params"})
    send("/robot_0/wheel_states", JointState, joint_states(wheels, "velocity"), contract.QOS_CONTROL, 2)
    send("/robot_0/wheel_setpoints", JointState, joint_states(wheels, "velocity"), contract.QOS_CONTROL)
    send("/robot_0/motor_duty", JointState, joint_states(wheels, "effort"), contract.QOS_CONTROL)
    frames, odoms = [], []
    for t in bad_times(loop.sim_s()):
        frame = PointCloud2(height=1, width=2, point_step=48, row_step=96, is_dense=True)
        frame.header.stamp, frame.header.frame_id = t, contract.FIELD_FRAME
        frame.fields = [PointField(name=name, offset=8 * k, datatype=PointField.FLOAT64, count=1)
                        for k, name in enumerate(contract.VISION_ROBOT_FIELDS)]
        frame.data = (struct.pack("<6d", 0.0, 0.0, 0.0, 0.0, contract.VISION_BALL_CODE, 0.0)  # the ball and robot_0
                      + struct.pack("<6d", 0.0, 0.0, 0.0, 0.0, contract.OURS.code, 0.0))  # at the origin
        odom = Odometry()
        odom.header.stamp, odom.pose.pose.orientation.w = t, 1.0
        frames.append(frame)
        odoms.append(odom)
    send("/vision/robots", PointCloud2, frames, contract.QOS_SENSOR)
    send("/robot_0/odom", Odometry, odoms, contract.QOS_STATE)
    # not time, but the other single message that killed the catcher: 4 columns under the right label
    table = Float64MultiArray(data=[-2.5, -0.3, 0.6, 1.0] * 3)
    table.layout.dim = [MultiArrayDimension(label=",".join(contract.BALL_MODEL_PARAM_ROWS), size=3, stride=12),
                        MultiArrayDimension(label=",".join(contract.BALL_MODEL_PARAM_LABELS), size=4, stride=4)]
    send("/ball/model_params", Float64MultiArray, [table], contract.BALL_MODEL_PARAMS.qos)
    loop.spin_wall(0.5)
    loop.watch.paused.clear()

    expected = {
        "velocity_controller": ["dropped /clock", "rejected wheel_states: stamp -1 s 0 ns is not a valid time",
                                "rejected wheel_states: stamp 0.000000 s is before"],
        "motor_boards": ["dropped /clock", "rejected wheel_states: stamp", "rejected wheel_setpoints: stamp"],
        "ball_predictor": ["dropped /clock", "rejected vision/ball: stamp", "rejected vision/robots (robot_0): stamp"],
        "catcher": ["dropped /clock", "rejected odom: stamp -1 s 0 ns is not a valid time",
                    "rejected model_params: table has 4 columns, its labels name 3"],
    }
    for node, texts in expected.items():
        out = loop.procs[node].output()
        for text in texts:
            assert text in out, f"{node} did not log {text!r}:\n{out[-3000:]}"
        assert "time line restarted" not in out, f"{node} took a bad stamp for a restart:\n{out[-3000:]}"
    for node in NODES:
        assert loop.procs[node].alive(), f"{node} died:\n{loop.procs[node].output()[-3000:]}"

    closes_the_loop(loop)
    odom = loop.watch.latest["/robot_0/odom"]
    assert abs(odom.header.stamp.sec + odom.header.stamp.nanosec * 1e-9 - loop.sim_s()) < 0.5
    loop.watch.assert_all_finite()
    assert np.all(np.isfinite(loop.velocity()))
