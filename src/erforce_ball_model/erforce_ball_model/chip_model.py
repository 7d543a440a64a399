"""A chipped ball: hops under gravity, then the two-phase roll (beyond the paper, whose model is flat).

The ball flies as a projectile (no air drag): from ``(p, z)`` with ``(v, vz)`` its centre is at
``p + v t`` and height ``z + vz t - g t^2 / 2``. It lands after ``T = (vz + sqrt(vz^2 + 2 g z)) / g``
(``2 vz / g`` from the ground), its apex is ``z + vz^2 / (2 g)``. At each touchdown it bounces by the
dampings of ``ChipParams`` (ball_model.py, the one home of the model's parameters): vertical speed
times ``damping_z``, horizontal velocity times ``damping_xy_first_hop`` at the first bounce and
``damping_xy_other_hops`` after. A bounce that leaves less than ``min_hop_vz_mps`` upwards hands the
ball over to the flat model: a ``BallTrajectory`` from the touchdown point with the damped horizontal
velocity, rolling (the bounces' friction has matched its spin to its speed).

Heights ``z`` are of the ball's centre above where it rests on the carpet (0 on the ground).

>>> from erforce_ball_model.ball_model import ChipParams
>>> chip = ChipTrajectory((0.0, 0.0, 0.0), (3.0, 0.0, 3.0), ChipParams())  # 4.24 m/s at 45 deg along +x
>>> round(chip.apex_height_m, 3), round(float(chip.touchdown_times_s[0]), 3)  # vz^2 / 2g, 2 vz / g
(0.459, 0.612)
>>> chip.touchdown_points_m[0].round(3).tolist()
[1.835, 0.0]
>>> round(chip.time_below_height_s(), 3)  # from then on a robot's body stops it (ChipParams.max_catch_height_m)
0.557
>>> [(round(a, 3), round(b, 3)) for a, b in chip.low_windows_s()]  # when it is low enough: just kicked, then landed
[(0.0, 0.055), (0.557, inf)]
>>> round(chip.time_below_height_s(chip.params.max_receive_height_m), 3)  # a dribbler takes it (hops < a radius)
1.128

Catch times (catch_time.CatchSearch) search the ball's ``ground_track`` (where its shadow is: the hops as
straight pieces at constant speed, then the roll) only within its ``low_windows_s``, a receiver's only from
``time_below_height_s(max_receive_height_m)`` on.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from erforce_ball_model.ball_model import (
    MAX_POSITION_M,
    MAX_SPEED_MPS,
    BallFloats,
    BallModelParams,
    BallTrajectory,
    ChipParams,
)
from erforce_ball_model.walls import Walls

__all__ = ["MAX_HOPS", "PHASE_CHIP", "PHASE_HOPPING", "ChipHop", "ChipTrajectory", "chip_settle_distance",
           "flying_ball"]

# /ball/phase of a chipped ball from its detection until its first touchdown, then until it rolls
# (erforce_interfaces.wire.contract.BALL_PHASES says the same)
PHASE_CHIP, PHASE_HOPPING = "chip", "hopping"

# A ball still hopping after this many bounces (dampings near 1) rolls on from there.
MAX_HOPS = 100
_NUMBER = int | float | np.floating | np.integer


class ChipHop(NamedTuple):
    """One flight: its start (time, ground point, height) and launch velocity, and how long it lasts."""

    t_start_s: float
    x_m: float
    y_m: float
    z_m: float
    vx_mps: float
    vy_mps: float
    vz_mps: float
    duration_s: float


def _hops(x, y, z, vx, vy, vz, p: ChipParams,
          bounced: bool = False) -> tuple[tuple[ChipHop, ...], tuple[float, float, float, float, float]]:
    """The flights of a ball at ``(x, y, z)`` with ``(vx, vy, vz)`` and where it rolls from: (t, x, y, vx, vy);
    ``bounced``: it has touched down since the kick (its next bounce damps as a later one)."""
    g, hops, t = p.g_mps2, [], 0.0
    if z <= 0.0 and vz < p.min_hop_vz_mps:  # on the ground, not leaving it: no flight
        return (), (0.0, x, y, vx, vy)
    while True:
        v_land = math.sqrt(vz * vz + 2.0 * g * z)  # vertical speed at touchdown (downwards)
        duration = (vz + v_land) / g
        hops.append(ChipHop(t, x, y, z, vx, vy, vz, duration))
        damping = p.damping_xy_first_hop if len(hops) == 1 and not bounced else p.damping_xy_other_hops
        t, x, y = t + duration, x + vx * duration, y + vy * duration
        z, vx, vy, vz = 0.0, vx * damping, vy * damping, v_land * p.damping_z
        if vz < p.min_hop_vz_mps or len(hops) >= MAX_HOPS:
            return tuple(hops), (t, x, y, vx, vy)


def _finite_values(name: str, value, n: int) -> tuple[float, ...]:
    values = np.asarray(value, dtype=float) if not isinstance(value, str) else None
    if values is None or values.shape != (n,):
        raise ValueError(f"{name}: one ball, {n} numbers, got {value!r}")
    if not np.isfinite(values).all():
        raise ValueError(f"{name}: must be finite, got {value!r}")
    return tuple(float(v) for v in values)


class ChipTrajectory:
    """The future of one chipped ball: its hops, then its roll as a ``BallTrajectory``. Immutable.

    ``position_m`` is ``(x, y, z)`` (z of the centre above its resting height, >= 0), ``velocity_mps``
    ``(vx, vy, vz)``. Queries take a time (float out) or an array of times (array out, plus a trailing 3
    for vectors); a time at or after the hand-over asks the roll.
    """

    __slots__ = ("_ends", "_hop_rows", "_starts", "_track", "bounced", "hops", "params", "roll", "roll_start_s")

    def __init__(self, position_m, velocity_mps, params: ChipParams,
                 ball_params: BallModelParams | None = None, bounced: bool = False) -> None:
        ball_params = BallModelParams() if ball_params is None else ball_params
        if not isinstance(params, ChipParams) or not isinstance(ball_params, BallModelParams):
            raise ValueError(f"params, ball_params: expected ChipParams and BallModelParams, got "
                             f"{type(params).__name__} and {type(ball_params).__name__}")
        x, y, z = _finite_values("position_m", position_m, 3)
        vx, vy, vz = _finite_values("velocity_mps", velocity_mps, 3)
        if z < 0.0:
            raise ValueError(f"position_m: height z must be >= 0 (the carpet), got {z}")
        if max(abs(x), abs(y), z) > MAX_POSITION_M or math.sqrt(vx * vx + vy * vy + vz * vz) > MAX_SPEED_MPS:
            raise ValueError(f"position_m / velocity_mps: beyond {MAX_POSITION_M} m or {MAX_SPEED_MPS} m/s")
        hops, (t_roll, rx, ry, rvx, rvy) = _hops(x, y, z, vx, vy, vz, params, bool(bounced))
        # rolling from the start: kicked at speed / c_switch, the fastest kick that rolls at this speed
        v_shoot = min(math.hypot(rvx, rvy) / ball_params.c_switch, MAX_SPEED_MPS)
        _init(self, params, hops, BallTrajectory.of_floats(rx, ry, rvx, rvy, v_shoot, ball_params), t_roll,
              bool(bounced))

    def __setattr__(self, name, value):
        raise AttributeError(f"ChipTrajectory is immutable (cannot set {name})")

    def __delattr__(self, name):
        raise AttributeError(f"ChipTrajectory is immutable (cannot delete {name})")

    def __reduce__(self):
        return _of_parts, (self.params, self.hops, self.roll, self.roll_start_s, self.bounced)

    def __repr__(self) -> str:
        return (f"ChipTrajectory(position_m={self.position_m.tolist()!r}, velocity_mps={self.velocity_mps.tolist()!r}, "
                f"params={self.params!r}, ball_params={self.roll.params!r}, bounced={self.bounced!r})")

    # -- properties -------------------------------------------------------------------------------
    @property
    def position_m(self) -> np.ndarray:
        return self.position_at(0.0)

    @property
    def velocity_mps(self) -> np.ndarray:
        return self.velocity_at(0.0)

    @property
    def touchdown_times_s(self) -> np.ndarray:
        """When the ball lands after each flight (the last one is the hand-over to rolling)."""
        return _read_only(self._ends)

    @property
    def touchdown_points_m(self) -> np.ndarray:
        """Where the ball lands after each flight, shape (n, 2)."""
        points = np.array([(h.x_m + h.vx_mps * h.duration_s, h.y_m + h.vy_mps * h.duration_s) for h in self.hops])
        return _read_only(points.reshape(-1, 2))

    @property
    def apex_height_m(self) -> float:
        """The highest the ball gets (its height now when it only falls or rolls)."""
        return max((_apex(h, self.params.g_mps2) for h in self.hops), default=0.0)

    stop_time_s = property(lambda self: self.roll_start_s + self.roll.stop_time_s)
    stop_point = property(lambda self: self.roll.stop_point)

    # -- queries ----------------------------------------------------------------------------------
    def time_below_height_s(self, height_m: float | None = None) -> float:
        """From when on the ball's centre stays at most ``height_m`` high (None: ``max_catch_height_m``)."""
        h = self.params.max_catch_height_m if height_m is None else height_m
        if not isinstance(h, _NUMBER) or not math.isfinite(h) or h < 0.0:
            raise ValueError(f"height_m: must be a finite number >= 0, got {height_m!r}")
        return _settled(self.hops, h, self.params.g_mps2)[0]

    def low_windows_s(self, height_m: float | None = None) -> tuple[tuple[float, float], ...]:
        """The stretches of time ``(start, end)``, in order, in which the ball's centre is at most ``height_m``
        high (None: ``max_catch_height_m``): where a robot can take it. The last one ends at +inf."""
        h = self.params.max_catch_height_m if height_m is None else height_m
        if not isinstance(h, _NUMBER) or not math.isfinite(h) or h < 0.0:
            raise ValueError(f"height_m: must be a finite number >= 0, got {height_m!r}")
        g, windows, start = self.params.g_mps2, [], 0.0
        for hop in self.hops:
            if _apex(hop, g) <= h:
                continue
            root = math.sqrt(max(hop.vz_mps**2 + 2.0 * g * (hop.z_m - h), 0.0))
            up = hop.t_start_s + max((hop.vz_mps - root) / g, 0.0)  # rises through h (or starts above it)
            down = hop.t_start_s + (hop.vz_mps + root) / g  # comes down through h
            if up > start:
                windows.append((start, up))
            start = down
        windows.append((start, math.inf))
        return tuple(windows)

    def ground_track(self, walls: Walls | None = None) -> BallTrajectory:
        """Where the ball is on the field (its centre's x, y) as a path of straight pieces: each hop at its
        constant horizontal velocity up to its touchdown, then the roll's pieces (off ``walls``, if given:
        the roll only; a ball in the air flies over the wall's line). For queries (``position_at``,
        ``time_in_field``, ``time_to_distance``, ``table``) and the catch search; to move it on, advance the chip.
        Without walls it is made once per chip (the catch search asks for it several times)."""
        if walls is None and self._track is not None:
            return self._track
        pieces = [(h.t_start_s, _flight_floats(h)) for h in self.hops]
        roll = self.roll.within(walls)
        pieces += [(self.roll_start_s + t, f) for t, f in roll.pieces]
        track = BallTrajectory.of_pieces(pieces, roll.params, walls)
        if walls is None:
            object.__setattr__(self, "_track", track)
        return track

    def position_at(self, t_s) -> np.ndarray:
        """Where the ball's centre is: ``(x, y, z)``, shape ``shape(t_s) + (3,)``."""
        return self._state_at(t_s, velocity=False)

    def velocity_at(self, t_s) -> np.ndarray:
        """``(vx, vy, vz)``; at a touchdown instant the velocity after the bounce."""
        return self._state_at(t_s, velocity=True)

    def advanced(self, dt_s: float) -> ChipTrajectory:
        """The same ball ``dt_s`` seconds later (its hops so far counted: a later bounce damps as a later one)."""
        dt = BallTrajectory._time(dt_s)
        if not isinstance(dt, float):
            raise ValueError(f"dt_s: one number, got {dt_s!r}")
        if dt >= self.roll_start_s:
            hops, roll, t_roll, i = (), self.roll.advanced(dt - self.roll_start_s), 0.0, len(self.hops)
        else:
            i = int(np.searchsorted(self._starts, dt, side="right")) - 1
            h = self.hops[i]
            tau, g = dt - h.t_start_s, self.params.g_mps2
            now = ChipHop(0.0, h.x_m + h.vx_mps * tau, h.y_m + h.vy_mps * tau,
                          max(h.z_m + tau * (h.vz_mps - 0.5 * g * tau), 0.0), h.vx_mps, h.vy_mps, h.vz_mps - g * tau,
                          h.duration_s - tau)
            hops = (now, *(k._replace(t_start_s=k.t_start_s - dt) for k in self.hops[i + 1:]))
            roll, t_roll = self.roll, self.roll_start_s - dt
        return _of_parts(self.params, hops, roll, t_roll, self.bounced or i > 0)

    def sensitivity_at(self, t_s: float) -> np.ndarray:
        """How the state ``(x, y, z, vx, vy, vz)`` at ``t_s`` (before the roll) moves with the start state: the
        (6, 6) derivative, to carry a covariance along the flight. Within a hop the projectile's, ``p += v t``; at
        each touchdown the bounce's saltation matrix (the dampings, and the touchdown time moving with the height:
        a ball a little higher lands a little later, ``dT = dz / |vz|``)."""
        t = BallTrajectory._time(t_s)
        if not isinstance(t, float) or not 0.0 <= t < self.roll_start_s:
            raise ValueError(f"t_s: one time in [0, {self.roll_start_s}) (in the air), got {t_s!r}")
        p, g, out = self.params, self.params.g_mps2, np.eye(6)
        for k, hop in enumerate(self.hops):
            tau = min(t - hop.t_start_s, hop.duration_s)
            flow = np.eye(6)
            flow[0, 3] = flow[1, 4] = flow[2, 5] = tau
            out = flow @ out
            if t < hop.t_start_s + hop.duration_s:
                return out
            d_xy = p.damping_xy_first_hop if k == 0 and not self.bounced else p.damping_xy_other_hops
            vz_in = hop.vz_mps - g * hop.duration_s  # < 0: landing
            reset = np.diag([1.0, 1.0, 1.0, d_xy, d_xy, -p.damping_z])
            # f+ - R f- over vz-: the bounce's effect of landing dz / |vz| later (the flows before and after it)
            jump = np.array([(d_xy - 1.0) * hop.vx_mps, (d_xy - 1.0) * hop.vy_mps, -(1.0 + p.damping_z) * vz_in,
                             0.0, 0.0, -(1.0 + p.damping_z) * g]) / vz_in
            reset[:, 2] += jump
            out = reset @ out
        return out

    def _state_at(self, t_s, velocity: bool) -> np.ndarray:
        t = np.asarray(BallTrajectory._time(t_s), dtype=float)
        flat = t.reshape(-1)
        out = np.zeros(flat.shape + (3,))
        in_air = flat < self.roll_start_s
        if in_air.any():
            ta = flat[in_air]
            i = np.searchsorted(self._starts, ta, side="right") - 1
            hop = self._hop_rows[i]  # columns: ChipHop's fields
            tau, g = ta - hop[:, 0], self.params.g_mps2
            if velocity:
                out[in_air] = np.stack([hop[:, 4], hop[:, 5], hop[:, 6] - g * tau], axis=-1)
            else:
                out[in_air] = np.stack([hop[:, 1] + hop[:, 4] * tau, hop[:, 2] + hop[:, 5] * tau,
                                        np.maximum(hop[:, 3] + tau * (hop[:, 6] - 0.5 * g * tau), 0.0)], axis=-1)
        if not in_air.all():
            tr = flat[~in_air] - self.roll_start_s
            out[~in_air, :2] = self.roll.velocity_at(tr) if velocity else self.roll.position_at(tr)
        return out.reshape(t.shape + (3,))


