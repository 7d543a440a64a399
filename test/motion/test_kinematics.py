"""Omni-wheel kinematics (Rojas): round trips, a hand-computed 4-wheel case, slip residual vs SVD."""

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from erforce_interfaces.wire.robot_config import RobotConfig
from erforce_motion.kinematics import OmniKinematics

KIN = OmniKinematics.from_robot_config(RobotConfig())
finite = st.floats(-10.0, 10.0, allow_nan=False)


@given(st.tuples(finite, finite, finite))
def test_forward_of_inverse_is_identity(twist):
    np.testing.assert_allclose(KIN.forward(KIN.inverse(twist)), twist, atol=1e-9)


@given(st.tuples(finite, finite, finite))
def test_rigid_motion_has_no_slip_residual(twist):
    residual, norm = KIN.slip_residual(KIN.inverse(twist))
    assert norm < 1e-9
    np.testing.assert_allclose(residual, 0.0, atol=1e-9)


def test_hand_computed_four_wheel_layout():
    # wheels at 45, 135, 225, 315 deg, R = 0.1 m, r = 0.05 m
    kin = OmniKinematics(wheel_angles_rad=tuple(math.radians(a) for a in (45, 135, 225, 315)), wheel_distance_m=0.1,
                         wheel_radius_m=0.05)
    s = math.sqrt(0.5)
    # vx = 1 m/s: w_i = -sin(theta_i) / r
    np.testing.assert_allclose(kin.inverse([1.0, 0.0, 0.0]), [-s / 0.05, -s / 0.05, s / 0.05, s / 0.05])
    # vy = 1 m/s: w_i = cos(theta_i) / r
    np.testing.assert_allclose(kin.inverse([0.0, 1.0, 0.0]), [s / 0.05, -s / 0.05, -s / 0.05, s / 0.05])
    # wz = 2 rad/s: every wheel R wz / r = 4 rad/s
    np.testing.assert_allclose(kin.inverse([0.0, 0.0, 2.0]), [4.0, 4.0, 4.0, 4.0])
    # combined, explicit numbers: vx=0.5, vy=-0.2, wz=1 -> wheel 0: (-s*0.5 - 0.2*s + 0.1)/0.05
    expected0 = (-s * 0.5 + s * -0.2 + 0.1) / 0.05
    assert kin.inverse([0.5, -0.2, 1.0])[0] == pytest.approx(expected0)


def test_vectorized_batch_shapes():
    twists = np.arange(24, dtype=float).reshape(2, 4, 3) / 10
    wheels = KIN.inverse(twists)
    assert wheels.shape == (2, 4, 4)
    np.testing.assert_allclose(wheels[1, 2], KIN.inverse(twists[1, 2]))
    np.testing.assert_allclose(KIN.forward(wheels), twists, atol=1e-12)
    residual, norm = KIN.slip_residual(wheels)
    assert residual.shape == (2, 4, 4) and norm.shape == (2, 4)


@given(st.lists(finite, min_size=4, max_size=4))
def test_slip_residual_equals_null_space_projection_from_svd(pattern):
    w = np.array(pattern)
    u, _sv, _ = np.linalg.svd(KIN.wheel_matrix)  # column space = first 3 columns of U
    null_basis = u[:, 3:]
    expected = null_basis @ (null_basis.T @ w)
    residual, norm = KIN.slip_residual(w)
    np.testing.assert_allclose(residual, expected, atol=1e-9)
    assert norm == pytest.approx(np.linalg.norm(expected), abs=1e-9)


def test_non_rigid_pattern_has_expected_residual_norm():
    u, _, _ = np.linalg.svd(KIN.wheel_matrix)
    slip = 3.0 * u[:, 3]  # pure null-space pattern
    _, norm = KIN.slip_residual(slip + KIN.inverse([1.0, 0.5, 2.0]))
    assert norm == pytest.approx(3.0)


def test_lengths_and_angles_are_keyword_only():
    with pytest.raises(TypeError):
        OmniKinematics((0.0, 2.0, 4.0), 0.08, 0.03)


def test_three_wheel_layout_has_no_null_space():
    kin = OmniKinematics(wheel_angles_rad=tuple(math.radians(a) for a in (0, 120, 240)), wheel_distance_m=0.08,
                         wheel_radius_m=0.03)
    _, norm = kin.slip_residual([1.0, -2.0, 5.0])
    assert norm < 1e-9


@pytest.mark.parametrize("bad", [[1.0, 2.0], [1.0, 2.0, 3.0, 4.0], [math.nan, 0.0, 0.0], [math.inf, 0, 0]])
def test_bad_twist_raises(bad):
    with pytest.raises(ValueError):
        KIN.inverse(bad)


@pytest.mark.parametrize("bad", [[1.0, 2.0, 3.0], [0.0] * 5, [0.0, 0.0, math.nan, 0.0], 3.0])
def test_bad_wheel_speeds_raise(bad):
    with pytest.raises(ValueError):
        KIN.forward(bad)
    with pytest.raises(ValueError):
        KIN.slip_residual(bad)


def test_bad_geometry_raises():
    with pytest.raises(ValueError):
        OmniKinematics(wheel_angles_rad=(0.0, 1.0), wheel_distance_m=0.08, wheel_radius_m=0.03)
    with pytest.raises(ValueError):
        OmniKinematics(wheel_angles_rad=(0.0, 1.0, 2.0), wheel_distance_m=-0.08, wheel_radius_m=0.03)
    with pytest.raises(ValueError):
        OmniKinematics(wheel_angles_rad=(0.0, 1.0, 2.0), wheel_distance_m=0.08, wheel_radius_m=math.nan)
    with pytest.raises(ValueError):
        # all wheels in one place: rank 2
        OmniKinematics(wheel_angles_rad=(0.0, 0.0, 0.0), wheel_distance_m=0.08, wheel_radius_m=0.03)
    with pytest.raises(ValueError):
        OmniKinematics(wheel_angles_rad=(0.0, math.inf, 2.0), wheel_distance_m=0.08, wheel_radius_m=0.03)


def test_is_frozen():
    with pytest.raises(AttributeError):
        KIN.wheel_radius_m = 1.0
