"""DC motor + gear + wheel (drivetrain.py): steady states from the motor equations, thermal node."""

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from erforce_interfaces.wire.robot_config import FieldConfig, RobotConfig
from erforce_sim.world import World
from erforce_sim.world_types import PhysicsParams, RobotSpec

CFG = RobotConfig()
FIELD = FieldConfig.preset("division_b")


def rig_world(**physics) -> World:
    w = World(FIELD, [RobotSpec(config=CFG)], physics=PhysicsParams(**physics), seed=0)
    w.set_lifted(0, True)
    return w


@pytest.mark.parametrize("duty", [0.25, -0.5, 1.0])
def test_free_wheel_steady_state_matches_dc_motor_equations(duty):
    w = rig_world()
    w.set_duty(0, [duty] * 4)
    for _ in range(60):
        w.step(0.01)
    v = CFG.supply_voltage_v * duty
    R, k = CFG.motor_resistance_ohm, CFG.motor_torque_constant_nm_per_a
    b, tc, eps = CFG.motor_viscous_friction_nms, CFG.motor_coulomb_friction_nm, PhysicsParams().coulomb_smoothing_radps

    # free wheel: no load, so k_t i equals the shaft friction; w_motor = (V - R i)/k_e
    def residual(wm):
        i = (b * wm + tc * wm / (abs(wm) + eps)) / k
        return wm - (v - R * i) / k

    wm_expected = brentq(residual, -1e4, 1e4)
    i_expected = (v - k * wm_expected) / R
    assert w.wheel_speeds_radps(0) * CFG.gear_ratio == pytest.approx([wm_expected] * 4, rel=1e-6)
    assert w.motor_currents_a(0) == pytest.approx([i_expected] * 4, rel=1e-5)
    # sanity: the no-load current is small and the speed close to V/k_e
    assert abs(i_expected) < 0.1
    assert abs(wm_expected) == pytest.approx(abs(v) / k, rel=0.01)


@pytest.mark.parametrize("duty", [0.05, -0.1])
def test_locked_rotor_current_is_v_over_r(duty):
    w = rig_world()
    w.set_wheels_locked(0, True)
    w.set_duty(0, [duty] * 4)
    w.step(0.01)  # 26 electrical time constants L/R
    assert w.motor_currents_a(0) == pytest.approx([CFG.supply_voltage_v * duty / CFG.motor_resistance_ohm] * 4)


def test_current_rises_with_electrical_time_constant():
    w = rig_world()
    w.set_wheels_locked(0, True)
    w.set_duty(0, [0.1] * 4)
    tau = CFG.motor_inductance_h / CFG.motor_resistance_ohm
    w.step(tau)
    i_inf = 2.4 / CFG.motor_resistance_ohm
    assert w.motor_currents_a(0)[0] == pytest.approx(i_inf * (1 - math.exp(-1)), rel=1e-9)


def test_winding_temperature_first_order_with_29_s():
    w = rig_world()
    w.set_wheels_locked(0, True)
    w.set_duty(0, [0.06] * 4)
    i = 24.0 * 0.06 / CFG.motor_resistance_ohm
    for _ in range(50):
        w.step(0.1)
    dt_ss = CFG.motor_resistance_ohm * i * i * CFG.winding_thermal_resistance_k_per_w
    expected = CFG.ambient_temperature_c + dt_ss * (1 - math.exp(-5.0 / 29.0))
    # the first 1 ms of current rise heats slightly less: allow 0.2 %
    assert w.winding_temperature_c(0) == pytest.approx([expected] * 4, rel=2e-3)


def test_positive_wheel_speed_turns_robot_counter_clockwise():
    w = World(FIELD, [RobotSpec()], seed=0)
    w.set_duty(0, [0.3] * 4)
    for _ in range(200):
        w.step(0.001)
    s = w.robot_state(0)
    assert s.w > 1.0
    # equal wheel speeds are a pure rotation kinematically; with this uneven wheel layout the
    # traction forces during spin-up do not cancel exactly, so a little drift remains
    assert math.hypot(s.vx, s.vy) < 0.03 * s.w * CFG.wheel_distance_m


def test_forward_drive_from_inverse_kinematics():
    # wheel rim speed for a body velocity (u forward, 0 lateral, 0 yaw) is -sin(a_i) u
    a = np.array(CFG.wheel_angles_rad)
    duty = -np.sin(a) * 0.5
    w = World(FIELD, [RobotSpec(theta=0.3)], seed=0)
    w.set_duty(0, duty)
    for _ in range(500):
        w.step(0.001)
    s = w.robot_state(0)
    speed = math.hypot(s.vx, s.vy)
    assert speed > 0.5
    assert math.atan2(s.vy, s.vx) == pytest.approx(0.3, abs=0.02)
    assert abs(s.w) < 0.05


def test_traction_limit_bounds_acceleration_and_wheels_slip():
    w = World(FIELD, [RobotSpec()], seed=0)
    a = np.array(CFG.wheel_angles_rad)
    w.set_duty(0, -np.sin(a) / np.max(np.abs(np.sin(a))))  # full forward
    w.step(0.02)
    s = w.robot_state(0)
    a_max = CFG.traction_mu * 9.81  # all wheels at mu N: sum of |force| bounded by mu m g
    assert math.hypot(s.vx, s.vy) <= a_max * 0.02 + 1e-9
    rim = np.array(s.wheel_speeds_radps) * CFG.wheel_radius_m
    contact = -np.sin(a) * s.vx + np.cos(a) * s.vy + CFG.wheel_distance_m * s.w
    assert np.max(np.abs(rim - contact)) > 0.05  # the motors spin the wheels faster than the body follows


def test_substep_rate_converged():
    def run(hz):
        w = World(FIELD, [RobotSpec()], physics=PhysicsParams(substep_hz=hz), seed=0)
        w.set_duty(0, [0.4, -0.2, 0.3, -0.5])
        for _ in range(300):
            w.step(0.001)
        return w.robot_state(0)

    a, b = run(10000.0), run(40000.0)
    assert a.x == pytest.approx(b.x, abs=2e-4)
    assert a.y == pytest.approx(b.y, abs=2e-4)
    assert a.currents_a == pytest.approx(b.currents_a, abs=0.02)
    assert a.wheel_speeds_radps == pytest.approx(b.wheel_speeds_radps, rel=5e-3)


def test_duty_validation_nan_clamp_length():
    w = World(FIELD, [RobotSpec()], seed=0)
    with pytest.raises(ValueError, match="finite"):
        w.set_duty(0, [0.1, float("nan"), 0.0, 0.0])
    with pytest.raises(ValueError, match="finite"):
        w.set_duty(0, [0.1, float("inf"), 0.0, 0.0])
    with pytest.raises(ValueError, match="expected 4"):
        w.set_duty(0, [0.1, 0.2, 0.3])
    with pytest.raises(ValueError):
        w.set_duty(0, "abcd")
    with pytest.raises(ValueError, match="robot index"):
        w.set_duty(1, [0.0] * 4)
    assert w.set_duty(0, [1.5, -3.0, 0.5, 1.0]) == 2
    assert w.duty(0).tolist() == [1.0, -1.0, 0.5, 1.0]
    assert w.set_duty(0, [1e300, 0.0, 0.0, 0.0]) == 1
    assert w.clamped_duty_count(0) == 3
