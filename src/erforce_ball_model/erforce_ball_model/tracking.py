"""Ball (and robot) tracking from noisy, delayed vision (ER-Force ETDP 2016, Sec. 5.2 and 5.3).

The paper's model needs the current ball velocity and the tracked kick speed ``v_shoot`` ("update
v_shoot when the ball speed increases") and notes that ricochets break the model. This module
provides both, made robust to vision noise (1-3 mm, 60-75 Hz, dropouts):

* ``KalmanCV2D``: constant-velocity Kalman filter on (x, y, vx, vy) with white-acceleration process
  noise, variable dt, optional known acceleration input. ``BallTracker`` feeds it the two-phase
  model deceleration (a_slide / a_roll along the motion), which removes the lag a plain CV filter
  has on a decelerating ball.
* Maneuver detection by innovation gating: one observation outside the gate is held back as a
  possible outlier; a second consecutive one confirms a maneuver and the filter is re-seeded from
  the two observations; two frames further apart than ``max_ball_speed_mps`` allows are not one
  motion, and the newer is held back instead. A maneuver that raises the speed by more than
  ``kick_threshold_mps`` (and 3 sigma of the two-point velocity) is a *kick*; one that turns the
  direction by more than ``ricochet_angle_rad`` while moving is a *ricochet* (paper Sec. 5.3).
* ``v_shoot``: after a kick (or ricochet) it is the median, over the next frames while the ball
  slides, of ``speed + |a_slide| * (t - t_event)`` (the speed extrapolated back to the event), so
  single noisy velocity estimates do not move it. Otherwise the paper rule applies with a noise
  threshold: raise v_shoot only when the speed exceeds it by 3 sigma + 5 cm/s.
* ``uncertain``: set by ricochets, cleared when the last ``fit_frames`` innovations all lie within
  3 sigma, i.e. the model fits the observations again.

``RobotTracker`` reuses the filter for robots (position plus optional orientation).
"""

from __future__ import annotations

import enum
import math
from collections import deque
from dataclasses import dataclass

import numpy as np

from erforce_ball_model.ball_model import BallModelParams, BallPhase, BallTrajectory

__all__ = ["BallTracker", "KalmanCV2D", "RobotTracker", "TrackerConfig", "UpdateStatus"]

RESTING_VELOCITY_STD_MPS = 0.05  # velocity uncertainty of a ball that reappeared at rest elsewhere


class UpdateStatus(enum.IntEnum):
    INITIALIZED = 0  # first observation (or re-initialization after a long gap)
    ACCEPTED = 1
    HELD_BACK = 2  # outside the gate: possible outlier, not fused yet
    MANEUVER = 3  # confirmed change of motion: filter re-seeded
    REJECTED_TIME = 4  # stamp not after the previous one
    REJECTED_INVALID = 5  # non-finite input


class KalmanCV2D:
    """Constant-velocity Kalman filter on (x, y, vx, vy) in the field frame.

    The axes are independent (per-axis motion model, isotropic noise), and both start from the
    same variances and see the same updates, so they share one 2x2 covariance
    ``(var_pos, cov_pos_vel, var_vel)``; the update is a few float operations per frame
    (numpy arrays for 4 states cost more in call overhead than the arithmetic).
    """

    def __init__(self, position_noise_m: float, accel_noise_psd: float) -> None:
        if not (math.isfinite(position_noise_m) and position_noise_m > 0.0):
            raise ValueError(f"position_noise_m: must be finite and > 0, got {position_noise_m!r}")
        if not (math.isfinite(accel_noise_psd) and accel_noise_psd > 0.0):
            raise ValueError(f"accel_noise_psd: must be finite and > 0, got {accel_noise_psd!r}")
        self.r = position_noise_m**2
        self.q = accel_noise_psd
        self.state: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)  # x, y, vx, vy
        self.cov: tuple[float, float, float] = (1.0, 0.0, 1.0)  # per axis: var_pos, cov_pos_vel, var_vel

    @property
    def x(self) -> np.ndarray:
        return np.array(self.state)

    @property
    def p(self) -> np.ndarray:
        """The full 4x4 covariance of (x, y, vx, vy)."""
        a, b, c = self.cov
        return np.array([[a, 0.0, b, 0.0], [0.0, a, 0.0, b], [b, 0.0, c, 0.0], [0.0, b, 0.0, c]])

    def reset(self, position, velocity, position_var: float, velocity_var: float) -> None:
        self.state = (float(position[0]), float(position[1]), float(velocity[0]), float(velocity[1]))
        self.cov = (float(position_var), 0.0, float(velocity_var))

    def predicted(self, dt: float, accel=(0.0, 0.0)) -> tuple[tuple, tuple]:
        """State and covariance after ``dt`` with a known acceleration (does not change the filter)."""
        px, py, vx, vy = self.state
        ax, ay = accel
        h = 0.5 * dt * dt
        x = (px + vx * dt + h * ax, py + vy * dt + h * ay, vx + dt * ax, vy + dt * ay)
        a, b, c = self.cov
        q = self.q  # white-acceleration noise: q dt^3/3, q dt^2/2, q dt
        return x, (a + dt * (2.0 * b + dt * c) + q * dt**3 / 3.0, b + dt * c + q * h, c + q * dt)

    def innovation(self, x: tuple, p: tuple, z) -> tuple[tuple[float, float], float]:
        """Innovation (x, y) and its variance, the same on both axes."""
        return (z[0] - x[0], z[1] - x[1]), p[0] + self.r

    def correct(self, x: tuple, p: tuple, z) -> None:
        (nx, ny), s = self.innovation(x, p, z)
        a, b, c = p
        kp, kv = a / s, b / s  # gain for position and velocity
        self.state = (x[0] + kp * nx, x[1] + kp * ny, x[2] + kv * nx, x[3] + kv * ny)
        # Joseph form (I - K H) P (I - K H)^T + K r K^T: stays symmetric positive.
        r, m = self.r, 1.0 - kp
        self.cov = (m * m * a + kp * kp * r, m * (b - kv * a) + kp * kv * r, kv * kv * (a + r) - 2.0 * kv * b + c)


