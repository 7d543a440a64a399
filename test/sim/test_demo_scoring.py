"""The demo's scoring rules, on synthetic ball paths with hand-derivable answers."""

import math

import numpy as np
import pytest

from erforce_ball_model.catch_time import RobotLimits
from erforce_interfaces.wire.robot_config import FieldConfig
from erforce_sim.in_process.scenes import default_scenes, reachable

FIELD = FieldConfig.preset("division_b")
LIMITS = RobotLimits(3.0, 2.0)


def straight_path(speed, y=0.0, t_end=2.0):
    t = np.arange(0.0, t_end, 0.01)
    x = -3.0 + speed * t
    return np.stack([t, x, np.full_like(t, y), np.full_like(t, speed), np.zeros_like(t)], axis=1)


def test_a_ball_rolling_straight_at_the_robot_is_reachable():
    truth = straight_path(3.0)
    assert reachable(truth, 0.0, 1.3, np.array([1.0, 0.0]), LIMITS, 0.0815, FIELD)


def test_a_ball_passing_far_and_fast_is_not_reachable():
    # 2 m beside at 6 m/s: the ball passes x = 1 after ~0.65 s; the robot needs
    # 2 * sqrt(1 m / 3 m/s^2) = 1.15 s (v_max not reached) to move 2 m and stop
    truth = straight_path(6.0, y=2.0, t_end=1.2)
    assert not reachable(truth, 0.0, 1.2, np.array([1.0, 0.0]), LIMITS, 0.0815, FIELD)


def test_the_reaction_delay_counts():
    # 0.5 m beside at 3 m/s: arrival at x~1 after ~1.36 s; the robot needs 2 sqrt(0.25/3) = 0.577 s
    truth = straight_path(3.0, y=0.5, t_end=1.36)
    assert reachable(truth, 0.0, 1.36, np.array([1.0, 0.0]), LIMITS, 0.0815, FIELD, reaction_s=0.1)
    assert not reachable(truth, 0.0, 0.6, np.array([1.0, 0.0]), LIMITS, 0.0815, FIELD, reaction_s=0.1)


def test_outside_the_field_does_not_count():
    truth = straight_path(3.0, y=3.5)  # rolling along beyond the side line
    assert not reachable(truth, 0.0, 2.0, np.array([1.0, 3.4]), LIMITS, 0.0815, FIELD)


def test_scene_sequence_covers_the_issue():
    scenes = default_scenes(FIELD)
    kicks = [s for s in scenes if s.ball is None]
    assert scenes[0].ball == (-2.0, 0.0, 2.0, 0.0) and scenes[0].receiver_pose[2] == math.pi  # Fig. 6
    speeds = [s.kick_speed_mps for s in kicks]
    assert min(speeds) == 1.0 and max(speeds) == 6.5
    assert any("wall" in s.name for s in kicks) and any("passing" in s.name for s in kicks)
    assert any("straight" in s.name for s in kicks)


def test_the_prediction_compared_is_the_newest_made_a_lead_before_the_contact():
    from erforce_sim.in_process.scenes import compared_prediction

    preds = [(10.1, 1.0), (10.3, 0.75), (10.5, -1.0), (10.7, 0.2)]  # (made at, catch time after it)
    assert compared_prediction(preds, 10.0, 11.0) == pytest.approx(10.7 + 0.2)  # newest made by 10.7 s
    assert compared_prediction(preds, 10.0, 10.85) is None  # newest made by 10.55 s says "never"
    assert compared_prediction(preds, 10.0, None) == pytest.approx(10.3 + 0.75)  # not caught: 0.3 s after start
    assert compared_prediction(preds, 10.0, 10.2) == pytest.approx(10.3 + 0.75)  # caught sooner than the lead
    assert compared_prediction([], 10.0, 11.0) is None
