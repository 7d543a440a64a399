"""The simulator protocols of the Small Size League as plain functions: the ssl-simulation-protocol
(ER-Force's simulator, and our plant's ``ssl_sim_server``) and grSim's own packet.

No rclpy here: the bridge and server nodes convert messages, call these, and handle sockets.

Ports (the protocol's defaults): simulator control 10300, robot control 10301 (blue) and 10302
(yellow); a simulator answers each ``RobotControl`` with a ``RobotControlResponse`` to the sender's
address. grSim takes ``grSim_Packet`` on 20011 and reports ``Robots_Status`` on 30011 (blue)
and 30012 (yellow).

Frames and units: the protocol's field coordinates are metres with the origin at the centre (grSim's
replacement too, its robot direction in degrees). The contract's ``field`` frame has x towards the
opponents' goal: when we defend the simulator's positive x it is the simulator's frame turned by half a
turn (``teleport_packet``, as ssl_vision_bridge turns vision), else they map 1:1. Local velocities are the contract's
``base_link`` (forward = x towards the dribbler, left = y). Kick speed in m/s; dribbler speed on the
wire in rpm, in rad/s on the contract. A chip is the protocol's ``kick_speed`` (the ball's speed, in 3D)
with ``kick_angle`` (its elevation in degrees, 0 flat); grSim takes the same kick as the ball's
velocity components, ``kickspeedx`` along the carpet and ``kickspeedz`` upwards.

Decoders raise ``WireError`` (a ValueError) naming the problem: garbage, a missing required field,
non-finite or absurd values, absurd counts. Nothing non-finite leaves a decoder.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

from google.protobuf.message import DecodeError

from erforce_interfaces.runtime.param_schema import schema_defaults
from erforce_interfaces.ssl.ssl_proto import (
    grsim_pb2,
    ssl_gc_common_pb2,
    ssl_simulation_control_pb2,
    ssl_simulation_robot_control_pb2,
    ssl_simulation_robot_feedback_pb2,
)
from erforce_interfaces.wire.conversions import finite_within
from erforce_interfaces.wire.robot_config import half_turn, turned_half

_BRIDGE = schema_defaults("erforce_sim", "ssl_sim_bridge")  # the bridge node's defaults

SIM_CONTROL_PORT = 10300
ROBOT_CONTROL_PORTS = {"blue": 10301, "yellow": 10302}
GRSIM_COMMAND_PORT = 20011
GRSIM_STATUS_PORTS = {"blue": 30011, "yellow": 30012}
TEAMS = ("blue", "yellow")

MAX_DATAGRAM_BYTES = 65507  # the UDP payload limit over IPv4
MAX_ROBOTS_PER_PACKET = 32  # 2 x 16 ids; more is not a team
MAX_ROBOT_ID = 255
# Beyond any SSL robot or ball; such values are garbage (a unit mix-up), not commands.
MAX_LINEAR_MPS = 20.0
MAX_ANGULAR_RADPS = 100.0
MAX_KICK_MPS = 20.0
MAX_KICK_ANGLE_DEG = 90.0  # exclusive: an elevation of 90 deg has no direction on the carpet
MAX_DRIBBLER_RPM = 1.0e5
MAX_POSITION_M = 100.0

RPM_PER_RADPS = 60.0 / (2.0 * math.pi)

# SimulatorError codes this stack's server sends (stable, for clients to act on).
ERROR_UNSUPPORTED = "ERFORCE_UNSUPPORTED"
ERROR_UNKNOWN_ROBOT = "ERFORCE_UNKNOWN_ROBOT"
ERROR_INVALID = "ERFORCE_INVALID"
MAX_ERROR_TEXT_CHARS = 500  # of one SimulatorError as the bridge reports it: a log line, not a dump

_TEAM_ENUM = {"yellow": ssl_gc_common_pb2.YELLOW, "blue": ssl_gc_common_pb2.BLUE}


class WireError(ValueError):
    """A datagram this module cannot accept, with the reason."""


def check_team(team: str) -> str:
    if team not in TEAMS:
        raise ValueError(f"team must be blue or yellow, got {team!r}")
    return team


def _parse(message, data: bytes, what: str):
    if not isinstance(data, bytes | bytearray | memoryview):
        raise WireError(f"{what}: expected bytes, got {type(data).__name__}")
    if len(data) > MAX_DATAGRAM_BYTES:
        raise WireError(f"{what}: {len(data)} bytes is more than a UDP datagram holds")
    try:
        message.ParseFromString(bytes(data))
    except (DecodeError, RuntimeError, ValueError) as exc:  # garbage, wrong wire types, missing required
        raise WireError(f"{what}: not a valid message ({exc})") from None
    if not message.IsInitialized():  # the runtime parses past missing required fields
        missing = ", ".join(message.FindInitializationErrors()[:5])
        raise WireError(f"{what}: required field(s) missing: {missing}")
    return message


def finite_value(what: str, value: float, limit: float) -> float:
    """``value`` as a float; WireError when it is not finite or beyond +-``limit``."""
    return finite_within(what, value, limit, WireError)


def _count(what: str, items: Sequence) -> None:
    if len(items) > MAX_ROBOTS_PER_PACKET:
        raise WireError(f"{what}: {len(items)} entries, at most {MAX_ROBOTS_PER_PACKET} make sense")


def _robot_id(what: str, robot_id: int) -> int:
    if robot_id > MAX_ROBOT_ID:
        raise WireError(f"{what}: robot id {robot_id} is beyond {MAX_ROBOT_ID}")
    return int(robot_id)


# ------------------------------------------------------------------ the client side (our bridge)
@dataclass(frozen=True)
class RobotCommand:
    """One robot's command as this stack produces it: cmd_vel in base_link, kick, dribbler."""

    robot_id: int
    forward_mps: float = 0.0
    left_mps: float = 0.0
    angular_radps: float = 0.0
    kick_speed_mps: float = 0.0  # > 0: kick when the ball is at the kicker (the ball's speed, in 3D for a chip)
    dribbler_radps: float = 0.0
    kick_angle_deg: float = 0.0  # the kick's elevation: 0 flat, in (0, 90) a chip

    def __post_init__(self) -> None:
        if int(self.robot_id) != self.robot_id or not 0 <= self.robot_id <= MAX_ROBOT_ID:
            raise ValueError(f"robot_id must be an integer in [0, {MAX_ROBOT_ID}], got {self.robot_id!r}")
        limits = (("forward_mps", MAX_LINEAR_MPS), ("left_mps", MAX_LINEAR_MPS),
                  ("angular_radps", MAX_ANGULAR_RADPS), ("kick_speed_mps", MAX_KICK_MPS),
                  ("dribbler_radps", MAX_DRIBBLER_RPM / RPM_PER_RADPS))
        for name, limit in limits:
            try:
                finite_value(name, getattr(self, name), limit)
            except WireError as exc:
                raise ValueError(str(exc)) from None
        if self.kick_speed_mps < 0.0:
            raise ValueError(f"kick_speed_mps must be >= 0, got {self.kick_speed_mps!r}")
        check_kick_angle("kick_angle_deg", self.kick_angle_deg)


