"""Two-phase ball model (paper Sec. 5.1, 5.2, 5.4): hand numbers, physics identities, bad input."""

import math
import pickle

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from erforce_ball_model import ball_model
from erforce_ball_model.ball_model import BallModelParams, BallPhase, BallTrajectory
from erforce_interfaces.wire.robot_config import FieldConfig

SHOT = BallTrajectory([0.0, 0.0], [3.3, 0.0], 3.3)


def test_hand_numbers_3_3_mps_shot_paper_defaults():
    # Sliding until 0.6 * 3.3 = 1.98 m/s at -2.5 m/s^2, then rolling at -0.3 m/s^2.
    t_sw = (0.6 * 3.3 - 3.3) / -2.5
    assert t_sw == pytest.approx(0.528)
    assert SHOT.switch_time_s == pytest.approx(0.528)
    assert SHOT.v_switch_mps == pytest.approx(1.98)
    d_sw = 3.3 * 0.528 - 0.5 * 2.5 * 0.528**2  # 1.39392
    assert SHOT.switch_distance_m == pytest.approx(1.39392)
    assert SHOT.distance_at(0.528) == pytest.approx(d_sw)
    assert SHOT.stop_time_s == pytest.approx(0.528 + 1.98 / 0.3)  # 7.128
    assert SHOT.stop_distance_m == pytest.approx(d_sw + 1.98**2 / 0.6)  # 7.92792
    np.testing.assert_allclose(SHOT.stop_point, [7.92792, 0.0])
    np.testing.assert_allclose(SHOT.velocity_at(1.0), [1.98 - 0.3 * 0.472, 0.0])
    np.testing.assert_allclose(SHOT.position_at(2.0), [d_sw + 1.98 * 1.472 - 0.15 * 1.472**2, 0.0])
    assert SHOT.time_to_distance(1.0) == pytest.approx((3.3 - math.sqrt(3.3**2 - 5.0)) / 2.5)
    # Roll-phase quadratic uses v_switch (the paper's Algorithm 1 uses v_current there).
    tau = (1.98 - math.sqrt(1.98**2 - 0.6 * 2.0)) / 0.3
    assert SHOT.time_to_distance(d_sw + 2.0) == pytest.approx(0.528 + tau)
    assert math.isinf(SHOT.time_to_distance(8.0))


def test_kick_distances_are_each_kicks_distance():
    """Row i at the kick speed v_i (paper defaults: slide at -2.5 m/s^2 down to 0.6 v, then roll at -0.3 m/s^2):
    3.3 m/s at 0.528 s has slid 1.39392 m; 1 m/s slides 0.16 s (0.128 m), then rolls from 0.6 m/s; at any time
    as kick_distance gives it, to the last bit."""
    p = BallModelParams()
    tau = np.array([[0.0, 0.528, 2.0], [0.1, 0.5, 20.0]])
    distances = ball_model.kick_distances(tau, [3.3, 1.0], p.a_slide_mps2, p.a_roll_mps2, p.c_switch)
    assert distances[0, :2].tolist() == pytest.approx([0.0, 1.39392])
    assert distances[1, :2].tolist() == pytest.approx([0.1 - 1.25 * 0.01, 0.128 + 0.6 * 0.34 - 0.15 * 0.34**2])
    assert distances[1, 2] == pytest.approx(0.4 * 1.0 / 2.5 * 0.8 + 0.6**2 / 0.6)  # stopped: slide + roll
    for i, v in enumerate((3.3, 1.0)):
        assert distances[i].tolist() == ball_model.kick_distance(tau[i], v, p.a_slide_mps2, p.a_roll_mps2,
                                                                 p.c_switch).tolist()


def test_direction_and_phases():
    ball = BallTrajectory([1.0, 2.0], [0.0, -3.3], 3.3)
    np.testing.assert_allclose(ball.stop_point, [1.0, 2.0 - 7.92792])
    assert list(ball.phase_at([0.0, 0.5, 0.6, 7.2])) == [
        BallPhase.SLIDING, BallPhase.SLIDING, BallPhase.ROLLING, BallPhase.STOPPED
    ]


