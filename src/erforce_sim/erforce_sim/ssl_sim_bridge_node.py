"""ssl_sim_bridge: drives an external SSL simulator (ER-Force's, grSim) with this stack's robot commands.

Every ``1 / rate_hz`` of wall time it sends the newest ``cmd_vel`` (a local velocity), ``kick`` (a kick,
armed for ``kick_hold_s`` and sent in one command once the simulator reports the ball at the kicker:
ssl_sim.BridgeCommands; a chip at ``kick_angle`` [deg] when that is above 0: the protocol's kick_speed
and kick_angle, grSim's kickspeedx and kickspeedz) and ``dribbler`` of each robot in ``robot_ids``: with
``protocol: ssl`` a ``RobotControl`` of the ssl-simulation-protocol to the team's port (10301 blue, 10302
yellow), with ``protocol: grsim`` a ``grSim_Packet`` to 20011. With ``team: opponents`` it drives the ``opponent_<id>/``
topics: one bridge per colour, as each team drives its own robots. A cmd_vel older than
``command_timeout_s`` is sent as zero.

The answers go back onto the contract: dribbler ball contact on ``ball_detected``, the simulator's
errors as warnings and on ``/sim/events``; garbage is dropped with a throttled warning. ``/sim/set_ball``
and ``sim/set_state`` become teleports, so scenario scripts place ball and robots as in our plant; like
ssl_vision_bridge, ``team_color`` and ``defend_side`` say how ``field`` maps onto the simulator's frame.
Vision comes back as SSL-Vision packets, for ssl_vision_bridge. Sockets are polled in the send timer, so
feedback is at most one period old.
"""

from __future__ import annotations

import socket
import time

from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
from rclpy.clock import Clock as RclClock
from rclpy.clock import ClockType
from std_msgs.msg import Bool, Float64, String

from erforce_interfaces.runtime.node_support import (
    SchemaNode,
    contract_publisher,
    contract_subscription,
    run_node,
)
from erforce_interfaces.runtime.param_schema import load_schema
from erforce_interfaces.ssl import ssl_sim
from erforce_interfaces.wire import contract
from erforce_interfaces.wire.conversions import ConversionError, float64_from_msg, odometry_from_msg, twist_from_msg

SCHEMA = load_schema("erforce_sim", "ssl_sim_bridge")

_MAX_DATAGRAMS_PER_PERIOD = 256  # a flood cannot starve the send timer
_BARRIER_REPEAT_S = 0.1  # ball_detected goes out on change and at least this often


def _check(c):
    """Refuses ids and a host the bridge cannot use (the schema checked the rest); every parameter is read-only."""
    ssl_sim.BridgeCommands(c.robot_ids)  # refuses bad ids
    try:
        socket.getaddrinfo(c.simulator_host, None, socket.AF_INET, socket.SOCK_DGRAM)
    except OSError as exc:
        raise ValueError(f"simulator_host {c.simulator_host!r}: {exc}") from None
    return c


