"""The simulated world's small immutable values: what a ``World`` is built from (``RobotSpec``, one robot to
simulate; ``PhysicsParams``) and what it reports (``RobotState``, ``KickResult``, ``EnergyBreakdown``), with the
input checks they share with it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from erforce_interfaces.runtime.param_schema import check_finite_fields, schema_defaults
from erforce_interfaces.wire.robot_config import RobotConfig
from erforce_sim.contacts import ContactParams
from erforce_sim.kicker import DEFAULT_TILT_COMPLIANCE_RAD_PER_M

__all__ = ["EnergyBreakdown", "KickResult", "PhysicsParams", "RobotSpec", "RobotState", "bounded", "finite"]

_PLANT = schema_defaults("erforce_sim", "plant")  # the plant node's defaults


def finite(name: str, value: float) -> float:
    """``value`` as a float; a ValueError naming ``name`` when it is not a finite number."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: must be a number, got {value!r}") from None
    if not math.isfinite(v):
        raise ValueError(f"{name}: must be finite, got {value!r}")
    return v


def bounded(name: str, value: float, limit: float) -> float:
    """``finite`` and at most ``limit`` in magnitude (a plausibility bound)."""
    v = finite(name, value)
    if abs(v) > limit:
        raise ValueError(f"{name}: |{v}| exceeds the plausible limit {limit}")
    return v


@dataclass(frozen=True)
class RobotSpec:
    """One robot to simulate: its description, initial pose, identity and kicker plate."""

    config: RobotConfig = field(default_factory=RobotConfig)
    x: float = 0.0
    y: float = 0.0
    theta: float = 0.0
    team: str = "yellow"
    robot_id: int = 0
    kicker_plate: str = "flat"  # 'flat' | 'curved'

    def __post_init__(self) -> None:
        if not isinstance(self.config, RobotConfig):
            raise ValueError(f"RobotSpec.config: must be a RobotConfig, got {type(self.config).__name__}")
        for name in ("x", "y", "theta"):
            finite(f"RobotSpec.{name}", getattr(self, name))
        if self.team not in ("yellow", "blue"):
            raise ValueError(f"RobotSpec.team: must be 'yellow' or 'blue', got {self.team!r}")
        if not isinstance(self.robot_id, int) or self.robot_id < 0:
            raise ValueError(f"RobotSpec.robot_id: must be an int >= 0, got {self.robot_id!r}")
        if self.kicker_plate not in ("flat", "curved"):
            raise ValueError(f"RobotSpec.kicker_plate: must be 'flat' or 'curved', got {self.kicker_plate!r}")


@dataclass(frozen=True)
class PhysicsParams:
    substep_hz: float = _PLANT["substep_hz"]  # motor/body/ball substep rate (>= 10 kHz; exact-exponential electrics)
    traction_damping_nspm: float = 300.0  # slip-velocity force law, clipped at mu N
    coulomb_smoothing_radps: float = 1.0  # motor-shaft speed over which Coulomb friction ramps in
    contacts: ContactParams = field(default_factory=ContactParams)
    kick_max_speed_mps: float = 8.0  # kicks above this are clamped (and reported)
    # default w r / v after a kick; < 0 backspin: -0.4 gives the paper's c_switch 0.6
    kick_spin_ratio: float = _PLANT["kick_spin_ratio"]
    kick_tilt_compliance_rad_per_m: float = DEFAULT_TILT_COMPLIANCE_RAD_PER_M  # plunger bending
    kick_touch_tolerance_m: float = 0.005  # ball surface to front face gap that still counts as touching
    dribbler_time_constant_s: float = 0.005  # ball velocity relaxes to the bar's velocity when dribbling
    dribbler_pull_mps2: float = 2.0  # dribbler pulls the touching ball towards the robot
    wheel_speed_noise_radps: float = 0.0  # motor-board sensor noise (std), default off
    current_noise_a: float = 0.0
    max_step_s: float = 0.1

    def __post_init__(self) -> None:
        check_finite_fields(self, ("substep_hz",), 10000.0, 1e6)
        check_finite_fields(self, ("traction_damping_nspm", "coulomb_smoothing_radps", "kick_max_speed_mps",
                                   "kick_tilt_compliance_rad_per_m", "kick_touch_tolerance_m",
                                   "dribbler_time_constant_s", "max_step_s"), 0.0, lower_open=True)
        check_finite_fields(self, ("wheel_speed_noise_radps", "current_noise_a", "dribbler_pull_mps2"), 0.0)
        check_finite_fields(self, ("kick_spin_ratio",), -1.0, 1.0)


@dataclass(frozen=True)
class RobotState:
    """Ground truth of one robot: pose and velocity in the field frame, drive train per wheel."""

    x: float
    y: float
    theta: float
    vx: float
    vy: float
    w: float
    wheel_speeds_radps: tuple[float, ...]
    currents_a: tuple[float, ...]
    winding_temperatures_c: tuple[float, ...]


@dataclass(frozen=True)
class KickResult:
    fired: bool  # the ball was in the dribbler region and got kicked
    armed: bool  # not fired yet, waiting for the ball (armed_for_s > 0)
    speed_mps: float  # kick speed actually used (after clamping)
    clamped: bool  # the requested speed exceeded kick_max_speed_mps
    offset_m: float = 0.0  # lateral ball offset on the plate (base_link y), when fired
    deviation_rad: float = 0.0  # kick direction relative to the robot heading, when fired


@dataclass(frozen=True)
class EnergyBreakdown:
    bodies_j: float  # robot translation + rotation
    wheels_j: float  # wheel + reflected rotor rotation
    magnetic_j: float  # 1/2 L i^2 of all windings
    ball_j: float  # ball translation + rotation

    @property
    def total_j(self) -> float:
        return self.bodies_j + self.wheels_j + self.magnetic_j + self.ball_j
