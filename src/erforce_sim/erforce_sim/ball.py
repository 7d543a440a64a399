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

In the air (after a chip, ``z`` > 0 or ``vz`` > 0; z is the centre's height above where it rests): a
projectile under gravity, no drag, spin kept, each substep in closed form and split at the touchdown.
At a touchdown the vertical speed is reversed and scaled by ``floor_restitution``; the carpet's Coulomb
friction impulse (at most ``floor_friction`` times the normal impulse, at most the sticking value) acts
on the contact point's slip like the sliding friction above: a ball without spin loses 1 - 1/(1 + I/(m r^2))
of its speed (2/7, solid) at the first bounce, a ball spun up to rolling none. A bounce leaving less than
``LANDED_VZ_MPS`` upwards ends the flight: the ball goes on on the carpet as above.

Defaults: mu_slide = 2.5/g and mu_roll = 0.3/g reproduce the paper's a_slide = 2.5 m/s^2 and
a_roll = 0.3 m/s^2. No rclpy import.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from erforce_interfaces.wire.robot_config import (
    BALL_A_ROLL_MPS2,
    BALL_A_SLIDE_MPS2,
    BALL_CHIP_DAMPING_Z,
    BALL_CHIP_MIN_HOP_VZ_MPS,
    BALL_INERTIA_FACTOR,
    BALL_RADIUS_M,
    GRAVITY_MPS2,
)


def _check_positive(name: str, value: float) -> None:
    if not (isinstance(value, int | float) and math.isfinite(value) and value > 0.0):
        raise ValueError(f"{name}: must be finite and > 0, got {value!r}")


@dataclass(frozen=True)
class BallParams:
    radius_m: float = BALL_RADIUS_M
    mass_kg: float = 0.046
    inertia_factor: float = BALL_INERTIA_FACTOR  # I = inertia_factor * m r^2 (0.4 solid sphere, 2/3 hollow sphere)
    mu_slide: float = -BALL_A_SLIDE_MPS2 / GRAVITY_MPS2  # sliding deceleration = mu_slide g = 2.5 m/s^2
    mu_roll: float = -BALL_A_ROLL_MPS2 / GRAVITY_MPS2  # rolling deceleration = mu_roll g = 0.3 m/s^2

    def __post_init__(self) -> None:
        for name in ("radius_m", "mass_kg", "inertia_factor", "mu_slide", "mu_roll"):
            _check_positive(name, getattr(self, name))
        for name in ("floor_restitution", "floor_friction"):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and math.isfinite(v) and v >= 0.0):
                raise ValueError(f"{name}: must be finite and >= 0, got {v!r}")
        if self.floor_restitution >= 1.0:
            raise ValueError(f"floor_restitution: must be < 1 (the hops end), got {self.floor_restitution!r}")

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

    # Bounces of a ball in the air (chip kicks): fields like those above, declared here.
    floor_restitution: float = BALL_CHIP_DAMPING_Z  # vertical speed kept at a bounce on the carpet
    floor_friction: float = 0.5  # Coulomb friction of a bounce (enough to stop a 60 deg chip's slip)


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
    z: float = 0.0  # height of the centre above where it rests on the carpet (> 0 in the air)
    vz: float = 0.0

    def __post_init__(self) -> None:
        for name in ("x", "y", "vx", "vy", "wx", "wy", "wz", "z", "vz"):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and math.isfinite(v)):
                raise ValueError(f"BallState.{name}: must be a finite number, got {v!r}")
        if self.z < 0.0:
            raise ValueError(f"BallState.z: must be >= 0 (the carpet), got {self.z!r}")

    @property
    def speed_mps(self) -> float:
        return math.hypot(self.vx, self.vy)


LANDED_VZ_MPS = BALL_CHIP_MIN_HOP_VZ_MPS  # a bounce leaving less than this upwards (a 0.1 mm hop) ends the flight


