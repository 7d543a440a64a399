"""Main-board robot velocity controller, paper Sec. 4.1 / Fig. 2.

    desired twist (robot frame, from the AI over radio)
        -> setpoint shaper (speed and acceleration limits that keep the direction of motion)
        -> PID on the twist error, measured twist = forward kinematics of the measured wheel speeds
        -> command twist = [shaped setpoint as feedforward, switchable] + PID output
        -> inverse kinematics -> wheel speed setpoints for the motor boards (Fig. 3).

`feedforward_enabled=False` is the paper's current design (the PID alone produces the
commanded velocity, so it needs its integral); `True` is the paper's "next step": the
shaped setpoint is passed through and the PID only corrects.
The shaper and the loop are written once, as compiled kernels on the rows (robots) of (robots, ...)
arrays (``shape_step``, ``velocity_step``): ``SetpointShaper`` and ``VelocityController`` hold the state
of ``n_robots`` robots, and firmware.py's loops call the same kernels for one robot or a team.

Two guards keep the loop honest on a plant with bounded traction (measured on the
erforce_sim plant, test/sim/test_motion_on_sim*.py):

* traction limit in the shaper: with identical, gripping wheel loops the wheel forces are
  the minimum-norm solution f = pinv(D) [m a_x, m a_y, I alpha] (D the 3 x n wrench of unit
  wheel forces), so the shaper limits every step such that max |f_i| <= fraction * mu m g / n.
  For the default 60/135/225/300 deg layout that is 5.7 m/s^2 forward but only 4.0 m/s^2 along
  (2, 1): a single 6 m/s^2 limit over-drives two wheels, they slip and the robot yaws.
* slip hold: while the measured wheel speeds contain a slip residual (the part no rigid
  twist explains, `OmniKinematics.slip_residual`) above a threshold, the forward kinematics is
  not the body's motion, so the twist integrator is held.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from erforce_interfaces.runtime.numba_support import compiled_for, numba
from erforce_interfaces.runtime.param_schema import schema_defaults
from erforce_interfaces.wire.robot_config import GRAVITY_MPS2, RobotConfig
from erforce_motion.kinematics import OmniKinematics
from erforce_motion.pid import DEFAULT_ANTI_WINDUP, AntiWindup, PidConfig, PidState, pid_reset, pid_step, pid_tables

_DEFAULTS = schema_defaults("erforce_motion", "velocity_controller")


@dataclass(frozen=True)
class VelocityControlConfig:
    """Limits and gains of the main-board loop.

    Defaults (tuned on the erforce_sim plant through InProcessRunner, 1 kHz, default motor
    boards; bench/bench_motion.py): feedforward on, PI kp 0.3, ki 5/s per axis: the feedforward
    does the work, the PI only corrects. The P path runs through the motor boards with one
    extra loop period of delay (the setpoint is used one tick later), so (1 + kp) * motor kp is
    the loop gain on the wheel inertia; when wheels lose traction (slipping, or robot lifted)
    that inertia drops ~3.5x and kp >= ~0.65 with the default motor boards limit-cycles at
    +-9 A (the "wheel fight"); kp 0.3 keeps a ~2x margin. Pass the motor boards' saturation
    flags to `step` (wheels_saturated) where they are available, or the integrator winds up
    while the wheels are current-limited. `pid_only()` is the feedforward-free design with
    kp 1, ki 20/s (its loop gain is kp * motor kp, same margin argument).
    traction_limit_fraction: wheel force limit of the shaper as a fraction of mu m g / n
    (None: no traction limit, only max_accel_mps2). slip_hold_threshold_radps: slip residual
    norm [rad/s of wheel speed] above which the integrator is held (None: never).
    """

    max_speed_mps: float = _DEFAULTS["max_speed_mps"]
    max_accel_mps2: float = _DEFAULTS["max_accel_mps2"]  # below the traction limit mu*g ~ 7.8 m/s^2
    max_angular_speed_radps: float = _DEFAULTS["max_angular_speed_radps"]
    max_angular_accel_radps2: float = _DEFAULTS["max_angular_accel_radps2"]
    feedforward_enabled: bool = _DEFAULTS["feedforward_enabled"]
    kp_translation: float = _DEFAULTS["kp_translation"]  # (m/s) per (m/s)
    ki_translation: float = _DEFAULTS["ki_translation"]  # 1/s
    kd_translation: float = _DEFAULTS["kd_translation"]
    kp_rotation: float = _DEFAULTS["kp_rotation"]
    ki_rotation: float = _DEFAULTS["ki_rotation"]
    kd_rotation: float = _DEFAULTS["kd_rotation"]
    derivative_filter_tau_s: float = _DEFAULTS["derivative_filter_tau_s"]
    command_limit_mps: float = _DEFAULTS["command_limit_mps"]  # PID output (incl. feedforward) per axis
    command_limit_radps: float = _DEFAULTS["command_limit_radps"]
    anti_windup: AntiWindup = DEFAULT_ANTI_WINDUP
    # integrator bound per linear axis while feedforward is on
    ff_integrator_limit_mps: float = _DEFAULTS["ff_integrator_limit_mps"]
    ff_integrator_limit_radps: float = _DEFAULTS["ff_integrator_limit_radps"]
    traction_limit_fraction: float | None = _DEFAULTS["traction_limit_fraction"]
    slip_hold_threshold_radps: float | None = _DEFAULTS["slip_hold_threshold_radps"]

    def __post_init__(self) -> None:
        for name in (
            "max_speed_mps", "max_accel_mps2", "max_angular_speed_radps", "max_angular_accel_radps2",
            "kp_translation", "kp_rotation", "command_limit_mps", "command_limit_radps",
            "ff_integrator_limit_mps", "ff_integrator_limit_radps",
        ):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0.0):
                raise ValueError(f"{name}: must be finite and > 0, got {v!r}")
        for name in (
            "ki_translation", "kd_translation", "ki_rotation", "kd_rotation", "derivative_filter_tau_s",
        ):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0.0):
                raise ValueError(f"{name}: must be finite and >= 0, got {v!r}")
        for name in ("traction_limit_fraction", "slip_hold_threshold_radps"):
            v = getattr(self, name)
            if v is not None and not (isinstance(v, int | float) and math.isfinite(v) and v > 0.0):
                raise ValueError(f"{name}: must be None or finite and > 0, got {v!r}")
        if not isinstance(self.feedforward_enabled, bool):
            raise ValueError("feedforward_enabled: must be a bool")
        self.pid_config()  # the PID's own checks (anti-windup mode, limits), in one place: pid.py

    @classmethod
    def pid_only(cls, **overrides) -> VelocityControlConfig:
        """The paper's current design (no feedforward) with PI gains tuned for it on the sim plant."""
        values = {"feedforward_enabled": False, "kp_translation": 1.0, "ki_translation": 20.0,
                  "kp_rotation": 1.0, "ki_rotation": 20.0}
        values.update(overrides)
        return cls(**values)

    def pid_config(self) -> PidConfig:
        lim = (self.command_limit_mps, self.command_limit_mps, self.command_limit_radps)
        # With feedforward the integrator only corrects model error; bounding it keeps an outage
        # of the motor boards (wheels not following at all) from winding it up into a lurch.
        i_lim = (self.ff_integrator_limit_mps, self.ff_integrator_limit_mps, self.ff_integrator_limit_radps) \
            if self.feedforward_enabled else lim
        return PidConfig(
            integrator_min=tuple(-x for x in i_lim),
            integrator_max=i_lim,
            kp=(self.kp_translation, self.kp_translation, self.kp_rotation),
            ki=(self.ki_translation, self.ki_translation, self.ki_rotation),
            kd=(self.kd_translation, self.kd_translation, self.kd_rotation),
            output_min=tuple(-x for x in lim),
            output_max=lim,
            anti_windup=self.anti_windup,
            derivative_filter_tau_s=self.derivative_filter_tau_s,
            n_channels=3,
        )