def check_kick_angle(what: str, angle_deg: float) -> float:
    """A kick's elevation [deg] in [0, 90) (0: flat, else a chip), else a ValueError naming ``what``."""
    if not (isinstance(angle_deg, int | float) and math.isfinite(angle_deg) and 0.0 <= angle_deg < MAX_KICK_ANGLE_DEG):
        raise ValueError(f"{what} must be in [0, {MAX_KICK_ANGLE_DEG:g}) degrees, got {angle_deg!r}")
    return float(angle_deg)


def encode_robot_control(commands: Iterable[RobotCommand]) -> bytes:
    """A ``RobotControl`` with a local-velocity move command per robot."""
    msg = ssl_simulation_robot_control_pb2.RobotControl()
    for c in commands:
        cmd = msg.robot_commands.add()
        cmd.id = c.robot_id
        local = cmd.move_command.local_velocity
        local.forward = c.forward_mps
        local.left = c.left_mps
        local.angular = c.angular_radps
        cmd.kick_speed = c.kick_speed_mps
        cmd.kick_angle = c.kick_angle_deg
        cmd.dribbler_speed = c.dribbler_radps * RPM_PER_RADPS
    return msg.SerializeToString()


def encode_grsim_commands(commands: Iterable[RobotCommand], team: str, timestamp_s: float = 0.0) -> bytes:
    """A ``grSim_Packet`` with the velocity commands of one team (grSim's dribbler is on or off)."""
    packet = grsim_pb2.grSim_Packet()
    packet.commands.timestamp = float(timestamp_s)
    packet.commands.isteamyellow = check_team(team) == "yellow"
    for c in commands:
        cmd = packet.commands.robot_commands.add()
        cmd.id = c.robot_id
        elevation = math.radians(c.kick_angle_deg)  # grSim: the ball's velocity along the carpet and upwards
        cmd.kickspeedx = c.kick_speed_mps * math.cos(elevation)
        cmd.kickspeedz = c.kick_speed_mps * math.sin(elevation)
        cmd.veltangent = c.forward_mps
        cmd.velnormal = c.left_mps
        cmd.velangular = c.angular_radps
        cmd.spinner = c.dribbler_radps > 0.0
        cmd.wheelsspeed = False
    return packet.SerializeToString()


