"""robotTimeToPos / robotTimeToBall (paper Sec. 5.5, Algorithm 2): hand cases and brute force."""

import math

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from erforce_ball_model import catch_time
from erforce_ball_model.ball_model import BallTrajectory, ChipParams
from erforce_ball_model.catch_time import (
    MAX_RECEIVE_ANGLE_RAD,
    CatchKind,
    CatchSearch,
    RobotLimits,
    can_reach,
    can_reach_in_time,
    catch_after_reaction,
    contact_offset,
    load_kernels,
    receive_facing,
    robot_time_curve,
    robot_time_to_ball,
    robot_time_to_block,
    robot_time_to_pos,
)
from erforce_ball_model.catch_time_kernels import _axis_time, _may_reach
from erforce_ball_model.walls import Walls
from erforce_interfaces.runtime.numba_support import numba
from erforce_interfaces.wire.robot_config import FieldConfig

# The scalar functions as the kernels run them: compiled (the kernels compile them inline, these are
# compiled alone with the same error model).
load_kernels()
axis_time = np.vectorize(numba.njit(error_model="numpy")(_axis_time), otypes=[float])  # over arrays
may_reach = numba.njit(error_model="numpy")(_may_reach)

OFFSET = 0.0815
DIV_B = FieldConfig.preset("division_b")


# --- 1D and 2D bang-bang ----------------------------------------------------------------------
def test_axis_time_hand_cases():
    # from rest, 1 m, A = 1: triangle 2*sqrt(d/A) = 2 s (speed limit 100 m/s not reached)
    assert axis_time(1.0, 0.0, 1.0, 100.0) == pytest.approx(2.0)
    # 4 m with A = 1, V = 1: 1 s up, 3 s cruise, 1 s down
    assert axis_time(4.0, 0.0, 1.0, 1.0) == pytest.approx(5.0)
    # symmetric in the sign of the distance
    assert axis_time(-1.0, 0.0, 1.0, 100.0) == pytest.approx(2.0)
    # moving at 1 m/s towards a target exactly at the stopping distance 0.5 m: brake only, 1 s
    assert axis_time(0.5, 1.0, 1.0, 100.0) == pytest.approx(1.0)
    # moving away at 1 m/s from a target 1 m ahead: 1 s to stop (0.5 m back), then 1.5 m from rest
    assert axis_time(1.0, -1.0, 1.0, 100.0) == pytest.approx(1.0 + 2.0 * math.sqrt(1.5))
    # overshoot: 2 m/s towards a target 1 m ahead (stopping needs 2 m): 2 s, then 1 m back
    assert axis_time(1.0, 2.0, 1.0, 100.0) == pytest.approx(2.0 + 2.0)
    # at the target at rest: 0, even without any authority on the axis
    assert axis_time(0.0, 0.0, np.inf, 1.0) == 0.0
    assert math.isinf(axis_time(0.1, 0.0, np.inf, 1.0))


def test_robot_time_to_pos_hand_cases():
    lim = RobotLimits(2.0, 3.0)
    # straight along x from rest: the whole budget goes to x, 2*sqrt(2/2) = 2 s
    assert robot_time_to_pos([0.0, 0.0], [0.0, 0.0], [2.0, 0.0], lim) == pytest.approx(2.0, abs=1e-6)
    # diagonal from rest: alpha = 45 deg is the straight-line optimum, 2*sqrt(D/a) with D = sqrt(2)
    assert robot_time_to_pos([0.0, 0.0], [0.0, 0.0], [1.0, 1.0], lim) == pytest.approx(
        2.0 * math.sqrt(math.sqrt(2.0) / 2.0), abs=1e-6
    )
    # long distance: trapezoid with the speed limit 3: 1.5 s up, 1.5 s down, (10 - 4.5) / 3 cruise
    assert robot_time_to_pos([0.0, 0.0], [0.0, 0.0], [0.0, -10.0], lim) == pytest.approx(3.0 + 5.5 / 3.0, abs=1e-6)
    # already there at rest
    assert robot_time_to_pos([1.0, 1.0], [0.0, 0.0], [1.0, 1.0], lim) == pytest.approx(0.0, abs=1e-9)


def test_robot_time_to_pos_broadcasts_over_robots_and_targets():
    rng = np.random.default_rng(0)
    robots = rng.uniform(-3, 3, (4, 1, 2))
    targets = rng.uniform(-3, 3, (1, 6, 2))
    lim = RobotLimits(np.array([1.0, 2.0, 3.0, 4.0])[:, None], 2.5)
    out = robot_time_to_pos(robots, np.zeros((4, 1, 2)), targets, lim)
    assert out.shape == (4, 6)
    one = robot_time_to_pos(robots[2, 0], [0.0, 0.0], targets[0, 5], RobotLimits(3.0, 2.5))
    assert out[2, 5] == pytest.approx(float(one))


vec = st.tuples(st.floats(-4, 4), st.floats(-4, 4))


@settings(max_examples=300, deadline=None)
@given(vec, vec, vec, st.floats(0.5, 6.0), st.floats(0.5, 4.0), st.floats(0.5, 1.5))
def test_reachability_test_agrees_with_alpha_search(p0, v0, target, a_max, v_max, factor):
    """The closed-form sign test is exactly the alpha-search time compared with the budget."""
    lim = RobotLimits(a_max, v_max)
    t = float(robot_time_to_pos(p0, v0, target, lim))
    assert math.isfinite(t) and t >= 0.0
    d = np.subtract(target, p0)
    budget = t * factor
    if abs(factor - 1.0) * t > 1e-5:
        assert bool(can_reach_in_time(d, v0, budget, a_max, v_max)) == (factor > 1.0)


@settings(max_examples=300, deadline=None)
@given(vec, vec, st.floats(0.5, 6.0), st.floats(0.5, 4.0), st.floats(0.5, 1.5))
def test_reachability_of_robots_at_rest_agrees_with_alpha_search(p0, target, a_max, v_max, factor):
    """Robots at rest take a closed-form path in the sign test: same answer as the search."""
    lim = RobotLimits(a_max, v_max)
    t = float(robot_time_to_pos(p0, [0.0, 0.0], target, lim))
    d = np.subtract(target, p0)
    if abs(factor - 1.0) * t > 1e-6:
        assert bool(can_reach_in_time(d, [0.0, 0.0], t * factor, a_max, v_max)) == (factor > 1.0)
    # 1D from rest along the line: triangle 2 sqrt(D / a) or trapezoid D / v + v / a
    dist = math.hypot(*d)
    expected = 2.0 * math.sqrt(dist / a_max) if dist <= v_max**2 / a_max else dist / v_max + v_max / a_max
    assert t == pytest.approx(expected, abs=1e-9)


@settings(max_examples=200, deadline=None)
@given(st.floats(-5, 5), st.floats(-4, 4), st.floats(0.05, 5.0), st.floats(0.05, 3.0))
def test_axis_time_monotone_in_acceleration_share(d, w, inv_a, rho):
    t = axis_time(d, w, inv_a, rho)
    assert axis_time(d, w, inv_a * 1.01, rho) >= t - 1e-12