class SetpointShaper:
    """Speed and acceleration limits on a twist that keep the direction of translation.

    The translational part is limited as a 2-vector: a too fast command is scaled as a
    whole, and the change per step is limited in magnitude (|dv| <= a_max dt), so the
    shaped velocity moves along a straight line toward the target, never per axis.
    The rotation is limited separately. With a robot and config.traction_limit_fraction,
    the whole step (translation and rotation together, so the direction in twist space is
    kept) is then scaled down until no wheel's minimum-norm traction force exceeds the
    fraction of mu m g / n (see the module docstring). Centripetal forces of a robot that
    turns while translating are not included: they need no change of the body-frame setpoint.
    ``twist`` holds the shaped twist of ``n_robots`` robots; ``step``, ``state`` and ``reset`` act on robot 0.
    """

    def __init__(self, config: VelocityControlConfig, robot: RobotConfig | None = None, n_robots: int = 1) -> None:
        self.twist = np.zeros((n_robots, 3))
        use_force = robot is not None and config.traction_limit_fraction is not None
        self.force_rows = np.ascontiguousarray(wheel_force_per_accel(robot)) if use_force else np.zeros((0, 3))
        self.wheel_force_limit_n = (config.traction_limit_fraction * robot.traction_mu * robot.mass_kg
                                    * GRAVITY_MPS2 / robot.num_wheels) if use_force else math.inf
        self.params = (float(config.max_speed_mps), float(config.max_accel_mps2),
                       float(config.max_angular_speed_radps), float(config.max_angular_accel_radps2),
                       float(self.wheel_force_limit_n))
        self._row, self._target, self._dt = np.zeros(1, dtype=np.int64), np.zeros((1, 3)), np.zeros(1)
        self._step = compiled_for(shape_step, self._row, self.params, self.force_rows, self.twist, self._target,
                                  self._dt)

    @property
    def state(self) -> tuple[float, float, float]:
        return tuple(self.twist[0].tolist())

    def reset(self, twist=(0.0, 0.0, 0.0)) -> None:
        vx, vy, wz = (float(v) for v in twist)
        if not all(math.isfinite(v) for v in (vx, vy, wz)):
            raise ValueError("reset twist must be finite")
        self.twist[0] = (vx, vy, wz)

    def step(self, vx: float, vy: float, wz: float, dt_s: float) -> tuple[float, float, float]:
        self._target[0] = (vx, vy, wz)
        self._dt[0] = dt_s
        self._step(self._row, self.params, self.force_rows, self.twist, self._target, self._dt)
        return self.state


