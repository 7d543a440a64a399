"""Per-camera systematic offsets of SSL-Vision, estimated online from what two cameras see at one capture.

A calibrated camera still reports every object a few cm off (ER-Force's simulator's "Realistic" preset: 2 cm along
the camera's direction from the field's centre); in an overlap two cameras then disagree about a ball at rest, and
a chip detector that reads the disagreement as parallax takes flat kicks for chips. SSL-Vision reports a robot
where its marker height's projection lies, the same rule for every camera, so two cameras' positions of one robot
at one capture differ only by their offsets and noise: ``d = p_a - p_b = o_a - o_b + e``. A ball lying still is
the same; a ball that may be in the air is not (its two projections differ by its height's parallax), so a ball
feeds the estimate only with a sighting after which each camera saw it still for ``rest_s``.

The offsets are only defined up to a common shift: the estimate is the least-squares one with zero mean over the
cameras that were paired (``o = L^+ r``, L the graph Laplacian weighted by each pair's sample count, r each
camera's summed differences). Its covariance per axis is ``s^2 L^+`` with s the differences' standard deviation
estimated from the residuals: ``uncertainty_m``; it is solved again once the differences taken since grow by
RESOLVE_SHARE of all. Each pair keeps at most ``max_samples`` (older samples are scaled
down), so the estimate follows a calibration that changes.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np

BALL_KEY = ("ball",)
RESOLVE_SHARE = 0.01  # solve again once the new differences are this share of all (a pseudo-inverse per frame costs)


@dataclass
class _Pair:
    n: float = 0.0
    sum_x_m: float = 0.0  # sums of p_a - p_b (a < b)
    sum_y_m: float = 0.0
    sum_sq_m2: float = 0.0  # sum of |p_a - p_b|^2 (both axes)


class CameraAlignment:
    """Online estimate of each camera's offset from pairs of sightings at one capture; ``correct`` removes it.

    ``frame`` takes one camera frame (its capture time, its robots and balls); pairs with the newest frame of every
    other camera within ``max_capture_gap_s``. A robot pairs when its motion over the two captures' gap (from the
    camera's previous sighting) is below ``max_motion_m``; a pair whose difference is further than
    ``max_disagreement_m`` from the pair's mean so far (a wrong id, a reflection) is left out."""

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
        self._newest: dict[int, dict[tuple, tuple[float, float, float, float]]] = {}
        self._balls: dict[int, deque[tuple[float, float, float]]] = {}
        self._pairs: dict[tuple[int, int], _Pair] = {}
        self._solution: tuple[dict[int, int], np.ndarray, np.ndarray] | None = None
        self._samples = 0.0  # all differences held (after down-weighting old ones)
        self._new_samples = 0  # since the last solution

    # ------------------------------------------------------------------ input
    def frame(self, camera_id: int, t_capture_s: float, robots=(), balls=()) -> None:
        """One camera frame: ``robots`` as (team, robot_id, x_m, y_m), ``balls`` as (x_m, y_m), as the camera
        reported them. Only a frame with one ball lets the ball pair (several: which is which is unknown)."""
        seen: dict[tuple, tuple[float, float, float, float]] = {}  # x, y, speed, the sighting's capture time
        previous = self._newest.get(camera_id)
        for team, robot_id, x, y in robots:
            key = (int(team), int(robot_id))
            if previous is not None and key in previous and t_capture_s > previous[key][3]:
                px, py, _, pt = previous[key]
                speed = math.hypot(x - px, y - py) / (t_capture_s - pt)
            else:
                speed = math.inf  # unknown motion: pairs only at the same capture
            seen[key] = (float(x), float(y), speed, t_capture_s)
        resting = self._resting_ball(camera_id, t_capture_s, list(balls))
        if resting is not None:
            seen[BALL_KEY] = resting
        for other, other_seen in self._newest.items():
            if other == camera_id:
                continue
            for key, (x, y, speed, t_s) in seen.items():
                match = other_seen.get(key)
                if match is None:
                    continue
                gap_s = abs(t_s - match[3])
                if gap_s == 0.0 or (gap_s <= self.max_capture_gap_s and speed * gap_s <= self.max_motion_m):
                    self._add(camera_id, other, x - match[0], y - match[1])
        self._newest[camera_id] = seen

    def _resting_ball(self, camera_id: int, t_s: float, balls: list) -> tuple[float, float, float, float] | None:
        """The camera's newest ball sighting at least ``rest_s`` old after which the ball stayed within
        ``rest_radius_m`` of it, if any. A ball in the air cannot: over any ``rest_s`` its height leaves the first
        one's by at least g rest_s^2 / 8 (2.8 cm at 0.15 s, the apex in the middle), which a camera 4 m high sees
        at 1.5 m from below it as 1 cm; in an overlap at least one of the two cameras is that far."""
        history = self._balls.setdefault(camera_id, deque())
        if len(balls) != 1:
            history.clear()
            return None
        history.append((t_s, float(balls[0][0]), float(balls[0][1])))
        while len(history) > 1 and history[1][0] <= t_s - self.rest_s:
            history.popleft()  # history[0]: the newest sighting at least rest_s old
        t0, x0, y0 = history[0]
        if t0 > t_s - self.rest_s or any(math.hypot(x - x0, y - y0) > self.rest_radius_m for _, x, y in history):
            return None
        return x0, y0, 0.0, t0

    def _add(self, a: int, b: int, dx: float, dy: float) -> None:
        if a > b:
            a, b, dx, dy = b, a, -dx, -dy
        pair = self._pairs.setdefault((a, b), _Pair())
        n = pair.n
        if n > 0 and math.hypot(dx - pair.sum_x_m / n, dy - pair.sum_y_m / n) > self.max_disagreement_m:
            return
        if n + 1.0 > self.max_samples:  # a window of about max_samples: older samples weigh less
            k = (self.max_samples - 1.0) / n
            self._samples -= n - n * k
            pair.n, pair.sum_x_m, pair.sum_y_m, pair.sum_sq_m2 = n * k, pair.sum_x_m * k, pair.sum_y_m * k, \
                pair.sum_sq_m2 * k
        pair.n += 1.0
        pair.sum_x_m += dx
        pair.sum_y_m += dy
        pair.sum_sq_m2 += dx * dx + dy * dy
        self._new_samples += 1
        self._samples += 1.0
        if self._new_samples >= max(1.0, RESOLVE_SHARE * self._samples):
            self._solution = None

    # ----------------------------------------------------------------- output
    def _solve(self) -> tuple[dict[int, int], np.ndarray, np.ndarray]:
        if self._solution is None:
            self._new_samples = 0
            ids = sorted({c for pair in self._pairs for c in pair})
            index = {c: i for i, c in enumerate(ids)}
            lap = np.zeros((len(ids), len(ids)))
            r = np.zeros((len(ids), 2))
            sq, dof = 0.0, 0.0
            for (a, b), p in self._pairs.items():
                i, j = index[a], index[b]
                lap[i, i] += p.n
                lap[j, j] += p.n
                lap[i, j] -= p.n
                lap[j, i] -= p.n
                r[i] += p.sum_x_m, p.sum_y_m
                r[j] -= p.sum_x_m, p.sum_y_m
                sq += p.sum_sq_m2 - (p.sum_x_m**2 + p.sum_y_m**2) / p.n  # residuals about the pair's mean, both axes
                dof += 2.0 * (p.n - 1.0)
            lap_pinv = np.linalg.pinv(lap) if ids else lap
            offsets = lap_pinv @ r
            var_m2 = max(sq, 0.0) / dof if dof > 0.0 else math.inf  # per axis, of one difference (>= 0: rounding)
            self._solution = (index, offsets, np.sqrt(np.maximum(np.diag(lap_pinv), 0.0) * var_m2))
        return self._solution

    def offset_m(self, camera_id: int) -> tuple[float, float]:
        """The camera's estimated offset (zero mean over the paired cameras); (0, 0) for a camera never paired."""
        index, offsets, _ = self._solve()
        i = index.get(camera_id)
        return (0.0, 0.0) if i is None else (float(offsets[i, 0]), float(offsets[i, 1]))

    def uncertainty_m(self, camera_id: int) -> float:
        """The estimate's standard deviation per axis (inf for a camera never paired or too few samples)."""
        index, _, std = self._solve()
        i = index.get(camera_id)
        return math.inf if i is None or not math.isfinite(std[i]) else float(std[i])

    def samples(self, camera_a: int, camera_b: int) -> float:
        """How many differences (after down-weighting old ones) the pair holds."""
        pair = self._pairs.get((min(camera_a, camera_b), max(camera_a, camera_b)))
        return 0.0 if pair is None else pair.n

    def correct(self, camera_id: int, x_m: float, y_m: float) -> tuple[float, float]:
        """What the camera reports at (x_m, y_m) without its estimated offset."""
        ox, oy = self.offset_m(camera_id)
        return x_m - ox, y_m - oy