def local_address_towards(target: tuple[str, int]) -> str:
    """The IPv4 address this host sends from to ``target`` (the kernel's route; nothing is sent)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        try:
            probe.connect(target)
        except OSError as exc:
            raise ValueError(f"simulator_host {target[0]!r}: no route ({exc})") from None
        return probe.getsockname()[0]


class SslSimBridgeNode(SchemaNode):
    def __init__(self) -> None:
        super().__init__("ssl_sim_bridge", SCHEMA, _check)
        v = self._values
        self._team = v["team_color"]
        whose = contract.TEAMS[v["team"]]  # whose topics: ours (robot_<id>) or the opponents' (opponent_<id>)
        self._grsim = v["protocol"] == "grsim"
        self._state = ssl_sim.BridgeCommands(v["robot_ids"], v["command_timeout_s"], v["kick_hold_s"])
        default_port = ssl_sim.GRSIM_COMMAND_PORT if self._grsim else ssl_sim.ROBOT_CONTROL_PORTS[self._team]
        self._target = (v["simulator_host"], v["command_port"] or default_port)
        # Both sockets listen only on the address our datagrams to the simulator leave from (127.0.0.1 for a
        # simulator on this machine): the simulator answers to it, grSim sends its robot status to it.
        local = local_address_towards(self._target)
        self._sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._sock.setblocking(False)
        self._sock.bind((local, 0))  # the simulator answers to this port
        self._status_sock = None
        if self._grsim:
            self._status_sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            self._status_sock.setblocking(False)
            self._status_sock.bind((local, v["grsim_status_port"] or ssl_sim.GRSIM_STATUS_PORTS[self._team]))
        self._events_pub = contract_publisher(self, contract.SIM_EVENTS)
        self._barrier_pubs = {}
        self._barrier_sent: dict[int, tuple[bool, float]] = {}
        q = contract
        for i in self._state.robot_ids:
            self._barrier_pubs[i] = contract_publisher(self, q.BALL_DETECTED, whose.topic(q.BALL_DETECTED, i))
            contract_subscription(self, q.CMD_VEL, lambda m, i=i: self._on_cmd_vel(i, m), whose.topic(q.CMD_VEL, i))
            contract_subscription(self, q.KICK, lambda m, i=i: self._on_kick(i, m), whose.topic(q.KICK, i))
            contract_subscription(self, q.KICK_ANGLE, lambda m, i=i: self._on_kick_angle(i, m),
                                  whose.topic(q.KICK_ANGLE, i))
            contract_subscription(self, q.DRIBBLER, lambda m, i=i: self._on_dribbler(i, m), whose.topic(q.DRIBBLER, i))
        self._control_target = None
        if v["control_port"]:
            self._control_target = self._target if self._grsim else (v["simulator_host"], v["control_port"])
            contract_subscription(self, q.SIM_SET_BALL, self._on_set_ball)
            for i in self._state.robot_ids:
                contract_subscription(self, q.SIM_SET_STATE, lambda m, i=i: self._on_set_robot(i, m),
                                      whose.topic(q.SIM_SET_STATE, i))
        self._last_errors: tuple[str, ...] = ()
        self.sent = 0
        self.create_timer(1.0 / v["rate_hz"], self._tick, clock=RclClock(clock_type=ClockType.STEADY_TIME))
        self.get_logger().info(
            f"ssl_sim_bridge: {self._team} robots {list(self._state.robot_ids)} ({whose.prefix}<id>) defending "
            f"{v['defend_side']} -> {v['protocol']} simulator at {self._target[0]}:{self._target[1]}")
        self._params.on_change(lambda _config: None)  # defend_side: read at each teleport

    # ---------------------------------------------------------------- commands in
    def _on_cmd_vel(self, robot: int, msg: Twist) -> None:
        try:
            fwd, left, ang = twist_from_msg(msg, ssl_sim.MAX_LINEAR_MPS, ssl_sim.MAX_ANGULAR_RADPS)
            self._state.set_velocity(robot, time.monotonic(), fwd, left, ang)
        except (ConversionError, ValueError) as exc:
            self._state.stop(robot)
            self._warn.warn(f"cmd_vel{robot}", f"robot_{robot}: rejected cmd_vel ({exc}); stopping")

    def _on_kick(self, robot: int, msg: Float64) -> None:
        try:
            self._state.kick(robot, time.monotonic(), float64_from_msg(msg, ssl_sim.MAX_KICK_MPS))
        except (ConversionError, ValueError) as exc:
            self._warn.warn(f"kick{robot}", f"robot_{robot}: rejected kick: {exc}")

    def _on_kick_angle(self, robot: int, msg: Float64) -> None:
        try:
            self._state.set_kick_angle(robot, float64_from_msg(msg, ssl_sim.MAX_KICK_ANGLE_DEG))
        except (ConversionError, ValueError) as exc:
            self._warn.warn(f"kick_angle{robot}", f"robot_{robot}: rejected kick_angle: {exc}")

    def _on_dribbler(self, robot: int, msg: Float64) -> None:
        try:
            self._state.set_dribbler(robot, float64_from_msg(msg, ssl_sim.MAX_DRIBBLER_RPM / ssl_sim.RPM_PER_RADPS))
        except (ConversionError, ValueError) as exc:
            self._warn.warn(f"dribbler{robot}", f"robot_{robot}: rejected dribbler: {exc}")

    # ---------------------------------------------------------------- scenario commands -> teleports
    def _teleport(self, ball=None, robots=()) -> None:
        """Ball and robots placed where the ``field`` frame says (the side we defend is read now)."""
        data = ssl_sim.teleport_packet(self._values["protocol"], self._values["defend_side"], ball, robots)
        try:
            self._sock.sendto(data, self._control_target)
        except OSError as exc:
            self._warn.warn("teleport", f"cannot send a teleport to {self._control_target}: {exc}")

    def _on_set_ball(self, msg: Odometry) -> None:
        try:
            _, pose, velocity, _ = odometry_from_msg(msg)
            ball = tuple(ssl_sim.finite_value(n, v, lim) for n, v, lim in (
                ("x", pose[0], ssl_sim.MAX_POSITION_M), ("y", pose[1], ssl_sim.MAX_POSITION_M),
                ("vx", velocity[0], ssl_sim.MAX_LINEAR_MPS), ("vy", velocity[1], ssl_sim.MAX_LINEAR_MPS)))
        except (ConversionError, ssl_sim.WireError) as exc:
            self._warn.warn("set_ball", f"rejected /sim/set_ball: {exc}")
            return
        self._teleport(ball=ball)

    def _on_set_robot(self, robot: int, msg: Odometry) -> None:
        try:
            _, pose, _, _ = odometry_from_msg(msg)
            x, y = (ssl_sim.finite_value(n, v, ssl_sim.MAX_POSITION_M) for n, v in (("x", pose[0]), ("y", pose[1])))
        except (ConversionError, ssl_sim.WireError) as exc:
            self._warn.warn(f"set_state{robot}", f"rejected robot_{robot}/sim/set_state: {exc}")
            return
        self._teleport(robots=[(self._team, robot, x, y, float(pose[2]))])

    # ---------------------------------------------------------------- the simulator
    def _tick(self) -> None:
        now = time.monotonic()
        commands = self._state.commands(now)
        if self._grsim:
            data = ssl_sim.encode_grsim_commands(commands, self._team, timestamp_s=time.time())
        else:
            data = ssl_sim.encode_robot_control(commands)
        try:
            self._sock.sendto(data, self._target)
            self.sent += 1
        except OSError as exc:
            self._warn.warn("send", f"cannot send to the simulator at {self._target[0]}:{self._target[1]}: {exc}")
        if self._status_sock is not None:
            self._drain(self._status_sock, ssl_sim.decode_grsim_robots_status, now)
        else:
            self._drain(self._sock, ssl_sim.decode_robot_control_response, now)

    def _drain(self, sock: socket.socket, decode, now: float) -> None:
        for _ in range(_MAX_DATAGRAMS_PER_PERIOD):
            try:
                data = sock.recv(ssl_sim.MAX_DATAGRAM_BYTES + 1)
            except BlockingIOError:
                return
            except OSError as exc:  # e.g. ICMP port unreachable while no simulator listens
                self._warn.warn("recv", f"no simulator at {self._target[0]}:{self._target[1]} ({exc})")
                return
            try:
                feedback = decode(data)
            except ssl_sim.WireError as exc:
                self._warn.warn("garbage", f"dropped a simulator answer: {exc}")
                continue
            self._apply(feedback, now)

    def _apply(self, feedback: ssl_sim.Feedback, now: float) -> None:
        for robot, contact in feedback.ball_contact.items():
            pub = self._barrier_pubs.get(robot)
            if pub is None:
                continue  # a robot of the simulator this bridge does not drive
            self._state.ball_contact(robot, contact)
            last = self._barrier_sent.get(robot)
            if last is None or last[0] != contact or now - last[1] >= _BARRIER_REPEAT_S:
                self._barrier_sent[robot] = (contact, now)
                pub.publish(Bool(data=contact))
        if feedback.errors and feedback.errors != self._last_errors:
            text = "simulator: " + "; ".join(feedback.errors)
            self._events_pub.publish(String(data=text))
            self._warn.warn("sim_error", text)
        self._last_errors = feedback.errors

    def destroy_node(self) -> None:
        self._sock.close()
        if self._status_sock is not None:
            self._status_sock.close()
        super().destroy_node()


def main(args: list[str] | None = None) -> int:
    return run_node(SslSimBridgeNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