@numba.njit(cache=True, error_model="numpy")
def shape_step(rows, prm, force_rows, twist, target, dt):
    """SetpointShaper's step for each robot k in rows: moves twist[k] toward target[k] (vx, vy, wz) within the
    limits prm, in dt[k]."""
    for k in rows:
        _shape_row(k, prm, force_rows, twist, target[k, 0], target[k, 1], target[k, 2], dt[k])


@numba.njit(cache=True, error_model="numpy")
def _shape_row(k, prm, force_rows, twist, vx, vy, wz, dt):
    v_max, a_max, w_max, aw_max, f_lim = prm
    speed = math.hypot(vx, vy)
    if speed > v_max:
        vx *= v_max / speed
        vy *= v_max / speed
    dx, dy = vx - twist[k, 0], vy - twist[k, 1]
    dv = math.hypot(dx, dy)
    if dv > a_max * dt:
        f = a_max * dt / dv
        dx *= f
        dy *= f
    wz = min(max(wz, -w_max), w_max)
    dw = min(max(wz - twist[k, 2], -aw_max * dt), aw_max * dt)
    if force_rows.shape[0]:
        peak = 0.0
        for i in range(force_rows.shape[0]):
            peak = max(peak, abs(force_rows[i, 0] * dx + force_rows[i, 1] * dy + force_rows[i, 2] * dw))
        peak = peak / dt
        if peak > f_lim:
            f = f_lim / peak
            dx *= f
            dy *= f
            dw *= f
    twist[k, 0] += dx
    twist[k, 1] += dy
    twist[k, 2] += dw


def wheel_force_per_accel(robot: RobotConfig) -> np.ndarray:
    """n x 3 matrix: minimum-norm wheel traction forces [N] per body acceleration (ax, ay [m/s^2], alpha [rad/s^2]).

    Wheel i pushes with force f_i along its drive direction (-sin a_i, cos a_i) at lever arm R,
    so the body wrench is D f with D = [[-sin a], [cos a], [R]] (3 x n); identical gripping wheel
    loops produce the force pattern in the range of D^T, i.e. f = pinv(D) diag(m, m, I) accel.
    """
    th = np.asarray(robot.wheel_angles_rad)
    d = np.vstack([-np.sin(th), np.cos(th), np.full_like(th, robot.wheel_distance_m)])
    return np.linalg.pinv(d) @ np.diag([robot.mass_kg, robot.mass_kg, robot.inertia_kgm2])


@dataclass(frozen=True)
class VelocityControlStatus:
    shaped_twist: np.ndarray
    measured_twist: np.ndarray
    command_twist: np.ndarray
    saturated: np.ndarray  # per twist axis
    slip_residual_radps: float  # norm of the wheel-speed part no rigid twist explains
    integrator_held: bool  # by wheels_saturated or by the slip hold


