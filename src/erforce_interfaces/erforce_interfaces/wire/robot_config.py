"""One robot description shared by the motion controllers and the simulator.

erforce_motion builds its kinematics and actuator model from it, erforce_sim builds
the plant from it, so the controller and the plant can never disagree about geometry.
All values are SI (REP 103): metres, kilograms, seconds, radians, volts, amperes.

Wheel angles are measured in the robot frame ``base_link`` (x forward, towards the
dribbler and kicker; y left; z up), counter-clockwise from +x to the wheel's position
vector. A wheel drives tangentially: positive wheel speed pushes the robot
counter-clockwise about its centre (Rojas, "Omnidirectional control", 2005).

No rclpy import: the cores use this module directly.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path

import numpy as np
import yaml


def _default_wheel_angles() -> tuple[float, ...]:
    # A typical SSL layout: front pair 30 deg off the lateral axis (room for the
    # dribbler), rear pair 45 deg. Not evenly spaced on purpose.
    return tuple(math.radians(a) for a in (60.0, 135.0, 225.0, 300.0))


def _doc(default, doc: str, **bounds):
    """A dataclass field with its documentation and bounds (``gt``, ``le``, ``min_size``); the node
    parameter descriptors and the checks in ``RobotConfig.__post_init__`` both come from them."""
    meta = {"doc": doc, **bounds}
    if callable(default):
        return field(default_factory=default, metadata=meta)
    return field(default=default, metadata=meta)


def _positive(default, doc: str):
    return _doc(default, doc, gt=0.0)


# A wheel layout whose matrix is this ill-conditioned turns small body commands into huge wheel speeds.
MAX_WHEEL_LAYOUT_CONDITION = 100.0


@dataclass(frozen=True)
class RobotConfig:
    """Geometry, inertia and drive train of one omni-wheel SSL robot."""

    wheel_angles_rad: tuple[float, ...] = _doc(
        _default_wheel_angles, "wheel positions in base_link, CCW from +x [rad]; 3 or more, spread so that "
        "the wheels can produce every twist", min_size=3)
    wheel_radius_m: float = _positive(0.0275, "wheel radius [m]")
    wheel_distance_m: float = _positive(0.081, "robot centre to wheel contact point [m]")
    robot_radius_m: float = _positive(0.09, "robot body radius [m]")
    mass_kg: float = _positive(2.6, "robot mass [kg]")
    inertia_kgm2: float = _positive(0.011, "robot inertia about z through the centre of mass [kg m^2]")
    dribbler_offset_m: float = _positive(0.0815, "robot centre to ball centre when the ball touches the dribbler [m]")
    dribbler_width_m: float = _positive(0.07, "usable width of the dribbler and kicker plate [m]")
    traction_mu: float = _positive(0.8, "wheel-carpet friction coefficient")
    # Drive train: Maxon EC-45 flat 50 W class motor behind a spur gear.
    gear_ratio: float = _positive(3.6, "motor revolutions per wheel revolution")
    gear_efficiency: float = _doc(0.9, "gear efficiency", gt=0.0, le=1.0)
    motor_resistance_ohm: float = _positive(0.94, "winding resistance [ohm]")
    motor_inductance_h: float = _positive(0.36e-3, "winding inductance [H]")
    motor_torque_constant_nm_per_a: float = _positive(0.036, "torque constant [N m/A] = back-EMF constant [V s/rad]")
    motor_rotor_inertia_kgm2: float = _positive(1.35e-5, "rotor inertia [kg m^2]")
    wheel_inertia_kgm2: float = _positive(2.0e-5, "wheel with rollers, about its axle [kg m^2]")
    motor_viscous_friction_nms: float = _positive(2.0e-6, "viscous friction at the motor shaft [N m s]")
    motor_coulomb_friction_nm: float = _positive(1.5e-3, "Coulomb friction at the motor shaft [N m]")
    supply_voltage_v: float = _positive(24.0, "battery voltage at the motor bridge [V]")
    winding_thermal_time_constant_s: float = _positive(29.0, "winding thermal time constant [s]")
    winding_thermal_resistance_k_per_w: float = _positive(1.9, "winding to housing thermal resistance [K/W]")
    winding_max_temperature_c: float = _positive(125.0, "maximum winding temperature [degC]")
    ambient_temperature_c: float = _doc(25.0, "ambient temperature [degC]")
    continuous_current_limit_a: float = _positive(1.3, "the paper's limit on the ~10 s average motor current [A]")

    def __post_init__(self) -> None:
        angles = tuple(float(a) for a in self.wheel_angles_rad)
        object.__setattr__(self, "wheel_angles_rad", angles)
        for f in fields(self):
            value = getattr(self, f.name)
            values = value if isinstance(value, tuple) else (value,)
            if not all(isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v) for v in values):
                raise ValueError(f"{f.name}: must be finite numbers, got {value!r}")
            meta = f.metadata
            if len(values) < meta.get("min_size", 0):
                raise ValueError(f"{f.name}: need at least {meta['min_size']} values, got {len(values)}")
            if "gt" in meta and value <= meta["gt"]:
                raise ValueError(f"{f.name}: must be > {meta['gt']:g}, got {value!r}")
            if "le" in meta and value > meta["le"]:
                raise ValueError(f"{f.name}: must be <= {meta['le']:g}, got {value!r}")
        self._check_as_a_whole()

    def _check_as_a_whole(self) -> None:
        """What no single value shows: the parts must make one robot that can drive."""
        if self.winding_max_temperature_c <= self.ambient_temperature_c:
            raise ValueError("winding_max_temperature_c must exceed ambient_temperature_c")
        if self.wheel_distance_m > self.robot_radius_m:
            raise ValueError(f"wheel_distance_m: {self.wheel_distance_m} m puts the wheels outside the body "
                             f"(robot_radius_m {self.robot_radius_m} m)")
        condition = self.wheel_layout_condition
        if not condition <= MAX_WHEEL_LAYOUT_CONDITION:
            degrees = ", ".join(f"{math.degrees(a):.1f}" for a in self.wheel_angles_rad)
            raise ValueError(f"wheel_angles_rad: the wheels at [{degrees}] deg cannot produce every twist (wheel "
                             f"matrix condition number {condition:.3g}, at most {MAX_WHEEL_LAYOUT_CONDITION:g}); "
                             "spread them around the robot")

    @property
    def wheel_layout_condition(self) -> float:
        """Condition number of the wheel matrix rows [-sin a, cos a, 1] (the rotation column in units of
        the wheel distance, so that it does not depend on the robot's size); inf when its rank is < 3."""
        rows = [(-math.sin(a), math.cos(a), 1.0) for a in self.wheel_angles_rad]
        return float(np.linalg.cond(np.array(rows)))

    @property
    def wheel_no_load_speed_radps(self) -> float:
        """The fastest the motors turn a wheel: supply voltage over back-EMF constant, through the gear."""
        return self.supply_voltage_v / (self.motor_torque_constant_nm_per_a * self.gear_ratio)

    @property
    def top_wheel_speed_mps(self) -> float:
        """Speed of a wheel's rim at the motors' no-load speed: no robot motion asks more of one wheel."""
        return self.wheel_radius_m * self.wheel_no_load_speed_radps

    @property
    def num_wheels(self) -> int:
        return len(self.wheel_angles_rad)

    @property
    def wheel_names(self) -> tuple[str, ...]:
        return tuple(f"wheel_{i}" for i in range(self.num_wheels))

    def to_dict(self) -> dict:
        d = asdict(self)
        d["wheel_angles_rad"] = list(self.wheel_angles_rad)
        return d

    @classmethod
    def from_dict(cls, values: dict) -> RobotConfig:
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(values) - known)
        if unknown:
            raise ValueError(f"unknown robot config keys: {', '.join(unknown)}")
        values = dict(values)
        if "wheel_angles_rad" in values:
            values["wheel_angles_rad"] = tuple(values["wheel_angles_rad"])
        return cls(**values)

    @classmethod
    def from_yaml(cls, path: str | Path) -> RobotConfig:
        """Load a ROS 2 parameter file's ``robot.*`` parameters (the format of config/robot.yaml).

        Every node of a graph loads the same file; a file that gives the nodes different robots (one
        ``robot`` section per node name, not all equal) is refused, naming what differs. Nested maps
        and the dotted form (``robot.mass_kg: 2.6``) are both read, as ROS reads them.
        """
        data = yaml.safe_load(Path(path).read_text()) or {}
        if not isinstance(data, dict):
            raise ValueError(f"{path}: expected a ROS 2 parameter file (<node>: ros__parameters: ...)")
        found: dict[str, RobotConfig] = {}
        for scope, content in data.items():  # "/**", or a node name
            params = (content or {}).get("ros__parameters", {}) if isinstance(content, dict) else {}
            robot = dict(params.get("robot") or {})
            robot.update({k[len("robot."):]: v for k, v in params.items() if k.startswith("robot.")})
            if robot:
                try:
                    found[scope] = cls.from_dict(robot)
                except (ValueError, TypeError) as exc:
                    raise ValueError(f"{path}: {scope}: robot.{exc}") from None
        if not found:
            raise ValueError(f"{path}: no robot parameters (expected <node>: ros__parameters: robot: ...)")
        (first_scope, first), *others = found.items()
        for scope, other in others:
            if other != first:
                a, b = first.to_dict(), other.to_dict()
                diff = ", ".join(f"{k} {a[k]!r} vs {b[k]!r}" for k in a if a[k] != b[k])
                raise ValueError(f"{path}: the nodes {first_scope!r} and {scope!r} get different robots ({diff}); "
                                 "one robot description serves every node")
        return first


