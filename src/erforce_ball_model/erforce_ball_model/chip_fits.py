"""Least-squares fits of a kick's ball sightings on the cameras' rays (the chip detector's, chip_tracking).

SSL-Vision reports every ball on the ground: a ball at height ``z`` shows where the ray from its
camera ``c = (cx, cy, cz)`` meets the field, ``G = c + (P - c) cz / (cz - z)``. Turned round, the
ball's ground track is ``P = G - (G - c) z / cz``. With a flight ``P = p0 + v t`` and
``z = z0 + vz t - g t^2 / 2`` (times from the kick's first sighting) each sighting gives two
equations linear in the six unknowns ``(x0, y0, vx, vy, z0, vz)``:

    p0 + v t + (G - c) (z0 + vz t) / cz = G + (G - c) g t^2 / (2 cz)

so the flight is a linear least-squares fit over the sightings since the kick (every camera's: two
cameras see a flying ball at two ground points, which only a height explains, ``triangulate_height``; one camera
sees a curve that no rolling ball makes). The old motion's sightings before the kick are in the fit as the ball on
the ground there (they pin the launch point). The fits, each for one launch time or batched over many (the detector
searches the launch time):
- ``fit_flight`` / ``flights``: the free flight from the ground (x0, y0, vx, vy, vz);
- ``fit_flight_at_angle`` / ``flights_at_angle``: the flight at a known elevation (a kick hint's, or a bound of the
  plausible ones), four unknowns, optionally with a commanded ground speed as one more equation;
- ``fit_ground`` / ``grounds``: the same sightings as a ball kicked on the ground (the flat model's deceleration
  along its motion), the null hypothesis;
- ``fit_hop_flight`` / ``hop_flights``: a chip that landed within its sightings, through its first bounce (the chip
  model's hops at a given touchdown time, ``hop_tables``; four linear unknowns, closed form).
What is reported of a fit taken: its covariance (``flight_covariance``; from one camera the first height is unsure by
tens of cm, along the camera's ray), and the flight within the kicker's limits (``within_kicker_limits``: the noise
that shows a chip early also overstates its height).

No rclpy import.
"""

from __future__ import annotations

import functools
import math
from typing import NamedTuple

import numpy as np

from erforce_ball_model.ball_model import MAX_SPEED_MPS, BallModelParams, ChipParams, kick_distances
from erforce_ball_model.chip_model import ChipTrajectory
from erforce_interfaces.wire.robot_config import SSL_MAX_KICK_MPS

__all__ = ["ChipFit", "Sighting", "fit_flight", "fit_flight_at_angle", "fit_ground", "fit_hop_flight",
           "flight_covariance", "flights", "flights_at_angle", "grounds", "hop_flights", "hop_tables",
           "triangulate_height", "within_kicker_limits"]

# A ground fit's iterations: its deceleration along the motion from the previous iteration's speed.
GROUND_ITERATIONS = 3

# The launch point (the flat filter's ball before the kick, averaged over the frames it lay there) weighs as
# this many sightings' standard errors in one: twice as sure as one sighting.
ORIGIN_WEIGHT = 2.0

# A chip landed within its sightings is fitted through its first bounce (``fit_hop_flight``) at these first-touchdown
# times after the launch [s] (its vz = g T / 2; finer steps move its touchdown by less than a frame's noise), from
# tables of a chip at unit ground speed over the times since the launch (linear between steps of HOP_TAU_STEP_S: a
# parabola's chord is off by g step^2 / 8, 1e-6 m).
HOP_T1_S = np.arange(0.03, 0.4001, 0.002)
HOP_TAU_STEP_S = 0.001
HOP_TAU_MAX_S = 0.5

# The league's limit on a kicked ball's speed [m/s]: with the kicker's elevations, the flights a reported chip can be.
KICK_SPEED_LIMIT_MPS = SSL_MAX_KICK_MPS

# Fixed standard normal draws (antithetic pairs: their mean is exactly 0) for the flight under the kicker's limits.
_DRAWS = np.random.default_rng(37).standard_normal((256, 6))
_DRAWS = np.concatenate([_DRAWS, -_DRAWS])


