"""predictor.BallPredictor, the per-frame object of the node, the scenes and the bench: its decisions in-process."""

import dataclasses
import math

import numpy as np
import pytest
import scipy.linalg
from ballmodel_sim import observe, simulate

from erforce_ball_model.ball_model import BallModelParams, ChipParams
from erforce_ball_model.catch_time import CatchSearch, RobotLimits, catch_after_reaction
from erforce_ball_model.chip_model import ChipTrajectory
from erforce_ball_model.identification import FitResult, ShotAccumulator
from erforce_ball_model.predictor import CATCH_TIME_NEVER, BallPredictor, FrameTimes, PredictorConfig
from erforce_ball_model.tracking import UpdateStatus
from erforce_interfaces.wire.robot_config import FieldConfig

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


def test_robots_of_the_old_time_line_get_no_catch_after_the_ball_restarts_it():
    predictor = BallPredictor(PredictorConfig(num_robots=2, robot_timeout_s=1.0))
    predictor.robot_frame(0, 1.3, 1.0, 0.0, math.pi)  # the old line; 0.3 s from the new ball's stamp: "fresh" by age
    predictor.robot_frame(1, 1.3, 1.0, 1.0, math.pi)
    rolling_frames(predictor, 1.3, -2.0, 2.0, n=2)
    frame = predictor.ball_frame(1.0, -2.0, 0.0, restart=True)  # the simulator restarted
    assert frame is not None and frame.catch_robots == []  # no robot of the old line is answered
    predictor.robot_frame(1, 1.0, 1.0, 1.0, math.pi, restart=True)  # robot_1's own stream on the new line
    frame = predictor.ball_frame(1.01, -1.98, 0.0)
    assert frame.catch_robots == [1]


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


# A model far from the defaults (-2.5 / -0.3 / 0.6): grSim's, as its SSL geometry packet carries it.
FAR_MODEL = BallModelParams(-14.0, -0.7, 0.7)
AFTER_KICK_S = (0.1, 0.25, 0.5, 1.0)
KICK_T_S = 0.5


def kick_track(v0_mps: float, model: BallModelParams, seed: int = 3):
    """Vision of a ball at rest at (-5, 0.3) kicked along +x at ``v0_mps`` at KICK_T_S under ``model``
    (ballmodel_sim's Euler steps, no closed forms), 70 Hz with 2 mm noise: frame stamps and positions."""
    t, pos, _ = simulate([(KICK_T_S, (v0_mps, 0.0))], KICK_T_S + 1.05, -model.a_slide_mps2, -model.a_roll_mps2,
                         model.c_switch, p0=(-5.0, 0.3))
    stamps, xy, _ = observe(t, pos, fps=70.0, noise_m=0.002, dropout=0.0, seed=seed)
    return stamps, xy


def filtered(predictor: BallPredictor, stamps, xy, change=None):
    """Feed the track; ``change(predictor)`` runs once half-way through the rest before the kick (the new model
    arrives while the ball lies there). Returns the rest estimate at the kick and, at each of AFTER_KICK_S, the
    newest frame's (v_shoot, stop point)."""
    rest, answers = None, {}
    for t, (x, y) in zip(stamps, xy, strict=True):
        if change is not None and t > 0.5 * KICK_T_S:
            change(predictor)
            change = None
        frame = predictor.ball_frame(t, x, y)
        if t < KICK_T_S:
            rest = frame.trajectory.position_m
        for after in AFTER_KICK_S:
            if t <= KICK_T_S + after:
                answers[after] = (frame.trajectory.v_shoot_mps, np.array(frame.stop_point_m))
    return rest, answers


def accepted_fit(model: BallModelParams) -> FitResult:
    return FitResult(model, 0.01, 0.001, 0.001, num_shots=5, num_points=500, rms_residual_m=0.001)


# Each way the model in use changes, as the node's shell calls the core: SSL geometry (/vision/ball_model, also
# the in-process ssl_ball_predictor), a parameter set at run time (the node's on_change -> configure) and an
# accepted online fit (Sec. 5.2 identification: what identify does with a fit within ident_max_std).
MODEL_CHANGES = {
    "ssl_geometry": lambda predictor, config: predictor.set_vision_geometry(model=FAR_MODEL),
    "parameter": lambda predictor, config: predictor.configure(dataclasses.replace(config, model=FAR_MODEL)),
    "online_fit": lambda predictor, config: predictor._fit_done(accepted_fit(FAR_MODEL)),
}


