"""Per-camera systematic offsets of SSL-Vision, estimated online from what two cameras see at one capture.

A calibrated camera still reports every object a few cm off (ER-Force's simulator's "Realistic" preset: 2 cm along
the camera's direction from the field's centre); in an overlap two cameras then disagree about a ball at rest, and
a chip detector that reads the disagreement as parallax takes flat kicks for chips. SSL-Vision reports a robot
where its marker height's projection lies, the same rule for every camera, so two cameras' positions of one robot
at one capture differ only by their offsets and noise: ``d = p_a - p_b = o_a - o_b + e``. A ball lying still is
the same; a ball that may be in the air is not (its two projections differ by its height's parallax), so a ball
feeds the estimate only with a sighting after which each camera saw it still for ``rest_s``.

The offsets are only defined up to a common shift: the estimate is the least-squares one with zero mean over the
cameras that were paired, within each set that shares differences (``o = L^+ r``, L the graph Laplacian weighted by
each pair's sample count, r each camera's summed differences). Its covariance per axis is ``s^2 L^+`` with s the
differences' standard deviation estimated from the residuals: ``uncertainty_m``; it is solved again once the
differences taken since grow by RESOLVE_SHARE of all. Each pair keeps at most ``max_samples`` (older samples are
scaled down), so the estimate follows a calibration that changes.

What a frame feeds is a compiled kernel over arrays (``alignment_frame``), the one the bridge's compiled pass
(vision_fast_path) runs per datagram and ``CameraAlignment.frame`` runs for everyone else, so the bridge's two
paths learn and correct alike; ``correct_rows`` takes the offsets off a frame's rows in both. numba's cache of
vision_fast_path goes by that file alone: after a change here remove its ``__pycache__`` entries.
"""

from __future__ import annotations

import math

import numpy as np

from erforce_interfaces.runtime.numba_support import numba
from erforce_interfaces.ssl.ssl_vision import DecodeLimits

RESOLVE_SHARE = 0.01  # solve again once the new differences are this share of all (a solve per frame costs)
N_CAMERAS = DecodeLimits().max_camera_id + 1  # camera ids SSL-Vision can report
IDS_PER_TEAM = DecodeLimits().max_robot_id + 1
N_KEYS = 2 * IDS_PER_TEAM + 1  # what two cameras can both see: a robot by team (0, 1) and id, then the ball
HISTORY = 64  # ball sightings a camera keeps for the rest test (0.15 s at up to ~400 Hz)
# settings
SET_GAP, SET_MOTION, SET_REST, SET_REST_RADIUS, SET_DISAGREEMENT, SET_MAX_SAMPLES, SET_RESOLVE_SHARE = range(7)
# totals: all differences held (after down-weighting old ones), the new ones since the last solution, 1: solve again
TOTAL_SAMPLES, TOTAL_NEW, TOTAL_STALE = range(3)
CAM_FRAMES, CAM_HEAD, CAM_COUNT = range(3)  # per camera: frames fed, its ball history's ring (first, length)
PAIR_N, PAIR_SUM_X, PAIR_SUM_Y, PAIR_SUM_SQ = range(4)  # per pair a < b: count, sums of p_a - p_b, of |p_a - p_b|^2

__all__ = ["CameraAlignment", "alignment_frame", "correct_rows", "load_kernels", "solve"]


@numba.njit(cache=True, error_model="numpy")
def _add(pairs, totals, settings, a, b, dx, dy):
    """One difference p_a - p_b into its pair, unless it lies further than the disagreement bound from the pair's
    mean; a pair beyond max_samples is scaled down first (a window of about max_samples)."""
    if a > b:
        a, b, dx, dy = b, a, -dx, -dy
    pair = pairs[a, b]
    n = pair[PAIR_N]
    if n > 0.0 and math.hypot(dx - pair[PAIR_SUM_X] / n, dy - pair[PAIR_SUM_Y] / n) > settings[SET_DISAGREEMENT]:
        return
    if n + 1.0 > settings[SET_MAX_SAMPLES]:
        k = (settings[SET_MAX_SAMPLES] - 1.0) / n
        totals[TOTAL_SAMPLES] -= n - n * k
        pair *= k
    pair[PAIR_N] += 1.0
    pair[PAIR_SUM_X] += dx
    pair[PAIR_SUM_Y] += dy
    pair[PAIR_SUM_SQ] += dx * dx + dy * dy
    totals[TOTAL_NEW] += 1.0
    totals[TOTAL_SAMPLES] += 1.0
    if totals[TOTAL_NEW] >= max(1.0, settings[SET_RESOLVE_SHARE] * totals[TOTAL_SAMPLES]):
        totals[TOTAL_STALE] = 1.0