@dataclass(frozen=True)
class TrackerConfig:
    position_noise_m: float = 0.002
    accel_noise_psd: float = 0.05  # (m/s^2)^2/Hz of the residual acceleration beyond the model
    gate_sigma: float = 5.0
    gate_min_m: float = 0.01
    kick_threshold_mps: float = 0.5
    ricochet_angle_rad: float = math.radians(30.0)
    ricochet_min_speed_mps: float = 0.3
    shoot_window_s: float = 0.15
    fit_frames: int = 6
    max_gap_s: float = 1.0  # longer gaps re-initialize the filter
    # Two frames further apart than this speed allows are not one motion (the SSL limit is 6.5 m/s).
    max_ball_speed_mps: float = 10.0

    def __post_init__(self) -> None:
        for name, value in self.__dict__.items():
            if not math.isfinite(value) or value <= 0:
                raise ValueError(f"{name}: must be finite and > 0, got {value!r}")


_NUMBER_TYPES = (int, float, np.floating, np.integer)  # a tuple built once (a union in the loop is built per item)


def _check_obs(t_s, values) -> bool:
    return all(isinstance(v, _NUMBER_TYPES) and math.isfinite(v) for v in (t_s, *values))


class BallTracker:
    """Tracks one ball: filtered state, v_shoot, kick/ricochet events and a trajectory for prediction.

    Call ``update(t_s, x_m, y_m)`` per vision frame (strictly increasing stamps); read
    ``trajectory()`` and the flags ``kicked`` / ``ricochet`` (true for the update that detected the
    event), ``uncertain`` and ``phase``.
    """

    def __init__(self, params: BallModelParams | None = None, config: TrackerConfig | None = None) -> None:
        self.params = params or BallModelParams()
        self.config = config or TrackerConfig()
        self.kf = KalmanCV2D(self.config.position_noise_m, self.config.accel_noise_psd)
        self.t_s: float | None = None
        self.v_shoot_mps = 0.0
        self.kicked = False
        self.ricochet = False
        self.uncertain = True
        self.kick_count = 0
        self.ricochet_count = 0
        self.last_event_time_s: float | None = None
        self._held: tuple[float, float, float] | None = None
        self._prev_obs: tuple[float, float, float] | None = None
        self._shoot_samples: list[float] = []
        self._fit_ok: deque[bool] = deque(maxlen=self.config.fit_frames)
        self._rolling = False  # latched once the speed fell below the switch speed (no flicker)

    # -- state ----------------------------------------------------------------------------------
    @property
    def initialized(self) -> bool:
        return self.t_s is not None

    @property
    def position_m(self) -> np.ndarray:
        return np.array(self.kf.state[:2])

    @property
    def velocity_mps(self) -> np.ndarray:
        return np.array(self.kf.state[2:])

    @property
    def velocity_std_mps(self) -> float:
        return math.sqrt(self.kf.cov[2])

    @property
    def position_variance_m2(self) -> float:
        return self.kf.cov[0]

    def _speed(self) -> float:
        return math.hypot(self.kf.state[2], self.kf.state[3])

    def _effective_v_shoot(self, speed: float) -> float:
        # Once rolling, stay rolling until the next kick or ricochet: speed noise around the switch
        # speed must not flip the model back to sliding.
        return max(self.v_shoot_mps, speed / self.params.c_switch) if self._rolling else self.v_shoot_mps

    def trajectory(self) -> BallTrajectory:
        """The ball's future from the latest filtered state (at time ``self.t_s``)."""
        if not self.initialized:
            raise RuntimeError("BallTracker: no observation yet")
        x = self.kf.state
        return BallTrajectory(x[:2], x[2:], self._effective_v_shoot(self._speed()), self.params)

    @property
    def phase(self) -> BallPhase:
        return self.trajectory().phase

    # -- update ---------------------------------------------------------------------------------
    def _predict(self, dt: float) -> tuple[tuple, tuple]:
        """The filter prediction with the two-phase model's deceleration along the motion."""
        speed = self._speed()
        if speed < 1e-6:
            return self.kf.predicted(dt)
        sliding = speed > self.params.c_switch * max(self._effective_v_shoot(speed), speed)
        decel = -(self.params.a_slide_mps2 if sliding else self.params.a_roll_mps2)
        decel = min(decel, speed / dt)  # the ball stops within dt: do not let it turn back
        k = -decel / speed
        return self.kf.predicted(dt, (k * self.kf.state[2], k * self.kf.state[3]))

    def update(self, t_s: float, x_m: float, y_m: float) -> UpdateStatus:
        self.kicked = False
        self.ricochet = False
        if not _check_obs(t_s, (x_m, y_m)):
            return UpdateStatus.REJECTED_INVALID
        t_s, z = float(t_s), (float(x_m), float(y_m))
        cfg = self.config
        if self.t_s is not None and t_s <= self.t_s:
            return UpdateStatus.REJECTED_TIME
        if self.t_s is None or t_s - self.t_s > cfg.max_gap_s:
            self.kf.reset(z, (0.0, 0.0), cfg.position_noise_m**2, 1.0)
            self.t_s, self._held, self._prev_obs = t_s, None, (t_s, *z)
            self.uncertain = True
            self._fit_ok.clear()
            return UpdateStatus.INITIALIZED

        x_pred, p_pred = self._predict(t_s - self.t_s)
        (nu_x, nu_y), s = self.kf.innovation(x_pred, p_pred, z)
        sigma = math.sqrt(s)
        worst = max(abs(nu_x), abs(nu_y))
        if worst <= max(cfg.gate_sigma * sigma, cfg.gate_min_m):
            self._held = None
            self.kf.correct(x_pred, p_pred, z)
            self.t_s = t_s
            self._prev_obs = (t_s, *z)
            self._fit_ok.append(worst <= 3.0 * sigma)
            self._after_accept()
            return UpdateStatus.ACCEPTED

        if self._held is None or not self._one_motion(t_s, z):
            # Maybe an outlier: wait for the next frame. A held frame this one cannot have followed
            # (a ball put down elsewhere right after it was seen, a false detection) is dropped for it.
            self._held = (t_s, *z)
            self._fit_ok.append(False)
            return UpdateStatus.HELD_BACK
        self._maneuver(t_s, z)
        return UpdateStatus.MANEUVER

    def _one_motion(self, t_s: float, z: tuple[float, float]) -> bool:
        t1, x1, y1 = self._held
        return math.hypot(z[0] - x1, z[1] - y1) <= self.config.max_ball_speed_mps * (t_s - t1)

    def _maneuver(self, t_s: float, z: tuple[float, float]) -> None:
        cfg = self.config
        t1, x1, y1 = self._held
        dt = t_s - t1
        v_new = (np.array(z) - np.array([x1, y1])) / dt
        v_old = self.kf.x[2:]
        p_old = self.kf.x[:2] + v_old * (t1 - self.t_s)
        speed_new, speed_old = float(np.hypot(*v_new)), float(np.hypot(*v_old))
        sigma_v = math.sqrt(2.0) * cfg.position_noise_m / dt
        var_v = 2.0 * sigma_v**2 + 0.01
        if speed_new <= 3.0 * sigma_v:
            # Two frames at the new place, no motion above the noise: a ball put down there (ball
            # placement, a vision swap), not a fast one. Start it at rest with a confident velocity,
            # or the noise of the next frames reads as tenths of m/s; a real slow motion is picked
            # up through the process noise.
            v_new, speed_new, var_v = np.zeros(2), 0.0, RESTING_VELOCITY_STD_MPS**2
            # A ball at rest has no shot: the kick speed of its past must not shape its next motion.
            self.v_shoot_mps, self.last_event_time_s, self._shoot_samples, self._rolling = 0.0, None, [], False
        t_prev = self._prev_obs[0] if self._prev_obs else t1
        self.kf.reset(z, v_new, cfg.position_noise_m**2, var_v)
        self.t_s, self._held, self._prev_obs = t_s, None, (t_s, *z)
        self._fit_ok.clear()
        self.uncertain = True
        # When did the new motion start? Extrapolate it back to where the old motion would be.
        gap = float(np.hypot(*(np.array([x1, y1]) - p_old)))
        t_event = t1 - gap / speed_new if speed_new > 0.0 else t1
        t_event = min(max(t_event, t_prev - dt), t1)
        if speed_new > speed_old + max(cfg.kick_threshold_mps, 3.0 * sigma_v):
            self.kicked = True
            self.kick_count += 1
        elif speed_old > cfg.ricochet_min_speed_mps and speed_new > cfg.ricochet_min_speed_mps:
            cos_turn = float(v_new @ v_old) / (speed_new * speed_old)
            if cos_turn < math.cos(cfg.ricochet_angle_rad):
                self.ricochet = True
                self.ricochet_count += 1
        if self.kicked or self.ricochet:
            self._rolling = False
            self.last_event_time_s = t_event
            self.v_shoot_mps = speed_new
            self._shoot_samples = []
        else:
            self.v_shoot_mps = max(self.v_shoot_mps, speed_new)
        if not self.ricochet:
            self.uncertain = self.kicked  # kicks are modelled; cleared once the fit is confirmed

    def _after_accept(self) -> None:
        cfg = self.config
        speed = self._speed()
        t_ev = self.last_event_time_s
        if t_ev is not None and self.t_s - t_ev <= cfg.shoot_window_s:
            # v_shoot from the speed extrapolated back to the kick, over the sliding phase only.
            if speed > self.params.c_switch * self.v_shoot_mps:
                self._shoot_samples.append(speed - self.params.a_slide_mps2 * (self.t_s - t_ev))
                self.v_shoot_mps = float(np.median(self._shoot_samples))
        elif speed > self.v_shoot_mps + 3.0 * self.velocity_std_mps + 0.05:
            self.v_shoot_mps = speed  # the paper's rule, above the noise
            self._rolling = False
        if speed < self.params.c_switch * self.v_shoot_mps - self.velocity_std_mps:
            self._rolling = True
        if len(self._fit_ok) == cfg.fit_frames and all(self._fit_ok):
            self.uncertain = False


