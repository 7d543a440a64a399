"""Omni-wheel kinematics after Rojas, "Omnidirectional control" (2005), as cited in paper Sec. 4.1 / Fig. 2.

The main-board velocity controller turns a robot-frame twist (vx, vy, wz) into one
rotation speed per wheel and, in the other direction, the measured wheel speeds
into the measured twist. Wheel i sits at angle theta_i (counter-clockwise from the
robot's +x axis), at distance R from the centre, and has radius r. Its rolling
direction is tangential, so

    w_i = (-sin(theta_i) vx + cos(theta_i) vy + R wz) / r      [rad/s]

For more than three wheels the map twist -> wheel speeds is overdetermined; the
forward direction is the least-squares twist (Moore-Penrose pseudo-inverse) and
whatever the rigid motion cannot explain is the slip residual.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from erforce_interfaces.wire.robot_config import RobotConfig


def _as_finite_array(values, last_dim: int, name: str) -> np.ndarray:
    arr = np.asarray(values, dtype=float)
    if arr.ndim == 0 or arr.shape[-1] != last_dim:
        raise ValueError(f"{name}: last dimension must have length {last_dim}, got shape {arr.shape}")
    if not np.isfinite(arr).all():
        raise ValueError(f"{name}: must be finite")
    return arr


@dataclass(frozen=True, kw_only=True)
class OmniKinematics:
    """Twist <-> wheel speed maps of an omni-wheel robot with n >= 3 wheels at arbitrary angles.

    Keyword-only (two lengths side by side are easy to swap):

    >>> kin = OmniKinematics(wheel_angles_rad=(0.0, 2.0944, 4.1888), wheel_distance_m=0.08, wheel_radius_m=0.03)
    >>> kin.inverse([0.0, 0.0, 1.0]).round(3).tolist()  # turning at 1 rad/s: every wheel at d / r
    [2.667, 2.667, 2.667]
    """

    wheel_angles_rad: tuple[float, ...]
    wheel_distance_m: float
    wheel_radius_m: float
    # n x 3: wheel speeds = wheel_matrix @ twist
    wheel_matrix: np.ndarray = field(init=False, repr=False, compare=False)
    # 3 x n: least-squares twist = forward_matrix @ wheel speeds
    forward_matrix: np.ndarray = field(init=False, repr=False, compare=False)
    # n x n: projector onto the wheel-speed patterns no rigid motion produces
    slip_projector: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        angles = tuple(float(a) for a in self.wheel_angles_rad)
        object.__setattr__(self, "wheel_angles_rad", angles)
        if len(angles) < 3:
            raise ValueError(f"wheel_angles_rad: need at least 3 wheels, got {len(angles)}")
        if not all(math.isfinite(a) for a in angles):
            raise ValueError("wheel_angles_rad: must be finite")
        for name in ("wheel_distance_m", "wheel_radius_m"):
            v = float(getattr(self, name))
            if not (math.isfinite(v) and v > 0.0):
                raise ValueError(f"{name}: must be finite and > 0, got {v!r}")
            object.__setattr__(self, name, v)
        th = np.asarray(angles)
        j = np.column_stack([-np.sin(th), np.cos(th), np.full_like(th, self.wheel_distance_m)])
        j /= self.wheel_radius_m
        if np.linalg.matrix_rank(j) < 3:
            raise ValueError("wheel_angles_rad: wheel layout cannot produce every twist (rank < 3)")
        pinv = np.linalg.pinv(j)
        proj = np.eye(len(angles)) - j @ pinv
        for name, m in (("wheel_matrix", j), ("forward_matrix", pinv), ("slip_projector", proj)):
            m.flags.writeable = False
            object.__setattr__(self, name, m)

    @classmethod
    def from_robot_config(cls, cfg: RobotConfig) -> OmniKinematics:
        return cls(wheel_angles_rad=cfg.wheel_angles_rad, wheel_distance_m=cfg.wheel_distance_m,
                   wheel_radius_m=cfg.wheel_radius_m)

    @property
    def num_wheels(self) -> int:
        return len(self.wheel_angles_rad)

    def inverse(self, twist) -> np.ndarray:
        """Wheel speeds [rad/s] for robot-frame twist(s) (vx m/s, vy m/s, wz rad/s); shape (...,3) -> (...,n)."""
        arr = _as_finite_array(twist, 3, "twist")
        return arr @ self.wheel_matrix.T

    def forward(self, wheel_speeds_radps) -> np.ndarray:
        """Least-squares robot-frame twist for measured wheel speeds; shape (...,n) -> (...,3)."""
        arr = _as_finite_array(wheel_speeds_radps, self.num_wheels, "wheel_speeds_radps")
        return arr @ self.forward_matrix.T

    def slip_residual(self, wheel_speeds_radps) -> tuple[np.ndarray, np.ndarray]:
        """(residual wheel speeds [rad/s], its Euclidean norm): the part no rigid twist explains."""
        arr = _as_finite_array(wheel_speeds_radps, self.num_wheels, "wheel_speeds_radps")
        residual = arr @ self.slip_projector.T
        return residual, np.linalg.norm(residual, axis=-1)