@dataclass(frozen=True)
class Feedback:
    """What a simulator answered: ball contact per robot id, and its errors as text ("code: message")."""

    ball_contact: dict[int, bool] = field(default_factory=dict)
    errors: tuple[str, ...] = ()


def _error_text(error) -> str:
    """A SimulatorError as "code: message" (either may be missing), cut to MAX_ERROR_TEXT_CHARS."""
    text = ": ".join(part for part in (error.code or "no code", error.message) if part)
    if len(text) > MAX_ERROR_TEXT_CHARS:
        text = text[:MAX_ERROR_TEXT_CHARS] + f"... ({len(text)} characters)"
    return text


def decode_robot_control_response(data: bytes) -> Feedback:
    msg = _parse(ssl_simulation_robot_feedback_pb2.RobotControlResponse(), data, "RobotControlResponse")
    _count("RobotControlResponse.feedback", msg.feedback)
    _count("RobotControlResponse.errors", msg.errors)
    contact = {_robot_id("RobotFeedback", f.id): bool(f.dribbler_ball_contact)
               for f in msg.feedback if f.HasField("dribbler_ball_contact")}
    return Feedback(contact, tuple(_error_text(e) for e in msg.errors))


def decode_grsim_robots_status(data: bytes) -> Feedback:
    msg = _parse(grsim_pb2.Robots_Status(), data, "Robots_Status")
    _count("Robots_Status", msg.robots_status)
    contact = {}
    for status in msg.robots_status:
        if status.robot_id < 0:
            raise WireError(f"Robots_Status: negative robot id {status.robot_id}")
        contact[_robot_id("Robots_Status", status.robot_id)] = bool(status.infrared)
    return Feedback(contact)


def encode_teleport(ball: Sequence[float] | None = None,
                    robots: Iterable[tuple[str, int, float, float, float]] = ()) -> bytes:
    """A ``SimulatorCommand`` that places the ball (x, y, vx, vy) and robots (team, id, x, y, yaw).

    A moving ball is asked to roll (``roll``), as our plant starts a set ball; a ball placed at rest leaves the
    flag unset, since grSim answers every ``roll`` with GRSIM_UNSUPPORTED_ROLL_BALL."""
    msg = ssl_simulation_control_pb2.SimulatorCommand()
    if ball is not None:
        b = msg.control.teleport_ball
        b.x, b.y, b.vx, b.vy = (float(v) for v in ball)
        if b.vx or b.vy:
            b.roll = True
    for team, robot_id, x, y, yaw in robots:
        r = msg.control.teleport_robot.add()
        r.id.id = int(robot_id)
        r.id.team = _TEAM_ENUM[check_team(team)]
        r.x, r.y, r.orientation = float(x), float(y), float(yaw)
        r.present = True
    return msg.SerializeToString()


