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

This module is the one home of these closed forms. ``BallFloats`` holds one ball's numbers
(position, direction, the switch and stop constants, the decelerations) and ``ball_distance``,
``ball_speed`` and ``ball_time_to_distance`` answer from them: plain Python on floats, and
compiled into the numba kernels that call them (catch_time's robotTimeToBall search, the array
queries here), which read the ball by name (``ball.stop_time_s``), never by position in an array.
numba is imported on the first kernel a process needs (``numba_ball_type``), not with this module:
a node that only asks scalar questions (the catcher) starts without it (~0.7 s of CPU less).

``BallTrajectory`` is an immutable value (one ball's future) with these queries
(``position_at`` is the paper's ballAtTime, ``time_to_distance`` is ballRollTime). A number
in gives a float out; an array of times or distances gives an array of that shape (plus a
trailing 2 for vectors).

>>> ball = BallTrajectory((0.0, 0.0), (3.3, 0.0), v_shoot_mps=3.3)  # kicked at 3.3 m/s along +x
>>> round(ball.switch_time_s, 3), round(ball.stop_distance_m, 3)  # slides 0.528 s, rests after 7.93 m
(0.528, 7.928)
>>> round(ball.time_to_distance(1.0), 3)
0.349
"""

from __future__ import annotations

import enum
import functools
import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from erforce_interfaces.robot_config import FieldConfig

__all__ = [
    "MAX_POSITION_M", "MAX_SPEED_MPS", "BallFloats", "BallModelParams", "BallPhase", "BallTrajectory", "ball_distance",
    "ball_floats", "ball_speed", "ball_time_to_distance", "kick_distance", "load_kernels", "numba_ball_type",
]

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


@dataclass(frozen=True)
class ChipParams:
    """A chipped ball's hops (chip_model.ChipTrajectory): gravity and the damping at each bounce.

    At each touchdown the vertical speed is reversed and scaled by ``damping_z`` (normal restitution),
    the horizontal velocity scaled by ``damping_xy_first_hop`` at the first bounce (the ball has no spin
    yet: the carpet's friction spins it up, which costs speed; a solid sphere that stops slipping keeps
    1 / (1 + 2/5) of it) and by ``damping_xy_other_hops`` after (it spins already). A bounce that
    leaves less than ``min_hop_vz_mps`` upwards ends the hops: the ball rolls on (two-phase model, in its
    rolling phase). ``max_catch_height_m``: a robot can take a ball whose centre is at most this high
    (about the robot's height). The SSL geometry's fixed-loss chip model names the same three dampings.
    The defaults are the simulator's ball (erforce_sim.ball: a solid ball chipped without spin, no drag),
    as BallModelParams' are its carpet; a real field's come from its logs or its geometry packet.
    """

    g_mps2: float = 9.81
    damping_z: float = 0.566
    damping_xy_first_hop: float = 1.0 / 1.4
    damping_xy_other_hops: float = 1.0
    min_hop_vz_mps: float = 0.05
    max_catch_height_m: float = 0.15

    def __post_init__(self) -> None:
        for name in ("g_mps2", "damping_z", "damping_xy_first_hop", "damping_xy_other_hops", "min_hop_vz_mps",
                     "max_catch_height_m"):
            value = getattr(self, name)
            if not isinstance(value, int | float | np.floating | np.integer) or not math.isfinite(value):
                raise ValueError(f"ChipParams.{name}: must be a finite number, got {value!r}")
            object.__setattr__(self, name, float(value))
        if self.g_mps2 <= 0.0 or self.min_hop_vz_mps <= 0.0 or self.max_catch_height_m < 0.0:
            raise ValueError(f"ChipParams: g_mps2 > 0, min_hop_vz_mps > 0 and max_catch_height_m >= 0, got "
                             f"{self.g_mps2}, {self.min_hop_vz_mps}, {self.max_catch_height_m}")
        if not 0.0 <= self.damping_z < 1.0:  # below 1: the hops end
            raise ValueError(f"ChipParams.damping_z: must be in [0, 1), got {self.damping_z}")
        for name in ("damping_xy_first_hop", "damping_xy_other_hops"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise ValueError(f"ChipParams.{name}: must be in [0, 1], got {getattr(self, name)}")


_NUMBER = int | float | np.floating | np.integer


class BallFloats(NamedTuple):
    """One ball's numbers as plain floats: what scalar code and the compiled kernels read."""

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
    a_slide_mps2: float
    a_roll_mps2: float


def ball_floats(x_m: float, y_m: float, vx_mps: float, vy_mps: float, v_shoot_mps: float, a_slide_mps2: float,
                a_roll_mps2: float, c_switch: float) -> BallFloats:
    """The switch and stop constants (module docstring) of a ball; no checks (the fit tries any decelerations)."""
    speed = math.hypot(vx_mps, vy_mps)
    ux, uy = (vx_mps / speed, vy_mps / speed) if speed > 0.0 else (0.0, 0.0)
    v_shoot = max(v_shoot_mps, speed)
    v_switch = min(speed, c_switch * v_shoot)
    t_switch = (speed - v_switch) / -a_slide_mps2
    d_switch = speed * t_switch + 0.5 * a_slide_mps2 * t_switch**2
    t_roll = v_switch / -a_roll_mps2
    d_stop = d_switch + v_switch * t_roll + 0.5 * a_roll_mps2 * t_roll**2
    values = (x_m, y_m, vx_mps, vy_mps, ux, uy, v_shoot, speed, v_switch, t_switch, d_switch, t_switch + t_roll,
              d_stop, a_slide_mps2, a_roll_mps2)
    return BallFloats(*map(float, values))


def ball_distance(ball: BallFloats, t_s: float) -> float:
    """Distance travelled along the line of motion after ``t_s`` >= 0 seconds (monotone)."""
    t = min(t_s, ball.stop_time_s)
    ts = min(t, ball.switch_time_s)
    tr = t - ts
    return ts * (ball.speed_mps + 0.5 * ball.a_slide_mps2 * ts) + tr * (ball.v_switch_mps + 0.5 * ball.a_roll_mps2 * tr)


def ball_speed(ball: BallFloats, t_s: float) -> float:
    """Speed after ``t_s`` >= 0 seconds."""
    t = min(t_s, ball.stop_time_s)
    ts = min(t, ball.switch_time_s)
    return max(ball.speed_mps + ball.a_slide_mps2 * ts + ball.a_roll_mps2 * (t - ts), 0.0)


def ball_time_to_distance(ball: BallFloats, d_m: float) -> float:
    """Time until the ball has travelled ``d_m`` >= 0 (paper: ballRollTime); +inf if it stops short.

    A distance a rounding error beyond the stop distance still means "at the stop point".
    """
    d_stop = ball.stop_distance_m
    if d_m > d_stop + 1e-12 * (1.0 + d_stop):
        return math.inf
    d = min(d_m, d_stop)
    d_slide = min(d, ball.switch_distance_m)
    d_roll = d - d_slide
    t = 0.0
    # Citardauq form 2d / (v + sqrt(v^2 + 2ad)) of the quadratic root: no cancellation.
    if d_slide > 0.0:
        s0 = ball.speed_mps
        t += 2.0 * d_slide / (s0 + math.sqrt(max(s0 * s0 + 2.0 * ball.a_slide_mps2 * d_slide, 0.0)))
    if d_roll > 0.0:
        v_sw = ball.v_switch_mps
        t += 2.0 * d_roll / (v_sw + math.sqrt(max(v_sw * v_sw + 2.0 * ball.a_roll_mps2 * d_roll, 0.0)))
    return min(t, ball.stop_time_s)


@functools.cache
def numba_ball_type():
    """The numba type of a BallFloats, for kernels' signatures; imports numba and makes the closed forms
    above callable from compiled code (``register_jitable``). Every kernel module calls it first."""
    from erforce_interfaces.numba_support import numba, register_jitable

    for closed_form in (ball_distance, ball_speed, ball_time_to_distance):
        register_jitable(closed_form)
    return numba.types.NamedUniTuple(numba.types.float64, len(BallFloats._fields), BallFloats)


def _distance_many(ball, t, out):
    for i in range(t.shape[0]):
        out[i] = ball_distance(ball, t[i])


def _speed_many(ball, t, out):
    for i in range(t.shape[0]):
        out[i] = ball_speed(ball, t[i])


def _time_to_distance_many(ball, d, out):
    for i in range(d.shape[0]):
        out[i] = ball_time_to_distance(ball, d[i])


@functools.cache
def _array_kernel(loop):
    """``loop`` (one of the three above) compiled for arrays, on its first use (cached on disk beside this module)."""
    from erforce_interfaces.numba_support import numba

    signature = numba.void(numba_ball_type(), numba.float64[::1], numba.float64[::1])
    return numba.njit(signature, cache=True, error_model="numpy")(loop)


def load_kernels() -> None:
    """Compile or load the array queries' kernels now rather than on their first use."""
    for loop in (_distance_many, _speed_many, _time_to_distance_many):
        _array_kernel(loop)


# Up to this many values an array query runs the closed form in Python (~1 us each) instead of the
# kernel: a process that asks only short ones (the field view's path marks) never loads numba (~0.7 s of CPU).
_PYTHON_MAX_VALUES = 64
_SCALAR_OF = {_distance_many: ball_distance, _speed_many: ball_speed, _time_to_distance_many: ball_time_to_distance}


def _many(loop, ball: BallFloats, values: np.ndarray) -> np.ndarray:
    flat = np.ascontiguousarray(values, dtype=float).ravel()
    if flat.size <= _PYTHON_MAX_VALUES:
        scalar = _SCALAR_OF[loop]
        return np.array([scalar(ball, v) for v in flat.tolist()], dtype=float).reshape(values.shape)
    out = np.empty(flat.shape)
    _array_kernel(loop)(ball, flat, out)
    return out.reshape(values.shape)


def kick_distance(tau_s: np.ndarray, v_shoot_mps: float, a_slide_mps2: float, a_roll_mps2: float,
                  c_switch: float) -> np.ndarray:
    """Distance after ``tau_s`` >= 0 (array) of a ball kicked from rest at ``v_shoot_mps``; no checks
    on the parameters (the identification's least squares tries any decelerations < 0)."""
    ball = ball_floats(0.0, 0.0, float(v_shoot_mps), 0.0, float(v_shoot_mps), float(a_slide_mps2),
                       float(a_roll_mps2), float(c_switch))
    return _many(_distance_many, ball, np.asarray(tau_s, dtype=float))


def _is_pair(value) -> bool:
    if isinstance(value, np.ndarray):
        return value.shape == (2,)
    return isinstance(value, tuple | list) and len(value) == 2 and all(isinstance(v, _NUMBER) for v in value)


def _read_only(*values: float) -> np.ndarray:
    a = np.array(values)
    a.setflags(write=False)
    return a


class BallTrajectory:
    """The future of one ball under the two-phase model. Immutable.

    ``v_shoot_mps`` is the tracked kick speed; when it is below the current speed it is raised
    to the current speed (the ball cannot be faster than it was kicked). When the current speed
    is at most ``c_switch * v_shoot`` the ball already rolls. Its numbers are ``floats``
    (BallFloats); the scalar properties are floats, the vectors read-only arrays.
    """

    __slots__ = ("floats", "params")

    def __init__(self, position_m, velocity_mps, v_shoot_mps: float, params: BallModelParams | None = None) -> None:
        params = BallModelParams() if params is None else params
        if not isinstance(params, BallModelParams):
            raise ValueError(f"params: expected BallModelParams, got {type(params).__name__}")
        if not (_is_pair(position_m) and _is_pair(velocity_mps)):
            raise ValueError(f"position_m and velocity_mps: one ball, 2 numbers each, got {position_m!r} and "
                             f"{velocity_mps!r}")
        if not (isinstance(v_shoot_mps, _NUMBER) or (isinstance(v_shoot_mps, np.ndarray) and v_shoot_mps.ndim == 0)):
            raise ValueError(f"v_shoot_mps: one number, got {v_shoot_mps!r}")
        (x, y), (vx, vy) = position_m, velocity_mps
        x, y, vx, vy, v_shoot = float(x), float(y), float(vx), float(vy), float(v_shoot_mps)
        checks = (("position_m", (x, y), position_m), ("velocity_mps", (vx, vy), velocity_mps),
                  ("v_shoot_mps", (v_shoot,), v_shoot_mps))
        for name, values, raw in checks:
            if not all(map(math.isfinite, values)):
                raise ValueError(f"{name}: must be finite, got {raw!r}")
        if v_shoot < 0.0:
            raise ValueError(f"v_shoot_mps: must be >= 0, got {v_shoot_mps!r}")
        if math.hypot(vx, vy) > MAX_SPEED_MPS or v_shoot > MAX_SPEED_MPS:
            raise ValueError(f"velocity_mps / v_shoot_mps: speed above {MAX_SPEED_MPS} m/s is not a ball")
        if abs(x) > MAX_POSITION_M or abs(y) > MAX_POSITION_M:
            raise ValueError(f"position_m: beyond {MAX_POSITION_M} m")
        init = object.__setattr__
        init(self, "params", params)
        init(self, "floats", ball_floats(x, y, vx, vy, v_shoot, params.a_slide_mps2, params.a_roll_mps2,
                                         params.c_switch))

    @classmethod
    def of_floats(cls, x: float, y: float, vx: float, vy: float, v_shoot_mps: float,
                  params: BallModelParams) -> BallTrajectory:
        """``BallTrajectory((x, y), (vx, vy), v_shoot_mps, params)`` for plain floats: the same ball, the same
        checks (values that fail one go through the constructor, which names it), in a few comparisons."""
        if (type(params) is BallModelParams and abs(x) <= MAX_POSITION_M and abs(y) <= MAX_POSITION_M
                and math.hypot(vx, vy) <= MAX_SPEED_MPS and 0.0 <= v_shoot_mps <= MAX_SPEED_MPS):
            ball = object.__new__(cls)  # NaN and inf fail the comparisons above
            init = object.__setattr__
            init(ball, "params", params)
            init(ball, "floats", ball_floats(float(x), float(y), float(vx), float(vy), float(v_shoot_mps),
                                             params.a_slide_mps2, params.a_roll_mps2, params.c_switch))
            return ball
        return cls((x, y), (vx, vy), v_shoot_mps, params)

    def __setattr__(self, name, value):
        raise AttributeError(f"BallTrajectory is immutable (cannot set {name})")

    def __delattr__(self, name):
        raise AttributeError(f"BallTrajectory is immutable (cannot delete {name})")

    def __reduce__(self):
        f = self.floats
        return BallTrajectory, ((f.x_m, f.y_m), (f.vx_mps, f.vy_mps), f.v_shoot_mps, self.params)

    def __repr__(self) -> str:
        f = self.floats
        return (f"BallTrajectory(position_m=({f.x_m!r}, {f.y_m!r}), velocity_mps=({f.vx_mps!r}, {f.vy_mps!r}), "
                f"v_shoot_mps={f.v_shoot_mps!r}, params={self.params!r})")

    # -- properties -------------------------------------------------------------------------------
    position_m = property(lambda self: _read_only(self.floats.x_m, self.floats.y_m))
    velocity_mps = property(lambda self: _read_only(self.floats.vx_mps, self.floats.vy_mps))
    direction = property(lambda self: _read_only(self.floats.ux, self.floats.uy), doc="unit vector of motion")
    v_shoot_mps = property(lambda self: self.floats.v_shoot_mps)
    speed_mps = property(lambda self: self.floats.speed_mps)
    v_switch_mps = property(lambda self: self.floats.v_switch_mps)
    switch_time_s = property(lambda self: self.floats.switch_time_s)
    switch_distance_m = property(lambda self: self.floats.switch_distance_m)
    stop_time_s = property(lambda self: self.floats.stop_time_s)
    stop_distance_m = property(lambda self: self.floats.stop_distance_m)

    @property
    def phase(self) -> BallPhase:
        """The phase now: ``phase_at(0)``."""
        f = self.floats
        if f.stop_time_s <= 0.0:
            return BallPhase.STOPPED
        return BallPhase.SLIDING if f.switch_time_s > 0.0 else BallPhase.ROLLING

    @property
    def stop_point(self) -> np.ndarray:
        f = self.floats
        return _read_only(f.x_m + f.ux * f.stop_distance_m, f.y_m + f.uy * f.stop_distance_m)

    @property
    def switch_point(self) -> np.ndarray:
        f = self.floats
        return _read_only(f.x_m + f.ux * f.switch_distance_m, f.y_m + f.uy * f.switch_distance_m)

    # -- queries ----------------------------------------------------------------------------------
    @staticmethod
    def _time(t_s) -> float | np.ndarray:
        """A time query: a float for a number, else a float array; NaN and negative times refused."""
        t = float(t_s) if isinstance(t_s, _NUMBER) or np.ndim(t_s) == 0 else np.asarray(t_s, dtype=float)
        if np.isnan(t).any():
            raise ValueError("t_s: must not be NaN")
        if (np.asarray(t) < 0.0).any():
            raise ValueError("t_s: must be >= 0 (the trajectory starts now)")
        return t

    def distance_at(self, t_s) -> float | np.ndarray:
        """Distance travelled along the line of motion after ``t_s`` seconds (monotone)."""
        t = self._time(t_s)
        return ball_distance(self.floats, t) if isinstance(t, float) else _many(_distance_many, self.floats, t)

    def speed_at(self, t_s) -> float | np.ndarray:
        t = self._time(t_s)
        return ball_speed(self.floats, t) if isinstance(t, float) else _many(_speed_many, self.floats, t)

    def position_at(self, t_s) -> np.ndarray:
        """Ball position (paper: ballAtTime); shape ``shape(t_s) + (2,)``."""
        d = np.asarray(self.distance_at(t_s))
        f = self.floats
        return np.stack([f.x_m + f.ux * d, f.y_m + f.uy * d], axis=-1)

    def velocity_at(self, t_s) -> np.ndarray:
        s = np.asarray(self.speed_at(t_s))
        return np.stack([self.floats.ux * s, self.floats.uy * s], axis=-1)

    def phase_at(self, t_s) -> BallPhase | np.ndarray:
        """``BallPhase`` (int8 codes for an array): sliding before the switch, stopped from t_stop on."""
        t = self._time(t_s)
        f = self.floats
        phase = np.where(t >= f.stop_time_s, BallPhase.STOPPED,
                         np.where(t < f.switch_time_s, BallPhase.SLIDING, BallPhase.ROLLING)).astype(np.int8)
        return BallPhase(int(phase)) if isinstance(t, float) else phase

    def time_to_distance(self, d_m) -> float | np.ndarray:
        """Time until the ball has travelled ``d_m`` (paper: ballRollTime); +inf if it stops short."""
        d = float(d_m) if isinstance(d_m, _NUMBER) or np.ndim(d_m) == 0 else np.asarray(d_m, dtype=float)
        if np.isnan(d).any():
            raise ValueError(f"d_m: must not be NaN, got {d_m!r}")
        if (np.asarray(d) < 0.0).any():
            raise ValueError("d_m: must be >= 0")
        if isinstance(d, float):
            return ball_time_to_distance(self.floats, d)
        return _many(_time_to_distance_many, self.floats, d)

    def time_in_field(self, field_config: FieldConfig, margin_m: float = 0.0) -> tuple[float, float]:
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
        s_in, s_out = 0.0, math.inf  # the stretch of the path inside, as distances along it
        for p, u, h in ((f.x_m, f.ux, half[0]), (f.y_m, f.uy, half[1])):
            if u == 0.0:
                if abs(p) > h:
                    s_in = math.inf
                continue
            s1, s2 = (-h - p) / u, (h - p) / u
            s_in, s_out = max(s_in, min(s1, s2)), min(s_out, max(s1, s2))
        d_stop = f.stop_distance_m
        if s_in > s_out or s_in > d_stop:
            return math.inf, math.inf
        t_in = ball_time_to_distance(f, s_in) if s_in > 0.0 else 0.0
        return t_in, (math.inf if s_out > d_stop else ball_time_to_distance(f, s_out))

    def advanced(self, dt_s: float) -> BallTrajectory:
        """The same ball ``dt_s`` seconds later (same kick speed, so the phases stay consistent)."""
        dt = self._time(dt_s)
        if not isinstance(dt, float):
            raise ValueError(f"dt_s: one number, got {dt_s!r}")
        f = self.floats
        d, s = ball_distance(f, dt), ball_speed(f, dt)
        return BallTrajectory.of_floats(f.x_m + f.ux * d, f.y_m + f.uy * d, f.ux * s, f.uy * s, f.v_shoot_mps,
                                        self.params)
