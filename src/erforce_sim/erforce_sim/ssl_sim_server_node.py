"""ssl_sim_server: our plant speaks the ssl-simulation-protocol, as ER-Force's simulator does, so a
team's existing AI can drive it (and its motor-board emulation) unchanged.

It listens on the robot control port of ``team`` (10301 blue, 10302 yellow) and on the simulator
control port (10300), on ``bind_address`` (loopback by default). How commands enter the stack:

- A local velocity becomes ``robot_<id>/cmd_vel``: the robot's velocity controller (the firmware loop)
  turns it into wheel setpoints, the motor boards into duty, the plant into motion, exactly as for
  this stack's own AI. A global velocity is first rotated into the robot frame with the robot's true
  heading (``ground_truth/odom``), as a simulator knows it. Wheel velocities are refused with an error.
- A kick speed (kick_angle 0) becomes ``robot_<id>/kick`` while it is set (the plant keeps each kick
  armed for 0.1 s; it is repeated every ``kick_repeat_s``). Chip kicks are refused with an error.
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
from typing import Any

from nav_msgs.msg import Odometry
from rclpy.node import Node
from std_msgs.msg import Bool, Float64

from erforce_interfaces import contract, ssl_sim
from erforce_interfaces.conversions import (
    ConversionError,
    odometry_from_msg,
    odometry_msg,
    stamp_to_nanoseconds,
    twist_msg,
)
from erforce_interfaces.node_support import (
    NodeParams,
    ThrottledWarner,
    check_stamp,
    contract_publisher,
    contract_subscription,
    run_node,
)
from erforce_interfaces.param_schema import load_schema
from erforce_interfaces.stamps import StampFilter, StampVerdict

SCHEMA = load_schema("erforce_sim", "ssl_sim_server")


def _check(c):
    """Refuses robot ids the protocol cannot carry (the schema checked the rest); every parameter is read-only."""
    ssl_sim.BridgeCommands(c.robot_ids)
    return c


class SslSimServerNode(Node):
    def __init__(self) -> None:
        super().__init__("ssl_sim_server")
        self._warn = ThrottledWarner(self)
        self._params = NodeParams(self, SCHEMA, _check)
        v = self._values = self._params.values
        self._team = v["team"]
        self._ids = tuple(sorted(set(v["robot_ids"])))
        q = contract
        self._pubs: dict[int, dict[str, Any]] = {}
        self._pose: dict[int, tuple[float, float, float]] = {}
        self._odom_stamps = {i: StampFilter() for i in self._ids}  # the time rule: a stale pose is not the newest
        self._contact: dict[int, bool] = dict.fromkeys(self._ids, False)
        self._last_kick: dict[int, float] = dict.fromkeys(self._ids, -math.inf)
        for i in self._ids:
            self._pubs[i] = {
                "cmd_vel": contract_publisher(self, q.CMD_VEL, q.CMD_VEL.for_robot(i)),
                "kick": contract_publisher(self, q.KICK, q.KICK.for_robot(i)),
                "set_state": contract_publisher(self, q.SIM_SET_STATE, q.SIM_SET_STATE.for_robot(i)),
            }
            contract_subscription(self, q.GROUND_TRUTH_ODOM, lambda m, i=i: self._on_odom(i, m),
                                  q.GROUND_TRUTH_ODOM.for_robot(i))
            contract_subscription(self, q.BALL_DETECTED, lambda m, i=i: self._on_contact(i, m),
                                  q.BALL_DETECTED.for_robot(i))
        self._set_ball_pub = contract_publisher(self, q.SIM_SET_BALL)
        robot_port = v["robot_control_port"] or ssl_sim.ROBOT_CONTROL_PORTS[self._team]
        self._stop = threading.Event()
        self._socks = []
        threads = []
        for port, handler in ((robot_port, self._robot_control), (v["control_port"], self._simulator_control)):
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
            threads.append(threading.Thread(target=self._serve, args=(sock, handler), daemon=True))
        self.ports = [s.getsockname()[1] for s in self._socks]
        for t in threads:
            t.start()
        self._threads = threads
        self.get_logger().info(
            f"ssl_sim_server: {self._team} robots {list(self._ids)}; robot control on "
            f"{v['bind_address']}:{self.ports[0]}, simulator control on {v['bind_address']}:{self.ports[1]}")

    # ---------------------------------------------------------------- the plant's state
    def _on_odom(self, robot: int, msg: Odometry) -> None:
        try:
            _, pose, _, _ = odometry_from_msg(msg)
        except ConversionError as exc:
            self._warn.warn(f"odom{robot}", f"robot_{robot}: rejected ground_truth/odom: {exc}")
            return
        verdict = check_stamp(self._odom_stamps[robot], stamp_to_nanoseconds(msg.header.stamp), self._warn,
                              f"robot_{robot}/ground_truth/odom", self)
        if verdict is StampVerdict.DROP:
            return
        self._pose[robot] = (float(pose[0]), float(pose[1]), float(pose[2]))

    def _on_contact(self, robot: int, msg: Bool) -> None:
        self._contact[robot] = bool(msg.data)

    def _yaw(self, robot: int) -> float | None:
        pose = self._pose.get(robot)
        return None if pose is None else pose[2]

    # ---------------------------------------------------------------- the sockets
    def _serve(self, sock: socket.socket, handler) -> None:
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
                reply = (ssl_sim.encode_robot_control_response({}, error) if handler == self._robot_control
                         else ssl_sim.encode_simulator_response(error))
            try:
                sock.sendto(reply, addr)
            except OSError as exc:
                self._warn.warn("reply", f"cannot answer {addr[0]}:{addr[1]}: {exc}")

    def _robot_control(self, data: bytes) -> bytes:
        requests = ssl_sim.decode_robot_control(data)
        actions, errors = ssl_sim.plan_robot_control(requests, self._ids, self._yaw)
        now = time.monotonic()
        for a in actions:
            pubs = self._pubs[a.robot_id]
            if a.twist is not None:
                pubs["cmd_vel"].publish(twist_msg(a.twist))
            if a.kick_speed_mps > 0.0 and now - self._last_kick[a.robot_id] >= self._values["kick_repeat_s"]:
                self._last_kick[a.robot_id] = now
                pubs["kick"].publish(Float64(data=a.kick_speed_mps))
        if errors:
            self._warn.warn("robot_errors", "robot control: " + "; ".join(e.message for e in errors))
        return ssl_sim.encode_robot_control_response(dict(self._contact), errors)

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
            if r.team != self._team or r.robot_id not in self._pubs:
                errors.append(ssl_sim.SimError(ssl_sim.ERROR_UNKNOWN_ROBOT,
                                               f"teleport_robot: {r.team} {r.robot_id} is not simulated here"))
                continue
            if r.present is False or r.by_force:
                errors.append(ssl_sim.SimError(unsupported, "teleport_robot: present=false and by_force are not "
                                                            "supported"))
                continue
            now = self._pose.get(r.robot_id)
            if now is None and None in (r.x_m, r.y_m, r.yaw_rad):
                errors.append(ssl_sim.SimError(ssl_sim.ERROR_INVALID,
                                               f"teleport_robot {r.robot_id}: no pose yet, set x, y and orientation"))
                continue
            pose = tuple(given if given is not None else current
                         for given, current in zip((r.x_m, r.y_m, r.yaw_rad), now or (0.0, 0.0, 0.0), strict=True))
            self._pubs[r.robot_id]["set_state"].publish(odometry_msg(0.0, pose, r.velocity))
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