def encode_grsim_replacement(ball: Sequence[float] | None = None,
                             robots: Iterable[tuple[str, int, float, float, float]] = ()) -> bytes:
    """A ``grSim_Packet`` that places the ball (x, y, vx, vy) and robots (team, id, x, y, yaw [rad]);
    grSim takes the robot's direction in degrees."""
    packet = grsim_pb2.grSim_Packet()
    if ball is not None:
        b = packet.replacement.ball
        b.x, b.y, b.vx, b.vy = (float(v) for v in ball)
    for team, robot_id, x, y, yaw in robots:
        packet.replacement.robots.add(x=float(x), y=float(y), dir=math.degrees(float(yaw)), id=int(robot_id),
                                      yellowteam=check_team(team) == "yellow", turnon=True)
    return packet.SerializeToString()


def teleport_packet(protocol: str, defend_side: str, ball: Sequence[float] | None = None,
                    robots: Iterable[tuple[str, int, float, float, float]] = ()) -> bytes:
    """A teleport of the ball (x, y, vx, vy) and robots (team, id, x, y, yaw) given in the ``field`` frame, in the
    simulator's frame (``defend_side`` of the side we defend there) and wire format (protocol ``ssl``: a
    ``SimulatorCommand``, ``grsim``: a ``grSim_Packet``)."""
    if turned_half(defend_side):
        if ball is not None:
            x, y, vx, vy = ball
            ball = (*half_turn(x, y), *half_turn(vx, vy))
        robots = [(team, robot_id, *half_turn(x, y, yaw)) for team, robot_id, x, y, yaw in robots]
    encode = encode_grsim_replacement if protocol == "grsim" else encode_teleport
    return encode(ball, robots)


def decode_simulator_response(data: bytes) -> tuple[str, ...]:
    msg = _parse(ssl_simulation_control_pb2.SimulatorResponse(), data, "SimulatorResponse")
    _count("SimulatorResponse.errors", msg.errors)
    return tuple(_error_text(e) for e in msg.errors)


# ------------------------------------------------------------------ the simulator side (our plant)
@dataclass(frozen=True)
class MoveRequest:
    """One robot's command as a simulator receives it. ``kind``: local | global | wheel | none;
    ``velocity``: (forward, left, angular) for local, (vx, vy, angular) for global, the four wheel
    speeds (front right, back right, back left, front left) for wheel. The values are as sent: a value that is
    not finite or out of range is refused for its robot alone (plan_robot_control)."""

    robot_id: int
    kind: str
    velocity: tuple[float, ...]
    kick_speed_mps: float
    kick_angle_deg: float
    dribbler_rpm: float


def decode_robot_control(data: bytes) -> list[MoveRequest]:
    msg = _parse(ssl_simulation_robot_control_pb2.RobotControl(), data, "RobotControl")
    _count("RobotControl.robot_commands", msg.robot_commands)
    requests = []
    for cmd in msg.robot_commands:
        robot_id = _robot_id("RobotCommand", cmd.id)
        kind = cmd.move_command.WhichOneof("command") if cmd.HasField("move_command") else None
        if kind == "local_velocity":
            m = cmd.move_command.local_velocity
            values, kind = (m.forward, m.left, m.angular), "local"
        elif kind == "global_velocity":
            m = cmd.move_command.global_velocity
            values, kind = (m.x, m.y, m.angular), "global"
        elif kind == "wheel_velocity":
            m = cmd.move_command.wheel_velocity
            values, kind = (m.front_right, m.back_right, m.back_left, m.front_left), "wheel"
        else:
            values, kind = (), "none"
        requests.append(MoveRequest(robot_id, kind, tuple(float(v) for v in values), float(cmd.kick_speed),
                                    float(cmd.kick_angle), float(cmd.dribbler_speed)))
    return requests


def _move_limits(kind: str, n: int) -> tuple[float, ...]:
    linear = 4 if kind == "wheel" else 2
    return (MAX_LINEAR_MPS,) * min(linear, n) + (MAX_ANGULAR_RADPS,) * max(n - linear, 0)


def _refused(what: str, value: float, limit: float, low: float = -math.inf) -> str | None:
    """Why one command value is refused (not finite, beyond ``limit`` in magnitude, below ``low``), or None."""
    if not math.isfinite(value):
        return f"{what} = {value!r} is not finite"
    if abs(value) > limit or value < low:
        return f"{what} = {value:g} is outside [{max(low, -limit):g}, {limit:g}]"
    return None