def test_already_rolling_when_speed_below_switch_speed():
    ball = BallTrajectory([0.0, 0.0], [1.0, 0.0], 3.0)  # 1.0 <= 0.6 * 3.0
    assert ball.switch_time_s == 0.0
    assert ball.stop_time_s == pytest.approx(1.0 / 0.3)
    assert ball.stop_distance_m == pytest.approx(1.0 / 0.6)
    assert ball.phase_at(0.0) == BallPhase.ROLLING


def test_v_shoot_below_current_speed_is_raised_to_it():
    low = BallTrajectory([0.0, 0.0], [2.0, 0.0], 1.0)
    same = BallTrajectory([0.0, 0.0], [2.0, 0.0], 2.0)
    assert low.v_shoot_mps == 2.0
    assert low.stop_time_s == pytest.approx(same.stop_time_s)
    assert low.switch_time_s == pytest.approx((2.0 - 1.2) / 2.5)


def test_ball_at_rest():
    ball = BallTrajectory([1.0, 1.0], [0.0, 0.0], 0.0)
    assert ball.stop_time_s == 0.0
    np.testing.assert_allclose(ball.position_at([0.0, 3.0]), [[1.0, 1.0], [1.0, 1.0]])
    assert ball.time_to_distance(0.0) == 0.0
    assert math.isinf(ball.time_to_distance(0.1))
    assert ball.time_in_field(FieldConfig.preset("division_b")) == (0.0, math.inf)


def test_array_queries_match_scalar_queries_and_advanced():
    """A long array of times runs compiled, a number (and a short array) in Python: the same closed forms,
    element by element."""
    rng = np.random.default_rng(0)
    pos, vel = rng.normal(size=(8, 2)), rng.normal(0, 3, size=(8, 2))
    shoot = rng.uniform(0, 6, 8)
    vel[5] = 0.0  # at rest
    shoot[6] = 0.5 * np.hypot(*vel[6])  # v_shoot below the speed: raised to it
    shoot[7] = 3.0 * np.hypot(*vel[7])  # already rolling
    t = np.linspace(0, 6, 97)  # more than ball_model._PYTHON_MAX_VALUES: the kernels
    assert t.size > ball_model._PYTHON_MAX_VALUES
    for i in range(8):
        ball = BallTrajectory(pos[i], vel[i], shoot[i])
        positions, speeds, phases = ball.position_at(t), ball.speed_at(t), ball.phase_at(t)
        assert positions.shape == (97, 2) and speeds.shape == phases.shape == (97,)
        short = t[::16]
        np.testing.assert_allclose(ball.position_at(short), positions[::16], rtol=1e-15)
        np.testing.assert_allclose(ball.speed_at(short), speeds[::16], rtol=1e-15)
        d = ball.distance_at(t)
        np.testing.assert_allclose(ball.time_to_distance(d[::16]), ball.time_to_distance(d)[::16], rtol=1e-15)
        for k, tk in enumerate(t):
            assert isinstance(ball.distance_at(tk), float) and isinstance(ball.speed_at(tk), float)
            np.testing.assert_allclose(positions[k], ball.position_at(float(tk)), rtol=1e-15)
            assert speeds[k] == pytest.approx(ball.speed_at(float(tk)), rel=1e-15, abs=0.0)
            assert phases[k] == ball.phase_at(float(tk))
        assert ball.phase == ball.phase_at(0.0)
        for dt in (0.0, 0.05, 0.7, 2.5, 30.0):
            later = ball.advanced(dt)
            np.testing.assert_allclose(later.position_m, ball.position_at(dt), rtol=1e-14, atol=1e-15)
            np.testing.assert_allclose(later.velocity_mps, ball.velocity_at(dt), rtol=1e-14, atol=1e-15)
    with pytest.raises(ValueError, match="one ball"):
        BallTrajectory(pos, vel, shoot)


speeds = st.floats(0.0, 8.0)
shoots = st.floats(0.0, 10.0)
params = st.builds(
    BallModelParams,
    a_slide_mps2=st.floats(-6.0, -1.0),
    a_roll_mps2=st.floats(-0.9, -0.05),
    c_switch=st.floats(0.3, 1.0),
)


