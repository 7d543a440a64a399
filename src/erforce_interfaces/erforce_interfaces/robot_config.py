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

import yaml


def _default_wheel_angles() -> tuple[float, ...]:
    # A typical SSL layout: front pair 30 deg off the lateral axis (room for the
    # dribbler), rear pair 45 deg. Not evenly spaced on purpose.
    return tuple(math.radians(a) for a in (60.0, 135.0, 225.0, 300.0))


def _doc(default, doc: str):
    """A dataclass field with its documentation (the node parameter descriptions come from it)."""
    if callable(default):
        return field(default_factory=default, metadata={"doc": doc})
    return field(default=default, metadata={"doc": doc})


@dataclass(frozen=True)
class RobotConfig:
    """Geometry, inertia and drive train of one omni-wheel SSL robot."""

    wheel_angles_rad: tuple[float, ...] = _doc(
        _default_wheel_angles, "wheel positions in base_link, CCW from +x [rad]; 3 or more")
    wheel_radius_m: float = _doc(0.0275, "wheel radius [m]")
    wheel_distance_m: float = _doc(0.081, "robot centre to wheel contact point [m]")
    robot_radius_m: float = _doc(0.09, "robot body radius [m]")
    mass_kg: float = _doc(2.6, "robot mass [kg]")
    inertia_kgm2: float = _doc(0.011, "robot inertia about z through the centre of mass [kg m^2]")
    dribbler_offset_m: float = _doc(0.0815, "robot centre to ball centre when the ball touches the dribbler [m]")
    dribbler_width_m: float = _doc(0.07, "usable width of the dribbler and kicker plate [m]")
    traction_mu: float = _doc(0.8, "wheel-carpet friction coefficient")
    # Drive train: Maxon EC-45 flat 50 W class motor behind a spur gear.
    gear_ratio: float = _doc(3.6, "motor revolutions per wheel revolution")
    gear_efficiency: float = _doc(0.9, "gear efficiency, (0, 1]")
    motor_resistance_ohm: float = _doc(0.94, "winding resistance [ohm]")
    motor_inductance_h: float = _doc(0.36e-3, "winding inductance [H]")
    motor_torque_constant_nm_per_a: float = _doc(0.036, "torque constant [N m/A] = back-EMF constant [V s/rad]")
    motor_rotor_inertia_kgm2: float = _doc(1.35e-5, "rotor inertia [kg m^2]")
    wheel_inertia_kgm2: float = _doc(2.0e-5, "wheel with rollers, about its axle [kg m^2]")
    motor_viscous_friction_nms: float = _doc(2.0e-6, "viscous friction at the motor shaft [N m s]")
    motor_coulomb_friction_nm: float = _doc(1.5e-3, "Coulomb friction at the motor shaft [N m]")
    supply_voltage_v: float = _doc(24.0, "battery voltage at the motor bridge [V]")
    winding_thermal_time_constant_s: float = _doc(29.0, "winding thermal time constant [s]")
    winding_thermal_resistance_k_per_w: float = _doc(1.9, "winding to housing thermal resistance [K/W]")
    winding_max_temperature_c: float = _doc(125.0, "maximum winding temperature [degC]")
    ambient_temperature_c: float = _doc(25.0, "ambient temperature [degC]")
    continuous_current_limit_a: float = _doc(1.3, "the paper's limit on the ~10 s average motor current [A]")

    def __post_init__(self) -> None:
        angles = tuple(float(a) for a in self.wheel_angles_rad)
        object.__setattr__(self, "wheel_angles_rad", angles)
        if len(angles) < 3:
            raise ValueError(f"wheel_angles_rad: need at least 3 wheels, got {len(angles)}")
        for f in fields(self):
            value = getattr(self, f.name)
            values = value if isinstance(value, tuple) else (value,)
            if not all(math.isfinite(v) for v in values):
                raise ValueError(f"{f.name}: must be finite, got {value!r}")
            if f.name not in ("wheel_angles_rad", "ambient_temperature_c") and value <= 0.0:
                raise ValueError(f"{f.name}: must be > 0, got {value!r}")
        if self.gear_efficiency > 1.0:
            raise ValueError(f"gear_efficiency: must be <= 1, got {self.gear_efficiency}")
        if self.winding_max_temperature_c <= self.ambient_temperature_c:
            raise ValueError("winding_max_temperature_c must exceed ambient_temperature_c")

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
        """Load a ROS 2 parameter file's ``robot.*`` parameters (the format of config/robot.yaml)."""
        data = yaml.safe_load(Path(path).read_text()) or {}
        for scope in data.values():  # "/**", or a node name
            params = (scope or {}).get("ros__parameters", {})
            if "robot" in params:
                return cls.from_dict(params["robot"])
        raise ValueError(f"{path}: no robot parameters (expected <node>: ros__parameters: robot: ...)")

    @classmethod
    def field_docs(cls) -> dict[str, str]:
        return {f.name: f.metadata.get("doc", "") for f in fields(cls)}


@dataclass(frozen=True)
class FieldConfig:
    """Playing surface; the field frame has its origin at the centre, x along the long side."""

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