@settings(max_examples=200, deadline=None)
@given(vec, vec, vec, st.floats(0.5, 6.0), st.floats(0.5, 4.0))
def test_robot_time_to_pos_is_certified_by_the_sign_test(p0, v0, target, a_max, v_max):
    """Achievable (the sign test says reachable) and at most 1e-7 s above the optimum (not just below)."""
    t = float(robot_time_to_pos(p0, v0, target, RobotLimits(a_max, v_max)))
    d = np.subtract(target, p0)
    assert bool(can_reach_in_time(d, v0, t * (1.0 + 1e-12) + 1e-12, a_max, v_max))
    if t > 1e-6:
        assert not bool(can_reach_in_time(d, v0, t - 2e-7, a_max, v_max))


@settings(max_examples=300, deadline=None)
@given(vec, vec, st.floats(-1.0, 6.0), st.floats(0.5, 6.0), st.floats(0.5, 4.0))
@example((0.0, 0.0), (0.0, 0.0), 0.0, 2.0, 3.0)  # at the target, at rest, no time
@example((1.0, 0.0), (0.0, 0.0), 0.0, 2.0, 3.0)  # a zero budget (0 / 0 in the quadratic)
@example((1.0, 0.5), (0.5, 0.0), 1.5, 2.0, 3.0)  # t == rho: the trapezoid's c is 0
@example((1.0, 0.0), (-1.0, 0.0), 2.0, 2.0, 3.0)  # moving away: w < 0, no 1 / w
def test_plain_python_can_reach_answers_as_the_compiled_sign_test(d, w, t, a_max, v_max):
    """can_reach (the catcher's, plain Python) gives the kernel's answer, also where numba's x / 0 is inf."""
    compiled = bool(can_reach_in_time(d, w, t, a_max, v_max)) if t >= 0.0 else False
    assert can_reach(d, w, t, a_max, v_max) is compiled


def test_the_search_run_as_python_while_the_kernels_load_gives_the_compiled_numbers(monkeypatch):
    """kernels="background" (a restarted predictor) answers with the same loop as Python until numba is in:
    every output equal to the bit, also for robots and balls at rest, and the compiled search once loaded."""
    rng = np.random.default_rng(5)
    lim = RobotLimits(3.0, 2.0)
    compiled = CatchSearch(4, lim, field=DIV_B, field_margin_m=0.3)  # up to the wall
    monkeypatch.setattr(catch_time, "kernels_loaded", lambda: False)  # as while the thread still loads
    python = CatchSearch(4, lim, field=DIV_B, field_margin_m=0.3, kernels="background")
    walls = Walls.of_field(DIV_B)
    for k in range(30):
        ball = BallTrajectory(tuple(rng.uniform(-4.5, 4.5, 2)), tuple(rng.normal(0, 3, 2) * (k % 6 != 0)),
                              float(rng.uniform(0, 6)), walls=walls if k % 2 else None)  # half off the walls
        robots, vels = rng.uniform(-4.5, 4.5, (4, 2)), rng.normal(0, 1, (4, 2)) * (k % 4 != 0)
        facing = rng.uniform(-math.pi, math.pi, 4)
        fields = ("time_s", "ball_position_m", "robot_target_m", "kind")
        want = compiled.run(ball, robots, vels, facing)
        want = [getattr(want, name).copy() for name in fields]
        got = python.run(ball, robots, vels, facing)
        assert python._search is None and not python.compiled  # still the Python loop
        for name, w in zip(fields, want, strict=True):
            assert np.array_equal(w, getattr(got, name), equal_nan=True), (k, name, w, getattr(got, name))
    monkeypatch.undo()
    python.run(ball, robots, vels, facing)
    assert python._search is compiled._search  # the kernels are in: the compiled search from then on
    assert python.compiled and compiled.compiled
    with pytest.raises(ValueError, match="kernels"):
        CatchSearch(1, lim, field=DIV_B, kernels="later")


def test_robot_time_to_pos_never_worse_than_a_dense_alpha_scan():
    rng = np.random.default_rng(7)
    alpha = np.linspace(1e-6, 0.5 * math.pi - 1e-6, 20001)
    for _ in range(40):
        p0, v0, tgt = rng.uniform(-4, 4, 2), rng.normal(0, 1.5, 2), rng.uniform(-4, 4, 2)
        a_max, v_max = rng.uniform(1.0, 5.0), rng.uniform(1.0, 4.0)
        d = tgt - p0
        tx = axis_time(d[0], v0[0], 1.0 / (a_max * np.cos(alpha)), v_max / a_max)
        ty = axis_time(d[1], v0[1], 1.0 / (a_max * np.sin(alpha)), v_max / a_max)
        scan = float(np.maximum(tx, ty).min())
        t = float(robot_time_to_pos(p0, v0, tgt, RobotLimits(a_max, v_max)))
        assert scan - 1e-3 <= t <= scan + 1e-7


def test_prepared_search_reused_over_frames_equals_one_off_calls():
    """CatchSearch (the predictor's per-frame form) gives what robot_time_to_ball gives, frame after frame."""
    rng = np.random.default_rng(11)
    robots, vels = rng.uniform(-4, 4, (5, 2)), rng.normal(0, 1, (5, 2))
    lim = RobotLimits(rng.uniform(2, 5, 5), 2.5)
    search = CatchSearch(5, lim, field=DIV_B, grid_step_s=0.02)
    for _ in range(20):
        ball = BallTrajectory(tuple(rng.uniform(-4, 4, 2)), tuple(rng.normal(0, 3, 2)), float(rng.uniform(0, 6)))
        facing = rng.uniform(-math.pi, math.pi, 5)
        got = search.run(ball, robots, vels, facing)
        want = robot_time_to_ball(ball, robots, vels, lim, facing, field=DIV_B, grid_step_s=0.02)
        for name in ("time_s", "kind", "ball_position_m", "robot_target_m"):
            np.testing.assert_array_equal(getattr(got, name), getattr(want, name), err_msg=name)
    assert search.run(ball, robots, vels, 0.0) is got  # the result arrays are reused
    with pytest.raises(ValueError, match="must both be"):
        search.run(ball, robots[:4], vels[:4])
    with pytest.raises(ValueError, match="facing_rad"):
        search.run(ball, robots, vels, np.zeros(4))
    bad = robots.copy()
    bad[3, 1] = np.inf
    with pytest.raises(ValueError, match="finite"):
        search.run(ball, bad, vels)
    with pytest.raises(ValueError, match="BallTrajectory"):
        search.run(ball.floats, robots, vels)
    with pytest.raises(ValueError):
        CatchSearch(0, lim, field=DIV_B)


@settings(max_examples=300, deadline=None)
@given(vec, vec, vec, st.floats(0.0, 4.0), st.floats(0.5, 6.0), st.floats(0.5, 4.0))
@example((0.0, 0.0), (0.0, 0.25), (0.0, 2.1245449335086068e-218), 1.0, 1.0, 1.0)  # |d|^2 underflows to 0
def test_cheap_bound_never_rules_out_a_reachable_point(p0, v0, target, t, a_max, v_max):
    """robotTimeToBall skips the exact test where _may_reach is False: that must be sound."""
    d = np.subtract(target, p0)
    s0 = math.hypot(*v0)
    if bool(can_reach_in_time(d, v0, t, a_max, v_max)):
        assert bool(may_reach(d[0], d[1], v0[0], v0[1], s0, t, a_max, v_max))