# The ball and the field wall: the one default of each, for the simulator's physics (erforce_sim.ball,
# erforce_sim.contacts) and the ball model's wall bounce (erforce_ball_model.walls.Walls).
GRAVITY_MPS2 = 9.81  # the field's gravity: the plant's wheels and ball, the motion loop's tilt, the chip model
ROBOT_HEIGHT_M = 0.15  # SSL rules: a robot is at most 0.15 m high (a ball higher flies over it)
SSL_MAX_KICK_MPS = 6.5  # SSL rules: the ball's speed after a kick
BALL_RADIUS_M = 0.02135  # SSL rules: a standard golf ball, about 43 mm across
BALL_INERTIA_FACTOR = 0.4  # I = k m r^2: a golf ball is close to a solid sphere (2/5)
BALL_WALL_RESTITUTION = 0.6  # the ball's speed normal to the wall, off it / onto it
BALL_WALL_FRICTION = 0.3  # Coulomb friction between ball and wall (cuts the ball's speed along the wall)
# The carpet's two-phase ball model (paper Sec. 5.2, its measured values): the plant's carpet and the ball
# predictor's model until SSL geometry or identification says otherwise.
BALL_A_SLIDE_MPS2 = -2.5
BALL_A_ROLL_MPS2 = -0.3
BALL_C_SWITCH = 0.6
# A chipped ball's hops (erforce_ball_model.ball_model.ChipParams): the plant's ball, a solid sphere chipped
# without spin (no drag), and the ball predictor's chip model until its parameters say otherwise.
BALL_CHIP_DAMPING_Z = 0.566  # vertical speed off / onto the carpet at a bounce (the plant's floor_restitution)
BALL_CHIP_DAMPING_XY_FIRST_HOP = 1.0 / (1.0 + BALL_INERTIA_FACTOR)  # horizontal speed kept at the first bounce
BALL_CHIP_DAMPING_XY_OTHER_HOPS = 1.0  # ... at the later ones (the ball spins already)
BALL_CHIP_MIN_HOP_VZ_MPS = 0.05  # a bounce leaving less upwards ends the hops: the ball rolls on
# The chip model's part that SSL geometry's chip_fixed_loss gives (ChipParams' field names; the columns of
# /vision/chip_model): the only dampings the world may replace.
BALL_CHIP_DAMPING_NAMES = ("damping_z", "damping_xy_first_hop", "damping_xy_other_hops")
# Two heights of a ball's centre above its rest: a robot's body stops a ball up to about its own height (SSL: at
# most 0.15 m; the plant's robot_height_m), the interception height; but it controls a ball only as high as its
# light barrier's beam and dribbler bar reach, which sit at a resting ball's centre (the plant's World): a ball
# whose centre is one radius higher passes above both, the reception height.
BALL_MAX_CATCH_HEIGHT_M = ROBOT_HEIGHT_M
BALL_MAX_RECEIVE_HEIGHT_M = BALL_RADIUS_M
# SSL-Vision's position noise (standard deviation): what the plant adds and what the ball filter expects.
VISION_NOISE_M = 0.002


