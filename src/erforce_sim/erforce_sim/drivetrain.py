"""Robot plant: DC motors, gears, omni wheels with bounded traction, planar rigid body.

Physics behind the paper's Sec. 4 (motion control, 1.3 A current limit) in simulation:

* Electrical, per motor:   L di/dt = V_supply*duty - R i - k_e w_motor   (k_e = k_t, SI).
  Over one substep h the back-EMF is held constant and the current is updated with the exact
  exponential  i(h) = i_ss + (i0 - i_ss) exp(-h R/L),  i_ss = (V - k_e w_motor)/R,  and the torque
  uses the exact mean current of that interval. L/R = 0.38 ms, so this is stable for any h and
  accurate at the 10-20 kHz substep rate.
* Shaft torque  T_shaft = k_t i - b w_m - T_c * w_m / (|w_m| + w_eps)  (viscous + Coulomb friction
  at the motor shaft, the Coulomb part smoothed over w_eps so explicit integration stays stable).
  The gear passes T_wheel = G * T_shaft * eta when the shaft delivers power (T_shaft*w_m >= 0) and
  G * T_shaft / eta when the wheel back-drives the motor, so the gear only ever dissipates.
* Wheel: (J_wheel + G^2 J_rotor) dw/dt = T_wheel - r F  with the traction force F of the carpet.
* Traction: F = c * (r w - v_contact) along the wheel's drive direction (-sin a_i, cos a_i), a stiff
  but bounded slip law clipped at mu N, N = m g / n_wheels. Rollers carry no lateral force.
  The damping c is applied linearly-implicitly (c / (1 + c h / m_eff)) so it is stable at any h.
* Body: m dv/dt = sum F_i d_i (rotated to the field frame), I dw/dt = sum L F_i.
* Winding temperature (one thermal node per motor):  C_th dT/dt = R i^2 - (T - T_amb)/R_th,
  tau = R_th C_th = 29 s (RobotConfig), advanced once per world step with the exact exponential
  using the mean R i^2 of that step, so the paper's current limit can be judged by temperature.

The substep loop is plain float math: for 3-6 wheels it is faster than numpy (measured in
bench/bench_sim.py). No rclpy import.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from erforce_interfaces.robot_config import RobotConfig

GRAVITY_MPS2 = 9.81


@dataclass(frozen=True)
class DriveTrainCoefficients:
    """Constants of one robot's drive train derived from RobotConfig (per-substep factors in `for_substep`)."""

    num_wheels: int
    sin_a: tuple[float, ...]
    cos_a: tuple[float, ...]
    wheel_distance_m: float
    wheel_radius_m: float
    gear_ratio: float
    gear_efficiency: float
    resistance_ohm: float
    inductance_h: float
    torque_constant: float
    supply_voltage_v: float
    viscous_nms: float
    coulomb_nm: float
    coulomb_smoothing_radps: float
    wheel_inertia_total_kgm2: float  # wheel + reflected rotor, about the wheel axle
    mass_kg: float
    inertia_kgm2: float
    traction_force_max_n: float
    traction_damping_nspm: float
    thermal_tau_s: float
    thermal_resistance_k_per_w: float
    ambient_c: float

    @classmethod
    def from_config(
        cls, cfg: RobotConfig, traction_damping_nspm: float, coulomb_smoothing_radps: float
    ) -> DriveTrainCoefficients:
        if not (math.isfinite(traction_damping_nspm) and traction_damping_nspm > 0.0):
            raise ValueError(f"traction_damping_nspm: must be finite and > 0, got {traction_damping_nspm!r}")
        if not (math.isfinite(coulomb_smoothing_radps) and coulomb_smoothing_radps > 0.0):
            raise ValueError(
                f"coulomb_smoothing_radps: must be finite and > 0, got {coulomb_smoothing_radps!r}"
            )
        g = cfg.gear_ratio
        return cls(
            num_wheels=cfg.num_wheels,
            sin_a=tuple(math.sin(a) for a in cfg.wheel_angles_rad),
            cos_a=tuple(math.cos(a) for a in cfg.wheel_angles_rad),
            wheel_distance_m=cfg.wheel_distance_m,
            wheel_radius_m=cfg.wheel_radius_m,
            gear_ratio=g,
            gear_efficiency=cfg.gear_efficiency,
            resistance_ohm=cfg.motor_resistance_ohm,
            inductance_h=cfg.motor_inductance_h,
            torque_constant=cfg.motor_torque_constant_nm_per_a,
            supply_voltage_v=cfg.supply_voltage_v,
            viscous_nms=cfg.motor_viscous_friction_nms,
            coulomb_nm=cfg.motor_coulomb_friction_nm,
            coulomb_smoothing_radps=coulomb_smoothing_radps,
            wheel_inertia_total_kgm2=cfg.wheel_inertia_kgm2 + g * g * cfg.motor_rotor_inertia_kgm2,
            mass_kg=cfg.mass_kg,
            inertia_kgm2=cfg.inertia_kgm2,
            traction_force_max_n=cfg.traction_mu * cfg.mass_kg * GRAVITY_MPS2 / cfg.num_wheels,
            traction_damping_nspm=traction_damping_nspm,
            thermal_tau_s=cfg.winding_thermal_time_constant_s,
            thermal_resistance_k_per_w=cfg.winding_thermal_resistance_k_per_w,
            ambient_c=cfg.ambient_temperature_c,
        )

    @property
    def thermal_capacity_j_per_k(self) -> float:
        """C_th = tau / R_th (29 s / 1.9 K/W = 15.3 J/K with the defaults)."""
        return self.thermal_tau_s / self.thermal_resistance_k_per_w

    def traction_effective_mass_kg(self) -> float:
        """Mass seen by one wheel's slip coordinate: wheel rim + body (translation and rotation)."""
        r = self.wheel_radius_m
        inv = 1.0 / self.mass_kg + self.wheel_distance_m**2 / self.inertia_kgm2
        inv += r * r / self.wheel_inertia_total_kgm2
        return 1.0 / inv

    def for_substep(self, h_s: float) -> tuple[float, float, float]:
        """(exp(-h R/L), mean-current factor, implicit traction damping) for substep length h."""
        x = h_s * self.resistance_ohm / self.inductance_h
        decay = math.exp(-x)
        mean_factor = (1.0 - decay) / x  # mean of exp(-t R/L) over [0, h]
        c = self.traction_damping_nspm
        c_eff = c / (1.0 + c * h_s / self.traction_effective_mass_kg())
        return decay, mean_factor, c_eff