# --- robotTimeToBall: hand cases ---------------------------------------------------------------
def test_robot_at_rest_on_the_path_facing_the_ball():
    # Ball rolling along +x at 2 m/s; robot at (2, 0) facing it (left); a = 3, v_max = 3.
    # The robot meets the ball when 1.9185 - d(t) = a t^2 / 4 (triangle from rest, moving left):
    # 1.9185 - 2t + 0.15t^2 = 0.75t^2  ->  0.6t^2 + 2t - 1.9185 = 0.
    ball = BallTrajectory([0.0, 0.0], [2.0, 0.0], 2.0 / 0.6)
    res = robot_time_to_ball(ball, [[2.0, 0.0]], [[0.0, 0.0]], RobotLimits(3.0, 3.0), math.pi, unbounded=True)
    t_hand = (-2.0 + math.sqrt(4.0 + 4.0 * 0.6 * (2.0 - OFFSET))) / 1.2
    assert res.kind[0] == CatchKind.MOVING
    assert t_hand - 1e-9 <= res.time_s[0] <= t_hand + 1e-4  # never early, at most one sub-step late
    d = 2.0 * res.time_s[0] - 0.15 * res.time_s[0] ** 2
    np.testing.assert_allclose(res.ball_position_m[0], [d, 0.0], atol=1e-9)
    np.testing.assert_allclose(res.robot_target_m[0], [d + OFFSET, 0.0], atol=1e-9)


def test_fast_ball_at_a_robot_standing_on_its_path_is_caught_however_narrow_the_window():
    # A 5.3 m/s ball 0.38 m before the dribbler of a robot at rest on its path: the window is only
    # about a t^2 / (2 v) = 3 ms wide (the robot can shift a t^2 / 4 while the ball passes), far
    # narrower than the 10 ms grid, yet the robot that just stands there catches it.
    ball = BallTrajectory([0.534, 0.0], [5.3, 0.0], 6.5)
    robot = [[0.534 + 0.38 + OFFSET, 0.0]]
    lim = RobotLimits(4.5, 2.5)
    res = robot_time_to_ball(ball, robot, [[0.0, 0.0]], lim, math.pi, field=DIV_B)
    t_arrive = float(ball.time_to_distance(0.38))  # the ball reaches the standing dribbler
    t_ref, width = _dense_first_crossing(ball, np.array(robot[0]), np.zeros(2), lim, math.pi, 1.0, step=1e-5)
    assert width < 0.005 and t_ref <= t_arrive + 1e-9
    assert res.kind[0] == CatchKind.MOVING
    assert t_ref - 1e-6 <= res.time_s[0] <= t_arrive + 1e-9


def test_ball_already_stopped():
    ball = BallTrajectory([1.0, 0.0], [0.0, 0.0], 0.0)
    res = robot_time_to_ball(ball, [[0.0, 0.0]], [[0.0, 0.0]], RobotLimits(2.0, 3.0), 0.0, field=DIV_B)
    assert res.kind[0] == CatchKind.AT_REST
    assert res.time_s[0] == pytest.approx(2.0 * math.sqrt((1.0 - OFFSET) / 2.0), abs=1e-6)
    np.testing.assert_allclose(res.robot_target_m[0], [1.0 - OFFSET, 0.0])


def test_robot_standing_at_the_catch_point_of_a_resting_ball_catches_at_zero():
    ball = BallTrajectory([1.0, 0.0], [0.0, 0.0], 0.0)
    res = robot_time_to_ball(ball, [[1.0 - OFFSET, 0.0]], [[0.0, 0.0]], RobotLimits(2.0, 3.0), 0.0, unbounded=True)
    assert res.time_s[0] == 0.0 and res.kind[0] == CatchKind.MOVING


def test_ball_leaving_the_field_is_never_caught():
    ball = BallTrajectory([3.5, 0.0], [5.0, 0.0], 5.0)
    res = robot_time_to_ball(ball, [[-4.0, 0.0]], [[0.0, 0.0]], RobotLimits(3.0, 3.0), 0.0, field=DIV_B)
    assert res.kind[0] == CatchKind.NEVER
    assert math.isinf(res.time_s[0])
    assert np.isnan(res.ball_position_m[0]).all()
    # Without a field the ball stops 18.2 m further on; a slow robot (0.5 m/s) only gets it at rest.
    slow = RobotLimits(1.0, 0.5)
    res = robot_time_to_ball(ball, [[-4.0, 0.0]], [[0.0, 0.0]], slow, 0.0, unbounded=True)
    assert res.kind[0] == CatchKind.AT_REST
    target = ball.stop_point - [OFFSET, 0.0]
    assert res.time_s[0] == pytest.approx(float(robot_time_to_pos([-4.0, 0.0], [0.0, 0.0], target, slow)), abs=1e-9)
    assert res.time_s[0] > ball.stop_time_s



def test_ball_rolling_back_in_from_the_run_off_area_is_caught_inside_only():
    """Off a wall the ball is outside the side line, coming back in: the paper's bound (t_out = 0) would say
    never; the search covers the stretch inside the field instead, from where the ball crosses the line."""
    # In the run-off area, 0.25 m beyond the side line, rolling (v_shoot 2 m/s) back in.
    ball = BallTrajectory([0.0, 3.25], [0.9, -0.3], 2.0)
    t_in = float(ball.time_in_field(DIV_B)[0])
    assert t_in == pytest.approx(float(ball.time_to_distance(0.25 * math.hypot(0.9, 0.3) / 0.3)))
    facing = math.atan2(0.3, -0.9)  # against the ball's motion
    lim = RobotLimits(3.0, 2.5)
    # A robot waiting where the ball crosses into the field catches it there, not before: the spot next
    # to it, outside, is excluded even though the robot would be in time for it.
    crossing = ball.position_at(t_in)
    robot = crossing - OFFSET * np.array([math.cos(facing), math.sin(facing)])
    res = robot_time_to_ball(ball, robot, [0.0, 0.0], lim, facing, field=DIV_B)  # one robot: floats
    assert res.kind == CatchKind.MOVING
    assert isinstance(res.time_s, float) and res.time_s == pytest.approx(t_in, abs=1e-9)
    # Robots farther inside: the first crossing of t_robot(t) = t after t_in, by a dense reference.
    t_max = float(ball.stop_time_s)
    robots = np.array([[1.0, 1.5], [2.0, 2.0], [-1.0, 1.0]])
    res = robot_time_to_ball(ball, robots, np.zeros((3, 2)), lim, facing, field=DIV_B)
    for r in range(3):
        t_ref, _ = _dense_first_crossing(ball, robots[r], np.zeros(2), lim, facing, t_max, t_min=t_in)
        assert res.kind[r] == CatchKind.MOVING
        assert t_ref - 1e-5 <= res.time_s[r] <= t_ref + 1e-3
        assert abs(res.ball_position_m[r, 1]) <= DIV_B.half_width_m + 1e-9
    # Moving away from the field, or stopping before the line: never.
    for away in (BallTrajectory([0.0, 3.25], [0.8, 0.02], 0.85), BallTrajectory([0.0, 3.25], [0.0, -0.3], 0.3)):
        res = robot_time_to_ball(away, [[0.0, 2.5]], [[0.0, 0.0]], lim, facing, field=DIV_B)
        assert res.kind[0] == CatchKind.NEVER

