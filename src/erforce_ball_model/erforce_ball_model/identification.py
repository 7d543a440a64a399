"""Identification of the two-phase ball model parameters (ER-Force ETDP 2016, Sec. 5.2).

The paper measured a_slide = -2.5 m/s^2, a_roll = -0.3 m/s^2 and c_switch = 0.6 "with our plotter
software"; they depend on the carpet, so we fit them per field from observed shots.

Model per shot k (positions projected on the shot's line, s = distance along it)::

    s(t) = p_k + D(max(t - t_k, 0); v_k, a_slide, a_roll, c_switch)

with D the two-phase distance of ``ball_model`` (``kick_distance``) for a ball kicked at time t_k with speed
v_shoot = v_k from rest at p_k. A segment should start a few frames *before* the kick (the ball at
rest pins p_k and the kick time; without it c_switch and the kick speed are not separable).
``scipy.optimize.least_squares`` fits the 3 shared + 3 per-shot parameters; standard errors come
from the Gauss-Newton covariance ``s^2 (J^T J)^-1`` with s^2 = SSR / (m - n).

Offline: ``fit_recording(t, x, y)`` or the CLI ``ball_fit FILE.csv`` (columns t,x,y, optional
header) cut the recording into shots with ``BallTracker`` kick events. Online: ``ShotAccumulator``
collects shots while observations stream in and refits on demand.
"""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from erforce_ball_model.ball_model import BallModelParams, kick_distance
from erforce_ball_model.tracking import BallTracker, TrackerConfig, UpdateStatus

__all__ = ["FitResult", "Shot", "ShotAccumulator", "fit_recording", "fit_shots", "main", "split_shots"]


@dataclass(frozen=True, eq=False)
class Shot:
    """Observations of one shot: times (N,) and positions (N, 2), starting shortly before the kick."""

    t_s: np.ndarray
    xy_m: np.ndarray

    def __post_init__(self) -> None:
        t = np.asarray(self.t_s, dtype=float)
        xy = np.asarray(self.xy_m, dtype=float)
        if t.ndim != 1 or xy.shape != (t.size, 2):
            raise ValueError(f"Shot: need t (N,) and xy (N, 2), got {t.shape} and {xy.shape}")
        if t.size < 8:
            raise ValueError(f"Shot: need at least 8 observations, got {t.size}")
        if not (np.isfinite(t).all() and np.isfinite(xy).all()):
            raise ValueError("Shot: observations must be finite")
        if (np.diff(t) <= 0.0).any():
            raise ValueError("Shot: times must be strictly increasing")
        object.__setattr__(self, "t_s", t)
        object.__setattr__(self, "xy_m", xy)


@dataclass(frozen=True)
class FitResult:
    params: BallModelParams
    a_slide_std: float
    a_roll_std: float
    c_switch_std: float
    num_shots: int
    num_points: int
    rms_residual_m: float

    def summary(self) -> str:
        p = self.params
        return (
            f"a_slide  = {p.a_slide_mps2:+.4f} +- {self.a_slide_std:.4f} m/s^2\n"
            f"a_roll   = {p.a_roll_mps2:+.4f} +- {self.a_roll_std:.4f} m/s^2\n"
            f"c_switch = {p.c_switch:.4f} +- {self.c_switch_std:.4f}\n"
            f"({self.num_shots} shots, {self.num_points} points, rms residual {1e3 * self.rms_residual_m:.2f} mm)"
        )


def _project(shot: Shot) -> tuple[np.ndarray, np.ndarray]:
    """Distances along the shot's line (principal direction of the moving part) from the start."""
    xy = shot.xy_m
    centred = xy - xy.mean(axis=0)
    _, _, vt = np.linalg.svd(centred, full_matrices=False)
    u = vt[0]
    s = (xy - xy[0]) @ u
    if s[-1] < s[0]:
        s = -s
    return shot.t_s, s