@pytest.mark.parametrize("v0_mps", [3.0, 5.0])
@pytest.mark.parametrize("how", MODEL_CHANGES)
def test_a_new_model_is_filtered_with_as_by_a_predictor_started_with_it(how, v0_mps):
    config = PredictorConfig(num_robots=1, field=FieldConfig.preset("division_a"))
    stamps, xy = kick_track(v0_mps, FAR_MODEL)
    pinned_rest, pinned = filtered(BallPredictor(dataclasses.replace(config, model=FAR_MODEL)), stamps, xy)
    changed = BallPredictor(config)
    changed_rest, answers = filtered(changed, stamps, xy, lambda p: MODEL_CHANGES[how](p, config))
    assert changed.model == FAR_MODEL
    # Both fuse the same frames with the same model since the change; before it, the ball lay still. The kick
    # re-seeds both filters from the same two frames, and their past enters only through the kick's time, from
    # the rest estimate: a difference d of it moves v_shoot (speed + |a_slide| (t - t_kick)) by |a_slide| d / v0,
    # and the stop point by about (c_switch^2 v0 / |a_roll|) times that. With d < 1 um: v_shoot within
    # 14e-6 / 3 < 1e-5 m/s, the stop point within 3.5 * 1e-5 < 1e-4 m. (A filter kept on the old model is
    # 0.5-0.7 m/s and 0.07-1.8 m off.)
    assert np.hypot(*(changed_rest - pinned_rest)) < 1e-6
    for after in AFTER_KICK_S:
        (v_shoot, stop), (want_v_shoot, want_stop) = answers[after], pinned[after]
        assert abs(v_shoot - want_v_shoot) < 1e-5, (after, v_shoot, want_v_shoot)
        assert np.hypot(*(stop - want_stop)) < 1e-4, (after, stop, want_stop)


def test_the_online_identification_cuts_shots_with_the_model_in_use():
    """Its own filter finds the kicks and the stops: with the model from geometry, as one started with it would
    (on these frames one kept on the defaults ends the shot 3 frames later)."""
    config = PredictorConfig(num_robots=1, field=FieldConfig.preset("division_a"), online_identification=True)
    t, pos, _ = simulate([(0.5, (3.0, 0.0))], 6.0, 14.0, 0.7, 0.7, p0=(-4.0, 0.3))  # rests after 3.6 s
    stamps, xy, _ = observe(t, pos, fps=70.0, noise_m=0.002, dropout=0.0, seed=2)
    predictor = BallPredictor(config)
    predictor.set_vision_geometry(model=FAR_MODEL)
    pinned = ShotAccumulator()
    pinned.tracker.params = FAR_MODEL
    try:
        for ti, (x, y) in zip(stamps, xy, strict=True):
            predictor.identify(predictor.ball_frame(ti, x, y))
            pinned.add(ti, x, y)
        shots = predictor._shots.shots
        assert len(shots) == len(pinned.shots) == 1
        assert np.array_equal(shots[0].t_s, pinned.shots[0].t_s)
    finally:
        predictor.close()


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


def test_ssl_geometry_chip_dampings_become_the_chip_model_in_use():
    """grSim's chip_fixed_loss (damping_z 0.42, xy 0.6 first hop, 0.96 after) replaces the configured dampings while
    use_vision_geometry; g, the minimum hop and the catchable height stay the configured ones. A 4 m/s chip at 45 deg
    (vz = vx = 2.8284 m/s) lands first at 2 vx vz / g = 1.6310 m after 2 vz / g = 0.57664 s whatever the dampings;
    then it hops at 0.42 vz for 2 (0.42 vz) / g = 0.24219 s and 0.6 vx, so its second touchdown is 1.6310 +
    0.6 vx 0.24219 = 2.0420 m (under the defaults 0.566 and 1 / 1.4: 1.6310 + 0.32638 * 2.0203 = 2.2904 m)."""
    configured = ChipParams(max_catch_height_m=0.2, min_hop_vz_mps=0.1)
    predictor = BallPredictor(PredictorConfig(num_robots=1, field=FIELD, chip=configured))
    grsim = {"damping_z": 0.42, "damping_xy_first_hop": 0.6, "damping_xy_other_hops": 0.96}
    assert predictor.set_vision_geometry(chip_dampings=grsim) is False  # the flat model in use did not change
    assert predictor.chip_model == ChipParams(damping_z=0.42, damping_xy_first_hop=0.6, damping_xy_other_hops=0.96,
                                              max_catch_height_m=0.2, min_hop_vz_mps=0.1)
    v = 4.0 / math.sqrt(2.0)
    chip = ChipTrajectory((0.0, 0.0, 0.0), (v, 0.0, v), predictor.chip_model)
    assert chip.touchdown_times_s[:2].tolist() == pytest.approx([0.57664, 0.57664 + 0.24219], abs=1e-5)
    assert chip.touchdown_points_m[:2, 0].tolist() == pytest.approx([1.6310, 2.0420], abs=1e-4)
    nominal = ChipTrajectory((0.0, 0.0, 0.0), (v, 0.0, v), ChipParams())
    assert nominal.touchdown_points_m[1, 0] == pytest.approx(2.2904, abs=1e-4)

    # other parameters change: the geometry's dampings stay; turned off: the configured ones; on again: the geometry's
    predictor.configure(PredictorConfig(num_robots=1, field=FIELD, chip=configured, reaction_s=0.2))
    assert predictor.chip_model.damping_z == 0.42
    predictor.configure(PredictorConfig(num_robots=1, field=FIELD, chip=configured, use_vision_geometry=False))
    assert predictor.chip_model == configured
    predictor.configure(PredictorConfig(num_robots=1, field=FIELD, chip=configured))
    assert predictor.chip_model.damping_xy_other_hops == 0.96

    # dampings that make no chip model (a ball that never stops hopping, a name that is none) change nothing
    for bad in ({**grsim, "damping_z": 1.0}, {**grsim, "damping_xy_first_hop": math.nan}, {"g_mps2": 1.0}):
        with pytest.raises(ValueError):
            predictor.set_vision_geometry(chip_dampings=bad)
        assert predictor.chip_model.damping_z == 0.42 and predictor.chip_model.g_mps2 == 9.81


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