def test_at_rest_time_of_a_moving_robot_is_an_upper_bound_within_the_sub_grid_step():
    ball = BallTrajectory([1.0, 0.5], [0.0, 0.0], 0.0)
    robots = np.array([[-3.0, 1.0], [2.0, -2.0], [0.0, 3.0]])
    vels = np.array([[1.0, -0.5], [-1.5, 0.2], [0.3, 0.3]])
    lim = RobotLimits(2.5, 2.0)
    res = robot_time_to_ball(ball, robots, vels, lim, 0.0, field=DIV_B)
    assert (res.kind == CatchKind.AT_REST).all()
    exact = robot_time_to_pos(robots, vels, ball.stop_point - [OFFSET, 0.0], lim)
    assert (res.time_s >= exact - 1e-9).all() and (res.time_s <= exact + 0.01 / 128).all()


def test_fig6_situation_finds_the_early_window():
    from erforce_ball_model.figures import fig6_curves

    c = fig6_curves(4000)
    ok = c["t_robot"] <= c["t_ball"]
    edges = np.flatnonzero(np.diff(ok.astype(int)))
    assert edges.size >= 3  # window opens, closes, catch-up opens
    first_window_m = c["dist"][edges[1]] - c["dist"][edges[0]]
    assert 0.2 <= first_window_m <= 0.3  # "a small window of roughly 0.25 m"
    t_catch = c["catch"].time_s
    assert float(c["ball"].distance_at(t_catch)) == pytest.approx(c["dist"][edges[0] + 1], abs=2e-3)


# --- robotTimeToBall: brute force --------------------------------------------------------------
def _dense_first_crossing(ball, p0, v0, lim, facing, t_max, step=1e-3, t_min=0.0):
    """Reference from the alpha-search time alone (not the sign test): dense grid + bisection."""
    grid = np.append(np.arange(t_min, t_max, step), t_max)
    off = OFFSET * np.array([math.cos(facing), math.sin(facing)])
    f = robot_time_to_pos(p0, v0, ball.position_at(grid) - off, lim) - grid
    idx = np.flatnonzero(f <= 0.0)
    if idx.size == 0:
        return math.inf, 0.0
    k = idx[0]
    gaps = np.flatnonzero(f[k:] > 0.0)
    width = (gaps[0] if gaps.size else grid.size - k) * step
    if k == 0:
        return t_min, width
    lo, hi = grid[k - 1], grid[k]
    for _ in range(25):
        mid = 0.5 * (lo + hi)
        if float(robot_time_to_pos(p0, v0, ball.position_at(mid) - off, lim)) <= mid:
            hi = mid
        else:
            lo = mid
    return hi, width


def test_matches_dense_search_on_random_scenarios():
    rng = np.random.default_rng(42)
    checked = wide = 0
    for _ in range(16):
        pos = rng.uniform([-3.0, -2.0], [3.0, 2.0])
        speed = rng.uniform(0.5, 5.0)
        ang = rng.uniform(0, 2 * math.pi)
        ball = BallTrajectory(pos, speed * np.array([math.cos(ang), math.sin(ang)]), speed * rng.uniform(1, 1.5))
        n = 20
        robots = pos + ball.direction * rng.uniform(0, 3, (n, 1)) + rng.normal(0, 0.8, (n, 2))
        vels = rng.normal(0, 0.7, (n, 2))
        facing = rng.uniform(0, 2 * math.pi, n)
        a_max, v_max = rng.uniform(1.5, 4.0, n), rng.uniform(1.5, 3.5, n)
        res = robot_time_to_ball(ball, robots, vels, RobotLimits(a_max, v_max), facing, field=DIV_B)
        t_max = min(float(ball.stop_time_s), float(ball.time_in_field(DIV_B)[1]))
        for r in range(n):
            lim = RobotLimits(a_max[r], v_max[r])
            t_ref, width = _dense_first_crossing(ball, robots[r], vels[r], lim, facing[r], t_max)
            checked += 1
            if math.isinf(t_ref):
                assert res.kind[r] != CatchKind.MOVING
                continue
            if width >= 0.02:  # the stated guarantee: windows >= h = 10 ms are never missed
                wide += 1
                assert res.kind[r] == CatchKind.MOVING
                assert t_ref - 1e-5 <= res.time_s[r] <= t_ref + 1e-3
            # found time is always feasible
            if res.kind[r] == CatchKind.MOVING:
                off = OFFSET * np.array([math.cos(facing[r]), math.sin(facing[r])])
                tgt = ball.position_at(res.time_s[r]) - off
                assert float(robot_time_to_pos(robots[r], vels[r], tgt, lim)) <= res.time_s[r] + 1e-5
    assert checked == 320 and wide > 40


def test_matches_dense_search_on_balls_bouncing_off_the_wall():
    """Balls heading for the wall, the search's field reaching the wall (margin = the run-off area): the catch
    windows after the bounce are found as the dense reference finds them on the same reflected path."""
    rng = np.random.default_rng(7)
    walls = Walls.of_field(DIV_B)
    checked = after_bounce = 0
    for _ in range(6):
        pos = rng.uniform([1.0, -2.0], [3.5, 2.0])
        speed = rng.uniform(2.5, 5.0)
        ang = rng.uniform(-0.8, 0.8)  # towards the +x wall
        ball = BallTrajectory(pos, speed * np.array([math.cos(ang), math.sin(ang)]), speed * rng.uniform(1, 1.5),
                              walls=walls)
        t_bounce = ball.pieces[1][0]
        n = 12
        robots = rng.uniform([0.0, -2.8], [4.7, 2.8], (n, 2))
        vels = rng.normal(0, 0.5, (n, 2))
        facing = rng.uniform(0, 2 * math.pi, n)
        lim = RobotLimits(3.0, 2.5)
        res = robot_time_to_ball(ball, robots, vels, lim, facing, field=DIV_B, field_margin_m=DIV_B.boundary_m)
        for r in range(n):
            t_ref, width = _dense_first_crossing(ball, robots[r], vels[r], lim, facing[r], ball.stop_time_s)
            checked += 1
            if math.isinf(t_ref):
                assert res.kind[r] == CatchKind.AT_REST
                continue
            if width >= 0.02:
                assert res.kind[r] == CatchKind.MOVING
                assert t_ref - 1e-5 <= res.time_s[r] <= t_ref + 1e-3
                after_bounce += t_ref > t_bounce
    assert checked == 72 and after_bounce >= 5
    # The stop point of a ball nobody meets in time lies inside the wall: the search's at-rest target.
    ball = BallTrajectory([3.0, 0.0], [3.0, 0.0], 3.0, walls=walls)
    res = robot_time_to_ball(ball, [[-4.0, 0.0]], [[0.0, 0.0]], RobotLimits(1.0, 0.5), 0.0, field=DIV_B,
                             field_margin_m=DIV_B.boundary_m)
    assert res.kind[0] == CatchKind.AT_REST
    assert res.ball_position_m[0].tolist() == pytest.approx(ball.stop_point.tolist(), abs=1e-12)
    assert res.ball_position_m[0, 0] < walls.half_x_m


