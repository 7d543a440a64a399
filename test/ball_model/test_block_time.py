"""robotTimeToBlock (catch_time.robot_time_to_block): hand cases, a closed-form root and a dense brute force."""

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from erforce_ball_model import catch_time
from erforce_ball_model.ball_model import BallModelParams, BallTrajectory
from erforce_ball_model.catch_time import RobotLimits, can_reach, robot_time_to_block

R_BODY = 0.09 + 0.02135  # robot radius + ball radius
# A ball that keeps its speed (decelerations of nanometres per s^2): its place at t is v t, by hand.
STEADY = BallModelParams(a_slide_mps2=-2e-9, a_roll_mps2=-1e-9, c_switch=1.0)
FAST = RobotLimits(a_max_mps2=3.0, v_max_mps=100.0)  # no speed cap within these cases: d = a t^2 / 4 at rest


def steady_ball(v_mps: float) -> BallTrajectory:
    return BallTrajectory((0.0, 0.0), (v_mps, 0.0), v_shoot_mps=v_mps, params=STEADY)


@pytest.mark.parametrize("offset_m", [0.0, 0.05, 0.11])
def test_a_robot_standing_in_the_lane_blocks_when_the_ball_reaches_its_body(offset_m):
    # not reacting (reaction longer than the pass): the ball runs into it where its centre is R_BODY away
    ball = steady_ball(2.0)
    t = robot_time_to_block(ball, [(1.5, offset_m)], [(0.0, 0.0)], FAST, R_BODY, 5.0, reaction_s=10.0)
    along = 1.5 - math.sqrt(R_BODY ** 2 - offset_m ** 2)
    assert t[0] == pytest.approx(along / 2.0, abs=1e-6)


def test_a_standing_robot_beside_the_lane_never_blocks_without_moving():
    ball = steady_ball(2.0)
    t = robot_time_to_block(ball, [(1.5, R_BODY + 0.01)], [(0.0, 0.0)], FAST, R_BODY, 5.0, reaction_s=10.0)
    assert t[0] == math.inf


def test_the_ball_starting_inside_the_body_is_blocked_at_once():
    t = robot_time_to_block(steady_ball(2.0), [(0.05, 0.0)], [(0.0, 0.0)], FAST, R_BODY, 5.0, reaction_s=0.1)
    assert t[0] == 0.0


@pytest.mark.parametrize(("x_m", "side_m", "reaction_s"), [(1.0, 0.5, 0.0), (0.6, 0.8, 0.0), (1.5, 0.3, 0.1),
                                                            (3.0, 1.2, 0.2)])
def test_a_robot_at_rest_beside_the_lane_steps_in_at_the_closed_form_time(x_m, side_m, reaction_s):
    # At rest, straight bang-bang to the nearest point of the ball's body disc: distance a tau^2 / 4 in tau.
    # The first block solves  hypot(v t - x, side) - R = a (t - reaction)^2 / 4.
    v, a = 2.0, 3.0
    ball = steady_ball(v)

    def gap(t):
        return math.hypot(v * t - x_m, side_m) - R_BODY - a * max(t - reaction_s, 0.0) ** 2 / 4.0

    ts = np.arange(0.0, 5.0, 1e-4)
    first = next(t for t in ts if gap(t) <= 0.0)
    expected = brentq(gap, first - 1e-4, first) if first > 0.0 else 0.0
    t = robot_time_to_block(ball, [(x_m, side_m)], [(0.0, 0.0)], FAST, R_BODY, 5.0, reaction_s=reaction_s)
    assert t[0] == pytest.approx(expected, abs=1e-4)


def test_the_horizon_ends_the_search():
    # the ball would reach the body at 0.75 s; the pass ends (the receiver has it) at 0.5 s
    t = robot_time_to_block(steady_ball(2.0), [(1.5 + R_BODY, 0.0)], [(0.0, 0.0)], FAST, R_BODY, 0.5,
                            reaction_s=10.0)
    assert t[0] == math.inf


