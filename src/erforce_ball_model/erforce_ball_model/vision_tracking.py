"""Tracking from real vision: several overlapping cameras, false ball candidates, frames out of order.

SSL-Vision sends one frame per camera, each camera at its own rate and latency. A frame may list
several ball candidates (the ball, a reflection at the field edge, a second ball lying in the
run-off area) or none, and the ball may be in two cameras' views at once. ``VisionTracker`` turns
those frames into what the single-stream trackers of ``tracking`` take: one ball observation and
one pose per robot at strictly increasing stamps.

Ball: the candidate nearest to the tracked ball's prediction within a gate that grows with the
time since it was last seen (``max_ball_speed_mps``) is the ball; it is fed to a
``tracking.BallTracker``, which keeps v_shoot, kick and ricochet detection. Every candidate is
also a hypothesis; one seen in ``confirm_frames`` frames within ``confirm_window_s``, each time
where the previous sighting could have moved, and last seen within ``fresh_s`` is confirmed.
Without a track the best confirmed one (inside the field lines first, then the highest summed
confidence) starts it. A track moves to a confirmed hypothesis inside the field lines when its
ball has not been seen for ``lost_after_s`` (a ball put down elsewhere) or while it follows a
ball in the run-off area (the game ball is the one on the field); a ball in the run-off area
takes over a track only after the track has been gone for the ball filter's ``max_gap_s``.

Order: a camera frame whose capture time is not after the newest one used is older news; its
ball is not used (another camera saw the ball later already) and neither are its robots that
were seen later. Robots: per team and id, a sighting that the last pose cannot reach at
``max_robot_speed_mps`` is held back; two consecutive held-back sightings that agree re-seed
the robot (it was put down elsewhere). Duplicate ids in one frame: the nearest to the last pose.
The robot streams run in one compiled pass per frame over an array of the frame's sightings
(``frame_arrays``; the bridge gets that array from its decoder), ids 0 .. ``MAX_ROBOT_ID`` per team.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from erforce_ball_model.ball_model import BallModelParams
from erforce_ball_model.tracking import BallTracker, TrackerConfig, UpdateStatus
from erforce_interfaces.numba_support import numba
from erforce_interfaces.robot_config import FieldConfig
from erforce_interfaces.ssl_vision import TEAMS, DecodeLimits

__all__ = ["MAX_ROBOT_ID", "BallObservation", "RobotObservation", "VisionTracker", "VisionTrackingConfig"]

MAX_ROBOT_ID = DecodeLimits().max_robot_id  # what SSL-Vision can report
_TEAM_INDEX = {team: k for k, team in enumerate(TEAMS)}


@dataclass(frozen=True)
class VisionTrackingConfig:
    ball_gate_m: float = 0.15  # gate radius around the prediction, plus the growth below
    max_ball_speed_mps: float = 10.0  # the gate grows at this speed while the ball is unseen ...
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
    status: UpdateStatus


class RobotObservation(NamedTuple):
    team: str
    robot_id: int
    t_s: float
    x_m: float
    y_m: float
    theta_rad: float | None
    camera_id: int


@dataclass(slots=True)
class _Hypothesis:
    t_s: float
    x_m: float
    y_m: float
    hit_times: deque
    confidence_sum: float
    inside: bool


# Robot tracks: one row per team and id (team index * (MAX_ROBOT_ID + 1) + id), these columns.
_SEEN, _T, _X, _Y, _HELD, _HELD_T, _HELD_X, _HELD_Y = range(8)


@numba.njit(cache=True, error_model="numpy")
def _track_robots(robots, t_s, tracks, gate_m, speed_mps, max_id, used):
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

    def __init__(self, field: FieldConfig, params: BallModelParams | None = None,
                 tracker_config: TrackerConfig | None = None, config: VisionTrackingConfig | None = None) -> None:
        self.field = field
        self.config = config or VisionTrackingConfig()
        self._params = params or BallModelParams()
        self._tracker_config = tracker_config or TrackerConfig()
        self.ball = BallTracker(self._params, self._tracker_config)
        self._t_ball_s: float | None = None  # stamp of the newest ball observation used
        self._last_used: tuple[float, float, float] | None = None  # (t_s, x_m, y_m) of it
        self._hypotheses: list[_Hypothesis] = []
        self._robot_tracks = np.zeros((len(TEAMS) * (MAX_ROBOT_ID + 1), 8))
        self._used = np.empty(len(self._robot_tracks), np.int64)  # _track_robots' output
        # counters for the node's statistics and the tests
        self.frames = 0
        self.late_balls = 0
        self.false_candidates = 0
        self.switches = 0
        self.kicks = 0

    @property
    def field(self) -> FieldConfig:
        return self._field

    @field.setter
    def field(self, value: FieldConfig) -> None:
        self._field = value
        self._half_length_m, self._half_width_m = value.half_length_m, value.half_width_m

    def _inside(self, x: float, y: float, margin_m: float = 0.0) -> bool:
        """FieldConfig.contains with the half sizes kept (it runs for every ball candidate)."""
        return abs(x) <= self._half_length_m + margin_m and abs(y) <= self._half_width_m + margin_m

    @property
    def params(self) -> BallModelParams:
        return self._params

    @params.setter
    def params(self, value: BallModelParams) -> None:
        self._params = value
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
        ball, used = self.frame_arrays(camera_id, t_s, balls, np.array(rows, dtype=float).reshape(len(rows), 5))
        return ball, [
            RobotObservation(TEAMS[int(team)], int(robot_id), t_s, x, y, None if math.isnan(theta) else theta,
                             camera_id)
            for team, robot_id, x, y, theta in used
        ]

    def frame_arrays(
        self, camera_id: int, t_s: float, balls: Iterable[Sequence[float]], robots: np.ndarray
    ) -> tuple[BallObservation | None, list[list[float]]]:
        """``frame`` with the robots as an array of rows (team index in TEAMS, id, x_m, y_m, theta_rad or
        NaN, ...): returns the ball observation and the rows to use (as lists; their stamp is t_s)."""
        if not math.isfinite(t_s):
            raise ValueError(f"frame stamp {t_s!r} is not finite")
        self.frames += 1
        cfg = self.config
        min_confidence = cfg.min_confidence
        max_x, max_y = self._half_length_m + cfg.outside_margin_m, self._half_width_m + cfg.outside_margin_m
        candidates = [
            (b[0], b[1], b[2]) for b in balls
            if b[2] >= min_confidence and abs(b[0]) <= max_x and abs(b[1]) <= max_y  # False for NaN
        ]
        self._update_hypotheses(t_s, candidates)
        ball = None
        if self._t_ball_s is not None and t_s <= self._t_ball_s:
            if candidates:
                self.late_balls += 1
        elif candidates:
            ball = self._pick_ball(camera_id, t_s, candidates)
        if not len(robots):
            return ball, []
        if len(robots) > len(self._used):
            self._used = np.empty(len(robots), np.int64)
        n = _track_robots(robots, t_s, self._robot_tracks, cfg.robot_gate_m, cfg.max_robot_speed_mps,
                          MAX_ROBOT_ID, self._used)
        return ball, robots[self._used[:n]].tolist()

    def _gate_m(self, t_s: float, t_ref_s: float) -> float:
        cfg = self.config
        return min(cfg.ball_gate_m + cfg.max_ball_speed_mps * max(t_s - t_ref_s, 0.0), cfg.max_ball_gate_m)

    def _pick_ball(self, camera_id: int, t_s: float, candidates: list) -> BallObservation | None:
        chosen = None
        if self._t_ball_s is not None and self.ball.initialized:
            # Two gates: around the filter's prediction (constant velocity is close enough: the
            # deceleration moves the ball < 2 cm in 0.1 s), and around the last observation used,
            # which the filter may hold back (a kick: the filter still has the ball at rest).
            x, y, vx, vy = self.ball.kf.state
            dt = t_s - self.ball.t_s
            gates = [(x + vx * dt, y + vy * dt, self._gate_m(t_s, self.ball.t_s))]
            last = self._last_used
            if last is not None and last[0] > self.ball.t_s:
                gates.append((last[1], last[2], self._gate_m(t_s, last[0])))
            best = math.inf
            for cx, cy, _c in candidates:
                for px, py, radius in gates:
                    d = math.hypot(cx - px, cy - py)
                    if d <= radius and d < best:
                        chosen, best = (cx, cy), d
            self.false_candidates += len(candidates) - (chosen is not None)
            other = None
            unseen_s = t_s - self._t_ball_s
            if chosen is None and unseen_s >= self.config.lost_after_s:
                # long gone (a filter restart's gap): any confirmed ball, also one in the run-off area
                other = self._best_confirmed(t_s, inside_only=unseen_s < self._tracker_config.max_gap_s)
            elif chosen is not None and not self._inside(*chosen):
                # tracking a ball in the run-off area: a confirmed one on the field is the game ball
                other = self._best_confirmed(t_s, inside_only=True)
                if other is not None and math.dist(other, chosen) <= self.config.ball_gate_m:
                    other = None
            if other is not None:
                chosen = other
                self.switches += 1
                self.ball = BallTracker(self._params, self._tracker_config)  # a new ball: no history
        else:
            chosen = self._best_confirmed(t_s)
            if chosen is not None:
                self.false_candidates += len(candidates) - 1
        if chosen is None:
            return None
        status = self.ball.update(t_s, chosen[0], chosen[1])
        if status in (UpdateStatus.REJECTED_TIME, UpdateStatus.REJECTED_INVALID):
            return None
        self.kicks += int(self.ball.kicked)
        self._t_ball_s = t_s
        self._last_used = (t_s, chosen[0], chosen[1])
        return BallObservation(t_s, chosen[0], chosen[1], camera_id, status)

    def _update_hypotheses(self, t_s: float, candidates: Sequence[tuple[float, float, float]]) -> None:
        cfg = self.config
        timeout_s, gate_m, speed = cfg.hypothesis_timeout_s, cfg.ball_gate_m, cfg.max_ball_speed_mps
        hyps = [h for h in self._hypotheses if abs(t_s - h.t_s) <= timeout_s]
        for x, y, c in candidates:
            best, best_d2 = None, math.inf
            for h in hyps:  # squared distances: this loop runs for every candidate of every frame
                reach = gate_m + speed * abs(t_s - h.t_s)
                dx, dy = x - h.x_m, y - h.y_m
                d2 = dx * dx + dy * dy
                if d2 <= reach * reach and d2 < best_d2:
                    best, best_d2 = h, d2
            inside = self._inside(x, y)
            if best is None:
                if len(hyps) < cfg.max_hypotheses:
                    hyps.append(_Hypothesis(t_s, x, y, deque([t_s], maxlen=cfg.confirm_frames), c, inside))
            elif t_s > best.t_s:  # a new sighting (not the same instant from an overlapping camera)
                best.t_s, best.x_m, best.y_m, best.inside = t_s, x, y, inside
                best.hit_times.append(t_s)
                best.confidence_sum += c
        self._hypotheses = hyps

    def _best_confirmed(self, t_s: float, inside_only: bool = False) -> tuple[float, float] | None:
        cfg = self.config
        confirmed = [
            h for h in self._hypotheses
            if len(h.hit_times) == cfg.confirm_frames and h.hit_times[-1] - h.hit_times[0] <= cfg.confirm_window_s
            and t_s - h.hit_times[-1] <= cfg.fresh_s and (h.inside or not inside_only)
        ]
        if not confirmed:
            return None
        best = max(confirmed, key=lambda h: (h.inside, h.confidence_sum))
        return best.x_m, best.y_m
