"""predictor.BallPredictor, the per-frame object of the node, the scenes and the bench: its decisions in-process."""

import math

import numpy as np
import pytest

from erforce_ball_model.ball_model import BallModelParams
from erforce_ball_model.catch_time import CatchSearch, RobotLimits, catch_after_reaction
from erforce_ball_model.identification import FitResult
from erforce_ball_model.predictor import CATCH_TIME_NEVER, BallPredictor, FrameTimes, PredictorConfig
from erforce_interfaces.robot_config import FieldConfig

FIELD = FieldConfig.preset("division_b")


def rolling_frames(predictor, t0, x0, speed, n=8, dt=0.01):
    """A ball moving along +x at ``speed`` (noise-free frames); returns the last frame."""
    frame = None
    for k in range(n):
        frame = predictor.ball_frame(t0 + k * dt, x0 + speed * k * dt, 0.0)
    return frame


def test_catch_time_is_the_search_after_the_reaction_time_plus_the_reaction_time():
    config = PredictorConfig(num_robots=1, reaction_s=0.15)
    predictor = BallPredictor(config)
    predictor.robot_frame(0, 1.0, 1.0, 0.0, math.pi)
    frame = rolling_frames(predictor, 1.0, -2.0, 2.0)
    # The same question asked directly of catch_after_reaction with the node's configuration.
    search = CatchSearch(1, config.limits, dribbler_offset_m=config.dribbler_offset_m, field=config.field)
    direct = catch_after_reaction(search, frame.trajectory, np.array([[1.0, 0.0]]), np.zeros((1, 2)), 0.15,
                                  np.zeros(1, dtype=bool), np.zeros(1), config.rest_speed_mps)
    assert frame.catch_robots == [0]
    assert frame.catch_times_s[0] == pytest.approx(direct.time_s[0] + 0.15, abs=1e-12)
    assert frame.catch_points_m[0] == pytest.approx(tuple(direct.robot_target_m[0]), abs=1e-12)


def test_a_ball_that_leaves_the_field_first_is_never_caught():
    predictor = BallPredictor(PredictorConfig(num_robots=1))
    predictor.robot_frame(0, 1.0, -4.0, 2.5, 0.0)  # far behind the ball, in a corner
    frame = rolling_frames(predictor, 1.0, 3.5, 5.0)  # 5 m/s towards the goal line at x = 4.5
    assert frame.catch_robots == [0]
    assert frame.catch_times_s == [CATCH_TIME_NEVER] and frame.catch_points_m == [None]


def test_only_robots_seen_within_the_timeout_are_answered():
    predictor = BallPredictor(PredictorConfig(num_robots=3, robot_timeout_s=0.5))
    predictor.robot_frame(1, 1.0, 1.0, 0.0, math.pi)
    predictor.robot_frame(2, 0.4, 1.0, 1.0, math.pi)  # 0.6 s before the ball: stale
    frame = rolling_frames(predictor, 1.0, -2.0, 2.0, n=2)
    assert frame.catch_robots == [1]  # robot_0 never seen


def test_a_new_time_line_restarts_the_trackers_and_a_repeated_stamp_is_rejected():
    warnings = []
    predictor = BallPredictor(PredictorConfig(num_robots=1), warn=lambda k, t: warnings.append(k))
    rolling_frames(predictor, 10.0, -2.0, 2.0, n=3)
    assert predictor.ball_frame(10.0, 0.0, 0.0) is None and warnings == ["ball_time"]  # repeated stamp
    assert predictor.ball_frame(1.0, 0.5, 0.5) is None  # before the newest, without the verdict: rejected
    frame = predictor.ball_frame(1.0, 0.5, 0.5, restart=True)  # StampFilter's RESTART: the simulator restarted
    assert frame is not None and frame.phase == "unknown"  # a fresh filter
    assert predictor.robot_frame(0, 12.0, 1.0, 0.0, 0.0) is not None
    assert predictor.robot_frame(0, 2.0, 1.0, 0.0, 0.0) is None
    assert predictor.robot_frame(0, 2.0, 1.0, 0.0, 0.0, restart=True) is not None


def test_vision_outside_the_field_margin_is_rejected():
    warnings = []
    predictor = BallPredictor(PredictorConfig(num_robots=1, vision_reject_margin_m=0.5),
                              warn=lambda k, t: warnings.append(k))
    assert predictor.ball_frame(1.0, 4.5 + 0.6, 0.0) is None
    assert predictor.robot_frame(0, 1.0, 0.0, 3.0 + 0.6, 0.0) is None
    assert warnings == ["ball_outside", "pose0"]
    assert predictor.ball_frame(1.0, 4.5 + 0.4, 0.0) is not None


def test_the_model_in_use_follows_configuration_and_accepted_fits_only():
    config = PredictorConfig(num_robots=1, ident_min_shots=3, ident_max_std=(0.1, 0.02, 0.03))
    predictor = BallPredictor(config)
    assert predictor.model == BallModelParams()
    assert predictor.configure(config) is False  # nothing changed
    hand = BallModelParams(-2.5, -0.5, 0.6)
    assert predictor.configure(PredictorConfig(num_robots=1, model=hand)) is True
    assert predictor.model == hand
    fitted = BallModelParams(-3.0, -0.4, 0.65)
    loose = FitResult(fitted, 0.05, 0.05, 0.01, num_shots=5, num_points=500, rms_residual_m=0.001)
    predictor._fit_done(loose)  # a_roll's std error 0.05 > 0.02: kept as the last fit, not used
    assert predictor.model == hand and predictor.last_fit is loose
    good = FitResult(fitted, 0.05, 0.01, 0.01, num_shots=5, num_points=500, rms_residual_m=0.001)
    predictor._fit_done(good)
    assert predictor.model == fitted
    few = FitResult(BallModelParams(-2.0, -0.2, 0.5), 0.01, 0.01, 0.01, num_shots=2, num_points=200,
                    rms_residual_m=0.001)
    predictor._fit_done(few)  # fewer shots than ident_min_shots
    assert predictor.model == fitted


