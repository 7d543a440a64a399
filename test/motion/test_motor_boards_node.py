"""motor_boards over DDS: lockstep answers, the setpoint join, status, bad input, parameters."""

import itertools
import math

import numpy as np
import pytest
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray

from erforce_interfaces.tools.messages import joint_state_msg
from erforce_interfaces.wire import contract
from erforce_interfaces.wire.robot_config import RobotConfig
from erforce_interfaces.wire.tables import table_from_msg

pytestmark = pytest.mark.integration

NAMES = RobotConfig().wheel_names
MS = 1_000_000


def stamp_ns(msg):
    return msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec


class Rig:
    def __init__(self, graph, **params):
        self.graph = graph
        # these tests tick every 1 ms (MS), so the boards run at 1 kHz (the node's default is 500 Hz)
        params = {"loop_rate_hz": 1000.0, **params}
        self.node = graph.start_node("erforce_motion", "motor_boards", namespace="robot_0", params=params)
        probe = graph.probe
        self.duties = probe.subscribe("/robot_0/motor_duty", JointState, contract.QOS_CONTROL)
        self.status = probe.subscribe("/robot_0/motor_status", Float64MultiArray, contract.QOS_STATE)
        self.states = probe.wait_for_subscribers("/robot_0/wheel_states", JointState, timeout_s=20.0,
                                                 qos=contract.QOS_CONTROL)
        self.setpoints = probe.wait_for_subscribers("/robot_0/wheel_setpoints", JointState, timeout_s=20.0,
                                                    qos=contract.QOS_CONTROL)
        probe.spin_until(lambda: probe.node.count_publishers("/robot_0/motor_duty") > 0, 20.0, "duty publisher")

    def send_state(self, t_ns, speeds=None, currents=None):
        self.states.publish(joint_state_msg(t_ns, NAMES, velocity=np.zeros(4) if speeds is None else speeds,
                                            effort=np.zeros(4) if currents is None else currents))

    def answer(self, t_ns, timeout_s=5.0):
        self.graph.probe.spin_until(lambda: any(stamp_ns(m) == t_ns for m in self.duties), timeout_s,
                                    f"duty for {t_ns}")
        return np.array(next(m for m in self.duties if stamp_ns(m) == t_ns).effort)


def test_duty_answers_each_tick_with_the_previous_ticks_setpoint(ros_graph):
    rig = Rig(ros_graph)
    rig.send_state(1 * MS)
    assert np.all(rig.answer(1 * MS) == 0.0)  # no setpoint yet: zero speed, at rest -> zero duty
    rig.setpoints.publish(joint_state_msg(1 * MS, NAMES, velocity=[50.0, 50.0, 50.0, 50.0]))
    rig.send_state(2 * MS)
    duty = rig.answer(2 * MS)
    # inverse model at rest: duty = R/V * i_cmd > 0 for a positive speed error
    assert np.all(duty > 0.0) and np.all(duty <= 1.0)


def test_lockstep_join_holds_the_tick_until_the_setpoint_arrives(ros_graph):
    rig = Rig(ros_graph, setpoint_wait_s=5.0)
    rig.send_state(1 * MS)
    rig.answer(1 * MS)
    rig.send_state(2 * MS)  # the answer needs tick 1's setpoint, not sent yet
    rig.send_state(2 * MS)  # the plant re-sends a tick unanswered after 50 ms: it must wait all the same
    ros_graph.probe.spin_for(0.3)
    assert not any(stamp_ns(m) == 2 * MS for m in rig.duties)
    rig.setpoints.publish(joint_state_msg(1 * MS, NAMES, velocity=[-30.0] * 4))
    assert np.all(rig.answer(2 * MS) < 0.0)


def test_silent_velocity_controller_costs_one_wait_then_wheels_stop(ros_graph):
    rig = Rig(ros_graph, setpoint_wait_s=0.05, setpoint_timeout_s=0.005)
    rig.send_state(1 * MS)
    rig.answer(1 * MS)
    rig.setpoints.publish(joint_state_msg(1 * MS, NAMES, velocity=[40.0] * 4))
    rig.send_state(2 * MS)
    rig.answer(2 * MS)
    for k in range(3, 20):  # the controller went silent: answered after one wall-clock wait
        rig.send_state(k * MS)
        rig.answer(k * MS, timeout_s=2.0)
    rig.node.wait_for_output("no setpoint for 0.005 s: stopping the wheels", timeout_s=5.0)


