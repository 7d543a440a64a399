"""Two-phase ball model (ER-Force ETDP 2016, Sec. 5.1, 5.2 and 5.4).

A kicked ball first *slides* with the large deceleration ``a_slide`` until its speed has
dropped to ``v_switch = c_switch * v_shoot``; from then on it *rolls* with the small
deceleration ``a_roll`` until it stops (paper Fig. 5). The ball moves on a straight line.

Everything below is derived from these kinematics, not transcribed from the paper's
Algorithm 1 (which uses ``v_current`` instead of ``v_switch`` in the roll-phase quadratic
and writes the decelerations in m/s). With ``s0`` the current speed and
``v_sw = min(s0, c_switch * max(v_shoot, s0))``::

    t_switch = (s0 - v_sw) / |a_slide|          (0 when the ball already rolls)
    t_stop   = t_switch + v_sw / |a_roll|
    d(t)     = s0*ts + a_slide*ts^2/2 + v_sw*tr + a_roll*tr^2/2
               with ts = min(t, t_switch), tr = min(t, t_stop) - ts

``BallTrajectory`` is an immutable value (the ball's future) with closed-form queries
(``position_at`` is the paper's ballAtTime, ``time_to_distance`` is ballRollTime). It holds
one ball (position shape ``(2,)``) or a batch (shape ``(..., 2)``); queries broadcast as an
outer product: a query array of shape ``S`` returns shape ``batch + S`` (plus a trailing 2 for
vectors), so many balls x many times need no Python loop.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from erforce_interfaces.robot_config import FieldConfig

__all__ = ["MAX_POSITION_M", "MAX_SPEED_MPS", "BallFloats", "BallModelParams", "BallPhase", "BallTrajectory"]

# Sanity bounds: far beyond any SSL ball (6.5 m/s kick limit, 12 m field), they only catch garbage
# (unit mix-ups, uninitialized memory) before it overflows the arithmetic.
MAX_SPEED_MPS = 100.0
MAX_POSITION_M = 1e4


class BallPhase(enum.IntEnum):
    SLIDING = 0
    ROLLING = 1
    STOPPED = 2


@dataclass(frozen=True)
class BallModelParams:
    """Decelerations (m/s^2, negative) and the slide-to-roll speed ratio (paper Sec. 5.2)."""

    a_slide_mps2: float = -2.5
    a_roll_mps2: float = -0.3
    c_switch: float = 0.6

    def __post_init__(self) -> None:
        for name in ("a_slide_mps2", "a_roll_mps2", "c_switch"):
            value = getattr(self, name)
            if not isinstance(value, int | float | np.floating | np.integer) or not math.isfinite(value):
                raise ValueError(f"{name}: must be a finite number, got {value!r}")
            object.__setattr__(self, name, float(value))
        if self.a_slide_mps2 >= 0.0 or self.a_roll_mps2 >= 0.0:
            raise ValueError(
                f"decelerations must be < 0, got a_slide={self.a_slide_mps2}, a_roll={self.a_roll_mps2}"
            )
        if abs(self.a_slide_mps2) <= abs(self.a_roll_mps2):
            raise ValueError(
                f"|a_slide| must exceed |a_roll|, got a_slide={self.a_slide_mps2}, a_roll={self.a_roll_mps2}"
            )
        if not 0.0 < self.c_switch <= 1.0:
            raise ValueError(f"c_switch: must be in (0, 1], got {self.c_switch}")


def _as_finite(name: str, value, *, allow_inf: bool = False) -> np.ndarray:
    arr = np.asarray(value, dtype=float)
    if np.isnan(arr).any() or (not allow_inf and np.isinf(arr).any()):
        raise ValueError(f"{name}: must be finite, got {value!r}")
    return arr


_NUMBER = int | float | np.floating | np.integer


def _is_pair(value) -> bool:
    """One 2-vector (tuple, list or shape-(2,) array): the one-ball case."""
    if isinstance(value, np.ndarray):
        return value.shape == (2,)
    return isinstance(value, tuple | list) and len(value) == 2 and all(isinstance(v, _NUMBER) for v in value)


def _read_only(value) -> np.ndarray:
    a = np.array(value, dtype=float)
    a.setflags(write=False)
    return a


class BallFloats(NamedTuple):
    """A one-ball trajectory's numbers as plain floats, for scalar code and compiled kernels."""

    x_m: float
    y_m: float
    vx_mps: float
    vy_mps: float
    ux: float  # unit direction of motion ((0, 0) at rest)
    uy: float
    v_shoot_mps: float
    speed_mps: float
    v_switch_mps: float
    switch_time_s: float
    switch_distance_m: float
    stop_time_s: float
    stop_distance_m: float


