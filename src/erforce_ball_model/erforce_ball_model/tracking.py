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
import functools
import math
from dataclasses import dataclass

import numpy as np

from erforce_ball_model.ball_model import BallModelParams, BallPhase, BallTrajectory
from erforce_interfaces.runtime.param_schema import schema_defaults
from erforce_interfaces.wire.robot_config import VISION_NOISE_M

_DEFAULTS = schema_defaults("erforce_ball_model", "ball_predictor")

__all__ = ["BallTracker", "KalmanCV2D", "RobotTracker", "TrackerConfig", "UpdateStatus", "ball_step",
           "compiled_ball_step", "load_kernels"]

RESTING_VELOCITY_STD_MPS = 0.05  # velocity uncertainty of a ball that reappeared at rest elsewhere
# v_shoot samples kept after an event (0.15 s at 1.7 kHz); further samples in the window are not added
SHOOT_SAMPLES = 256


class UpdateStatus(enum.IntEnum):
    INITIALIZED = 0  # first observation (or re-initialization after a long gap)
    ACCEPTED = 1
    HELD_BACK = 2  # outside the gate: possible outlier, not fused yet
    MANEUVER = 3  # confirmed change of motion: filter re-seeded
    REJECTED_TIME = 4  # stamp not after the previous one
    REJECTED_INVALID = 5  # non-finite input


def cv_predicted(px, py, vx, vy, a, b, c, q, dt, ax, ay):
    """The CV filter's state and per-axis covariance after ``dt`` with a known acceleration (ax, ay): a tuple
    of 7 (x, y, vx, vy, var_pos, cov_pos_vel, var_vel). Plain Python, and compiled in ``ball_step``."""
    h = 0.5 * dt * dt
    # white-acceleration noise: q dt^3/3, q dt^2/2, q dt (dt * dt * dt: the same bits compiled and in Python)
    return (px + vx * dt + h * ax, py + vy * dt + h * ay, vx + dt * ax, vy + dt * ay,
            a + dt * (2.0 * b + dt * c) + q * (dt * dt * dt) / 3.0, b + dt * c + q * h, c + q * dt)


def cv_corrected(px, py, vx, vy, a, b, c, r, zx, zy):
    """The correction with the position (zx, zy) measured with variance ``r`` (prediction px..c): the state
    and covariance, a tuple of 7. Joseph form (I - K H) P (I - K H)^T + K r K^T: stays symmetric positive."""
    nx, ny, s = zx - px, zy - py, a + r
    kp, kv = a / s, b / s  # gain for position and velocity
    m = 1.0 - kp
    return (px + kp * nx, py + kp * ny, vx + kv * nx, vy + kv * ny,
            m * m * a + kp * kp * r, m * (b - kv * a) + kp * kv * r, kv * kv * (a + r) - 2.0 * kv * b + c)


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
        out = cv_predicted(*self.state, *self.cov, self.q, dt, accel[0], accel[1])
        return out[:4], out[4:]

    def innovation(self, x: tuple, p: tuple, z) -> tuple[tuple[float, float], float]:
        """Innovation (x, y) and its variance, the same on both axes."""
        return (z[0] - x[0], z[1] - x[1]), p[0] + self.r

    def correct(self, x: tuple, p: tuple, z) -> None:
        out = cv_corrected(*x, *p, self.r, z[0], z[1])
        self.state, self.cov = out[:4], out[4:]


@dataclass(frozen=True)
class TrackerConfig:
    position_noise_m: float = VISION_NOISE_M
    accel_noise_psd: float = _DEFAULTS["accel_noise_psd"]  # (m/s^2)^2/Hz of the residual acceleration beyond the model
    gate_sigma: float = _DEFAULTS["gate_sigma"]
    gate_min_m: float = 0.01
    kick_threshold_mps: float = _DEFAULTS["kick_threshold_mps"]
    ricochet_angle_rad: float = math.radians(30.0)
    ricochet_min_speed_mps: float = 0.3
    shoot_window_s: float = 0.15
    fit_frames: int = 6
    max_gap_s: float = _DEFAULTS["max_gap_s"]  # longer gaps re-initialize the filter
    # a frame held back this long after the last fused one gets no estimate: the old motion extrapolated over
    # a gap (an occlusion, vision that stopped) says where the ball is not; the next frame re-seeds the filter
    max_hold_gap_s: float = 0.2
    # Two frames further apart than this speed allows are not one motion (the SSL limit is 6.5 m/s).
    max_ball_speed_mps: float = _DEFAULTS["max_ball_speed_mps"]

    def __post_init__(self) -> None:
        for name, value in self.__dict__.items():
            if not math.isfinite(value) or value <= 0:
                raise ValueError(f"{name}: must be finite and > 0, got {value!r}")


