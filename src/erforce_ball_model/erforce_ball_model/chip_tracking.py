"""Chip detection and flight reconstruction from the cameras' projected ball (beside the flat filter).

A kick's sightings (every camera's) are fitted on the cameras' rays (chip_fits) as a flight from the ground and,
as the null hypothesis, as a ball kicked on the ground; the launch time is searched. A chip is declared when two
cameras at one instant disagree by a height ``height_sigma`` standard errors above the ground
(``triangulate_height``), or when the flight explains the sightings better than the ground by ``min_gain``
(in units of the noise variance) and is a flight a chip kicker launches (speed, elevation, ``vz`` above
zero; a free fit outside gives way to the best flight at the bounds of the elevations). A short chip that
lands within its sightings is fitted through its first bounce as well (``fit_hop_flight``: the chip model's hops
at a searched touchdown time, four linear unknowns) and judged by the same test when that explains them better:
the bounce cuts the ground speed at once where a ground kick slows steadily. A kick the flat filter does not
report (a slow one stays within its gate) starts from the sightings: a ball at rest that moves off by
``moved_sigma`` noise. Until the first touchdown every new sighting refines the fit; then the chip model
(chip_model.ChipTrajectory with ``ChipParams``) predicts the hops and the hand-over to rolling. Kick hints (the
kicker's angle and commanded speed, ``ChipDetector.hint``) are prior knowledge the cameras correct.

What is reported of a fit taken: its covariance (``flight_covariance``), the flight within the kicker's limits
(``within_kicker_limits``), and the state's covariance at any time (``ChipDetector.state_covariance_at``).

>>> cameras = ((-3.0, 0.0, 4.0), (3.0, 1.0, 4.0))
>>> truth = ChipTrajectory((1.0, 0.5, 0.0), (2.0, 0.0, 2.0), ChipParams())  # kicked at t = 0 from (1, 0.5)
>>> detector = ChipDetector(None, ChipParams())
>>> detector.start(0.01, before=(0.0, 1.0, 0.5, 0.0, 0.0))  # first seen moving at 0.01 s; at rest before
>>> for k in range(1, 8):  # 100 Hz, both cameras, no noise
...     x, y, z = truth.position_at(0.01 * k)
...     for cx, cy, cz in cameras:
...         s = cz / (cz - z)  # where the camera sees it on the ground
...         _ = detector.add(0.01 * k, cx + (x - cx) * s, cy + (y - cy) * s, (cx, cy, cz))
>>> chip = detector.chip_at(0.07)
>>> [round(float(v), 3) for v in chip.velocity_mps]  # at t = 0.07 s: vz = 2 - 9.81 * 0.07
[2.0, 0.0, 1.313]
>>> [round(float(v), 3) for v in chip.touchdown_points_m[0]]  # 1 + 2 * (2 * 2 / 9.81)
[1.815, 0.5]

No rclpy import.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from erforce_ball_model.ball_model import BallModelParams, BallTrajectory, ChipParams
from erforce_ball_model.chip_fits import (
    GROUND_ITERATIONS,
    HOP_T1_S,
    ChipFit,
    Sighting,
    fit_flight,
    flight_covariance,
    flights,
    flights_at_angle,
    grounds,
    hop_flights,
    hop_tables,
    triangulate_height,
    within_kicker_limits,
)
from erforce_ball_model.chip_model import ChipTrajectory
from erforce_interfaces.runtime.param_schema import schema_defaults
from erforce_interfaces.wire.robot_config import VISION_NOISE_M

__all__ = ["ChipDetector", "ChipDetectorConfig"]


_DEFAULTS = schema_defaults("erforce_ball_model", "ball_predictor")

# The cameras contradict a chip hint when another model explains the sightings better than the hinted flight by this
# much (noise variances; chi-square with 2 degrees of freedom at 1 %): the free flight (the commanded speed and angle
# give way to it) or the ground (the ball did not fly: the hint is dropped).
HINT_CONTRADICTED = 9.21

# The old motion's sightings span this long at least before a kick is looked for among them (a velocity from
# fewer is too noisy to extrapolate).
MOVED_SPAN_S = 0.05

# The flights at the bounds of the plausible elevations are fitted this far inside them.
BOUND_INSIDE_DEG = 0.5

# The chip through its first bounce (chip_fits.fit_hop_flight) is searched as follows.
# A bounce is fitted once sightings this long after it are in [s] (two frames): a touchdown fitted just before the
# last sighting bends a high chip's early path as well, its time moving on with every new sighting.
HOP_SEEN_AFTER_S = 0.025
HOP_COARSE = 2  # the first search takes every other touchdown time, then the best's neighbours
HOP_LAUNCH_STEPS = 7  # launch times per search (the free flight's grid is finer: the hop fit runs on fewer)


def _line_velocity(rows: np.ndarray) -> tuple[float, float] | None:
    """The velocity of the least-squares line through sightings (rows of t, x, y, ...); None under two times."""
    if len(rows) < 2:
        return None
    t = rows[:, 0] - rows[:, 0].mean()
    tt = t @ t
    if not tt > 0.0:
        return None
    return float(t @ (rows[:, 1] - rows[:, 1].mean()) / tt), float(t @ (rows[:, 2] - rows[:, 2].mean()) / tt)


@dataclass(frozen=True)
class ChipDetectorConfig:
    """When a kick's sightings are a chip, and how long they are collected."""

    noise_m: float = VISION_NOISE_M  # standard deviation of one sighting per axis (the predictor's position_noise_m)
    min_sightings: int = 4
    min_gain: float = 12.0  # the flight's squared residuals this much below the ground's (noise variances)
    vz_sigma: float = 0.5
    min_vz_mps: float = 0.3
    # a flight a chip kicker can launch (the league's 6.5 m/s kick limit, and what a fit of a few noisy sightings
    # adds to it; a chip kicker's elevation): a fit outside is noise a flight happened to explain, not a chip
    max_launch_speed_mps: float = 8.0
    min_elevation_deg: float = 15.0
    max_elevation_deg: float = 75.0
    launch_steps: int = 12  # launch times tried between the old motion's last sighting and the new one's first
    # the kick may precede the flat filter's first sighting of the new motion by this much (the filter takes the
    # first frame after a kick for noise of the old motion when it moved the ball little)
    launch_lookback_s: float = 0.035
    # a sighting this many ``noise_m`` off the straight line through the sightings before it has moved: the new
    # motion starts there when the flat filter saw it only later (a slow kick moves the ball a few mm a frame)
    moved_sigma: float = 5.0
    launch_refine_steps: int = 2  # finer grids refining the best launch time of the first
    origin_s: float = 0.1  # the old motion's sightings this long before the kick pin the launch point
    # a ball slower than this over ``origin_s`` lies at rest (the predictor's stopped ball): its sightings
    # ``moved_sigma`` off start a kick the flat filter has not reported (it takes a slow kick's first frames within
    # its gate)
    rest_speed_mps: float = _DEFAULTS["rest_speed_mps"]
    window_s: float = 0.3  # sightings of one kick kept this long
    # two cameras' sightings this close in time are of one instant: their disagreement is the ball's height
    pair_dt_s: float = 1e-4
    # standard deviation of the difference between two cameras' ground points of one ball on the ground (their
    # own noise and calibration), and how many of them a height must stand above it to be a ball in the air
    pair_noise_m: float = 0.005
    height_sigma: float = 5.0
    # a kick hint (the kicker's own word: it chipped at this angle, or kicked flat) belongs to the motion first seen
    # this long after it at most
    hint_window_s: float = 0.1
    # with a chip hint: the flight at the kicker's angle may explain the sightings worse than the ground by this much
    # (noise variances) and still be taken (it guards against a hint whose ball did not fly)
    hint_max_loss: float = 4.0
    flat_hint_factor: float = 4.0  # with a flat-kick hint a chip needs this many times min_gain
    # how far a kick's launch speed strays from the commanded one (a kick hint's speed): one standard deviation as a
    # share of the command; it weighs the command against what the cameras see
    kick_speed_std_ratio: float = _DEFAULTS["kick_speed_std_ratio"]
    # with a chip hint that carries the speed the flight is known up to its direction: this many new sightings judge
    hint_min_sightings: int = 2
    # a fit taken as the chip explains its sightings to within this many ``noise_m`` (root mean square per axis): a
    # worse one is of sightings of a ball no longer in that flight
    fit_rms_sigma: float = 10.0

    def __post_init__(self) -> None:
        for name, value in self.__dict__.items():
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"ChipDetectorConfig.{name}: must be finite and > 0, got {value!r}")



