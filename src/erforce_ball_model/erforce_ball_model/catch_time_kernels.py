"""The compiled scalar loops of catch_time: robotTimeToPos (the alpha search), the exact reachability test and
its cheap bound, the robotTimeToBall grid search and the robotTimeToBlock search (catch_time's module docstring
says what each computes and guarantees; its functions check the inputs and call these).

They share one file because numba's on-disk cache of a kernel notices changes to the file the kernel is defined
in only, not to the functions compiled into it from other files: the searches call robotTimeToPos's and the
reachability's steps, so all of them live here, where an edit recompiles every kernel. (ball_model's closed forms
are compiled into them too: after a change there, delete ``__pycache__/catch_time_kernels*.nb*``.)
``compiled_kernels`` compiles or loads the four entry points on a process's first search, not at import; until
then, and in a process that never loads numba (the catcher), the same functions run as plain Python.
"""

from __future__ import annotations

import enum
import functools
import math
import threading
from types import SimpleNamespace

from erforce_ball_model.ball_model import ball_time_to_distance, numba_ball_type, path_piece, path_point

__all__ = [
    "CatchKind",
    "block_search_loop",
    "catch_search_loop",
    "compiled_kernels",
    "kernels_loaded",
    "load_kernels",
    "load_kernels_in_background",
    "reachable",
]


# --- 1D bang-bang ---------------------------------------------------------------------------------
def _axis_time(d, w, x, rho):
    """Minimal 1D time to travel ``d`` and stop, starting at speed ``w``: ``x`` is 1/A (may be +inf: no
    authority on this axis), the speed limit ``V = rho * A`` (rho = v_max / a_max, the same for both
    axes of the alpha split)."""
    if d < 0.0:  # mirror so that d >= 0
        d, w = -d, -w
    if math.isinf(x):  # no authority on this axis
        return 0.0 if d == 0.0 and w == 0.0 else math.inf
    if w > 0.0 and 0.5 * w * w * x > d:
        d, w = -d, -w  # overshoot: cannot stop before the target, so stop first and come back
    elif w * x > rho:
        return max(d / w + 0.5 * w * x, 0.0)  # already faster than the speed share: cruise, then brake
    root_q = math.sqrt(max(d * x + 0.5 * w * w * x * x, 0.0))
    return max(-w * x + 2.0 * root_q + max(root_q - rho, 0.0) ** 2 / rho, 0.0)  # (max: subnormal speeds)


def _axis_min_accel(d, w, t, rho, two_rho2):
    """Smallest acceleration A >= 0 for which ``axis_time(d, w, 1/A, rho) <= t`` (its inverse).

    axis_time is increasing in x = 1/A and on each piece a quadratic in x (after squaring the
    triangle case), so: find the piece from the times at the piece boundaries (overshoot, triangle
    -> trapezoid, speed share below the current speed), solve its quadratic for A in the
    cancellation-free form. 0 when the axis needs no motion; +inf when it cannot make it (e.g.
    ``t`` 0 while moving). ``two_rho2`` is ``2 rho^2`` (hoisted by the caller).
    """
    w = math.copysign(1.0, d) * w  # mirror so that d >= 0
    d = abs(d)
    w2 = w * w
    if d == 0.0 and w2 == 0.0:
        return 0.0  # at rest at the target
    wpos = w > 0.0
    iw = 1.0 / w if wpos else 0.0  # read only where w > 0 (plain Python raises on 1 / 0)
    ds = d + math.sqrt(d * d + w2 * two_rho2)
    t_over = 2.0 * d * iw if wpos else math.inf  # beyond: cannot stop before the target
    over = t > t_over
    trap = t > ds * iw + 2.0 * rho if over else t > min(2.0 * rho - w * (two_rho2 / ds), t_over)
    tw = t * w
    if wpos and not over and t > d * iw + 0.5 * rho:  # keeps its speed above the share
        q = w2 / (2.0 * (tw - d))
    else:
        # Root in A of  c A^2 + b A + a2 = 0  (x = 1/A of  a2 x^2 + b x + c = 0, c <= 0).
        if trap:
            b, a2, c = d - w * rho, 0.5 * w2, rho * (rho - t)
        else:
            b, a2, c = 4.0 * d - 2.0 * tw, w2, -t * t
        if over:
            b = -b
        disc = math.sqrt(max(b * b - 4.0 * a2 * c, 0.0))
        if b < 0.0:
            q = 2.0 * a2 / (disc - b)
        else:  # c == 0 (a zero budget, or the trapezoid's at t = rho): x / 0 and 0 / 0, no root >= 0
            q = (b + disc) / (-2.0 * c) if c != 0.0 else math.inf
    return q if q >= 0.0 else math.inf  # no root >= 0: impossible


