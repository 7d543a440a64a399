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

The update is written once, in the compiled ``pid_step``, for the rows (robots) of a (robots, channels)
state in one call: the velocity loop, the motor boards and the team firmware call it for their robots,
and ``Pid`` is that same kernel for one row.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np

from erforce_interfaces.runtime.numba_support import compiled_for, numba

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


# flags of a PID table (``pid_tables``): deadband, derivative, integral, back-calculation, integrator limits
_F_DB, _F_D, _F_I, _F_BACK, _F_ILIM = range(5)


def pid_tables(config: PidConfig) -> tuple[np.ndarray, np.ndarray]:
    """A PidConfig as (10, channels) parameters (kp, ki, kd, output min/max, integrator min/max, kt, tau_d,
    deadband) and the feature flags: the hot loops skip the arithmetic of features that are off."""
    a = config.arrays()
    params = np.vstack([a["kp"], a["ki"], a["kd"], a["output_min"], a["output_max"], a["integrator_min"],
                        a["integrator_max"], a["tracking_gain_kt"], a["derivative_filter_tau_s"], a["deadband"]])
    flags = np.array([
        (a["deadband"] > 0.0).any(), (a["kd"] > 0.0).any(), (a["ki"] > 0.0).any(),
        config.anti_windup == "back_calculation",
        np.isfinite(a["integrator_min"]).any() or np.isfinite(a["integrator_max"]).any(),
    ], dtype=np.bool_)
    return np.ascontiguousarray(params), flags


class PidState:
    """The state of one PID for ``n_rows`` robots: integrator, derivative filter, previous measurement, the
    last step's output u, unsaturated output v and terms p, i, d (for status and saturation flags), and
    whether each robot's last step was finite (``ok``)."""

    def __init__(self, n_rows: int, n_channels: int) -> None:
        # two arrays hold it all (a kernel call unpacks each array it is passed), the names are views of them
        self.values = np.zeros((8, n_rows, n_channels))
        self.integrator, self.d_filtered, self.y_prev, self.u, self.v, self.p, self.i, self.d = self.values
        self.flags = np.zeros((2, n_rows), dtype=np.bool_)
        self.have_y_prev, self.ok = self.flags

    def arrays(self) -> tuple[np.ndarray, np.ndarray]:
        return self.values, self.flags


@numba.njit(cache=True, error_model="numpy")
def pid_step(rows, prm, flags, st, sp, y, dt, ff, lo, hi, hold, out):
    """One step of each robot k in ``rows`` (the module docstring's equations), channel by channel; writes u
    into out[k].

    prm, flags: ``pid_tables``; st: ``PidState.arrays()``; sp, y, ff, lo, hi (robots, channels) inputs, dt
    per robot; hold: (robots, channels) flags that freeze the integrator. A robot whose unsaturated output
    is not finite stops at that channel (its state there unchanged) with ok[k] False; returns whether all
    robots were ok. The state is unpacked here once for all rows: the team's call is one call."""
    values, flags_k = st
    integ, dfilt, yprev, last_u = values[0], values[1], values[2], values[3]
    last_v, last_p, last_i, last_d = values[4], values[5], values[6], values[7]
    have_y, ok = flags_k[0], flags_k[1]
    use_db, use_d, use_i, back, ilim = flags[0], flags[1], flags[2], flags[3], flags[4]
    all_ok = True
    for k in rows:
        dt_k = dt[k]
        ok[k] = True
        for c in range(out.shape[1]):
            e = sp[k, c] - y[k, c]
            if use_db:
                e = np.sign(e) * max(abs(e) - prm[9, c], 0.0)
            p = prm[0, c] * e
            i_now = integ[k, c]
            if use_d:
                df = dfilt[k, c]
                if have_y[k]:
                    df = df + (dt_k / (prm[8, c] + dt_k)) * ((yprev[k, c] - y[k, c]) / dt_k - df)
                d = prm[2, c] * df
                v = p + i_now + d + ff[k, c]
            else:
                df = d = 0.0
                v = p + i_now + ff[k, c]
            if not math.isfinite(v):
                ok[k] = all_ok = False
                break
            u = min(max(v, lo[k, c]), hi[k, c])
            if use_i and not hold[k, c]:
                inc = (prm[1, c] * dt_k) * e
                if back:
                    new_i = i_now + inc + (prm[7, c] * dt_k) * (u - v)
                else:
                    if v != u and (v - u) * inc > 0.0:  # conditional integration: not further into saturation
                        inc = 0.0
                    new_i = i_now + inc
                if ilim:
                    new_i = min(max(new_i, prm[5, c]), prm[6, c])
                integ[k, c] = new_i
            if use_d:
                dfilt[k, c] = df
                yprev[k, c] = y[k, c]
            last_u[k, c] = u
            last_v[k, c] = v
            last_p[k, c] = p
            last_i[k, c] = i_now
            last_d[k, c] = d
            out[k, c] = u
        if use_d and ok[k]:
            have_y[k] = True
    return all_ok


