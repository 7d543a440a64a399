"""ssl_sim_server: the plant driven over UDP with the ssl-simulation-protocol, as a team's AI would drive
ER-Force's simulator. Local and global velocities move the simulated robot through its velocity
controller and motor boards; teleports place ball and robot; unsupported features and garbage are
answered with errors."""

import math
import socket
import time
from pathlib import Path

import pytest
from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
from std_msgs.msg import String

from erforce_interfaces.ssl import ssl_sim
from erforce_interfaces.ssl.ssl_proto import (
    ssl_simulation_control_pb2,
    ssl_simulation_robot_control_pb2,
    ssl_simulation_robot_feedback_pb2,
)
from erforce_interfaces.wire import contract
from erforce_interfaces.wire.conversions import odometry_msg
from erforce_interfaces.wire.robot_config import RobotConfig

pytestmark = pytest.mark.integration

LAUNCH = Path(__file__).resolve().parents[2] / "src/erforce_sim/launch/sim_one_robot.launch.yaml"


def free_udp_ports(n: int) -> list[int]:
    socks = [socket.socket(socket.AF_INET, socket.SOCK_DGRAM) for _ in range(n)]
    for s in socks:
        s.bind(("127.0.0.1", 0))
    ports = [s.getsockname()[1] for s in socks]
    for s in socks:
        s.close()
    return ports


class Client:
    """A team's AI, speaking only the protocol."""

    def __init__(self, robot_port: int, control_port: int) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.settimeout(0.05)
        self.robot_addr = ("127.0.0.1", robot_port)
        self.control_addr = ("127.0.0.1", control_port)

    def answers(self) -> list[bytes]:
        out = []
        while True:
            try:
                out.append(self.sock.recv(65536))
            except TimeoutError:
                return out

    def local(self, robot_id: int, forward: float) -> bytes:
        msg = ssl_simulation_robot_control_pb2.RobotControl()
        v = msg.robot_commands.add(id=robot_id).move_command.local_velocity
        v.forward, v.left, v.angular = forward, 0.0, 0.0
        return msg.SerializeToString()

    def ask(self, data: bytes, addr, timeout_s: float = 5.0) -> bytes:
        deadline = time.monotonic() + timeout_s
        self.answers()  # drop older answers
        self.sock.sendto(data, addr)
        while time.monotonic() < deadline:
            try:
                return self.sock.recv(65536)
            except TimeoutError:
                continue
        raise TimeoutError("no answer from ssl_sim_server")


def drive(graph, client, data, condition, timeout_s, what):
    deadline = time.monotonic() + timeout_s
    while not condition():
        if time.monotonic() > deadline:
            raise TimeoutError(what)
        client.sock.sendto(data, client.robot_addr)
        graph.probe.spin_for(0.05)


def at_rest_for(truth: list[Odometry], duration_s: float, near_x: float | None = None) -> bool:
    """The newest ground-truth messages cover ``duration_s`` of simulated time with the robot still
    (and, with ``near_x``, within 5 cm of that x) throughout."""
    if not truth:
        return False
    t_end = stamp_s(truth[-1])
    for m in reversed(truth):
        still = math.hypot(m.twist.twist.linear.x, m.twist.twist.linear.y) < 0.02
        if not still or (near_x is not None and abs(m.pose.pose.position.x - near_x) >= 0.05):
            return False
        if t_end - stamp_s(m) >= duration_s:
            return True
    return False


def stamp_s(msg: Odometry) -> float:
    return msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec


def test_a_protocol_client_drives_and_places_our_plant(ros_graph):
    robot_port, control_port = free_udp_ports(2)
    ros_graph.start_launch(LAUNCH)
    server = ros_graph.start_node("erforce_sim", "ssl_sim_server", params={
        "team": "yellow", "robot_ids": [0], "robot_control_port": robot_port, "control_port": control_port})
    server.wait_for_output("ssl_sim_server: yellow robots", timeout_s=20.0)
    probe = ros_graph.probe
    truth = probe.subscribe(contract.GROUND_TRUTH_ODOM.for_robot(0), Odometry)
    ball = probe.subscribe(contract.GROUND_TRUTH_BALL.name, Odometry)
    client = Client(robot_port, control_port)
    probe.spin_until(lambda: truth, 30.0, "the plant's ground truth")

    # local velocity -> cmd_vel -> velocity controller -> motor boards -> plant: the robot drives forward
    drive(ros_graph, client, client.local(0, 1.0), lambda: truth[-1].pose.pose.position.x > 0.3, 30.0,
          "robot_0 driving forward")
    assert abs(truth[-1].pose.pose.position.y) < 0.05
    fb = ssl_simulation_robot_feedback_pb2.RobotControlResponse.FromString(
        client.ask(client.local(0, 0.0), client.robot_addr))
    assert [f.id for f in fb.feedback] == [0] and fb.feedback[0].HasField("dribbler_ball_contact")
    assert not fb.errors

    # Stop first: a teleport zeroes the robot's speed but not its controller's setpoint ramp, which would
    # drive it on along its new heading.
    drive(ros_graph, client, client.local(0, 0.0), lambda: at_rest_for(truth, 0.3), 30.0, "robot_0 stopping")

    # teleport the robot to face +y, then a global velocity along +x moves it sideways in its own frame
    reply = client.ask(ssl_sim.encode_teleport(None, [("yellow", 0, -1.0, 0.0, math.pi / 2)]), client.control_addr)
    assert ssl_sim.decode_simulator_response(reply) == ()
    probe.spin_until(lambda: at_rest_for(truth, 0.3, near_x=-1.0), 20.0, "the robot teleported and at rest")
    x0, y0 = truth[-1].pose.pose.position.x, truth[-1].pose.pose.position.y
    glob = ssl_simulation_robot_control_pb2.RobotControl()
    g = glob.robot_commands.add(id=0).move_command.global_velocity
    g.x, g.y, g.angular = 1.0, 0.0, 0.0
    drive(ros_graph, client, glob.SerializeToString(), lambda: truth[-1].pose.pose.position.x > x0 + 0.3, 30.0,
          "robot_0 driving along field x")
    assert abs(truth[-1].pose.pose.position.y - y0) < 0.05

    # the ball teleport reaches the plant
    assert ssl_sim.decode_simulator_response(
        client.ask(ssl_sim.encode_teleport((2.0, -1.0, 0.0, 0.0)), client.control_addr)) == ()
    probe.spin_until(lambda: ball and abs(ball[-1].pose.pose.position.x - 2.0) < 1e-3
                     and abs(ball[-1].pose.pose.position.y + 1.0) < 1e-3, 10.0, "the ball teleport")

    # a chip: kick_speed 3 m/s at kick_angle 45 deg from robot_0 at rest at the origin facing +x, the ball at its
    # dribbler; the plant flies it: along the carpet at 3 cos 45 = 2.12 m/s (a flat kick would roll at 3 m/s)
    events = probe.subscribe(contract.SIM_EVENTS.name, String)
    drive(ros_graph, client, client.local(0, 0.0), lambda: at_rest_for(truth, 0.3), 30.0, "robot_0 stopping")
    reach = RobotConfig().dribbler_offset_m + 0.002
    assert ssl_sim.decode_simulator_response(client.ask(ssl_sim.encode_teleport(
        (reach, 0.0, 0.0, 0.0), [("yellow", 0, 0.0, 0.0, 0.0)]), client.control_addr)) == ()
    probe.spin_until(lambda: at_rest_for(truth, 0.3, near_x=0.0) and abs(ball[-1].pose.pose.position.x - reach) < 1e-3,
                     20.0, "robot and ball placed")
    chip = ssl_sim.encode_robot_control([ssl_sim.RobotCommand(0, kick_speed_mps=3.0, kick_angle_deg=45.0)])
    fb = ssl_simulation_robot_feedback_pb2.RobotControlResponse.FromString(client.ask(chip, client.robot_addr))
    assert not fb.errors
    probe.spin_until(lambda: any("chip 45 deg" in e.data and "fired" in e.data for e in events), 10.0,
                     "the plant's chip event")
    # the first flight lasts 2 (3 sin 45) / 9.81 = 0.43 s and ends 0.92 m on: each of its ground-truth samples the
    # probe took (a loaded probe may take its first one past some x only after the touchdown, slower)
    v_carpet_mps, v_up_mps = 3.0 * math.cos(math.radians(45.0)), 3.0 * math.sin(math.radians(45.0))
    touchdown_x = reach + v_carpet_mps * 2.0 * v_up_mps / 9.81
    probe.spin_until(lambda: ball[-1].pose.pose.position.x > touchdown_x, 10.0, "the chipped ball past its touchdown")
    flight = [m for m in ball if m.pose.pose.position.z > 0.0 and m.pose.pose.position.x < touchdown_x - 0.05]
    assert flight, "no ground truth of the ball in its first flight"
    speeds = [math.hypot(m.twist.twist.linear.x, m.twist.twist.linear.y) for m in flight]
    assert speeds == pytest.approx([v_carpet_mps] * len(speeds), abs=0.05)

    # unsupported features and unknown robots get errors; garbage gets ERFORCE_INVALID; the server goes on
    bad = ssl_simulation_robot_control_pb2.RobotControl()
    w = bad.robot_commands.add(id=0).move_command.wheel_velocity
    w.front_right = w.back_right = w.back_left = w.front_left = 1.0
    bad.robot_commands.add(id=7)
    reply = client.ask(bad.SerializeToString(), client.robot_addr)
    # on the wire as the league defines SimulatorError: code = 1 (tag 0x0a), then message = 2 (tag 0x12)
    code = ssl_sim.ERROR_UNSUPPORTED.encode()
    assert b"\x0a" + bytes([len(code)]) + code + b"\x12" in reply
    fb = ssl_simulation_robot_feedback_pb2.RobotControlResponse.FromString(reply)
    codes = sorted(e.code for e in fb.errors)
    assert codes == [ssl_sim.ERROR_UNKNOWN_ROBOT, ssl_sim.ERROR_UNSUPPORTED]
    assert any("wheel velocities" in e.message for e in fb.errors)
    fb = ssl_simulation_robot_feedback_pb2.RobotControlResponse.FromString(client.ask(b"\xff\xfe", client.robot_addr))
    assert [e.code for e in fb.errors] == [ssl_sim.ERROR_INVALID]
    # a flood of garbage: every datagram is answered with an error, and a good command is served after it
    for _ in range(2000):
        client.sock.sendto(b"\xff\xfe flood", client.robot_addr)

    def served() -> bool:
        client.sock.sendto(client.local(0, 0.0), client.robot_addr)
        return any(not r.errors and r.feedback for r in map(
            ssl_simulation_robot_feedback_pb2.RobotControlResponse.FromString, client.answers()))

    probe.spin_until(served, 30.0, "a good command answered after the flood")
    speed = ssl_simulation_control_pb2.SimulatorCommand()
    speed.control.simulation_speed = 2.0
    errors = ssl_sim.decode_simulator_response(client.ask(speed.SerializeToString(), client.control_addr))
    assert len(errors) == 1 and "real_time_factor" in errors[0]
    assert server.alive()


