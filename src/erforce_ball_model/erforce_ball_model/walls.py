"""The field walls as a ball's centre meets them, and the impulse a wall gives the ball (beyond the paper):
what ``BallTrajectory`` (ball_model) bounces the ball's path off, the simulator's wall contact as a value.
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from erforce_interfaces.wire.robot_config import (
    BALL_INERTIA_FACTOR,
    BALL_RADIUS_M,
    BALL_WALL_FRICTION,
    BALL_WALL_RESTITUTION,
    FieldConfig,
)

__all__ = ["Walls"]

_NUMBER = int | float | np.floating | np.integer


@dataclass(frozen=True)
class Walls:
    """The field walls as the ball's centre meets them, and how the ball bounces off them.

    The centre stays in ``|x| <= half_x_m``, ``|y| <= half_y_m``: the walls' inner faces (half the field's
    length and width plus the run-off area, FieldConfig.wall_half_*) less the ball's radius. At a wall the
    ball gets the impulse of a rigid wall with restitution and Coulomb friction (the simulator's contact
    model, erforce_sim.contacts): its speed normal to the wall reversed and scaled by ``restitution``
    (0: it stays at the wall), its speed along the wall cut by ``friction`` times the normal impulse, at most
    to the sticking value. The impulse acts at the ball's equator and leaves its rolling spin as it was, so
    the ball leaves the wall sliding on the carpet (``BallTrajectory`` says how it goes on).
    """

    half_x_m: float
    half_y_m: float
    restitution: float = BALL_WALL_RESTITUTION
    friction: float = BALL_WALL_FRICTION
    inertia_factor: float = BALL_INERTIA_FACTOR  # I = k m r^2 of the ball: sets the slide after the bounce

    def __post_init__(self) -> None:
        for name in ("half_x_m", "half_y_m", "restitution", "friction", "inertia_factor"):
            value = getattr(self, name)
            if not isinstance(value, _NUMBER) or not math.isfinite(value):
                raise ValueError(f"Walls.{name}: must be a finite number, got {value!r}")
            object.__setattr__(self, name, float(value))
        if min(self.half_x_m, self.half_y_m) <= 0.0:
            raise ValueError(f"Walls: half extents must be > 0, got {self.half_x_m}, {self.half_y_m}")
        if not 0.0 <= self.restitution <= 1.0:
            raise ValueError(f"Walls.restitution: must be in [0, 1], got {self.restitution}")
        if self.friction < 0.0 or self.inertia_factor <= 0.0:
            raise ValueError(f"Walls: friction >= 0 and inertia_factor > 0, got {self.friction}, "
                             f"{self.inertia_factor}")

    @classmethod
    def of_field(cls, field: FieldConfig, restitution: float = BALL_WALL_RESTITUTION) -> Walls:
        """The walls of ``field`` (at its run-off area's outer edge) for a ball of the league's size."""
        if not isinstance(field, FieldConfig):
            raise ValueError(f"field: expected FieldConfig, got {type(field).__name__}")
        return _walls_of_field(cls, field, restitution)

    def first_hit(self, x_m: float, y_m: float, ux: float, uy: float) -> tuple[float, float, float] | None:
        """(distance along the line, inward normal) of the first wall the line from ``(x_m, y_m)`` along the unit
        vector ``(ux, uy)`` meets going forward, or None."""
        best = None
        for p, u, h, axis in ((x_m, ux, self.half_x_m, 0), (y_m, uy, self.half_y_m, 1)):
            if abs(u) <= 1e-12:  # along this wall (the bounce leaves exactly 0 there)
                continue
            d = max(((h if u > 0.0 else -h) - p) / u, 0.0)
            if best is None or d < best[0]:
                n = -1.0 if u > 0.0 else 1.0
                best = (d, n, 0.0) if axis == 0 else (d, 0.0, n)
        return best

    def impulse(self, vx: float, vy: float, nx: float, ny: float) -> tuple[float, float]:
        """The ball's velocity just after it meets the wall of inward normal ``(nx, ny)`` at ``(vx, vy)``."""
        vn = vx * nx + vy * ny
        if vn >= 0.0:
            return vx, vy
        jn = -(1.0 + self.restitution) * vn  # per unit mass
        tx, ty = -ny, nx
        # sticking would stop the contact point's slip along the wall: 1 / (1/m + r^2/I) per unit mass
        jt = -(vx * tx + vy * ty) / (1.0 + 1.0 / self.inertia_factor)
        limit = self.friction * jn
        jt = max(-limit, min(limit, jt))
        return vx + jn * nx + jt * tx, vy + jn * ny + jt * ty


@functools.lru_cache(maxsize=16)
def _walls_of_field(cls, field: FieldConfig, restitution: float) -> Walls:
    """Walls.of_field, built once per field (a predictor asks every frame)."""
    return cls(field.wall_half_length_m - BALL_RADIUS_M, field.wall_half_width_m - BALL_RADIUS_M, restitution)
