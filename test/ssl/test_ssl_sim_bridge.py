"""ssl_sim_bridge over DDS and real UDP, against a stand-in simulator that only speaks the protocols:
cmd_vel drives the simulator's robots, a kick goes out once with the ball at the kicker, ball contact comes back on
ball_detected, scenario topics become teleports, simulator errors reach /sim/events, garbage and floods
do not stop the bridge; and the stack's predictor and catcher receive a ball in the stand-in, which they
see only through its SSL-Vision and drive only through the bridge."""

import math
import socket
import time

import pytest
from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
from sim_standin import SimStandIn, VisionSimStandIn
from std_msgs.msg import Bool, Float64, String

from erforce_interfaces.ssl import ssl_sim
from erforce_interfaces.wire import contract
from erforce_interfaces.wire.conversions import odometry_msg

pytestmark = pytest.mark.integration


def free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def forward(speed: float) -> Twist:
    t = Twist()
    t.linear.x = speed
    return t


def drive_until(graph, pub, twist, condition, timeout_s, what):
    """Publish cmd_vel at 20 Hz (the bridge zeroes a command older than 0.2 s) until ``condition``."""
    deadline = time.monotonic() + timeout_s
    while not condition():
        if time.monotonic() > deadline:
            raise TimeoutError(what)
        pub.publish(twist)
        graph.probe.spin_for(0.05)


@pytest.fixture
def standin():
    sim = SimStandIn()
    yield sim
    sim.close()


def test_bridge_drives_the_simulator_and_maps_its_answers_back(ros_graph, standin):
    node = ros_graph.start_node("erforce_sim", "ssl_sim_bridge", params={
        "team_color": "blue", "robot_ids": [0, 1], "command_port": standin.port, "control_port": standin.control_port,
        "rate_hz": 100.0})
    probe = ros_graph.probe
    contact = probe.subscribe(contract.BALL_DETECTED.for_robot(0), Bool)
    events = probe.subscribe(contract.SIM_EVENTS.name, String)
    cmd = probe.wait_for_subscribers(contract.CMD_VEL.for_robot(0), Twist, timeout_s=20.0)
    kick = probe.wait_for_subscribers(contract.KICK.for_robot(1), Float64, timeout_s=20.0)

    # robot 0 drives forward at 1 m/s in the simulator until it touches the stand-in's ball line
    drive_until(ros_graph, cmd, forward(1.0), lambda: any(m.data for m in contact), 20.0,
                "ball contact from the simulator on /robot_0/ball_detected")
    x0, y0, _ = standin.pose(0)
    assert x0 > 0.5 and abs(y0) < 1e-6
    assert standin.pose(1) == [0.0, 0.0, 0.0]  # robot 1 got zero velocity all along

    # without cmd_vel the bridge sends zero after command_timeout_s: the robot stops
    probe.spin_for(0.4)
    x_stop = standin.pose(0)[0]
    probe.spin_for(0.3)
    assert standin.pose(0)[0] == pytest.approx(x_stop, abs=1e-9)

    # a kick is armed for kick_hold_s and goes out in one command once the simulator reports the ball at the
    # kicker: robot 1 (no contact) never kicks, robot 0 (contact) kicks in exactly one of about 10 commands
    kick.publish(Float64(data=3.0))
    kick0 = probe.wait_for_subscribers(contract.KICK.for_robot(0), Float64, timeout_s=20.0)
    kick0.publish(Float64(data=2.5))
    probe.spin_until(lambda: any(k == (0, 2.5) for k in standin.kicks), 5.0, "robot 0's kick at the simulator")
    probe.spin_for(0.3)
    assert [k for k in standin.kicks if k[0] == 0] == [(0, 2.5)]
    assert not [k for k in standin.kicks if k[0] == 1]

    # scenario commands become teleports at the simulator's control port
    set_ball = probe.wait_for_subscribers(contract.SIM_SET_BALL.name, Odometry, timeout_s=20.0)
    set_ball.publish(odometry_msg(0.0, (1.5, -1.0, 0.0), (2.0, 0.0, 0.0)))
    set_robot = probe.wait_for_subscribers(contract.SIM_SET_STATE.for_robot(1), Odometry, timeout_s=20.0)
    set_robot.publish(odometry_msg(0.0, (-2.0, 0.5, 1.0), (0.0, 0.0, 0.0)))
    probe.spin_until(lambda: len(standin.teleports) >= 2, 10.0, "two teleports at the simulator")
    ball, robot = standin.teleports[0].control.teleport_ball, standin.teleports[1].control.teleport_robot[0]
    assert (ball.x, ball.y, ball.vx, ball.vy) == (1.5, -1.0, 2.0, 0.0)
    assert (robot.id.id, robot.id.team, robot.x, robot.y) == (1, 2, -2.0, 0.5)  # team 2 = BLUE
    assert robot.orientation == pytest.approx(1.0)

    # a simulator error reaches /sim/events with its code and message; a garbage answer is dropped and the
    # bridge goes on
    standin.error_text = "no such robot"
    probe.spin_until(lambda: any("STANDIN: no such robot" in m.data for m in events), 10.0, "the simulator error")
    standin.garbage_next = True
    node.wait_for_output("dropped a simulator answer", timeout_s=10.0)
    sent = standin.packets
    probe.spin_until(lambda: standin.packets > sent + 20, 10.0, "commands after the garbage answer")
    # a flood of 3000 garbage answers: dropped with throttled warnings, commands keep going out
    standin.flood_next = 3000
    probe.spin_until(lambda: standin.flood_next == 0, 10.0, "the flood sent")
    sent = standin.packets
    probe.spin_until(lambda: standin.packets > sent + 50, 20.0, "commands during and after the flood")
    assert node.alive()
    assert node.output().count("dropped a simulator answer") < 20  # throttled, not one line per datagram