def test_plan_robot_control_rotates_global_velocities_and_reports_each_unsupported_feature_once():
    reqs = [ssl_sim.MoveRequest(0, "global", (1.0, 0.0, 0.5), 0.0, 0.0, 0.0),
            ssl_sim.MoveRequest(1, "wheel", (1.0, 1.0, 1.0, 1.0), 3.0, 30.0, 100.0),
            ssl_sim.MoveRequest(2, "wheel", (1.0, 1.0, 1.0, 1.0), 0.0, 0.0, 0.0),
            ssl_sim.MoveRequest(9, "local", (1.0, 0.0, 0.0), 0.0, 0.0, 0.0)]
    actions, errors = ssl_sim.plan_robot_control(reqs, [0, 1, 2], {0: math.pi / 2, 1: 0.0, 2: 0.0}.get)
    a0 = actions[0]
    assert a0.twist == pytest.approx((0.0, -1.0, 0.5))  # +x in the field is the robot's right when it faces +y
    assert actions[1] == ssl_sim.RobotAction(1, None, 3.0, 0.0, 30.0)  # the chip kicks (its wheels do not move)
    messages = sorted(e.message.split()[0] for e in errors)
    assert messages == ["robot", "this", "wheel"]  # one each: unknown robot 9, dribbler, wheel


def test_plan_robot_control_flies_chips_and_refuses_an_angle_outside_0_to_90_deg():
    reqs = [ssl_sim.MoveRequest(0, "local", (0.0, 0.0, 0.0), 4.0, 45.0, 0.0),
            ssl_sim.MoveRequest(1, "local", (0.0, 0.0, 0.0), 4.0, -10.0, 0.0),
            ssl_sim.MoveRequest(2, "local", (0.0, 0.0, 0.0), 4.0, 90.0, 0.0),
            ssl_sim.MoveRequest(3, "local", (0.0, 0.0, 0.0), 0.0, 60.0, 0.0)]  # no kick: no angle either
    actions, errors = ssl_sim.plan_robot_control(reqs, [0, 1, 2, 3], {}.get, dribbler=True)
    assert [(a.kick_speed_mps, a.kick_angle_deg) for a in actions] == [(4.0, 45.0), (0.0, 0.0), (0.0, 0.0),
                                                                        (0.0, 0.0)]
    assert sorted(e.code for e in errors) == [ssl_sim.ERROR_INVALID] * 2
    assert all("kick_angle" in e.message for e in errors)