def _time_to_pos(dx, dy, wx, wy, a, vmax, tol_s):
    """robotTimeToPos for one robot: the alpha search, bisecting the split until certified.

    The split is parametrized by ``u = tan(alpha / 2)`` in (0, 1) (rational cos/sin, no trig):
    ``1 / (a cos alpha) = k / (1 - u^2)``, ``1 / (a sin alpha) = k / (2 u)`` with
    ``k = (1 + u^2) / a``. ``t_x`` grows and ``t_y`` falls with u, so a bracket [lo, hi] of the
    crossing certifies the synchronized time T*: ``max(t_x(lo), t_y(hi)) <= T* <=
    min(t_y(lo), t_x(hi))``. Bisection stops when that gap is at most ``tol_s``; the upper end
    is returned (an achievable time). A robot at rest needs no search: both axes then take
    ``f(d_i / share_i)`` with the same f, so they arrive together at the split along the line to
    the target (closed form, exact).
    """
    rho = vmax / a
    if wx == 0.0 and wy == 0.0:
        return _axis_time(math.sqrt(dx * dx + dy * dy), 0.0, 1.0 / a, rho)
    eps = 1e-9  # keeps both shares > 0 so both times stay finite
    lo, hi = eps, 1.0 - eps
    k = (1.0 + lo * lo) / a
    tx_lo, ty_lo = _axis_time(dx, wx, k / (1.0 - lo * lo), rho), _axis_time(dy, wy, k / (2.0 * lo), rho)
    if tx_lo > ty_lo:  # no crossing (y needs nothing): the whole budget to x is optimal
        return tx_lo
    k = (1.0 + hi * hi) / a
    tx_hi, ty_hi = _axis_time(dx, wx, k / (1.0 - hi * hi), rho), _axis_time(dy, wy, k / (2.0 * hi), rho)
    if tx_hi <= ty_hi:  # likewise for x
        return ty_hi
    for _ in range(200):  # the u interval reaches rounding after ~55 halvings; the bound is a guard
        if min(ty_lo, tx_hi) - max(tx_lo, ty_hi) <= tol_s:
            break
        u = 0.5 * (lo + hi)
        if u <= lo or u >= hi:
            break
        k = (1.0 + u * u) / a
        tx, ty = _axis_time(dx, wx, k / (1.0 - u * u), rho), _axis_time(dy, wy, k / (2.0 * u), rho)
        if tx <= ty:
            lo, tx_lo, ty_lo = u, tx, ty
        else:
            hi, tx_hi, ty_hi = u, tx, ty
    return min(ty_lo, tx_hi)


def _time_to_pos_many(dx, dy, wx, wy, a, vmax, tol_s, out):
    for i in range(out.shape[0]):
        out[i] = _time_to_pos(dx[i], dy[i], wx[i], wy[i], a[i], vmax[i], tol_s)


def reachable(dx, dy, wx, wy, t, a, vmax):
    """can_reach_in_time for one case.

    Each axis needs at least the acceleration ``A_i(t)`` (``_axis_min_accel``) and gets
    ``a cos(alpha)`` resp. ``a sin(alpha)``: some alpha works iff ``A_x^2 + A_y^2 <= a^2``.
    """
    rho = vmax / a
    two_rho2 = 2.0 * rho * rho
    ax = _axis_min_accel(dx, wx, t, rho, two_rho2)
    if not ax <= a:
        return False
    ay = _axis_min_accel(dy, wy, t, rho, two_rho2)
    return ax * ax + ay * ay <= a * a  # an absurd need overflows to inf: unreachable, as it should


def _can_reach_many(dx, dy, wx, wy, t, a, vmax, out):
    for i in range(out.shape[0]):
        out[i] = reachable(dx[i], dy[i], wx[i], wy[i], t[i], a[i], vmax[i])