class RobotPlant:
    """Mutable state of one simulated robot and its substep integrator.

    Pose and velocities are in the field frame (x, y, theta; vx, vy, w). Wheel i: speed
    ``wheel_w[i]`` (rad/s, positive pushes the robot counter-clockwise), current ``current[i]`` (A),
    winding temperature ``temp_c[i]``. ``duty[i]`` in [-1, 1] is held between world steps.
    """

    __slots__ = (
        "cos_th",
        "current",
        "duty",
        "i2_integral",
        "k",
        "lifted",
        "locked",
        "sin_th",
        "temp_c",
        "theta",
        "vx",
        "vy",
        "w",
        "wheel_w",
        "x",
        "y",
    )

    def __init__(self, coeffs: DriveTrainCoefficients, x: float, y: float, theta: float) -> None:
        self.k = coeffs
        n = coeffs.num_wheels
        self.x, self.y, self.theta = x, y, theta
        self.cos_th, self.sin_th = math.cos(theta), math.sin(theta)
        self.vx = self.vy = self.w = 0.0
        self.wheel_w = [0.0] * n
        self.current = [0.0] * n
        self.duty = [0.0] * n
        self.i2_integral = [0.0] * n  # integral of i^2 dt since the last thermal update
        self.temp_c = [coeffs.ambient_c] * n
        self.lifted = False  # on a stand: no traction, body held still
        self.locked = False  # blocked-rotor rig: wheels held at zero speed

    def set_pose_velocity(self, x: float, y: float, theta: float, vx: float, vy: float, w: float) -> None:
        """Place the body; wheels are set rolling without slip at that velocity, currents zero."""
        self.x, self.y, self.theta = x, y, theta
        self.cos_th, self.sin_th = math.cos(theta), math.sin(theta)
        self.vx, self.vy, self.w = vx, vy, w
        k = self.k
        u = self.cos_th * vx + self.sin_th * vy
        v = -self.sin_th * vx + self.cos_th * vy
        for i in range(k.num_wheels):
            vc = -k.sin_a[i] * u + k.cos_a[i] * v + k.wheel_distance_m * w
            self.wheel_w[i] = 0.0 if self.locked else vc / k.wheel_radius_m
            self.current[i] = 0.0

    def advance(self, m: int, h: float, decay: float, mean_factor: float, c_eff: float) -> None:
        """Advance motors, wheels and body by m substeps of h seconds (semi-implicit Euler mechanics).

        The whole loop runs on local floats; World calls it with m = 1 while contacts are possible
        and with whole contact-free segments otherwise.
        """
        k = self.k
        r = k.wheel_radius_m
        dist = k.wheel_distance_m
        gear = k.gear_ratio
        eta = k.gear_efficiency
        inv_eta = 1.0 / eta
        kt = k.torque_constant
        v_over_r = k.supply_voltage_v / k.resistance_ohm
        ke_over_r = kt / k.resistance_ohm
        bv = k.viscous_nms
        tc = k.coulomb_nm
        weps = k.coulomb_smoothing_radps
        fmax = k.traction_force_max_n
        h_over_j = h / k.wheel_inertia_total_kgm2
        hm = h / k.mass_kg
        hi = h / k.inertia_kgm2
        lifted = self.lifted
        locked = self.locked
        wheels = list(zip(k.sin_a, k.cos_a, range(k.num_wheels), strict=True))
        wheel_w, current, i2 = self.wheel_w, self.current, self.i2_integral
        drive = [v_over_r * d for d in self.duty]  # steady-state current at standstill
        x, y, th = self.x, self.y, self.theta
        ct, st = self.cos_th, self.sin_th
        vx, vy, w = self.vx, self.vy, self.w
        two_pi = 2.0 * math.pi
        for _ in range(m):
            u = ct * vx + st * vy
            v = -st * vx + ct * vy
            fu = fv = tz = 0.0
            for sa, ca, i in wheels:
                ww = wheel_w[i]
                if lifted:
                    f = 0.0
                else:
                    f = c_eff * (r * ww + sa * u - ca * v - dist * w)
                    if f > fmax:
                        f = fmax
                    elif f < -fmax:
                        f = -fmax
                    fu -= sa * f
                    fv += ca * f
                    tz += f
                wm = gear * ww
                iss = drive[i] - ke_over_r * wm
                di = current[i] - iss
                imean = iss + di * mean_factor
                current[i] = iss + di * decay
                i2[i] += imean * imean * h
                if locked:
                    wheel_w[i] = 0.0
                    continue
                tsh = kt * imean - bv * wm - tc * wm / (abs(wm) + weps)
                tw = gear * tsh * (eta if tsh * wm >= 0.0 else inv_eta)
                wheel_w[i] = ww + (tw - r * f) * h_over_j
            if lifted:
                vx = vy = w = 0.0
                continue
            vx += (ct * fu - st * fv) * hm
            vy += (st * fu + ct * fv) * hm
            w += dist * tz * hi
            x += vx * h
            y += vy * h
            if w != 0.0:
                th += w * h
                if th > math.pi:
                    th -= two_pi
                elif th <= -math.pi:
                    th += two_pi
                ct = math.cos(th)
                st = math.sin(th)
        self.x, self.y, self.theta = x, y, th
        self.cos_th, self.sin_th = ct, st
        self.vx, self.vy, self.w = vx, vy, w

    def update_temperature(self, dt_s: float) -> None:
        """Exact first-order thermal step with the mean Joule power of the last dt_s."""
        k = self.k
        decay = math.exp(-dt_s / k.thermal_tau_s)
        for i in range(k.num_wheels):
            power_w = k.resistance_ohm * self.i2_integral[i] / dt_s
            t_ss = k.ambient_c + power_w * k.thermal_resistance_k_per_w
            self.temp_c[i] = t_ss + (self.temp_c[i] - t_ss) * decay
            self.i2_integral[i] = 0.0

    def kinetic_energy_j(self) -> float:
        k = self.k
        e = 0.5 * k.mass_kg * (self.vx * self.vx + self.vy * self.vy) + 0.5 * k.inertia_kgm2 * self.w * self.w
        e += 0.5 * k.wheel_inertia_total_kgm2 * sum(ww * ww for ww in self.wheel_w)
        return e

    def magnetic_energy_j(self) -> float:
        return 0.5 * self.k.inductance_h * sum(i * i for i in self.current)