@numba.njit(cache=True, error_model="numpy")
def _resting_ball(history, cams, settings, camera, t_s, balls, out):
    """The camera's newest ball sighting at least ``rest_s`` old after which the ball stayed within
    ``rest_radius_m`` of it, into ``out`` (x, y, 0, its capture time); False when there is none. A ball in the air
    cannot: over any ``rest_s`` its height leaves the first one's by at least g rest_s^2 / 8 (2.8 cm at 0.15 s, the
    apex in the middle), which a camera 4 m high sees at 1.5 m from below it as 1 cm; in an overlap at least one of
    the two cameras is that far. Only a frame with one ball (several: which is which is unknown)."""
    ring = history[camera]
    cap = len(ring)
    if len(balls) != 1 or not (np.isfinite(balls[0, 0]) and np.isfinite(balls[0, 1])):
        cams[camera, CAM_COUNT] = 0
        return False
    head, count = cams[camera, CAM_HEAD], cams[camera, CAM_COUNT]
    if count == cap:  # full: the oldest goes (the rest test then waits for a span the ring holds)
        head, count = (head + 1) % cap, count - 1
    at = (head + count) % cap
    ring[at, 0], ring[at, 1], ring[at, 2] = t_s, balls[0, 0], balls[0, 1]
    count += 1
    while count > 1 and ring[(head + 1) % cap, 0] <= t_s - settings[SET_REST]:
        head, count = (head + 1) % cap, count - 1  # ring[head]: the newest sighting at least rest_s old
    cams[camera, CAM_HEAD], cams[camera, CAM_COUNT] = head, count
    t0, x0, y0 = ring[head, 0], ring[head, 1], ring[head, 2]
    if t0 > t_s - settings[SET_REST]:
        return False
    for j in range(count):
        k = (head + j) % cap
        if math.hypot(ring[k, 1] - x0, ring[k, 2] - y0) > settings[SET_REST_RADIUS]:
            return False
    out[0], out[1], out[2], out[3] = x0, y0, 0.0, t0
    return True


@numba.njit(cache=True, error_model="numpy")
def _inverse_spd(a):
    """The inverse of the symmetric positive definite ``a`` (Cholesky; a few cameras)."""
    m = len(a)
    low = np.zeros((m, m))
    for i in range(m):
        for j in range(i + 1):
            acc = a[i, j]
            for k in range(j):
                acc -= low[i, k] * low[j, k]
            low[i, j] = math.sqrt(acc) if i == j else acc / low[j, j]
    inv = np.zeros((m, m))
    for col in range(m):  # solve low low^T x = e_col
        y = np.zeros(m)
        for i in range(m):
            acc = 1.0 if i == col else 0.0
            for k in range(i):
                acc -= low[i, k] * y[k]
            y[i] = acc / low[i, i]
        for i in range(m - 1, -1, -1):
            acc = y[i]
            for k in range(i + 1, m):
                acc -= low[k, i] * inv[k, col]
            inv[i, col] = acc / low[i, i]
    return inv


