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


@dataclass(frozen=True)
class RobotConfig:
    """Geometry, inertia and drive train of one omni-wheel SSL robot."""

    wheel_angles_rad: tuple[float, ...] = field(default_factory=_default_wheel_angles)
    wheel_radius_m: float = 0.0275
    wheel_distance_m: float = 0.081  # robot centre to wheel contact point
    robot_radius_m: float = 0.09
    mass_kg: float = 2.6
    inertia_kgm2: float = 0.011  # about z through the centre of mass
    dribbler_offset_m: float = 0.0815  # robot centre to ball centre when the ball touches the dribbler
    dribbler_width_m: float = 0.07  # usable width of the dribbler / kicker plate
    traction_mu: float = 0.8  # wheel-carpet friction coefficient

    # Drive train: Maxon EC-45 flat 50 W class motor behind a spur gear.
    gear_ratio: float = 3.6  # motor revolutions per wheel revolution
    gear_efficiency: float = 0.9
    motor_resistance_ohm: float = 0.94
    motor_inductance_h: float = 0.36e-3
    motor_torque_constant_nm_per_a: float = 0.036  # equals the back-EMF constant in V*s/rad
    motor_rotor_inertia_kgm2: float = 1.35e-5
    wheel_inertia_kgm2: float = 2.0e-5  # wheel with rollers, about its axle
    motor_viscous_friction_nms: float = 2.0e-6  # at the motor shaft
    motor_coulomb_friction_nm: float = 1.5e-3  # at the motor shaft
    supply_voltage_v: float = 24.0
    winding_thermal_time_constant_s: float = 29.0
    winding_thermal_resistance_k_per_w: float = 1.9  # winding to housing
    winding_max_temperature_c: float = 125.0
    ambient_temperature_c: float = 25.0
    continuous_current_limit_a: float = 1.3  # the paper's average-current limit

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
        """Load ``robot:`` from a YAML file (the format of config/robot.yaml)."""
        data = yaml.safe_load(Path(path).read_text()) or {}
        return cls.from_dict(data.get("robot", data))


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