@dataclass(frozen=True)
class FieldConfig:
    """Playing surface; the field frame has its origin at the centre, x along the long side. The walls
    stand ``boundary_m`` (SSL geometry's boundary_width, the run-off area) beyond the field lines."""

    length_m: float
    width_m: float
    boundary_m: float = 0.3  # run-off area between field lines and walls

    def __post_init__(self) -> None:
        for name in ("length_m", "width_m", "boundary_m"):
            v = getattr(self, name)
            if not math.isfinite(v) or v < 0.0 or (name != "boundary_m" and v == 0.0):
                raise ValueError(f"{name}: must be finite and > 0, got {v!r}")

    @property
    def half_length_m(self) -> float:
        return 0.5 * self.length_m

    @property
    def half_width_m(self) -> float:
        return 0.5 * self.width_m

    @property
    def wall_half_length_m(self) -> float:
        return self.half_length_m + self.boundary_m

    @property
    def wall_half_width_m(self) -> float:
        return self.half_width_m + self.boundary_m

    def contains(self, x: float, y: float, margin_m: float = 0.0) -> bool:
        """True when (x, y) lies inside the field lines extended by ``margin_m``."""
        return abs(x) <= self.half_length_m + margin_m and abs(y) <= self.half_width_m + margin_m

    @classmethod
    def preset(cls, name: str) -> FieldConfig:
        try:
            return FIELD_PRESETS[name]
        except KeyError:
            raise ValueError(f"unknown field preset {name!r}; known: {', '.join(FIELD_PRESETS)}") from None


