"""A minimal external simulator for tests: it speaks only the protocols over UDP (ssl-simulation-protocol
robot control, or grSim's packet and robot status), integrates each commanded robot as a point with a
heading, and answers with ball contact once a robot has driven past ``contact_x_m``."""

from __future__ import annotations

import math
import socket
import threading
import time

import numpy as np
from google.protobuf.message import DecodeError

from erforce_interfaces.ssl.ssl_proto import (
    grsim_pb2,
    ssl_simulation_control_pb2,
    ssl_simulation_robot_control_pb2,
    ssl_simulation_robot_feedback_pb2,
)


def _length_delimited(field_number: int, body: bytes) -> bytes:
    """One length-delimited field (wire type 2): tag, length varint, body."""
    n, length = len(body), bytearray()
    while n >= 0x80:
        length.append(n & 0x7F | 0x80)
        n >>= 7
    return bytes([field_number << 3 | 2]) + bytes(length) + bytes([n]) + body


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
        self.bad_control = 0  # datagrams on the control port that were no SimulatorCommand
        self.status_port = status_port
        self.poses: dict[int, list[float]] = {}  # id -> [x, y, yaw]
        self.kicks: list[tuple[int, float]] = []  # (id, kick speed) of every command with a kick
        self.packets = 0
        self.foreign = 0  # datagrams that were not the protocol
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
            try:
                commands = self._commands(data)
            except DecodeError:  # not the protocol (a stray datagram on this port): a simulator ignores it
                self.foreign += 1
                continue
            now = time.monotonic()
            dt = 0.0 if self._last_t is None else min(now - self._last_t, 0.1)
            self._last_t = now
            contact = {}
            with self._lock:
                self.packets += 1
                for robot_id, fwd, left, ang, kick in commands:
                    x, y, yaw = self.poses.setdefault(robot_id, [0.0, 0.0, 0.0])
                    x += (fwd * math.cos(yaw) - left * math.sin(yaw)) * dt
                    y += (fwd * math.sin(yaw) + left * math.cos(yaw)) * dt
                    self.poses[robot_id] = [x, y, yaw + ang * dt]
                    if kick > 0.0:
                        self.kicks.append((robot_id, kick))
                    contact[robot_id] = self._contact(robot_id, x)
            self._answer(contact, addr)

    def _contact(self, robot_id: int, x: float) -> bool:
        return x > self.contact_x_m

    def _run_control(self) -> None:
        while not self._stop.is_set():
            try:
                data, addr = self.control.recvfrom(65536)
            except TimeoutError:
                continue
            except OSError:
                return
            try:
                self.teleports.append(ssl_simulation_control_pb2.SimulatorCommand.FromString(data))
            except DecodeError:  # a stray datagram on a reused port is no command: counted, not answered
                self.bad_control += 1
                continue
            self.control.sendto(ssl_simulation_control_pb2.SimulatorResponse().SerializeToString(), addr)

    def _answer(self, contact: dict[int, bool], addr) -> None:
        for k in range(self.flood_next):
            self.sock.sendto(b"\x0a\xff flood %d" % k, addr)
        self.flood_next = 0
        if self.garbage_next:
            self.garbage_next = False
            reply = b"\xff\x00garbage"
        elif self.protocol == "grsim":
            status = grsim_pb2.Robots_Status()
            for robot_id, c in contact.items():
                status.robots_status.add(robot_id=robot_id, infrared=c, flat_kick=False, chip_kick=False)
            reply = status.SerializeToString()
            addr = ("127.0.0.1", self.status_port)
        else:
            response = ssl_simulation_robot_feedback_pb2.RobotControlResponse()
            for robot_id, c in contact.items():
                response.feedback.add(id=robot_id, dribbler_ball_contact=c)
            reply = response.SerializeToString()
            if self.error_text:  # written from the field numbers: errors = 1 {code = 1, message = 2}
                error = _length_delimited(1, b"STANDIN") + _length_delimited(2, self.error_text.encode())
                reply += _length_delimited(1, error)
        self.sock.sendto(reply, addr)

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=2.0)
        self._control_thread.join(timeout=2.0)
        self.sock.close()
        self.control.close()


class VisionSimStandIn(SimStandIn):
    """The stand-in plus a ball and SSL-Vision: one camera sends robot 0 (blue) and the ball at 60 Hz to a
    multicast group on loopback. The ball rolls by the two-phase model after ``kick``; it is caught (stops
    in front of the robot, dribbler contact) once it comes within ``catch_radius_m`` of robot 0."""

    def __init__(self, vision_port: int, catch_radius_m: float = 0.13) -> None:
        from erforce_sim.ssl_cameras import open_multicast_sender

        self.vision_addr = ("224.5.23.2", vision_port)
        self.vision_sock = open_multicast_sender("127.0.0.1")
        self.catch_radius_m = catch_radius_m
        self.ball_rest = (2.5, 0.6)
        self.trajectory = None
        self.t_kick = 0.0
        self.caught_at: tuple[float, float] | None = None
        super().__init__(contact_x_m=1e9)
        self._vision_thread = threading.Thread(target=self._run_vision, daemon=True)
        self._vision_thread.start()

    def kick(self, x: float, y: float, vx: float, vy: float) -> None:
        from erforce_ball_model.ball_model import BallTrajectory

        self.t_kick = time.monotonic()
        self.trajectory = BallTrajectory((x, y), (vx, vy), float(np.hypot(vx, vy)))

    def ball(self) -> tuple[float, float]:
        if self.caught_at is not None:
            return self.caught_at
        if self.trajectory is None:
            return self.ball_rest
        p = self.trajectory.position_at(time.monotonic() - self.t_kick)
        return float(p[0]), float(p[1])

    def _run_vision(self) -> None:
        from erforce_interfaces.ssl.ssl_vision import BallCandidate, CameraFrame, RobotSighting, encode_frame

        frame_number = 0
        while not self._stop.is_set():
            x, y, yaw = self.pose(0)
            bx, by = self.ball()
            if self.caught_at is None and math.hypot(bx - x, by - y) < self.catch_radius_m:
                self.caught_at = (bx, by)
            frame_number += 1
            t = time.time()
            data = encode_frame(CameraFrame(0, frame_number, t, t + 0.002, (BallCandidate(bx, by, 0.9),),
                                            (RobotSighting("blue", 0, x, y, math.remainder(yaw, 2 * math.pi), 0.9),)))
            self.vision_sock.sendto(data, self.vision_addr)
            time.sleep(1.0 / 60.0)

    def _contact(self, robot_id: int, x: float) -> bool:
        return robot_id == 0 and self.caught_at is not None

    def close(self) -> None:
        super().close()
        self._vision_thread.join(timeout=2.0)
        self.vision_sock.close()