class ChipDetector:
    """One kick's sightings (``start``, then ``add`` per camera sighting), judged chip or not; the chip's
    trajectory at a time (``chip_at``) from its detection until it rolls (then ``hand_over`` gives its roll to
    the flat model once).

    A kick starts with ``start`` (the flat filter's new motion) or, when the filter reports none, from the
    sightings: a ball at rest (slower than ``rest_speed_mps``) whose last two frames lie ``moved_sigma`` noise off.
    The launch time is searched from ``launch_lookback_s`` before the first sighting of the new motion (the flat
    filter may have taken the kick's first frame for the old motion; its own sightings may show the kick earlier
    than the filter's word, ``moved_sigma``) to it; the launch point is pinned by the old
    motion's own sightings (``origin_s`` of them), else by the flat filter's last state (``before``). The flight is
    refitted with every sighting (other cameras' of one capture together: ``add``'s ``judge``) until its first
    touchdown; ``fit`` is the newest fit judged a chip (None while the kick is not one), ``detected_at_s`` the time
    of that judgement. A fit is taken only while it explains its
    sightings (``fit_rms_sigma``), a refit only while it is a flight a chip kicker launches: a ball caught or placed
    elsewhere in the air leaves the last good fit in place.

    A kick hint (``hint``: the kicker says it kicked at a time with an elevation; 0 flat) for the motion first seen
    within ``hint_window_s`` after it is prior knowledge: with a chip's angle the flight at that angle is fitted as
    well (four unknowns, as the ground's), taken while the free fit's vertical speed is not yet significant, and
    the kick is a chip unless the ground explains it clearly better; a flat hint raises the evidence a chip needs.
    """

    def __init__(self, config: ChipDetectorConfig | None, params: ChipParams,
                 ball_params: BallModelParams | None = None) -> None:
        """``params``: the chip model in use (the predictor's, predictor.BallPredictor.chip_model)."""
        if not isinstance(params, ChipParams):
            raise ValueError(f"params: expected the chip model in use (ChipParams), got {type(params).__name__}")
        self.config = config or ChipDetectorConfig()
        self.params = params
        self.ball_params = ball_params or BallModelParams()
        self._rows: list[Sighting] = []
        self.t_start_s: float | None = None
        self._before: tuple[float, float, float, float, float] | None = None
        self.fit: ChipFit | None = None
        self.detected_at_s: float | None = None
        self._chip: ChipTrajectory | None = None
        self._handed_over = False
        self._hint: tuple[float, float, float | None] | None = None  # the newest kick hint (t_s, angle_deg, speed)
        self._pre_velocity = (0.0, 0.0)  # the old motion's velocity (the ball before the launch)
        self._origin_seen = False  # the old motion's own sightings pin the launch point
        self._ground_rss: tuple[tuple, float] = ((), math.inf)  # the last ground fit: its sightings' key, its rss
        self.hint_angle_deg: float | None = None  # the hint that belongs to the current kick
        self.hint_speed_mps: float | None = None  # its commanded speed (None: not known)
        self._launch_covariance: np.ndarray | None = None  # the reported flight's (launch_covariance)
        self._pending = False  # sightings added without a judgement since the last one (add's ``judge``)

    def hint(self, t_s: float, angle_deg: float, speed_mps: float | None = None) -> None:
        """The kicker's word: it kicked at ``t_s`` with the elevation ``angle_deg`` (0: flat; a chip in (0, 90))
        and the launch speed ``speed_mps`` commanded (None: not known). It belongs to the next motion first seen
        within ``hint_window_s`` (or the current one, if so seen and not judged a chip yet). A motion first seen before
        ``t_s`` is not that kick (the kicker held the ball then): its collection ends, with any chip found in it, so
        that the kick starts its own (a ball carried round a turning robot's front can pass for a steep chip, and
        while that "chip" hops a kick would count as its bounce). Raises ValueError for a non-finite time, an angle
        outside [0, 90) or a speed that is not finite and > 0.

        A chip hint with its speed is the launch up to its direction (the launch point is where the ball lay): the
        flight at that angle is fitted with the commanded ground speed as one more equation, weighed by
        ``kick_speed_std_ratio`` (fit_flight_at_angle), from ``hint_min_sightings`` new sightings on, and kept
        while the free flight does not explain the sightings better by ``HINT_CONTRADICTED``. A chip hint that the
        cameras contradict (that free flight, or the ground better than the hinted flight by as much: a ball that did
        not fly) is dropped, a chip taken on it withdrawn: the kick is judged from the cameras alone."""
        if not (math.isfinite(t_s) and math.isfinite(angle_deg) and 0.0 <= angle_deg < 90.0):
            raise ValueError(f"kick hint at {t_s!r} s with angle {angle_deg!r} deg: the time must be finite, the "
                             f"angle in [0, 90)")
        if speed_mps is not None and not (math.isfinite(speed_mps) and speed_mps > 0.0):
            raise ValueError(f"kick hint at {t_s!r} s with speed {speed_mps!r} m/s: the speed must be finite, > 0")
        self.judge_pending()
        self._hint = (float(t_s), float(angle_deg), None if speed_mps is None else float(speed_mps))
        if self.t_start_s is not None and self.t_start_s < t_s:
            self.t_start_s, self.fit, self.detected_at_s, self._chip = None, None, None, None
            self.hint_angle_deg, self.hint_speed_mps, self._launch_covariance = None, None, None
        if self.t_start_s is not None and self.fit is None and self._hint_fits(self.t_start_s):
            self.hint_angle_deg, self.hint_speed_mps = self._hint[1:]

    def _hint_fits(self, t_first_s: float) -> bool:
        return self._hint is not None and 0.0 <= t_first_s - self._hint[0] <= self.config.hint_window_s

    def start(self, t_first_s: float, before: tuple[float, float, float, float, float] | None = None) -> None:
        """A new motion (the flat filter's kick) first seen at ``t_first_s``; ``before``: the old motion's
        last state (t_s, x_m, y_m, vx_mps, vy_mps), where the ball left from. Sightings from ``t_first_s`` on
        count, those already added included; a chip detected before is forgotten."""
        self.judge_pending()
        cfg = self.config
        self._rows = [r for r in self._rows if r.t_s >= t_first_s - cfg.launch_lookback_s - cfg.origin_s]
        self.t_start_s, self._before = min(float(t_first_s), self._first_moved(t_first_s)), before
        self._pre_velocity = self._old_velocity(before)
        self._origin_seen = len(self._settled()) > 0
        self.fit, self.detected_at_s, self._chip, self._handed_over = None, None, None, False
        self._ground_rss = ((), math.inf)
        self.hint_angle_deg, self.hint_speed_mps = self._hint[1:] if self._hint_fits(self.t_start_s) else (None, None)

    def _first_moved(self, t_first_s: float) -> float:
        """The time of the first sighting before ``t_first_s`` that, with the next frame's, lies off the old motion by
        ``moved_sigma`` noise: where the kick shows first when the flat filter saw it late (inf: none does)."""
        rows = np.array(self._rows, dtype=float).reshape(-1, 6)
        times = np.unique(rows[:, 0])
        for i in np.flatnonzero(times < t_first_s):
            if self._moved_at(rows, times, int(i)):
                return float(times[i])
        return math.inf

    def _moved_at(self, rows: np.ndarray, times: np.ndarray, i: int, max_speed_mps: float = math.inf) -> bool:
        """A sighting of ``times[i]`` and one of the next frame lie ``moved_sigma`` noise off the old motion: the
        straight line through the sightings before them, once these span ``MOVED_SPAN_S`` (the flat filter's velocity
        may already hold the kick), and only if it is no faster than ``max_speed_mps``."""
        cfg = self.config
        j = int(np.searchsorted(rows[:, 0], times[i]))
        t, x, y = rows[:j, 0], rows[:j, 1], rows[:j, 2]
        if j < 3 or t[-1] - t[0] < MOVED_SPAN_S:
            return False
        tc = t - t.mean()
        vx, vy = tc @ (x - x.mean()) / (tc @ tc), tc @ (y - y.mean()) / (tc @ tc)
        if math.hypot(vx, vy) > max_speed_mps:
            return False
        for k in {i, min(i + 1, len(times) - 1)}:  # each frame: one camera's sighting off suffices (in an overlap
            later = rows[rows[:, 0] == times[k]]  # a flying ball's motion can hide along one camera's ray)
            dt = later[:, 0] - t.mean()
            if not np.any(np.hypot(later[:, 1] - x.mean() - vx * dt, later[:, 2] - y.mean() - vy * dt)
                          > cfg.moved_sigma * cfg.noise_m):
                return False
        return True

    def _self_start(self) -> None:
        """Starts a kick the flat filter has not reported: a ball at rest (its sightings over ``origin_s`` slower than
        ``rest_speed_mps``) whose last two frames lie ``moved_sigma`` noise off it. A slow kick, a slow chip's
        projected path above all, can move on within the filter's gate for its whole flight."""
        cfg = self.config
        t_now = self._rows[-1].t_s
        recent = [r for r in self._rows if t_now - r.t_s <= cfg.origin_s + MOVED_SPAN_S]
        rows = np.array(recent, dtype=float).reshape(-1, 6)
        times = np.unique(rows[:, 0])
        if len(times) >= 4 and self._moved_at(rows, times, len(times) - 2, cfg.rest_speed_mps):
            self.start(float(times[-2]))

    def _still_at_rest(self) -> bool:
        """The kick's sightings since its start span ``origin_s`` and their last ``origin_s`` lie on a line slower than
        ``rest_speed_mps``: the ball stayed at rest, the start was noise (a ball at rest whose sightings strayed
        ``moved_sigma`` by chance). Left in place, such a collection would hold a real kick soon after it (the flat
        filter's kick starts none while one is under way) until ``window_s`` ends."""
        cfg, t_now = self.config, self._rows[-1].t_s
        if t_now - self.t_start_s < cfg.origin_s:
            return False
        velocity = _line_velocity(np.array([r for r in self._rows if t_now - r.t_s <= cfg.origin_s], dtype=float))
        return velocity is not None and math.hypot(*velocity) < cfg.rest_speed_mps

    @property
    def active(self) -> bool:
        """Busy with a kick: judging its sightings, or its chip is still hopping (a new motion the flat filter sees
        then is a bounce, not a kick)."""
        if self.t_start_s is None or not self._rows:
            return False
        if self._chip is not None:
            return self._rows[-1].t_s < self.fit.t_launch_s + self._chip.roll_start_s
        return self._rows[-1].t_s - self.t_start_s <= self.config.window_s

    def _judging(self) -> bool:
        """Sightings still refine the kick: not judged a chip within ``window_s``, or in the chip's first flight."""
        if self._chip is not None:
            return self._rows[-1].t_s < self.fit.t_launch_s + self._chip.touchdown_times_s[0]
        return self._rows[-1].t_s - self.t_start_s <= self.config.window_s

    def add(self, t_s: float, x_m: float, y_m: float, camera_m: tuple[float, float, float], *,
            judge: bool = True) -> ChipFit | None:
        """One camera's ball sighting; the chip fit after it (None: no chip so far). ``judge=False``: more cameras'
        sightings of this capture may follow; they are judged together once (``judge_pending``, which a sighting of
        another time calls first), not each on its own (a refit per camera multiplies the cost by the cameras)."""
        if not all(math.isfinite(v) for v in (t_s, x_m, y_m, *camera_m)) or camera_m[2] <= 0.0:
            raise ValueError(f"sighting ({t_s!r}, {x_m!r}, {y_m!r}) from camera {camera_m!r}: must be finite, "
                             f"the camera above the field")
        if self._rows and t_s != self._rows[-1].t_s:
            self.judge_pending()
        self._rows.append(Sighting(float(t_s), float(x_m), float(y_m), *map(float, camera_m)))
        if not self.active:  # no kick under way: keep a short history only
            self._rows = [r for r in self._rows if t_s - r.t_s <= self.config.window_s]
        self._pending = not judge
        if judge:
            self._judge_newest()
        return self.fit

    def judge_pending(self) -> None:
        """Judge the sightings added with ``judge=False`` since the last judgement (the capture of the newest one is
        complete), as of that capture's time."""
        if self._pending:
            self._pending = False
            self._judge_newest()

    def _judge_newest(self) -> None:
        """The newest capture's judgement: a kick the flat filter missed starts (``_self_start``), a kick's sightings
        are judged."""
        if self.active and self._chip is None and self._still_at_rest():
            self.t_start_s = None  # the ball did not follow that start (noise): a kick after it starts anew
        if not self.active:
            self._self_start()
        if self.active and self._judging():
            self._judge(self._rows[-1].t_s)

    def _settled(self) -> np.ndarray:
        """The kick's sightings that are surely of the old motion (before the earliest launch time tried)."""
        rows = np.array(self._rows, dtype=float).reshape(-1, 6)
        return rows[rows[:, 0] < self.t_start_s - self.config.launch_lookback_s]

    def _old_velocity(self, before) -> tuple[float, float]:
        """The old motion's velocity: a straight line through its own sightings (two frames at least), else the
        flat filter's."""
        velocity = _line_velocity(self._settled())
        if velocity is not None:
            return velocity
        return (0.0, 0.0) if before is None else (float(before[3]), float(before[4]))

    def _launch_times(self) -> tuple[float, float]:
        t_first = self.t_start_s
        t_from = t_first - self.config.launch_lookback_s
        if self._before is not None:
            t_from = min(self._before[0], t_from)
        return t_from, t_first

    def _origins(self, t_launch_s: np.ndarray):
        """The launch points as prior knowledge (m, 2): the flat filter's, only when the old motion's own sightings
        are missing (they pin it themselves, and the filter's last state may already hold the kick's first
        frame); else None."""
        if self._before is None or self._origin_seen:
            return None
        t, x, y, vx, vy = self._before
        dt = np.asarray(t_launch_s, dtype=float) - t
        return np.stack([x + vx * dt, y + vy * dt], axis=1)

    def _over_launch_times(self, evaluate) -> tuple[int, np.ndarray, np.ndarray]:
        """The launch time minimising ``evaluate(times) -> rss`` (an array; inf: undetermined) over the kick's range:
        a grid of ``launch_steps``, then ``launch_refine_steps`` finer grids between the best one's neighbours, then
        the vertex of a parabola (a launch time off by a grid step leaves residuals a wrong model could explain
        better). Returns the best index into the last times evaluated, those times and their rss."""
        lo, hi = self._launch_times()
        times = np.linspace(lo, hi, self.config.launch_steps)
        rss = evaluate(times)
        for _ in range(self.config.launch_refine_steps):
            i = int(np.argmin(rss))
            if not math.isfinite(rss[i]):
                break
            finer = np.linspace(times[max(i - 1, 0)], times[min(i + 1, len(times) - 1)], self.config.launch_steps)
            finer_rss = evaluate(finer)
            if np.min(finer_rss) <= rss[i]:
                times, rss = finer, finer_rss
        i = int(np.argmin(rss))
        if 0 < i < len(times) - 1 and np.all(np.isfinite(rss[i - 1:i + 2])):
            # the vertex of the parabola through the best and its neighbours (rss is smooth between sightings)
            (t0, t1, t2), (r0, r1, r2) = times[i - 1:i + 2], rss[i - 1:i + 2]
            curvature = (r2 - r1) / (t2 - t1) - (r1 - r0) / (t1 - t0)
            if curvature > 0.0:
                vertex = 0.5 * (t0 + t1) - (r1 - r0) / (t1 - t0) * 0.5 * (t2 - t0) / curvature
                vertex_times = np.array([vertex])
                vertex_rss = evaluate(vertex_times)
                if vertex_rss[0] < rss[i]:
                    return 0, vertex_times, vertex_rss
        return i, times, rss

    def _best_flight(self, rows: np.ndarray, tan_angle: float | None = None,
                     speed_prior: tuple[float, float] | None = None) -> ChipFit | None:
        """The best flight over the launch times: free, or at the elevation ``tan_angle`` (a hint's, or a bound of
        the plausible elevations; ``speed_prior``: with a hint's commanded speed, fit_flight_at_angle)."""
        cfg, g, u = self.config, self.params.g_mps2, self._pre_velocity
        prior = None if speed_prior is None else (speed_prior[0], cfg.noise_m / speed_prior[1])

        solved = {}  # the solutions of each grid of times evaluated: the best one's are among them

        def rss_at(times):
            if tan_angle is None:
                solved[id(times)] = times, flights(rows, times, self._origins(times), g, cfg.noise_m, u)
            else:
                solved[id(times)] = times, flights_at_angle(rows, times, self._origins(times), g, cfg.noise_m,
                                                             tan_angle, 3, u, prior)
            return solved[id(times)][1][2]

        i, times, rss = self._over_launch_times(rss_at)
        if not math.isfinite(rss[i]):
            return None
        theta, vz_std, _ = solved[id(times)][1]
        x0, y0, vx, vy, vz = theta[i].tolist()
        return ChipFit(float(times[i]), x0, y0, vx, vy, vz, float(vz_std[i]), float(rss[i]))

    def _hop_flight(self, rows: np.ndarray) -> ChipFit | None:
        """The best chip through its first bounce (``fit_hop_flight``) over the launch times and the first-touchdown
        times that land it ``HOP_SEEN_AFTER_S`` before the last sighting and leave it hopping until then (a flight
        landing later is the free flight's): a grid of both, then finer launch times and the touchdown times next to
        the best. None when no such chip is determined."""
        u = self._pre_velocity
        tables = hop_tables(self.params, self.ball_params)
        lo, hi = self._launch_times()
        t_last = float(rows[-1, 0])
        hops = np.flatnonzero((HOP_T1_S < t_last - lo) & (tables[2] > t_last - hi))
        if len(hops) == 0:
            return None

        def evaluate(times, ks):
            tt, kk = np.repeat(times, len(ks)), np.tile(ks, len(times))
            theta, rss = hop_flights(rows, tt, kk, tables, self._origins(tt), u)
            rss[HOP_T1_S[kk] > t_last - tt - HOP_SEEN_AFTER_S] = math.inf  # landed later: the free flight's
            i = int(np.argmin(rss))
            return tt[i], kk[i], theta[i], rss[i], times, i // len(ks)

        t, k, theta, rss, times, i = evaluate(np.linspace(lo, hi, HOP_LAUNCH_STEPS), hops[::HOP_COARSE])
        for near in (HOP_COARSE + 1, 1):  # finer launch times, the touchdown times next to the best
            if not math.isfinite(rss):
                break
            finer = np.linspace(times[max(i - 1, 0)], times[min(i + 1, len(times) - 1)], HOP_LAUNCH_STEPS)
            best = evaluate(finer, hops[np.abs(hops - k) <= near])
            if best[3] <= rss:
                t, k, theta, rss, times, i = best
        if not math.isfinite(rss):
            return None
        x0, y0, vx, vy = theta.tolist()
        return ChipFit(float(t), x0, y0, vx, vy, 0.5 * self.params.g_mps2 * float(HOP_T1_S[k]), 0.0, float(rss))

    def _bounded_flight(self, rows: np.ndarray, fit: ChipFit | None) -> ChipFit | None:
        """The best flight a chip kicker launches: ``fit`` (the free one) if it is one, else the better of the
        flights at the bounds of the plausible elevations (the least-squares optimum over the plausible flights lies
        on their boundary when the free optimum lies outside; a steep or flat free fit of a few noisy sightings is
        often a true chip's, its height poorly seen). Before a detection only when the free fit's gain over the ground
        reaches the threshold: a bounded fit explains the sightings no better than the free one, and the ground at the
        free fit's launch time no better than the best ground (one fit instead of a search)."""
        if fit is None or self._plausible(fit):
            return fit
        cfg = self.config
        if self.fit is None:
            times = np.array([fit.t_launch_s])
            ground = grounds(rows, times, self._origins(times), self.ball_params, GROUND_ITERATIONS,
                              self._pre_velocity)[0]
            if (ground - fit.rss_m2) / cfg.noise_m**2 < self._min_gain():
                return fit
        # just inside the bounds: a fit at an angle takes the direction of its previous iteration, a hair off its own
        bounded = [self._best_flight(rows, math.tan(math.radians(a)))
                   for a in (cfg.min_elevation_deg + BOUND_INSIDE_DEG, cfg.max_elevation_deg - BOUND_INSIDE_DEG)]
        bounded = [f for f in bounded if f is not None and self._plausible(f)]
        return min(bounded, key=lambda f: f.rss_m2, default=fit)

    def _best_ground(self, rows: np.ndarray) -> float:
        """The squared residual of the best ball kicked on the ground over the launch times (inf: undetermined); the
        last one is kept for the same sightings."""
        key = (len(rows), float(rows[0, 0]), float(rows[-1, 0]), self.t_start_s)
        if self._ground_rss[0] == key:
            return self._ground_rss[1]

        def evaluate(times):
            return grounds(rows, times, self._origins(times), self.ball_params, GROUND_ITERATIONS,
                            self._pre_velocity)

        i, _, rss = self._over_launch_times(evaluate)
        self._ground_rss = (key, float(rss[i]))
        return float(rss[i])

    def _min_gain(self) -> float:
        """The gain over the ground a chip needs without a chip hint (more after a flat hint)."""
        cfg = self.config
        return cfg.min_gain * (cfg.flat_hint_factor if self.hint_angle_deg == 0.0 else 1.0)

    def _judge(self, t_s: float) -> None:
        cfg, g = self.config, self.params.g_mps2
        rows = np.array(self._rows, dtype=float).reshape(-1, 6)
        prior = self._speed_prior()
        if self._new_sightings(rows) < (cfg.min_sightings if prior is None else cfg.hint_min_sightings):
            return
        commanded = None if prior is None else self._commanded_flight(rows, prior)
        if commanded is not None and commanded[0] is None:  # the cameras contradict the command
            self._drop_hint()
            self._judge(t_s)  # from the cameras alone
            return
        all_rows, free = rows, None
        if commanded is not None:
            fit, rows = commanded
            tan_angle = math.tan(math.radians(self.hint_angle_deg))
        else:
            prior = None
            if self._new_sightings(rows) < cfg.min_sightings:
                return
            fit = free = self._flight(rows)
            if fit is not None and fit.vz_mps > cfg.vz_sigma * fit.vz_std_mps:
                # sightings after the first touchdown belong to the next hop: fit the first flight only (once the
                # flight is sure enough to say when it lands)
                first_hop = self._first_flight(rows, fit)
                if len(first_hop) < len(rows):
                    rows = first_hop
                    fit = self._flight(rows) if self._new_sightings(rows) >= cfg.min_sightings else None
            tan_angle = None
            if self._chip_hinted() and self._new_sightings(rows) >= cfg.min_sightings and (
                    fit is None or fit.vz_mps < cfg.vz_sigma * fit.vz_std_mps):  # the free fit says too little yet
                tan_angle = math.tan(math.radians(self.hint_angle_deg))
                fit = self._best_flight(rows, tan_angle)
        if fit is not None and self._chip_hinted() and self._ground_contradicts(fit, rows):
            self._drop_hint()
            self._judge(t_s)
            return
        if fit is None or not self._is_chip(fit, rows):
            fit = None
        landed = None
        if commanded is None and (fit is None or all_rows[-1, 0] - fit.t_launch_s >= 2.0 * fit.vz_mps / g):
            # no chip in the air through the sightings: one that bounced within them, if that explains them better
            landed = self._landed_chip(all_rows, free)
        if landed is not None:
            fit, rows = landed, self._first_flight(all_rows, landed)
        if fit is None:
            return
        try:
            chip, covariance = self._reported_flight(fit, rows, tan_angle, prior, landed is not None)
        except ValueError:
            return
        self.fit, self._chip, self._launch_covariance = fit, chip, covariance
        if self.detected_at_s is None:
            self.detected_at_s = t_s

    def _speed_prior(self) -> tuple[float, float] | None:
        """A chip hint's commanded ground speed and its standard deviation (``kick_speed_std_ratio``); None without
        a chip hint or its speed."""
        if not self._chip_hinted() or self.hint_speed_mps is None:
            return None
        v_ground = self.hint_speed_mps * math.cos(math.radians(self.hint_angle_deg))
        return v_ground, self.config.kick_speed_std_ratio * v_ground

    def _commanded_flight(self, rows: np.ndarray, prior: tuple[float, float]):
        """The flight at the hint's angle with its commanded speed as a prior, fitted to the sightings of its first
        flight, and those sightings; (None, sightings) when the cameras contradict it (the free flight explains them
        better by ``HINT_CONTRADICTED``); None when it is not determined (then judged as with the angle alone)."""
        cfg, g = self.config, self.params.g_mps2
        tan_angle = math.tan(math.radians(self.hint_angle_deg))
        fit = self._best_flight(rows, tan_angle, prior)
        if fit is None or not fit.vz_mps > 0.0:
            return None
        first_hop = self._first_flight(rows, fit)  # the next hop's are not this flight's
        if len(first_hop) < len(rows) and self._new_sightings(first_hop) >= cfg.hint_min_sightings:
            rows = first_hop
            fit = self._best_flight(rows, tan_angle, prior)
            if fit is None:
                return None
        free = None
        if self._new_sightings(rows) >= cfg.min_sightings:  # once a chip is taken: launched when the commanded one
            free = self._best_flight(rows) if self.fit is None else fit_flight(
                rows, fit.t_launch_s, self._origins([fit.t_launch_s]), g, cfg.noise_m, self._pre_velocity)
        if free is not None and (fit.rss_m2 - free.rss_m2) / cfg.noise_m**2 > HINT_CONTRADICTED:
            return None, rows
        return fit, rows

    def _ground_contradicts(self, fit: ChipFit, rows: np.ndarray) -> bool:
        """The ground explains the sightings better than the hinted flight ``fit`` by ``HINT_CONTRADICTED``: the
        ball did not fly (a flat ball, which one camera's first frames may not tell from the chip). Once a chip is
        taken, the best ground kick of one batch (the launch times' first grid and the flight's), not a search: it is
        checked every frame."""
        if self.fit is None:
            ground = self._best_ground(rows)  # the judgement's own (kept for _is_chip)
        else:
            times = np.append(np.linspace(*self._launch_times(), self.config.launch_steps), fit.t_launch_s)
            ground = float(np.min(grounds(rows, times, self._origins(times), self.ball_params, GROUND_ITERATIONS,
                                           self._pre_velocity)))
        return (ground - fit.rss_m2) / self.config.noise_m**2 < -HINT_CONTRADICTED

    def _drop_hint(self) -> None:
        """The cameras contradict the kick's hint: it is dropped (the kick is judged from the cameras alone from now
        on) and a chip taken on it withdrawn."""
        self.hint_angle_deg = self.hint_speed_mps = None
        self.fit = self._chip = self._launch_covariance = self.detected_at_s = None

    def _first_flight(self, rows: np.ndarray, fit: ChipFit) -> np.ndarray:
        """The sightings of ``fit``'s first flight (before its first touchdown)."""
        return rows[rows[:, 0] - fit.t_launch_s < 2.0 * fit.vz_mps / self.params.g_mps2]

    def _landed_chip(self, rows: np.ndarray, fit: ChipFit | None) -> ChipFit | None:
        """Before a detection without a chip hint: the chip through its first bounce (``_hop_flight``) when it
        explains the sightings better than the free flight ``fit`` and is a chip by the same test (None: not). The
        bounce takes a share of the ground speed at once and starts a lower flight, which no ground kick does and a
        free flight through the sightings after it mistakes for a steep or slow one. Asked only when no chip stays
        in the air through the sightings: a high chip's early sightings fit a short hop by chance now and then."""
        if self.fit is not None or self._chip_hinted():
            return None
        hop = self._hop_flight(rows)
        if hop is None or (fit is not None and fit.rss_m2 <= hop.rss_m2) or not self._is_chip(hop, rows):
            return None
        return hop

    def _flight(self, rows: np.ndarray) -> ChipFit | None:
        """The flight judged: the best one a chip kicker launches (with a chip hint: the best free one)."""
        fit = self._best_flight(rows)
        return fit if self._chip_hinted() else self._bounded_flight(rows, fit)

    def _new_sightings(self, rows: np.ndarray) -> int:
        """How many of ``rows`` are of the new motion (from the flat filter's first sighting of it on)."""
        return int(np.count_nonzero(rows[:, 0] >= self.t_start_s))

    def _is_chip(self, fit: ChipFit, rows: np.ndarray) -> bool:
        cfg = self.config
        # Sightings no flight explains (the ball caught, or placed elsewhere while in the air) fit a steep flight of
        # tens of m/s whose touchdown is seconds away: taken, it would keep absorbing sightings and carry the chip
        # far off the field. A fit taken as the chip explains its sightings; else the last good fit stays.
        if math.sqrt(fit.rss_m2 / (2 * len(rows))) > cfg.fit_rms_sigma * cfg.noise_m:
            return False
        if self.fit is not None:  # judged a chip: a refit must stay a flight a chip kicker launches
            return fit.vz_mps > cfg.min_vz_mps and self._plausible(fit)
        if fit.vz_mps >= cfg.min_vz_mps and self._triangulated(rows, fit.t_launch_s):
            return True
        hinted = self._chip_hinted()
        if not hinted and not self._plausible(fit):
            return False
        if not fit.vz_mps >= (cfg.min_vz_mps if hinted else max(cfg.min_vz_mps, cfg.vz_sigma * fit.vz_std_mps)):
            return False
        ground = self._best_ground(rows)
        if not math.isfinite(ground):  # the sightings do not determine a ground ball either
            return False
        gain = (ground - fit.rss_m2) / cfg.noise_m**2
        if hinted:
            return gain >= -cfg.hint_max_loss
        return gain >= self._min_gain()

    def _plausible(self, fit: ChipFit) -> bool:
        """A flight a chip kicker launches: not faster than ``max_launch_speed_mps``, its elevation in range."""
        cfg = self.config
        v_ground = math.hypot(fit.vx_mps, fit.vy_mps)
        elevation_deg = math.degrees(math.atan2(fit.vz_mps, v_ground))
        return (math.hypot(v_ground, fit.vz_mps) <= cfg.max_launch_speed_mps
                and cfg.min_elevation_deg <= elevation_deg <= cfg.max_elevation_deg)

    def _triangulated(self, rows: np.ndarray, t_launch_s: float) -> bool:
        """Two cameras saw the flight at one instant at ground points only a ball ``height_sigma`` standard errors
        above the ground explains."""
        cfg = self.config
        rows = rows[rows[:, 0] > t_launch_s]
        for i in range(len(rows) - 1):
            for j in range(i + 1, len(rows)):
                if rows[j, 0] - rows[i, 0] > cfg.pair_dt_s:
                    break
                z_m, m_per_m = triangulate_height(Sighting(*rows[i]), Sighting(*rows[j]))
                if z_m > cfg.height_sigma * cfg.pair_noise_m * m_per_m:
                    return True
        return False

    def _chip_hinted(self) -> bool:
        return self.hint_angle_deg is not None and self.hint_angle_deg > 0.0

    @property
    def launch(self) -> ChipTrajectory | None:
        """The chip as it left the ground (at ``fit.t_launch_s``), None while no chip is detected."""
        return self._chip

    def chip_at(self, t_s: float) -> ChipTrajectory | None:
        """The chip at ``t_s``: None when none is detected or it rolls by then (the flat model's ball)."""
        chip = self._chip
        if chip is None:
            return None
        dt = t_s - self.fit.t_launch_s
        if dt >= chip.roll_start_s:
            return None
        return chip.advanced(max(dt, 0.0))

    def _reported_flight(self, fit: ChipFit, rows: np.ndarray, tan_angle: float | None,
                         speed_prior: tuple[float, float] | None = None, landed: bool = False):
        """The chip reported of a fit taken, and its launch covariance: the fit's flight_covariance, then the
        flight within the kicker's limits (within_kicker_limits; the fit's own launch time kept) -- one camera's
        early fit trades height for ground distance along the ray, and a fit beyond what a kicker launches is the
        noise's. The fit as it is where nothing of it is within them, and for a chip fitted through its bounce
        (``landed``: its touchdown pins vz; the covariance of its first flight's sightings alone overstates that).
        Raises ValueError for a flight ChipTrajectory refuses."""
        origin = None
        if self._before is not None and not self._origin_seen:  # as _origins: the flat filter's launch point
            origin = (*self._origins([fit.t_launch_s])[0], self._before[3], self._before[4])
        covariance = flight_covariance(rows, fit, origin, self.params.g_mps2, self.config.noise_m,
                                       self._pre_velocity, tan_angle, speed_prior)
        launch = np.array([fit.x_m, fit.y_m, fit.vx_mps, fit.vy_mps, fit.vz_mps, fit.t_launch_s])
        if covariance is not None and not landed:
            limited = within_kicker_limits(launch, covariance, self.config.min_elevation_deg,
                                           self.config.max_elevation_deg)
            if limited is not None:
                launch, covariance = limited
        x0, y0, vx, vy, vz = launch[:5].tolist()
        return ChipTrajectory((x0, y0, 0.0), (vx, vy, max(vz, 0.0)), self.params, self.ball_params), covariance

    def launch_covariance(self) -> np.ndarray | None:
        """The covariance (6, 6) of the reported chip's ``(x0, y0, vx, vy, vz, t_launch)``; None while no chip is
        detected or the sightings do not determine it."""
        return None if self._chip is None else self._launch_covariance

    def state_covariance_at(self, t_s: float) -> np.ndarray | None:
        """The covariance (6, 6) of ``(x, y, z, vx, vy, vz)`` of ``chip_at(t_s)``: the fit's (launch_covariance)
        carried along the flight and its bounces (ChipTrajectory.sensitivity_at; a later launch is the same
        flight earlier). None when chip_at is None or the fit's covariance is."""
        chip, cov = self._chip, self.launch_covariance()
        if chip is None or cov is None:
            return None
        dt = max(t_s - self.fit.t_launch_s, 0.0)
        if dt >= chip.roll_start_s:
            return None
        jac = np.zeros((6, 6))
        # the launch state (x0, y0, 0, vx, vy, vz) from the fit's unknowns, then along the flight
        jac[:, :5] = chip.sensitivity_at(dt)[:, [0, 1, 3, 4, 5]]
        (vx, vy, vz) = chip.velocity_at(dt).tolist()
        jac[:, 5] = -np.array([vx, vy, vz, 0.0, 0.0, -self.params.g_mps2])
        return jac @ cov @ jac.T

    def hand_over(self, t_s: float) -> BallTrajectory | None:
        """Once, when the detected chip rolls at ``t_s``: its roll then, for the flat model to take over."""
        chip = self._chip
        if chip is None or self._handed_over or t_s - self.fit.t_launch_s < chip.roll_start_s:
            return None
        self._handed_over = True
        return chip.roll.advanced(t_s - self.fit.t_launch_s - chip.roll_start_s)