@numba.njit(cache=True, error_model="numpy")
def solve(pairs, totals, offsets, std_m):
    """The least-squares offsets with zero mean over each set of cameras that share differences, ``o = L^+ r``, and
    their standard deviations ``sqrt(s^2 diag L^+)`` into ``offsets`` and ``std_m`` (0 and inf for a camera never
    paired). For a connected set of m cameras ``L^+ = (L + 1 1^T / m)^-1 - 1 1^T / m``; as r sums to zero over the
    set, ``o = (L + 1 1^T / m)^-1 r``."""
    totals[TOTAL_NEW] = totals[TOTAL_STALE] = 0.0
    n_cams = len(pairs)
    n = np.zeros((n_cams, n_cams))
    r = np.zeros((n_cams, 2))
    sq, dof = 0.0, 0.0
    for a in range(n_cams):
        for b in range(a + 1, n_cams):
            w = pairs[a, b, PAIR_N]
            if w > 0.0:
                n[a, b] = n[b, a] = w
                sx, sy = pairs[a, b, PAIR_SUM_X], pairs[a, b, PAIR_SUM_Y]
                r[a, 0] += sx
                r[a, 1] += sy
                r[b, 0] -= sx
                r[b, 1] -= sy
                sq += pairs[a, b, PAIR_SUM_SQ] - (sx * sx + sy * sy) / w  # about the pair's mean, both axes
                dof += 2.0 * (w - 1.0)
    var_m2 = max(sq, 0.0) / dof if dof > 0.0 else np.inf  # per axis, of one difference (>= 0: rounding)
    offsets[:] = 0.0
    std_m[:] = np.inf
    component = np.full(n_cams, -1, np.int64)
    members = np.empty(n_cams, np.int64)
    for start in range(n_cams):
        if component[start] >= 0 or not (n[start] > 0.0).any():
            continue
        component[start] = start
        members[0], m, seen = start, 1, 0
        while seen < m:  # the cameras connected to start
            c = members[seen]
            seen += 1
            for other in range(n_cams):
                if n[c, other] > 0.0 and component[other] < 0:
                    component[other] = start
                    members[m] = other
                    m += 1
        a = np.empty((m, m))
        for i in range(m):
            for j in range(m):
                a[i, j] = 1.0 / m - n[members[i], members[j]]
            for j in range(m):
                if j != i:
                    a[i, i] += n[members[i], members[j]]
        inv = _inverse_spd(a)
        for i in range(m):
            ox, oy = 0.0, 0.0
            for j in range(m):
                ox += inv[i, j] * r[members[j], 0]
                oy += inv[i, j] * r[members[j], 1]
            offsets[members[i], 0], offsets[members[i], 1] = ox, oy
            std = math.sqrt(max(inv[i, i] - 1.0 / m, 0.0) * var_m2)
            std_m[members[i]] = std if np.isfinite(std) else np.inf