def _initial_shot_guess(t: np.ndarray, s: np.ndarray) -> tuple[float, float, float]:
    moved = np.abs(s - s[0]) > 0.02
    k = int(np.argmax(moved)) if moved.any() else 1
    k = max(k, 1)
    p0 = float(np.median(s[: max(k - 1, 1)]))
    dt = np.diff(t[k : k + 4])
    v0 = float(np.max(np.diff(s[k : k + 4]) / dt)) if dt.size else 1.0
    return p0, float(t[k - 1]), max(v0, 0.1)


def _solve(data, shared0, nuisance0):
    # Imported here: scipy.optimize costs a ball predictor ~0.5 s of CPU at start (and a respawn as
    # long), yet it fits only with online_identification, on its worker thread.
    from scipy.optimize import least_squares

    lo = [-30.0, -5.0, 0.05]
    hi = [-0.05, -0.005, 1.0]
    for t, _ in data:
        lo += [-np.inf, t[0] - 1.0, 0.05]
        hi += [np.inf, t[-1], 20.0]
    x0 = np.clip(np.concatenate([shared0, nuisance0]), np.array(lo) + 1e-9, np.array(hi) - 1e-9)

    def residuals(theta):
        a_s, a_r, c = theta[:3]
        out = []
        for k, (t, s) in enumerate(data):
            p, tk, v = theta[3 + 3 * k : 6 + 3 * k]
            out.append(p + kick_distance(np.maximum(t - tk, 0.0), v, a_s, a_r, c) - s)
        return np.concatenate(out)

    return least_squares(residuals, x0, bounds=(lo, hi), x_scale="jac", method="trf")


def fit_shots(shots: list[Shot], initial: BallModelParams | None = None) -> FitResult:
    """Least-squares fit of (a_slide, a_roll, c_switch) plus per-shot (p, t_kick, v_shoot).

    Each shot is fitted alone first (a good start for its nuisance parameters; the joint problem
    from a generic start can stall in a local minimum), then all shots jointly.
    """
    if not shots:
        raise ValueError("fit_shots: need at least one shot")
    initial = initial or BallModelParams()
    data = [_project(s) for s in shots]
    shared0 = np.array([initial.a_slide_mps2, initial.a_roll_mps2, initial.c_switch])
    singles = [_solve([d], shared0, np.array(_initial_shot_guess(*d))).x for d in data]
    if len(data) == 1:
        sol = _solve(data, singles[0][:3], singles[0][3:])
    else:
        shared = np.median([x[:3] for x in singles], axis=0)
        sol = _solve(data, shared, np.concatenate([x[3:] for x in singles]))
    m, n = sol.fun.size, sol.x.size
    if m <= n:
        raise ValueError(f"fit_shots: {m} points cannot determine {n} parameters")
    s2 = float(sol.fun @ sol.fun) / (m - n)
    cov = np.linalg.pinv(sol.jac.T @ sol.jac) * s2
    std = np.sqrt(np.maximum(np.diag(cov)[:3], 0.0))
    a_s, a_r, c = (float(v) for v in sol.x[:3])
    return FitResult(
        params=BallModelParams(a_s, a_r, c),
        a_slide_std=float(std[0]),
        a_roll_std=float(std[1]),
        c_switch_std=float(std[2]),
        num_shots=len(shots),
        num_points=m,
        rms_residual_m=math.sqrt(float(sol.fun @ sol.fun) / m),
    )