class RobotTracker:
    """Robot pose tracking: KalmanCV2D on the position plus a CV filter on the unwrapped heading."""

    def __init__(
        self,
        position_noise_m: float = 0.002,
        accel_noise_psd: float = 1.0,
        heading_noise_rad: float = 0.01,
        angular_accel_noise_psd: float = 200.0,
    ) -> None:
        self.kf = KalmanCV2D(position_noise_m, accel_noise_psd)
        # The heading filter is a CV filter on (theta, 0) in x; y stays unused.
        self.heading = KalmanCV2D(heading_noise_rad, angular_accel_noise_psd)
        self.t_s: float | None = None
        self._has_heading = False

    def update(self, t_s: float, x_m: float, y_m: float, theta_rad: float | None = None) -> UpdateStatus:
        values = (x_m, y_m) if theta_rad is None else (x_m, y_m, theta_rad)
        if not _check_obs(t_s, values):
            return UpdateStatus.REJECTED_INVALID
        if self.t_s is not None and t_s <= self.t_s:
            return UpdateStatus.REJECTED_TIME
        z = (float(x_m), float(y_m))
        if self.t_s is None:
            self.kf.reset(z, (0.0, 0.0), self.kf.r, 1.0)
            status = UpdateStatus.INITIALIZED
        else:
            x, p = self.kf.predicted(t_s - self.t_s)
            self.kf.correct(x, p, z)
            status = UpdateStatus.ACCEPTED
        if theta_rad is not None:
            if not self._has_heading or self.t_s is None:
                self.heading.reset((theta_rad, 0.0), (0.0, 0.0), self.heading.r, 1.0)
                self._has_heading = True
            else:
                x, p = self.heading.predicted(t_s - self.t_s)
                wrapped = x[0] + math.remainder(theta_rad - x[0], 2.0 * math.pi)
                self.heading.correct(x, p, (wrapped, 0.0))
        self.t_s = float(t_s)
        return status

    @property
    def position_m(self) -> np.ndarray:
        return np.array(self.kf.state[:2])

    @property
    def velocity_mps(self) -> np.ndarray:
        return np.array(self.kf.state[2:])

    @property
    def heading_rad(self) -> float | None:
        return math.remainder(self.heading.state[0], 2.0 * math.pi) if self._has_heading else None

    @property
    def angular_velocity_radps(self) -> float | None:
        return self.heading.state[2] if self._has_heading else None