@numba.njit(cache=True, error_model="numpy")
def alignment_frame(newest, history, cams, pairs, totals, settings, offsets, std_m, camera, t_s, robots, balls):
    """One camera frame into the estimate's arrays (``CameraAlignment``'s): ``robots`` as ssl_vision's ROBOT_COLUMNS
    (team 0/1, robot_id, x, y, ...), ``balls`` as its BALL_COLUMNS (x, y, ...), as the camera reported them, at its
    capture time ``t_s``. Each thing seen pairs with the newest frame of every other camera: at the same capture, or
    within max_capture_gap_s when the camera saw it move less than max_motion_m over the gap (from its previous
    sighting); an id the frame reports twice does not pair. ``newest[camera]``: the things of its newest frame (x, y,
    speed, the sighting's time; NaN: not seen). Once the differences taken since the last solution are
    RESOLVE_SHARE of all, ``solve`` again (``offsets``, ``std_m``)."""
    seen = np.full((newest.shape[1], 4), np.nan)
    previous = newest[camera]
    times_seen = np.zeros(newest.shape[1], np.int64)
    ids = (newest.shape[1] - 1) // 2
    for k in range(len(robots)):
        team, robot_id, x, y = robots[k, 0], robots[k, 1], robots[k, 2], robots[k, 3]
        if not ((team == 0.0 or team == 1.0) and 0.0 <= robot_id < ids and np.isfinite(x) and np.isfinite(y)):
            continue
        key = int(team) * ids + int(robot_id)
        times_seen[key] += 1
        t_previous = previous[key, 3]
        speed = np.inf  # unknown motion: pairs only at the same capture
        if t_s > t_previous:  # False for NaN: not in the camera's previous frame
            speed = math.hypot(x - previous[key, 0], y - previous[key, 1]) / (t_s - t_previous)
        seen[key, 0], seen[key, 1], seen[key, 2], seen[key, 3] = x, y, speed, t_s
    keys = np.empty(newest.shape[1], np.int64)
    n_keys = 0
    for key in range(len(seen) - 1):
        if times_seen[key] == 1:
            keys[n_keys] = key
            n_keys += 1
        elif times_seen[key] > 1:  # one id twice: which is which is unknown, as with several balls
            seen[key] = np.nan
    if _resting_ball(history, cams, settings, camera, t_s, balls, seen[len(seen) - 1]):
        keys[n_keys] = len(seen) - 1
        n_keys += 1
    for other in range(len(newest)):
        if other == camera or cams[other, CAM_FRAMES] == 0:
            continue
        for j in range(n_keys):
            key = keys[j]
            t_match = newest[other, key, 3]
            if t_match != t_match:
                continue
            gap_s = abs(seen[key, 3] - t_match)
            if gap_s == 0.0 or (gap_s <= settings[SET_GAP] and seen[key, 2] * gap_s <= settings[SET_MOTION]):
                _add(pairs, totals, settings, camera, other, seen[key, 0] - newest[other, key, 0],
                     seen[key, 1] - newest[other, key, 1])
    newest[camera] = seen
    cams[camera, CAM_FRAMES] += 1
    if totals[TOTAL_STALE]:
        solve(pairs, totals, offsets, std_m)


@numba.njit(cache=True, error_model="numpy")
def correct_rows(offsets, camera, balls, robots):
    """The camera's offset taken off its balls (BALL_COLUMNS rows) and robots (ROBOT_COLUMNS rows), in place."""
    ox, oy = offsets[camera, 0], offsets[camera, 1]
    for k in range(len(balls)):
        balls[k, 0] -= ox
        balls[k, 1] -= oy
    for k in range(len(robots)):
        robots[k, 2] -= ox
        robots[k, 3] -= oy


