"""Discrete PID controller used by every loop of paper Sec. 4.1 (Fig. 2 velocity, Fig. 3 speed and current).

One object serves n channels (numpy arrays): the three twist axes, or the wheels of
a robot. Gains may be scalars or one value per channel.

Per step, with e the error after the deadband and y the measurement:

    P = kp * e
    D = kd * d,   d <- d + dt/(tau_d + dt) * (-(y - y_prev)/dt - d)   derivative on measurement,
                                                                      first-order low-pass (backward Euler)
    v = P + I + D + feedforward          (feedforward enters before saturation)
    u = clip(v, output_min, output_max)

then the integrator is advanced for the next step (forward Euler, as in Astrom & Murray,
"Feedback Systems", Sec. 10.5):

    'clamp':            I <- I + ki*e*dt unless v is saturated and e pushes further into it
    'back_calculation': I <- I + ki*e*dt + kt*(u - v)*dt
    I <- clip(I, integrator_min, integrator_max)

so with kp=2, ki=1, dt=0.1 and a constant error 1 the outputs are 2.0, 2.1, 2.2, ...
The integrator state I is kept in output units, which makes `reset` bumpless.
The deadband is the continuous (shifted) kind: e = sign(e_raw) * max(|e_raw| - deadband, 0).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np

AntiWindup = Literal["clamp", "back_calculation"]
ANTI_WINDUP_MODES = ("clamp", "back_calculation")
DEFAULT_ANTI_WINDUP: AntiWindup = "clamp"  # every PID's, and both motion nodes' anti_windup


def _channel_values(value, n: int, name: str) -> np.ndarray:
    arr = np.asarray(value, dtype=float)
    if arr.ndim == 0:
        arr = np.full(n, float(arr))
    if arr.shape != (n,):
        raise ValueError(f"{name}: need a scalar or {n} values, got shape {arr.shape}")
    return arr


@dataclass(frozen=True)
class PidConfig:
    """Gains and limits; every gain/limit is a scalar or a tuple with one value per channel.

    Output and integrator limits may be +-inf (no limit) but never NaN.
    tracking_gain_kt [1/s] is used by 'back_calculation'; None picks kt = ki/kp (tracking
    time constant equal to the integral time, Astrom & Hagglund's choice for a PI).
    """

    kp: float | tuple[float, ...] = 1.0
    ki: float | tuple[float, ...] = 0.0
    kd: float | tuple[float, ...] = 0.0
    output_min: float | tuple[float, ...] = -math.inf
    output_max: float | tuple[float, ...] = math.inf
    integrator_min: float | tuple[float, ...] = -math.inf
    integrator_max: float | tuple[float, ...] = math.inf
    anti_windup: AntiWindup = DEFAULT_ANTI_WINDUP
    tracking_gain_kt: float | tuple[float, ...] | None = None
    derivative_filter_tau_s: float | tuple[float, ...] = 0.0
    deadband: float | tuple[float, ...] = 0.0
    n_channels: int = 1

    def __post_init__(self) -> None:
        n = self.n_channels
        if not isinstance(n, int) or isinstance(n, bool) or n < 1:
            raise ValueError(f"n_channels: must be an int >= 1, got {n!r}")
        if self.anti_windup not in ANTI_WINDUP_MODES:
            raise ValueError(f"anti_windup: must be one of {ANTI_WINDUP_MODES}, got {self.anti_windup!r}")
        arrays = self.arrays()
        for name in ("kp", "ki", "kd", "derivative_filter_tau_s", "deadband", "tracking_gain_kt"):
            a = arrays[name]
            if not np.isfinite(a).all():
                raise ValueError(f"{name}: must be finite, got {getattr(self, name)!r}")
        if not (arrays["kp"] > 0.0).all():
            raise ValueError(f"kp: must be > 0, got {self.kp!r}")
        for name in ("ki", "kd", "derivative_filter_tau_s", "deadband", "tracking_gain_kt"):
            if not (arrays[name] >= 0.0).all():
                raise ValueError(f"{name}: must be >= 0, got {getattr(self, name)!r}")
        for lo, hi in (("output_min", "output_max"), ("integrator_min", "integrator_max")):
            a, b = arrays[lo], arrays[hi]
            if np.isnan(a).any() or np.isnan(b).any():
                raise ValueError(f"{lo}/{hi}: must not be NaN")
            if not (a < b).all():
                raise ValueError(f"{lo} must be < {hi}, got {getattr(self, lo)!r} and {getattr(self, hi)!r}")

    def arrays(self) -> dict[str, np.ndarray]:
        """Every per-channel parameter as an array of length n_channels."""
        n = self.n_channels
        out = {
            name: _channel_values(getattr(self, name), n, name)
            for name in (
                "kp", "ki", "kd", "output_min", "output_max", "integrator_min", "integrator_max",
                "derivative_filter_tau_s", "deadband",
            )
        }
        if self.tracking_gain_kt is None:
            with np.errstate(divide="ignore", invalid="ignore"):  # kp <= 0 is rejected by the caller
                out["tracking_gain_kt"] = out["ki"] / out["kp"]
        else:
            out["tracking_gain_kt"] = _channel_values(self.tracking_gain_kt, n, "tracking_gain_kt")
        return out


@dataclass(frozen=True)
class PidStatus:
    """Snapshot after the last step; every array has one entry per channel."""

    output: np.ndarray
    unsaturated_output: np.ndarray
    saturated_high: np.ndarray
    saturated_low: np.ndarray
    p_term: np.ndarray
    i_term: np.ndarray
    d_term: np.ndarray

    @property
    def saturated(self) -> np.ndarray:
        return self.saturated_high | self.saturated_low


class Pid:
    """Vectorized discrete PID; see the module docstring for the exact update equations."""

    def __init__(self, config: PidConfig) -> None:
        self.config = config
        a = config.arrays()
        self._n = config.n_channels
        self._kp, self._ki, self._kd = a["kp"], a["ki"], a["kd"]
        self._out_lo, self._out_hi = a["output_min"], a["output_max"]
        self._int_lo, self._int_hi = a["integrator_min"], a["integrator_max"]
        self._kt = a["tracking_gain_kt"]
        self._tau_d = a["derivative_filter_tau_s"]
        self._deadband = a["deadband"]
        # Skip the arithmetic of features that are switched off: the hot loops run at 1 kHz.
        self._use_deadband = bool((self._deadband > 0.0).any())
        self._use_d = bool((self._kd > 0.0).any())
        self._use_i = bool((self._ki > 0.0).any())
        self._back_calc = config.anti_windup == "back_calculation"
        self._limit_integrator = bool(np.isfinite(self._int_lo).any() or np.isfinite(self._int_hi).any())
        self._integrator = np.zeros(self._n)
        self._d_filtered = np.zeros(self._n)
        self._y_prev = np.zeros(self._n)
        self._have_y_prev = False
        zeros = np.zeros(self._n)
        self._last = (zeros, zeros, zeros, zeros, zeros)  # u, v, p, i, d
        self._e = np.zeros(self._n)

    @property
    def n_channels(self) -> int:
        return self._n

    @property
    def integrator(self) -> np.ndarray:
        return self._integrator.copy()

    def _error(self, setpoint, measurement) -> np.ndarray:
        e = self._e
        try:
            np.subtract(setpoint, measurement, out=e)
        except (ValueError, TypeError) as exc:
            raise ValueError(
                f"setpoint/measurement: need scalars or {self._n} values, got shapes "
                f"{np.shape(setpoint)} and {np.shape(measurement)}"
            ) from exc
        if self._use_deadband:
            e = np.sign(e) * np.maximum(np.abs(e) - self._deadband, 0.0)
        return e

    def step(self, setpoint, measurement, dt_s: float, feedforward=0.0, output_min=None, output_max=None,
             hold_integrator=False):
        """One control period; returns the saturated output (new array, length n).

        output_min/output_max override the configured output limits for this step only
        (e.g. a limit that moves with the thermal PWM limit); anti-windup uses them.
        hold_integrator (bool or per-channel mask) freezes the integrator, e.g. while a
        downstream loop is saturated (conditional integration from outside).
        Raises ValueError for dt_s <= 0 or non-finite, and for non-finite inputs/outputs;
        the state is left unchanged then.
        """
        if not (0.0 < dt_s < math.inf):
            raise ValueError(f"dt_s: must be finite and > 0, got {dt_s!r}")
        e = self._error(setpoint, measurement)
        p = self._kp * e
        y = measurement
        if self._use_d:
            if self._have_y_prev:
                raw = (self._y_prev - y) / dt_s
                d_filt = self._d_filtered + (dt_s / (self._tau_d + dt_s)) * (raw - self._d_filtered)
            else:
                d_filt = self._d_filtered
            d = self._kd * d_filt
            v = p + self._integrator + d + feedforward
        else:
            d_filt = d = None
            v = p + self._integrator + feedforward
        if not np.isfinite(v).all():
            raise ValueError("PID: non-finite setpoint, measurement, feedforward or output")
        lo = self._out_lo if output_min is None else output_min
        hi = self._out_hi if output_max is None else output_max
        u = np.minimum(np.maximum(v, lo), hi)

        i_used = self._integrator
        if self._use_i and hold_integrator is not True:
            inc = (self._ki * dt_s) * e
            if hold_integrator is not False:
                inc = np.where(hold_integrator, 0.0, inc)
            if self._back_calc:
                track = (self._kt * dt_s) * (u - v)
                if hold_integrator is not False:
                    track = np.where(hold_integrator, 0.0, track)
                new_i = self._integrator + inc + track
            else:
                sat = v != u
                if sat.any():  # conditional integration: no step that pushes further into saturation
                    inc = np.where(sat & ((v - u) * inc > 0.0), 0.0, inc)
                new_i = self._integrator + inc
            if self._limit_integrator:
                np.clip(new_i, self._int_lo, self._int_hi, out=new_i)
            self._integrator = new_i
        if self._use_d:
            self._d_filtered = d_filt
            self._y_prev[:] = y
            self._have_y_prev = True
        self._last = (u, v, p, i_used, d)
        return u

    def reset(self, output_hold=0.0, measurement=None, setpoint=None, feedforward=0.0) -> None:
        """Bumpless reset: the next step with the same setpoint, measurement and feedforward
        outputs exactly `output_hold` (unless the integrator limits clip the needed integrator).

        setpoint None means "no error", measurement None forgets the derivative history.
        """
        hold = _channel_values(output_hold, self._n, "output_hold")
        ff = _channel_values(feedforward, self._n, "feedforward")
        if not (np.isfinite(hold).all() and np.isfinite(ff).all()):
            raise ValueError("reset: output_hold and feedforward must be finite")
        p = np.zeros(self._n)
        if measurement is not None:
            y = _channel_values(measurement, self._n, "measurement")
            if not np.isfinite(y).all():
                raise ValueError("reset: measurement must be finite")
            if setpoint is not None:
                sp = _channel_values(setpoint, self._n, "setpoint")
                if not np.isfinite(sp).all():
                    raise ValueError("reset: setpoint must be finite")
                p = self._kp * self._error(sp, y)
            self._y_prev[:] = y
            self._have_y_prev = True
        else:
            self._have_y_prev = False
        self._integrator = np.clip(hold - p - ff, self._int_lo, self._int_hi)
        self._d_filtered = np.zeros(self._n)

    @property
    def saturated(self) -> np.ndarray:
        """Per channel: was the last output clipped by the output limits (cheaper than `status`)."""
        u, v = self._last[0], self._last[1]
        return (v != u) | np.zeros(self._n, dtype=bool)  # a fresh (n,) array; broadcast_to costs more here

    @property
    def status(self) -> PidStatus:
        u, v, p, i, d = self._last
        n = self._n
        return PidStatus(
            output=np.broadcast_to(u, (n,)).copy(),
            unsaturated_output=np.broadcast_to(v, (n,)).copy(),
            saturated_high=np.broadcast_to(v > u, (n,)).copy(),
            saturated_low=np.broadcast_to(v < u, (n,)).copy(),
            p_term=np.broadcast_to(p, (n,)).copy(),
            i_term=np.broadcast_to(i, (n,)).copy(),
            d_term=np.zeros(n) if d is None else np.broadcast_to(d, (n,)).copy(),
        )