def test_a_ball_off_the_wall_back_into_the_field_is_caught_inside():
    """From the run-off area towards the wall: straight it never enters the field; off the wall it rolls back
    in, and a robot waiting inside gets it there."""
    walls = Walls.of_field(DIV_B)
    ball = BallTrajectory([0.0, 3.15], [0.5, 3.0], 5.0, walls=walls)
    assert robot_time_to_ball(ball.within(None), [[0.3, 2.6]], [[0.0, 0.0]], RobotLimits(3.0, 2.5), -math.pi / 2,
                              field=DIV_B).kind[0] == CatchKind.NEVER
    res = robot_time_to_ball(ball, [[0.3, 2.6]], [[0.0, 0.0]], RobotLimits(3.0, 2.5), math.pi / 2, field=DIV_B)
    assert res.kind[0] != CatchKind.NEVER
    assert res.time_s[0] >= ball.time_in_field(DIV_B)[0]
    assert abs(res.ball_position_m[0, 1]) <= DIV_B.half_width_m + 1e-9


def test_a_ball_that_leaves_the_field_during_the_reaction_is_out_even_when_it_comes_back_off_the_wall():
    """catch_after_reaction searches the ball's first stretch inside the field from now: 0.2 m before the goal
    line at 3 m/s it is out before the robots react, and back in off the wall later; from the run-off area
    heading for the wall its first stretch inside is the one after the bounce."""
    walls = Walls.of_field(DIV_B)
    search = CatchSearch(1, RobotLimits(3.0, 2.5), field=DIV_B)
    robot, still, free = np.array([[3.0, 0.0]]), np.zeros((1, 2)), np.zeros(1, dtype=bool)
    leaving = BallTrajectory([4.3, 0.0], [3.0, 0.0], 3.0, walls=walls)
    assert leaving.time_in_field(DIV_B)[1] < 0.1 < leaving.stop_time_s
    assert leaving.advanced(0.1).time_in_field(DIV_B)[0] < math.inf  # on its own, the ball then comes back in
    res = catch_after_reaction(search, leaving, robot, still, 0.1, free, np.zeros(1), 0.1)
    assert res.kind[0] == CatchKind.NEVER
    coming_back = BallTrajectory([4.6, 0.0], [3.0, 0.0], 3.0, walls=walls)
    res = catch_after_reaction(search, coming_back, robot, still, 0.1, free, np.zeros(1), 0.1)
    assert res.kind[0] != CatchKind.NEVER and res.ball_position_m[0, 0] <= DIV_B.half_length_m

# --- bad input ---------------------------------------------------------------------------------
@pytest.mark.parametrize("a, v", [(0.0, 1.0), (1.0, -1.0), (np.nan, 1.0), (1.0, np.inf), ([1.0, 2.0], [1.0, 2.0, 3.0])])
def test_limits_validation(a, v):
    with pytest.raises(ValueError):
        RobotLimits(a, v)


def test_bad_input_raises():
    ball = BallTrajectory([0.0, 0.0], [1.0, 0.0], 1.0)
    lim = RobotLimits(2.0, 2.0)
    with pytest.raises(ValueError):
        robot_time_to_pos([np.nan, 0.0], [0.0, 0.0], [1.0, 0.0], lim)
    with pytest.raises(ValueError):
        robot_time_to_pos([0.0, 0.0, 0.0], [0.0, 0.0], [1.0, 0.0], lim)
    with pytest.raises(ValueError):
        robot_time_to_pos([0.0, 0.0], [0.0, 0.0], [1.0, 0.0], limits=2.0)
    with pytest.raises(ValueError):
        robot_time_to_ball(ball, [[0.0, 0.0]], [[0.0, 0.0], [1.0, 1.0]], lim, field=DIV_B)
    with pytest.raises(ValueError):
        robot_time_to_ball(ball, [[0.0, 0.0]], [[0.0, 0.0]], lim, facing_rad=np.nan, field=DIV_B)
    with pytest.raises(ValueError):
        robot_time_to_ball(ball, [[0.0, 0.0]], [[0.0, 0.0]], lim, grid_step_s=0.0, field=DIV_B)
    with pytest.raises(ValueError):
        robot_time_to_ball(ball, [[0.0, 0.0]], [[0.0, 0.0]], lim, dribbler_offset_m=-0.1, field=DIV_B)
    with pytest.raises(ValueError):
        robot_time_to_ball(ball, [[0.0, 0.0]] * 2, [[0.0, 0.0]] * 2, RobotLimits([1.0, 2.0, 3.0], 2.0), field=DIV_B)
    with pytest.raises(ValueError):
        robot_time_to_ball("ball", [[0.0, 0.0]], [[0.0, 0.0]], lim, field=DIV_B)
    # No field is an explicit choice: a forgotten field would search a ball rolling far off the field.
    with pytest.raises(ValueError, match="unbounded"):
        robot_time_to_ball(ball, [[0.0, 0.0]], [[0.0, 0.0]], lim)
    with pytest.raises(ValueError, match="one of them"):
        robot_time_to_ball(ball, [[0.0, 0.0]], [[0.0, 0.0]], lim, field=DIV_B, unbounded=True)
    # A ball that takes ~3e6 s to stop (a_roll -1e-6 m/s^2): refused at once, not searched for days.
    from erforce_ball_model.ball_model import BallModelParams
    crawler = BallTrajectory([0.0, 0.0], [3.0, 0.0], 3.0, BallModelParams(-2.5, -1e-6, 0.99))
    with pytest.raises(ValueError, match="grid points"):
        robot_time_to_ball(crawler, [[50.0, 50.0]], [[0.0, 0.0]], RobotLimits(1e-3, 1e-3), unbounded=True)


def test_compiled_ball_closed_forms_agree_with_the_python_ones():
    """ball_model's closed forms run as Python on floats and compiled inside the kernels: both must agree."""
    from erforce_ball_model.ball_model import BallModelParams, ball_distance, ball_time_to_distance

    rng = np.random.default_rng(3)
    for k in range(200):
        params = BallModelParams(rng.uniform(-6.0, -1.0), rng.uniform(-0.9, -0.05), rng.uniform(0.3, 1.0))
        speed = 0.0 if k % 10 == 0 else rng.uniform(0.01, 7.0)
        ang = rng.uniform(-math.pi, math.pi)
        ball = BallTrajectory(tuple(rng.uniform(-4.0, 4.0, 2)), (speed * math.cos(ang), speed * math.sin(ang)),
                              speed * rng.uniform(0.8, 2.0), params)
        stop = ball.stop_time_s
        times = np.array([0.0, 0.3 * ball.switch_time_s, ball.switch_time_s, 0.5 * (stop + 1e-3), stop, stop + 1.0])
        compiled = ball.distance_at(times)  # an array query runs compiled
        for t, got in zip(times, compiled, strict=True):
            assert got == pytest.approx(ball_distance(ball.floats, float(t)), rel=1e-12, abs=1e-15)
        d_stop = ball.stop_distance_m
        distances = np.array([0.0, 0.1 * d_stop, 0.9 * d_stop, d_stop, d_stop * 1.01 + 1e-3])
        for d, got in zip(distances, ball.time_to_distance(distances), strict=True):
            want = ball_time_to_distance(ball.floats, float(d))
            assert got == pytest.approx(want, rel=1e-12, abs=1e-15) or (math.isinf(got) and math.isinf(want))