def _may_reach(dx, dy, wx, wy, s0, t, a, vmax):
    """Cheap necessary condition for ``reachable``: False only where the robot surely cannot.

    Project the motion on the direction e to the target: the robot covers the distance D along e
    and ends at rest, its acceleration along e is at most ``a`` (the split keeps |a_vec| <= a)
    and its speed at most ``vcap = sqrt(v_max^2 + s0^2)`` (an axis moves at most at its share of
    v_max or at its own initial speed). In 1D, starting at ``w = v0 . e``, the farthest point
    reachable at rest within t is ``vp t - (vp^2 + (vp - w)^2) / (2a)`` with peak speed
    ``vp = min((w + a t) / 2, vcap)`` (accelerate, maybe cruise, brake), and no point at all
    before ``t = s0 / a`` (braking to rest takes that long). Both bounds are sound, so only
    cost, never correctness, depends on how tight they are.
    """
    at = a * t
    if at < s0 - 1e-9:
        return False
    dist = math.sqrt(dx * dx + dy * dy)
    if dist < 1e-150:  # the squares may have underflowed (hypot is exact but slower)
        dist = math.hypot(dx, dy)
    w = (dx * wx + dy * wy) / (dist + 1e-300)  # 0 at the target itself
    vp = min(0.5 * (w + at), math.sqrt(vmax * vmax + s0 * s0))
    return dist <= vp * t - (vp * vp + (vp - w) ** 2) * (0.5 / a) + 1e-9


def _feasible(path, hx, hy, t, sx, sy, wx, wy, a, vmax):
    """f(t) <= 0 and the ball inside the field (``|x| <= hx``, ``|y| <= hy``): the robot (start ``sx, sy`` = its
    centre plus the dribbler offset) reaches the ball of ``path`` (a trajectory's table) at ``t``."""
    bx, by = path_point(path, t)
    return abs(bx) <= hx and abs(by) <= hy and reachable(bx - sx, by - sy, wx, wy, t, a, vmax)


class CatchKind(enum.IntEnum):
    MOVING = 0  # caught while the ball is still on its way (the first window)
    AT_REST = 1  # the robot only gets there after the ball stopped inside the field
    NEVER = 2  # the ball leaves the field first


_MOVING, _AT_REST, _NEVER = int(CatchKind.MOVING), int(CatchKind.AT_REST), int(CatchKind.NEVER)


