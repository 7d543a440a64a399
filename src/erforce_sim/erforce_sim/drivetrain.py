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

The substep loop is scalar float math over a few wheels, compiled by numba (``_advance``, cached on
disk beside this module, no fastmath, so the IEEE results of the same operations in the same order);
``advance_robots`` runs it for many robots in one call (World keeps every robot's state in
per-robot arrays, each RobotPlant works on its rows): as plain Python at 10 kHz it would cost more
than the rest of a simulation (docs/decisions/0010). No rclpy import.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from erforce_interfaces.runtime.numba_support import numba
from erforce_interfaces.wire.robot_config import GRAVITY_MPS2, RobotConfig


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
            raise ValueError(f"coulomb_smoothing_radps: must be finite and > 0, got {coulomb_smoothing_radps!r}")
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

    __slots__ = ("_b", "_consts", "_consts_h", "_cos_a", "_sin_a", "current", "duty", "i2_integral", "k", "lifted",
                 "locked", "temp_c", "wheel_w")

    def __init__(self, coeffs: DriveTrainCoefficients, x: float, y: float, theta: float,
                 rows: tuple[np.ndarray, ...] | None = None) -> None:
        """rows: (body[8], wheel_w, current, duty, i2_integral, temp_c) views into a World's per-robot
        arrays (the world steps every robot's rows in one compiled call); None: arrays of its own."""
        self.k = coeffs
        n = coeffs.num_wheels
        if rows is None:
            rows = (np.zeros(8), np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n))
        # body: x, y, theta, cos theta, sin theta, vx, vy, w; per wheel float64 arrays worked on in place
        self._b, self.wheel_w, self.current, self.duty, self.i2_integral, self.temp_c = rows
        self.i2_integral[:] = 0.0  # integral of i^2 dt since the last thermal update
        self.temp_c[:] = coeffs.ambient_c
        self._sin_a, self._cos_a = np.array(coeffs.sin_a), np.array(coeffs.cos_a)
        self._b[:] = (x, y, theta, math.cos(theta), math.sin(theta), 0.0, 0.0, 0.0)
        self.lifted = False  # on a stand: no traction, body held still
        self.locked = False  # blocked-rotor rig: wheels held at zero speed
        self._consts_h = -1.0
        self._consts = np.zeros(0)

    def _get(i: int):  # a property factory for the body row
        return property(lambda self: float(self._b[i]), lambda self, v: self._b.__setitem__(i, v))

    x, y, theta, cos_th, sin_th = _get(0), _get(1), _get(2), _get(3), _get(4)
    vx, vy, w = _get(5), _get(6), _get(7)
    del _get

    def set_pose_velocity(self, x: float, y: float, theta: float, vx: float, vy: float, w: float) -> None:
        """Place the body; wheels are set rolling without slip at that velocity, currents zero."""
        ct, st = math.cos(theta), math.sin(theta)
        self._b[:] = (x, y, theta, ct, st, vx, vy, w)
        k = self.k
        u = ct * vx + st * vy
        v = -st * vx + ct * vy
        for i in range(k.num_wheels):
            vc = -k.sin_a[i] * u + k.cos_a[i] * v + k.wheel_distance_m * w
            self.wheel_w[i] = 0.0 if self.locked else vc / k.wheel_radius_m
            self.current[i] = 0.0

    def advance(self, m: int, h: float, decay: float, mean_factor: float, c_eff: float) -> None:
        """Advance motors, wheels and body by m substeps of h seconds (semi-implicit Euler mechanics).

        The whole loop runs on local floats; World calls it with m = 1 while contacts are possible
        and with whole contact-free segments otherwise.
        """
        if self.lifted or self.locked:
            self._advance_rig(m, h, decay, mean_factor)
            return
        if self._consts_h != h:
            self._consts = np.array(self.substep_constants(h))
            self._consts_h = h
        b = self._b
        b[:] = _advance(m, h, decay, mean_factor, c_eff, self._consts, self._sin_a, self._cos_a, self.duty,
                        self.wheel_w, self.current, self.i2_integral, b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7])

    def substep_constants(self, h: float) -> tuple[float, ...]:
        k = self.k
        h_over_j = h / k.wheel_inertia_total_kgm2
        return (
            k.wheel_radius_m,
            k.wheel_distance_m,
            k.gear_ratio,
            k.torque_constant,
            k.torque_constant / k.resistance_ohm,
            k.viscous_nms,
            k.coulomb_nm,
            k.coulomb_smoothing_radps,
            k.traction_force_max_n,
            k.gear_ratio * k.gear_efficiency * h_over_j,  # shaft torque -> wheel speed, motor driving
            k.gear_ratio / k.gear_efficiency * h_over_j,  # ... wheel back-driving the motor
            k.wheel_radius_m * h_over_j,
            h / k.mass_kg,
            k.wheel_distance_m * h / k.inertia_kgm2,
            k.supply_voltage_v / k.resistance_ohm,
        )

    def _advance_rig(self, m: int, h: float, decay: float, mean_factor: float) -> None:
        """Test-rig variant (slow, clear): lifted = on a stand (no traction, body held still);
        locked = blocked rotors (wheel speed held at 0; on the floor the locked wheels still brake
        the body through traction). Same equations as `advance`."""
        k = self.k
        gear, kt = k.gear_ratio, k.torque_constant
        ke_over_r = kt / k.resistance_ohm
        v_over_r = k.supply_voltage_v / k.resistance_ohm
        h_over_j = h / k.wheel_inertia_total_kgm2
        c_eff = k.for_substep(h)[2]
        for _ in range(m):
            ct, st = self.cos_th, self.sin_th
            u = ct * self.vx + st * self.vy
            v = -st * self.vx + ct * self.vy
            fu = fv = tz = 0.0
            for i in range(k.num_wheels):
                ww = self.wheel_w[i]
                f = 0.0
                if not self.lifted:
                    vc = -k.sin_a[i] * u + k.cos_a[i] * v + k.wheel_distance_m * self.w
                    f = max(-k.traction_force_max_n, min(k.traction_force_max_n, c_eff * (k.wheel_radius_m * ww - vc)))
                    fu -= k.sin_a[i] * f
                    fv += k.cos_a[i] * f
                    tz += k.wheel_distance_m * f
                wm = gear * ww
                iss = v_over_r * self.duty[i] - ke_over_r * wm
                di = self.current[i] - iss
                imean = iss + di * mean_factor
                self.current[i] = iss + di * decay
                self.i2_integral[i] += imean * imean * h
                if self.locked:
                    self.wheel_w[i] = 0.0
                    continue
                tsh = kt * imean - k.viscous_nms * wm - k.coulomb_nm * wm / (abs(wm) + k.coulomb_smoothing_radps)
                eta = k.gear_efficiency if tsh * wm >= 0.0 else 1.0 / k.gear_efficiency
                self.wheel_w[i] = ww + (gear * tsh * eta - k.wheel_radius_m * f) * h_over_j
            if self.lifted:
                self.vx = self.vy = self.w = 0.0
                continue
            self.vx += (ct * fu - st * fv) * h / k.mass_kg
            self.vy += (st * fu + ct * fv) * h / k.mass_kg
            self.w += tz * h / k.inertia_kgm2
            self.x += self.vx * h
            self.y += self.vy * h
            self.theta = math.remainder(self.theta + self.w * h, 2.0 * math.pi)
            self.cos_th, self.sin_th = math.cos(self.theta), math.sin(self.theta)

    def update_temperature(self, dt_s: float) -> None:
        """Exact first-order thermal step with the mean Joule power of the last dt_s (World does all robots at
        once with the same operations: update_temperatures)."""
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


