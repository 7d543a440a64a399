"""Main-board robot velocity controller, paper Sec. 4.1 / Fig. 2.

    desired twist (robot frame, from the AI over radio)
        -> setpoint shaper (speed and acceleration limits that keep the direction of motion)
        -> PID on the twist error, measured twist = forward kinematics of the measured wheel speeds
        -> command twist = [shaped setpoint as feedforward, switchable] + PID output
        -> inverse kinematics -> wheel speed setpoints for the motor boards (Fig. 3).

`feedforward_enabled=False` is the paper's current design (the PID alone produces the
commanded velocity, so it needs its integral); `True` is the paper's "next step": the
shaped setpoint is passed through and the PID only corrects.
`CommandWatchdog` is the pure logic that stops the robot when commands stop arriving.

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

from erforce_interfaces.wire.robot_config import RobotConfig
from erforce_motion.kinematics import OmniKinematics
from erforce_motion.pid import AntiWindup, Pid, PidConfig

GRAVITY_MPS2 = 9.81


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

    max_speed_mps: float = 4.0
    max_accel_mps2: float = 6.0  # below the traction limit mu*g ~ 7.8 m/s^2
    max_angular_speed_radps: float = 10.0
    max_angular_accel_radps2: float = 60.0
    feedforward_enabled: bool = True
    kp_translation: float = 0.3  # (m/s) per (m/s)
    ki_translation: float = 5.0  # 1/s
    kd_translation: float = 0.0
    kp_rotation: float = 0.3
    ki_rotation: float = 5.0
    kd_rotation: float = 0.0
    derivative_filter_tau_s: float = 0.005
    command_limit_mps: float = 5.0  # PID output (incl. feedforward) per axis
    command_limit_radps: float = 15.0
    anti_windup: AntiWindup = "clamp"
    ff_integrator_limit_mps: float = 0.3  # integrator bound per linear axis while feedforward is on
    ff_integrator_limit_radps: float = 0.3
    traction_limit_fraction: float | None = 0.9
    slip_hold_threshold_radps: float | None = 1.0

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
    """

    def __init__(self, config: VelocityControlConfig, robot: RobotConfig | None = None) -> None:
        self._v_max = config.max_speed_mps
        self._a_max = config.max_accel_mps2
        self._w_max = config.max_angular_speed_radps
        self._aw_max = config.max_angular_accel_radps2
        self._vx = self._vy = self._wz = 0.0
        self._force_rows: tuple[tuple[float, float, float], ...] | None = None
        self.wheel_force_limit_n = math.inf
        if robot is not None and config.traction_limit_fraction is not None:
            self._force_rows = tuple(tuple(float(x) for x in row) for row in wheel_force_per_accel(robot))
            self.wheel_force_limit_n = (config.traction_limit_fraction * robot.traction_mu * robot.mass_kg
                                        * GRAVITY_MPS2 / robot.num_wheels)

    @property
    def state(self) -> tuple[float, float, float]:
        return (self._vx, self._vy, self._wz)

    def reset(self, twist=(0.0, 0.0, 0.0)) -> None:
        vx, vy, wz = (float(v) for v in twist)
        if not all(math.isfinite(v) for v in (vx, vy, wz)):
            raise ValueError("reset twist must be finite")
        self._vx, self._vy, self._wz = vx, vy, wz

    def step(self, vx: float, vy: float, wz: float, dt_s: float) -> tuple[float, float, float]:
        speed = math.hypot(vx, vy)
        if speed > self._v_max:
            k = self._v_max / speed
            vx *= k
            vy *= k
        dx = vx - self._vx
        dy = vy - self._vy
        dv = math.hypot(dx, dy)
        dv_max = self._a_max * dt_s
        if dv > dv_max:
            k = dv_max / dv
            dx *= k
            dy *= k
        wz = min(max(wz, -self._w_max), self._w_max)
        dw_max = self._aw_max * dt_s
        dw = min(max(wz - self._wz, -dw_max), dw_max)
        if self._force_rows is not None:
            peak = max(abs(a * dx + b * dy + c * dw) for a, b, c in self._force_rows) / dt_s
            if peak > self.wheel_force_limit_n:
                k = self.wheel_force_limit_n / peak
                dx *= k
                dy *= k
                dw *= k
        self._vx += dx
        self._vy += dy
        self._wz += dw
        return self._vx, self._vy, self._wz


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
    """Fig. 2: desired robot twist + measured wheel speeds -> wheel speed setpoints [rad/s]."""

    def __init__(self, robot: RobotConfig | None = None, config: VelocityControlConfig | None = None) -> None:
        self.robot = robot if robot is not None else RobotConfig()
        self.config = config if config is not None else VelocityControlConfig()
        top_mps = self.robot.top_wheel_speed_mps
        if self.config.max_speed_mps > top_mps:
            raise ValueError(
                f"max_speed_mps {self.config.max_speed_mps:g} m/s is out of the motors' reach with this robot: "
                f"they turn a wheel at most {self.robot.wheel_no_load_speed_radps:.4g} rad/s, its rim "
                f"(robot.wheel_radius_m {self.robot.wheel_radius_m:g} m) at {top_mps:.3g} m/s")
        self.kinematics = OmniKinematics.from_robot_config(self.robot)
        self._n = self.kinematics.num_wheels
        self._j = np.array(self.kinematics.wheel_matrix)
        self._f = np.array(self.kinematics.forward_matrix)
        self._shaper = SetpointShaper(self.config, self.robot)
        self._p_slip = np.array(self.kinematics.slip_projector)
        self._slip_threshold = self.config.slip_hold_threshold_radps
        self._slip = 0.0
        self._held = False
        self._pid = Pid(self.config.pid_config())
        self._ff = self.config.feedforward_enabled
        self._measured = np.zeros(3)
        self._shaped = np.zeros(3)
        self._command = np.zeros(3)
        self._wheels = np.zeros(self._n)

    @property
    def max_setpoint_radps(self) -> float:
        """The largest wheel speed setpoint ``step`` can return: the PID output limits through the wheel matrix."""
        limits = np.array([self.config.command_limit_mps, self.config.command_limit_mps,
                           self.config.command_limit_radps])
        return float((np.abs(self._j) @ limits).max())

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
        w = np.asarray(measured_wheel_speeds_radps, dtype=float)
        if w.shape != (self._n,):
            raise ValueError(f"measured_wheel_speeds_radps: need {self._n} values, got shape {w.shape}")
        np.dot(self._f, w, out=self._measured)  # NaN in w surfaces in the PID's finite check
        shaped = self._shaper.step(vx, vy, wz, dt_s)
        self._shaped[0], self._shaped[1], self._shaped[2] = shaped
        hold = bool(np.any(wheels_saturated))
        if self._slip_threshold is not None:
            # slipping wheels: forward kinematics is not the body's motion, do not integrate it
            self._slip = math.sqrt(float(np.sum(np.square(self._p_slip @ w))))
            if self._slip > self._slip_threshold:
                hold = True
        self._held = hold
        cmd = self._pid.step(self._shaped, self._measured, dt_s, self._shaped if self._ff else 0.0,
                             hold_integrator=hold)
        self._command = cmd
        return self._j @ cmd

    def reset(self, measured_wheel_speeds_radps=None) -> None:
        """Bumpless (re)start from the measured motion (or from rest when None)."""
        if measured_wheel_speeds_radps is None:
            twist = np.zeros(3)
        else:
            twist = self.kinematics.forward(measured_wheel_speeds_radps)
        self._shaper.reset(twist)
        self._pid.reset(output_hold=twist, measurement=twist, setpoint=twist,
                        feedforward=twist if self._ff else 0.0)
        self._measured[:] = twist
        self._shaped[:] = twist
        self._command = twist.copy()

    @property
    def status(self) -> VelocityControlStatus:
        return VelocityControlStatus(
            shaped_twist=self._shaped.copy(),
            measured_twist=self._measured.copy(),
            command_twist=np.array(self._command, dtype=float),
            saturated=self._pid.status.saturated,
            slip_residual_radps=self._slip,
            integrator_held=self._held,
        )


class CommandWatchdog:
    """Stop when commands stop: `expired(now)` is True before the first command and once
    more than `timeout_s` has passed since the last `feed(now)`. Time must not go backwards."""

    def __init__(self, timeout_s: float) -> None:
        if not (math.isfinite(timeout_s) and timeout_s > 0.0):
            raise ValueError(f"timeout_s: must be finite and > 0, got {timeout_s!r}")
        self.timeout_s = float(timeout_s)
        self._last_feed_s: float | None = None
        self._latest_s = -math.inf

    def _check_time(self, now_s: float) -> None:
        if not math.isfinite(now_s):
            raise ValueError(f"now_s: must be finite, got {now_s!r}")
        if now_s < self._latest_s:
            raise ValueError(f"time went backwards: {now_s} < {self._latest_s}")
        self._latest_s = now_s

    def feed(self, now_s: float) -> None:
        self._check_time(now_s)
        self._last_feed_s = now_s

    def expired(self, now_s: float) -> bool:
        self._check_time(now_s)
        return self._last_feed_s is None or now_s - self._last_feed_s > self.timeout_s
