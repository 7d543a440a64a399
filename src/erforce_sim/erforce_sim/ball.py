"""Ball on the carpet from forces: the physics behind the paper's two-phase model (Sec. 5).

The ball is a sphere (radius r, mass m, inertia I = k m r^2; k = 2/5 solid, 2/3 hollow). Its state is
position, velocity and the angular velocity vector (wx, wy horizontal, wz vertical).

* Contact-point slip velocity:  s = v + w x (-r z) = (vx - r wy, vy + r wx).
* Sliding (|s| > 0): the carpet friction f = -mu_slide m g s/|s| acts on linear momentum
  (dv/dt = f/m, so the linear deceleration is exactly mu_slide g) and on angular momentum
  (dw/dt = (-r z) x f / I). Then ds/dt = f (1/m + r^2/I): s shrinks along its own direction.
* The slip vanishes on its own; the substep in which it would change sign is split and the friction
  impulse is cut to exactly the amount that zeroes the slip (implicit Coulomb friction).
  For a kick without spin this happens at v_switch / v_shoot = 1 / (1 + I/(m r^2)) = 5/7 (solid).
  A kick spin ratio s0 = w r / v (negative: backspin) gives v_switch/v_shoot = (m r^2/I + s0)/(m r^2/I + 1),
  e.g. s0 = -0.4 -> 0.6, the paper's measured c_switch.
* Rolling (s = 0): a constant rolling-resistance deceleration a_roll = mu_roll g along -v, the spin
  follows the velocity (no slip); below a_roll*h the ball stops exactly (no jitter at rest).

Defaults: mu_slide = 2.5/g and mu_roll = 0.3/g reproduce the paper's a_slide = 2.5 m/s^2 and
a_roll = 0.3 m/s^2. No rclpy import.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from erforce_interfaces.robot_config import BALL_INERTIA_FACTOR, BALL_RADIUS_M
from erforce_sim.drivetrain import GRAVITY_MPS2

# The paper's measured decelerations, in its sign (the two-phase model's a_slide, a_roll): the carpet's defaults.
A_SLIDE_MPS2 = -2.5
A_ROLL_MPS2 = -0.3


def _check_positive(name: str, value: float) -> None:
    if not (isinstance(value, int | float) and math.isfinite(value) and value > 0.0):
        raise ValueError(f"{name}: must be finite and > 0, got {value!r}")


@dataclass(frozen=True)
class BallParams:
    radius_m: float = BALL_RADIUS_M
    mass_kg: float = 0.046
    inertia_factor: float = BALL_INERTIA_FACTOR  # I = inertia_factor * m r^2 (0.4 solid sphere, 2/3 hollow sphere)
    mu_slide: float = -A_SLIDE_MPS2 / GRAVITY_MPS2  # sliding deceleration = mu_slide g = 2.5 m/s^2
    mu_roll: float = -A_ROLL_MPS2 / GRAVITY_MPS2  # rolling deceleration = mu_roll g = 0.3 m/s^2

    def __post_init__(self) -> None:
        for name in ("radius_m", "mass_kg", "inertia_factor", "mu_slide", "mu_roll"):
            _check_positive(name, getattr(self, name))

    @property
    def inertia_kgm2(self) -> float:
        return self.inertia_factor * self.mass_kg * self.radius_m**2

    @property
    def a_slide_mps2(self) -> float:
        return self.mu_slide * GRAVITY_MPS2

    @property
    def a_roll_mps2(self) -> float:
        return self.mu_roll * GRAVITY_MPS2

    @classmethod
    def from_model(cls, a_slide_mps2: float, a_roll_mps2: float) -> BallParams:
        """The carpet that gives the two-phase model's decelerations (the paper's sign: negative)."""
        return cls(mu_slide=-a_slide_mps2 / GRAVITY_MPS2, mu_roll=-a_roll_mps2 / GRAVITY_MPS2)

    def switch_ratio(self, spin_ratio: float = 0.0) -> float:
        """v_switch / v_shoot from momentum balance (closed form, for documentation and tests)."""
        q = 1.0 / self.inertia_factor  # m r^2 / I
        return (q + spin_ratio) / (q + 1.0)


@dataclass(frozen=True)
class BallState:
    """Ball ground truth in the field frame (SI). Angular velocity (wx, wy, wz) in rad/s."""

    x: float
    y: float
    vx: float = 0.0
    vy: float = 0.0
    wx: float = 0.0
    wy: float = 0.0
    wz: float = 0.0

    def __post_init__(self) -> None:
        for name in ("x", "y", "vx", "vy", "wx", "wy", "wz"):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and math.isfinite(v)):
                raise ValueError(f"BallState.{name}: must be a finite number, got {v!r}")

    @property
    def speed_mps(self) -> float:
        return math.hypot(self.vx, self.vy)


class BallBody:
    """Mutable ball state and its substep integrator (see module docstring)."""

    __slots__ = (
        "a_roll",
        "a_slide",
        "at_rest",
        "inertia",
        "mass",
        "radius",
        "slip_gain",
        "vx",
        "vy",
        "wx",
        "wy",
        "wz",
        "x",
        "y",
    )

    def __init__(self, params: BallParams, state: BallState) -> None:
        self.radius = params.radius_m
        self.mass = params.mass_kg
        self.inertia = params.inertia_kgm2
        self.a_slide = params.a_slide_mps2
        self.a_roll = params.a_roll_mps2
        self.slip_gain = 1.0 + self.mass * self.radius**2 / self.inertia  # d|s|/dt = -a_slide * slip_gain
        self.set_state(state)

    def set_state(self, s: BallState) -> None:
        self.x, self.y, self.vx, self.vy = float(s.x), float(s.y), float(s.vx), float(s.vy)
        self.wx, self.wy, self.wz = float(s.wx), float(s.wy), float(s.wz)
        self.at_rest = self.vx == 0.0 and self.vy == 0.0 and self.wx == 0.0 and self.wy == 0.0

    def state(self) -> BallState:
        return BallState(self.x, self.y, self.vx, self.vy, self.wx, self.wy, self.wz)

    def slip_mps(self) -> tuple[float, float]:
        return self.vx - self.radius * self.wy, self.vy + self.radius * self.wx

    def advance(self, m: int, h: float) -> None:
        """Advance m substeps of h seconds (sliding substep by substep, rolling in closed form)."""
        r = self.radius
        a_slide = self.a_slide
        dslip_max = a_slide * self.slip_gain * h
        mr_over_i = self.mass * r / self.inertia
        for j in range(m):
            if self.at_rest:
                return
            vx, vy = self.vx, self.vy
            sx = vx - r * self.wy
            sy = vy + r * self.wx
            slip = math.hypot(sx, sy)
            if slip <= 1e-12:
                self._roll((m - j) * h)
                return
            frac = 1.0 if slip > dslip_max else slip / dslip_max
            dv = a_slide * h * frac / slip  # friction impulse per unit mass and unit slip
            jx, jy = -dv * sx, -dv * sy
            vx += jx
            vy += jy
            self.wx += mr_over_i * jy
            self.wy -= mr_over_i * jx
            x0, y0, vx0, vy0 = self.x, self.y, self.vx, self.vy
            self.vx, self.vy = vx, vy
            if frac < 1.0:  # slip vanished inside this substep: roll for the rest of it
                self.x += 0.5 * (vx0 + vx) * h * frac
                self.y += 0.5 * (vy0 + vy) * h * frac
                self._roll(h * (1.0 - frac))
            else:
                self.x = x0 + 0.5 * (vx0 + vx) * h
                self.y = y0 + 0.5 * (vy0 + vy) * h

    def _roll(self, duration_s: float) -> None:
        """Pure rolling for duration_s: constant deceleration a_roll along -v, spin follows v, exact stop."""
        vx, vy = self.vx, self.vy
        speed = math.hypot(vx, vy)
        dec = self.a_roll * duration_s
        if speed <= dec:
            if speed > 0.0:
                travel = 0.5 * speed * speed / self.a_roll
                self.x += vx / speed * travel
                self.y += vy / speed * travel
            self.vx = self.vy = self.wx = self.wy = 0.0
            self.at_rest = True
            return
        scale = (speed - dec) / speed
        mean = 0.5 * (1.0 + scale) * duration_s
        self.x += vx * mean
        self.y += vy * mean
        self.vx, self.vy = vx * scale, vy * scale
        self.wx = -self.vy / self.radius
        self.wy = self.vx / self.radius

    def kinetic_energy_j(self) -> float:
        return 0.5 * self.mass * (self.vx**2 + self.vy**2) + 0.5 * self.inertia * (self.wx**2 + self.wy**2 + self.wz**2)