@numba.njit(cache=True, error_model="numpy")
def pid_reset(k, prm, flags, st, hold, ff, y, sp, with_measurement, with_setpoint):
    """Bumpless reset of row k: the next step with the same inputs outputs ``hold`` (see ``Pid.reset``)."""
    integ, dfilt, yprev, have_y = st[0][0], st[0][1], st[0][2], st[1][0]
    for c in range(hold.shape[0]):
        p = 0.0
        if with_measurement and with_setpoint:
            e = sp[c] - y[c]
            if flags[_F_DB]:
                e = np.sign(e) * max(abs(e) - prm[9, c], 0.0)
            p = prm[0, c] * e
        if with_measurement:
            yprev[k, c] = y[c]
        integ[k, c] = min(max(hold[c] - p - ff[c], prm[5, c]), prm[6, c])
        dfilt[k, c] = 0.0
    have_y[k] = with_measurement


class Pid:
    """Discrete PID on n channels (one row of ``pid_step``); see the module docstring for the equations."""

    def __init__(self, config: PidConfig) -> None:
        self.config = config
        self._n = n = config.n_channels
        self._prm, self._flags = pid_tables(config)
        self._state = PidState(1, n)
        self._st = self._state.arrays()
        self._row = np.zeros(1, dtype=np.int64)
        self._dt = np.zeros(1)
        self._hold = np.zeros((1, n), dtype=np.bool_)
        row = np.zeros((1, n))
        self._step = compiled_for(pid_step, self._row, self._prm, self._flags, self._st, row, row, self._dt,
                                  row, row, row, self._hold, row)

    @property
    def n_channels(self) -> int:
        return self._n

    @property
    def integrator(self) -> np.ndarray:
        return self._state.integrator[0].copy()

    def _channels(self, value, name: str) -> np.ndarray:
        try:
            return np.ascontiguousarray(np.broadcast_to(np.asarray(value, dtype=float), (self._n,)))
        except ValueError as exc:
            raise ValueError(f"{name}: need scalars or {self._n} values, got shape {np.shape(value)}") from exc

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
        if np.shape(setpoint) != np.shape(measurement) and np.ndim(setpoint) and np.ndim(measurement):
            raise ValueError(f"setpoint/measurement: need scalars or {self._n} values, got shapes "
                             f"{np.shape(setpoint)} and {np.shape(measurement)}")
        sp = self._channels(setpoint, "setpoint/measurement")
        y = self._channels(measurement, "setpoint/measurement")
        ff = self._channels(feedforward, "feedforward")
        lo = self._prm[3] if output_min is None else self._channels(output_min, "output_min")
        hi = self._prm[4] if output_max is None else self._channels(output_max, "output_max")
        self._hold[0] = hold_integrator
        self._dt[0] = dt_s
        out = np.empty((1, self._n))
        before = [a.copy() for a in self._st]  # a failing channel leaves the others stepped: undo them
        if not self._step(self._row, self._prm, self._flags, self._st, sp[None], y[None], self._dt, ff[None],
                          lo[None], hi[None], self._hold, out):
            for a, b in zip(self._st, before, strict=True):
                a[:] = b
            raise ValueError("PID: non-finite setpoint, measurement, feedforward or output")
        return out[0]

    def reset(self, output_hold=0.0, measurement=None, setpoint=None, feedforward=0.0) -> None:
        """Bumpless reset: the next step with the same setpoint, measurement and feedforward
        outputs exactly `output_hold` (unless the integrator limits clip the needed integrator).

        setpoint None means "no error", measurement None forgets the derivative history.
        """
        values = [_channel_values(output_hold, self._n, "output_hold"),
                  _channel_values(feedforward, self._n, "feedforward")]
        if not (np.isfinite(values[0]).all() and np.isfinite(values[1]).all()):
            raise ValueError("reset: output_hold and feedforward must be finite")
        for name, given in (("measurement", measurement), ("setpoint", setpoint)):
            arr = _channel_values(given if given is not None else 0.0, self._n, name)
            if not np.isfinite(arr).all():
                raise ValueError(f"reset: {name} must be finite")
            values.append(arr)
        pid_reset(0, self._prm, self._flags, self._st, *values, measurement is not None,
                  measurement is not None and setpoint is not None)

    @property
    def saturated(self) -> np.ndarray:
        """Per channel: was the last output clipped by the output limits (cheaper than `status`)."""
        return self._state.v[0] != self._state.u[0]

    @property
    def status(self) -> PidStatus:
        s = self._state
        u, v = s.u[0].copy(), s.v[0].copy()
        return PidStatus(output=u, unsaturated_output=v, saturated_high=v > u, saturated_low=v < u,
                         p_term=s.p[0].copy(), i_term=s.i[0].copy(), d_term=s.d[0].copy())