class ShotAccumulator:
    """Online: cuts streaming ball observations into shots (kick .. stop / next event) and refits.

    ``add(t_s, x_m, y_m)`` per vision frame; ``shots`` holds the completed shots (the newest
    ``max_shots``); ``fit()`` refits on them.
    """

    def __init__(
        self,
        pre_kick_frames: int = 6,
        stop_speed_mps: float = 0.05,
        min_points: int = 30,
        max_shots: int = 50,
        tracker_config: TrackerConfig | None = None,
    ) -> None:
        self.tracker = BallTracker(config=tracker_config)
        self.pre_kick_frames = pre_kick_frames
        self.stop_speed_mps = stop_speed_mps
        self.min_points = min_points
        self.max_shots = max_shots
        self.shots: list[Shot] = []
        self._recent: list[tuple[float, float, float]] = []  # accepted frames before a kick
        self._current: list[tuple[float, float, float]] | None = None
        self._held_last: list[tuple[float, float, float]] = []  # the frame held back before a kick

    def _close(self) -> None:
        if self._current is not None and len(self._current) >= self.min_points:
            arr = np.array(self._current)
            self.shots.append(Shot(arr[:, 0], arr[:, 1:]))
            del self.shots[: -self.max_shots]
        self._current = None

    def add(self, t_s: float, x_m: float, y_m: float) -> UpdateStatus:
        status = self.tracker.update(t_s, x_m, y_m)
        if status in (UpdateStatus.REJECTED_TIME, UpdateStatus.REJECTED_INVALID):
            return status
        obs = (float(t_s), float(x_m), float(y_m))
        if status == UpdateStatus.INITIALIZED:
            self._close()
            self._recent = [obs]
            return status
        if status == UpdateStatus.MANEUVER:
            self._close()
            if self.tracker.kicked:
                # pre-kick frames + the held-back first moving frame + this one
                self._current = [*self._recent[-self.pre_kick_frames :], *self._held_last, obs]
            self._recent = []
            self._held_last = []
            return status
        if status == UpdateStatus.HELD_BACK:
            self._held_last = [obs]
            return status
        self._held_last = []
        if self._current is not None:
            self._current.append(obs)
            if float(np.hypot(*self.tracker.velocity_mps)) < self.stop_speed_mps:
                self._close()
        else:
            self._recent.append(obs)
            del self._recent[: -self.pre_kick_frames]
        return status

    def finish(self) -> None:
        """Close the shot in progress (end of a recording)."""
        self._close()

    def fit(self, initial: BallModelParams | None = None) -> FitResult:
        return fit_shots(self.shots, initial)


def split_shots(t_s, x_m, y_m, **kwargs) -> list[Shot]:
    t, x, y = (np.asarray(v, dtype=float).ravel() for v in (t_s, x_m, y_m))
    if not t.size == x.size == y.size:
        raise ValueError(f"t, x, y must have equal lengths, got {t.size}, {x.size}, {y.size}")
    acc = ShotAccumulator(**kwargs)
    for ti, xi, yi in zip(t, x, y, strict=True):
        acc.add(ti, xi, yi)
    acc.finish()
    return acc.shots


def fit_recording(t_s, x_m, y_m, initial: BallModelParams | None = None, **kwargs) -> FitResult:
    """Fit from a whole recording (numpy arrays): split into shots by kick events, then fit."""
    shots = split_shots(t_s, x_m, y_m, **kwargs)
    if not shots:
        raise ValueError("no complete shot found in the recording (a kick from rest is needed)")
    return fit_shots(shots, initial)


def load_csv(path: str | Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Columns t, x, y (SI units); a header line is skipped."""
    text = Path(path).read_text().splitlines()
    rows = []
    for i, line in enumerate(text):
        if not line.strip():
            continue
        try:
            rows.append([float(v) for v in line.replace(";", ",").split(",")[:3]])
        except ValueError:
            if i == 0:
                continue  # header
            raise ValueError(f"{path}:{i + 1}: cannot parse {line!r}") from None
    arr = np.array(rows, dtype=float)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise ValueError(f"{path}: need three columns t,x,y")
    return arr[:, 0], arr[:, 1], arr[:, 2]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="ball_fit", description=__doc__.splitlines()[0])
    parser.add_argument("csv", help="recording with columns t,x,y (s, m, m)")
    args = parser.parse_args(argv)
    try:
        result = fit_recording(*load_csv(args.csv))
    except (OSError, ValueError) as exc:
        print(f"ball_fit: {exc}", file=sys.stderr)
        return 1
    print(result.summary())
    return 0


if __name__ == "__main__":
    sys.exit(main())