class CameraAlignment:
    """Online estimate of each camera's offset from pairs of sightings at one capture; ``correct`` removes it.

    ``frame`` takes one camera frame (its capture time, its robots and balls); pairs with the newest frame of every
    other camera within ``max_capture_gap_s``. A robot pairs when its motion over the two captures' gap (from the
    camera's previous sighting) is below ``max_motion_m``; a pair whose difference is further than
    ``max_disagreement_m`` from the pair's mean so far (a wrong id, a reflection) is left out. Camera ids and robot
    ids as SSL-Vision can report them (DecodeLimits). ``offsets`` (per camera id: x, y [m]) is what ``correct``
    and the bridge's compiled pass take off, solved again after a frame once the new differences are RESOLVE_SHARE
    of all."""

    def __init__(self, max_capture_gap_s: float = 0.004, max_motion_m: float = 0.002, rest_s: float = 0.15,
                 rest_radius_m: float = 0.005, max_disagreement_m: float = 0.1, max_samples: float = 5000.0) -> None:
        for name, value in (("max_capture_gap_s", max_capture_gap_s), ("max_motion_m", max_motion_m),
                            ("rest_s", rest_s), ("rest_radius_m", rest_radius_m),
                            ("max_disagreement_m", max_disagreement_m), ("max_samples", max_samples)):
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"CameraAlignment.{name}: must be finite and > 0, got {value!r}")
        self.max_capture_gap_s = max_capture_gap_s
        self.max_motion_m = max_motion_m
        self.rest_s = rest_s
        self.rest_radius_m = rest_radius_m
        self.max_disagreement_m = max_disagreement_m
        self.max_samples = max_samples
        self.settings = np.array([max_capture_gap_s, max_motion_m, rest_s, rest_radius_m, max_disagreement_m,
                                  max_samples, RESOLVE_SHARE])
        self.newest = np.full((N_CAMERAS, N_KEYS, 4), np.nan)
        self.history = np.zeros((N_CAMERAS, HISTORY, 3))
        self.cams = np.zeros((N_CAMERAS, 3), np.int64)
        self.pairs = np.zeros((N_CAMERAS, N_CAMERAS, 4))
        self.totals = np.zeros(3)
        self.offsets = np.zeros((N_CAMERAS, 2))
        self.std_m = np.full(N_CAMERAS, np.inf)

    def state(self) -> tuple:
        """The arrays ``alignment_frame`` takes before the camera (for a compiled caller)."""
        return self.newest, self.history, self.cams, self.pairs, self.totals, self.settings, self.offsets, self.std_m

    # ------------------------------------------------------------------ input
    def frame(self, camera_id: int, t_capture_s: float, robots=(), balls=()) -> None:
        """One camera frame: ``robots`` as (team 0/1, robot_id, x_m, y_m), ``balls`` as (x_m, y_m), as the camera
        reported them. Only a frame with one ball lets the ball pair (several: which is which is unknown)."""
        self.frame_rows(camera_id, t_capture_s, np.array(robots, float).reshape(-1, 4),
                        np.array(balls, float).reshape(-1, 2))

    def frame_rows(self, camera_id: int, t_capture_s: float, robots: np.ndarray, balls: np.ndarray) -> None:
        """``frame`` for ssl_vision's rows (ROBOT_COLUMNS, BALL_COLUMNS: their first columns are read)."""
        if not 0 <= camera_id < N_CAMERAS:
            raise ValueError(f"CameraAlignment: camera_id {camera_id} beyond 0..{N_CAMERAS - 1}")
        alignment_frame(*self.state(), camera_id, float(t_capture_s), np.ascontiguousarray(robots, float),
                        np.ascontiguousarray(balls, float))

    def take(self, camera_id: int, t_capture_s: float, balls: np.ndarray, robots: np.ndarray) -> tuple:
        """A camera frame's rows (field frame, the vision host's capture clock) fed in, and returned (copies) without
        the camera's estimated offset, as the bridge's compiled pass does."""
        self.frame_rows(camera_id, t_capture_s, robots, balls)
        balls, robots = np.array(balls, float), np.array(robots, float)
        correct_rows(self.offsets, camera_id, balls, robots)
        return balls, robots

    # ----------------------------------------------------------------- output
    def offset_m(self, camera_id: int) -> tuple[float, float]:
        """The camera's estimated offset (zero mean over the paired cameras); (0, 0) for a camera never paired."""
        return (0.0, 0.0) if not 0 <= camera_id < N_CAMERAS else tuple(self.offsets[camera_id].tolist())

    def uncertainty_m(self, camera_id: int) -> float:
        """The estimate's standard deviation per axis (inf for a camera never paired or too few samples)."""
        return math.inf if not 0 <= camera_id < N_CAMERAS else float(self.std_m[camera_id])

    def samples(self, camera_a: int, camera_b: int) -> float:
        """How many differences (after down-weighting old ones) the pair holds."""
        return float(self.pairs[min(camera_a, camera_b), max(camera_a, camera_b), PAIR_N])

    def correct(self, camera_id: int, x_m: float, y_m: float) -> tuple[float, float]:
        """What the camera reports at (x_m, y_m) without its estimated offset."""
        ox, oy = self.offset_m(camera_id)
        return x_m - ox, y_m - oy


def load_kernels() -> None:
    """Compile (or load from numba's cache) the alignment's kernels for the rows ssl_vision decodes."""
    alignment = CameraAlignment()
    rows = np.zeros((1, 6))
    alignment.take(0, 0.0, np.zeros((1, 4)), rows)
    alignment.take(1, 0.0, np.zeros((1, 4)), rows)
    alignment.frame(0, 1.0, [(0, 0, 0.0, 0.0)], [(0.0, 0.0)])