# One numba kernel, 81 lines with its docstring: the grid pass, the witness and the refinement share the
# robot's loop state, and splitting them would pass it through calls in the hot loop.
def catch_search_loop(path, hx, hy, t_min, t_max, h, stops_inside, m1, m2, rest_tol_s, offset_m, pos, vel, facing,
                      a, vmax, time_out, kind_out, ball_out, target_out):
    """robotTimeToBall per robot (catch_time's module docstring): time, kind, ball position and robot target.

    ``path`` is the ball's trajectory as its table of pieces (ball_model.PIECE_COLUMNS: one piece, or
    several off the walls), read by ``path_point``; a catch point counts only inside the field
    (``|x| <= hx``, ``|y| <= hy``; inf: no field). Grid pass: points ``min(t_min + k h, t_max)`` (none
    when ``t_min > t_max``: the ball is never in the field), the exact test only where ``_may_reach``
    leaves a chance. Witness: the first moment the ball passes the robot's spot on any piece, if in
    ``[t_min, t_max]``. Refinement: leftmost feasible sub-point on ``m1`` then ``m2`` sub-grids (``m2``
    0: one level). No window: robotTimeToPos to the stop point when ``stops_inside``, else never. False
    (and nothing computed) when an input of a robot is not finite.
    """
    for r in range(pos.shape[0]):
        for v in (pos[r, 0], pos[r, 1], vel[r, 0], vel[r, 1], facing[r]):
            if not math.isfinite(v):
                return False
    num = 0
    if t_min <= t_max:
        num = int(math.ceil((t_max - t_min) / h - 1e-9)) + 1  # noqa: RUF046 (int64 in numba, whatever ceil returns)
    for r in range(pos.shape[0]):
        ox, oy = offset_m * math.cos(facing[r]), offset_m * math.sin(facing[r])
        rx, ry = pos[r, 0] + ox, pos[r, 1] + oy  # target - start == ball position - (robot + offset)
        rwx, rwy, ra, rv = vel[r, 0], vel[r, 1], a[r], vmax[r]
        s0 = math.sqrt(rwx * rwx + rwy * rwy)
        right = math.inf  # known feasible
        left_idx = -1  # the grid point before it, known infeasible (-1: none)
        for k in range(num):
            t = min(t_min + k * h, t_max)
            bx, by = path_point(path, t)
            if abs(bx) > hx or abs(by) > hy:
                continue
            dx, dy = bx - rx, by - ry
            if _may_reach(dx, dy, rwx, rwy, s0, t, ra, rv) and reachable(dx, dy, rwx, rwy, t, ra, rv):
                right, left_idx = t, k - 1
                break
        # Witness: the ball passes the robot's spot (where it comes to rest when it brakes now,
        # projected on the path). A robot on or near the path has a window there however narrow.
        brake = 0.5 / ra
        spot_x, spot_y = rx + rwx * abs(rwx) * brake, ry + rwy * abs(rwy) * brake
        t_witness = math.inf
        for i in range(len(path)):
            piece = path_piece(path, i)
            along = (spot_x - piece.x_m) * piece.ux + (spot_y - piece.y_m) * piece.uy
            if along > 0.0:
                t_pass = path[i][0] + ball_time_to_distance(piece, along)
                if (t_min <= t_pass <= t_max and t_pass < right and t_pass < t_witness
                        and _feasible(path, hx, hy, t_pass, rx, ry, rwx, rwy, ra, rv)):
                    t_witness = t_pass
        if t_witness < right:
            right = t_witness
            left_idx = min(int((t_witness - t_min) / h), num - 1)  # the last grid point before t_witness
            while left_idx >= 0 and min(t_min + left_idx * h, t_max) >= t_witness:
                left_idx -= 1
            while left_idx + 1 < num and min(t_min + (left_idx + 1) * h, t_max) < t_witness:
                left_idx += 1
        if right < math.inf and left_idx >= 0:
            left = min(t_min + left_idx * h, t_max)
            for m in (m1, m2):
                if m == 0:
                    break
                lo = left
                for j in range(1, m + 1):  # j == m is ``right`` itself
                    s = left + (right - left) * (j / m) if j < m else right
                    if j == m or _feasible(path, hx, hy, s, rx, ry, rwx, rwy, ra, rv):
                        left, right = lo, s
                        break
                    lo = s
        if right < math.inf:
            kind = _MOVING
            bx, by = path_point(path, right)
        elif stops_inside:
            kind = _AT_REST
            bx, by = path_point(path, math.inf)
            right = _time_to_pos(bx - rx, by - ry, rwx, rwy, ra, rv, rest_tol_s)
        else:
            kind, bx, by = _NEVER, math.nan, math.nan
        time_out[r], kind_out[r] = right, kind
        ball_out[r, 0], ball_out[r, 1] = bx, by
        target_out[r, 0], target_out[r, 1] = bx - ox, by - oy
    return True


# --- robotTimeToBlock (beyond the paper) ----------------------------------------------------------
def block_search_loop(path, t_end, h, num, refine_steps, radius_m, reaction_s, pos, vel, a, vmax, out):
    """robot_time_to_block per robot into ``out`` (inf: none): the body-entry time if the robot blocks then, else
    the first grid time it blocks at, bisected ``refine_steps`` times against the grid point before it. Grid: k h
    for k < ``num``, then ``t_end``; a grid time at or after a feasible entry time ends the robot's search."""
    for r in range(pos.shape[0]):
        px, py, wx, wy, ra, rv = pos[r, 0], pos[r, 1], vel[r, 0], vel[r, 1], a[r], vmax[r]
        brake = 0.5 / ra
        sx, sy = px + wx * abs(wx) * brake, py + wy * abs(wy) * brake  # where it comes to rest braking now
        s0 = math.sqrt(wx * wx + wy * wy)
        best = _body_entry(path, sx, sy, radius_m)
        if not (best <= t_end and _block_at(path, best, px, py, wx, wy, s0, sx, sy, ra, rv, radius_m, reaction_s)):
            best = math.inf
        for k in range(num + 1):
            t = k * h if k < num else t_end
            if t >= best:
                break
            if _block_at(path, t, px, py, wx, wy, s0, sx, sy, ra, rv, radius_m, reaction_s):
                if k > 0:
                    lo = (k - 1) * h
                    for _ in range(refine_steps):  # bisect the first feasible grid step's left edge
                        mid = 0.5 * (lo + t)
                        if _block_at(path, mid, px, py, wx, wy, s0, sx, sy, ra, rv, radius_m, reaction_s):
                            t = mid
                        else:
                            lo = mid
                best = t
                break
        out[r] = best