def _init(ball: ChipTrajectory, params: ChipParams, hops: tuple[ChipHop, ...], roll: BallTrajectory,
          roll_start_s: float, bounced: bool) -> None:
    init = object.__setattr__
    init(ball, "bounced", bounced)
    init(ball, "params", params)
    init(ball, "hops", tuple(ChipHop(*h) for h in hops))
    init(ball, "roll_start_s", roll_start_s)
    init(ball, "roll", roll)
    init(ball, "_starts", np.array([h.t_start_s for h in hops]))
    init(ball, "_ends", np.array([h.t_start_s + h.duration_s for h in hops]))
    init(ball, "_hop_rows", np.array(ball.hops, dtype=float).reshape(-1, len(ChipHop._fields)))
    init(ball, "_track", None)


def _of_parts(params: ChipParams, hops, roll: BallTrajectory, roll_start_s: float,
              bounced: bool) -> ChipTrajectory:
    """A chip of given hops and roll (``advanced``, unpickling)."""
    ball = object.__new__(ChipTrajectory)
    _init(ball, params, hops, roll, roll_start_s, bounced)
    return ball


def flying_ball(position_m, velocity_mps, params: ChipParams, ball_params: BallModelParams | None = None,
                bounced: bool = False) -> ChipTrajectory | None:
    """The ball of a state ``(x, y, z)``, ``(vx, vy, vz)`` (as /ball/state carries it: z of the centre above
    its rest, 0 on the ground) as a ChipTrajectory while it is in the air (z > 0 or vz > 0), else None
    (a ball on the ground: the flat model's). ``bounced``: it has touched down since the kick (/ball/phase
    "hopping"), so its next bounce damps as a later one. The one conversion of a ball state to a chip."""
    z, vz = float(position_m[2]), float(velocity_mps[2])
    if not (z > 0.0 or vz > 0.0):
        return None
    return ChipTrajectory(position_m, velocity_mps, params, ball_params, bounced)