def test_robot_time_curve_is_fig7s_t_robot_and_its_first_crossing_is_robot_time_to_ball():
    """t_robot(t_ball) by hand for a robot at rest on the ball's line, and the first t with t_robot <= t equals
    robotTimeToBall's catch time (within the search's sub-step)."""
    ball = BallTrajectory([0.0, 0.0], [2.0, 0.0], 2.0 / 0.6)  # rolling at 2 m/s along +x
    lim = RobotLimits(3.0, 3.0)
    robot = (2.0, 0.0)
    t = np.linspace(0.0, 2.0, 2001)
    curve = robot_time_curve(ball, t, robot, (0.0, 0.0), lim, facing_rad=math.pi, dribbler_offset_m=OFFSET)
    # The dribbler point of the robot must move to d(t) + OFFSET: |2 - OFFSET - d(t)| on a line, triangle
    # profile from rest (v_max 3 is never reached over < 2 m at a = 3): 2 sqrt(distance / a).
    d = 2.0 * t - 0.15 * t**2
    np.testing.assert_allclose(curve, 2.0 * np.sqrt(np.abs(2.0 - OFFSET - d) / 3.0), rtol=1e-6, atol=1e-6)
    one = robot_time_curve(ball, 0.5, robot, (0.0, 0.0), lim, facing_rad=math.pi, dribbler_offset_m=OFFSET)
    assert isinstance(one, float) and one == pytest.approx(curve[500], abs=1e-9)
    first = t[int(np.argmax(curve <= t))]
    catch = robot_time_to_ball(ball, robot, (0.0, 0.0), lim, math.pi, dribbler_offset_m=OFFSET, unbounded=True)
    assert isinstance(catch.time_s, float) and catch.kind == CatchKind.MOVING
    assert first - 1e-3 <= catch.time_s <= first + 1e-9


def _angle_error(a_rad, b_rad):
    return abs(math.remainder(a_rad - b_rad, 2.0 * math.pi))


def test_receive_facing_is_the_next_target_within_the_receive_angle_else_the_ball():
    """Ball rolling along +x: against it is 180 deg. A target straight up from the robot is 90 deg off that:
    beyond the 45 deg limit (the ball would only graze the front face), so the robot faces the ball. Up-left
    at 150 deg is 30 deg off: the robot faces the target. Either side of the limit, at 135 and 225 deg,
    1e-4 deg in and out."""
    assert MAX_RECEIVE_ANGLE_RAD == pytest.approx(math.radians(45.0))
    assert _angle_error(receive_facing((1.0, 0.0), (1.0, 1.0), (1.0, 3.0)), math.pi) < 1e-9
    up_left_150 = (1.0 - math.sqrt(3.0), 2.0)
    assert _angle_error(receive_facing((2.0, 0.0), (1.0, 1.0), up_left_150), math.radians(150.0)) < 1e-9
    eps = 1e-6
    for side in (1.0, -1.0):
        for off, expected in ((45.0 - 1e-4, "target"), (45.0 + 1e-4, "ball")):
            angle = math.pi - side * math.radians(off)
            got = receive_facing((1.0, 0.0), (0.0, 0.0), (math.cos(angle), math.sin(angle)))
            want = angle if expected == "target" else math.pi
            assert _angle_error(got, want) < eps, (side, off)
    # With a wider limit (80 deg), straight up is still beyond, 70 deg off is not.
    assert _angle_error(receive_facing((1.0, 0.0), (0.0, 0.0), (0.0, 1.0), math.radians(80.0)), math.pi) < 1e-9
    up_left_70 = (-math.cos(math.radians(70.0)), math.sin(math.radians(70.0)))
    assert _angle_error(receive_facing((1.0, 0.0), (0.0, 0.0), up_left_70, math.radians(80.0)),
                        math.radians(110.0)) < 1e-9
    assert _angle_error(receive_facing((1.0, 0.0), (2.0, 2.0), (2.0, 2.0)), math.pi) < 1e-9  # no direction: the ball
    for bad in (math.radians(90.0), -0.1, math.nan):
        with pytest.raises(ValueError, match="max_angle_rad"):
            receive_facing((1.0, 0.0), (0.0, 0.0), (0.0, 1.0), bad)
    with pytest.raises(ValueError, match="non-zero"):
        receive_facing((0.0, 0.0), (0.0, 0.0), (0.0, 1.0))


def test_the_catch_point_facing_the_target_is_offset_by_the_dribbler_distance_towards_it():
    """The paper's robotTimeToBall with targetpos: the ball rolls along +x on y = 0 (2 m/s, rolling), the
    robot receives facing up-left at 135 deg. The robot's centre at the catch is the ball's position minus
    the offset 0.0815 m * (cos 135, sin 135) = (-0.05763, 0.05763): 0.05763 m right of and below the ball,
    so on y = -0.05763. The time is the first at which robotTimeToPos to that point is within the ball's
    time, found here by brute force on a 1 ms grid."""
    ball = BallTrajectory((-2.0, 0.0), (2.0, 0.0), v_shoot_mps=2.0 / 0.6)
    limits = RobotLimits(a_max_mps2=2.0, v_max_mps=2.0)
    start = np.array([0.3, -0.6])
    facing = math.radians(135.0)
    np.testing.assert_allclose(contact_offset(facing, OFFSET), [-0.0815 / math.sqrt(2.0), 0.0815 / math.sqrt(2.0)])
    catch = robot_time_to_ball(ball, start, (0.0, 0.0), limits, facing_rad=facing, unbounded=True)
    side = 0.0815 / math.sqrt(2.0)
    assert catch.kind == CatchKind.MOVING
    assert catch.ball_position_m[1] == pytest.approx(0.0, abs=1e-12)
    np.testing.assert_allclose(catch.robot_target_m, catch.ball_position_m + [side, -side], atol=1e-12)
    t = np.arange(0.0, 3.0, 0.001)
    behind = ball.position_at(t) + [side, -side]
    feasible = robot_time_to_pos(start, np.zeros(2), behind, limits) <= t
    t_first = t[np.argmax(feasible)]
    assert t_first - 0.001 <= catch.time_s <= t_first + 0.001
    # Facing the ball instead, the centre is on the ball's line: a different, nearer point for this robot.
    facing_ball = robot_time_to_ball(ball, start, (0.0, 0.0), limits, facing_rad=math.pi, unbounded=True)
    assert facing_ball.robot_target_m[1] == pytest.approx(0.0, abs=1e-12)
    assert facing_ball.time_s != pytest.approx(catch.time_s, abs=1e-3)