def _body_entry(path, sx: float, sy: float, radius_m: float) -> float:
    """When the ball's centre first comes within ``radius_m`` of the spot ``(sx, sy)`` on the ball's first piece
    (0 when it starts inside; inf when it never does, or only after that piece, e.g. off a wall)."""
    f = path_piece(path, 0)
    rx, ry = sx - f.x_m, sy - f.y_m
    along = rx * f.ux + ry * f.uy
    off = abs(rx * -f.uy + ry * f.ux)
    if not (off <= radius_m and along + radius_m >= 0.0):
        return math.inf
    enter = along - math.sqrt(max(radius_m * radius_m - off * off, 0.0))
    return 0.0 if enter <= 0.0 else path[0][0] + ball_time_to_distance(f, enter)


def _block_at(path, t, px, py, wx, wy, s0, sx, sy, a, vmax, radius_m, reaction_s) -> bool:
    """Whether the robot at ``(px, py)`` moving at ``(wx, wy)`` (speed ``s0``; braking spot ``(sx, sy)``) blocks
    the ball at ``t``: before ``reaction_s`` the ball is within ``radius_m`` of where it stands, from then on it
    reaches, at rest, the point of the ball's body disc nearest to its spot (``robot_time_to_block``)."""
    bx, by = path_point(path, t)
    if t < reaction_s:
        return math.hypot(bx - px, by - py) <= radius_m + 1e-9  # (the entry's rounding)
    gx, gy = sx - bx, sy - by
    gap = math.hypot(gx, gy)
    scale = radius_m / gap if gap > radius_m else 1.0
    dx, dy, tau = bx + gx * scale - px, by + gy * scale - py, t - reaction_s
    return _may_reach(dx, dy, wx, wy, s0, tau, a, vmax) and reachable(dx, dy, wx, wy, tau, a, vmax)


@functools.cache
def compiled_kernels() -> SimpleNamespace:
    """The four entry points compiled (or loaded from numba's cache beside this module), on first use.

    The scalar functions they call are compiled into them (``register_jitable``); the cache is keyed
    on this file, so an edit anywhere here recompiles. ``error_model="numpy"``: x / 0 is inf as in
    numpy, not an exception; no fastmath, so the results are the IEEE results numpy gives.
    """
    numba_ball_type()  # imports numba; ball_model's closed forms become callable from kernels
    from erforce_interfaces.runtime.numba_support import numba, register_jitable

    for scalar in (_axis_time, _axis_min_accel, _time_to_pos, reachable, _may_reach, _feasible, _body_entry,
                   _block_at):
        register_jitable(error_model="numpy")(scalar)
    f, vec, mat = numba.float64, numba.float64[::1], numba.float64[:, ::1]

    def jit(signature, loop):
        return numba.njit(signature, cache=True, error_model="numpy")(loop)

    return SimpleNamespace(
        time_to_pos_many=jit(numba.void(vec, vec, vec, vec, vec, vec, f, vec), _time_to_pos_many),
        can_reach_many=jit(numba.void(vec, vec, vec, vec, vec, vec, vec, numba.boolean[::1]), _can_reach_many),
        catch_search=jit(numba.boolean(mat, f, f, f, f, f, numba.boolean, numba.int64, numba.int64, f, f, mat, mat,
                                       vec, vec, vec, vec, numba.int8[::1], mat, mat), catch_search_loop),
        block_search=jit(numba.void(mat, f, f, numba.int64, numba.int64, f, f, mat, mat, vec, vec, vec),
                         block_search_loop),
    )


def load_kernels() -> None:
    """Compile or load the search's kernels now (CatchSearch does, at a node's start), not in its first frame."""
    compiled_kernels()


_background_load: threading.Thread | None = None


def kernels_loaded() -> bool:
    return compiled_kernels.cache_info().currsize > 0


def load_kernels_in_background() -> None:
    """Start loading the kernels in a daemon thread (once). Loading numba and the cached kernels costs a
    process about a second of CPU; a node restarted after a crash answers meanwhile with the same loops run
    as Python (CatchSearch with ``kernels="background"`` starts the load after its first answer)."""
    global _background_load
    if _background_load is None and not kernels_loaded():
        _background_load = threading.Thread(target=compiled_kernels, name="catch_time_kernels", daemon=True)
        _background_load.start()