_NUMBER_TYPES = (int, float, np.floating, np.integer)  # a tuple built once (a union in the loop is built per item)


def _check_obs(t_s, values) -> bool:
    return all(isinstance(v, _NUMBER_TYPES) and math.isfinite(v) for v in (t_s, *values))


# The ball filter's state, one float64 array per BallTracker (NaN: None), read and written by ``ball_step``
# (the usual update, compiled) and by BallTracker's Python (start, held frames, maneuvers, properties).
(S_T, S_X, S_Y, S_VX, S_VY, S_VAR_POS, S_COV_POS_VEL, S_VAR_VEL, S_V_SHOOT, S_ROLLING, S_EVENT_T, S_UNCERTAIN,
 S_FIT_RUN, S_N_SHOOT, S_KICKED, S_RICOCHET, S_HELD, S_HELD_T, S_HELD_X, S_HELD_Y, S_PREV_T, S_PREV_X,
 S_PREV_Y) = range(23)
STATE_SIZE = 23
# the model and configuration as ball_step reads them
(M_A_SLIDE, M_A_ROLL, M_C_SWITCH, M_R, M_Q, M_GATE_SIGMA, M_GATE_MIN, M_SHOOT_WINDOW, M_FIT_FRAMES,
 M_MAX_GAP) = range(10)
OUTSIDE_GATE = -1  # ball_step: not fused, nothing changed; Python holds the frame back or re-seeds


def effective_v_shoot(v_shoot, rolling, speed, c_switch):
    # Once rolling, stay rolling until the next kick or ricochet: speed noise around the switch
    # speed must not flip the model back to sliding.
    return max(v_shoot, speed / c_switch) if rolling else v_shoot