def test_plan_robot_control_passes_the_dribbler_speed_on_where_the_simulator_has_one():
    # 600 rpm = 600 * 2 pi / 60 = 20 pi rad/s; without a dribbler motor the speed is refused and nothing spins
    reqs = [ssl_sim.MoveRequest(0, "local", (0.5, 0.0, 0.0), 0.0, 0.0, 600.0),
            ssl_sim.MoveRequest(1, "local", (0.0, 0.0, 0.0), 0.0, 0.0, 0.0)]
    actions, errors = ssl_sim.plan_robot_control(reqs, [0, 1], {}.get, dribbler=True)
    assert [a.dribbler_radps for a in actions] == pytest.approx([20.0 * math.pi, 0.0])
    assert errors == []
    actions, errors = ssl_sim.plan_robot_control(reqs, [0, 1], {}.get)
    assert [a.dribbler_radps for a in actions] == [0.0, 0.0]
    assert [e.message for e in errors] == ["this simulator has no dribbler motor"]


def test_a_stale_pose_does_not_turn_global_velocities(ros_graph):
    """The time rule on ground_truth/odom: a pose stamped before the newest one is dropped, so a global
    velocity is still turned by the newest yaw (facing +x: field +x is the robot's forward)."""
    robot_port, control_port = free_udp_ports(2)
    server = ros_graph.start_node("erforce_sim", "ssl_sim_server", params={
        "robot_ids": [0], "robot_control_port": robot_port, "control_port": control_port})
    server.wait_for_output("ssl_sim_server: blue robots", timeout_s=20.0)
    probe = ros_graph.probe
    cmd = probe.subscribe(contract.CMD_VEL.for_robot(0), Twist, contract.CMD_VEL.qos)
    odom = probe.wait_for_subscribers(contract.GROUND_TRUTH_ODOM.for_robot(0), Odometry, timeout_s=20.0,
                                      qos=contract.GROUND_TRUTH_ODOM.qos)
    odom.publish(odometry_msg(10.0, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)))
    odom.publish(odometry_msg(9.0, (0.0, 0.0, math.pi / 2), (0.0, 0.0, 0.0)))  # from the past
    server.wait_for_output("stamp 9.000000 s is before the newest accepted 10.000000 s", timeout_s=10.0)
    msg = ssl_simulation_robot_control_pb2.RobotControl()
    v = msg.robot_commands.add(id=0).move_command.global_velocity
    v.x, v.y, v.angular = 1.0, 0.0, 0.0
    client = Client(robot_port, control_port)
    drive(ros_graph, client, msg.SerializeToString(), lambda: cmd, 20.0, "cmd_vel from a global velocity")
    assert (cmd[-1].linear.x, cmd[-1].linear.y) == pytest.approx((1.0, 0.0))


def test_a_bad_value_refuses_that_part_of_that_robots_command_alone():
    nan = float("nan")
    reqs = [ssl_sim.MoveRequest(0, "local", (nan, 0.0, 0.0), 4.0, 45.0, 0.0),  # no move; its chip still kicks
            ssl_sim.MoveRequest(1, "global", (1.0, 0.0, 1e6), 0.0, 0.0, 0.0),  # 1e6 rad/s: no move
            ssl_sim.MoveRequest(2, "local", (0.5, 0.0, 0.0), 0.0, 0.0, nan),  # its dribbler off, it moves
            ssl_sim.MoveRequest(3, "local", (0.5, 0.25, 1.0), 0.0, 0.0, 0.0)]
    actions, errors = ssl_sim.plan_robot_control(reqs, [0, 1, 2, 3], {1: 0.0}.get, dribbler=True)
    assert [a.twist for a in actions] == [None, None, (0.5, 0.0, 0.0), (0.5, 0.25, 1.0)]
    assert (actions[0].kick_speed_mps, actions[0].kick_angle_deg) == (4.0, 45.0)
    assert actions[2].dribbler_radps == 0.0
    assert sorted(e.message for e in errors) == [
        "robot 0 local velocity = nan is not finite: no move",
        f"robot 1 global velocity = 1e+06 is outside [-{ssl_sim.MAX_ANGULAR_RADPS:g}, {ssl_sim.MAX_ANGULAR_RADPS:g}]: "
        "no move",
        "robot 2 dribbler_speed = nan is not finite: dribbler off"]
