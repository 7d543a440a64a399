"""Robot-to-ball time (ER-Force ETDP 2016, Sec. 5.5: robotTimeToPos and Algorithm 2 robotTimeToBall).

robotTimeToPos (``robot_time_to_pos``): a 2D bang-bang time estimate from the robot's position and
field-frame velocity to *arriving at rest* at the target (a robot that arrives with speed overshoots the
catch point). ``a_max`` and ``v_max`` are split between the axes by an angle alpha, bisected until both
axes arrive together (the "alpha search" of Purwin & D'Andrea / TIGERs, implemented from scratch); per
axis the 1D time is closed-form, and an axis already faster than its share keeps its speed, which keeps
the time monotone in the split. The bisection stops on a certificate bracketing the synchronized time.

Reachability without the search (``can_reach``): for robotTimeToBall only the sign of
``t_robot(t) - t`` matters. For a budget T each axis needs a minimal acceleration A_i (closed form), and
the robot makes it iff ``A_x^2 + A_y^2 <= a_max^2``: the exact sign, with no iteration.

robotTimeToBall (beyond the paper): ``f(t) = t_robot(ball_position_at(t) - offset) - t`` is sampled per
robot on a grid of step h over ``[t_in, min(t_stop, t_out)]``, the stretch of the path inside the field
(``BallTrajectory.time_in_field``; ``t_in`` > 0 is a ball rolling back in off a wall, which the paper's
``t_out`` = 0 would never search). A path with ``Walls`` is followed piece by piece. Guarantee: a catch
window at least h wide is never missed, and the returned time is feasible and at most
``h / refine_points`` late (78 us with the defaults); one narrow window is never missed however narrow:
the moment the ball passes the robot's own braking point, tested exactly (a robot standing on a fast
ball's path). The crossing is refined by sub-grid passes, which also copes with the discontinuity of f
the paper mentions. Without a window the paper's fallback holds: robotTimeToPos to the stop point.
A cheap sound bound (catch_time_kernels' ``_may_reach``) skips the exact test where the robot surely cannot make it.

Chipped balls (beyond the paper): a ``ChipTrajectory`` (chip_model) is within a robot's reach only while it is
low, and how low depends on what the robot does with it (ChipParams). A robot that intercepts stops it with its
body: the ball's centre at most ``max_catch_height_m`` high, in each of the chip's ``low_windows_s`` (just after
the kick, near the touchdowns of hops that rise above the height, and from when it stays below it). A robot that
receives (``receiving``) must take it with its dribbler, under the light barrier's beam: only from when the chip
stays at most ``max_receive_height_m`` high (``time_below_height_s``); near a touchdown of a higher hop the ball
bounces up over the bar or off the robot's front. The search runs on the chip's ``ground_track`` (the hops'
shadows as straight pieces, then the roll) within each window in turn; a robot's catch is its first window there,
so a robot under the flight cannot take the ball while it is above its height. Each window is searched as the
flat ball's interval, with the same guarantee inside it.

Compiled scalar loops: the search is a few hundred branchy scalar steps per robot, too many small
array operations as numpy (docs/decisions/0028), so it is compiled by numba (catch_time_kernels: four entry
points, robot_time_to_block's among them, for fixed float64 signatures, cached on disk) on a process's first
search, not at import: the catcher, which asks ``can_reach`` a few dozen times per tick, runs it as Python
without numba. The ball enters a kernel as its table of pieces (``BallTrajectory.table``) and moves by
ball_model's own closed forms compiled into it. ``CatchSearch`` checks a team's limits and allocates once, so
the predictor pays one compiled call per frame; ``robot_time_to_ball`` is the one-off form.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from erforce_ball_model.ball_model import BallTrajectory
from erforce_ball_model.catch_time_kernels import (
    CatchKind,
    block_search_loop,
    catch_search_loop,
    compiled_kernels,
    kernels_loaded,
    load_kernels,
    load_kernels_in_background,
    reachable,
)
from erforce_ball_model.chip_model import ChipTrajectory
from erforce_interfaces.runtime.param_schema import schema_defaults
from erforce_interfaces.wire.robot_config import FieldConfig, RobotConfig

__all__ = [
    "MAX_RECEIVE_ANGLE_RAD",
    "ROBOT_A_MAX_MPS2",
    "ROBOT_V_MAX_MPS",
    "CatchKind",
    "CatchResult",
    "CatchSearch",
    "RobotLimits",
    "can_reach",
    "can_reach_in_time",
    "catch_after_reaction",
    "contact_offset",
    "facing_angles",
    "load_kernels",
    "receive_facing",
    "robot_time_curve",
    "robot_time_to_ball",
    "robot_time_to_block",
    "robot_time_to_pos",
]

DEFAULT_DRIBBLER_OFFSET_M = RobotConfig().dribbler_offset_m
_PREDICTOR = schema_defaults("erforce_ball_model", "ball_predictor")  # the search's defaults are the node's
# The robot's limits for catching: what robotTimeToPos plans with and the catcher drives with. The one
# default of each: CatcherConfig and both nodes' schemas (default_from) take it from here.
ROBOT_A_MAX_MPS2 = 4.5
ROBOT_V_MAX_MPS = 2.5
# Vision latency, tracking and control lag: a robot acts on a prediction (a kick) this much later. The
# predictor's and the passing game's reaction_s (default_from).
ROBOT_REACTION_S = 0.1
# A longer search (a ball that takes hours to stop, from an absurd deceleration) is refused, not run:
# realistic horizons are seconds (about 2,200 points for a 6.5 m/s ball at the default 10 ms step).
MAX_GRID_POINTS = 1_000_000
# Receiving facing somewhere else than against the ball (receive_facing): the largest angle between the
# dribbler's direction and the ball's incoming direction reversed. Aimed at the dribbler centre, the ball
# meets the flat front face for any angle below 90 deg, but a ball whose path is e off the aim touches the
# face e / cos(angle) off the dribbler centre, and the dribbler only holds it within half its width
# (RobotConfig.dribbler_width_m, 35 mm). The receiver stands still once it is within 20 mm of the ball's
# line (CatcherConfig.receive_line_tolerance_m): 20 / cos(angle) <= 35 mm needs angle <= 55 deg; 45 deg
# (28 mm) keeps a margin for the ball's sideways slip along the face (its speed times sin(angle)).
MAX_RECEIVE_ANGLE_RAD = math.radians(45.0)


def _kernel_array(x) -> np.ndarray:
    """``x`` as the compiled functions take arrays: float64, C-contiguous, writeable (copied if not)."""
    a = np.ascontiguousarray(x, dtype=float)  # ``x`` itself when it already is one (no np.require overhead)
    return a if a.flags.writeable else a.copy()


@dataclass(frozen=True, eq=False)
class RobotLimits:
    """Acceleration and speed limits of one robot or of many robots (arrays broadcast)."""

    a_max_mps2: np.ndarray | float = ROBOT_A_MAX_MPS2
    v_max_mps: np.ndarray | float = ROBOT_V_MAX_MPS

    def __post_init__(self) -> None:
        for name in ("a_max_mps2", "v_max_mps"):
            arr = np.array(getattr(self, name), dtype=float)
            if not np.isfinite(arr).all() or (arr <= 0.0).any():
                raise ValueError(f"{name}: must be finite and > 0, got {getattr(self, name)!r}")
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)
        try:
            np.broadcast_shapes(self.a_max_mps2.shape, self.v_max_mps.shape)
        except ValueError:
            raise ValueError(
                f"a_max_mps2 {self.a_max_mps2.shape} and v_max_mps {self.v_max_mps.shape} do not broadcast"
            ) from None


def _vec2(name: str, value) -> np.ndarray:
    arr = np.asarray(value, dtype=float)
    if arr.ndim < 1 or arr.shape[-1] != 2:
        raise ValueError(f"{name}: last axis must have length 2, got shape {arr.shape}")
    if not np.isfinite(arr).all():
        raise ValueError(f"{name}: must be finite")
    return arr


def _limits_arrays(limits: RobotLimits, shape) -> tuple[np.ndarray, np.ndarray]:
    if not isinstance(limits, RobotLimits):
        raise ValueError(f"limits: expected RobotLimits, got {type(limits).__name__}")
    try:
        a = np.broadcast_to(limits.a_max_mps2, shape)
        v = np.broadcast_to(limits.v_max_mps, shape)
    except ValueError:
        raise ValueError(f"limits of shape {limits.a_max_mps2.shape} do not fit {shape}") from None
    return a, v


def robot_time_to_pos(robot_pos_m, robot_vel_mps, target_m, limits: RobotLimits,
                      tol_s: float = 1e-7) -> float | np.ndarray:
    """Time (s) for a robot to reach ``target_m`` and stop there (paper: robotTimeToPos).

    Arrays broadcast: positions/velocities/targets ``(..., 2)``, limits per robot; one robot and
    one target give a float. The split angle alpha solves ``t_x(alpha) = t_y(alpha)``
    (catch_time_kernels). Returns an achievable time (an upper bound) certified to be within
    ``tol_s`` of the synchronized time.

    >>> round(robot_time_to_pos((0.0, 0.0), (0.0, 0.0), (2.0, 0.0), RobotLimits(a_max_mps2=2.0, v_max_mps=3.0)), 3)
    2.0
    """
    p0 = _vec2("robot_pos_m", robot_pos_m)
    v0 = _vec2("robot_vel_mps", robot_vel_mps)
    tgt = _vec2("target_m", target_m)
    if not (math.isfinite(tol_s) and tol_s > 0.0):
        raise ValueError(f"tol_s: must be finite and > 0, got {tol_s!r}")
    d = tgt - p0
    shape = np.broadcast_shapes(d.shape, v0.shape)[:-1]
    d = np.broadcast_to(d, (*shape, 2)).reshape(-1, 2)
    v0 = np.broadcast_to(v0, (*shape, 2)).reshape(-1, 2)
    a, vmax = (_kernel_array(np.ravel(x)) for x in _limits_arrays(limits, shape))
    out = np.empty(a.shape)
    compiled_kernels().time_to_pos_many(_kernel_array(d[:, 0]), _kernel_array(d[:, 1]), _kernel_array(v0[:, 0]),
                      _kernel_array(v0[:, 1]), a, vmax, tol_s, out)
    return float(out[0]) if shape == () else out.reshape(shape)


def can_reach_in_time(d_m, w_mps, t_budget_s, a_max_mps2, v_max_mps) -> np.ndarray:
    """True where the alpha-split bang-bang robot covers ``d_m`` (..., 2) and stops within the budget.

    Exact sign test for ``robot_time_to_pos(...) <= t_budget_s`` without the alpha search.
    """
    d = np.asarray(d_m, dtype=float)
    w = np.asarray(w_mps, dtype=float)
    args = np.broadcast_arrays(d[..., 0], d[..., 1], w[..., 0], w[..., 1], t_budget_s, a_max_mps2, v_max_mps)
    out = np.empty(args[0].shape, dtype=bool)
    compiled_kernels().can_reach_many(*(_kernel_array(x).ravel() for x in args), out.ravel())
    return out


def can_reach(d_m, w_mps, t_budget_s: float, a_max_mps2: float, v_max_mps: float) -> bool:
    """``can_reach_in_time`` for one robot and one target, in plain Python (no numba, no arrays).

    For a caller with a few targets per call (the catcher's receive points): numba stays unloaded
    and a case costs a few microseconds. ``d_m`` and ``w_mps`` are (x, y) pairs; a negative budget
    is never enough.

    >>> can_reach((2.0, 0.0), (0.0, 0.0), 2.0, 2.0, 3.0), can_reach((2.0, 0.0), (0.0, 0.0), 1.99, 2.0, 3.0)
    (True, False)
    """
    if not t_budget_s >= 0.0:
        return False
    return reachable(float(d_m[0]), float(d_m[1]), float(w_mps[0]), float(w_mps[1]), float(t_budget_s),
                      float(a_max_mps2), float(v_max_mps))


@dataclass(frozen=True, eq=False)
class CatchResult:
    """Per robot: catch time, where the ball and the robot centre are then, and which case applied.

    Arrays over the robots (R,) and (R, 2); for a single-robot call of ``robot_time_to_ball`` a float,
    two (2,) arrays and a CatchKind.
    """

    time_s: np.ndarray | float
    ball_position_m: np.ndarray
    robot_target_m: np.ndarray
    kind: np.ndarray | CatchKind


_MOVING, _NEVER = int(CatchKind.MOVING), int(CatchKind.NEVER)


def _check_field(field: FieldConfig | None, unbounded: bool) -> None:
    if field is None and not unbounded:
        raise ValueError("field: the search ends where the ball leaves the field: give the FieldConfig, or "
                         "unbounded=True to follow the ball until it stops wherever that is")
    if field is not None and unbounded:
        raise ValueError("field and unbounded=True: give one of them")


class CatchSearch:
    """robotTimeToBall for a fixed team of ``num_robots``, prepared once and run every vision frame.

    ``field`` (FieldConfig) bounds the search to the ball's stretch inside it; ``unbounded=True`` is the
    explicit choice of no field (the paper's interval up to the ball's stop, wherever that is).

    The limits, dribbler offset, field and grid are checked at construction and the outputs are
    allocated once, so ``run`` is a few checks and one compiled call (the predictor's hot path).
    The arrays of the returned CatchResult are reused by the next ``run``: copy what you keep.
    """

    def __init__(
        self,
        num_robots: int,
        limits: RobotLimits,
        *,
        dribbler_offset_m: float = DEFAULT_DRIBBLER_OFFSET_M,
        field: FieldConfig | None = None,
        unbounded: bool = False,
        field_margin_m: float = _PREDICTOR["field_margin_m"],
        grid_step_s: float = _PREDICTOR["grid_step_s"],
        refine_points: int = 128,
        kernels: str = "now",
    ) -> None:
        _check_field(field, unbounded)
        if kernels not in ("now", "background"):
            raise ValueError(f"kernels: 'now' or 'background', got {kernels!r}")
        if not (isinstance(num_robots, int) and num_robots >= 1):
            raise ValueError(f"num_robots: must be an int >= 1, got {num_robots!r}")
        if not (math.isfinite(dribbler_offset_m) and dribbler_offset_m >= 0.0):
            raise ValueError(f"dribbler_offset_m: must be finite and >= 0, got {dribbler_offset_m!r}")
        if not (math.isfinite(grid_step_s) and grid_step_s > 0.0):
            raise ValueError(f"grid_step_s: must be finite and > 0, got {grid_step_s!r}")
        if refine_points < 2:
            raise ValueError("refine_points: must be >= 2")
        if field is not None and not isinstance(field, FieldConfig):
            raise ValueError(f"field: expected FieldConfig or None, got {type(field).__name__}")
        self.num_robots = num_robots
        self._a, self._vmax = (_kernel_array(x) for x in _limits_arrays(limits, (num_robots,)))
        self._offset_m, self._field, self._margin_m, self._h = dribbler_offset_m, field, field_margin_m, grid_step_s
        m1 = math.ceil(math.sqrt(refine_points))
        self._m1, self._m2 = (m1, math.ceil(refine_points / m1)) if m1 > 2 else (refine_points, 0)
        self._rest_tol_s = grid_step_s / refine_points
        self._facing = np.zeros(num_robots)
        self._load_after_run = False
        self._search = None  # the compiled search, once loaded (kernels="background": the Python loop until then)
        if kernels == "now":
            self._search = compiled_kernels().catch_search
        self._result = CatchResult(np.empty(num_robots), np.empty((num_robots, 2)), np.empty((num_robots, 2)),
                                   np.empty(num_robots, dtype=np.int8))

    @property
    def limits(self) -> RobotLimits:
        """The robots' limits the search plans with (one per robot)."""
        return RobotLimits(self._a.copy(), self._vmax.copy())

    @property
    def compiled(self) -> bool:
        """Whether its answers come from the compiled kernels (kernels="background": once they are loaded)."""
        return self._search is not None

    def run(self, ball: BallTrajectory, robot_pos_m: np.ndarray, robot_vel_mps: np.ndarray,
            facing_rad=0.0, *, window_s: tuple[float, float] | None = None, receiving=False) -> CatchResult:
        """Catch times of all robots: positions and field-frame velocities (R, 2), facing scalar or (R,).

        ``window_s``: the stretch of the ball's path inside the field, when it is not this ball's own first
        one (``catch_after_reaction``: the first stretch of the ball before the reaction time, on this
        one's clock; a ball that left the field meanwhile is out, even if it comes back off the wall).
        ``receiving`` (scalar or (R,) bool): a chip is received, not intercepted (module docstring)."""
        if isinstance(ball, ChipTrajectory):
            return self._run_chip(ball, robot_pos_m, robot_vel_mps, facing_rad, window_s, receiving)
        if not isinstance(ball, BallTrajectory) or ball.floats is None:
            raise ValueError("ball: expected a single-ball BallTrajectory or a ChipTrajectory")
        return self._run(ball, robot_pos_m, robot_vel_mps, facing_rad, window_s, None)

    def _run_chip(self, chip: ChipTrajectory, robot_pos_m, robot_vel_mps, facing_rad,
                  window_s: tuple[float, float] | None, receiving) -> CatchResult:
        """The search on the chip's ground track, window by window of its low stretches (module docstring): per
        robot the first window with a catch on the way, else the last window's answer (at rest, or never); the
        interceptors' windows and the receivers' one apart."""
        try:
            receives = np.broadcast_to(np.asarray(receiving, dtype=bool), (self.num_robots,))
        except ValueError:
            raise ValueError(f"receiving: one bool or one per robot ({self.num_robots})") from None
        track = chip.ground_track()
        t_in, t_out = (0.0, math.inf) if self._field is None else (
            track.time_in_field(self._field, self._margin_m) if window_s is None else window_s)
        res = self._result
        best = CatchResult(np.full(self.num_robots, math.inf), np.full((self.num_robots, 2), math.nan),
                           np.full((self.num_robots, 2), math.nan), np.full(self.num_robots, _NEVER, dtype=np.int8))
        received = ((chip.time_below_height_s(chip.params.max_receive_height_m), math.inf),)
        for robots, windows in ((~receives, chip.low_windows_s()), (receives, received)):
            if not robots.any():
                continue
            for a, b in windows:
                lo, hi = max(a, t_in), min(b, t_out)
                if lo > min(hi, track.stop_time_s):
                    continue
                self._run(track, robot_pos_m, robot_vel_mps, facing_rad, (lo, hi), b == math.inf)
                now = robots & (best.kind != _MOVING) & ((res.kind == _MOVING) | (b == math.inf))
                best.time_s[now], best.kind[now] = res.time_s[now], res.kind[now]
                best.ball_position_m[now], best.robot_target_m[now] = res.ball_position_m[now], res.robot_target_m[now]
                if (best.kind[robots] == _MOVING).all():
                    break
        res.time_s[:], res.kind[:] = best.time_s, best.kind
        res.ball_position_m[:], res.robot_target_m[:] = best.ball_position_m, best.robot_target_m
        return res

    def _run(self, ball: BallTrajectory, robot_pos_m, robot_vel_mps, facing_rad, window_s,
             last_window: bool | None) -> CatchResult:
        """The compiled search on ``ball`` in its field stretch or ``window_s``; ``last_window`` (a chip's
        window, None: a flat ball) False: the ball does not stop in this window."""
        shape = (self.num_robots, 2)
        if np.shape(robot_pos_m) != shape or np.shape(robot_vel_mps) != shape:
            raise ValueError(f"robot_pos_m {np.shape(robot_pos_m)} and robot_vel_mps {np.shape(robot_vel_mps)} "
                             f"must both be {shape}")
        try:
            self._facing[:] = facing_rad
        except (ValueError, TypeError):
            raise ValueError(f"facing_rad: must be a number or one per robot ({self.num_robots})") from None
        t_stop = ball.stop_time_s
        t_in, t_out, hx, hy = 0.0, math.inf, math.inf, math.inf
        if self._field is not None:
            t_in, t_out = ball.time_in_field(self._field, self._margin_m) if window_s is None else window_s
            hx, hy = self._field.half_length_m + self._margin_m, self._field.half_width_m + self._margin_m
        t_max = min(t_stop, t_out)
        if t_in <= t_max and (t_max - t_in) / self._h > MAX_GRID_POINTS:  # e.g. a_roll of micrometres per s^2
            raise ValueError(f"search horizon {t_max - t_in:.6g} s needs more than {MAX_GRID_POINTS} grid points "
                             f"of {self._h} s")
        stops_inside = t_in < math.inf and t_out == math.inf
        if last_window is not None:  # a chip's window: its own end, the ball's field stretch already in it
            t_in, t_out = window_s
            t_max = min(t_stop, t_out)
            stops_inside = last_window and t_out == math.inf
        res = self._result
        search = self._search
        if search is None:
            search = catch_search_loop  # the same loop as Python: slower, the same numbers
            if kernels_loaded():
                search = self._search = compiled_kernels().catch_search
            else:
                # after this first answer: the thread's load must not delay it (both need the GIL and the CPU)
                self._load_after_run = True
        path = ball.rows if search is catch_search_loop else ball.table
        if not search(path, hx, hy, t_in, t_max, self._h, stops_inside, self._m1, self._m2,
                             self._rest_tol_s, self._offset_m, _kernel_array(robot_pos_m),
                             _kernel_array(robot_vel_mps), self._facing, self._a, self._vmax, res.time_s, res.kind,
                             res.ball_position_m, res.robot_target_m):
            raise ValueError("robot_pos_m, robot_vel_mps and facing_rad: must be finite")
        if self._load_after_run:
            self._load_after_run = False
            load_kernels_in_background()
        return res


def robot_time_to_ball(
    ball: BallTrajectory,
    robot_pos_m,
    robot_vel_mps,
    limits: RobotLimits,
    facing_rad=0.0,
    *,
    field: FieldConfig | None = None,
    unbounded: bool = False,
    dribbler_offset_m: float = DEFAULT_DRIBBLER_OFFSET_M,
    field_margin_m: float = _PREDICTOR["field_margin_m"],
    grid_step_s: float = _PREDICTOR["grid_step_s"],
    refine_points: int = 128,
    receiving=False,
) -> CatchResult:
    """Earliest time each robot can touch the ball with its dribbler while facing ``facing_rad``
    (a chip: ``receiving`` robots once it stays low enough to take, the others where they can stop it).

    Robots are vectorized: ``robot_pos_m``/``robot_vel_mps`` of shape (R, 2), ``facing_rad`` scalar
    or (R,), limits per robot; one robot given as (2,) gets a single-robot result (a float time).
    The robot centre must be at ``ball_position_at(t) - dribbler_offset_m * (cos, sin)(facing)``.
    Search interval ``[t_in, min(t_stop, t_out)]``, while the ball is inside ``field``; the field
    is required, or ``unbounded=True`` for none. If there is no window: the robot's time to the
    stop point when the ball stops inside (CatchKind.AT_REST), else +inf (CatchKind.NEVER). See the
    module docstring for the window-detection guarantee. One-off calls; a caller that asks every
    frame keeps a ``CatchSearch``.

    >>> from erforce_ball_model.ball_model import BallTrajectory
    >>> ball = BallTrajectory((-2.0, 0.0), (2.0, 0.0), v_shoot_mps=2.0 / 0.6)  # rolling at 2 m/s along +x
    >>> catch = robot_time_to_ball(ball, (-0.5, 0.3), (0.0, 0.0), RobotLimits(a_max_mps2=2.0, v_max_mps=2.0),
    ...                            facing_rad=math.pi, field=FieldConfig.preset("division_b"))
    >>> catch.kind.name, round(catch.time_s, 3), (catch.robot_target_m.round(3) + 0.0).tolist()
    ('MOVING', 0.78, [-0.45, 0.0])
    """
    p0 = np.asarray(robot_pos_m, dtype=float)
    v0 = np.asarray(robot_vel_mps, dtype=float)
    one = p0.shape == (2,)
    p0, v0 = (p0[None] if one else p0), (v0[None] if v0.shape == (2,) else v0)
    if p0.ndim != 2 or p0.shape[-1] != 2 or v0.shape != p0.shape:
        raise ValueError(f"robot_pos_m {p0.shape} and robot_vel_mps {v0.shape} must both be (R, 2) or (2,)")
    search = CatchSearch(p0.shape[0], limits, dribbler_offset_m=dribbler_offset_m, field=field, unbounded=unbounded,
                         field_margin_m=field_margin_m, grid_step_s=grid_step_s, refine_points=refine_points)
    res = search.run(ball, p0, v0, facing_rad, receiving=receiving)
    if one:
        return CatchResult(float(res.time_s[0]), res.ball_position_m[0].copy(), res.robot_target_m[0].copy(),
                           CatchKind(int(res.kind[0])))
    return res


def robot_time_curve(ball: BallTrajectory, t_ball_s, robot_pos_m, robot_vel_mps, limits: RobotLimits, *,
                     facing_rad: float = 0.0,
                     dribbler_offset_m: float = DEFAULT_DRIBBLER_OFFSET_M) -> float | np.ndarray:
    """The paper's t_robot(t_ball), the curve of Fig. 7: the time one robot needs to stand, facing
    ``facing_rad``, with its dribbler where the ball is at ``t_ball_s`` (robotTimeToPos to that point).

    Where ``t_robot <= t_ball`` the robot is there first (catch possible); robotTimeToBall is the
    first such ``t_ball``. A float for one time, an array of the shape of ``t_ball_s`` for many.

    >>> from erforce_ball_model.ball_model import BallTrajectory
    >>> ball = BallTrajectory((-2.0, 0.0), (2.0, 0.0), v_shoot_mps=2.0 / 0.6)
    >>> limits = RobotLimits(a_max_mps2=2.0, v_max_mps=2.0)
    >>> robot_time_curve(ball, [0.5, 1.0], (-0.5, 0.3), (0.0, 0.0), limits, facing_rad=math.pi).round(3).tolist()
    [1.045, 1.025]
    """
    p0, v0 = _vec2("robot_pos_m", robot_pos_m), _vec2("robot_vel_mps", robot_vel_mps)
    if p0.shape != (2,) or v0.shape != (2,):
        raise ValueError(f"robot_pos_m {p0.shape} and robot_vel_mps {v0.shape}: one robot, (2,) each")
    if not (math.isfinite(facing_rad) and math.isfinite(dribbler_offset_m) and dribbler_offset_m >= 0.0):
        raise ValueError(f"facing_rad and dribbler_offset_m: must be finite (offset >= 0), got {facing_rad!r}, "
                         f"{dribbler_offset_m!r}")
    return robot_time_to_pos(p0, v0, ball.position_at(t_ball_s) - contact_offset(facing_rad, dribbler_offset_m),
                             limits)


def contact_offset(facing_rad: float, dribbler_offset_m: float = DEFAULT_DRIBBLER_OFFSET_M) -> np.ndarray:
    """The paper's offset: robot centre to ball centre when the ball touches the dribbler of a robot facing
    ``facing_rad``; the robot stands at ``ball - offset``. (The compiled search computes the same inline.)

    >>> contact_offset(math.pi / 2, 0.08).round(3).tolist()
    [0.0, 0.08]
    """
    return dribbler_offset_m * np.array([math.cos(facing_rad), math.sin(facing_rad)])


def receive_facing(ball_direction, robot_xy, target_xy, max_angle_rad: float = MAX_RECEIVE_ANGLE_RAD) -> float:
    """The dribbler's direction for receiving a ball that moves along ``ball_direction`` (unit vector or any
    non-zero vector) and passing it on to ``target_xy`` (the paper's robotTimeToBall with targetpos: the
    offset points towards the robot's intended target): towards the target, seen from ``robot_xy``, when
    that is at most ``max_angle_rad`` from the ball's incoming direction reversed (MAX_RECEIVE_ANGLE_RAD
    says why there is a limit); else against the ball, as a receiver without a target does.

    >>> round(math.degrees(receive_facing((1.0, 0.0), (0.0, 0.0), (-1.0, 1.0))), 6)  # 45 deg off: the target
    135.0
    >>> round(math.degrees(receive_facing((1.0, 0.0), (0.0, 0.0), (0.0, 1.0))), 6)  # 90 deg off: the ball
    180.0
    """
    ux, uy = float(ball_direction[0]), float(ball_direction[1])
    towards_ball = math.atan2(0.0 - uy, 0.0 - ux)  # not -uy: atan2(-0.0, -1) is -pi
    if not (math.isfinite(max_angle_rad) and 0.0 <= max_angle_rad < 0.5 * math.pi):
        raise ValueError(f"max_angle_rad must be in [0, pi/2), got {max_angle_rad!r}")
    dx, dy = float(target_xy[0]) - float(robot_xy[0]), float(target_xy[1]) - float(robot_xy[1])
    if not all(math.isfinite(v) for v in (ux, uy, dx, dy)) or (ux == 0.0 and uy == 0.0):
        raise ValueError("ball_direction, robot_xy and target_xy: must be finite, the direction non-zero")
    if dx == 0.0 and dy == 0.0:
        return towards_ball
    towards_target = math.atan2(dy, dx)
    off = abs(math.remainder(towards_target - towards_ball, 2.0 * math.pi))
    return towards_target if off <= max_angle_rad else towards_ball


def facing_angles(
    fixed: np.ndarray, fixed_rad: np.ndarray, ball: BallTrajectory, robot_pos_m: np.ndarray, rest_speed_mps: float
) -> np.ndarray | float:
    """Dribbler direction per robot: the fixed angle, or against the ball's motion (towards a resting ball).

    One float when every robot faces against the moving ball (the common case, no array work).
    """
    f = ball.floats
    if f.speed_mps > rest_speed_mps:
        towards = math.atan2(-f.vy_mps, -f.vx_mps)
        if not fixed.any():
            return towards
    else:
        d = ball.position_m - robot_pos_m
        towards = np.arctan2(d[:, 1], d[:, 0])  # atan2(0, 0) = 0: a robot on the ball faces +x
    return np.where(fixed, fixed_rad, towards)


def catch_after_reaction(search: CatchSearch, ball: BallTrajectory, robot_pos_m: np.ndarray,
                         robot_vel_mps: np.ndarray, reaction_s: float, facing_fixed: np.ndarray,
                         facing_rad: np.ndarray, rest_speed_mps: float, receiving=False) -> CatchResult:
    """robotTimeToBall for robots that act on this prediction only ``reaction_s`` from now (the predictor's
    question every frame): the ball gets that head start, facing as ``facing_angles``.

    The robots are planned from their present state: meanwhile they execute their previous command,
    which continues their plan (coasting them would push a braking robot past its target and turn a
    catch in progress into "never"). The times count from the end of the reaction: add ``reaction_s``
    for times from now. The field's stretch searched is the ball's first one from now: a ball that leaves
    the field during the reaction is out, also when it comes back off the wall. The result's arrays are
    the search's, reused by its next run. ``receiving``: which robots receive a chip (CatchSearch.run).
    """
    chip = isinstance(ball, ChipTrajectory)
    if reaction_s <= 0.0:
        return search.run(ball, robot_pos_m, robot_vel_mps, facing_angles(
            facing_fixed, facing_rad, ball.ground_track() if chip else ball, robot_pos_m, rest_speed_mps),
            receiving=receiving)
    ahead = ball.advanced(reaction_s)
    facing = facing_angles(facing_fixed, facing_rad, ahead.ground_track() if chip else ahead, robot_pos_m,
                           rest_speed_mps)
    window = None
    path = ball.ground_track() if chip else ball
    if search._field is not None and len(path.pieces) > 1:  # off a wall: the stretch is the ball's of now
        t_in, t_out = path.time_in_field(search._field, search._margin_m)
        window = (max(t_in - reaction_s, 0.0), t_out - reaction_s) if t_in < math.inf else (math.inf, math.inf)
    return search.run(ahead, robot_pos_m, robot_vel_mps, facing, window_s=window, receiving=receiving)


# --- robotTimeToBlock (beyond the paper) ----------------------------------------------------------
def robot_time_to_block(ball: BallTrajectory, robot_pos_m, robot_vel_mps, limits: RobotLimits, body_radius_m: float,
                        t_end_s: float, *, reaction_s: float = 0.0, grid_step_s: float = _PREDICTOR["grid_step_s"],
                        refine_steps: int = 12, kernels: str = "now", t_start_s: float = 0.0) -> np.ndarray:
    """Earliest time (s, from now) each robot stands with its body on the ball's path where the ball is then: an
    interception without a catch. +inf where none comes before ``t_end_s`` (or the ball's stop).

    robotTimeToBall asks for the dribbler at the ball; a robot's body stops a ball as well, and an opponent
    beside the lane needs only to step into it: the ball's centre within ``body_radius_m`` (robot radius plus
    ball radius) of the robot's centre. Block at ``t``: for ``t < reaction_s`` the robot has not reacted and
    stands where it is (the ball runs into it); from then on it can arrive, at rest, at a point within
    ``body_radius_m`` of ``ball.position_at(t)`` by ``t`` (the bang-bang of robotTimeToPos, ``can_reach``, with
    the budget ``t - reaction_s``, from its present state as ``catch_after_reaction`` plans; at rest, since a
    robot that crosses the lane at speed is gone when the ball comes). The point tried is the one of that disc
    nearest to the robot's braking spot (where it comes to rest braking now): exact for a robot at rest
    (straight bang-bang to the nearest point), an achievable time for a moving one (at most later than its
    optimum). Grid of ``grid_step_s`` plus the moment the ball's centre reaches the body around the spot
    (a robot at rest beside the path: that window may be narrower than the grid), the first feasible time
    refined by ``refine_steps`` bisections. Compiled as the catch search is (catch_time_kernels);
    ``kernels="background"`` answers with the same loop as Python until they are loaded (CatchSearch's option of
    that name). ``t_start_s``: ``ball`` is the ball from then on (a chip's stretch low enough to stop, from the
    chip advanced to it): the block counts only from then, the times and ``t_end_s`` still from now.

    >>> ball = BallTrajectory((0.0, 0.0), (3.0, 0.0), v_shoot_mps=3.0)  # along +x
    >>> limits = RobotLimits(a_max_mps2=4.0, v_max_mps=2.0)
    >>> t = robot_time_to_block(ball, [(1.0, 0.05), (1.0, 0.5)], [(0.0, 0.0), (0.0, 0.0)], limits, 0.11, 2.0)
    >>> t.round(3).tolist()  # near the lane it steps towards the ball; 0.5 m beside it, it meets it further on
    [0.307, 1.099]
    """
    p0 = np.asarray(robot_pos_m, dtype=float).reshape(-1, 2)
    v0 = np.asarray(robot_vel_mps, dtype=float).reshape(-1, 2)
    if v0.shape != p0.shape or not (np.isfinite(p0).all() and np.isfinite(v0).all()):
        raise ValueError(f"robot_pos_m {p0.shape} and robot_vel_mps {v0.shape}: (R, 2) each, finite")
    for name, value in (("body_radius_m", body_radius_m), ("reaction_s", reaction_s), ("t_start_s", t_start_s)):
        if not (math.isfinite(value) and value >= 0.0):
            raise ValueError(f"{name}: must be finite and >= 0, got {value!r}")
    if not (math.isfinite(grid_step_s) and grid_step_s > 0.0) or math.isnan(t_end_s):
        raise ValueError(f"grid_step_s must be finite and > 0 and t_end_s a number, got {grid_step_s!r}, {t_end_s!r}")
    if kernels not in ("now", "background"):
        raise ValueError(f"kernels: 'now' or 'background', got {kernels!r}")
    a, vmax = (_kernel_array(np.ravel(x)) for x in _limits_arrays(limits, (len(p0),)))
    # on the clock of ``ball``: the robots react ``reaction_s - t_start_s`` after its start (< 0: before it)
    t_end, reaction_s = min(float(t_end_s) - t_start_s, ball.stop_time_s), reaction_s - t_start_s
    out = np.full(len(p0), math.inf)
    if not t_end >= 0.0 or not len(p0):
        return out
    if t_end / grid_step_s > MAX_GRID_POINTS:
        raise ValueError(f"block horizon {t_end:.6g} s needs more than {MAX_GRID_POINTS} grid points")
    num = math.ceil(t_end / grid_step_s)  # the grid k h for k < num (np.arange's points), then t_end
    if kernels == "now" or kernels_loaded():
        compiled_kernels().block_search(ball.table, t_end, grid_step_s, num, refine_steps, body_radius_m, reaction_s,
                                _kernel_array(p0), _kernel_array(v0), a, vmax, out)
    else:  # the same loop as Python (CatchSearch's kernels="background"): slower, the same numbers
        block_search_loop(ball.rows, t_end, grid_step_s, num, refine_steps, body_radius_m, reaction_s, p0, v0, a, vmax,
                      out)
        load_kernels_in_background()
    return out + t_start_s