def local_from_global(vx_mps: float, vy_mps: float, yaw_rad: float) -> tuple[float, float]:
    """A field-frame velocity in the robot frame of a robot heading ``yaw_rad`` (forward, left)."""
    c, s = math.cos(yaw_rad), math.sin(yaw_rad)
    return c * vx_mps + s * vy_mps, -s * vx_mps + c * vy_mps


@dataclass(frozen=True)
class SimError:
    """A SimulatorError as this stack's simulator sends it: one of the ERROR_* codes and a sentence."""

    code: str
    message: str


def _add_errors(container, errors: Iterable[SimError]) -> None:
    for e in errors:
        container.add(code=e.code, message=e.message)


def encode_robot_control_response(ball_contact: dict[int, bool], errors: Iterable[SimError] = ()) -> bytes:
    msg = ssl_simulation_robot_feedback_pb2.RobotControlResponse()
    _add_errors(msg.errors, errors)
    for robot_id, contact in sorted(ball_contact.items()):
        fb = msg.feedback.add()
        fb.id = robot_id
        fb.dribbler_ball_contact = bool(contact)
    return msg.SerializeToString()


@dataclass(frozen=True)
class TeleportRequest:
    """A robot placement; None fields keep the robot's current value."""

    team: str
    robot_id: int
    x_m: float | None
    y_m: float | None
    yaw_rad: float | None
    velocity: tuple[float, float, float]  # vx, vy [m/s], angular [rad/s] in the field frame
    present: bool | None
    by_force: bool


@dataclass(frozen=True)
class SimulatorRequest:
    ball: tuple[float, float, float, float] | None  # x, y, vx, vy
    ball_unsupported: tuple[str, ...]  # names of fields set that the request cannot honour
    robots: tuple[TeleportRequest, ...]
    simulation_speed: float | None
    has_config: bool


def decode_simulator_command(data: bytes) -> SimulatorRequest:
    msg = _parse(ssl_simulation_control_pb2.SimulatorCommand(), data, "SimulatorCommand")
    control = msg.control
    ball = None
    unsupported: list[str] = []
    if control.HasField("teleport_ball"):
        b = control.teleport_ball
        lim = (MAX_POSITION_M, MAX_POSITION_M, MAX_LINEAR_MPS, MAX_LINEAR_MPS)
        names = ("x", "y", "vx", "vy")
        ball = tuple(finite_value(f"teleport_ball.{n}", getattr(b, n), m) for n, m in zip(names, lim, strict=True))
        unsupported = [n for n in ("z", "vz") if b.HasField(n) and getattr(b, n) != 0.0]
        unsupported += [n for n in ("by_force",) if b.by_force]
    _count("SimulatorControl.teleport_robot", control.teleport_robot)
    robots = []
    for r in control.teleport_robot:
        team = {ssl_gc_common_pb2.YELLOW: "yellow", ssl_gc_common_pb2.BLUE: "blue"}.get(r.id.team)
        if team is None:
            raise WireError("teleport_robot: the robot's team is not set")
        robot_id = _robot_id("teleport_robot", r.id.id)

        def opt(name: str, limit: float, r=r, robot_id=robot_id):
            if not r.HasField(name):
                return None
            return finite_value(f"teleport_robot {robot_id}.{name}", getattr(r, name), limit)

        robots.append(TeleportRequest(
            team, robot_id, opt("x", MAX_POSITION_M), opt("y", MAX_POSITION_M), opt("orientation", 1e3),
            (finite_value("v_x", r.v_x, MAX_LINEAR_MPS), finite_value("v_y", r.v_y, MAX_LINEAR_MPS),
             finite_value("v_angular", r.v_angular, MAX_ANGULAR_RADPS)),
            r.present if r.HasField("present") else None, bool(r.by_force),
        ))
    speed = None
    if control.HasField("simulation_speed"):
        speed = finite_value("simulation_speed", control.simulation_speed, 1e3)
    return SimulatorRequest(ball, tuple(unsupported), tuple(robots), speed, msg.HasField("config"))


def encode_simulator_response(errors: Iterable[SimError] = ()) -> bytes:
    msg = ssl_simulation_control_pb2.SimulatorResponse()
    _add_errors(msg.errors, errors)
    return msg.SerializeToString()


