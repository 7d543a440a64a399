"""Ziegler-Nichols PID tuning from a measured step or impulse response, paper Sec. 4.2 / Fig. 4.

Procedure (as in the paper): excite the uncontrolled system (an impulse, or a step),
turn an impulse response into a step response by integrating it, fit a PT2

    G(s) = K e^{-Td s} / ((1 + T1 s)(1 + T2 s)),   step response
    y(t) = K [1 - (T1 e^{-t'/T1} - T2 e^{-t'/T2}) / (T1 - T2)],  t' = t - Td >= 0

(scipy least squares), draw the tangent at the inflection point
t_w = Td + T1 T2 ln(T1/T2) / (T1 - T2), and read off the delay time Tu (tangent meets 0)
and the balance time Tg (tangent rises from 0 to K). Gains follow from tables in the
parallel form u = kp e + ki int(e) + kd de/dt (ki = kp/Tn, kd = kp*Tv):

  Ziegler-Nichols, reaction-curve (tangent) rules:
      P:   kp = Tg/(K Tu)
      PI:  kp = 0.9 Tg/(K Tu),  Tn = 3.33 Tu
      PID: kp = 1.2 Tg/(K Tu),  Tn = 2 Tu,     Tv = 0.5 Tu
  Chien-Hrones-Reswick (1952), setpoint ("Fuehrung") table, for Tg/Tu > 3:
      0 % overshoot (aperiodic):   P 0.3;  PI 0.35, Tn = 1.2 Tg;  PID 0.6,  Tn = Tg,      Tv = 0.5 Tu
      20 % overshoot:              P 0.7;  PI 0.6,  Tn = Tg;      PID 0.95, Tn = 1.35 Tg, Tv = 0.47 Tu
      (factors multiply Tg/(K Tu))

`run_tuning_experiment` takes any callable that returns a measured response, so the
simulator package can plug in its plant; by default it measures the in-core
plant_model wheel: desired current step through the paper's linear actuator
(duty = (R/V) i) to wheel speed, i.e. the plant of the speed loop before closing it.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml
from scipy.optimize import least_squares

from erforce_interfaces.wire.robot_config import RobotConfig
from erforce_motion.plant_model import WheelPlant

RULES = ("zn", "chr_0", "chr_20")
_TABLES = {
    # rule: {structure: (kp factor on Tg/(K Tu), Tn as (coef, "Tu"|"Tg") or None, Tv coef on Tu or None)}
    "zn": {"P": (1.0, None, None), "PI": (0.9, (3.33, "Tu"), None), "PID": (1.2, (2.0, "Tu"), 0.5)},
    "chr_0": {"P": (0.3, None, None), "PI": (0.35, (1.2, "Tg"), None), "PID": (0.6, (1.0, "Tg"), 0.5)},
    "chr_20": {"P": (0.7, None, None), "PI": (0.6, (1.0, "Tg"), None), "PID": (0.95, (1.35, "Tg"), 0.47)},
}


def pt2_step(t, gain: float, t1_s: float, t2_s: float, dead_time_s: float = 0.0) -> np.ndarray:
    """Unit-input step response of K e^{-Td s}/((1+T1 s)(1+T2 s)); handles T1 == T2."""
    t = np.asarray(t, dtype=float)
    tp = np.maximum(t - dead_time_s, 0.0)
    if abs(t1_s - t2_s) <= 1e-9 * max(t1_s, t2_s):
        tau = 0.5 * (t1_s + t2_s)
        return gain * (1.0 - (1.0 + tp / tau) * np.exp(-tp / tau))
    return gain * (1.0 - (t1_s * np.exp(-tp / t1_s) - t2_s * np.exp(-tp / t2_s)) / (t1_s - t2_s))


@dataclass(frozen=True)
class Pt2Fit:
    gain: float
    t1_s: float  # the larger time constant
    t2_s: float
    dead_time_s: float
    rmse: float

    def step(self, t) -> np.ndarray:
        return pt2_step(t, self.gain, self.t1_s, self.t2_s, self.dead_time_s)


@dataclass(frozen=True)
class TangentTimes:
    """Inflection point (t_w, y_w), tangent slope, delay time Tu and balance time Tg."""

    t_inflection_s: float
    y_inflection: float
    slope_per_s: float
    delay_time_tu_s: float
    balance_time_tg_s: float
    gain: float


def impulse_to_step(t, y, impulse_area: float = 1.0) -> np.ndarray:
    """Step response from an impulse response: cumulative trapezoid integral / impulse area."""
    t = np.asarray(t, dtype=float)
    y = np.asarray(y, dtype=float)
    _check_series(t, y)
    if not (math.isfinite(impulse_area) and impulse_area != 0.0):
        raise ValueError(f"impulse_area: must be finite and non-zero, got {impulse_area!r}")
    out = np.zeros_like(y)
    out[1:] = np.cumsum(0.5 * (y[1:] + y[:-1]) * np.diff(t))
    return out / impulse_area


def _check_series(t: np.ndarray, y: np.ndarray) -> None:
    if t.ndim != 1 or t.shape != y.shape or t.size < 5:
        raise ValueError(f"need 1-D t and y of equal length >= 5, got shapes {t.shape} and {y.shape}")
    if not (np.isfinite(t).all() and np.isfinite(y).all()):
        raise ValueError("t and y must be finite")
    if not (np.diff(t) > 0.0).all():
        raise ValueError("t must be strictly increasing")


def fit_pt2(t, y, with_dead_time: bool = False, input_amplitude: float = 1.0) -> Pt2Fit:
    """Least-squares PT2 (optionally with dead time) through a step response to a step of `input_amplitude`."""
    t = np.asarray(t, dtype=float)
    y = np.asarray(y, dtype=float)
    _check_series(t, y)
    if not (math.isfinite(input_amplitude) and input_amplitude != 0.0):
        raise ValueError(f"input_amplitude: must be finite and non-zero, got {input_amplitude!r}")
    y = y / input_amplitude
    t = t - t[0]
    k0 = float(np.mean(y[-max(3, len(y) // 20):]))
    if k0 == 0.0:
        raise ValueError("response has no final value: cannot fit a PT2")
    # sum of time constants = area between final value and the normalised response
    resid_area = np.sum(0.5 * ((1 - y[1:] / k0) + (1 - y[:-1] / k0)) * np.diff(t))
    t_sum = float(np.clip(resid_area, 1e-6 * t[-1], t[-1]))
    span = t[-1]

    def model(p):
        k, t1, t2 = p[0], p[1], p[2]
        td = p[3] if with_dead_time else 0.0
        return pt2_step(t, k, t1, t2, td)

    best = None
    for frac in (0.9, 0.7, 0.5):  # a few starts: the PT2 cost has a ridge along T1 <-> T2
        x0 = [k0, frac * t_sum, max((1 - frac) * t_sum, 1e-6 * span)]
        lo = [-np.inf, 1e-9 * span, 1e-9 * span]
        hi = [np.inf, 10 * span, 10 * span]
        if with_dead_time:
            x0.append(0.01 * span)
            lo.append(0.0)
            hi.append(0.5 * span)
        res = least_squares(lambda p: model(p) - y, x0, bounds=(lo, hi), x_scale="jac")
        if best is None or res.cost < best.cost:
            best = res
    k, t1, t2 = best.x[:3]
    td = float(best.x[3]) if with_dead_time else 0.0
    t1, t2 = max(t1, t2), min(t1, t2)
    rmse = float(np.sqrt(np.mean(best.fun**2))) * abs(input_amplitude)
    return Pt2Fit(gain=float(k), t1_s=float(t1), t2_s=float(t2), dead_time_s=td, rmse=rmse)


def pt2_tangent_times(gain: float, t1_s: float, t2_s: float, dead_time_s: float = 0.0) -> TangentTimes:
    """Closed-form inflection tangent of a PT2 step response."""
    for name, v in (("t1_s", t1_s), ("t2_s", t2_s)):
        if not (math.isfinite(v) and v > 0.0):
            raise ValueError(f"{name}: must be finite and > 0, got {v!r}")
    if not (math.isfinite(gain) and gain != 0.0 and math.isfinite(dead_time_s) and dead_time_s >= 0.0):
        raise ValueError("gain must be finite and non-zero, dead_time_s finite and >= 0")
    if abs(t1_s - t2_s) <= 1e-9 * max(t1_s, t2_s):
        tau = 0.5 * (t1_s + t2_s)
        tw = tau
        slope = gain * tw / tau**2 * math.exp(-tw / tau)
    else:
        tw = t1_s * t2_s * math.log(t1_s / t2_s) / (t1_s - t2_s)
        slope = gain * (math.exp(-tw / t1_s) - math.exp(-tw / t2_s)) / (t1_s - t2_s)
    yw = float(pt2_step(tw, gain, t1_s, t2_s))
    tu = tw - yw / slope + dead_time_s
    return TangentTimes(tw + dead_time_s, yw, slope, tu, gain / slope, gain)


def tangent_times_from_samples(t, y, gain: float | None = None) -> TangentTimes:
    """Inflection tangent read from sampled data (steepest slope, by central differences)."""
    t = np.asarray(t, dtype=float)
    y = np.asarray(y, dtype=float)
    _check_series(t, y)
    k = float(np.mean(y[-max(3, len(y) // 20):])) if gain is None else float(gain)
    dy = np.gradient(y, t)
    i = int(np.argmax(dy * np.sign(k)))
    slope = float(dy[i])
    if slope == 0.0:
        raise ValueError("response has no slope")
    tu = t[i] - y[i] / slope
    return TangentTimes(float(t[i]), float(y[i]), slope, float(tu), k / slope, k)


@dataclass(frozen=True)
class PidGains:
    kp: float
    ki: float
    kd: float
    rule: str
    structure: str


def rule_gains(times: TangentTimes, rule: str = "zn", structure: str = "PID") -> PidGains:
    """P/PI/PID gains (parallel form) from (K, Tu, Tg) by the tables in the module docstring."""
    if rule not in _TABLES:
        raise ValueError(f"rule: one of {RULES}, got {rule!r}")
    if structure not in ("P", "PI", "PID"):
        raise ValueError(f"structure: 'P', 'PI' or 'PID', got {structure!r}")
    tu, tg, k = times.delay_time_tu_s, times.balance_time_tg_s, times.gain
    if not (tu > 0.0 and tg > 0.0 and math.isfinite(tu) and math.isfinite(tg) and k != 0.0):
        raise ValueError(f"need Tu > 0, Tg > 0 and K != 0, got Tu={tu}, Tg={tg}, K={k}")
    factor, tn, tv = _TABLES[rule][structure]
    kp = factor * tg / (k * tu)
    ki = 0.0 if tn is None else kp / (tn[0] * (tu if tn[1] == "Tu" else tg))
    kd = 0.0 if tv is None else kp * tv * tu
    return PidGains(kp=kp, ki=ki, kd=kd, rule=rule, structure=structure)


def all_rule_gains(times: TangentTimes) -> dict[str, dict[str, PidGains]]:
    return {rule: {s: rule_gains(times, rule, s) for s in ("P", "PI", "PID")} for rule in RULES}


def write_gains_yaml(path: str | Path, node_name: str, parameters: dict[str, float]) -> Path:
    """Write a ROS 2 parameter file `<node_name>:\\n  ros__parameters:\\n    key: value`."""
    if not node_name or any(c in node_name for c in " :\n"):
        raise ValueError(f"node_name: not a valid node name: {node_name!r}")
    clean = {}
    for key, value in parameters.items():
        v = float(value)
        if not math.isfinite(v):
            raise ValueError(f"parameter {key}: must be finite, got {value!r}")
        clean[str(key)] = v
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(yaml.safe_dump({node_name: {"ros__parameters": clean}}, sort_keys=False))
    return path


@dataclass(frozen=True)
class TuningResult:
    t_s: np.ndarray
    step_response: np.ndarray  # normalised per unit input
    raw_response: np.ndarray  # as measured (step or impulse)
    response_kind: str
    fit: Pt2Fit
    times: TangentTimes
    gains: dict[str, dict[str, PidGains]] = field(repr=False)


def default_plant_response(dt_s: float, duration_s: float, amplitude: float = 2.0,
                           robot: RobotConfig | None = None,
                           loop_delay_periods: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """In-core wheel: desired-current step [A] through the linear actuator duty = (R/V) i -> wheel speed [rad/s].

    Sampled as the loop sees it: commanded at t=0, applied `loop_delay_periods` loop periods
    later (the board computes a duty from one sample and applies it until the next), so the
    fitted dead time carries the sampling delay that the continuous plant lacks.
    """
    robot = robot if robot is not None else RobotConfig()
    plant = WheelPlant(robot, n_wheels=1)
    duty = np.array([amplitude * robot.motor_resistance_ohm / robot.supply_voltage_v])
    n = round(duration_s / dt_s)
    t = np.arange(n + 1) * dt_s
    y = np.zeros(n + 1)
    for k in range(n):
        w, _ = plant.step(duty if k >= loop_delay_periods else 0.0 * duty, dt_s)
        y[k + 1] = w[0]
    return t, y


def run_tuning_experiment(
    plant_step_fn: Callable[[float, float], tuple[np.ndarray, np.ndarray]] | None = None,
    *,
    dt_s: float = 0.001,
    duration_s: float = 0.4,
    input_amplitude: float = 2.0,
    response_kind: str = "step",
    with_dead_time: bool = True,
) -> TuningResult:
    """Measure, fit, read the tangent and apply every rule.

    plant_step_fn(dt_s, duration_s) -> (t, y) is the measured response of the uncontrolled
    system to a step of `input_amplitude` (response_kind 'step') or to an impulse of area
    `input_amplitude` ('impulse'). None uses `default_plant_response`.
    """
    if response_kind not in ("step", "impulse"):
        raise ValueError(f"response_kind: 'step' or 'impulse', got {response_kind!r}")
    if plant_step_fn is None:
        def plant_step_fn(dt, dur):
            return default_plant_response(dt, dur, amplitude=input_amplitude)
    t, raw = plant_step_fn(dt_s, duration_s)
    t = np.asarray(t, dtype=float)
    raw = np.asarray(raw, dtype=float)
    _check_series(t, raw)
    if response_kind == "impulse":
        step = impulse_to_step(t, raw, impulse_area=input_amplitude)
    else:
        step = raw / input_amplitude
    fit = fit_pt2(t, step, with_dead_time=with_dead_time)
    times = pt2_tangent_times(fit.gain, fit.t1_s, fit.t2_s, fit.dead_time_s)
    return TuningResult(t, step, raw, response_kind, fit, times, all_rule_gains(times))


def plot_tuning(result: TuningResult, path: str | Path, title: str = "PT2 fit and inflection tangent") -> Path:
    """PNG like the paper's Fig. 4: measured response, fitted PT2, tangent, Tu and Tg marked."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = result.t_s - result.t_s[0]
    tt = result.times
    fig, ax = plt.subplots(figsize=(7, 4.2))
    ax.plot(t, result.step_response, ".", ms=3, color="0.5", label="measured (step, per unit input)")
    tf = np.linspace(0.0, t[-1], 800)
    ax.plot(tf, result.fit.step(tf), "b-", lw=1.5,
            label=f"PT2 fit K={result.fit.gain:.3g}, T1={result.fit.t1_s * 1e3:.3g} ms, "
                  f"T2={result.fit.t2_s * 1e3:.3g} ms")
    t_end = tt.delay_time_tu_s + tt.balance_time_tg_s
    ax.plot([tt.delay_time_tu_s, t_end], [0.0, tt.gain], "r--", lw=1.2, label="inflection tangent")
    ax.plot([tt.t_inflection_s], [tt.y_inflection], "ro")
    ax.axhline(tt.gain, color="k", lw=0.6)
    ax.axhline(0.0, color="k", lw=0.6)
    ax.annotate("", xy=(tt.delay_time_tu_s, 0.04 * tt.gain), xytext=(0.0, 0.04 * tt.gain),
                arrowprops={"arrowstyle": "<->", "color": "g"})
    ax.text(0.5 * tt.delay_time_tu_s, 0.07 * tt.gain, f"Tu={tt.delay_time_tu_s * 1e3:.3g} ms", color="g",
            ha="center")
    ax.annotate("", xy=(t_end, 0.92 * tt.gain), xytext=(tt.delay_time_tu_s, 0.92 * tt.gain),
                arrowprops={"arrowstyle": "<->", "color": "m"})
    ax.text(tt.delay_time_tu_s + 0.5 * tt.balance_time_tg_s, 0.85 * tt.gain,
            f"Tg={tt.balance_time_tg_s * 1e3:.3g} ms", color="m", ha="center")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("output per unit input")
    ax.set_title(title)
    ax.legend(loc="lower right", fontsize=8)
    ax.grid(True, alpha=0.3)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
