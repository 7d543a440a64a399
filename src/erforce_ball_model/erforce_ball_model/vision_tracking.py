"""Tracking from real vision: several overlapping cameras, false ball candidates, frames out of order.

SSL-Vision sends one frame per camera, each at its own rate and latency; a frame may list several ball
candidates (the ball, a reflection, a second ball in the run-off area) or none. ``VisionTracker`` turns
those frames into what the single-stream trackers of ``tracking`` take: one ball observation and one
pose per robot at strictly increasing stamps.

Ball: the candidate nearest to the tracked ball's prediction, within a gate that grows with the time
since it was seen (``max_ball_speed_mps``), is fed to a ``tracking.BallTracker``. Every candidate is also
a hypothesis, confirmed when seen in ``confirm_frames`` frames within ``confirm_window_s`` where the
previous sighting could have moved. The track moves to a confirmed hypothesis inside the field lines
when its ball is lost for ``lost_after_s`` (put down elsewhere) or while it follows a ball in the run-off
area (the game ball is the one on the field).

Order and robots: a camera frame not after the newest one used is older news; its robots seen later are not used,
and its ball is not the ball's stream: the candidate near the ball taken (``sighting_gate_m``; another camera sees a
ball in the air elsewhere on the ground) is that camera's sighting, for the chip detector. A robot sighting that the
last pose cannot reach at ``max_robot_speed_mps`` is held back; two agreeing held-back sightings re-seed the robot;
duplicate ids take the nearest. The robot streams, the ball hypotheses and the choice of the ball are compiled
passes over arrays (``frame_arrays``), the same kernels vision_fast_path runs per datagram; outside that pass the
ball filter is updated through ``use_ball``.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from erforce_ball_model.ball_model import BallModelParams
from erforce_ball_model.tracking import S_T, BallTracker, TrackerConfig, UpdateStatus
from erforce_ball_model.tracking import load_kernels as load_ball_filter_kernels
from erforce_interfaces.runtime.numba_support import numba
from erforce_interfaces.runtime.param_schema import schema_defaults
from erforce_interfaces.ssl.ssl_vision import TEAMS, DecodeLimits
from erforce_interfaces.wire.robot_config import FieldConfig

_PREDICTOR = schema_defaults("erforce_ball_model", "ball_predictor")

__all__ = ["BALL_NONE", "BALL_SIGHTING", "BALL_SWITCH", "BALL_UPDATE", "COUNT_FRAMES", "COUNT_HYPOTHESES",
           "MAX_ROBOT_ID", "SETTING_BALL_GATE", "SETTING_BALL_SPEED", "SETTING_HALF_LENGTH", "SETTING_HALF_WIDTH",
           "SETTING_HYPOTHESIS_TIMEOUT", "SETTING_MAX_X", "SETTING_MAX_Y", "SETTING_MIN_CONFIDENCE",
           "SETTING_ROBOT_GATE", "SETTING_ROBOT_SPEED", "BallObservation", "RobotObservation", "VisionTracker",
           "VisionTrackingConfig", "choose_ball", "load_kernels", "track_robots", "update_hypotheses"]

MAX_ROBOT_ID = DecodeLimits().max_robot_id  # what SSL-Vision can report
_TEAM_INDEX = {team: k for k, team in enumerate(TEAMS)}


@dataclass(frozen=True)
class VisionTrackingConfig:
    ball_gate_m: float = 0.15  # gate radius around the prediction, plus the growth below
    # the gate grows at this speed while the ball is unseen ...
    max_ball_speed_mps: float = _PREDICTOR["max_ball_speed_mps"]
    max_ball_gate_m: float = 1.5  # ... up to this radius
    # unseen this long while another confirmed candidate is: switch (3-4 frames; a scenario or a referee
    # puts the ball down elsewhere, and every frame waited for is one the predictor lacks)
    lost_after_s: float = 0.05
    confirm_frames: int = 3  # sightings of a hypothesis ...
    confirm_window_s: float = 0.06  # ... within this time (a flickering reflection is not a ball) ...
    fresh_s: float = 0.05  # ... the last one this recent
    hypothesis_timeout_s: float = 0.1  # a candidate not seen again this long is forgotten
    min_confidence: float = 0.05
    outside_margin_m: float = 0.5  # candidates farther outside the field lines are not on our field
    max_robot_speed_mps: float = 6.0
    robot_gate_m: float = 0.1
    max_hypotheses: int = 16
    # a camera frame of an instant whose ball is taken (an overlap): its candidate this near the ball taken is that
    # camera's sighting of it (two cameras 3-4.5 m apart at 4 m see a ball 0.4-0.55 m up this far apart)
    sighting_gate_m: float = 0.5

    def __post_init__(self) -> None:
        for name, value in self.__dict__.items():
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"{name}: must be finite and >= 0, got {value!r}")
        if self.confirm_frames < 1 or self.max_hypotheses < 1:
            raise ValueError("confirm_frames and max_hypotheses must be >= 1")


class BallObservation(NamedTuple):
    t_s: float
    x_m: float
    y_m: float
    camera_id: int
    status: UpdateStatus  # a sighting: REJECTED_TIME (not after the ball's newest)
    sighting: bool = False  # another camera's view of an instant the ball's stream has (BALL_SIGHTING)


class RobotObservation(NamedTuple):
    team: str
    robot_id: int
    t_s: float
    x_m: float
    y_m: float
    theta_rad: float | None
    camera_id: int


# Ball hypotheses: one row each, in order of creation, these columns; their sighting times apart.
_H_T, _H_X, _H_Y, _H_CONFIDENCE, _H_INSIDE, _H_HITS = range(6)


@numba.njit(cache=True, error_model="numpy")
def update_hypotheses(hyps, hits, n_hyps, t_s, balls, min_confidence, max_x, max_y, half_length, half_width,
                       timeout_s, gate_m, speed_mps, candidates):
    """The frame's ball candidates (rows x, y, confidence of ``balls`` within the confidence and the
    margin) into ``candidates``; each joins the nearest hypothesis it can have reached or starts one.
    Returns (hypotheses, candidates). ``hits``: per hypothesis its last sighting times, oldest first."""
    kept = 0
    for k in range(n_hyps):  # forget those not seen for timeout_s (in order)
        if abs(t_s - hyps[k, _H_T]) <= timeout_s:
            hyps[kept] = hyps[k]
            hits[kept] = hits[k]
            kept += 1
    n_hyps = kept
    n_candidates = 0
    for k in range(balls.shape[0]):
        x, y, c = balls[k, 0], balls[k, 1], balls[k, 2]
        if not (c >= min_confidence and abs(x) <= max_x and abs(y) <= max_y):  # False for NaN
            continue
        candidates[n_candidates, 0], candidates[n_candidates, 1], candidates[n_candidates, 2] = x, y, c
        n_candidates += 1
        best, best_d2 = -1, np.inf
        for h in range(n_hyps):
            reach = gate_m + speed_mps * abs(t_s - hyps[h, _H_T])
            dx, dy = x - hyps[h, _H_X], y - hyps[h, _H_Y]
            d2 = dx * dx + dy * dy
            if d2 <= reach * reach and d2 < best_d2:
                best, best_d2 = h, d2
        inside = 1.0 if abs(x) <= half_length and abs(y) <= half_width else 0.0
        if best < 0:
            if n_hyps < hyps.shape[0]:
                hyps[n_hyps, _H_T], hyps[n_hyps, _H_X], hyps[n_hyps, _H_Y] = t_s, x, y
                hyps[n_hyps, _H_CONFIDENCE], hyps[n_hyps, _H_INSIDE], hyps[n_hyps, _H_HITS] = c, inside, 1.0
                hits[n_hyps, 0] = t_s
                n_hyps += 1
        elif t_s > hyps[best, _H_T]:  # a new sighting (not the same instant from an overlapping camera)
            hyps[best, _H_T], hyps[best, _H_X], hyps[best, _H_Y], hyps[best, _H_INSIDE] = t_s, x, y, inside
            hyps[best, _H_CONFIDENCE] += c
            n_hits = int(hyps[best, _H_HITS])
            if n_hits < hits.shape[1]:
                hits[best, n_hits] = t_s
                hyps[best, _H_HITS] = n_hits + 1
            else:  # keep the newest
                hits[best, :-1] = hits[best, 1:].copy()
                hits[best, -1] = t_s
    return n_hyps, n_candidates


@numba.njit(cache=True, error_model="numpy")
def _best_confirmed(hyps, hits, n_hyps, t_s, inside_only, window_s, fresh_s):
    """Index of the confirmed hypothesis inside the field lines first, then of the highest summed
    confidence (the first of equals), or -1."""
    best = -1
    confirm_frames = hits.shape[1]
    for h in range(n_hyps):
        if not (hyps[h, _H_HITS] == confirm_frames and hits[h, -1] - hits[h, 0] <= window_s
                and t_s - hits[h, -1] <= fresh_s and (hyps[h, _H_INSIDE] != 0.0 or not inside_only)):
            continue
        if best < 0 or hyps[h, _H_INSIDE] > hyps[best, _H_INSIDE] or (
                hyps[h, _H_INSIDE] == hyps[best, _H_INSIDE] and hyps[h, _H_CONFIDENCE] > hyps[best, _H_CONFIDENCE]):
            best = h
    return best


# The tracker's numbers for the compiled passes (these, update_hypotheses, choose_ball and track_robots are what
# erforce_ball_model.vision_fast_path runs): its settings (with the field's half sizes), the ball filter's state as the
# choice needs it (kept in step with ``VisionTracker.ball``), and its counters.
(SETTING_MIN_CONFIDENCE, SETTING_MAX_X, SETTING_MAX_Y, SETTING_HALF_LENGTH, SETTING_HALF_WIDTH,
 SETTING_HYPOTHESIS_TIMEOUT, SETTING_BALL_GATE, SETTING_BALL_SPEED, SETTING_MAX_BALL_GATE, SETTING_LOST_AFTER,
 SETTING_MAX_GAP, SETTING_CONFIRM_WINDOW, SETTING_FRESH, SETTING_ROBOT_GATE, SETTING_ROBOT_SPEED,
 SETTING_SIGHTING_GATE) = range(16)
(_B_USED, _B_T_USED, _B_LAST_X, _B_LAST_Y, _B_INITIALIZED, _B_FILTER_T, _B_X, _B_Y, _B_VX, _B_VY) = range(10)
COUNT_HYPOTHESES, COUNT_FRAMES, COUNT_LATE_BALLS, COUNT_FALSE_CANDIDATES, COUNT_SWITCHES = range(5)
BALL_NONE, BALL_UPDATE, BALL_SWITCH = range(3)  # what choose_ball asks of the ball filter
# the compiled pass fused the ball already (BALL_FUSED + its UpdateStatus: INITIALIZED or ACCEPTED)
BALL_FUSED = 3
# not the ball's: another camera's sighting of an instant taken (nothing for the filter; after BALL_FUSED's range)
BALL_SIGHTING = BALL_FUSED + len(UpdateStatus)


@numba.njit(cache=True, error_model="numpy")
def note_ball_taken(ball_state, t_s, x, y, ball_filter):
    """The ball filter's state as choose_ball reads it, after it took the observation (t_s, x, y); its state
    ``ball_filter`` is BallTracker.s (initialized)."""
    ball_state[_B_USED], ball_state[_B_T_USED], ball_state[_B_LAST_X], ball_state[_B_LAST_Y] = 1.0, t_s, x, y
    ball_state[_B_INITIALIZED] = 1.0
    for k in range(5):  # filter time, x, y, vx, vy
        ball_state[_B_FILTER_T + k] = ball_filter[S_T + k]


@numba.njit(cache=True, error_model="numpy")
def _gate_m(p, t_s, t_ref_s):
    return min(p[SETTING_BALL_GATE] + p[SETTING_BALL_SPEED] * max(t_s - t_ref_s, 0.0), p[SETTING_MAX_BALL_GATE])


@numba.njit(cache=True, error_model="numpy")
def choose_ball(hyps, hits, t_s, candidates, n_candidates, p, ball, counts):
    """Which of the frame's ``candidates`` (rows x, y, confidence; after update_hypotheses) is the ball (see the
    module docstring): (BALL_NONE / BALL_UPDATE / BALL_SWITCH (a new filter first) / BALL_SIGHTING, x, y);
    ``counts`` updated."""
    n_hyps = counts[COUNT_HYPOTHESES]
    if ball[_B_USED] != 0.0 and t_s <= ball[_B_T_USED]:
        if not n_candidates:
            return BALL_NONE, 0.0, 0.0
        counts[COUNT_LATE_BALLS] += 1
        # another camera's view of the ball taken: near it, allowing for the ball's motion in between
        radius = min(p[SETTING_SIGHTING_GATE] + p[SETTING_BALL_SPEED] * (ball[_B_T_USED] - t_s),
                     p[SETTING_MAX_BALL_GATE])
        chosen, best = -1, np.inf
        for k in range(n_candidates):
            d = math.hypot(candidates[k, 0] - ball[_B_LAST_X], candidates[k, 1] - ball[_B_LAST_Y])
            if d <= radius and d < best:
                chosen, best = k, d
        if chosen < 0:
            return BALL_NONE, 0.0, 0.0
        return BALL_SIGHTING, candidates[chosen, 0], candidates[chosen, 1]
    if n_candidates == 0:
        return BALL_NONE, 0.0, 0.0
    if ball[_B_USED] != 0.0 and ball[_B_INITIALIZED] != 0.0:
        # Two gates: around the filter's prediction (constant velocity is close enough: the deceleration
        # moves the ball < 2 cm in 0.1 s), and around the last observation used, which the filter may hold
        # back (a kick: the filter still has the ball at rest).
        filter_t = ball[_B_FILTER_T]
        dt = t_s - filter_t
        px, py = ball[_B_X] + ball[_B_VX] * dt, ball[_B_Y] + ball[_B_VY] * dt
        radius = _gate_m(p, t_s, filter_t)
        second = ball[_B_T_USED] > filter_t
        last_radius = _gate_m(p, t_s, ball[_B_T_USED])
        chosen, best = -1, np.inf
        for k in range(n_candidates):
            cx, cy = candidates[k, 0], candidates[k, 1]
            d = math.hypot(cx - px, cy - py)
            if d <= radius and d < best:
                chosen, best = k, d
            if second:
                d = math.hypot(cx - ball[_B_LAST_X], cy - ball[_B_LAST_Y])
                if d <= last_radius and d < best:
                    chosen, best = k, d
        counts[COUNT_FALSE_CANDIDATES] += n_candidates - (1 if chosen >= 0 else 0)
        other = -1
        unseen_s = t_s - ball[_B_T_USED]
        if chosen < 0 and unseen_s >= p[SETTING_LOST_AFTER]:
            # long gone (a filter restart's gap): any confirmed ball, also one in the run-off area
            other = _best_confirmed(hyps, hits, n_hyps, t_s, unseen_s < p[SETTING_MAX_GAP], p[SETTING_CONFIRM_WINDOW],
                                    p[SETTING_FRESH])
        elif chosen >= 0 and not (abs(candidates[chosen, 0]) <= p[SETTING_HALF_LENGTH]
                                  and abs(candidates[chosen, 1]) <= p[SETTING_HALF_WIDTH]):
            # tracking a ball in the run-off area: a confirmed one on the field is the game ball
            other = _best_confirmed(hyps, hits, n_hyps, t_s, True, p[SETTING_CONFIRM_WINDOW], p[SETTING_FRESH])
            if other >= 0 and math.hypot(hyps[other, _H_X] - candidates[chosen, 0],
                                         hyps[other, _H_Y] - candidates[chosen, 1]) <= p[SETTING_BALL_GATE]:
                other = -1
        if other >= 0:
            counts[COUNT_SWITCHES] += 1
            return BALL_SWITCH, hyps[other, _H_X], hyps[other, _H_Y]
        if chosen >= 0:
            return BALL_UPDATE, candidates[chosen, 0], candidates[chosen, 1]
        return BALL_NONE, 0.0, 0.0
    other = _best_confirmed(hyps, hits, n_hyps, t_s, False, p[SETTING_CONFIRM_WINDOW], p[SETTING_FRESH])
    if other < 0:
        return BALL_NONE, 0.0, 0.0
    counts[COUNT_FALSE_CANDIDATES] += n_candidates - 1
    return BALL_UPDATE, hyps[other, _H_X], hyps[other, _H_Y]


# Robot tracks: one row per team and id (team index * (MAX_ROBOT_ID + 1) + id), these columns.
_SEEN, _T, _X, _Y, _HELD, _HELD_T, _HELD_X, _HELD_Y = range(8)


@numba.njit(cache=True, error_model="numpy")
def track_robots(robots, t_s, tracks, gate_m, speed_mps, max_id, used):
    """The rows of ``robots`` (team, id, x, y, ...) to use at ``t_s``, in order of first sighting:
    their indices into ``used``, their number returned; ``tracks`` updated in place (see the module
    docstring). (Arrays in, a number out: numba boxes each returned array for about 1.5 us.)"""
    n = robots.shape[0]
    chosen = np.full(tracks.shape[0], -1, np.int64)
    keys = np.empty(n, np.int64)
    n_keys = 0
    for k in range(n):  # one sighting per robot: a duplicate id counts as the one nearer the last pose
        team, robot_id, x, y = robots[k, 0], robots[k, 1], robots[k, 2], robots[k, 3]
        if not (np.isfinite(x) and np.isfinite(y) and (team == 0.0 or team == 1.0)
                and 0.0 <= robot_id <= max_id and robot_id == np.floor(robot_id)):
            continue
        key = int(team) * (max_id + 1) + int(robot_id)
        other = chosen[key]
        if other < 0:
            chosen[key] = k
            keys[n_keys] = key
            n_keys += 1
        elif tracks[key, _SEEN] != 0.0:
            tx, ty = tracks[key, _X], tracks[key, _Y]
            if math.hypot(x - tx, y - ty) < math.hypot(robots[other, 2] - tx, robots[other, 3] - ty):
                chosen[key] = k
    n_used = 0
    for j in range(n_keys):
        key = keys[j]
        k = chosen[key]
        x, y = robots[k, 2], robots[k, 3]
        track = tracks[key]
        if track[_SEEN] != 0.0:
            if t_s <= track[_T]:
                continue  # seen later already (another camera)
            reach = gate_m + speed_mps * (t_s - track[_T])
            dx, dy = x - track[_X], y - track[_Y]
            if dx * dx + dy * dy > reach * reach and (
                track[_HELD] == 0.0
                or math.hypot(x - track[_HELD_X], y - track[_HELD_Y]) > gate_m + speed_mps * (t_s - track[_HELD_T])
            ):
                track[_HELD], track[_HELD_T], track[_HELD_X], track[_HELD_Y] = 1.0, t_s, x, y
                continue  # a jump: wait for a second sighting there
        track[_SEEN], track[_T], track[_X], track[_Y], track[_HELD] = 1.0, t_s, x, y, 0.0
        used[n_used] = k
        n_used += 1
    return n_used


class VisionTracker:
    """Multi-camera frames in; ball observations and robot poses out (see the module docstring).

    ``frame(camera_id, t_s, balls, robots)`` takes one camera frame with stamps already on the
    receiver's clock: ``balls`` as (x_m, y_m, confidence, ...), ``robots`` as (team, id, x_m, y_m,
    theta_rad or None, ...); further items are ignored, so ssl_vision's BallCandidate and
    RobotSighting go in as they are. It returns the ball observation to use (or None) and the robot
    poses to use.
    """

    def __init__(self, field: FieldConfig | None, params: BallModelParams | None = None,
                 tracker_config: TrackerConfig | None = None, config: VisionTrackingConfig | None = None) -> None:
        self.config = config or VisionTrackingConfig()
        self._tracker_config = tracker_config or TrackerConfig()
        self.ball = BallTracker(params, self._tracker_config)
        cfg = self.config
        self.settings = np.array([cfg.min_confidence, 0.0, 0.0, 0.0, 0.0, cfg.hypothesis_timeout_s, cfg.ball_gate_m,
                                  cfg.max_ball_speed_mps, cfg.max_ball_gate_m, cfg.lost_after_s,
                                  self._tracker_config.max_gap_s, cfg.confirm_window_s, cfg.fresh_s, cfg.robot_gate_m,
                                  cfg.max_robot_speed_mps, cfg.sighting_gate_m])
        self.field = field
        self.ball_state = np.zeros(10)  # the ball filter's as choose_ball reads it (_sync_ball)
        self.counts = np.zeros(5, np.int64)  # hypotheses alive, then the counters below
        self.hyps = np.zeros((cfg.max_hypotheses, 6))
        self.hits = np.zeros((cfg.max_hypotheses, cfg.confirm_frames))
        self.candidates = np.empty((DecodeLimits().max_balls, 3))
        self.robot_tracks = np.zeros((len(TEAMS) * (MAX_ROBOT_ID + 1), 8))
        self.used = np.empty(len(self.robot_tracks), np.int64)  # track_robots' output
        self.kicks = 0

    # counters for the node's statistics and the tests
    frames = property(lambda self: int(self.counts[COUNT_FRAMES]))
    late_balls = property(lambda self: int(self.counts[COUNT_LATE_BALLS]))
    false_candidates = property(lambda self: int(self.counts[COUNT_FALSE_CANDIDATES]))
    switches = property(lambda self: int(self.counts[COUNT_SWITCHES]))

    @property
    def field(self) -> FieldConfig | None:
        """The field candidates are judged against; None (not known yet): every candidate counts as inside."""
        return self._field

    @field.setter
    def field(self, value: FieldConfig | None) -> None:
        self._field = value
        half_length, half_width = (math.inf, math.inf) if value is None else (value.half_length_m, value.half_width_m)
        margin = self.config.outside_margin_m
        s = self.settings
        s[SETTING_HALF_LENGTH], s[SETTING_HALF_WIDTH] = half_length, half_width
        s[SETTING_MAX_X], s[SETTING_MAX_Y] = half_length + margin, half_width + margin

    @property
    def params(self) -> BallModelParams:
        """The ball filter's model (``BallTracker.params``: its kernels, also vision_fast_path's, read the change)."""
        return self.ball.params

    @params.setter
    def params(self, value: BallModelParams) -> None:
        self.ball.params = value

    # ------------------------------------------------------------------------------ ball
    def frame(
        self,
        camera_id: int,
        t_s: float,
        balls: Iterable[tuple[float, float, float]],
        robots: Iterable[tuple[str, int, float, float, float | None]] = (),
    ) -> tuple[BallObservation | None, list[RobotObservation]]:
        rows = [
            (_TEAM_INDEX.get(r[0], -1.0), r[1], r[2], r[3], math.nan if r[4] is None else r[4]) for r in robots
        ]
        ball_rows = [(b[0], b[1], b[2]) for b in balls]
        ball, used = self.frame_arrays(camera_id, t_s, np.array(ball_rows, dtype=float).reshape(len(ball_rows), 3),
                                       np.array(rows, dtype=float).reshape(len(rows), 5))
        return ball, [
            RobotObservation(TEAMS[int(team)], int(robot_id), t_s, x, y, None if math.isnan(theta) else theta,
                             camera_id)
            for team, robot_id, x, y, theta in used
        ]

    def frame_arrays(
        self, camera_id: int, t_s: float, balls: np.ndarray, robots: np.ndarray
    ) -> tuple[BallObservation | None, list[list[float]]]:
        """``frame`` with arrays of rows: balls (x_m, y_m, confidence, ...), robots (team index in TEAMS, id,
        x_m, y_m, theta_rad or NaN, ...); returns the ball observation and the robot rows to use (as lists;
        their stamp is t_s)."""
        ball, used = self.frame_indices(camera_id, t_s, balls, robots)
        return ball, robots[used].tolist() if len(used) else []

    def frame_indices(
        self, camera_id: int, t_s: float, balls: np.ndarray, robots: np.ndarray
    ) -> tuple[BallObservation | None, np.ndarray]:
        """``frame_arrays`` returning the indices of the robot rows to use (int64; a view valid until the next
        frame) instead of the rows."""
        if not math.isfinite(t_s):
            raise ValueError(f"frame stamp {t_s!r} is not finite")
        counts = self.counts
        counts[COUNT_FRAMES] += 1
        if len(balls) > len(self.candidates):
            self.candidates = np.empty((len(balls), 3))
        p = self.settings
        counts[COUNT_HYPOTHESES], n = update_hypotheses(
            self.hyps, self.hits, counts[COUNT_HYPOTHESES], t_s, balls, p[SETTING_MIN_CONFIDENCE], p[SETTING_MAX_X],
            p[SETTING_MAX_Y], p[SETTING_HALF_LENGTH], p[SETTING_HALF_WIDTH], p[SETTING_HYPOTHESIS_TIMEOUT],
            p[SETTING_BALL_GATE], p[SETTING_BALL_SPEED], self.candidates)
        action, x, y = choose_ball(self.hyps, self.hits, t_s, self.candidates, n, p, self.ball_state, counts)
        ball = self.use_ball(action, camera_id, t_s, x, y) if action else None
        if not len(robots):
            return ball, self.used[:0]
        if len(robots) > len(self.used):
            self.used = np.empty(len(robots), np.int64)
        n = track_robots(robots, t_s, self.robot_tracks, p[SETTING_ROBOT_GATE], p[SETTING_ROBOT_SPEED], MAX_ROBOT_ID,
                          self.used)
        return ball, self.used[:n]

    def use_ball(self, action: int, camera_id: int, t_s: float, x: float, y: float) -> BallObservation | None:
        """What choose_ball decided, done on the ball filter (a switch: a new ball, no history); the observation,
        or None when the filter refuses it. A sighting is the observation without the filter."""
        if action == BALL_SIGHTING:
            return BallObservation(t_s, x, y, camera_id, UpdateStatus.REJECTED_TIME, True)
        if action >= BALL_FUSED:
            return BallObservation(t_s, x, y, camera_id, UpdateStatus(action - BALL_FUSED))
        if action == BALL_SWITCH:
            self.ball.reset()
        status = self.ball.update(t_s, x, y)
        if status >= UpdateStatus.REJECTED_TIME:  # or REJECTED_INVALID
            self._sync_ball()
            return None
        ball = self.ball
        self.kicks += ball.kicked
        note_ball_taken(self.ball_state, t_s, x, y, ball.s)  # an accepted observation leaves it initialized
        return BallObservation(t_s, x, y, camera_id, status)

    def _sync_ball(self) -> None:
        b, ball = self.ball_state, self.ball
        b[_B_INITIALIZED] = float(ball.initialized)
        if ball.initialized:
            b[_B_FILTER_T:] = (ball.t_s, *ball.kf.state)


def load_kernels() -> None:
    """Compile (or load from numba's cache) the kernels of SSL decoding and of this tracker: at a node's
    start and before the tests, demo and benches (./run), not at the first camera frame."""
    from erforce_interfaces.ssl.ssl_vision import (
        BallCandidate,
        CameraFrame,
        RobotSighting,
        decode_wrapper,
        encode_frame,
    )

    load_ball_filter_kernels()
    data = encode_frame(CameraFrame(0, 1, 1.0, 1.0, (BallCandidate(0.0, 0.0, 1.0),),
                                    (RobotSighting("blue", 0, 0.0, 0.0, 0.0, 1.0),)))
    frame = decode_wrapper(data).detection
    tracker = VisionTracker(FieldConfig.preset("division_b"))
    for k in range(4):  # the last frames find a confirmed hypothesis
        tracker.frame_arrays(0, 1.0 + 0.01 * k, frame.balls, frame.robots)