class Sighting(NamedTuple):
    """One camera's ball: its capture time, the ground point it reports and the camera's position [m]."""

    t_s: float
    x_m: float
    y_m: float
    camera_x_m: float
    camera_y_m: float
    camera_z_m: float


class ChipFit(NamedTuple):
    """A flight fitted to sightings: launched from the ground at ``t_launch_s`` from ``(x_m, y_m)`` with
    ``(vx, vy, vz)``; the standard error of vz and the squared residual of the sightings."""

    t_launch_s: float
    x_m: float
    y_m: float
    vx_mps: float
    vy_mps: float
    vz_mps: float
    vz_std_mps: float
    rss_m2: float


def _system(rows: np.ndarray, t_launch_s, origin_xy, g_mps2: float, flight: bool, pre_velocity_mps=(0.0, 0.0)):
    """Least-squares rows for (x0, y0, vx, vy[, vz]), one system per launch time of ``t_launch_s`` (m of them):
    each sighting's two ray equations, then the origin (``origin_xy``: (m, 2), where the ball was at each launch, if
    known) as one more sighting on the ground. A sighting before the launch is of the ball on the ground at
    ``(x0, y0) + pre_velocity_mps (t - t_launch)`` (the old motion's velocity, known). Returns A (m, 2n[+2], 4|5),
    b (m, 2n[+2]) and the times since the launch (m, n; 0 before it)."""
    tau = rows[None, :, 0] - np.asarray(t_launch_s, dtype=float).reshape(-1, 1)
    t, pre = np.maximum(tau, 0.0), np.minimum(tau, 0.0)
    (m, n), gx, gy = tau.shape, rows[:, 1], rows[:, 2]
    a = np.zeros((m, 2 * n + (0 if origin_xy is None else 2), 5 if flight else 4))
    b = np.empty(a.shape[:2])
    a[:, :n, 0] = a[:, n:2 * n, 1] = 1.0
    a[:, :n, 2] = a[:, n:2 * n, 3] = t
    b[:, :n], b[:, n:2 * n] = gx - pre_velocity_mps[0] * pre, gy - pre_velocity_mps[1] * pre
    if flight:
        kx, ky = (gx - rows[:, 3]) / rows[:, 5], (gy - rows[:, 4]) / rows[:, 5]
        a[:, :n, 4], a[:, n:2 * n, 4] = kx * t, ky * t
        b[:, :n] += kx * (0.5 * g_mps2) * t * t
        b[:, n:2 * n] += ky * (0.5 * g_mps2) * t * t
    if origin_xy is not None:
        a[:, 2 * n, 0] = a[:, 2 * n + 1, 1] = ORIGIN_WEIGHT
        b[:, 2 * n:] = ORIGIN_WEIGHT * np.asarray(origin_xy, dtype=float).reshape(m, 2)
    return a, b, t


def _solve(a: np.ndarray, b: np.ndarray):
    """Least squares of small, well-scaled systems (a stack of m) by their normal equations (a few times faster than
    an SVD): the solutions, ``(A^T A)^-1`` (times the noise variance: a solution's covariance) and which of the m
    the sightings determine (the others' numbers are meaningless)."""
    ata = np.matmul(a.transpose(0, 2, 1), a)
    eigenvalues = np.linalg.eigvalsh(ata)  # ascending; of a symmetric matrix: its condition number's singular values
    ok = eigenvalues[:, -1] < 1e14 * eigenvalues[:, 0]
    inv = np.zeros_like(ata)
    inv[ok] = np.linalg.inv(ata[ok])
    return _apply(inv, a, b), inv, ok


