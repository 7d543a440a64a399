"""Kicker plates (paper Sec. 2.2) and the linear light barrier (paper Sec. 3).

Flat plate, physically inspired model of the paper's observation: an off-centre ball puts a torque on
the plunger; the plunger assembly bends elastically and the plate tilts by

    alpha = compliance * arm,   arm = moment arm of the contact force about the plunger axis,

and the ball leaves along the tilted plate normal. For the flat plate arm = lateral contact offset y,
so the deviation is linear in the offset, pointing outward (towards the side the ball sits on). The
compliance is calibrated to the paper's measurement: 12 deg at 3 cm  ->  4 deg/cm (6.98 rad/m),
independent of kick speed (the paper gives one number; we assume the bending scales with the kick).

Curved (concave) plate: the surface x = f(y) is computed (`KickerPlate.curved`) so that the local
surface normal angle phi(y) cancels the bending tilt for every contact point:

    phi(y) + compliance * (y cos phi - f(y) sin phi) = 0,   f'(y) = -tan phi(y),   f(0) = 0,

integrated outward from the centre. The ball touches the concave plate where the normal passes through
its centre (solved by fixed-point iteration); the residual deviation comes from the tabulated shape
and from any mismatch between the robot's real compliance and the design compliance.

Light barrier: a linear beam across the dribbler opening at depth `beam_depth_m` in front of the
front face (x = front_x + depth in base_link), spanning the dribbler width; the ball is seen when its
circle intersects the beam segment. No rclpy import.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np

from erforce_interfaces.runtime.numba_support import numba
from erforce_interfaces.wire.robot_config import BALL_RADIUS_M

FLAT_DEVIATION_DEG_AT_3CM = 12.0  # paper Sec. 2.2
DEFAULT_TILT_COMPLIANCE_RAD_PER_M = math.radians(FLAT_DEVIATION_DEG_AT_3CM) / 0.03


@dataclass(frozen=True)
class KickerPlate:
    """A kicker plate shape: 'flat' or 'curved' (designed for ``design_compliance_rad_per_m``)."""

    kind: str
    half_width_m: float
    design_compliance_rad_per_m: float = DEFAULT_TILT_COMPLIANCE_RAD_PER_M
    # curved plate table: y grid, surface depth f(y) (+x forward), normal angle phi(y)
    y_table: np.ndarray = field(default=None, repr=False, compare=False)
    f_table: np.ndarray = field(default=None, repr=False, compare=False)
    phi_table: np.ndarray = field(default=None, repr=False, compare=False)

    def __post_init__(self) -> None:
        if self.kind not in ("flat", "curved"):
            raise ValueError(f"kicker plate must be 'flat' or 'curved', got {self.kind!r}")
        for name in ("half_width_m", "design_compliance_rad_per_m"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0.0):
                raise ValueError(f"KickerPlate.{name}: must be finite and > 0, got {v!r}")
        if self.kind == "curved" and self.y_table is None:
            y, f, phi = _design_curved(self.half_width_m * 1.6, self.design_compliance_rad_per_m)
            object.__setattr__(self, "y_table", y)
            object.__setattr__(self, "f_table", f)
            object.__setattr__(self, "phi_table", phi)

    @classmethod
    def make(
        cls, kind: str, half_width_m: float, design_compliance_rad_per_m: float = DEFAULT_TILT_COMPLIANCE_RAD_PER_M
    ) -> KickerPlate:
        return cls(kind=kind, half_width_m=half_width_m, design_compliance_rad_per_m=design_compliance_rad_per_m)

    def surface(self, y_m: float) -> tuple[float, float]:
        """(f(y), phi(y)): surface depth ahead of the plate centre and normal angle at lateral y."""
        if self.kind == "flat":
            return 0.0, 0.0
        return (
            float(np.interp(y_m, self.y_table, self.f_table)),
            float(np.interp(y_m, self.y_table, self.phi_table)),
        )

    def contact_offset_m(self, ball_offset_m: float, ball_radius_m: float) -> float:
        """Lateral contact point for a ball whose centre sits ``ball_offset_m`` left of the plate axis."""
        yc = ball_offset_m
        if self.kind == "flat":
            return yc
        for _ in range(30):  # contraction factor ~ r*compliance ~ 0.15
            _, phi = self.surface(yc)
            y_new = ball_offset_m - ball_radius_m * math.sin(phi)
            if abs(y_new - yc) < 1e-12:
                return y_new
            yc = y_new
        return yc

    def deviation_rad(
        self, ball_offset_m: float, ball_radius_m: float, compliance_rad_per_m: float | None = None
    ) -> float:
        """Kick direction relative to the robot heading (positive = counter-clockwise)."""
        if not math.isfinite(ball_offset_m):
            raise ValueError(f"ball_offset_m: must be finite, got {ball_offset_m!r}")
        k = self.design_compliance_rad_per_m if compliance_rad_per_m is None else compliance_rad_per_m
        yc = self.contact_offset_m(ball_offset_m, ball_radius_m)
        f, phi = self.surface(yc)
        arm = yc * math.cos(phi) - f * math.sin(phi)
        return phi + k * arm


@functools.cache
def _design_curved(y_max: float, compliance: float, n: int = 1201) -> tuple[np.ndarray, ...]:
    """Integrate the concave plate shape outward from the centre (see module docstring). Once per design: every
    robot of a team has the same plate, and 14 designs were most of a restarted plant's construction (~1 s of
    CPU); the tables are shared, so they are read-only."""
    ys = np.linspace(0.0, y_max, n)
    f = np.zeros(n)
    phi = np.zeros(n)

    def solve_phi(y: float, fy: float) -> float:
        p = -compliance * y
        for _ in range(50):
            p_new = -compliance * (y * math.cos(p) - fy * math.sin(p))
            if abs(p_new - p) < 1e-15:
                break
            p = p_new
        return p

    dy = ys[1] - ys[0]
    for j in range(1, n):
        # midpoint (RK2) step of f' = -tan(phi(y, f))
        p0 = solve_phi(ys[j - 1], f[j - 1])
        f_mid = f[j - 1] - 0.5 * dy * math.tan(p0)
        p_mid = solve_phi(ys[j - 1] + 0.5 * dy, f_mid)
        f[j] = f[j - 1] - dy * math.tan(p_mid)
        phi[j] = solve_phi(ys[j], f[j])
    # symmetric plate: f even, phi odd
    y_full = np.concatenate((-ys[:0:-1], ys))
    f_full = np.concatenate((f[:0:-1], f))
    phi_full = np.concatenate((-phi[:0:-1], phi))
    for table in (y_full, f_full, phi_full):
        table.flags.writeable = False
    return y_full, f_full, phi_full


def deviation_table(
    offsets_m: list[float] | np.ndarray, half_width_m: float = 0.035, ball_radius_m: float = BALL_RADIUS_M
) -> list[tuple[float, float, float]]:
    """Rows (offset_m, flat_deviation_deg, curved_deviation_deg) for the bench and the docs."""
    flat = KickerPlate.make("flat", half_width_m)
    curved = KickerPlate.make("curved", half_width_m)
    return [
        (
            float(o),
            math.degrees(flat.deviation_rad(float(o), ball_radius_m)),
            math.degrees(curved.deviation_rad(float(o), ball_radius_m)),
        )
        for o in offsets_m
    ]


def beam_hit(ball_x_m: float, ball_y_m: float, ball_radius_m: float, beam_x_m: float, half_span_m: float) -> bool:
    """True when the ball circle (base_link centre) intersects the beam segment x = beam_x, |y| <= half_span."""
    dx = ball_x_m - beam_x_m
    if abs(dx) >= ball_radius_m:
        return False
    half_chord = math.sqrt(ball_radius_m * ball_radius_m - dx * dx)
    return abs(ball_y_m) - half_chord <= half_span_m


@numba.njit(cache=True, error_model="numpy")
def beam_hits(body, bx, by, r, beam_x, half_span):
    """kicker.beam_hit of the ball in every robot's frame (World._ball_in_robot_frame), per robot."""
    n = body.shape[0]
    out = np.zeros(n, dtype=np.bool_)
    for i in range(n):
        dx, dy = bx - body[i, 0], by - body[i, 1]
        ct, st = body[i, 3], body[i, 4]
        px = ct * dx + st * dy
        py = -st * dx + ct * dy
        ddx = px - beam_x[i]
        if abs(ddx) < r:
            out[i] = abs(py) - math.sqrt(r * r - ddx * ddx) <= half_span[i]
    return out
