"""Motion control (paper Sec. 4) on the physical simulated plant: erforce_sim World through InProcessRunner.

Regression tests for the "wheel fight": with the old defaults (velocity PI kp 1, shaper
6 m/s^2 in every direction) a diagonal command over-drove wheels 1 and 3 past mu*N, they
slipped, and the velocity P path through the slipping (3.5x lighter) wheels limit-cycled
at +-9 A for as long as the robot drove. Numbers here are physics identities or hand
computations, not copies of measured output.
"""

import math

import numpy as np
import pytest

from erforce_interfaces.wire.robot_config import RobotConfig
from erforce_motion.kinematics import OmniKinematics
from erforce_motion.velocity_control import (
    GRAVITY_MPS2,
    SetpointShaper,
    VelocityControlConfig,
    VelocityController,
    wheel_force_per_accel,
)
from erforce_sim.in_process.runner import InProcessRunner
from erforce_sim.plant_setup import PlantSetup

ROBOT = RobotConfig()
KIN = OmniKinematics.from_robot_config(ROBOT)
F_MAX_N = ROBOT.traction_mu * ROBOT.mass_kg * GRAVITY_MPS2 / ROBOT.num_wheels


def _body_twist(runner: InProcessRunner) -> np.ndarray:
    st = runner.world.robot_state(0)
    c, s = math.cos(st.theta), math.sin(st.theta)
    return np.array([c * st.vx + s * st.vy, -s * st.vx + c * st.vy, st.w])


def _drive(command, seconds, lifted=False, velocity_config=None):
    runner = InProcessRunner(PlantSetup(robot_poses=((0.0, 0.0, 0.0),), ball=(2.0, 2.0, 0.0, 0.0)),
                             velocity_config=velocity_config, command_timeout_s=30.0)
    runner.world.set_lifted(0, lifted)
    runner.command(0, command)
    log = {"w": [], "i": [], "theta": [], "twist": []}

    def record(r):
        log["w"].append(r.world.wheel_speeds_radps(0))
        log["i"].append(r.world.motor_currents_a(0))
        log["theta"].append(r.world.robot_state(0).theta)
        log["twist"].append(_body_twist(r))

    runner.run(seconds, record)
    return runner, {k: np.array(v) for k, v in log.items()}


@pytest.fixture(scope="module")
def diagonal():
    return _drive([1.0, 0.5, 0.0], 1.5)


def test_diagonal_constant_speed_has_no_wheel_fight(diagonal):
    _, log = diagonal
    steady = slice(-500, None)  # 1.0 .. 1.5 s
    # at constant speed the motors only overcome friction: Coulomb 1.5 mN m / k_t = 0.04 A (+ viscous)
    coulomb_a = ROBOT.motor_coulomb_friction_nm / ROBOT.motor_torque_constant_nm_per_a
    mean_abs_current = np.abs(log["i"][steady]).mean(axis=0)
    assert np.all(mean_abs_current < 0.5)
    assert np.all(mean_abs_current > 0.5 * coulomb_a)  # the motors do carry their friction
    _, slip = KIN.slip_residual(log["w"][steady])
    assert slip.max() < 0.05  # rad/s: the wheels roll as one rigid body
    np.testing.assert_allclose(log["twist"][-1], [1.0, 0.5, 0.0], atol=0.02)


def test_diagonal_start_keeps_every_wheel_below_the_traction_limit(diagonal):
    _, log = diagonal
    _, slip = KIN.slip_residual(log["w"])
    # an unsaturated wheel slips at most F_max / traction damping (17 mm/s) at its rim
    assert slip.max() < 2.0 * F_MAX_N / 300.0 / ROBOT.wheel_radius_m
    # no yaw from unbalanced wheel forces (old defaults: 0.085 rad)
    assert np.abs(log["theta"]).max() < 0.02


def test_lifted_robot_wheels_do_not_limit_cycle():
    # on a stand every wheel has only its own inertia, like a slipping wheel: the loop must stay stable
    _, log = _drive([0.3, 0.0, 0.0], 0.6, lifted=True)
    late = slice(-200, None)
    assert log["w"][late].std(axis=0).max() < 0.05
    assert np.abs(log["i"][late]).mean(axis=0).max() < 0.5
    np.testing.assert_allclose(log["w"][-1], KIN.inverse([0.3, 0.0, 0.0]), atol=0.05)