def test_bridge_turns_teleports_into_the_simulators_frame_when_we_defend_positive_x(ros_graph, standin):
    """The scenario topics are in the field frame (as vision after ssl_vision_bridge): defending the simulator's
    positive x, the ball at (1, 2) m rolling at (3, 0) m/s is placed at (-1, -2) m rolling at (-3, 0) m/s, and
    our robot 1 at (1, 2) m facing +y at (-1, -2) m facing -y."""
    ros_graph.start_node("erforce_sim", "ssl_sim_bridge", params={
        "team_color": "yellow", "defend_side": "positive_x", "robot_ids": [1], "command_port": standin.port,
        "control_port": standin.control_port})
    probe = ros_graph.probe
    set_ball = probe.wait_for_subscribers(contract.SIM_SET_BALL.name, Odometry, timeout_s=20.0)
    set_ball.publish(odometry_msg(0.0, (1.0, 2.0, 0.0), (3.0, 0.0, 0.0)))
    probe.spin_until(lambda: len(standin.teleports) >= 1, 10.0, "the ball's teleport at the simulator")
    set_robot = probe.wait_for_subscribers(contract.SIM_SET_STATE.for_robot(1), Odometry, timeout_s=20.0)
    set_robot.publish(odometry_msg(0.0, (1.0, 2.0, math.pi / 2), (0.0, 0.0, 0.0)))
    probe.spin_until(lambda: len(standin.teleports) >= 2, 10.0, "the robot's teleport at the simulator")
    ball, robot = standin.teleports[0].control.teleport_ball, standin.teleports[1].control.teleport_robot[0]
    assert (ball.x, ball.y, ball.vx, ball.vy) == (-1.0, -2.0, -3.0, 0.0)
    assert (robot.id.id, robot.id.team, robot.x, robot.y) == (1, 1, -1.0, -2.0)  # team 1 = YELLOW
    assert robot.orientation == pytest.approx(-math.pi / 2, abs=1e-6)


def test_bridge_speaks_grsim(ros_graph):
    status_port = free_udp_port()
    sim = SimStandIn(protocol="grsim", status_port=status_port)
    try:
        ros_graph.start_node("erforce_sim", "ssl_sim_bridge", params={
            "team_color": "yellow", "robot_ids": [3], "protocol": "grsim", "command_port": sim.port,
            "grsim_status_port": status_port})
        probe = ros_graph.probe
        contact = probe.subscribe(contract.BALL_DETECTED.for_robot(3), Bool)
        cmd = probe.wait_for_subscribers(contract.CMD_VEL.for_robot(3), Twist, timeout_s=20.0)
        drive_until(ros_graph, cmd, forward(2.0), lambda: any(m.data for m in contact), 20.0,
                    "grSim infrared on /robot_3/ball_detected")
        assert sim.pose(3)[0] > 0.5
    finally:
        sim.close()


def test_bridge_refuses_a_bad_configuration(ros_graph):
    node = ros_graph.start_node("erforce_sim", "ssl_sim_bridge", params={"team_color": "green"})
    assert node.wait_exit(timeout_s=20.0) == 1
    assert "invalid parameter team_color: must be one of blue, yellow" in node.output()