def test_the_number_of_robots_is_fixed():
    predictor = BallPredictor(PredictorConfig(num_robots=2))
    with pytest.raises(ValueError, match="num_robots"):
        predictor.configure(PredictorConfig(num_robots=3))
    with pytest.raises(ValueError, match="facing_rad"):
        PredictorConfig(num_robots=2, facing_rad=[0.0, 1.0, 2.0])
    assert RobotLimits().a_max_mps2 == PredictorConfig().limits.a_max_mps2


def test_ssl_geometry_outlives_parameter_changes_while_use_vision_geometry_is_on():
    # A ball at x = 5.5 m: outside division B's lines plus the 0.5 m margin (4.5 + 0.5), inside division A's (6.0).
    config = PredictorConfig(num_robots=1, field=FIELD)
    predictor = BallPredictor(config)
    geometry_field, geometry_model = FieldConfig.preset("division_a"), BallModelParams(-3.0, -0.35, 0.65)
    assert predictor.set_vision_geometry(field=geometry_field) is False  # the model in use did not change
    assert predictor.set_vision_geometry(model=geometry_model) is True
    assert predictor.set_vision_geometry(field=geometry_field, model=geometry_model) is False  # again: nothing new
    assert (predictor.config.field, predictor.model) == (geometry_field, geometry_model)
    assert predictor.ball_frame(1.0, 5.5, 0.0) is not None

    # other parameters change, the configured model too: the geometry stays in effect
    hand = BallModelParams(-2.0, -0.5, 0.5)
    assert predictor.configure(PredictorConfig(num_robots=1, field=FIELD, reaction_s=0.2, model=hand)) is False
    assert (predictor.config.field, predictor.model) == (geometry_field, geometry_model)
    assert predictor.config.reaction_s == 0.2
    assert predictor.ball_frame(1.01, 5.5, 0.0) is not None

    # turned off: the parameters' field and model; turned on again: the geometry received before
    assert predictor.configure(PredictorConfig(num_robots=1, field=FIELD, model=hand, use_vision_geometry=False))
    assert (predictor.config.field, predictor.model) == (FIELD, hand)
    assert predictor.ball_frame(1.02, 5.5, 0.0) is None
    assert predictor.set_vision_geometry(model=BallModelParams(-3.5, -0.3, 0.6)) is False  # kept, not used
    assert predictor.model == hand
    assert predictor.configure(PredictorConfig(num_robots=1, field=FIELD, model=hand)) is True
    assert (predictor.config.field, predictor.model) == (geometry_field, BallModelParams(-3.5, -0.3, 0.6))


def test_frame_times_summarize_each_full_window_and_a_flush_the_open_one():
    times = FrameTimes(4)
    # (to the catch times out, to the end) in seconds: medians 2.5 / 3.5 ms, maxima 4 / 5 ms
    assert [times.add(c * 1e-3, (c + 1) * 1e-3) for c in (1.0, 2.0, 3.0)] == [None, None, None]
    line = times.add(4e-3, 5e-3)
    assert line.startswith("ball frame processing over 4 frames: median 3.500 ms")
    assert "max 5.000 ms; catch times out after: median 2.500 ms" in line and line.endswith("max 4.000 ms")
    assert times.flush() is None  # the full window started a new one
    times.add(1e-3, 2e-3)
    assert times.flush().startswith("ball frame processing over 1 frames: median 2.000 ms, p99 2.000 ms")
    assert FrameTimes(0).add(1e-3, 2e-3) is None  # off


def test_with_the_field_from_the_world_nothing_is_judged_until_its_geometry_arrives():
    """Division B's lines are at |x| = 4.5 m (rejected beyond 4.5 + 0.5 m), Division A's at 6 m: a robot at
    x = 5.2 m and a ball at x = 5.3 m are outside the one and inside the other."""
    warnings = []
    predictor = BallPredictor(PredictorConfig(num_robots=1, field=None),
                              warn=lambda key, text: warnings.append(text))
    assert predictor.robot_frame(0, 1.0, 5.2, 0.0, 0.0) is None
    assert predictor.ball_frame(1.0, 5.3, 0.0) is None
    assert (warnings, predictor.waiting_frames) == ([], 2)  # waited, judged nothing
    predictor.set_vision_geometry(field=FieldConfig.preset("division_a"))
    assert predictor.robot_frame(0, 1.01, 5.2, 0.0, 0.0) is not None
    assert predictor.ball_frame(1.01, 5.3, 0.0) is not None
    assert warnings == []

    pinned = BallPredictor(PredictorConfig(num_robots=1, field=FIELD), warn=lambda key, text: warnings.append(text))
    assert pinned.robot_frame(0, 1.0, 5.2, 0.0, 0.0) is None
    assert warnings == ["robot_0: rejected robot pose outside the field: (5.200, 0.000) m"]
    with pytest.raises(ValueError, match="needs use_vision_geometry"):
        PredictorConfig(field=None, use_vision_geometry=False)