def _flight_floats(hop: ChipHop) -> BallFloats:
    """One hop's shadow on the carpet as a straight piece of constant speed (no deceleration) up to its end."""
    speed = math.hypot(hop.vx_mps, hop.vy_mps)
    ux, uy = (hop.vx_mps / speed, hop.vy_mps / speed) if speed > 0.0 else (0.0, 0.0)
    return BallFloats(hop.x_m, hop.y_m, hop.vx_mps, hop.vy_mps, ux, uy, speed, speed, speed, 0.0, 0.0,
                      hop.duration_s, speed * hop.duration_s, 0.0, 0.0)


def _settled(hops: tuple[ChipHop, ...], h: float, g: float) -> tuple[float, float]:
    """When the ball comes down through ``h`` for the last time, and how far along the carpet it has flown then
    (0, 0: never above it)."""
    for hop in reversed(hops):
        if _apex(hop, g) > h:  # the last flight above h: it comes down through h
            tau = (hop.vz_mps + math.sqrt(hop.vz_mps**2 + 2.0 * g * (hop.z_m - h))) / g
            return hop.t_start_s + tau, math.hypot(hop.x_m + hop.vx_mps * tau, hop.y_m + hop.vy_mps * tau)
    return 0.0, 0.0


def chip_settle_distance(speed_mps: float, angle_deg: float, params: ChipParams) -> float:
    """How far along the carpet a chip kicked from the ground at ``speed_mps`` and ``angle_deg`` flies until it
    stays at most ``params.max_receive_height_m`` high: ``ChipTrajectory.time_below_height_s``'s point, without
    building the trajectory (a pass's kick speed is searched with it)."""
    a = math.radians(angle_deg)
    hops, _ = _hops(0.0, 0.0, 0.0, speed_mps * math.cos(a), 0.0, speed_mps * math.sin(a), params)
    return _settled(hops, params.max_receive_height_m, params.g_mps2)[1]


def _apex(hop: ChipHop, g: float) -> float:
    return hop.z_m + max(hop.vz_mps, 0.0) ** 2 / (2.0 * g)


def _read_only(a: np.ndarray) -> np.ndarray:
    a = np.array(a, dtype=float)
    a.setflags(write=False)
    return a
