"""The robot description as a whole (RobotConfig) and its one shared file (RobotConfig.from_yaml)."""

import math

import numpy as np
import pytest
import yaml

from erforce_interfaces.wire.robot_config import MAX_WHEEL_LAYOUT_CONDITION, RobotConfig


def _deg(*angles):
    return tuple(math.radians(a) for a in angles)


@pytest.mark.parametrize("angles", [(0, 0, 0, 0), (0, 1, 2, 3), (10, 10, 190, 190)])
def test_a_wheel_layout_that_cannot_produce_every_twist_is_refused(angles):
    with pytest.raises(ValueError, match="cannot produce every twist"):
        RobotConfig(wheel_angles_rad=_deg(*angles))


def test_wheel_layout_condition_against_hand_computed_cases():
    # Three wheels 120 deg apart: M^T M = diag(3/2, 3/2, 3), so the condition number is sqrt(3 / 1.5).
    assert RobotConfig(wheel_angles_rad=_deg(0, 120, 240)).wheel_layout_condition == pytest.approx(math.sqrt(2))
    # Wheels at 10 and 190 deg twice: rows (-s, c, 1) and (s, -c, 1) span only two directions: rank 2.
    rows = np.array([(-math.sin(a), math.cos(a), 1.0) for a in _deg(10, 190)])
    assert np.linalg.matrix_rank(rows) == 2
    assert RobotConfig().wheel_layout_condition < MAX_WHEEL_LAYOUT_CONDITION


def test_masses_inertias_and_the_body_must_make_sense():
    for name in ("mass_kg", "inertia_kgm2", "wheel_inertia_kgm2", "motor_rotor_inertia_kgm2"):
        with pytest.raises(ValueError, match=name):
            RobotConfig(**{name: 0.0})
        with pytest.raises(ValueError, match=name):
            RobotConfig(**{name: -1.0})
    with pytest.raises(ValueError, match="wheels outside the body"):
        RobotConfig(wheel_distance_m=0.1, robot_radius_m=0.09)
    with pytest.raises(ValueError, match="gear_efficiency"):
        RobotConfig(gear_efficiency=1.01)
    with pytest.raises(ValueError, match="wheel_radius_m"):
        RobotConfig(wheel_radius_m=True)


def test_the_motors_speed_range_at_the_wheel():
    r = RobotConfig()
    # no-load: V / (k_e G) = 24 / (0.036 * 3.6) = 185.19 rad/s; the rim at 0.0275 m: 5.09 m/s
    assert r.wheel_no_load_speed_radps == pytest.approx(185.185, abs=1e-3)
    assert r.top_wheel_speed_mps == pytest.approx(5.0926, abs=1e-4)


def _write(tmp_path, data):
    path = tmp_path / "robot.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def test_one_file_for_every_node_and_different_robots_per_node_are_refused(tmp_path):
    same = {"/**": {"ros__parameters": {"robot": {"mass_kg": 3.0}}},
            "plant": {"ros__parameters": {"robot.mass_kg": 3.0, "seed": 2}}}
    assert RobotConfig.from_yaml(_write(tmp_path, same)).mass_kg == 3.0
    differ = {"/**": {"ros__parameters": {"robot": {"mass_kg": 3.0}}},
              "plant": {"ros__parameters": {"robot": {"mass_kg": 1.0e6}}}}
    with pytest.raises(ValueError, match=r"'/\*\*' and 'plant' get different robots \(mass_kg 3.0 vs 1000000.0\)"):
        RobotConfig.from_yaml(_write(tmp_path, differ))
    bad = {"/**": {"ros__parameters": {"robot": {"wheel_angles_rad": [0.0, 0.0, 0.0, 0.0]}}}}
    with pytest.raises(ValueError, match="cannot produce every twist"):
        RobotConfig.from_yaml(_write(tmp_path, bad))
    with pytest.raises(ValueError, match="no robot parameters"):
        RobotConfig.from_yaml(_write(tmp_path, {"/**": {"ros__parameters": {"seed": 1}}}))