def ball_step(s, shoot, m, t_s, x, y):
    """BallTracker's update of the state ``s`` with the observation (t_s, x, y) where it fuses or starts:
    the UpdateStatus, or OUTSIDE_GATE (the state unchanged but for the kicked and ricochet flags). Runs as
    Python until ``load_kernels``, then compiled (``compiled_ball_step``): the same bits either way."""
    s[S_KICKED] = 0.0
    s[S_RICOCHET] = 0.0
    if not (math.isfinite(t_s) and math.isfinite(x) and math.isfinite(y)):
        return 5  # UpdateStatus.REJECTED_INVALID
    t_prev = s[S_T]
    if not math.isnan(t_prev) and t_s <= t_prev:
        return 4  # UpdateStatus.REJECTED_TIME
    if math.isnan(t_prev) or t_s - t_prev > m[M_MAX_GAP]:
        s[S_X], s[S_Y], s[S_VX], s[S_VY] = x, y, 0.0, 0.0
        s[S_VAR_POS], s[S_COV_POS_VEL], s[S_VAR_VEL] = m[M_R], 0.0, 1.0
        s[S_T], s[S_HELD], s[S_PREV_T], s[S_PREV_X], s[S_PREV_Y] = t_s, 0.0, t_s, x, y
        s[S_UNCERTAIN], s[S_FIT_RUN] = 1.0, 0.0
        return 0  # UpdateStatus.INITIALIZED
    # the prediction with the two-phase model's deceleration along the motion
    dt = t_s - t_prev
    vx, vy = s[S_VX], s[S_VY]
    speed = math.hypot(vx, vy)
    ax = ay = 0.0
    if speed >= 1e-6:
        c_switch = m[M_C_SWITCH]
        sliding = speed > c_switch * max(effective_v_shoot(s[S_V_SHOOT], s[S_ROLLING] != 0.0, speed, c_switch), speed)
        decel = -(m[M_A_SLIDE] if sliding else m[M_A_ROLL])
        decel = min(decel, speed / dt)  # the ball stops within dt: do not let it turn back
        k = -decel / speed
        ax, ay = k * vx, k * vy
    px, py, pvx, pvy, a, b, c = cv_predicted(s[S_X], s[S_Y], vx, vy, s[S_VAR_POS], s[S_COV_POS_VEL], s[S_VAR_VEL],
                                             m[M_Q], dt, ax, ay)
    sigma = math.sqrt(a + m[M_R])
    worst = max(abs(x - px), abs(y - py))
    if not worst <= max(m[M_GATE_SIGMA] * sigma, m[M_GATE_MIN]):
        return OUTSIDE_GATE
    (s[S_X], s[S_Y], s[S_VX], s[S_VY], s[S_VAR_POS], s[S_COV_POS_VEL],
     s[S_VAR_VEL]) = cv_corrected(px, py, pvx, pvy, a, b, c, m[M_R], x, y)
    s[S_T], s[S_HELD], s[S_PREV_T], s[S_PREV_X], s[S_PREV_Y] = t_s, 0.0, t_s, x, y
    s[S_FIT_RUN] = s[S_FIT_RUN] + 1.0 if worst <= 3.0 * sigma else 0.0
    # v_shoot and the rolling latch after the accepted frame
    speed = math.hypot(s[S_VX], s[S_VY])
    velocity_std = math.sqrt(s[S_VAR_VEL])
    t_event = s[S_EVENT_T]
    if not math.isnan(t_event) and t_s - t_event <= m[M_SHOOT_WINDOW]:
        # v_shoot from the speed extrapolated back to the kick, over the sliding phase only
        if speed > m[M_C_SWITCH] * s[S_V_SHOOT]:
            n = int(s[S_N_SHOOT])
            if n < len(shoot):
                shoot[n] = speed - m[M_A_SLIDE] * (t_s - t_event)
                n += 1
                s[S_N_SHOOT] = n
            s[S_V_SHOOT] = np.median(shoot[:n])
    elif speed > s[S_V_SHOOT] + 3.0 * velocity_std + 0.05:
        s[S_V_SHOOT] = speed  # the paper's rule, above the noise
        s[S_ROLLING] = 0.0
    if speed < m[M_C_SWITCH] * s[S_V_SHOOT] - velocity_std:
        s[S_ROLLING] = 1.0
    if s[S_FIT_RUN] >= m[M_FIT_FRAMES]:  # the last fit_frames innovations all within 3 sigma
        s[S_UNCERTAIN] = 0.0
    return 1  # UpdateStatus.ACCEPTED


class _StateKalman(KalmanCV2D):
    """The ball's KalmanCV2D with its state and covariance in the tracker's state array."""

    def __init__(self, s: np.ndarray, position_noise_m: float, accel_noise_psd: float) -> None:
        self._s = s
        super().__init__(position_noise_m, accel_noise_psd)

    @property
    def state(self) -> tuple[float, float, float, float]:
        return tuple(self._s[S_X:S_VY + 1].tolist())

    @state.setter
    def state(self, value) -> None:
        self._s[S_X:S_VY + 1] = value

    @property
    def cov(self) -> tuple[float, float, float]:
        return tuple(self._s[S_VAR_POS:S_VAR_VEL + 1].tolist())

    @cov.setter
    def cov(self, value) -> None:
        self._s[S_VAR_POS:S_VAR_VEL + 1] = value


def _optional(index: int):
    """A float of the state array that may be None (NaN)."""
    def get(self):
        v = float(self.s[index])
        return None if math.isnan(v) else v

    def put(self, value):
        self.s[index] = math.nan if value is None else value

    return property(get, put)


def _flag(index: int):
    return property(lambda self: bool(self.s[index]), lambda self, value: self.s.__setitem__(index, float(value)))


@functools.cache
def compiled_ball_step():
    """``ball_step`` as a numba kernel (compiled or loaded from numba's cache on first call), callable from
    other kernels. numba is imported here, not with this module: a process that only tracks (the predictor
    restarted without its warm-up) starts without it."""
    from erforce_interfaces.runtime.numba_support import numba, register_jitable

    for rule in (cv_predicted, cv_corrected, effective_v_shoot):
        register_jitable(rule)
    return numba.njit(cache=True, error_model="numpy")(ball_step)