def test_old_gain_is_past_the_stability_limit_on_free_wheels():
    # the mechanism, shown: velocity kp 1 (loop gain (1+kp)*1.5 on the free wheel inertia) limit-cycles
    _, log = _drive([0.3, 0.0, 0.0], 0.6, lifted=True,
                    velocity_config=VelocityControlConfig(kp_translation=1.0, kp_rotation=1.0))
    assert log["w"][-200:].std(axis=0).max() > 1.0


# ---------------------------------------------------------------- traction-limited shaper (pure)

def test_wheel_forces_reproduce_the_wrench_with_the_smallest_norm():
    p = wheel_force_per_accel(ROBOT)
    th = np.asarray(ROBOT.wheel_angles_rad)
    d = np.vstack([-np.sin(th), np.cos(th), np.full(4, ROBOT.wheel_distance_m)])
    accel = np.array([1.3, -0.4, 7.0])
    wrench = np.array([ROBOT.mass_kg * 1.3, ROBOT.mass_kg * -0.4, ROBOT.inertia_kgm2 * 7.0])
    f = p @ accel
    np.testing.assert_allclose(d @ f, wrench, atol=1e-12)
    # any other solution differs by the null vector of D and is longer
    null = np.linalg.svd(d)[2][-1]
    for s in (-0.5, 0.1, 0.7):
        assert np.linalg.norm(f + s * null) > np.linalg.norm(f)


def test_three_wheel_shaper_limit_is_mu_g_over_two_hand_computed():
    # wheels at 90/210/330 deg, pure +x: forces (-2/3, 1/3, 1/3) m a, so a_max = fraction * mu g / 2
    robot = RobotConfig(wheel_angles_rad=tuple(math.radians(a) for a in (90.0, 210.0, 330.0)))
    sh = SetpointShaper(VelocityControlConfig(max_accel_mps2=50.0, traction_limit_fraction=0.9), robot)
    vx, vy, wz = sh.step(5.0, 0.0, 0.0, 0.01)
    a_max = 0.9 * robot.traction_mu * GRAVITY_MPS2 / 2.0
    assert vx == pytest.approx(a_max * 0.01, rel=1e-9)
    assert vy == pytest.approx(0.0, abs=1e-12) and wz == pytest.approx(0.0, abs=1e-12)


def test_shaper_keeps_direction_and_peak_wheel_force_at_the_limit():
    sh = SetpointShaper(VelocityControlConfig(max_accel_mps2=50.0), ROBOT)
    dt = 0.001
    vx, vy, wz = sh.step(0.02, 0.01, 0.03, dt)  # inside the speed/accel limits, far beyond traction
    assert vx / vy == pytest.approx(2.0) and vx / wz == pytest.approx(2.0 / 3.0)  # scaled as a whole
    assert vx < 0.02
    f = wheel_force_per_accel(ROBOT) @ (np.array([vx, vy, wz]) / dt)
    assert np.abs(f).max() == pytest.approx(0.9 * F_MAX_N, rel=1e-9)


def test_shaper_without_robot_or_with_none_fraction_uses_only_max_accel():
    for sh in (SetpointShaper(VelocityControlConfig(max_accel_mps2=50.0)),
               SetpointShaper(VelocityControlConfig(max_accel_mps2=50.0, traction_limit_fraction=None), ROBOT)):
        assert sh.step(2.0, 0.0, 0.0, 0.01)[0] == pytest.approx(0.5)


@pytest.mark.parametrize("kw", [{"traction_limit_fraction": 0.0}, {"traction_limit_fraction": math.nan},
                                {"slip_hold_threshold_radps": -1.0}, {"slip_hold_threshold_radps": math.inf}])
def test_bad_guard_parameters_raise(kw):
    with pytest.raises(ValueError):
        VelocityControlConfig(**kw)


def test_slip_hold_freezes_the_integrator_only_while_slipping():
    cfg = VelocityControlConfig(slip_hold_threshold_radps=1.0)
    null = np.asarray(KIN.slip_projector)[:, 0]
    null = 3.0 * null / np.linalg.norm(null)  # a pure slip pattern, norm 3 rad/s
    vc = VelocityController(ROBOT, cfg)
    vc.step((0.0, 0.0, 0.0), null, 0.001)
    for _ in range(20):
        vc.step((0.5, 0.0, 0.0), null, 0.001)
    assert vc.status.integrator_held and vc.status.slip_residual_radps == pytest.approx(3.0)
    np.testing.assert_allclose(vc.pid_state.integrator[0], 0.0)
    vc.step((0.5, 0.0, 0.0), np.zeros(4), 0.001)  # rigid (here: rest) again: integrates
    assert not vc.status.integrator_held and vc.pid_state.integrator[0, 0] > 0.0