FIELD_PRESETS: dict[str, FieldConfig] = {
    "division_a": FieldConfig(length_m=12.0, width_m=9.0, boundary_m=0.3),
    "division_b": FieldConfig(length_m=9.0, width_m=6.0, boundary_m=0.3),
}

# A node's ``field`` parameter may name a preset or this: the field is what the world's SSL geometry says, and
# nothing is judged against a field before it arrives.
FROM_GEOMETRY = "from_geometry"
# The field of our own world (the plant's), and the preset the AI nodes assume unless told otherwise.
FIELD_PRESET = "division_b"
# Robots per team on the field: division A's rule, the nodes' num_robots unless told otherwise.
TEAM_SIZE = 11
# what such a node logs once at start
WAITING_FOR_GEOMETRY = "waiting for SSL geometry: no vision is judged or used until the world's field is known"


def field_from_setting(name: str) -> FieldConfig | None:
    """The field a ``field`` parameter names: a preset, or None for ``from_geometry`` (wait for the world's)."""
    return None if name == FROM_GEOMETRY else FieldConfig.preset(name)


# The ``field`` frame: origin at the field's centre, x towards the opponents' goal. A world that has us
# defending its positive x (``defend_side``) is turned by half a turn against it.
DEFEND_SIDES = ("negative_x", "positive_x")
OUR_DEFEND_SIDE = "negative_x"  # unless told otherwise (both SSL bridges' defend_side)


def turned_half(defend_side: str) -> bool:
    """Whether the world's frame is our ``field`` frame turned by half a turn (we defend its positive x)."""
    if defend_side not in DEFEND_SIDES:
        raise ValueError(f"defend_side: must be one of {', '.join(DEFEND_SIDES)}, got {defend_side!r}")
    return defend_side == "positive_x"


def half_turn(x, y, theta=None):
    """A position (and heading) turned by half a turn about the field's centre: from the world's frame to
    ``field`` when ``turned_half``, and back (it is its own inverse). Velocities turn the same way
    (``half_turn(vx, vy)``). Floats or numpy arrays; a NaN heading (none seen) stays NaN; headings come
    back in [-pi, pi)."""
    if theta is None:
        return -x, -y
    return -x, -y, np.mod(theta, 2.0 * math.pi) - math.pi