class BallBody:
    """Mutable ball state and its substep integrator (see module docstring)."""

    __slots__ = (
        "a_roll",
        "a_slide",
        "airborne",
        "at_rest",
        "floor_friction",
        "floor_restitution",
        "g",
        "inertia",
        "mass",
        "radius",
        "slip_gain",
        "vx",
        "vy",
        "vz",
        "wx",
        "wy",
        "wz",
        "x",
        "y",
        "z",
    )

    def __init__(self, params: BallParams, state: BallState) -> None:
        self.radius = params.radius_m
        self.mass = params.mass_kg
        self.inertia = params.inertia_kgm2
        self.a_slide = params.a_slide_mps2
        self.a_roll = params.a_roll_mps2
        self.slip_gain = 1.0 + self.mass * self.radius**2 / self.inertia  # d|s|/dt = -a_slide * slip_gain
        self.g = GRAVITY_MPS2
        self.floor_restitution = params.floor_restitution
        self.floor_friction = params.floor_friction
        self.set_state(state)

    def set_state(self, s: BallState) -> None:
        self.x, self.y, self.vx, self.vy = float(s.x), float(s.y), float(s.vx), float(s.vy)
        self.wx, self.wy, self.wz = float(s.wx), float(s.wy), float(s.wz)
        self.z, self.vz = float(s.z), float(s.vz)
        self.airborne = self.z > 0.0 or self.vz > 0.0
        self.at_rest = self.vx == 0.0 and self.vy == 0.0 and self.wx == 0.0 and self.wy == 0.0 and not self.airborne

    def state(self) -> BallState:
        return BallState(self.x, self.y, self.vx, self.vy, self.wx, self.wy, self.wz, self.z, self.vz)

    def launch(self, vx: float, vy: float, vz: float) -> None:
        """Give the ball the velocity ``(vx, vy, vz)`` (a kick); ``vz`` > 0 lifts it off the carpet."""
        self.vx, self.vy = vx, vy
        if vz > 0.0:
            self.vz = vz
            self.airborne = True
        self.at_rest = False

    def slip_mps(self) -> tuple[float, float]:
        return self.vx - self.radius * self.wy, self.vy + self.radius * self.wx

    def advance(self, m: int, h: float) -> None:
        """Advance m substeps of h seconds (sliding substep by substep, rolling in closed form)."""
        r = self.radius
        a_slide = self.a_slide
        dslip_max = a_slide * self.slip_gain * h
        mr_over_i = self.mass * r / self.inertia
        for j in range(m):
            if self.airborne:
                landed = self._fly(m - j, h)
                if landed is None:
                    return
                used, rest_s = landed
                self.advance(1, rest_s)  # the rest of the landing substep on the carpet
                if j + used < m:
                    self.advance(m - j - used, h)
                return
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

    def _fly(self, m: int, h: float) -> tuple[int, float] | None:
        """m substeps of h in the air, or until it lands: then (substeps begun, the rest of the last one in s).

        Flight is exact (constant gravity); a substep that reaches the carpet is split at the touchdown.
        """
        g = self.g
        for k in range(m):
            vz, z = self.vz, self.z
            z_end = z + h * (vz - 0.5 * g * h)
            if z_end > 0.0:
                self.x += self.vx * h
                self.y += self.vy * h
                self.z, self.vz = z_end, vz - g * h
                continue
            v_land = math.sqrt(vz * vz + 2.0 * g * z)
            tau = min((vz + v_land) / g, h)
            self.x += self.vx * tau
            self.y += self.vy * tau
            self.z = 0.0
            self._bounce(v_land)
            if not self.airborne:
                return k + 1, h - tau
            rest = h - tau  # the new hop for the rest of this substep
            self.x += self.vx * rest
            self.y += self.vy * rest
            self.z, self.vz = self.vz * rest - 0.5 * g * rest * rest, self.vz - g * rest
            if self.z <= 0.0:  # a hop shorter than the rest of a substep: it has landed
                self.z = self.vz = 0.0
                self.airborne = False
                return k + 1, 0.0
        return None

    def _bounce(self, v_land: float) -> None:
        """Touchdown at ``v_land`` downwards: restitution on vz, Coulomb friction on the contact point's slip."""
        jn = (1.0 + self.floor_restitution) * v_land  # normal impulse per unit mass
        sx, sy = self.slip_mps()
        slip = math.hypot(sx, sy)
        if slip > 1e-12:
            dv = min(self.floor_friction * jn, slip / self.slip_gain) / slip
            jx, jy = -dv * sx, -dv * sy
            mr_over_i = self.mass * self.radius / self.inertia
            self.vx += jx
            self.vy += jy
            self.wx += mr_over_i * jy
            self.wy -= mr_over_i * jx
        self.vz = self.floor_restitution * v_land
        if self.vz < LANDED_VZ_MPS:
            self.vz = 0.0
            self.airborne = False

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
        """Translation and rotation, plus the height's potential energy in the air (a bounce only loses)."""
        return (0.5 * self.mass * (self.vx**2 + self.vy**2 + self.vz**2) + self.mass * self.g * self.z
                + 0.5 * self.inertia * (self.wx**2 + self.wy**2 + self.wz**2))