@settings(max_examples=200, deadline=None)
@given(speeds, st.floats(0, 2 * math.pi), shoots, params, st.floats(0.0, 1.0))
def test_time_to_distance_inverts_distance_at(speed, ang, shoot, p, frac):
    ball = BallTrajectory([0.0, 0.0], [speed * math.cos(ang), speed * math.sin(ang)], shoot, p)
    t = frac * float(ball.stop_time_s)
    d = ball.distance_at(t)
    t_back = ball.time_to_distance(d)
    # The distance of the recovered time is the distance (well conditioned everywhere) ...
    assert ball.distance_at(t_back) == pytest.approx(d, rel=1e-12, abs=1e-12)
    # ... and the time itself is tight while the ball moves; at the stop d(t) is flat, so a
    # rounding error e in d becomes sqrt(2 e / |a_roll|) in t.
    speed_there = float(ball.speed_at(t))
    tol_t = 1e-7 if speed_there > 0.01 else 1e-7 + math.sqrt(2 * 1e-12 * max(1.0, float(d)) / abs(p.a_roll_mps2))
    assert t_back == pytest.approx(t, abs=tol_t)


@settings(max_examples=200, deadline=None)
@given(st.floats(0.1, 8.0), shoots, params)
def test_monotone_and_continuous(speed, shoot, p):
    ball = BallTrajectory([0.0, 0.0], [speed, 0.0], shoot, p)
    t = np.linspace(0.0, float(ball.stop_time_s) * 1.2 + 0.1, 2001)
    d = ball.distance_at(t)
    v = ball.speed_at(t)
    assert np.all(np.diff(d) >= -1e-12)  # never moves backwards
    assert np.all(np.diff(v) <= 1e-12)  # speed never increases
    assert v[0] == pytest.approx(speed)
    # Continuity of position and velocity across the switch.
    ts = float(ball.switch_time_s)
    eps = 1e-7
    if ts > eps:
        jump = float(ball.distance_at(ts + eps)) - float(ball.distance_at(ts - eps))
        assert 0.0 <= jump <= 2.0 * eps * speed + 1e-12  # no jump beyond the motion in 2 eps
        assert float(ball.speed_at(ts + eps)) == pytest.approx(float(ball.speed_at(ts - eps)), abs=1e-5)
    # Speed is the derivative of distance (central differences, away from the kinks).
    mid = 0.5 * (t[1:] + t[:-1])
    fd = np.diff(d) / np.diff(t)
    smooth = (np.abs(mid - ts) > 2 * (t[1] - t[0])) & (mid < float(ball.stop_time_s) - 2 * (t[1] - t[0]))
    np.testing.assert_allclose(fd[smooth], ball.speed_at(mid[smooth]), atol=1e-6)


def _leave(ball, field, margin=0.0):
    return float(ball.time_in_field(field, margin)[1])


def test_leaving_field_division_a_and_b():
    ball = BallTrajectory([0.0, 0.0], [6.5, 0.0], 6.5)
    # Division B: line at x = 4.5 m, reached while sliding: 4.5 = 6.5 t - 1.25 t^2.
    t_b = (6.5 - math.sqrt(6.5**2 - 5.0 * 4.5)) / 2.5
    assert ball.time_in_field(FieldConfig.preset("division_b")) == (0.0, pytest.approx(t_b))
    # Division A: line at x = 6 m, reached while rolling (switch at 1.04 s, 5.408 m, 3.9 m/s).
    tau = (3.9 - math.sqrt(3.9**2 - 0.6 * (6.0 - 5.408))) / 0.3
    assert _leave(ball, FieldConfig.preset("division_a")) == pytest.approx(1.04 + tau)
    # Margin extends the field.
    assert _leave(ball, FieldConfig.preset("division_b"), 0.3) > t_b
    # Diagonal: the side line (y = 3 m) comes first.
    diag = BallTrajectory([0.0, 2.0], [3.0, 3.0], 5.0)
    t_side = float(diag.time_to_distance(math.sqrt(2.0)))
    assert _leave(diag, FieldConfig.preset("division_b")) == pytest.approx(t_side)
    # Stops inside: +inf.
    assert math.isinf(_leave(BallTrajectory([0.0, 0.0], [1.0, 0.0], 1.0), FieldConfig.preset("division_b")))