class _BallArray:
    """A read-only array attribute of BallTrajectory; for one ball made from ``floats`` on first access."""

    def __init__(self, index: int | slice) -> None:
        self.index = index

    def __set_name__(self, owner, name: str) -> None:
        self.name = name

    def __get__(self, obj, owner=None):
        if obj is None:
            return self
        arrays = obj._arrays
        value = arrays.get(self.name)
        if value is None:
            value = arrays[self.name] = _read_only(obj.floats[self.index])
        return value


class BallTrajectory:
    """The future of one ball (or a batch of balls) under the two-phase model. Immutable.

    ``v_shoot_mps`` is the tracked kick speed; when it is below the current speed it is raised
    to the current speed (the ball cannot be faster than it was kicked). When the current speed
    is at most ``c_switch * v_shoot`` the ball already rolls.

    For one ball the numbers live in ``floats`` (BallFloats) and the array attributes are made
    on first access: the predictor builds two trajectories per vision frame and reads them in
    scalar code, where making ten arrays would cost more than all of its arithmetic. A batch
    has ``floats`` None.
    """

    __slots__ = ("_arrays", "floats", "params")

    # In BallFloats order; a batch stores them in _arrays at construction.
    position_m = _BallArray(slice(0, 2))
    velocity_mps = _BallArray(slice(2, 4))
    direction = _BallArray(slice(4, 6))  # unit vector of motion, zero at rest
    v_shoot_mps = _BallArray(6)
    speed_mps = _BallArray(7)
    v_switch_mps = _BallArray(8)
    switch_time_s = _BallArray(9)
    switch_distance_m = _BallArray(10)
    stop_time_s = _BallArray(11)
    stop_distance_m = _BallArray(12)

    def __init__(self, position_m, velocity_mps, v_shoot_mps, params: BallModelParams | None = None) -> None:
        params = BallModelParams() if params is None else params
        if not isinstance(params, BallModelParams):
            raise ValueError(f"params: expected BallModelParams, got {type(params).__name__}")
        init = object.__setattr__
        init(self, "params", params)
        init(self, "_arrays", {})
        one_ball = _is_pair(position_m) and _is_pair(velocity_mps) and (
            isinstance(v_shoot_mps, _NUMBER) or (isinstance(v_shoot_mps, np.ndarray) and v_shoot_mps.ndim == 0))
        init(self, "floats", self._one_ball(position_m, velocity_mps, v_shoot_mps) if one_ball else None)
        if not one_ball:
            self._batch(position_m, velocity_mps, v_shoot_mps)

    def __setattr__(self, name, value):
        raise AttributeError(f"BallTrajectory is immutable (cannot set {name})")

    def __delattr__(self, name):
        raise AttributeError(f"BallTrajectory is immutable (cannot delete {name})")

    def __reduce__(self):
        return BallTrajectory, (self.position_m, self.velocity_mps, self.v_shoot_mps, self.params)

    def __repr__(self) -> str:
        return (f"BallTrajectory(position_m={self.position_m!r}, velocity_mps={self.velocity_mps!r}, "
                f"v_shoot_mps={self.v_shoot_mps!r}, params={self.params!r})")

    def _batch(self, position_m, velocity_mps, v_shoot_mps) -> None:
        pos = _as_finite("position_m", position_m)
        vel = _as_finite("velocity_mps", velocity_mps)
        if pos.ndim < 1 or pos.shape[-1] != 2:
            raise ValueError(f"position_m: last axis must have length 2, got shape {pos.shape}")
        if vel.shape != pos.shape:
            raise ValueError(f"velocity_mps: shape {vel.shape} must equal position shape {pos.shape}")
        batch = pos.shape[:-1]
        v_shoot = _as_finite("v_shoot_mps", v_shoot_mps)
        if (v_shoot < 0.0).any():
            raise ValueError(f"v_shoot_mps: must be >= 0, got {v_shoot_mps!r}")
        try:
            v_shoot = np.broadcast_to(v_shoot, batch)
        except ValueError:
            raise ValueError(f"v_shoot_mps: shape {v_shoot.shape} does not fit batch {batch}") from None
        speed = np.hypot(vel[..., 0], vel[..., 1])
        if (speed > MAX_SPEED_MPS).any() or (v_shoot > MAX_SPEED_MPS).any():
            raise ValueError(f"velocity_mps / v_shoot_mps: speed above {MAX_SPEED_MPS} m/s is not a ball")
        if (np.abs(pos) > MAX_POSITION_M).any():
            raise ValueError(f"position_m: beyond {MAX_POSITION_M} m")
        moving = speed > 0.0
        safe = np.where(moving, speed, 1.0)
        direction = np.where(moving[..., None], vel / safe[..., None], 0.0)
        v_shoot = np.maximum(v_shoot, speed)
        values = (pos, vel, direction, v_shoot, speed, *self._derive(speed, v_shoot, np.minimum))
        names = ("position_m", "velocity_mps", "direction", *BallFloats._fields[6:])
        self._arrays.update((name, _read_only(v)) for name, v in zip(names, values, strict=True))

    def _one_ball(self, position_m, velocity_mps, v_shoot_mps) -> BallFloats:
        """The batch path's checks and formulas for one ball, in floats."""
        (x, y), (vx, vy) = position_m, velocity_mps
        x, y, vx, vy, v_shoot = float(x), float(y), float(vx), float(vy), float(v_shoot_mps)
        checks = (("position_m", (x, y), position_m), ("velocity_mps", (vx, vy), velocity_mps),
                  ("v_shoot_mps", (v_shoot,), v_shoot_mps))
        for name, values, raw in checks:
            if not all(map(math.isfinite, values)):
                raise ValueError(f"{name}: must be finite, got {raw!r}")
        if v_shoot < 0.0:
            raise ValueError(f"v_shoot_mps: must be >= 0, got {v_shoot_mps!r}")
        speed = math.hypot(vx, vy)
        if speed > MAX_SPEED_MPS or v_shoot > MAX_SPEED_MPS:
            raise ValueError(f"velocity_mps / v_shoot_mps: speed above {MAX_SPEED_MPS} m/s is not a ball")
        if abs(x) > MAX_POSITION_M or abs(y) > MAX_POSITION_M:
            raise ValueError(f"position_m: beyond {MAX_POSITION_M} m")
        ux, uy = (vx / speed, vy / speed) if speed > 0.0 else (0.0, 0.0)
        v_shoot = max(v_shoot, speed)
        return BallFloats(x, y, vx, vy, ux, uy, v_shoot, speed, *self._derive(speed, v_shoot, min))

    def _derive(self, speed, v_shoot, minimum) -> tuple:
        """Switch speed, switch time and distance, stop time and distance (module docstring)."""
        p = self.params
        v_switch = minimum(speed, p.c_switch * v_shoot)
        t_switch = (speed - v_switch) / -p.a_slide_mps2
        d_switch = speed * t_switch + 0.5 * p.a_slide_mps2 * t_switch**2
        t_roll = v_switch / -p.a_roll_mps2
        t_stop = t_switch + t_roll
        d_stop = d_switch + v_switch * t_roll + 0.5 * p.a_roll_mps2 * t_roll**2
        return v_switch, t_switch, d_switch, t_stop, d_stop

    # -- properties -------------------------------------------------------------------------------
    @property
    def batch_shape(self) -> tuple[int, ...]:
        return () if self.floats is not None else self._arrays["position_m"].shape[:-1]

    @property
    def phase(self) -> BallPhase | np.ndarray:
        """The phase now: ``phase_at(0)``, a BallPhase for one ball."""
        f = self.floats
        if f is None:
            return self.phase_at(0.0)
        if f.stop_time_s <= 0.0:
            return BallPhase.STOPPED
        return BallPhase.SLIDING if f.switch_time_s > 0.0 else BallPhase.ROLLING

    @property
    def stop_point(self) -> np.ndarray:
        return self.position_m + self.direction * self.stop_distance_m[..., None]

    @property
    def switch_point(self) -> np.ndarray:
        return self.position_m + self.direction * self.switch_distance_m[..., None]

    def __getitem__(self, index) -> BallTrajectory:
        """One ball (or a sub-batch) of a batch."""
        if not self.batch_shape:
            raise IndexError("a single-ball trajectory cannot be indexed")
        return BallTrajectory(
            self.position_m[index], self.velocity_mps[index], self.v_shoot_mps[index], self.params
        )

    # -- broadcasting helpers ----------------------------------------------------------------------
    def _per_ball(self, value: np.ndarray, query: np.ndarray) -> np.ndarray:
        """Reshape a per-ball quantity so it broadcasts as an outer product with ``query``."""
        return value.reshape(value.shape + (1,) * query.ndim)

    def _time(self, t_s) -> np.ndarray:
        t = np.asarray(t_s, dtype=float)
        if np.isnan(t).any():
            raise ValueError("t_s: must not be NaN")
        if (t < 0.0).any():
            raise ValueError("t_s: must be >= 0 (the trajectory starts now)")
        return t

    def _split_time(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        t_switch = self._per_ball(self.switch_time_s, t)
        t_stop = self._per_ball(self.stop_time_s, t)
        t_clipped = np.minimum(t, t_stop)
        t_slide = np.minimum(t_clipped, t_switch)
        return t_slide, t_clipped - t_slide

    # -- queries ----------------------------------------------------------------------------------
    def distance_at(self, t_s) -> np.ndarray:
        """Distance travelled along the line of motion after ``t_s`` seconds (monotone)."""
        t = self._time(t_s)
        ts, tr = self._split_time(t)
        return self._kinematics(ts, tr, self._per_ball(self.speed_mps, t), self._per_ball(self.v_switch_mps, t))[0]

    def speed_at(self, t_s) -> np.ndarray:
        t = self._time(t_s)
        ts, tr = self._split_time(t)
        return np.maximum(self._kinematics(ts, tr, self._per_ball(self.speed_mps, t), 0.0)[1], 0.0)

    def _kinematics(self, ts, tr, s0, v_switch):
        """Distance and speed after ``ts`` seconds of sliding and ``tr`` of rolling (floats or arrays)."""
        p = self.params
        distance = ts * (s0 + 0.5 * p.a_slide_mps2 * ts) + tr * (v_switch + 0.5 * p.a_roll_mps2 * tr)
        return distance, s0 + p.a_slide_mps2 * ts + p.a_roll_mps2 * tr

    def position_at(self, t_s) -> np.ndarray:
        """Ball position (paper: ballAtTime); shape ``batch + shape(t_s) + (2,)``."""
        t = np.asarray(t_s, dtype=float)
        d = self.distance_at(t)
        pos = self.position_m.reshape(self.batch_shape + (1,) * t.ndim + (2,))
        u = self.direction.reshape(pos.shape)
        return pos + u * d[..., None]

    def velocity_at(self, t_s) -> np.ndarray:
        t = np.asarray(t_s, dtype=float)
        s = self.speed_at(t)
        u = self.direction.reshape(self.batch_shape + (1,) * t.ndim + (2,))
        return u * s[..., None]

    def phase_at(self, t_s) -> np.ndarray:
        """``BallPhase`` codes (int array): sliding before the switch, stopped from t_stop on."""
        t = self._time(t_s)
        t_switch = self._per_ball(self.switch_time_s, t)
        t_stop = self._per_ball(self.stop_time_s, t)
        return np.where(
            t >= t_stop, BallPhase.STOPPED, np.where(t < t_switch, BallPhase.SLIDING, BallPhase.ROLLING)
        ).astype(np.int8)

    def time_to_distance(self, d_m) -> np.ndarray:
        """Time until the ball has travelled ``d_m`` (paper: ballRollTime); +inf if it stops short."""
        d = _as_finite("d_m", d_m, allow_inf=True)
        if (d < 0.0).any():
            raise ValueError("d_m: must be >= 0")
        s0 = self._per_ball(self.speed_mps, d)
        v_sw = self._per_ball(self.v_switch_mps, d)
        d_sw = self._per_ball(self.switch_distance_m, d)
        d_stop = self._per_ball(self.stop_distance_m, d)
        t_stop = self._per_ball(self.stop_time_s, d)
        # A distance a rounding error beyond the stop distance still means "at the stop point".
        tol = 1e-12 * (1.0 + d_stop)
        beyond = d > d_stop + tol
        t = np.minimum(self._travel_time(np.minimum(d, d_stop), s0, v_sw, d_sw), t_stop)
        return np.where(beyond, np.inf, t)

    def _travel_time(self, d, s0, v_sw, d_sw) -> np.ndarray:
        """Time to travel ``d`` (at most the stop distance); per-ball values broadcast with it."""
        p = self.params
        d_slide = np.minimum(d, d_sw)
        d_roll = d - d_slide
        # Citardauq form 2d/(v + sqrt(v^2 + 2ad)) of the quadratic root: no cancellation.
        den_s = s0 + np.sqrt(np.maximum(s0 * s0 + 2.0 * p.a_slide_mps2 * d_slide, 0.0))
        den_r = v_sw + np.sqrt(np.maximum(v_sw * v_sw + 2.0 * p.a_roll_mps2 * d_roll, 0.0))
        with np.errstate(divide="ignore", invalid="ignore"):
            t = np.where(d_slide > 0.0, 2.0 * d_slide / den_s, 0.0)
            return t + np.where(d_roll > 0.0, 2.0 * d_roll / den_r, 0.0)

    def time_in_field(self, field_config: FieldConfig, margin_m: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """When the ball is inside the field lines (extended by ``margin_m``): ``(t_enter, t_leave)``.

        The straight path meets the field rectangle in one stretch. ``t_enter`` is 0 for a ball
        inside, the moment it crosses into the field for a ball outside heading in (off a wall, in
        the run-off area), +inf when it stops before. ``t_leave`` is when it crosses out again,
        +inf when it stops inside (or never enters). On a line counts as inside.
        """
        if not isinstance(field_config, FieldConfig):
            raise ValueError(f"field_config: expected FieldConfig, got {type(field_config).__name__}")
        if not math.isfinite(margin_m):
            raise ValueError(f"margin_m: must be finite, got {margin_m!r}")
        half = (field_config.half_length_m + margin_m, field_config.half_width_m + margin_m)
        if min(half) <= 0.0:
            raise ValueError(f"margin_m: {margin_m} leaves no field")
        f = self.floats
        if f is not None:  # one ball (every predictor frame): the same in floats
            s_in, s_out = 0.0, math.inf  # the stretch of the path, as distances along it
            for p, u, h in ((f.x_m, f.ux, half[0]), (f.y_m, f.uy, half[1])):
                if u == 0.0:
                    if abs(p) > h:
                        s_in = math.inf
                    continue
                s1, s2 = (-h - p) / u, (h - p) / u
                s_in, s_out = max(s_in, min(s1, s2)), min(s_out, max(s1, s2))
            d_stop = f.stop_distance_m
            if s_in > s_out or s_in > d_stop:
                return np.float64(math.inf), np.float64(math.inf)
            t_in = self._travel_time(s_in, f.speed_mps, f.v_switch_mps, f.switch_distance_m) if s_in > 0.0 else 0.0
            if s_out > d_stop:
                return np.float64(t_in), np.float64(math.inf)
            return np.float64(t_in), np.float64(self._travel_time(s_out, f.speed_mps, f.v_switch_mps,
                                                                  f.switch_distance_m))
        pos, u, half = self.position_m, self.direction, np.array(half)
        with np.errstate(divide="ignore", invalid="ignore"):
            s1, s2 = (-half - pos) / u, (half - pos) / u
        still = u == 0.0  # no motion along the axis: inside for all s, or never
        lo = np.where(still, np.where(np.abs(pos) > half, np.inf, -np.inf), np.minimum(s1, s2))
        hi = np.where(still, np.inf, np.maximum(s1, s2))
        s_in = np.maximum(lo.max(axis=-1), 0.0)
        s_out = hi.min(axis=-1)
        d_stop = self.stop_distance_m
        never = (s_in > s_out) | (s_in > d_stop)
        travel = self._travel_time  # of distances at most the stop distance
        t_in = np.where(never, np.inf, travel(np.minimum(s_in, d_stop), self.speed_mps, self.v_switch_mps,
                                               self.switch_distance_m))
        t_out = np.where(never | (s_out > d_stop), np.inf,
                         travel(np.clip(s_out, 0.0, d_stop), self.speed_mps, self.v_switch_mps,
                                self.switch_distance_m))
        return t_in, t_out

    def advanced(self, dt_s: float) -> BallTrajectory:
        """The same ball ``dt_s`` seconds later (same kick speed, so the phases stay consistent)."""
        f = self.floats
        if f is not None and isinstance(dt_s, int | float) and math.isfinite(dt_s) and dt_s >= 0.0:
            # One ball, one time (the predictor, every frame): the same in floats.
            t = min(dt_s, f.stop_time_s)
            ts = min(t, f.switch_time_s)
            d, s = self._kinematics(ts, t - ts, f.speed_mps, f.v_switch_mps)
            s = max(s, 0.0)
            return BallTrajectory((f.x_m + f.ux * d, f.y_m + f.uy * d), (f.ux * s, f.uy * s), f.v_shoot_mps,
                                  self.params)
        pos = self.position_at(dt_s)
        vel = self.velocity_at(dt_s)
        return BallTrajectory(pos, vel, self.v_shoot_mps, self.params)