class VelocityController:
    """Fig. 2: desired robot twist + measured wheel speeds -> wheel speed setpoints [rad/s].

    Holds the state of ``n_robots`` robots (rows of ``measured_twist``, ``shaped_twist``,
    ``command_twist`` ...) for ``velocity_step``; ``step``, ``reset`` and ``status`` act on robot 0.
    """

    def __init__(self, robot: RobotConfig | None = None, config: VelocityControlConfig | None = None,
                 n_robots: int = 1) -> None:
        self.robot = robot = robot if robot is not None else RobotConfig()
        self.config = c = config if config is not None else VelocityControlConfig()
        top_mps = robot.top_wheel_speed_mps
        if c.max_speed_mps > top_mps:
            raise ValueError(
                f"max_speed_mps {c.max_speed_mps:g} m/s is out of the motors' reach with this robot: "
                f"they turn a wheel at most {robot.wheel_no_load_speed_radps:.4g} rad/s, its rim "
                f"(robot.wheel_radius_m {robot.wheel_radius_m:g} m) at {top_mps:.3g} m/s")
        self.kinematics = kin = OmniKinematics.from_robot_config(robot)
        self._n = kin.num_wheels
        self.shaper = SetpointShaper(c, robot, n_robots)
        self.pid_state = PidState(n_robots, 3)
        self.twists = np.zeros((3, n_robots, 3))  # one array: each array a kernel call is passed costs it an unpacking
        self.measured_twist, self.shaped_twist, self.command_twist = self.twists  # command: PID output incl. ff
        self.integrator_held = np.zeros(n_robots, dtype=np.bool_)
        self.slip_residual_radps = np.zeros(n_robots)
        prm, flags = pid_tables(c.pid_config())
        use_slip = c.slip_hold_threshold_radps is not None
        loop = (c.feedforward_enabled, float(c.slip_hold_threshold_radps or 0.0), use_slip)
        matrices = tuple(np.ascontiguousarray(m) for m in (kin.wheel_matrix, kin.forward_matrix, kin.slip_projector))
        state = (self.shaper.twist, self.pid_state.arrays(), self.twists, self.integrator_held,
                 self.slip_residual_radps)
        # per robot: the PID's output limits and feedforward, then its integrator hold; a twist for the reset
        pid_inputs = np.zeros((3, n_robots, 3))
        pid_inputs[0], pid_inputs[1] = prm[3], prm[4]
        work = (pid_inputs, np.zeros((n_robots, 3), dtype=np.bool_), np.zeros(3))
        self.args = (matrices, self.shaper.params, self.shaper.force_rows, loop, prm, flags, state, work)
        self._row, self._desired, self._dt = np.zeros(1, dtype=np.int64), np.zeros((1, 3)), np.zeros(1)
        self._hold = np.zeros(1, dtype=np.bool_)
        wheels = np.zeros((1, self._n))
        self._step = compiled_for(velocity_step, self._row, self.args, self._desired, wheels, self._dt, self._hold,
                                  wheels)
        self._reset = compiled_for(velocity_reset, 0, self.args, np.zeros(self._n))

    @property
    def max_setpoint_radps(self) -> float:
        """The largest wheel speed setpoint ``step`` can return: the PID output limits through the wheel matrix."""
        limits = np.array([self.config.command_limit_mps, self.config.command_limit_mps,
                           self.config.command_limit_radps])
        return float((np.abs(self.kinematics.wheel_matrix) @ limits).max())

    def step(self, desired_twist, measured_wheel_speeds_radps, dt_s: float, wheels_saturated=False) -> np.ndarray:
        """One control period; returns the wheel speed setpoints [rad/s] (new array, length n).

        wheels_saturated (bool or per-wheel flags from the motor boards' status) holds the
        twist integrator while any wheel cannot follow, so the outer loop does not wind up.
        """
        if not (0.0 < dt_s < math.inf):
            raise ValueError(f"dt_s: must be finite and > 0, got {dt_s!r}")
        if len(desired_twist) != 3:
            raise ValueError(f"desired_twist: need 3 values (vx, vy, wz), got {len(desired_twist)}")
        vx, vy, wz = float(desired_twist[0]), float(desired_twist[1]), float(desired_twist[2])
        if not math.isfinite(vx + vy + wz):
            raise ValueError(f"desired_twist: must be finite, got {tuple(desired_twist)!r}")
        w = np.ascontiguousarray(measured_wheel_speeds_radps, dtype=float)
        if w.shape != (self._n,):
            raise ValueError(f"measured_wheel_speeds_radps: need {self._n} values, got shape {w.shape}")
        if not np.isfinite(w).all():
            raise ValueError(f"measured_wheel_speeds_radps: must be finite, got {w!r}")
        out = np.empty((1, self._n))
        self._desired[0] = (vx, vy, wz)
        self._dt[0] = dt_s
        self._hold[0] = np.any(wheels_saturated)
        self._step(self._row, self.args, self._desired, w[None], self._dt, self._hold, out)
        return out[0]

    def reset(self, measured_wheel_speeds_radps=None) -> None:
        """Bumpless (re)start from the measured motion (or from rest when None)."""
        w = np.zeros(self._n) if measured_wheel_speeds_radps is None else np.ascontiguousarray(
            measured_wheel_speeds_radps, dtype=float)
        if w.shape != (self._n,) or not np.isfinite(w).all():
            raise ValueError(f"measured_wheel_speeds_radps: need {self._n} finite values, got {w!r}")
        self._reset(0, self.args, w)

    @property
    def status(self) -> VelocityControlStatus:
        s = self.pid_state
        return VelocityControlStatus(
            shaped_twist=self.shaped_twist[0].copy(),
            measured_twist=self.measured_twist[0].copy(),
            command_twist=self.command_twist[0].copy(),
            saturated=s.v[0] != s.u[0],
            slip_residual_radps=float(self.slip_residual_radps[0]),
            integrator_held=bool(self.integrator_held[0]),
        )