def load_kernels() -> None:
    """Compile (or load) ``ball_step`` now; from then on every BallTracker's update runs it compiled."""
    global _step
    from erforce_interfaces.runtime.numba_support import compiled_for

    s = np.zeros(STATE_SIZE)
    _step = compiled_for(compiled_ball_step(), s, np.zeros(SHOOT_SAMPLES), np.zeros(10), 0.0, 0.0, 0.0)


_STATUSES = tuple(UpdateStatus)
_step = ball_step  # BallTracker's update: the Python source until load_kernels


class BallTracker:
    """Tracks one ball: filtered state, v_shoot, kick/ricochet events and a trajectory for prediction.

    Call ``update(t_s, x_m, y_m)`` per vision frame (strictly increasing stamps); read
    ``trajectory()`` and the flags ``kicked`` / ``ricochet`` (true for the update that detected the
    event), ``uncertain`` and ``phase``. The state lives in the array ``s`` (indices ``S_*``); the usual
    update is ``ball_step`` (compiled after ``load_kernels``; a kernel can call ``compiled_ball_step()`` on
    ``s``, ``shoot`` and ``m``). ``params`` is the ball model it filters and predicts with; setting it
    rewrites the model in ``m`` in place, so a kernel holding ``m`` filters with the new one at once.
    """

    t_s = _optional(S_T)
    last_event_time_s = _optional(S_EVENT_T)
    v_shoot_mps = property(lambda self: float(self.s[S_V_SHOOT]),
                           lambda self, value: self.s.__setitem__(S_V_SHOOT, value))
    kicked = _flag(S_KICKED)
    ricochet = _flag(S_RICOCHET)
    uncertain = _flag(S_UNCERTAIN)
    _rolling = _flag(S_ROLLING)  # latched once the speed fell below the switch speed (no flicker)

    def __init__(self, params: BallModelParams | None = None, config: TrackerConfig | None = None) -> None:
        self.config = cfg = config or TrackerConfig()
        self.s = np.zeros(STATE_SIZE)
        self.shoot = np.zeros(SHOOT_SAMPLES)
        self.m = np.array([math.nan, math.nan, math.nan, cfg.position_noise_m**2, cfg.accel_noise_psd, cfg.gate_sigma,
                           cfg.gate_min_m, cfg.shoot_window_s, cfg.fit_frames, cfg.max_gap_s])
        self.params = BallModelParams() if params is None else params
        self.kf = _StateKalman(self.s, cfg.position_noise_m, cfg.accel_noise_psd)
        self.reset()

    @property
    def params(self) -> BallModelParams:
        """The ball model the filter predicts with and ``trajectory`` hands on."""
        return self._params

    @params.setter
    def params(self, value: BallModelParams) -> None:
        # The kernel reads the model from ``m``: rewritten here, in place (compiled code that holds the array,
        # vision_fast_path.FramePass, sees it), so that the filter and the trajectory never use two models.
        if not isinstance(value, BallModelParams):
            raise ValueError(f"params: expected BallModelParams, got {type(value).__name__}")
        self._params = value
        self.m[M_A_SLIDE], self.m[M_A_ROLL], self.m[M_C_SWITCH] = value.a_slide_mps2, value.a_roll_mps2, value.c_switch

    def reset(self) -> None:
        """No observation yet (a new ball), in place: compiled code that holds the arrays sees it."""
        self.s[:] = 0.0
        self.s[[S_T, S_EVENT_T]] = math.nan
        self.kf.cov = (1.0, 0.0, 1.0)
        self.uncertain = True
        self.kick_count = 0
        self.ricochet_count = 0

    # -- state ----------------------------------------------------------------------------------
    @property
    def initialized(self) -> bool:
        return not math.isnan(self.s[S_T])

    @property
    def position_m(self) -> np.ndarray:
        return self.s[S_X:S_Y + 1].copy()

    @property
    def velocity_mps(self) -> np.ndarray:
        return self.s[S_VX:S_VY + 1].copy()

    @property
    def velocity_std_mps(self) -> float:
        return math.sqrt(self.s[S_VAR_VEL])

    @property
    def position_variance_m2(self) -> float:
        return float(self.s[S_VAR_POS])

    def variances_at(self, t_s: float) -> tuple[float, float]:
        """The filter's variance of each position coordinate [m^2] and of each velocity component [(m/s)^2] at
        ``t_s`` (not before the newest fused frame): its covariance predicted there, as ``trajectory`` is."""
        dt = t_s - self.s[S_T]
        var_pos, _, var_vel = self.kf.predicted(dt)[1] if dt > 0.0 else self.kf.cov
        return float(var_pos), float(var_vel)

    @property
    def _held(self) -> tuple[float, float, float] | None:
        return tuple(self.s[S_HELD_T:S_HELD_Y + 1].tolist()) if self.s[S_HELD] else None

    @_held.setter
    def _held(self, value: tuple[float, float, float] | None) -> None:
        self.s[S_HELD] = value is not None
        if value is not None:
            self.s[S_HELD_T:S_HELD_Y + 1] = value

    def _speed(self) -> float:
        return math.hypot(self.s[S_VX], self.s[S_VY])

    def _effective_v_shoot(self, speed: float) -> float:
        return effective_v_shoot(self.v_shoot_mps, self._rolling, speed, self.params.c_switch)

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
    def update(self, t_s: float, x_m: float, y_m: float) -> UpdateStatus:
        if not _check_obs(t_s, (x_m, y_m)):
            self.s[S_KICKED] = self.s[S_RICOCHET] = 0.0
            return UpdateStatus.REJECTED_INVALID
        t_s, z = float(t_s), (float(x_m), float(y_m))
        status = _step(self.s, self.shoot, self.m, t_s, z[0], z[1])
        if status != OUTSIDE_GATE:
            return _STATUSES[status]
        if self._held is None or not self._one_motion(t_s, z):
            # Maybe an outlier: wait for the next frame. A held frame this one cannot have followed
            # (a ball put down elsewhere right after it was seen, a false detection) is dropped for it.
            self._held = (t_s, *z)
            self.s[S_FIT_RUN] = 0.0
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
            self.v_shoot_mps, self.last_event_time_s, self._rolling = 0.0, None, False
            self.s[S_N_SHOOT] = 0.0
        t_prev = self.s[S_PREV_T]
        self.kf.reset(z, v_new, cfg.position_noise_m**2, var_v)
        self.t_s, self._held = t_s, None
        self.s[S_PREV_T:S_PREV_Y + 1] = (t_s, *z)
        self.s[S_FIT_RUN] = 0.0
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
            self.s[S_N_SHOOT] = 0.0
        else:
            self.v_shoot_mps = max(self.v_shoot_mps, speed_new)
        if not self.ricochet:
            self.uncertain = self.kicked  # kicks are modelled; cleared once the fit is confirmed


    def hand_over(self, t_s: float, trajectory: BallTrajectory) -> None:
        """Take the ball over from another model at ``t_s`` (not before the newest frame): its position, velocity
        and kick speed as if fused then (a chipped ball that rolls now, chip_tracking). No kick is counted."""
        f = trajectory.floats
        cfg, s = self.config, self.s
        self.kf.reset((f.x_m, f.y_m), (f.vx_mps, f.vy_mps), cfg.position_noise_m**2, RESTING_VELOCITY_STD_MPS**2)
        s[S_T], s[S_HELD], s[S_FIT_RUN], s[S_N_SHOOT] = t_s, 0.0, 0.0, 0.0
        s[S_PREV_T:S_PREV_Y + 1] = (t_s, f.x_m, f.y_m)
        self.v_shoot_mps, self.last_event_time_s = f.v_shoot_mps, None
        self._rolling = f.speed_mps <= f.v_switch_mps


class RobotTracker:
    """Robot pose tracking: KalmanCV2D on the position plus a CV filter on the unwrapped heading."""

    def __init__(
        self,
        position_noise_m: float = VISION_NOISE_M,
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

    @property
    def variances(self) -> tuple[float, float, float | None, float | None]:
        """The filters' variance of each position coordinate [m^2], of each velocity component [(m/s)^2], of the
        heading [rad^2] and of the yaw rate [(rad/s)^2] (the last two None without a heading), at the newest
        frame."""
        var_pos, _, var_vel = self.kf.cov
        if not self._has_heading:
            return var_pos, var_vel, None, None
        var_heading, _, var_rate = self.heading.cov
        return var_pos, var_vel, var_heading, var_rate