# --- robotTimeToBall on chipped balls: brute force ----------------------------------------------
def _dense_first_chip_catch(chip, p0, v0, lim, facing, field, step=1e-3, receiving=False):
    """Reference for a chip: the first time on a dense grid at which the ball is low enough (an interceptor: its
    centre at most max_catch_height_m; a receiver: from when it stays at most max_receive_height_m), inside the
    field and reached by the alpha-search time alone; refined by bisection against the previous grid point (not
    feasible). Returns (time, width of that window on the grid)."""
    track = chip.ground_track()
    t_settled = chip.time_below_height_s(chip.params.max_receive_height_m)
    t_end = min(track.stop_time_s, track.time_in_field(field)[1])
    grid = np.append(np.arange(0.0, t_end, step), t_end)
    off = OFFSET * np.array([math.cos(facing), math.sin(facing)])

    def feasible(t):
        p = chip.position_at(t)
        inside = (np.abs(p[..., 0]) <= field.half_length_m) & (np.abs(p[..., 1]) <= field.half_width_m)
        low = np.asarray(t) >= t_settled if receiving else p[..., 2] <= chip.params.max_catch_height_m
        return low & inside & (robot_time_to_pos(p0, v0, p[..., :2] - off, lim) <= t)

    ok = feasible(grid)
    idx = np.flatnonzero(ok)
    if idx.size == 0:
        return math.inf, 0.0
    k = idx[0]
    gaps = np.flatnonzero(~ok[k:])
    width = (gaps[0] if gaps.size else grid.size - k) * step
    if k == 0:
        return 0.0, width
    lo, hi = grid[k - 1], grid[k]
    for _ in range(25):
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if bool(feasible(mid)) else (mid, hi)
    return hi, width


def _random_chip(rng):
    from erforce_ball_model.chip_model import ChipTrajectory

    pos = rng.uniform([-3.0, -2.0], [1.0, 2.0])
    speed, elevation = rng.uniform(2.0, 6.5), math.radians(rng.uniform(25.0, 60.0))
    heading = rng.uniform(-0.6, 0.6)
    vxy = speed * math.cos(elevation)
    return ChipTrajectory((*pos, 0.0), (vxy * math.cos(heading), vxy * math.sin(heading),
                                        speed * math.sin(elevation)), ChipParams())


@pytest.mark.parametrize("receiving", [False, True])
def test_chip_catches_match_the_dense_search_and_are_never_above_the_catch_height(receiving):
    """The flat case's guarantees on chips: a window of the reference at least 2 h wide is found, no earlier than
    its start and at most 1 ms later; every catch found is reachable, inside the field and with the ball low (an
    interceptor: below max_catch_height_m; a receiver: once it stays below max_receive_height_m)."""
    rng = np.random.default_rng(37)
    checked = wide = under = 0
    for _ in range(10):
        chip = _random_chip(rng)
        track = chip.ground_track()
        n = 16
        along = rng.uniform(0.0, 4.0, (n, 1))
        robots = track.position_at(0.0) + np.array([track.floats.ux, track.floats.uy]) * along
        robots += rng.normal(0.0, 0.4, (n, 2))
        vels = rng.normal(0, 0.5, (n, 2))
        facing = rng.uniform(0, 2 * math.pi, n)
        lim = RobotLimits(3.5, 2.5)
        res = robot_time_to_ball(chip, robots, vels, lim, facing, field=DIV_B, receiving=receiving)
        t_low = chip.time_below_height_s()
        t_settled = chip.time_below_height_s(chip.params.max_receive_height_m)
        for r in range(n):
            t_ref, width = _dense_first_chip_catch(chip, robots[r], vels[r], lim, facing[r], DIV_B,
                                                   receiving=receiving)
            checked += 1
            if res.kind[r] == CatchKind.MOVING:
                t = float(res.time_s[r])
                assert chip.position_at(t)[2] <= chip.params.max_catch_height_m + 1e-9
                assert not receiving or t >= t_settled - 1e-9
                off = OFFSET * np.array([math.cos(facing[r]), math.sin(facing[r])])
                tgt = chip.position_at(t)[:2] - off
                assert float(robot_time_to_pos(robots[r], vels[r], tgt, lim)) <= t + 1e-5
                assert t >= t_ref - 1e-5
            if math.isinf(t_ref):
                assert res.kind[r] != CatchKind.MOVING
                continue
            if width >= 0.02:
                wide += 1
                assert res.kind[r] == CatchKind.MOVING
                assert t_ref - 1e-5 <= res.time_s[r] <= t_ref + 1e-3
                under += t_ref >= t_low and math.dist(robots[r], track.position_at(0.5 * t_low)) < 1.0
    assert checked == 160 and wide > 40 and under > 3


def test_a_robot_under_the_flight_takes_the_chip_only_once_it_is_low():
    """Standing under the apex, facing the ball: a flat ball of that speed would be caught at once; the chip
    only where it has come down to max_catch_height_m, which the robot reaches by moving along the track."""
    from erforce_ball_model.chip_model import ChipTrajectory

    chip = ChipTrajectory((-2.0, 0.0, 0.0), (3.0, 0.0, 3.0), ChipParams())  # apex 0.46 m at x = -2 + 0.92
    t_apex = 3.0 / chip.params.g_mps2
    robot = np.array([-2.0 + 3.0 * t_apex + OFFSET, 0.0])
    flat = robot_time_to_ball(BallTrajectory((-2.0, 0.0), (3.0, 0.0), 3.0), robot, (0.0, 0.0), RobotLimits(),
                              math.pi, field=DIV_B)
    res = robot_time_to_ball(chip, robot, (0.0, 0.0), RobotLimits(), math.pi, field=DIV_B)
    assert flat.kind == CatchKind.MOVING and flat.time_s < t_apex + 0.01
    assert res.kind == CatchKind.MOVING
    assert res.time_s >= chip.time_below_height_s() - 1e-9
    assert chip.position_at(res.time_s)[2] <= chip.params.max_catch_height_m + 1e-9


def test_a_chip_over_the_field_line_is_never_caught_and_a_ground_ball_state_is_no_chip():
    from erforce_ball_model.chip_model import ChipTrajectory, flying_ball

    chip = ChipTrajectory((4.0, 0.0, 0.0), (3.0, 0.0, 3.0), ChipParams())  # lands at x = 5.8, beyond the field line 4.5
    res = robot_time_to_ball(chip, [[4.3, 0.0]], [[0.0, 0.0]], RobotLimits(), math.pi, field=DIV_B)
    assert res.kind[0] == CatchKind.NEVER or res.time_s[0] < 0.06  # only just after the kick, before it rises
    assert flying_ball((1.0, 2.0, 0.0), (1.0, 0.0, 0.0), ChipParams()) is None
    assert isinstance(flying_ball((1.0, 2.0, 0.1), (1.0, 0.0, -0.5), ChipParams()), ChipTrajectory)


@settings(max_examples=40, deadline=None)
@given(st.floats(1.0, 6.5), st.floats(20.0, 65.0), st.floats(-3.0, 3.0), st.floats(-2.5, 2.5),
       st.floats(0.0, 2 * math.pi))
