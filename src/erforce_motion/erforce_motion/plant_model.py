"""Small in-core plant models for tuning (paper Sec. 4.2) and for tests and bench of this package.

Not the simulator (that is erforce_sim): just enough physics to close the loops of
Fig. 2 and Fig. 3 offline. Per motor, with w the wheel speed and w_m = gear * w:

    L di/dt = V_supply * duty - R i - k_e w_m
    J dw/dt = gear * eta * k_t * i - gear * (b w_m + c tanh(w_m / w_eps))     (wheel axle)

The electrical equation is integrated exactly over each substep with w frozen (it is
much faster than the mechanics, tau_e = L/R ~ 0.4 ms), the mechanics by semi-implicit
Euler. `WheelPlant` has independent wheels with a lumped load inertia (and can lock a
wheel for stall tests); `OmniRobotPlant` couples the wheels through a rigid omni-wheel
body without slip: (M + J^T I_w J) dxi/dt = J^T tau + Coriolis, J the Rojas matrix.
"""

from __future__ import annotations

import math

import numpy as np

from erforce_interfaces.wire.robot_config import RobotConfig
from erforce_motion.kinematics import OmniKinematics

_COULOMB_SMOOTHING_RADPS = 1.0  # motor-shaft speed below which Coulomb friction fades (tanh)


def wheel_axle_inertia_kgm2(robot: RobotConfig) -> float:
    """Wheel plus rotor inertia seen at the wheel axle."""
    return robot.wheel_inertia_kgm2 + robot.gear_ratio**2 * robot.motor_rotor_inertia_kgm2


def equivalent_wheel_load_inertia_kgm2(robot: RobotConfig) -> float:
    """Lumped inertia per wheel for the single-wheel model: own inertia + an n-th of the mass at radius r."""
    return wheel_axle_inertia_kgm2(robot) + robot.mass_kg * robot.wheel_radius_m**2 / robot.num_wheels


class _Motors:
    """Shared electrical and friction model of n identical motors."""

    def __init__(self, robot: RobotConfig, n: int, substeps: int) -> None:
        if not (isinstance(substeps, int) and substeps >= 1):
            raise ValueError(f"substeps: must be an int >= 1, got {substeps!r}")
        self.robot = robot
        self.n = n
        self.substeps = substeps
        self.current_a = np.zeros(n)
        self._r = robot.motor_resistance_ohm
        self._l = robot.motor_inductance_h
        self._ke = robot.motor_torque_constant_nm_per_a
        self._g = robot.gear_ratio
        self._torque_per_a = robot.gear_ratio * robot.gear_efficiency * robot.motor_torque_constant_nm_per_a
        self._v = robot.supply_voltage_v

    def _check(self, duty, dt_s: float) -> np.ndarray:
        if not (0.0 < dt_s < math.inf):
            raise ValueError(f"dt_s: must be finite and > 0, got {dt_s!r}")
        d = np.asarray(duty, dtype=float)
        if d.shape != (self.n,):
            raise ValueError(f"duty: need {self.n} values, got shape {d.shape}")
        if not np.isfinite(d).all():
            raise ValueError("duty: must be finite")
        return np.clip(d, -1.0, 1.0)

    def _electrical(self, duty: np.ndarray, wheel_speed: np.ndarray, h: float) -> None:
        i_ss = (self._v * duty - self._ke * self._g * wheel_speed) / self._r
        self.current_a = i_ss + (self.current_a - i_ss) * math.exp(-h * self._r / self._l)

    def _axle_torque(self, wheel_speed: np.ndarray) -> np.ndarray:
        r = self.robot
        wm = self._g * wheel_speed
        friction = r.motor_viscous_friction_nms * wm + r.motor_coulomb_friction_nm * np.tanh(
            wm / _COULOMB_SMOOTHING_RADPS)
        return self._torque_per_a * self.current_a - self._g * friction


class WheelPlant(_Motors):
    """n independent motor + wheel units, each driving a lumped load inertia (axle side)."""

    def __init__(self, robot: RobotConfig | None = None, n_wheels: int | None = None,
                 load_inertia_kgm2: float | None = None, substeps: int = 4) -> None:
        robot = robot if robot is not None else RobotConfig()
        n = n_wheels if n_wheels is not None else robot.num_wheels
        super().__init__(robot, n, substeps)
        j = equivalent_wheel_load_inertia_kgm2(robot) if load_inertia_kgm2 is None else load_inertia_kgm2
        if not (math.isfinite(j) and j > 0.0):
            raise ValueError(f"load_inertia_kgm2: must be finite and > 0, got {j!r}")
        self.inertia_kgm2 = float(j)
        self.wheel_speed_radps = np.zeros(n)
        self.locked = np.zeros(n, dtype=bool)

    def step(self, duty, dt_s: float) -> tuple[np.ndarray, np.ndarray]:
        """Apply duty for dt_s; returns (wheel speeds [rad/s], motor currents [A]) at the end."""
        d = self._check(duty, dt_s)
        h = dt_s / self.substeps
        for _ in range(self.substeps):
            self._electrical(d, self.wheel_speed_radps, h)
            acc = self._axle_torque(self.wheel_speed_radps) / self.inertia_kgm2
            self.wheel_speed_radps = np.where(self.locked, 0.0, self.wheel_speed_radps + h * acc)
        return self.wheel_speed_radps.copy(), self.current_a.copy()


class OmniRobotPlant(_Motors):
    """Rigid omni-wheel robot on a plane with n motors, no wheel slip.

    State: robot-frame twist (vx, vy, wz), motor currents, and the field-frame pose
    (x, y, heading) integrated from the twist.
    """

    def __init__(self, robot: RobotConfig | None = None, substeps: int = 4) -> None:
        robot = robot if robot is not None else RobotConfig()
        super().__init__(robot, robot.num_wheels, substeps)
        kin = OmniKinematics.from_robot_config(robot)
        self._j = np.array(kin.wheel_matrix)
        m = np.diag([robot.mass_kg, robot.mass_kg, robot.inertia_kgm2])
        m_total = m + wheel_axle_inertia_kgm2(robot) * (self._j.T @ self._j)
        self._m_inv = np.linalg.inv(m_total)
        self._mass = robot.mass_kg
        self.twist = np.zeros(3)
        self.pose = np.zeros(3)

    @property
    def wheel_speed_radps(self) -> np.ndarray:
        return self._j @ self.twist

    def step(self, duty, dt_s: float) -> tuple[np.ndarray, np.ndarray]:
        """Apply duty for dt_s; returns (wheel speeds [rad/s], motor currents [A]) at the end."""
        d = self._check(duty, dt_s)
        h = dt_s / self.substeps
        for _ in range(self.substeps):
            w = self._j @ self.twist
            self._electrical(d, w, h)
            vx, vy, wz = self.twist
            # body-frame translation: m (dv/dt + wz x v) = F
            gen_force = self._j.T @ self._axle_torque(w) + np.array(
                [self._mass * wz * vy, -self._mass * wz * vx, 0.0])
            self.twist = self.twist + h * (self._m_inv @ gen_force)
            c, s = math.cos(self.pose[2]), math.sin(self.pose[2])
            vx, vy, wz = self.twist
            self.pose = self.pose + h * np.array([c * vx - s * vy, s * vx + c * vy, wz])
        return self._j @ self.twist, self.current_a.copy()
