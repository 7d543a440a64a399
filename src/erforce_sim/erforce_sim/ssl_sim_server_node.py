"""ssl_sim_server: our plant speaks the ssl-simulation-protocol, as ER-Force's simulator does, so a
team's existing AI can drive it (and its motor-board emulation) unchanged.

It listens on the robot control port of ``team`` (10301 blue, 10302 yellow) and on the simulator
control port (10300), on ``bind_address`` (loopback by default); with ``opponent_ids`` also on the other
colour's robot control port, for the plant's second team (``opponent_<id>``), so one server takes both
teams' commands as ER-Force's simulator and grSim do. How commands enter the stack:

- A local velocity becomes ``robot_<id>/cmd_vel``: the robot's velocity controller (the firmware loop)
  turns it into wheel setpoints, the motor boards into duty, the plant into motion, exactly as for
  this stack's own AI. A global velocity is first rotated into the robot frame with the robot's true
  heading (``ground_truth/odom``), as a simulator knows it. Wheel velocities are refused with an error.
- A kick speed becomes ``robot_<id>/kick`` while it is set (the plant keeps each kick armed for 0.1 s; it
  is repeated every ``kick_repeat_s``), its ``kick_angle`` ``robot_<id>/kick_angle`` first whenever it
  changes: 0 a flat kick, in (0, 90) deg a chip, which the plant flies (``World.kick``'s ``angle_deg``:
  the speed is the ball's, in 3D, as the protocol's ``kick_speed``). An angle outside [0, 90) or a speed
  not finite, negative or beyond the kicker's is refused with an error and does not kick; a velocity or
  dribbler speed not finite or out of range refuses that robot's move or dribbler alone
  (ssl_sim.plan_robot_control): the other robots of the packet act.
- The dribbler speed becomes ``robot_<id>/dribbler`` (rad/s) when it changes and every second.
- Each RobotControl is answered with a RobotControlResponse: every served robot's dribbler ball
  contact (the plant's light barrier, ``ball_detected``) and the errors of that packet.
- SimulatorCommand: ball teleports go to ``/sim/set_ball``, robot teleports to ``robot_<id>/sim/set_state``
  (unset fields keep the robot's true pose); ``simulation_speed`` (use the plant's ``real_time_factor``),
  configuration, ``present``, ``by_force`` and a ball height are refused with an error.

Run it beside the plant and the robots' velocity_controller and motor_boards (the demo graph without the
catcher). A datagram that does not decode is answered with an ``ERFORCE_INVALID`` error and a throttled
warning. The sockets are read on two threads that publish directly.
"""

from __future__ import annotations

import math
import socket
import threading
import time
from dataclasses import dataclass, field
from typing import Any

from nav_msgs.msg import Odometry
from std_msgs.msg import Float64

from erforce_interfaces.runtime.node_support import (
    SchemaNode,
    check_stamp,
    contract_publisher,
    contract_subscription,
    run_node,
)
from erforce_interfaces.runtime.param_schema import load_schema
from erforce_interfaces.ssl import ssl_sim
from erforce_interfaces.wire import contract
from erforce_interfaces.wire.conversions import (
    ConversionError,
    odometry_from_msg,
    odometry_msg,
    stamp_to_nanoseconds,
    twist_msg,
)
from erforce_interfaces.wire.stamps import StampFilter, StampVerdict

SCHEMA = load_schema("erforce_sim", "ssl_sim_server")
DRIBBLER_REPEAT_S = 1.0  # each robot's dribbler speed goes out on change and this often (a restarted plant learns it)


def _check(c):
    """Refuses robot ids the protocol cannot carry (the schema checked the rest); every parameter is read-only."""
    ssl_sim.BridgeCommands(c.robot_ids)
    if c.opponent_ids:
        ssl_sim.BridgeCommands(c.opponent_ids)
    return c


@dataclass
class _Side:
    """The robots of one colour this server drives: their topics, true poses, light barriers and last commands."""

    color: str
    team: contract.Team  # whose topics: ours (robot_<id>) or the opponents' (opponent_<id>)
    ids: tuple[int, ...]
    pubs: dict[int, dict[str, Any]] = field(default_factory=dict)
    pose: dict[int, tuple[float, float, float]] = field(default_factory=dict)
    stamps: dict[int, StampFilter] = field(default_factory=dict)  # the time rule: a stale pose is not the newest
    contact: dict[int, bool] = field(default_factory=dict)
    last_kick: dict[int, float] = field(default_factory=dict)
    kick_angle: dict[int, float] = field(default_factory=dict)  # the kick_angle last published per robot [deg]
    dribbler: dict[int, tuple[float, float]] = field(default_factory=dict)  # robot -> (rad/s sent, when)

    def yaw(self, robot: int) -> float | None:
        pose = self.pose.get(robot)
        return None if pose is None else pose[2]