def _cv_step(p: np.ndarray, dt_s: float, q: float) -> np.ndarray:
    """The textbook constant-velocity prediction of one axis' covariance: F P F^T + Q with F = [[1, dt], [0, 1]]
    and white acceleration noise Q = q [[dt^3 / 3, dt^2 / 2], [dt^2 / 2, dt]]."""
    f = np.array([[1.0, dt_s], [0.0, 1.0]])
    return f @ p @ f.T + q * np.array([[dt_s**3 / 3.0, dt_s**2 / 2.0], [dt_s**2 / 2.0, dt_s]])


def _cv_covariances(dts_s, r_m2: float, q: float, velocity_prior_m2ps2: float) -> list[np.ndarray]:
    """One axis' covariance of (x, v) after each frame of that Kalman filter measuring x with variance r (gain K =
    P H^T / (H P H^T + r), P <- (I - K H) P, H = [1, 0]); the first frame sets x (variance r), v has the prior."""
    out = [np.diag([r_m2, velocity_prior_m2ps2])]
    h = np.array([[1.0, 0.0]])
    for dt in dts_s:
        p = _cv_step(out[-1], dt, q)
        k = p @ h.T / (h @ p @ h.T + r_m2)
        out.append((np.eye(2) - k @ h) @ p)
    return out


def test_a_flat_balls_variances_are_the_constant_velocity_kalman_filters():
    """A ball at rest seen without noise at 60 Hz: the filter (r = VISION_NOISE_M^2 = 4e-6 m^2, q = accel_noise_psd
    0.05) starts from x with variance r and v with 1 (m/s)^2, then each frame is the textbook CV step. By hand after
    the second frame: predicted a = r + dt^2 + q dt^3 / 3, b = dt + q dt^2 / 2, c = 1 + q dt, corrected var_v = c -
    b^2 / (a + r) = 0.02828 (m/s)^2: nearly two positions differenced, 2 r / dt^2 = 0.0288. After 5 s the
    variances are the steady state of the discrete Riccati equation. A frame held back (an outlier 0.3 m off) is
    answered with the covariance predicted to its stamp, as its state is."""
    predictor = BallPredictor(PredictorConfig(num_robots=1, field=FIELD))
    tracker = predictor.config.tracker
    r, q, dt = tracker.position_noise_m**2, tracker.accel_noise_psd, 1.0 / 60.0
    assert (r, q) == (4e-6, 0.05)
    frames = [predictor.ball_frame(k * dt, 0.5, -0.2) for k in range(300)]
    got = np.array([(f.position_variance_m2, f.velocity_variance_m2ps2) for f in frames])
    assert got[0].tolist() == [r, 1.0]
    a, b, c = r + dt**2 + q * dt**3 / 3.0, dt + q * dt**2 / 2.0, 1.0 + q * dt
    assert got[1, 1] == pytest.approx(c - b * b / (a + r), rel=1e-9)
    assert got[1, 1] == pytest.approx(0.02828, abs=1e-5) == pytest.approx(2.0 * r / dt**2, rel=0.02)
    expected = _cv_covariances([dt] * 299, r, q, 1.0)
    np.testing.assert_allclose(got, [(p[0, 0], p[1, 1]) for p in expected], rtol=1e-9)

    f, h = np.array([[1.0, dt], [0.0, 1.0]]), np.array([[1.0], [0.0]])
    prior = scipy.linalg.solve_discrete_are(f.T, h, _cv_step(np.zeros((2, 2)), dt, q), np.array([[r]]))
    steady = prior - prior[:, :1] @ prior[:1, :] / (prior[0, 0] + r)
    np.testing.assert_allclose(got[-1], np.diag(steady), rtol=1e-6)

    held = predictor.ball_frame(300 * dt, 0.8, -0.2)
    assert held.status == UpdateStatus.HELD_BACK
    predicted = _cv_step(expected[-1], dt, q)
    assert (held.position_variance_m2, held.velocity_variance_m2ps2) == pytest.approx(
        (predicted[0, 0], predicted[1, 1]), rel=1e-9)
