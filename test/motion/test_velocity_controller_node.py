"""velocity_controller over DDS: answers every tick, follows cmd_vel, rejects bad input, validates parameters."""

import math

import numpy as np
import pytest
from geometry_msgs.msg import Twist
from sensor_msgs.msg import JointState

from erforce_interfaces.tools.messages import joint_state_msg
from erforce_interfaces.wire import contract
from erforce_interfaces.wire.robot_config import RobotConfig
from erforce_motion.kinematics import OmniKinematics

pytestmark = pytest.mark.integration

ROBOT = RobotConfig()
NAMES = ROBOT.wheel_names
MS = 1_000_000


class Rig:
    """Plays the plant for one velocity_controller in namespace robot_0."""

    def __init__(self, graph, **params):
        self.graph = graph
        self.node = graph.start_node("erforce_motion", "velocity_controller", namespace="robot_0", params=params)
        probe = graph.probe
        self.setpoints = probe.subscribe("/robot_0/wheel_setpoints", JointState, contract.QOS_CONTROL)
        self.states = probe.wait_for_subscribers("/robot_0/wheel_states", JointState, timeout_s=20.0,
                                                 qos=contract.QOS_CONTROL)
        self.cmd = probe.wait_for_subscribers("/robot_0/cmd_vel", Twist, timeout_s=20.0, qos=contract.QOS_COMMAND)
        probe.spin_until(lambda: self.states.get_subscription_count() > 0 and
                         self.graph.probe.node.count_publishers("/robot_0/wheel_setpoints") > 0,
                         20.0, "velocity_controller endpoints")
        self.t_ns = 0

    def tick(self, wheel_speeds=None):
        """Publish one sensor tick and wait for its answer."""
        self.t_ns += MS
        speeds = np.zeros(4) if wheel_speeds is None else wheel_speeds
        self.states.publish(joint_state_msg(self.t_ns, NAMES, velocity=speeds, effort=np.zeros(4)))
        t = self.t_ns
        self.graph.probe.spin_until(
            lambda: any(m.header.stamp.sec * 10**9 + m.header.stamp.nanosec == t for m in self.setpoints),
            5.0, f"answer to tick {t}")
        return np.array(self.setpoints[-1].velocity)

    def command(self, twist: Twist, max_ticks: int = 2000) -> np.ndarray:
        """Send cmd_vel and tick, feeding the setpoints back as the measured speeds, until the output moves:
        the node takes the command when it arrives, which may be some ticks later (DDS orders no two topics).
        Returns the first moving output, one tick into the command."""
        self.cmd.publish(twist)
        speeds = np.zeros(4)
        for _ in range(max_ticks):
            speeds = self.tick(speeds)
            if np.any(speeds != 0.0):
                return speeds
        raise AssertionError(f"no response to cmd_vel within {max_ticks} ticks")


def test_answers_each_tick_and_accelerates_toward_cmd_vel(ros_graph):
    # 4 m/s^2: below the shaper's traction limit along +x (0.9 * 5.66 m/s^2 for the default robot)
    rig = Rig(ros_graph, max_accel_mps2=4.0)
    rig.tick()
    msg = Twist()
    msg.linear.x = 1.0
    # Wheels "follow" perfectly: feed back the setpoint as the measured speed, so the
    # shaped ramp is what comes out: 4 m/s^2 * 1 ms per tick.
    speeds = rig.command(msg)
    for _ in range(49):
        speeds = rig.tick(speeds)
    kin = OmniKinematics.from_robot_config(ROBOT)
    twist = kin.forward(speeds)
    assert twist[0] == pytest.approx(50 * 0.004, rel=0.05)
    assert abs(twist[1]) < 1e-3 and abs(twist[2]) < 1e-3


@pytest.mark.parametrize("bad", [math.nan, math.inf, 1e6])
def test_bad_twist_is_rejected_robot_stops_node_survives(ros_graph, bad):
    rig = Rig(ros_graph)
    rig.tick()
    good = Twist()
    good.linear.x = 1.0
    speeds = rig.command(good)
    for _ in range(30):
        speeds = rig.tick(speeds)
    moving = OmniKinematics.from_robot_config(ROBOT).forward(speeds)[0]
    assert moving > 0.1
    bad_msg = Twist()
    bad_msg.linear.x = bad
    rig.cmd.publish(bad_msg)
    for _ in range(2000):  # cmd_vel is taken with the next tick after it arrived
        speeds = rig.tick(speeds)
        if "rejected cmd_vel" in rig.node.output():
            break
    rig.node.wait_for_output("rejected cmd_vel", timeout_s=1.0)
    for _ in range(30):
        speeds = rig.tick(speeds)
        assert np.all(np.isfinite(speeds))
    assert OmniKinematics.from_robot_config(ROBOT).forward(speeds)[0] < moving  # decelerating, not NaN
    assert rig.node.alive()


def test_wrong_length_wheel_states_rejected_with_a_message(ros_graph):
    rig = Rig(ros_graph)
    rig.states.publish(JointState(velocity=[1.0, 2.0], effort=[0.0, 0.0]))
    rig.node.wait_for_output("rejected wheel_states.*2 entries, expected 4", timeout_s=10.0)
    assert np.all(np.isfinite(rig.tick()))  # and it keeps answering


def test_command_timeout_stops_the_robot(ros_graph):
    rig = Rig(ros_graph, command_timeout_s=0.02, max_accel_mps2=50.0)
    rig.tick()
    msg = Twist()
    # 0.05 m/s sideways: reached in 12 ms at the shaper's traction limit (0.9 * 4.74 m/s^2 along y)
    msg.linear.y = 0.05
    speeds = rig.command(msg)
    for _ in range(14):  # 15 ms < timeout: moving
        speeds = rig.tick(speeds)
    kin = OmniKinematics.from_robot_config(ROBOT)
    assert kin.forward(speeds)[1] == pytest.approx(0.05, rel=0.05)
    for _ in range(40):  # past the 20 ms timeout: brakes to rest within ~12 ms
        speeds = rig.tick(speeds)
    assert np.allclose(kin.forward(speeds), 0.0, atol=1e-3)


NODE = "/robot_0/velocity_controller"


@pytest.fixture(scope="module")
def unchanged_rig(module_ros_graph):
    """One node for the refused changes (a refusal leaves it as it was)."""
    return Rig(module_ros_graph)


@pytest.mark.parametrize(
    ("name", "value"),
    [
        ("kp_translation", -1.0),
        ("kp_translation", 0.0),
        ("max_accel_mps2", math.nan),
        ("robot.wheel_radius_m", 0.0),
        ("robot.wheel_angles_rad", [0.0, 1.0]),
        ("anti_windup", "none"),
    ],
)
def test_bad_parameters_rejected_old_value_kept(unchanged_rig, name, value):
    rig, probe = unchanged_rig, unchanged_rig.graph.probe
    before = probe.get_parameter(NODE, name)
    result = probe.set_parameter(NODE, name, value)
    assert not result.successful and result.reason
    assert probe.get_parameter(NODE, name) == before
    assert np.all(np.isfinite(rig.tick()))


def test_good_parameter_change_is_accepted(ros_graph):
    rig = Rig(ros_graph)
    assert ros_graph.probe.set_parameter(NODE, "kp_translation", 2.0).successful
    assert ros_graph.probe.get_parameter(NODE, "kp_translation") == 2.0
    assert np.all(np.isfinite(rig.tick()))