# ------------------------------------------------------------------ the bridge's per-robot state
class BridgeCommands:
    """The newest command of each controlled robot, as the bridge sends them every period.

    A velocity older than ``command_timeout_s`` goes out as zero (a silent AI stops its robots, as
    the velocity controller does). A kick stays armed for ``kick_hold_s``: a simulator kicks when
    the ball touches the kicker while the command's kick speed is set, and the contract's ``kick``
    is one message. It goes out in one command only, the first one while the simulator reports the
    ball at the kicker (``ball_contact``): grSim applies every command with a kick speed that finds
    the ball still at its kicker, each one damping the ball's speed by the kicker's damp factor
    before setting it (``v = v_kick - 0.2 v_ball``, robot.cpp ``Kicker::kick``), and it takes all
    commands queued in one physics step, so a kick repeated over a few commands leaves at 0.8 of its
    speed. Without any contact report from the simulator the kick goes out in every command while
    armed (nothing tells when it happened). Times are any monotonic seconds.
    """

    def __init__(self, robot_ids: Iterable[int], command_timeout_s: float = _BRIDGE["command_timeout_s"],
                 kick_hold_s: float = _BRIDGE["kick_hold_s"]) -> None:
        self.robot_ids = tuple(sorted({int(i) for i in robot_ids}))
        if not self.robot_ids:
            raise ValueError("robot_ids: need at least one robot")
        for i in self.robot_ids:
            RobotCommand(i)  # checks the id
        self.command_timeout_s = float(command_timeout_s)
        self.kick_hold_s = float(kick_hold_s)
        never = -math.inf
        self._velocity = {i: ((0.0, 0.0, 0.0), never) for i in self.robot_ids}
        self._kick = {i: (0.0, never) for i in self.robot_ids}
        self._kick_angle = dict.fromkeys(self.robot_ids, 0.0)
        self._contact: dict[int, bool | None] = dict.fromkeys(self.robot_ids)  # None: never reported
        self._dribbler = dict.fromkeys(self.robot_ids, 0.0)

    def set_velocity(self, robot_id: int, now_s: float, forward_mps: float, left_mps: float,
                     angular_radps: float) -> None:
        RobotCommand(robot_id, forward_mps, left_mps, angular_radps)  # refuses bad values with the reason
        self._velocity[robot_id] = ((float(forward_mps), float(left_mps), float(angular_radps)), now_s)

    def stop(self, robot_id: int) -> None:
        self._velocity[robot_id] = ((0.0, 0.0, 0.0), -math.inf)

    def kick(self, robot_id: int, now_s: float, speed_mps: float) -> None:
        RobotCommand(robot_id, kick_speed_mps=speed_mps)
        self._kick[robot_id] = (float(speed_mps), now_s)

    def set_kick_angle(self, robot_id: int, angle_deg: float) -> None:
        """The elevation of this robot's kicks from now on (0: flat, else a chip; the contract's ``kick_angle``)."""
        RobotCommand(robot_id, kick_angle_deg=angle_deg)
        self._kick_angle[robot_id] = float(angle_deg)

    def set_dribbler(self, robot_id: int, radps: float) -> None:
        RobotCommand(robot_id, dribbler_radps=radps)
        self._dribbler[robot_id] = float(radps)

    def ball_contact(self, robot_id: int, contact: bool) -> None:
        """The simulator's latest report of whether the ball touches this robot's kicker (its light barrier)."""
        if robot_id in self._contact:
            self._contact[robot_id] = bool(contact)

    def commands(self, now_s: float) -> list[RobotCommand]:
        out = []
        for i in self.robot_ids:
            velocity, t_velocity = self._velocity[i]
            if now_s - t_velocity > self.command_timeout_s:
                velocity = (0.0, 0.0, 0.0)
            kick, t_kick = self._kick[i]
            if now_s - t_kick > self.kick_hold_s or self._contact[i] is False:
                kick = 0.0
            elif self._contact[i] and kick > 0.0:
                self._kick[i] = (0.0, t_kick)  # fired: this command is the kick's only one
            out.append(RobotCommand(i, *velocity, kick_speed_mps=kick, dribbler_radps=self._dribbler[i],
                                    kick_angle_deg=self._kick_angle[i] if kick > 0.0 else 0.0))
        return out


