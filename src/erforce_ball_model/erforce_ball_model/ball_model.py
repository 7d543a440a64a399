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
compiled into the numba kernels that call them (catch_time_kernels' robotTimeToBall search, the array
queries here), which read the ball by name (``ball.stop_time_s``), never by position in an array.
numba is imported on the first kernel a process needs (``numba_ball_type``), not with this module:
a node that only asks scalar questions (the catcher) starts without it.

``BallTrajectory`` is an immutable value (one ball's future) with these queries
(``position_at`` is the paper's ballAtTime, ``time_to_distance`` is ballRollTime). A number
in gives a float out; an array of times or distances gives an array of that shape (plus a
trailing 2 for vectors). Given the field's ``Walls`` it reflects off them (beyond the paper, which
lets the ball roll on through the wall): its path is then straight pieces, each with these numbers,
and every query answers piecewise (``BallTrajectory`` says how the ball comes off a wall).

>>> ball = BallTrajectory((0.0, 0.0), (3.3, 0.0), v_shoot_mps=3.3)  # kicked at 3.3 m/s along +x
>>> round(ball.switch_time_s, 3), round(ball.stop_distance_m, 3)  # slides 0.528 s, rests after 7.93 m
(0.528, 7.928)
>>> round(ball.time_to_distance(1.0), 3)
0.349
>>> walls = Walls.of_field(FieldConfig.preset("division_b"))  # the wall 4.8 m from the centre along x
>>> BallTrajectory((2.0, 0.0), (3.3, 0.0), 3.3, walls=walls).stop_point.round(3).tolist()  # off it: inside
[4.464, 0.0]
"""

from __future__ import annotations

import bisect
import enum
import functools
import itertools
import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from erforce_ball_model.walls import Walls
from erforce_interfaces.wire.robot_config import (
    BALL_A_ROLL_MPS2,
    BALL_A_SLIDE_MPS2,
    BALL_C_SWITCH,
    BALL_CHIP_DAMPING_XY_FIRST_HOP,
    BALL_CHIP_DAMPING_XY_OTHER_HOPS,
    BALL_CHIP_DAMPING_Z,
    BALL_CHIP_MIN_HOP_VZ_MPS,
    BALL_MAX_CATCH_HEIGHT_M,
    BALL_MAX_RECEIVE_HEIGHT_M,
    GRAVITY_MPS2,
    FieldConfig,
)

__all__ = [
    "MAX_POSITION_M", "MAX_SPEED_MPS", "MAX_WALL_BOUNCES", "PIECE_COLUMNS", "BallFloats", "BallModelParams",
    "BallPhase", "BallTrajectory", "ChipParams", "ball_distance", "ball_floats", "ball_speed",
    "ball_time_to_distance", "kick_distance", "kick_distances", "load_kernels", "numba_ball_type", "path_piece",
    "path_point",
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

    a_slide_mps2: float = BALL_A_SLIDE_MPS2
    a_roll_mps2: float = BALL_A_ROLL_MPS2
    c_switch: float = BALL_C_SWITCH

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
    rolling phase). Two heights of the ball's centre: ``max_catch_height_m``, the interception height: a robot
    stops a ball this low with its body (about the robot's height; an opponent under the flight cannot);
    ``max_receive_height_m``, the reception height: a robot controls a ball only this low (light barrier and
    dribbler bar), so a receiver takes a chip once it stays below it (``ChipTrajectory.time_below_height_s``).
    The SSL geometry's fixed-loss chip model names the same three dampings.
    The defaults are the simulator's ball (erforce_sim.ball: a solid ball chipped without spin, no drag),
    as BallModelParams' are its carpet; a real field's come from its logs or its geometry packet. The chip
    model in use is the ball predictor's (its ``chip_*`` parameters), published on /ball/chip_model_params.
    """

    g_mps2: float = GRAVITY_MPS2
    damping_z: float = BALL_CHIP_DAMPING_Z
    damping_xy_first_hop: float = BALL_CHIP_DAMPING_XY_FIRST_HOP
    damping_xy_other_hops: float = BALL_CHIP_DAMPING_XY_OTHER_HOPS
    min_hop_vz_mps: float = BALL_CHIP_MIN_HOP_VZ_MPS
    max_catch_height_m: float = BALL_MAX_CATCH_HEIGHT_M
    max_receive_height_m: float = BALL_MAX_RECEIVE_HEIGHT_M

    def __post_init__(self) -> None:
        for name in ("g_mps2", "damping_z", "damping_xy_first_hop", "damping_xy_other_hops", "min_hop_vz_mps",
                     "max_catch_height_m", "max_receive_height_m"):
            value = getattr(self, name)
            if not isinstance(value, int | float | np.floating | np.integer) or not math.isfinite(value):
                raise ValueError(f"ChipParams.{name}: must be a finite number, got {value!r}")
            object.__setattr__(self, name, float(value))
        if (self.g_mps2 <= 0.0 or self.min_hop_vz_mps <= 0.0 or self.max_catch_height_m < 0.0
                or self.max_receive_height_m < 0.0):
            raise ValueError(f"ChipParams: g_mps2 > 0, min_hop_vz_mps > 0, max_catch_height_m >= 0 and "
                             f"max_receive_height_m >= 0, got {self.g_mps2}, {self.min_hop_vz_mps}, "
                             f"{self.max_catch_height_m}, {self.max_receive_height_m}")
        if self.max_receive_height_m > self.max_catch_height_m:  # what a robot can take, it can stop
            raise ValueError(f"ChipParams.max_receive_height_m: must be <= max_catch_height_m "
                             f"({self.max_catch_height_m}), got {self.max_receive_height_m}")
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


# -- the path off the field wall (the walls and their impulse: walls.py) ----------------------------
# A ball that keeps hitting walls (into a corner) is followed this many bounces; then it ends at the wall.
MAX_WALL_BOUNCES = 8
_STILL_MPS = 1e-9  # below this a speed (or a slip) is none: no piece, no bounce


def _slide_off(px, py, vx, vy, sx_spin, sy_spin, nx, ny, walls, a_slide_mps2, a_roll_mps2):
    """The piece a ball slides along after leaving the wall at ``(px, py)`` with ``(vx, vy)`` and its
    spin's rolling velocity ``(sx_spin, sy_spin)``; (piece or None, its motion, the rolling velocity after it).

    The carpet's friction works on the slip ``v - spin`` at ``|a_slide|`` and shrinks it at
    ``|a_slide| (1 + 1/k)`` (erforce_sim.ball), so the slide lasts ``|slip| / (|a_slide| (1 + 1/k))`` and
    ends rolling at ``(v + k spin) / (1 + k)``. The true path is a parabola; the piece is its chord,
    travelled at the true path's speed along the chord (exact at both ends). Motion into the wall is
    taken by the wall (a ball pressed against it rolls along it).
    """
    k = walls.inertia_factor
    slip_x, slip_y = vx - sx_spin, vy - sy_spin
    slip = math.hypot(slip_x, slip_y)
    if slip <= _STILL_MPS:
        return None, None, (vx, vy)
    a = -a_slide_mps2
    duration = slip / (a * (1.0 + 1.0 / k))
    ax, ay = -a * slip_x / slip, -a * slip_y / slip
    end_vx, end_vy = vx + ax * duration, vy + ay * duration
    cx, cy = 0.5 * (vx + end_vx) * duration, 0.5 * (vy + end_vy) * duration
    into = end_vx * nx + end_vy * ny
    if into < 0.0:
        end_vx, end_vy = end_vx - into * nx, end_vy - into * ny
    into = cx * nx + cy * ny
    if into < 0.0:
        cx, cy = cx - into * nx, cy - into * ny
    length = math.hypot(cx, cy)
    if length <= _STILL_MPS * duration:
        return None, None, (end_vx, end_vy)
    ux, uy = cx / length, cy / length
    v_start = max(vx * ux + vy * uy, 0.0)
    v_end = 2.0 * length / duration - v_start
    if v_end < 0.0:
        v_start = v_end = length / duration
    piece = BallFloats(px, py, ux * v_start, uy * v_start, ux, uy, v_start, v_start, v_end, duration, length,
                       duration, length, (v_end - v_start) / duration, a_roll_mps2)
    return piece, (vx, vy, sx_spin, sy_spin, ax, ay), (end_vx, end_vy)


def _state_at(f: BallFloats, t: float, motion, k: float) -> tuple[float, float, float, float]:
    """Velocity and spin's rolling velocity of piece ``f`` at its time ``t``: a straight two-phase piece
    (``motion`` None: while it slides, ``v + k spin`` stays at ``(1 + k) v_switch``), or a slide off a wall."""
    if motion is None:
        s = ball_speed(f, t)
        spin = s if t >= f.switch_time_s else ((1.0 + k) * f.v_switch_mps - s) / k
        return f.ux * s, f.uy * s, f.ux * spin, f.uy * spin
    vx, vy, sx, sy, ax, ay = motion
    return vx + ax * t, vy + ay * t, sx - ax * t / k, sy - ay * t / k


def _pieces_within(first: BallFloats, walls: Walls, params: BallModelParams) -> tuple[tuple[float, BallFloats], ...]:
    """The ball's path as pieces ``(start time, BallFloats)`` that end where a wall cuts them (module docstring)."""
    pieces = []
    t0, f, motion, after = 0.0, first, None, None
    bounces = 0
    while True:
        hit = walls.first_hit(f.x_m, f.y_m, f.ux, f.uy)
        if hit is None or hit[0] >= f.stop_distance_m:
            pieces.append((t0, f))
            if after is None:
                return tuple(pieces)
            # the slide off a wall ended: the ball rolls on from its end
            t0, d = t0 + f.stop_time_s, f.stop_distance_m
            vx, vy = after
            f = ball_floats(f.x_m + f.ux * d, f.y_m + f.uy * d, vx, vy, 0.0, params.a_slide_mps2,
                            params.a_roll_mps2, 1.0)
            motion = after = None
            if f.stop_time_s <= 0.0:
                return tuple(pieces)
            continue
        d, nx, ny = hit
        t = ball_time_to_distance(f, d)
        pieces.append((t0, BallFloats(*f[:11], t, d, f.a_slide_mps2, f.a_roll_mps2)))  # ends at the wall
        bounces += 1
        if bounces > MAX_WALL_BOUNCES:
            return tuple(pieces)
        px, py = f.x_m + f.ux * d, f.y_m + f.uy * d
        vx, vy, sx, sy = _state_at(f, t, motion, walls.inertia_factor)
        vx, vy = walls.impulse(vx, vy, nx, ny)
        t0 += t
        f, motion, after = _slide_off(px, py, vx, vy, sx, sy, nx, ny, walls, params.a_slide_mps2,
                                      params.a_roll_mps2)
        if f is None:  # no slide: it rolls on from the wall (or rests there)
            vx, vy = after
            f = ball_floats(px, py, vx, vy, 0.0, params.a_slide_mps2, params.a_roll_mps2, 1.0)
            motion = after = None
            if f.stop_time_s <= 0.0:
                pieces.append((t0, f))
                return tuple(pieces)


# A trajectory's pieces as one table for the compiled kernels: one row per piece, its start time, then its
# BallFloats in their order. ``path_piece`` is the one place that reads a row back.
PIECE_COLUMNS = ("t_start_s", *BallFloats._fields)


def path_piece(table, i: int) -> BallFloats:
    """Row ``i`` of a trajectory's table (PIECE_COLUMNS; an array, or tuples for plain Python) as its BallFloats."""
    row = table[i]
    return BallFloats(row[1], row[2], row[3], row[4], row[5], row[6], row[7], row[8], row[9], row[10], row[11],
                      row[12], row[13], row[14], row[15])


def path_index(table, t_s: float) -> int:
    """The row of the piece the ball is on at ``t_s`` >= 0 (the last one from its end on)."""
    i = len(table) - 1
    while i > 0 and table[i][0] > t_s:
        i -= 1
    return i


def path_point(table, t_s: float) -> tuple[float, float]:
    """Where the ball of a trajectory's table is at ``t_s`` >= 0 (+inf: where it stops)."""
    i = path_index(table, t_s)
    f = path_piece(table, i)
    d = ball_distance(f, t_s - table[i][0])
    return f.x_m + f.ux * d, f.y_m + f.uy * d


@functools.cache
def numba_ball_type():
    """The numba type of a BallFloats, for kernels' signatures; imports numba and makes the closed forms
    above callable from compiled code (``register_jitable``). Every kernel module calls it first."""
    from erforce_interfaces.runtime.numba_support import numba, register_jitable

    for closed_form in (ball_distance, ball_speed, ball_time_to_distance, path_piece, path_index, path_point):
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
    from erforce_interfaces.runtime.numba_support import numba

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


def kick_distances(tau_s: np.ndarray, v_shoot_mps: np.ndarray, a_slide_mps2: float, a_roll_mps2: float,
                   c_switch: float) -> np.ndarray:
    """``kick_distance`` of many kicks at once: row i of ``tau_s`` (m, n) for the kick at ``v_shoot_mps[i]``, each row
    by the compiled kernel (a fit that tries many kicks over a few dozen times each would spend its time in Python's
    closed form otherwise)."""
    tau = np.ascontiguousarray(tau_s, dtype=float)
    out = np.empty(tau.shape)
    kernel = _array_kernel(_distance_many)
    for i, v in enumerate(np.asarray(v_shoot_mps, dtype=float).tolist()):
        kernel(ball_floats(0.0, 0.0, v, 0.0, v, float(a_slide_mps2), float(a_roll_mps2), float(c_switch)), tau[i],
               out[i])
    return out


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

    With ``walls`` (Walls, e.g. ``Walls.of_field(field)``) the path respects the field wall: it
    *reflects* there, by the wall's restitution (a parameter; 0 leaves the ball at the wall), and the
    ball goes on as it physically does rather than ending at the wall, because a ball that comes back
    off the wall into the field is one a robot can still get. The two-phase model continues from the
    bounce state: the wall's impulse reverses the normal speed (times the restitution) and cuts the
    speed along the wall by friction; the ball's rolling spin is untouched by it, so the ball slides
    (at ``a_slide``) until the slip has gone, then rolls (at ``a_roll``) to its stop or the next wall
    (``Walls``, ``_slide_off``: the model of the simulator's ball and wall, erforce_sim.ball and
    contacts). The path is then ``pieces``, straight two-phase pieces that end at a wall or where a
    slide ends; every query answers on them piecewise: ``distance_at`` and ``time_to_distance`` count
    along the path, ``stop_point`` is where the ball comes to rest. ``floats`` is the first piece
    (the ball now up to the first wall). Without walls there is one piece, the paper's straight line.
    """

    __slots__ = ("_offsets", "_rows", "_starts", "_table", "floats", "params", "pieces", "walls")

    def __init__(self, position_m, velocity_mps, v_shoot_mps: float, params: BallModelParams | None = None,
                 walls: Walls | None = None) -> None:
        params = BallModelParams() if params is None else params
        if not isinstance(params, BallModelParams):
            raise ValueError(f"params: expected BallModelParams, got {type(params).__name__}")
        if walls is not None and not isinstance(walls, Walls):
            raise ValueError(f"walls: expected Walls or None, got {type(walls).__name__}")
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
        self._init(ball_floats(x, y, vx, vy, v_shoot, params.a_slide_mps2, params.a_roll_mps2, params.c_switch),
                   params, walls)

    def _init(self, first: BallFloats, params: BallModelParams, walls: Walls | None,
              pieces: tuple[tuple[float, BallFloats], ...] | None = None) -> None:
        if pieces is None:
            pieces = ((0.0, first),) if walls is None else _pieces_within(first, walls, params)
        init = object.__setattr__
        init(self, "params", params)
        init(self, "walls", walls)
        init(self, "pieces", pieces)
        init(self, "floats", pieces[0][1])
        init(self, "_starts", tuple(t for t, _ in pieces))
        offsets, total = [], 0.0
        for _, f in pieces:
            offsets.append(total)
            total += f.stop_distance_m
        init(self, "_offsets", tuple(offsets))
        init(self, "_rows", tuple((t, *f) for t, f in pieces))
        init(self, "_table", None)

    @classmethod
    def of_floats(cls, x: float, y: float, vx: float, vy: float, v_shoot_mps: float,
                  params: BallModelParams, walls: Walls | None = None) -> BallTrajectory:
        """``BallTrajectory((x, y), (vx, vy), v_shoot_mps, params, walls)`` for plain floats: the same ball, the
        same checks (values that fail one go through the constructor, which names it), in a few comparisons."""
        if (type(params) is BallModelParams and (walls is None or type(walls) is Walls)
                and abs(x) <= MAX_POSITION_M and abs(y) <= MAX_POSITION_M
                and math.hypot(vx, vy) <= MAX_SPEED_MPS and 0.0 <= v_shoot_mps <= MAX_SPEED_MPS):
            ball = object.__new__(cls)  # NaN and inf fail the comparisons above
            ball._init(ball_floats(float(x), float(y), float(vx), float(vy), float(v_shoot_mps), params.a_slide_mps2,
                                   params.a_roll_mps2, params.c_switch), params, walls)
            return ball
        return cls((x, y), (vx, vy), v_shoot_mps, params, walls)

    @classmethod
    def of_pieces(cls, pieces, params: BallModelParams, walls: Walls | None = None) -> BallTrajectory:
        """A path of given straight pieces, ``(start time, BallFloats)`` each in order, the first from 0: e.g. a
        chipped ball's track on the ground (chip_model). Its queries answer piecewise; ``advanced`` needs walls."""
        if not pieces or pieces[0][0] != 0.0 or any(b[0] < a[0] for a, b in itertools.pairwise(pieces)):
            raise ValueError("pieces: (start time, BallFloats) in order of time, the first from 0")
        return _of_pieces(tuple((float(t), BallFloats(*f)) for t, f in pieces), params, walls)

    def within(self, walls: Walls | None) -> BallTrajectory:
        """The same ball now, its path bounded by ``walls`` (None: the unbounded straight line)."""
        if walls is self.walls:
            return self
        if walls is not None and not isinstance(walls, Walls):
            raise ValueError(f"walls: expected Walls or None, got {type(walls).__name__}")
        f = self.floats
        if len(self.pieces) > 1:  # the first piece ends at a wall: its numbers from the ball's state
            return BallTrajectory.of_floats(f.x_m, f.y_m, f.vx_mps, f.vy_mps, f.v_shoot_mps, self.params, walls)
        ball = object.__new__(BallTrajectory)
        ball._init(f, self.params, walls)
        return ball

    def __setattr__(self, name, value):
        raise AttributeError(f"BallTrajectory is immutable (cannot set {name})")

    def __delattr__(self, name):
        raise AttributeError(f"BallTrajectory is immutable (cannot delete {name})")

    def __reduce__(self):
        f = self.floats
        if len(self.pieces) > 1 or self._starts[0] != 0.0:  # e.g. advanced() on a wall: keep the pieces
            return _of_pieces, (self.pieces, self.params, self.walls)
        return BallTrajectory, ((f.x_m, f.y_m), (f.vx_mps, f.vy_mps), f.v_shoot_mps, self.params, self.walls)

    def __repr__(self) -> str:
        f = self.floats
        walls = "" if self.walls is None else f", walls={self.walls!r}"
        return (f"BallTrajectory(position_m=({f.x_m!r}, {f.y_m!r}), velocity_mps=({f.vx_mps!r}, {f.vy_mps!r}), "
                f"v_shoot_mps={f.v_shoot_mps!r}, params={self.params!r}{walls})")

    # -- properties -------------------------------------------------------------------------------
    position_m = property(lambda self: _read_only(self.floats.x_m, self.floats.y_m))
    velocity_mps = property(lambda self: _read_only(self.floats.vx_mps, self.floats.vy_mps))
    direction = property(lambda self: _read_only(self.floats.ux, self.floats.uy), doc="unit vector of motion")
    v_shoot_mps = property(lambda self: self.floats.v_shoot_mps)
    speed_mps = property(lambda self: self.floats.speed_mps)
    v_switch_mps = property(lambda self: self.floats.v_switch_mps)
    switch_time_s = property(lambda self: min(self.floats.switch_time_s, self.floats.stop_time_s),
                             doc="end of the kick's slide (at the first wall, when it comes first)")
    switch_distance_m = property(lambda self: min(self.floats.switch_distance_m, self.floats.stop_distance_m))
    stop_time_s = property(lambda self: self._starts[-1] + self.pieces[-1][1].stop_time_s)
    stop_distance_m = property(lambda self: self._offsets[-1] + self.pieces[-1][1].stop_distance_m,
                               doc="length of the path to the stop point")

    @property
    def table(self) -> np.ndarray:
        """The pieces as the compiled kernels read them (PIECE_COLUMNS; ``path_point``): not to be written."""
        if self._table is None:
            object.__setattr__(self, "_table", np.array(self._rows, dtype=float))
        return self._table

    rows = property(lambda self: self._rows, doc="the table as tuples, for the same functions run as Python")

    @property
    def bounce_points(self) -> np.ndarray:
        """Where the path turns (the starts of the pieces after the first), shape (n, 2)."""
        return _read_only(*(v for _, f in self.pieces[1:] for v in (f.x_m, f.y_m))).reshape(-1, 2)

    @property
    def phase(self) -> BallPhase:
        """The phase now: ``phase_at(0)``."""
        f = self.floats
        if self.stop_time_s <= 0.0:
            return BallPhase.STOPPED
        return BallPhase.SLIDING if f.switch_time_s > 0.0 else BallPhase.ROLLING

    @property
    def stop_point(self) -> np.ndarray:
        f = self.pieces[-1][1]
        return _read_only(f.x_m + f.ux * f.stop_distance_m, f.y_m + f.uy * f.stop_distance_m)

    @property
    def switch_point(self) -> np.ndarray:
        f, d = self.floats, self.switch_distance_m
        return _read_only(f.x_m + f.ux * d, f.y_m + f.uy * d)

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

    def _piece_at(self, t: float) -> int:
        return max(bisect.bisect_right(self._starts, t) - 1, 0)

    def _per_piece(self, loop, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``loop``'s answer on each time's own piece (its local time), and the piece of each time."""
        if len(self.pieces) == 1:
            return _many(loop, self.floats, t), np.zeros(t.shape, dtype=int)
        index = np.maximum(np.searchsorted(np.array(self._starts), t, side="right") - 1, 0)
        out = np.empty(t.shape)
        for i, (start, f) in enumerate(self.pieces):
            mask = index == i
            if mask.any():
                out[mask] = _many(loop, f, t[mask] - start)
        return out, index

    def distance_at(self, t_s) -> float | np.ndarray:
        """Distance travelled along the path after ``t_s`` seconds (monotone)."""
        t = self._time(t_s)
        if isinstance(t, float):
            i = self._piece_at(t)
            return self._offsets[i] + ball_distance(self.pieces[i][1], t - self._starts[i])
        d, index = self._per_piece(_distance_many, t)
        return d + np.array(self._offsets)[index] if len(self.pieces) > 1 else d

    def speed_at(self, t_s) -> float | np.ndarray:
        t = self._time(t_s)
        t_stop = self.stop_time_s
        if isinstance(t, float):
            i = self._piece_at(t)
            return 0.0 if t >= t_stop else ball_speed(self.pieces[i][1], t - self._starts[i])
        s = self._per_piece(_speed_many, t)[0]
        return np.where(t >= t_stop, 0.0, s)

    def _directions(self, t) -> tuple[np.ndarray | float, np.ndarray | float, np.ndarray | float, np.ndarray | float]:
        """(start x, start y, ux, uy) of the piece of each time, and the distance along it."""
        if len(self.pieces) == 1:
            f = self.floats
            return f.x_m, f.y_m, f.ux, f.uy
        index = np.maximum(np.searchsorted(np.array(self._starts), t, side="right") - 1, 0)
        rows = np.array([(f.x_m, f.y_m, f.ux, f.uy) for _, f in self.pieces])[index]
        return rows[..., 0], rows[..., 1], rows[..., 2], rows[..., 3]

    def position_at(self, t_s) -> np.ndarray:
        """Ball position (paper: ballAtTime); shape ``shape(t_s) + (2,)``."""
        t = self._time(t_s)
        if len(self.pieces) == 1:
            d = np.asarray(self.distance_at(t))
            f = self.floats
            return np.stack([f.x_m + f.ux * d, f.y_m + f.uy * d], axis=-1)
        t_arr = np.asarray(t, dtype=float)
        local, _ = self._per_piece(_distance_many, t_arr.reshape(-1))
        x0, y0, ux, uy = self._directions(t_arr.reshape(-1))
        return np.stack([x0 + ux * local, y0 + uy * local], axis=-1).reshape(t_arr.shape + (2,))

    def velocity_at(self, t_s) -> np.ndarray:
        t = self._time(t_s)
        s = np.asarray(self.speed_at(t))
        if len(self.pieces) == 1:
            return np.stack([self.floats.ux * s, self.floats.uy * s], axis=-1)
        _, _, ux, uy = self._directions(np.asarray(t, dtype=float).reshape(-1))
        return np.stack([ux * s.reshape(-1), uy * s.reshape(-1)], axis=-1).reshape(s.shape + (2,))

    def phase_at(self, t_s) -> BallPhase | np.ndarray:
        """``BallPhase`` (int8 codes for an array): sliding before its piece's switch, stopped from t_stop on."""
        t = self._time(t_s)
        t_arr = np.asarray(t, dtype=float)
        if len(self.pieces) == 1:
            switch, local = self.floats.switch_time_s, t_arr
        else:
            index = np.maximum(np.searchsorted(np.array(self._starts), t_arr, side="right") - 1, 0)
            switch = np.array([f.switch_time_s for _, f in self.pieces])[index]
            local = t_arr - np.array(self._starts)[index]
        phase = np.where(t_arr >= self.stop_time_s, BallPhase.STOPPED,
                         np.where(local < switch, BallPhase.SLIDING, BallPhase.ROLLING)).astype(np.int8)
        return BallPhase(int(phase)) if isinstance(t, float) else phase

    def time_to_distance(self, d_m) -> float | np.ndarray:
        """Time until the ball has travelled ``d_m`` along its path (paper: ballRollTime); +inf if it stops short."""
        d = float(d_m) if isinstance(d_m, _NUMBER) or np.ndim(d_m) == 0 else np.asarray(d_m, dtype=float)
        if np.isnan(d).any():
            raise ValueError(f"d_m: must not be NaN, got {d_m!r}")
        if (np.asarray(d) < 0.0).any():
            raise ValueError("d_m: must be >= 0")
        if len(self.pieces) == 1:
            if isinstance(d, float):
                return ball_time_to_distance(self.floats, d)
            return _many(_time_to_distance_many, self.floats, d)
        if isinstance(d, float):
            return self._time_to_path_distance(d)
        return np.vectorize(self._time_to_path_distance, otypes=[float])(d)

    def _time_to_path_distance(self, d: float) -> float:
        i = max(bisect.bisect_right(self._offsets, d) - 1, 0)
        f = self.pieces[i][1]
        rest = d - self._offsets[i]
        if i + 1 < len(self.pieces):
            rest = min(rest, f.stop_distance_m)  # a distance on the next piece's start is this one's end
        return self._starts[i] + ball_time_to_distance(f, rest)

    def time_in_field(self, field_config: FieldConfig, margin_m: float = 0.0) -> tuple[float, float]:
        """When the ball is inside the field lines (extended by ``margin_m``): ``(t_enter, t_leave)``.

        A straight path meets the field rectangle in one stretch. ``t_enter`` is 0 for a ball
        inside, the moment it crosses into the field for a ball outside heading in (off a wall, in
        the run-off area), +inf when it stops before. ``t_leave`` is when it crosses out again,
        +inf when it stops inside (or never enters). On a line counts as inside. A path off walls
        counts the same way: its first stretch inside, which may go on across bounces (a field margin
        reaching the wall) and may start after one (a ball in the run-off area comes back off the wall).
        """
        if not isinstance(field_config, FieldConfig):
            raise ValueError(f"field_config: expected FieldConfig, got {type(field_config).__name__}")
        if not math.isfinite(margin_m):
            raise ValueError(f"margin_m: must be finite, got {margin_m!r}")
        half = (field_config.half_length_m + margin_m, field_config.half_width_m + margin_m)
        if min(half) <= 0.0:
            raise ValueError(f"margin_m: {margin_m} leaves no field")
        t_enter = math.inf
        last = len(self.pieces) - 1
        for i, (start, f) in enumerate(self.pieces):
            t_in, t_out = _piece_in_field(f, half, ends_at_rest=i == last)
            if t_in == math.inf:
                if t_enter < math.inf:  # was inside up to the end of the previous piece: left at the bounce
                    return t_enter, start
                continue
            if t_enter == math.inf:
                t_enter = start + t_in
            elif t_in > 0.0:  # entered again after a gap
                return t_enter, start
            if t_out == math.inf:
                return t_enter, math.inf
            if t_out < f.stop_time_s or i == last:
                return t_enter, start + t_out
        return t_enter, math.inf

    def advanced(self, dt_s: float) -> BallTrajectory:
        """The same ball ``dt_s`` seconds later (same kick speed, so the phases stay consistent)."""
        dt = self._time(dt_s)
        if not isinstance(dt, float):
            raise ValueError(f"dt_s: one number, got {dt_s!r}")
        if self.walls is None:
            f = self.floats
            d, s = ball_distance(f, dt), ball_speed(f, dt)
            return BallTrajectory.of_floats(f.x_m + f.ux * d, f.y_m + f.uy * d, f.ux * s, f.uy * s, f.v_shoot_mps,
                                            self.params)
        i = self._piece_at(dt)
        rest = [(start - dt, f) for start, f in self.pieces[i + 1:]]
        return _of_pieces(((0.0, _piece_after(self.pieces[i][1], dt - self._starts[i])), *rest), self.params,
                          self.walls)


def _piece_in_field(f: BallFloats, half: tuple[float, float], ends_at_rest: bool) -> tuple[float, float]:
    """``(t_enter, t_leave)`` of one straight piece in the rectangle ``half`` (BallTrajectory.time_in_field);
    a piece that ends inside without coming to rest (at a bounce) leaves at its end."""
    s_in, s_out = 0.0, math.inf  # the stretch of the line inside, as distances along it
    for p, u, h in ((f.x_m, f.ux, half[0]), (f.y_m, f.uy, half[1])):
        if u == 0.0:
            if abs(p) > h:
                s_in = math.inf
            continue
        s1, s2 = (-h - p) / u, (h - p) / u
        s_in, s_out = max(s_in, min(s1, s2)), min(s_out, max(s1, s2))
    d_end = f.stop_distance_m
    if s_in > s_out or s_in > d_end:
        return math.inf, math.inf
    t_in = ball_time_to_distance(f, s_in) if s_in > 0.0 else 0.0
    if s_out > d_end:
        return t_in, math.inf if ends_at_rest else f.stop_time_s
    return t_in, ball_time_to_distance(f, s_out)


def _piece_after(f: BallFloats, t: float) -> BallFloats:
    """Piece ``f`` from its time ``t`` >= 0 on (at its end from ``f.stop_time_s`` on): its numbers then."""
    t = min(t, f.stop_time_s)
    d, s = ball_distance(f, t), ball_speed(f, t)
    sliding = t < f.switch_time_s
    return f._replace(x_m=f.x_m + f.ux * d, y_m=f.y_m + f.uy * d, vx_mps=f.ux * s, vy_mps=f.uy * s, speed_mps=s,
                      v_switch_mps=f.v_switch_mps if sliding else s,
                      switch_time_s=f.switch_time_s - t if sliding else 0.0,
                      switch_distance_m=f.switch_distance_m - d if sliding else 0.0,
                      stop_time_s=f.stop_time_s - t, stop_distance_m=f.stop_distance_m - d)


def _of_pieces(pieces, params: BallModelParams, walls: Walls | None) -> BallTrajectory:
    """A trajectory of given pieces (``advanced`` on a path off walls, unpickling)."""
    ball = object.__new__(BallTrajectory)
    ball._init(pieces[0][1], params, walls, tuple(pieces))
    return ball