@numba.njit(cache=True, error_model="numpy")
def _advance(m, h, decay, mean_factor, c_eff, consts, sin_a, cos_a, duty, wheel_w, current, i2_integral,
             x, y, th, ct, st, vx, vy, w):
    """RobotPlant.advance's substeps: motors, wheels and body (semi-implicit Euler mechanics). Updates the
    wheel arrays in place and returns the body (x, y, theta, cos, sin, vx, vy, w)."""
    r, dist, gear, kt, ke_over_r, bv, tc, weps, fmax = consts[0], consts[1], consts[2], consts[3], consts[4], \
        consts[5], consts[6], consts[7], consts[8]
    drive_gain, back_gain, r_hj, hm, hi, v_over_r = consts[9], consts[10], consts[11], consts[12], consts[13], \
        consts[14]
    n = wheel_w.shape[0]
    i_sq = np.zeros(n)
    i_stall = np.empty(n)
    for i in range(n):
        i_stall[i] = v_over_r * duty[i]
    two_pi = 2.0 * math.pi
    for _ in range(m):
        u = ct * vx + st * vy
        v = -st * vx + ct * vy
        fu = 0.0
        fv = 0.0
        tz = 0.0
        dw = dist * w
        for i in range(n):
            sa, ca = sin_a[i], cos_a[i]
            ww = wheel_w[i]
            f = c_eff * (r * ww + sa * u - ca * v - dw)  # rim speed minus contact-point speed
            if f > fmax:
                f = fmax
            elif f < -fmax:
                f = -fmax
            fu -= sa * f
            fv += ca * f
            tz += f
            wm = gear * ww
            iss = i_stall[i] - ke_over_r * wm
            di = current[i] - iss
            imean = iss + di * mean_factor
            current[i] = iss + di * decay
            i_sq[i] += imean * imean
            tsh = kt * imean - bv * wm - tc * wm / (abs(wm) + weps)
            wheel_w[i] = ww + tsh * (drive_gain if tsh * wm >= 0.0 else back_gain) - r_hj * f
        vx += (ct * fu - st * fv) * hm
        vy += (st * fu + ct * fv) * hm
        w += tz * hi
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
    for i in range(n):
        i2_integral[i] += i_sq[i] * h
    return x, y, th, ct, st, vx, vy, w


@numba.njit(cache=True, error_model="numpy")
def advance_robots(robots, m, h, factors, consts, num_wheels, sin_a, cos_a, duty, wheel_w, current, i2_integral,
                   body):
    """RobotPlant.advance for the robots ``robots`` (rows of the per-robot arrays; wheels padded to the
    widest robot): the same operations per robot, one call for all. factors: (decay, mean factor, c_eff)."""
    for idx in range(robots.shape[0]):
        k = robots[idx]
        n = num_wheels[k]
        b = body[k]
        out = _advance(m, h, factors[k, 0], factors[k, 1], factors[k, 2], consts[k], sin_a[k, :n], cos_a[k, :n],
                            duty[k, :n], wheel_w[k, :n], current[k, :n], i2_integral[k, :n], b[0], b[1], b[2],
                            b[3], b[4], b[5], b[6], b[7])
        for j in range(8):
            b[j] = out[j]


@numba.njit(cache=True, error_model="numpy")
def thermal_step(temp, i2, resistance, ambient, thermal_r, decay, dt):
    """RobotPlant.update_temperature for every robot and wheel (the same operations)."""
    for k in range(temp.shape[0]):
        for i in range(temp.shape[1]):
            power_w = resistance[k, 0] * i2[k, i] / dt
            t_ss = ambient[k, 0] + power_w * thermal_r[k, 0]
            temp[k, i] = t_ss + (temp[k, i] - t_ss) * decay[k, 0]
            i2[k, i] = 0.0