def brute_block_time(ball, p0, v0, limits, t_end, reaction_s, dt=1e-3):
    """The first time on a 1 ms grid at which some point of the body disc (24 angles x 4 radii and the ball's
    centre) is reachable at rest within the budget, or the unreacted robot already covers the ball."""
    a, vmax = float(limits.a_max_mps2), float(limits.v_max_mps)
    angles = np.linspace(0.0, 2.0 * math.pi, 24, endpoint=False)
    ring = np.concatenate([[(0.0, 0.0)]] + [r * np.stack([np.cos(angles), np.sin(angles)], 1)
                                            for r in (0.25, 0.5, 0.75, 1.0)]) * R_BODY
    for t in np.arange(0.0, t_end, dt):
        b = ball.position_at(t)
        if t < reaction_s:
            if math.dist(b, p0) <= R_BODY:
                return t
            continue
        if any(can_reach(b + q - p0, v0, t - reaction_s, a, vmax) for q in ring):
            return t
    return math.inf


@pytest.mark.parametrize("seed", range(12))
def test_dense_brute_force(seed):
    rng = np.random.default_rng(seed)
    limits = RobotLimits(a_max_mps2=4.5, v_max_mps=2.5)
    ball = BallTrajectory((0.0, 0.0), (rng.uniform(1.5, 5.0), rng.uniform(-0.5, 0.5)), v_shoot_mps=5.0)
    n = 4
    p0 = np.stack([rng.uniform(0.3, 3.0, n), rng.uniform(-0.8, 0.8, n)], 1)
    still = seed % 2 == 0
    v0 = np.zeros((n, 2)) if still else rng.uniform(-1.5, 1.5, (n, 2))
    reaction = float(rng.choice([0.0, 0.1]))
    t = robot_time_to_block(ball, p0, v0, limits, R_BODY, 1.5, reaction_s=reaction)
    for r in range(n):
        ref = brute_block_time(ball, p0[r], v0[r], limits, 1.5, reaction)
        if still:  # exact: the nearest disc point is the robot's best target
            assert t[r] == pytest.approx(ref, abs=2e-3) or (ref == math.inf and t[r] == math.inf)
        else:  # achievable, never earlier than the dense reference can make it, and near it
            assert t[r] >= ref - 2e-3
            assert t[r] <= ref + 0.05 or (ref == math.inf and t[r] == math.inf)


def test_the_block_search_run_as_python_gives_the_compiled_numbers(monkeypatch):
    """kernels="background" before numba is in answers with the same loop as Python: equal to the bit, for robots
    at rest and moving, before and after their reaction, on the lane and beside it; "now" is the compiled one."""
    rng = np.random.default_rng(11)
    limits = RobotLimits(a_max_mps2=4.5, v_max_mps=2.5)
    balls, python = [], []
    monkeypatch.setattr(catch_time, "kernels_loaded", lambda: False)  # as while the thread still loads
    monkeypatch.setattr(catch_time, "load_kernels_in_background", lambda: None)
    for k in range(24):
        ball = BallTrajectory((0.0, 0.0), (rng.uniform(1.0, 6.0), rng.uniform(-1.0, 1.0)), v_shoot_mps=6.0)
        p0 = np.stack([rng.uniform(-0.2, 4.0, 5), rng.uniform(-1.0, 1.0, 5)], 1)
        v0 = rng.uniform(-2.0, 2.0, (5, 2)) * (k % 3 != 0)
        args = (ball, p0, v0, limits, R_BODY, float(rng.uniform(0.2, 3.0)))
        reaction = float(rng.choice([0.0, 0.1, 0.3]))
        balls.append((args, reaction))
        python.append(robot_time_to_block(*args, reaction_s=reaction, kernels="background"))
    monkeypatch.undo()
    for (args, reaction), want in zip(balls, python, strict=True):
        assert np.array_equal(robot_time_to_block(*args, reaction_s=reaction, kernels="now"), want)
    assert np.isfinite(np.concatenate(python)).any() and np.isinf(np.concatenate(python)).any()
    with pytest.raises(ValueError, match="kernels"):
        robot_time_to_block(*balls[0][0], kernels="later")