def test_bridge_commands_send_a_kick_at_the_kick_angle_in_force_and_no_angle_without_a_kick():
    state = ssl_sim.BridgeCommands([1], kick_hold_s=0.1)
    state.set_kick_angle(1, 45.0)
    state.kick(1, 10.0, 4.0)
    (now,) = state.commands(10.05)
    assert (now.kick_speed_mps, now.kick_angle_deg) == (4.0, 45.0)
    (later,) = state.commands(10.2)
    assert (later.kick_speed_mps, later.kick_angle_deg) == (0.0, 0.0)
    state.set_kick_angle(1, 0.0)
    state.kick(1, 11.0, 3.0)
    assert state.commands(11.0)[0].kick_angle_deg == 0.0
    with pytest.raises(ValueError, match="kick_angle"):
        state.set_kick_angle(1, 95.0)


def test_bridge_commands_zero_a_stale_velocity_and_hold_a_kick():
    state = ssl_sim.BridgeCommands([2, 0], command_timeout_s=0.2, kick_hold_s=0.1)
    state.set_velocity(0, 10.0, 1.0, -0.5, 0.25)
    state.kick(2, 10.0, 4.0)
    now = state.commands(10.1)
    assert [(c.robot_id, c.forward_mps, c.kick_speed_mps) for c in now] == [(0, 1.0, 0.0), (2, 0.0, 4.0)]
    later = state.commands(10.25)
    assert [(c.forward_mps, c.kick_speed_mps) for c in later] == [(0.0, 0.0), (0.0, 0.0)]
    with pytest.raises(ValueError, match="not finite"):
        state.set_velocity(0, 11.0, float("nan"), 0.0, 0.0)


def test_bridge_commands_send_a_kick_once_when_the_simulator_reports_the_ball_at_the_kicker():
    # grSim applies each command's kick while the ball still touches the kicker, damping it each time
    state = ssl_sim.BridgeCommands([0, 1], kick_hold_s=0.1)
    state.ball_contact(0, True)
    state.ball_contact(1, False)
    state.kick(0, 10.0, 4.0)
    state.kick(1, 10.0, 3.0)
    kicks = [[c.kick_speed_mps for c in state.commands(10.0 + k * 0.01)] for k in range(5)]
    assert kicks == [[4.0, 0.0], [0.0, 0.0], [0.0, 0.0], [0.0, 0.0], [0.0, 0.0]]
    state.ball_contact(1, True)  # the ball reaches robot 1 while its kick is armed: it goes out once
    assert [c.kick_speed_mps for c in state.commands(10.06)] == [0.0, 3.0]
    assert [c.kick_speed_mps for c in state.commands(10.07)] == [0.0, 0.0]
    state.kick(1, 11.0, 3.0)
    state.ball_contact(1, False)  # ... and not at all when the ball never comes within kick_hold_s
    assert all(c.kick_speed_mps == 0.0 for t in (11.0, 11.05, 11.2) for c in state.commands(t))


def test_the_stacks_catcher_receives_a_ball_in_an_external_simulator(ros_graph):
    """The whole loop through the protocols only: the stand-in's SSL-Vision -> ssl_vision_bridge ->
    ball_predictor -> catcher -> cmd_vel -> ssl_sim_bridge -> RobotControl -> the stand-in's robot, which
    drives into the rolling ball's path; its ball contact comes back on ball_detected."""
    vision_port = free_udp_port()
    sim = VisionSimStandIn(vision_port)
    try:
        ros_graph.start_node("erforce_ball_model", "ssl_vision_bridge", params={
            "interface": "127.0.0.1", "port": vision_port, "num_robots": 1, "field": "division_b"})
        ros_graph.start_node("erforce_ball_model", "ball_predictor", params={"num_robots": 1})
        ros_graph.start_node("erforce_ball_model", "catcher", namespace="robot_0")
        ros_graph.start_node("erforce_sim", "ssl_sim_bridge", params={
            "team_color": "blue", "robot_ids": [0], "command_port": sim.port, "control_port": 0})
        probe = ros_graph.probe
        odom = probe.subscribe(contract.ODOM.for_robot(0), Odometry, contract.ODOM.qos)
        contact = probe.subscribe(contract.BALL_DETECTED.for_robot(0), Bool)
        probe.spin_until(lambda: odom and sim.packets > 50, 60.0, "robot_0 tracked from the simulator's vision")
        assert not any(m.data for m in contact)
        sim.kick(2.5, 0.6, -1.6, 0.0)  # rolls along y = 0.6, past robot_0 at the origin
        probe.spin_until(lambda: any(m.data for m in contact), 30.0, "robot_0 receiving the ball")
        _, y, _ = sim.pose(0)
        assert y > 0.3  # it drove into the ball's line
        assert sim.caught_at is not None and sim.caught_at[0] > 0.0  # before the ball passed it
    finally:
        sim.close()