# ------------------------------------------------------------------ a simulator's decisions
@dataclass(frozen=True)
class RobotAction:
    """What a simulator with velocity-commanded robots, a flat and a chip kicker does for one RobotCommand."""

    robot_id: int
    twist: tuple[float, float, float] | None  # forward, left [m/s], angular [rad/s]; None: no move command
    kick_speed_mps: float  # 0: no kick
    dribbler_radps: float = 0.0  # with ``dribbler``: the requested dribbler speed (0: off)
    kick_angle_deg: float = 0.0  # the kick's elevation: 0 flat, in (0, 90) a chip


def plan_robot_control(requests: Iterable[MoveRequest], robot_ids: Iterable[int],
                       yaw_of, dribbler: bool = False) -> tuple[list[RobotAction], list[SimError]]:
    """Turn decoded robot commands into actions for the robots in ``robot_ids``.

    ``yaw_of(robot_id)`` gives a robot's heading [rad] (or None when unknown) for global velocities.
    Unsupported features (wheel velocities, a dribbler when ``dribbler`` is False) give
    one SimError each per packet, as the protocol recommends, and the rest of the command still acts. A value
    not finite or out of range refuses that part of that robot's command (its move, its kick, its dribbler)
    with an ERROR_INVALID naming it; the other robots' commands act.
    """
    served = set(robot_ids)
    actions: list[RobotAction] = []
    errors: dict[str, SimError] = {}
    for r in requests:
        if r.robot_id not in served:
            errors.setdefault(f"robot{r.robot_id}", SimError(
                ERROR_UNKNOWN_ROBOT, f"robot {r.robot_id} is not simulated here (robots {sorted(served)})"))
            continue
        twist, what = None, f"robot {r.robot_id}"
        bad = next(filter(None, (_refused(f"{what} {r.kind} velocity", v, lim)
                                 for v, lim in zip(r.velocity, _move_limits(r.kind, len(r.velocity)), strict=True))),
                   None)
        if bad is not None:
            errors.setdefault(f"move{r.robot_id}", SimError(ERROR_INVALID, f"{bad}: no move"))
        elif r.kind == "local":
            twist = r.velocity
        elif r.kind == "global":
            yaw = yaw_of(r.robot_id)
            if yaw is None:
                errors.setdefault(f"pose{r.robot_id}", SimError(
                    ERROR_INVALID, f"robot {r.robot_id}: no pose yet for a global velocity"))
            else:
                twist = (*local_from_global(r.velocity[0], r.velocity[1], yaw), r.velocity[2])
        elif r.kind == "wheel":
            errors.setdefault("wheel", SimError(
                ERROR_UNSUPPORTED, "wheel velocities are not supported: send local or global velocities"))
        kick, angle = r.kick_speed_mps, r.kick_angle_deg if r.kick_speed_mps > 0.0 else 0.0
        bad = _refused(f"{what} kick_speed", kick, MAX_KICK_MPS, 0.0)
        if bad is None and not (math.isfinite(angle) and 0.0 <= angle < MAX_KICK_ANGLE_DEG):
            bad = f"{what}: kick_angle {angle:g} deg is not in [0, 90)"
        if bad is not None:
            errors.setdefault(f"kick{r.robot_id}", SimError(ERROR_INVALID, f"{bad}: no kick"))
            kick, angle = 0.0, 0.0
        dribbler_rpm = r.dribbler_rpm
        bad = _refused(f"{what} dribbler_speed", dribbler_rpm, MAX_DRIBBLER_RPM)
        if bad is not None:
            errors.setdefault(f"dribbler{r.robot_id}", SimError(ERROR_INVALID, f"{bad}: dribbler off"))
            dribbler_rpm = 0.0
        elif dribbler_rpm != 0.0 and not dribbler:
            errors.setdefault("dribbler", SimError(ERROR_UNSUPPORTED, "this simulator has no dribbler motor"))
        actions.append(RobotAction(r.robot_id, twist, kick, dribbler_rpm / RPM_PER_RADPS if dribbler else 0.0,
                                   angle))
    return actions, list(errors.values())
