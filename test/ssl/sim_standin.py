"""A minimal external simulator for tests: it speaks only the protocols over UDP (ssl-simulation-protocol
robot control, or grSim's packet and robot status), integrates each commanded robot as a point with a
heading, and answers with ball contact once a robot has driven past ``contact_x_m``."""

from __future__ import annotations

import math
import socket
import threading
import time

from erforce_interfaces.ssl_proto import (
    grsim_pb2,
    ssl_simulation_control_pb2,
    ssl_simulation_robot_control_pb2,
    ssl_simulation_robot_feedback_pb2,
)


class SimStandIn:
    def __init__(self, protocol: str = "ssl", contact_x_m: float = 0.5, status_port: int | None = None) -> None:
        self.protocol = protocol
        self.contact_x_m = contact_x_m
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.settimeout(0.1)
        self.port = self.sock.getsockname()[1]
        self.control = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)  # simulator control (teleports)
        self.control.bind(("127.0.0.1", 0))
        self.control.settimeout(0.1)
        self.control_port = self.control.getsockname()[1]
        self.teleports: list = []  # SimulatorCommand messages received
        self.status_port = status_port
        self.poses: dict[int, list[float]] = {}  # id -> [x, y, yaw]
        self.kicks: list[tuple[int, float]] = []  # (id, kick speed) of every command with a kick
        self.packets = 0
        self.error_text: str | None = None  # sent in every answer while set
        self.garbage_next = False
        self.flood_next = 0  # send this many garbage datagrams with the next answer
        self._last_t: float | None = None
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()
        self._control_thread = threading.Thread(target=self._run_control, daemon=True)
        self._control_thread.start()

    def pose(self, robot_id: int) -> list[float]:
        with self._lock:
            return list(self.poses.get(robot_id, [0.0, 0.0, 0.0]))

    def _commands(self, data: bytes) -> list[tuple[int, float, float, float, float]]:
        if self.protocol == "grsim":
            packet = grsim_pb2.grSim_Packet.FromString(data)
            return [(c.id, c.veltangent, c.velnormal, c.velangular, c.kickspeedx)
                    for c in packet.commands.robot_commands]
        msg = ssl_simulation_robot_control_pb2.RobotControl.FromString(data)
        out = []
        for c in msg.robot_commands:
            v = c.move_command.local_velocity
            out.append((c.id, v.forward, v.left, v.angular, c.kick_speed))
        return out

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                data, addr = self.sock.recvfrom(65536)
            except TimeoutError:
                continue
            except OSError:
                return
            now = time.monotonic()
            dt = 0.0 if self._last_t is None else min(now - self._last_t, 0.1)
            self._last_t = now
            contact = {}
            with self._lock:
                self.packets += 1
                for robot_id, fwd, left, ang, kick in self._commands(data):
                    x, y, yaw = self.poses.setdefault(robot_id, [0.0, 0.0, 0.0])
                    x += (fwd * math.cos(yaw) - left * math.sin(yaw)) * dt
                    y += (fwd * math.sin(yaw) + left * math.cos(yaw)) * dt
                    self.poses[robot_id] = [x, y, yaw + ang * dt]
                    if kick > 0.0:
                        self.kicks.append((robot_id, kick))
                    contact[robot_id] = x > self.contact_x_m
            self._answer(contact, addr)

    def _run_control(self) -> None:
        while not self._stop.is_set():
            try:
                data, addr = self.control.recvfrom(65536)
            except TimeoutError:
                continue
            except OSError:
                return
            self.teleports.append(ssl_simulation_control_pb2.SimulatorCommand.FromString(data))
            self.control.sendto(ssl_simulation_control_pb2.SimulatorResponse().SerializeToString(), addr)

    def _answer(self, contact: dict[int, bool], addr) -> None:
        for k in range(self.flood_next):
            self.sock.sendto(b"\x0a\xff flood %d" % k, addr)
        self.flood_next = 0
        if self.garbage_next:
            self.garbage_next = False
            reply = b"\xff\x00garbage"
        elif self.protocol == "grsim":
            status = grsim_pb2.grSim_Robots_Status()
            for robot_id, c in contact.items():
                status.robots_status.add(robot_id=robot_id, infrared=c, flat_kick=False, chip_kick=False)
            reply = status.SerializeToString()
            addr = ("127.0.0.1", self.status_port)
        else:
            response = ssl_simulation_robot_feedback_pb2.RobotControlResponse()
            for robot_id, c in contact.items():
                response.feedback.add(id=robot_id, dribbler_ball_contact=c)
            if self.error_text:
                response.errors.add(code="STANDIN", message=self.error_text)
            reply = response.SerializeToString()
        self.sock.sendto(reply, addr)

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=2.0)
        self._control_thread.join(timeout=2.0)
        self.sock.close()
        self.control.close()