def _apply(inv: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``(A^T A)^-1 A^T b`` for a stack of systems (m, 2n, k) given ``inv``: the least-squares solutions (m, k)."""
    return np.matmul(inv, np.matmul(b[:, None, :], a).transpose(0, 2, 1))[:, :, 0]


def _rss(a: np.ndarray, theta: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The squared residual (m,) of each system of a stack at its solution."""
    r = np.matmul(a, theta[:, :, None])[:, :, 0] - b
    return np.einsum("mi,mi->m", r, r)


def flights(rows: np.ndarray, t_launch_s, origin_xy, g_mps2: float, noise_m: float, pre_velocity_mps):
    """``fit_flight`` for every launch time of ``t_launch_s``: solutions (m, 5), vz's standard errors, squared
    residuals (inf where the sightings do not determine it)."""
    a, b, _ = _system(rows, t_launch_s, origin_xy, g_mps2, True, pre_velocity_mps)
    theta, inv, ok = _solve(a, b)
    rss = np.where(ok, _rss(a, theta, b), math.inf)
    return theta, np.sqrt(np.maximum(inv[:, 4, 4], 0.0)) * noise_m, rss


def grounds(rows: np.ndarray, t_launch_s, origin_xy, ball_params: BallModelParams, iterations: int,
             pre_velocity_mps) -> np.ndarray:
    """``fit_ground``'s squared residual for every launch time of ``t_launch_s`` (inf where undetermined)."""
    a, b, t = _system(rows, t_launch_s, origin_xy, 0.0, False, pre_velocity_mps)
    theta, inv, ok = _solve(a, b)
    n, p = len(rows), ball_params
    known = np.zeros_like(b)
    for _ in range(iterations):
        speed = np.hypot(theta[:, 2], theta[:, 3])
        moving = np.flatnonzero(ok & (speed > 1e-6) & (speed <= MAX_SPEED_MPS))
        v = speed[moving, None]
        along = kick_distances(t[moving], v[:, 0], p.a_slide_mps2, p.a_roll_mps2, p.c_switch) - v * t[moving]
        known[moving, :n], known[moving, n:2 * n] = theta[moving, 2:3] / v * along, theta[moving, 3:4] / v * along
        theta = _apply(inv, a, b - known)
    return np.where(ok, _rss(a, theta, b - known), math.inf)


@functools.lru_cache(maxsize=4)
def hop_tables(params: ChipParams, ball_params: BallModelParams) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For each first-touchdown time of ``HOP_T1_S``: a chip launched from the ground at unit ground speed with the vz
    that lands it then (chip_model.ChipTrajectory under ``params``), its ground distance [m per m/s] and height [m] at
    the times ``0, HOP_TAU_STEP_S, ... HOP_TAU_MAX_S`` since the launch (k, j each), and when it rolls (k,). Its ground
    track scales with the launch's ground speed until it rolls (the roll's deceleration does not)."""
    tau = np.arange(0.0, HOP_TAU_MAX_S + 0.5 * HOP_TAU_STEP_S, HOP_TAU_STEP_S)
    chips = [ChipTrajectory((0.0, 0.0, 0.0), (1.0, 0.0, 0.5 * params.g_mps2 * t1), params, ball_params)
             for t1 in HOP_T1_S]
    track = np.array([chip.position_at(tau) for chip in chips])
    return track[:, :, 0], track[:, :, 2], np.array([chip.roll_start_s for chip in chips])


def hop_flights(rows: np.ndarray, t_launch_s, hop, tables, origin_xy, pre_velocity_mps):
    """Least squares for (x0, y0, vx, vy) of a chip launched at ``t_launch_s`` (m,) that first lands ``HOP_T1_S[hop]``
    (m,) later, through its bounces (``hop_tables``): its ground track ``p0 + v D(t)`` seen from the camera at height
    ``H(t)`` gives ``p0 + v D + (G - c) H / cz = G`` per sighting, linear in the four unknowns (before the launch the
    ball on the ground as in ``_system``; the origin, if given, as one more sighting). x and y share the normal
    matrix ``[[n, sum D], [sum D, sum D^2]]``: solved in closed form, all m at once. Solutions (m, 4), squared
    residuals (m,; inf where undetermined)."""
    t_launch_s = np.asarray(t_launch_s, dtype=float)
    tau = rows[None, :, 0] - t_launch_s.reshape(-1, 1)
    distance, height, _ = tables
    index = np.maximum(tau, 0.0) / HOP_TAU_STEP_S
    j = np.minimum(index.astype(int), distance.shape[1] - 2)
    f, k = index - j, np.asarray(hop).reshape(-1, 1)
    d = distance[k, j] * (1.0 - f) + distance[k, j + 1] * f
    h = height[k, j] * (1.0 - f) + height[k, j + 1] * f
    pre = np.minimum(tau, 0.0)
    ref = rows[0, 1:3]  # sums of small numbers: no cancellation in the squared residual
    s0, s1, s2 = np.full(len(t_launch_s), float(len(rows))), d.sum(axis=1), (d * d).sum(axis=1)
    if origin_xy is not None:
        s0 = s0 + ORIGIN_WEIGHT**2
    det = s0 * s2 - s1 * s1
    ok = det > 1e-12 * np.maximum(s0 * s2, 1e-300)
    det = np.where(ok, det, 1.0)
    theta, rss = np.zeros((len(t_launch_s), 4)), np.zeros(len(t_launch_s))
    for axis in (0, 1):
        b = (rows[:, 1 + axis] - ref[axis]) - pre_velocity_mps[axis] * pre \
            - (rows[:, 1 + axis] - rows[:, 3 + axis]) / rows[:, 5] * h
        b0, b1, bb = b.sum(axis=1), (d * b).sum(axis=1), (b * b).sum(axis=1)
        if origin_xy is not None:
            o = np.asarray(origin_xy, dtype=float).reshape(-1, 2)[:, axis] - ref[axis]
            b0, bb = b0 + ORIGIN_WEIGHT**2 * o, bb + ORIGIN_WEIGHT**2 * o * o
        p0, v = (s2 * b0 - s1 * b1) / det, (s0 * b1 - s1 * b0) / det
        theta[:, axis], theta[:, 2 + axis] = p0 + ref[axis], v
        rss += bb - p0 * b0 - v * b1
    return theta, np.where(ok, np.maximum(rss, 0.0), math.inf)


def fit_hop_flight(rows: np.ndarray, t_launch_s: float, hop: int, tables, origin_xy, g_mps2: float,
                   pre_velocity_mps=(0.0, 0.0)) -> ChipFit | None:
    """The chip launched at ``t_launch_s`` that first lands ``HOP_T1_S[hop]`` later (its vz: g T / 2) and bounces as
    the chip model says (``tables``: hop_tables) that best explains the sightings ``rows``, by least squares on the
    rays (as ``fit_flight``); its vz is given, so ``vz_std_mps`` is 0. None when the sightings do not determine it."""
    origins = None if origin_xy is None else [origin_xy]
    theta, rss = hop_flights(rows, [t_launch_s], [hop], tables, origins, pre_velocity_mps)
    if not math.isfinite(rss[0]):
        return None
    x0, y0, vx, vy = theta[0].tolist()
    return ChipFit(float(t_launch_s), x0, y0, vx, vy, 0.5 * g_mps2 * float(HOP_T1_S[hop]), 0.0, float(rss[0]))


def fit_flight(rows: np.ndarray, t_launch_s: float, origin_xy, g_mps2: float, noise_m: float,
               pre_velocity_mps=(0.0, 0.0)) -> ChipFit | None:
    """The flight launched from the ground at ``t_launch_s`` (from ``origin_xy`` if not None) that best explains
    the sightings ``rows`` (Sighting columns; those before the launch: the ball on the ground, see ``_system``), by
    least squares on the rays; None when they do not determine it."""
    theta, vz_std, rss = flights(rows, [t_launch_s], origin_xy, g_mps2, noise_m, pre_velocity_mps)
    if not math.isfinite(rss[0]):
        return None
    x0, y0, vx, vy, vz = theta[0].tolist()
    return ChipFit(float(t_launch_s), x0, y0, vx, vy, vz, float(vz_std[0]), float(rss[0]))


def flight_covariance(rows: np.ndarray, fit: ChipFit, origin, g_mps2: float, noise_m: float,
                      pre_velocity_mps=(0.0, 0.0), tan_angle: float | None = None,
                      speed_prior: tuple[float, float] | None = None) -> np.ndarray | None:
    """The covariance (6, 6) of a fitted flight's ``(x0, y0, vx, vy, vz, t_launch)`` by Gauss-Newton,
    ``sigma^2 (J^T J)^-1``: J the derivatives of ``_system``'s ray residuals at the fit, the launch time's column
    included (the fit searched it); ``sigma`` the larger of ``noise_m`` and the fit's own rms residual per degree
    of freedom (noise or a model worse than assumed widens it). ``origin``: None, or ``(x, y, vx, vy)``: the launch
    point prior at ``t_launch`` and how it moves with it. ``tan_angle``: the fit was at a known elevation (``vz =
    tan_angle |v|``, fit_flight_at_angle), one unknown fewer; ``speed_prior``: ``(v_mps, std_mps)``, with the
    commanded ground speed as one more equation. None when the sightings do not determine it.

    From one camera the height and the ground distance trade off along the camera's ray: few early sightings leave
    ``vz`` (and with it the height) far less certain than the ground track."""
    origin_xy = None if origin is None else [origin[:2]]
    a, b, _ = _system(rows, [fit.t_launch_s], origin_xy, g_mps2, True, pre_velocity_mps)
    a, b, n = a[0], b[0], len(rows)
    tau = rows[:, 0] - fit.t_launch_s
    post = tau > 0.0
    kx, ky = (rows[:, 1] - rows[:, 3]) / rows[:, 5], (rows[:, 2] - rows[:, 4]) / rows[:, 5]
    vz_now = fit.vz_mps - g_mps2 * tau
    jac = np.zeros((a.shape[0], 6))
    jac[:, :5] = a
    # d residual / d t_launch: the flight's projected ground speed after the launch, the old motion's before it
    jac[:n, 5] = np.where(post, -(fit.vx_mps + kx * vz_now), -pre_velocity_mps[0])
    jac[n:2 * n, 5] = np.where(post, -(fit.vy_mps + ky * vz_now), -pre_velocity_mps[1])
    if origin is not None:
        jac[2 * n:, 5] = -ORIGIN_WEIGHT * np.asarray(origin[2:4], dtype=float)
    # a ray residual is the sighting's error times (cz - z) / cz: per unit of the sighting's noise it is the
    # derivative of where the camera sees the ball
    z_m = np.where(post, tau * (fit.vz_mps - 0.5 * g_mps2 * tau), 0.0)
    scale = np.ones(a.shape[0])
    scale[:n] = scale[n:2 * n] = rows[:, 5] / np.maximum(rows[:, 5] - z_m, 1e-3)
    jac *= scale[:, None]
    rss_m2 = float(np.sum((scale * (a @ np.array(fit[1:6]) - b)) ** 2))
    v_ground = math.hypot(fit.vx_mps, fit.vy_mps)
    if speed_prior is not None and v_ground > 0.0:  # the commanded ground speed: one more equation
        weight = noise_m / speed_prior[1]
        prior_row = np.zeros((1, 6))
        prior_row[0, 2:4] = weight * fit.vx_mps / v_ground, weight * fit.vy_mps / v_ground
        jac = np.concatenate([jac, prior_row])
        rss_m2 += (weight * (v_ground - speed_prior[0])) ** 2
    basis = np.eye(6)
    if tan_angle is not None:  # vz follows (vx, vy): the unknowns are (x0, y0, vx, vy, t_launch)
        speed = math.hypot(fit.vx_mps, fit.vy_mps)
        if not speed > 0.0:
            return None
        basis = np.delete(basis, 4, axis=1)
        basis[4, 2:4] = tan_angle * fit.vx_mps / speed, tan_angle * fit.vy_mps / speed
    j = jac @ basis
    jtj = j.T @ j
    if not np.linalg.cond(jtj) < 1e14:  # the launch time not determined by itself: taken as the fit's
        basis[5] = 0.0
        j = jac @ basis
        jtj = j.T @ j + np.diag(np.where(np.any(basis != 0.0, axis=0), 0.0, 1.0))
        if not np.linalg.cond(jtj) < 1e14:
            return None
    dof = j.shape[0] - j.shape[1]
    sigma2 = noise_m**2 if dof <= 0 else max(noise_m**2, rss_m2 / dof)
    return basis @ np.linalg.inv(jtj) @ basis.T * sigma2


def within_kicker_limits(launch: np.ndarray, covariance: np.ndarray, min_elevation_deg: float,
                         max_elevation_deg: float, max_speed_mps: float = KICK_SPEED_LIMIT_MPS):
    """A fitted flight's ``(x0, y0, vx, vy, vz, t_launch)`` and covariance (flight_covariance) given that a
    kicker launched it: the mean and covariance of the fit's Gaussian restricted to the flights a chip kicker
    launches (speed at most ``max_speed_mps``, elevation in range), a uniform prior over them. A fit well inside
    comes back as it is; one that its uncertainty lets out of range moves in (along the camera's ray, where one
    camera's fit is unsure), its covariance the spread the limits leave plus the move. None when (almost) no flight
    within the fit's uncertainty is one a kicker launches. The Gaussian's part within them is taken from fixed
    draws (deterministic)."""
    vx, vy, vz = launch[2:5].tolist()
    v_ground = math.hypot(vx, vy)
    speed = math.hypot(v_ground, vz)
    if speed > 0.0 and v_ground > 0.0:  # linearised: the limits 4 standard errors away or more leave the fit as it is
        d_speed = np.array([0.0, 0.0, vx / speed, vy / speed, vz / speed, 0.0])
        d_elevation = np.array([0.0, 0.0, -vz * vx / v_ground, -vz * vy / v_ground, v_ground, 0.0]) / speed**2
        std_speed = math.sqrt(max(d_speed @ covariance @ d_speed, 0.0))
        std_elevation_deg = math.degrees(math.sqrt(max(d_elevation @ covariance @ d_elevation, 0.0)))
        elevation_deg = math.degrees(math.atan2(vz, v_ground))
        if (speed + 4.0 * std_speed <= max_speed_mps
                and min_elevation_deg <= elevation_deg - 4.0 * std_elevation_deg
                and elevation_deg + 4.0 * std_elevation_deg <= max_elevation_deg):
            return launch, covariance
    try:
        root = np.linalg.cholesky(covariance + 1e-18 * np.eye(6))
    except np.linalg.LinAlgError:
        return None
    samples = launch + _DRAWS @ root.T
    v_ground = np.hypot(samples[:, 2], samples[:, 3])
    elevation_deg = np.degrees(np.arctan2(samples[:, 4], v_ground))
    ok = ((np.hypot(v_ground, samples[:, 4]) <= max_speed_mps) & (elevation_deg >= min_elevation_deg)
          & (elevation_deg <= max_elevation_deg))
    kept = int(np.count_nonzero(ok))
    if kept == len(samples):
        return launch, covariance
    if kept < 0.01 * len(samples):
        return None
    inside = samples[ok]
    mean = inside.mean(axis=0)
    # the limits' own spread is too sure where they disagree with the fit (most of it beyond them: the sightings'
    # noise, a camera or a model off); the distance they moved the fit counts as an error as well
    shift = mean - launch
    return mean, np.cov(inside, rowvar=False) + np.outer(shift, shift)


def flights_at_angle(rows: np.ndarray, t_launch_s, origin_xy, g_mps2: float, noise_m: float, tan_angle: float,
                      iterations: int, pre_velocity_mps, speed_prior=None):
    """``fit_flight_at_angle`` for every launch time of ``t_launch_s``: solutions (m, 5), vz's standard errors,
    squared residuals (inf where the sightings do not determine it). ``speed_prior``: None, or ``(v_mps, weight)``:
    the ground speed is ``v_mps`` as one more equation of this weight (``noise_m`` over the prior's standard
    deviation: its squared residual counts in noise variances as a sighting's does)."""
    a5, b, _ = _system(rows, t_launch_s, origin_xy, g_mps2, True, pre_velocity_mps)
    theta = np.einsum("mkn,mn->mk", np.linalg.pinv(a5), b)[:, :4]  # the direction: the free flight's
    if speed_prior is not None:  # a last row, along the direction of the previous iteration
        a5 = np.concatenate([a5, np.zeros((len(b), 1, 5))], axis=1)
        b = np.concatenate([b, np.full((len(b), 1), speed_prior[1] * speed_prior[0])], axis=1)
    a, inv, ok = a5[:, :, :4], None, np.ones(len(b), dtype=bool)
    for _ in range(iterations):
        speed = np.hypot(theta[:, 2], theta[:, 3])
        ok &= (speed > 1e-6) & (speed <= MAX_SPEED_MPS)
        u = theta[:, 2:4] / np.where(ok, speed, 1.0)[:, None]
        a = a5[:, :, :4].copy()
        a[:, :, 2] += a5[:, :, 4] * (tan_angle * u[:, 0:1])
        a[:, :, 3] += a5[:, :, 4] * (tan_angle * u[:, 1:2])
        if speed_prior is not None:
            a[:, -1, 2:4] = speed_prior[1] * u
        theta, inv, solved = _solve(a, b)
        ok &= solved
    rss = np.where(ok, _rss(a, theta, b), math.inf)
    grad = np.zeros((len(b), 4))
    grad[:, 2:] = tan_angle * u  # d vz / d theta at the last direction
    vz_var = np.einsum("mj,mjk,mk->m", grad, inv, grad) * noise_m**2
    vz = tan_angle * np.einsum("mj,mj->m", u, theta[:, 2:4])
    return np.column_stack([theta, vz]), np.sqrt(np.maximum(vz_var, 0.0)), rss


def fit_flight_at_angle(rows: np.ndarray, t_launch_s: float, origin_xy, g_mps2: float, noise_m: float,
                        tan_angle: float, iterations: int = 3, pre_velocity_mps=(0.0, 0.0),
                        speed_prior: tuple[float, float] | None = None) -> ChipFit | None:
    """As ``fit_flight`` with the launch's elevation known (``vz = tan_angle |v|``, the kicker's angle): four
    unknowns, as many as a ball on the ground has, so a few sightings suffice. The direction of the ground speed is
    taken from the previous iteration (the first: the flight's without the known angle), which keeps it linear.
    ``speed_prior``: ``(v_mps, std_mps)``, the ground speed commanded and how far kicks stray from it, weighed
    against the sightings (the squared residual includes its term)."""
    origins = None if origin_xy is None else [origin_xy]
    prior = None if speed_prior is None else (speed_prior[0], noise_m / speed_prior[1])
    theta, vz_std, rss = flights_at_angle(rows, [t_launch_s], origins, g_mps2, noise_m, tan_angle, iterations,
                                           pre_velocity_mps, prior)
    if not math.isfinite(rss[0]):
        return None
    x0, y0, vx, vy, vz = theta[0].tolist()
    return ChipFit(float(t_launch_s), x0, y0, vx, vy, vz, float(vz_std[0]), float(rss[0]))


def fit_ground(rows: np.ndarray, t_start_s: float, origin_xy, ball_params: BallModelParams,
               iterations: int = 3, pre_velocity_mps=(0.0, 0.0)) -> float:
    """The squared residual [m^2] of the best ball kicked on the ground at ``t_start_s`` (from ``origin_xy`` if
    not None) under the two-phase model ``ball_params``. The model's deceleration along the motion is taken as
    known from the previous iteration's velocity (the first: constant velocity), which keeps the fit linear. inf when
    the sightings do not determine it."""
    return float(grounds(rows, [t_start_s], origin_xy, ball_params, iterations, pre_velocity_mps)[0])


def triangulate_height(a: Sighting, b: Sighting) -> tuple[float, float]:
    """The height [m] of a ball two cameras see at once at the ground points ``a`` and ``b``, and the height one
    metre of disagreement between them makes (its standard error is ``pair_noise_m`` times that).

    Each camera's ray gives the ball at ``G - (G - c) z / cz``; equal for both cameras,
    ``Ga - Gb = z ((Ga - ca) / caz - (Gb - cb) / cbz) = z k``, solved for ``z`` by least squares. The same
    camera twice (``k = 0``) gives no height: (0, inf)."""
    kx = (a.x_m - a.camera_x_m) / a.camera_z_m - (b.x_m - b.camera_x_m) / b.camera_z_m
    ky = (a.y_m - a.camera_y_m) / a.camera_z_m - (b.y_m - b.camera_y_m) / b.camera_z_m
    k2 = kx * kx + ky * ky
    if k2 < 1e-12:
        return 0.0, math.inf
    return ((a.x_m - b.x_m) * kx + (a.y_m - b.y_m) * ky) / k2, 1.0 / math.sqrt(k2)