class SslSimServerNode(SchemaNode):
    def __init__(self) -> None:
        super().__init__("ssl_sim_server", SCHEMA, _check)
        v = self._values
        self._team = v["team"]
        other = ssl_sim.TEAMS[1 - ssl_sim.TEAMS.index(self._team)]
        self._sides = {self._team: _Side(self._team, contract.OURS, tuple(sorted(set(v["robot_ids"]))))}
        if v["opponent_ids"]:
            self._sides[other] = _Side(other, contract.OPPONENTS, tuple(sorted(set(v["opponent_ids"]))))
        self._ids = self._sides[self._team].ids
        for side in self._sides.values():
            self._serve_topics(side)
        self._set_ball_pub = contract_publisher(self, contract.SIM_SET_BALL)
        ports = {self._team: v["robot_control_port"] or ssl_sim.ROBOT_CONTROL_PORTS[self._team],
                 other: v["opponent_robot_control_port"] or ssl_sim.ROBOT_CONTROL_PORTS[other]}
        listen = [(ports[c], lambda data, side=side: self._robot_control(side, data))
                  for c, side in self._sides.items()] + [(v["control_port"], self._simulator_control)]
        self._stop = threading.Event()
        self._socks = []
        threads = []
        for port, handler in listen:
            sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            try:
                sock.bind((v["bind_address"], port))
            except OSError as exc:
                sock.close()
                for s in self._socks:
                    s.close()
                raise ValueError(f"cannot listen on {v['bind_address']}:{port}: {exc}") from None
            sock.settimeout(0.2)  # the threads look at the stop flag this often
            self._socks.append(sock)
            robot_control = handler is not self._simulator_control
            threads.append(threading.Thread(target=self._serve, args=(sock, handler, robot_control), daemon=True))
        self.ports = [s.getsockname()[1] for s in self._socks]
        for t in threads:
            t.start()
        self._threads = threads
        sides = zip(self._sides.values(), self.ports[:-1], strict=True)
        served = "; ".join(f"{side.color} robots {list(side.ids)} ({side.team.prefix}<id>) on robot control "
                           f"{v['bind_address']}:{port}" for side, port in sides)
        self.get_logger().info(f"ssl_sim_server: {served}; simulator control on {v['bind_address']}:{self.ports[-1]}")

    def _serve_topics(self, side: _Side) -> None:
        q, team = contract, side.team
        for i in side.ids:
            side.pubs[i] = {
                "cmd_vel": contract_publisher(self, q.CMD_VEL, team.topic(q.CMD_VEL, i)),
                "kick": contract_publisher(self, q.KICK, team.topic(q.KICK, i)),
                "kick_angle": contract_publisher(self, q.KICK_ANGLE, team.topic(q.KICK_ANGLE, i)),
                "dribbler": contract_publisher(self, q.DRIBBLER, team.topic(q.DRIBBLER, i)),
                "set_state": contract_publisher(self, q.SIM_SET_STATE, team.topic(q.SIM_SET_STATE, i)),
            }
            side.stamps[i] = StampFilter()
            side.contact[i] = False
            side.last_kick[i] = -math.inf
            contract_subscription(self, q.GROUND_TRUTH_ODOM, lambda m, i=i: self._on_odom(side, i, m),
                                  team.topic(q.GROUND_TRUTH_ODOM, i))
            contract_subscription(self, q.BALL_DETECTED, lambda m, i=i: side.contact.__setitem__(i, bool(m.data)),
                                  team.topic(q.BALL_DETECTED, i))

    # ---------------------------------------------------------------- the plant's state
    def _on_odom(self, side: _Side, robot: int, msg: Odometry) -> None:
        name = side.team.topic(contract.GROUND_TRUTH_ODOM, robot)
        try:
            _, pose, _, _ = odometry_from_msg(msg)
        except ConversionError as exc:
            self._warn.warn(f"odom{name}", f"rejected {name}: {exc}")
            return
        verdict = check_stamp(side.stamps[robot], stamp_to_nanoseconds(msg.header.stamp), self._warn, name, self)
        if verdict is StampVerdict.DROP:
            return
        side.pose[robot] = (float(pose[0]), float(pose[1]), float(pose[2]))

    # ---------------------------------------------------------------- the sockets
    def _serve(self, sock: socket.socket, handler, robot_control: bool) -> None:
        while not self._stop.is_set():
            try:
                data, addr = sock.recvfrom(ssl_sim.MAX_DATAGRAM_BYTES + 1)
            except TimeoutError:
                continue
            except OSError:
                return  # closed at shutdown
            try:
                reply = handler(data)
            except ssl_sim.WireError as exc:
                self._warn.warn(f"garbage{sock.getsockname()[1]}", f"refused a datagram from {addr[0]}: {exc}")
                error = [ssl_sim.SimError(ssl_sim.ERROR_INVALID, str(exc))]
                reply = (ssl_sim.encode_robot_control_response({}, error) if robot_control
                         else ssl_sim.encode_simulator_response(error))
            except Exception:
                if not self.context.ok():
                    return  # shutting down: a command that arrived meanwhile has nowhere to go
                raise
            try:
                sock.sendto(reply, addr)
            except OSError as exc:
                self._warn.warn("reply", f"cannot answer {addr[0]}:{addr[1]}: {exc}")

    def _robot_control(self, side: _Side, data: bytes) -> bytes:
        requests = ssl_sim.decode_robot_control(data)
        actions, errors = ssl_sim.plan_robot_control(requests, side.ids, side.yaw, dribbler=True)
        now = time.monotonic()
        for a in actions:
            pubs = side.pubs[a.robot_id]
            if a.twist is not None:
                pubs["cmd_vel"].publish(twist_msg(a.twist))
            if a.kick_speed_mps > 0.0 and now - side.last_kick[a.robot_id] >= self._values["kick_repeat_s"]:
                side.last_kick[a.robot_id] = now
                if side.kick_angle.get(a.robot_id, 0.0) != a.kick_angle_deg:  # before the kick it is for
                    side.kick_angle[a.robot_id] = a.kick_angle_deg
                    pubs["kick_angle"].publish(Float64(data=a.kick_angle_deg))
                pubs["kick"].publish(Float64(data=a.kick_speed_mps))
            sent = side.dribbler.get(a.robot_id)
            if sent is None or sent[0] != a.dribbler_radps or now - sent[1] >= DRIBBLER_REPEAT_S:
                side.dribbler[a.robot_id] = (a.dribbler_radps, now)
                pubs["dribbler"].publish(Float64(data=a.dribbler_radps))
        if errors:
            self._warn.warn(f"robot_errors_{side.color}",
                            f"robot control ({side.color}): " + "; ".join(e.message for e in errors))
        return ssl_sim.encode_robot_control_response(dict(side.contact), errors)

    def _simulator_control(self, data: bytes) -> bytes:
        request = ssl_sim.decode_simulator_command(data)
        errors = []
        unsupported = ssl_sim.ERROR_UNSUPPORTED
        if request.ball is not None:
            x, y, vx, vy = request.ball
            self._set_ball_pub.publish(odometry_msg(0.0, (x, y, 0.0), (vx, vy, 0.0)))
        if request.ball_unsupported:
            errors.append(ssl_sim.SimError(unsupported, "teleport_ball: not simulated: "
                                           + ", ".join(request.ball_unsupported)))
        for r in request.robots:
            side = self._sides.get(r.team)
            if side is None or r.robot_id not in side.pubs:
                errors.append(ssl_sim.SimError(ssl_sim.ERROR_UNKNOWN_ROBOT,
                                               f"teleport_robot: {r.team} {r.robot_id} is not simulated here"))
                continue
            if r.present is False or r.by_force:
                errors.append(ssl_sim.SimError(unsupported, "teleport_robot: present=false and by_force are not "
                                                            "supported"))
                continue
            now = side.pose.get(r.robot_id)
            if now is None and None in (r.x_m, r.y_m, r.yaw_rad):
                errors.append(ssl_sim.SimError(ssl_sim.ERROR_INVALID,
                                               f"teleport_robot {r.robot_id}: no pose yet, set x, y and orientation"))
                continue
            pose = tuple(given if given is not None else current
                         for given, current in zip((r.x_m, r.y_m, r.yaw_rad), now or (0.0, 0.0, 0.0), strict=True))
            side.pubs[r.robot_id]["set_state"].publish(odometry_msg(0.0, pose, r.velocity))
        if request.simulation_speed is not None:
            errors.append(ssl_sim.SimError(unsupported, "simulation_speed: set the plant's real_time_factor"))
        if request.has_config:
            errors.append(ssl_sim.SimError(unsupported, "simulator configuration is not supported"))
        if errors:
            self._warn.warn("sim_errors", "simulator control: " + "; ".join(e.message for e in errors))
        return ssl_sim.encode_simulator_response(errors)

    def destroy_node(self) -> None:
        self._stop.set()
        for s in self._socks:
            s.close()
        for t in self._threads:
            t.join(timeout=1.0)
        super().destroy_node()


def main(args: list[str] | None = None) -> int:
    return run_node(SslSimServerNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