def test_entering_field_from_the_run_off_area():
    div_b = FieldConfig.preset("division_b")
    # 0.5 m outside the goal line, rolling back in at 1 m/s (v_shoot 1: rolls after 0.128 m of sliding,
    # stops after 0.728 m). It crosses x = 4.5 after 0.5 m and stops inside.
    ball = BallTrajectory([5.0, 0.0], [-1.0, 0.0], 1.0)
    t_in, t_out = ball.time_in_field(div_b)
    assert t_in == pytest.approx(float(ball.time_to_distance(0.5))) and math.isinf(t_out)
    # Across a corner of the field and out again: in at the side line y = -3, out at the goal line x = 4.5.
    cross = BallTrajectory([4.0, -3.3], [3.0, 3.0], 6.0)
    t_in, t_out = cross.time_in_field(div_b)
    assert t_in == pytest.approx(float(cross.time_to_distance(0.3 * math.sqrt(2.0))))
    assert t_out == pytest.approx(float(cross.time_to_distance(0.5 * math.sqrt(2.0))))
    # Outside and moving away, stopping short, passing beside the field, or at rest outside: never.
    for never in (BallTrajectory([5.0, 0.0], [1.0, 0.0], 1.0), BallTrajectory([5.0, 0.0], [-0.3, 0.0], 0.3),
                  BallTrajectory([5.0, 3.2], [-3.0, 0.0], 3.0), BallTrajectory([5.0, 0.0], [0.0, 0.0], 0.0)):
        assert never.time_in_field(div_b) == (math.inf, math.inf)


def test_time_in_field_matches_brute_force():
    """The closed form against the path sampled every 0.1 ms (independent: position_at and a box test)."""
    rng = np.random.default_rng(11)
    div_b = FieldConfig.preset("division_b")
    half = np.array([div_b.half_length_m, div_b.half_width_m])
    positions, velocities = rng.uniform(-6.0, 6.0, (200, 2)), rng.uniform(-5.0, 5.0, (200, 2))
    shots = rng.uniform(0.0, 7.0, 200)
    dt = 1e-4
    for i in range(200):
        ball = BallTrajectory(positions[i], velocities[i], shots[i])
        t_in, t_out = ball.time_in_field(div_b)
        t = np.arange(0.0, float(ball.stop_time_s) + dt, dt)
        inside = (np.abs(ball.position_at(t)) <= half).all(axis=-1)
        if not inside.any():
            assert math.isinf(t_in) and math.isinf(t_out)
            continue
        first = int(np.argmax(inside))
        assert t[max(first - 1, 0)] <= t_in <= t[first] + 1e-12
        after = ~inside[first:]
        if not after.any():
            assert math.isinf(t_out)
        else:
            k = first + int(np.argmax(after))
            assert t[k - 1] <= t_out <= t[k] + 1e-12
            assert inside[first:k].all()  # one stretch: the path never comes back in


@pytest.mark.parametrize(
    "kwargs",
    [
        dict(a_slide_mps2=2.5),
        dict(a_roll_mps2=0.0),
        dict(a_slide_mps2=-0.2, a_roll_mps2=-0.3),
        dict(c_switch=0.0),
        dict(c_switch=1.2),
        dict(a_slide_mps2=float("nan")),
        dict(a_roll_mps2=float("-inf")),
        dict(c_switch="0.6"),
    ],
)
def test_params_validation(kwargs):
    with pytest.raises(ValueError):
        BallModelParams(**kwargs)