def test_status_reports_average_current_and_limit(ros_graph):
    rig = Rig(ros_graph, status_rate_hz=1000.0)
    rig.send_state(1 * MS, currents=[2.0, 0.0, 0.0, 0.0])
    rig.answer(1 * MS)
    ros_graph.probe.spin_until(lambda: len(rig.status) > 0, 5.0, "motor_status")
    table = table_from_msg(rig.status[-1], contract.MOTOR_STATUS_COLUMNS)
    assert table.shape == (4, 4)
    # one 1 ms sample of 2 A in a 10 s boxcar that starts from zero: 2 A / 10000
    assert table[0, 0] == pytest.approx(2.0 / 10000)
    assert np.all(table[:, 1] == 1.0)  # full PWM allowed


@pytest.mark.parametrize("bad", ["nan_speed", "nan_current", "short", "huge"])
def test_bad_wheel_states_rejected_node_keeps_answering(ros_graph, bad):
    rig = Rig(ros_graph)
    msg = JointState(velocity=[0.0] * 4, effort=[0.0] * 4)
    msg.header.stamp.sec = 1
    if bad == "nan_speed":
        msg.velocity[1] = math.nan
    elif bad == "nan_current":
        msg.effort[2] = math.inf
    elif bad == "short":
        msg.velocity = [0.0] * 3
    else:
        msg.velocity[0] = 1e12
    rig.states.publish(msg)
    rig.node.wait_for_output("rejected wheel_states", timeout_s=10.0)
    rig.send_state(2 * MS)
    assert np.all(np.isfinite(rig.answer(2 * MS)))
    assert not any(not np.all(np.isfinite(m.effort)) for m in rig.duties)


def test_a_lone_backwards_tick_is_dropped_and_a_confirmed_one_resets(ros_graph):
    """The time rule (erforce_interfaces.wire.stamps): one stamp from the past is dropped, a second that
    continues from it is a restarted plant, and the boards reset and answer it."""
    rig = Rig(ros_graph)
    for k in (5, 6, 7):
        rig.send_state(k * MS)
        rig.answer(k * MS)
    for stamp_sec in (-1, 0):  # no valid time; then a lone zero stamp
        msg = joint_state_msg(0, NAMES, velocity=np.zeros(4), effort=np.zeros(4))
        msg.header.stamp.sec = stamp_sec
        rig.states.publish(msg)
    rig.node.wait_for_output("rejected wheel_states: stamp -1 s 0 ns is not a valid time", timeout_s=10.0)
    rig.node.wait_for_output(r"rejected wheel_states: stamp 0\.000000 s is before the newest accepted", timeout_s=10.0)
    rig.send_state(8 * MS)
    rig.answer(8 * MS)  # the time line goes on
    ros_graph.probe.spin_for(0.3)  # the old plant fell silent (stamps.StampFilter.silence_s) ...
    rig.send_state(1 * MS)  # ... and a new one starts: its first tick is held as a possible restart ...
    rig.send_state(2 * MS)  # ... which its next one confirms
    assert np.all(np.isfinite(rig.answer(2 * MS)))
    rig.node.wait_for_output("time line restarted", timeout_s=10.0)
    rig.node.wait_for_output("time went backwards", timeout_s=10.0)
    assert not any(stamp_ns(m) in (0, 1 * MS) for m in rig.duties)


NODE = "/robot_0/motor_boards"


@pytest.fixture(scope="module")
def unchanged_rig(module_ros_graph):
    """One node for the refused changes (a refusal leaves it as it was), with the next tick to send."""
    rig = Rig(module_ros_graph)
    rig.next_tick = itertools.count(1)
    return rig


@pytest.mark.parametrize(
    ("name", "value"),
    [("speed_kp_a_per_radps", 0.0), ("current_ki_per_s", -5.0), ("robot.continuous_current_limit_a", 0.0),
     ("robot.motor_resistance_ohm", -0.94), ("peak_current_a", math.inf), ("actuator_mode", "magic"),
     ("loop_rate_hz", 0.0)],
)
def test_bad_parameters_rejected_old_value_kept(unchanged_rig, name, value):
    rig, probe = unchanged_rig, unchanged_rig.graph.probe
    before = probe.get_parameter(NODE, name)
    result = probe.set_parameter(NODE, name, value)
    assert not result.successful and result.reason
    assert probe.get_parameter(NODE, name) == before
    t_ns = next(rig.next_tick) * MS
    rig.send_state(t_ns)
    assert np.all(np.isfinite(rig.answer(t_ns)))


def test_current_limit_parameter_change_is_accepted(ros_graph):
    Rig(ros_graph)
    assert ros_graph.probe.set_parameter(NODE, "robot.continuous_current_limit_a", 1.0).successful
    assert ros_graph.probe.get_parameter(NODE, "robot.continuous_current_limit_a") == 1.0