@numba.njit(cache=True, error_model="numpy")
def velocity_step(rows, args, desired, w, dt, hold, setpoints):
    """VelocityController's step for each robot k in rows: desired twist[k] and wheel speeds w[k] ->
    setpoints[k] [rad/s], in dt[k].

    hold[k] freezes the twist integrator (the motor boards are saturated); the slip hold adds to it."""
    (jac, fwd, slip_proj), shaper_prm, force_rows, (ff_on, slip_thr, use_slip), prm, flags, state, work = args
    shaper, pid, twists, held, slip = state
    measured, shaped, command = twists[0], twists[1], twists[2]
    (pid_inputs, hold_pid) = work[0], work[1]
    lo, hi, ff = pid_inputs[0], pid_inputs[1], pid_inputs[2]
    n = w.shape[1]
    for k in rows:
        for a in range(3):
            s = 0.0
            for i in range(n):
                s += fwd[a, i] * w[k, i]
            measured[k, a] = s
    shape_step(rows, shaper_prm, force_rows, shaper, desired, dt)
    for k in rows:
        hold_k = hold[k]
        if use_slip:  # slipping wheels: forward kinematics is not the body's motion, do not integrate it
            sq = 0.0
            for i in range(n):
                r = 0.0
                for j in range(n):
                    r += slip_proj[i, j] * w[k, j]
                sq += r * r
            slip[k] = math.sqrt(sq)
            hold_k = hold_k or slip[k] > slip_thr
        held[k] = hold_k
        for a in range(3):
            shaped[k, a] = shaper[k, a]
            ff[k, a] = shaper[k, a] if ff_on else 0.0
            hold_pid[k, a] = hold_k
    pid_step(rows, prm, flags, pid, shaped, measured, dt, ff, lo, hi, hold_pid, command)
    for k in rows:
        for i in range(n):
            s = 0.0
            for a in range(3):
                s += jac[i, a] * command[k, a]
            setpoints[k, i] = s


@numba.njit(cache=True, error_model="numpy")
def velocity_reset(k, args, w):
    """VelocityController's bumpless restart of robot k from the motion of the wheel speeds w."""
    _, fwd, _ = args[0]
    ff_on, prm, flags = args[3][0], args[4], args[5]
    shaper, pid, twists = args[6][:3]
    ff, twist = args[7][0][2][k], args[7][2]
    for a in range(3):
        s = 0.0
        for i in range(w.shape[0]):
            s += fwd[a, i] * w[i]
        twist[a] = s
        ff[a] = s if ff_on else 0.0
        shaper[k, a] = twists[0, k, a] = twists[1, k, a] = twists[2, k, a] = s
    pid_reset(k, prm, flags, pid, twist, ff, twist, twist, True, True)