@pytest.mark.parametrize(
    "args",
    [
        ([np.nan, 0.0], [1.0, 0.0], 1.0),
        ([0.0, 0.0], [np.inf, 0.0], 1.0),
        ([0.0, 0.0, 0.0], [1.0, 0.0, 0.0], 1.0),
        ([0.0, 0.0], [1.0, 0.0, 0.0], 1.0),
        ([0.0, 0.0], [1.0, 0.0], -1.0),
        ([0.0, 0.0], [1.0, 0.0], np.nan),
        ([0.0, 0.0], [1e308, 1e308], 1.0),
        ([0.0, 0.0], [1.0, 0.0], 101.0),
        ([2e4, 0.0], [1.0, 0.0], 1.0),
        ([0.0, 0.0], [1.0, 0.0], 1.0, "not params"),
        (np.zeros((3, 2)), np.zeros((3, 2)), np.ones(4)),
    ],
)
def test_trajectory_validation(args):
    with pytest.raises(ValueError):
        BallTrajectory(*args)


def test_query_validation():
    with pytest.raises(ValueError):
        SHOT.position_at(-0.1)
    with pytest.raises(ValueError):
        SHOT.distance_at(np.nan)
    with pytest.raises(ValueError):
        SHOT.time_to_distance(-1.0)
    with pytest.raises(ValueError):
        SHOT.time_to_distance(np.nan)
    with pytest.raises(ValueError):
        SHOT.time_in_field("division_a")
    with pytest.raises(ValueError):
        SHOT.time_in_field(FieldConfig.preset("division_b"), -10.0)
    np.testing.assert_allclose(SHOT.position_at(np.inf), SHOT.stop_point)  # +inf: at rest


def test_immutable_and_advanced():
    with pytest.raises(ValueError):
        SHOT.position_m[0] = 1.0
    with pytest.raises(AttributeError):
        SHOT.position_m = np.zeros(2)
    with pytest.raises(AttributeError):
        SHOT.floats = None
    copy = pickle.loads(pickle.dumps(SHOT))
    np.testing.assert_array_equal(copy.position_at([0.0, 1.0, 9.0]), SHOT.position_at([0.0, 1.0, 9.0]))
    assert copy.floats == SHOT.floats
    later = SHOT.advanced(1.0)
    np.testing.assert_allclose(later.position_at(0.5), SHOT.position_at(1.5))
    assert later.stop_time_s == pytest.approx(SHOT.stop_time_s - 1.0)


def test_of_floats_is_the_constructor_for_plain_floats():
    """BallTrajectory.of_floats (the path of advanced() and of every pass evaluated) against the constructor:
    the same floats for balls sliding, rolling and at rest, at the position and speed limits; the same
    ValueError for what the constructor refuses."""
    from erforce_ball_model.ball_model import MAX_POSITION_M, MAX_SPEED_MPS

    params = BallModelParams(a_slide_mps2=-2.5, a_roll_mps2=-0.3, c_switch=0.6)
    for x, y, vx, vy, v_shoot in ((0.5, -1.0, 3.0, 4.0, 5.0), (1.0, 2.0, -0.6, 0.8, 3.0), (-3.0, 0.25, 0.0, 0.0, 0.0),
                                  (MAX_POSITION_M, -MAX_POSITION_M, 0.0, -MAX_SPEED_MPS, MAX_SPEED_MPS)):
        fast = BallTrajectory.of_floats(x, y, vx, vy, v_shoot, params)
        assert fast.floats == BallTrajectory((x, y), (vx, vy), v_shoot, params).floats and fast.params is params
    refused = ((math.nan, 0.0, 1.0, 0.0, 1.0, "finite"), (0.0, 0.0, math.inf, 0.0, 1.0, "finite"),
               (MAX_POSITION_M * 1.5, 0.0, 1.0, 0.0, 1.0, "beyond"), (0.0, 0.0, 80.0, 80.0, 1.0, "speed above"),
               (0.0, 0.0, 1.0, 0.0, -1.0, ">= 0"))
    for x, y, vx, vy, v_shoot, match in refused:
        with pytest.raises(ValueError, match=match):
            BallTrajectory((x, y), (vx, vy), v_shoot, params)
        with pytest.raises(ValueError, match=match):
            BallTrajectory.of_floats(x, y, vx, vy, v_shoot, params)