def test_random_chips_are_caught_only_where_they_are_low_reachable_and_inside(speed, elevation_deg, rx, ry, facing):
    from erforce_ball_model.chip_model import ChipTrajectory

    e = math.radians(elevation_deg)
    chip = ChipTrajectory((-1.0, 0.0, 0.0), (speed * math.cos(e), 0.0, speed * math.sin(e)), ChipParams())
    lim = RobotLimits()
    res = robot_time_to_ball(chip, (rx, ry), (0.0, 0.0), lim, facing, field=DIV_B)
    if res.kind == CatchKind.MOVING:
        p = chip.position_at(res.time_s)
        assert p[2] <= chip.params.max_catch_height_m + 1e-9
        assert abs(p[0]) <= DIV_B.half_length_m and abs(p[1]) <= DIV_B.half_width_m
        assert float(robot_time_to_pos((rx, ry), (0.0, 0.0), p[:2] - contact_offset(facing, OFFSET), lim)) \
            <= res.time_s + 1e-5
        assert res.ball_position_m.tolist() == pytest.approx(p[:2].tolist(), abs=1e-9)
    elif res.kind == CatchKind.AT_REST:
        assert res.ball_position_m.tolist() == pytest.approx(chip.stop_point.tolist(), abs=1e-9)


def _hops_by_hand(vxy: float, vz: float, params: ChipParams) -> list[tuple[float, float, float, float]]:
    """(start time, start x, horizontal speed, vertical speed) of each hop of a chip kicked from x = 0 on the ground
    along +x, written out from ChipParams' definition: each hop lasts 2 vz / g, the bounce keeps damping_z of vz and
    damping_xy_first_hop, then damping_xy_other_hops, of vxy; a bounce leaving less than min_hop_vz_mps ends them."""
    hops, t, x, g = [], 0.0, 0.0, params.g_mps2
    while vz >= params.min_hop_vz_mps:
        hops.append((t, x, vxy, vz))
        t, x = t + 2.0 * vz / g, x + vxy * 2.0 * vz / g
        vxy *= params.damping_xy_first_hop if len(hops) == 1 else params.damping_xy_other_hops
        vz *= params.damping_z
    return hops


def test_a_receiver_takes_a_chip_once_it_stays_below_the_reception_height_an_interceptor_where_it_is_low():
    """A chip kicked at 4 m/s, 45 deg (vxy = vz = 2.8284 m/s) with the default model. Its hops by hand: apexes
    vz_k^2 / 2g = 0.4077, 0.1306, 0.0418, 0.0134 m; the reception height is a ball radius, 0.02135 m, so it stays
    low enough to take from hop 2's descent through it on, (vz_2 + sqrt(vz_2^2 - 2 g r)) / g after hop 2 starts.
    A robot at rest facing the ball with its dribbler at the second touchdown point: as an interceptor (its body
    stops a ball up to 0.15 m, and after the first touchdown the ball never rises that high) it meets the ball
    before that touchdown; as a receiver the ball hops on over its bar (up to 4.2 cm), so it takes it only after
    the settle time, where the ball is that low for good. A receiver whose
    dribbler stands beyond the settle point, on the track, and cannot move takes it as the ball arrives there."""
    from erforce_ball_model.chip_model import ChipTrajectory

    p = ChipParams()
    v = 4.0 / math.sqrt(2.0)
    hops = _hops_by_hand(v, v, p)
    g, r = p.g_mps2, p.max_receive_height_m
    apexes = [vz * vz / (2.0 * g) for *_, vz in hops]
    assert apexes[:4] == pytest.approx([0.4077, 0.1306, 0.0418, 0.0134], abs=1e-4)
    assert apexes[2] > r > apexes[3]
    t2, x2, vxy2, vz2 = hops[2]
    t_settle = t2 + (vz2 + math.sqrt(vz2 * vz2 - 2.0 * g * r)) / g
    x_settle = x2 + vxy2 * (t_settle - t2)
    chip = ChipTrajectory((0.0, 0.0, 0.0), (v, 0.0, v), p)
    assert chip.time_below_height_s(r) == pytest.approx(t_settle, abs=1e-12)
    at_touchdown = np.array([x2 + OFFSET, 0.0])  # the dribbler at the second touchdown (hop 2's start)
    lim = RobotLimits()
    stops = robot_time_to_ball(chip, at_touchdown, (0.0, 0.0), lim, math.pi, field=DIV_B)
    takes = robot_time_to_ball(chip, at_touchdown, (0.0, 0.0), lim, math.pi, field=DIV_B, receiving=True)
    assert stops.kind == CatchKind.MOVING and stops.time_s <= t2
    assert chip.position_at(stops.time_s)[2] <= p.max_catch_height_m
    assert takes.kind == CatchKind.MOVING and takes.time_s >= t_settle - 1e-9
    assert chip.position_at(takes.time_s)[2] <= r + 1e-12
    beyond = x_settle + 0.3
    t3, x3, vxy3, _ = max(h for h in hops if h[1] <= beyond)  # the hop that crosses it
    stands = RobotLimits(a_max_mps2=1e-6, v_max_mps=1e-6)
    waits = robot_time_to_ball(chip, (beyond + OFFSET, 0.0), (0.0, 0.0), stands, math.pi, field=DIV_B,
                               receiving=True)
    assert waits.time_s == pytest.approx(t3 + (beyond - x3) / vxy3, abs=1e-4)
    both = robot_time_to_ball(chip, [at_touchdown, at_touchdown], [(0.0, 0.0)] * 2, lim, math.pi, field=DIV_B,
                              receiving=[False, True])
    assert both.time_s.tolist() == pytest.approx([stops.time_s, takes.time_s], abs=1e-12)


def test_a_body_blocks_a_chip_only_where_it_is_low_enough():
    """robot_time_to_block with ``t_start_s``, on the chip above: it is low enough to stop (0.15 m) from
    a = (v + sqrt(v^2 - 2 g 0.15)) / g on (hop 1 rises to 0.13 m only), 0.167 m before its first touchdown. Two
    robots standing on the track (body radius 0.11 m): one centred 0.5 m before the touchdown, whose body the ball
    passes while still high (it flies over); one 0.1 m before it, whose body the ball is inside when it comes low:
    blocked at a. On the ground track alone (a flat ball's shadow) both would block where the ball's centre first
    reaches their body."""
    from erforce_ball_model.chip_model import ChipTrajectory

    p = ChipParams()
    v = 4.0 / math.sqrt(2.0)
    chip = ChipTrajectory((0.0, 0.0, 0.0), (v, 0.0, v), p)
    (_, _), (a, b) = chip.low_windows_s()
    t_down = 2.0 * v / p.g_mps2
    assert a == pytest.approx((v + math.sqrt(v * v - 2.0 * p.g_mps2 * p.max_catch_height_m)) / p.g_mps2, abs=1e-12)
    assert b == math.inf and v * (t_down - a) == pytest.approx(0.167, abs=1e-3)
    robots = [(v * t_down - 0.5, 0.0), (v * t_down - 0.1, 0.0)]
    limits = RobotLimits(a_max_mps2=1e-6, v_max_mps=1e-6)  # they stand
    track = chip.advanced(a).ground_track()
    blocked = robot_time_to_block(track, robots, [(0.0, 0.0)] * 2, limits, 0.11, t_down, reaction_s=0.1, t_start_s=a)
    assert blocked[0] == math.inf and blocked[1] == pytest.approx(a, abs=1e-9)
    shadow = robot_time_to_block(chip.ground_track(), robots, [(0.0, 0.0)] * 2, limits, 0.11, t_down, reaction_s=0.1)
    assert shadow.tolist() == pytest.approx([(v * t_down - 0.61) / v, (v * t_down - 0.21) / v], abs=1e-9)
