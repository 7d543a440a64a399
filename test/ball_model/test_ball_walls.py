"""The ball's path off the field wall (walls.Walls, BallTrajectory's pieces): hand-computed bounces,
brute-force integration of the same dynamics, the simulator's ball on the same field, the predictor's stop point."""

import math
import pickle

import numpy as np
import pytest

from erforce_ball_model.ball_model import BallModelParams, BallPhase, BallTrajectory
from erforce_ball_model.predictor import BallPredictor, PredictorConfig
from erforce_ball_model.walls import Walls
from erforce_interfaces.wire.robot_config import FieldConfig

DIV_B = FieldConfig.preset("division_b")
WALLS = Walls.of_field(DIV_B)
MODEL = BallModelParams()  # a_slide -2.5, a_roll -0.3, c_switch 0.6
WALL_X = 4.5 + 0.3 - 0.02135  # half length + run-off area - the ball's radius: where the centre meets the wall
WALL_Y = 3.0 + 0.3 - 0.02135


def rolling(x, y, vx, vy, walls=WALLS, params=MODEL):
    """A ball that already rolls (v_shoot high enough that v_switch is the speed now)."""
    return BallTrajectory((x, y), (vx, vy), math.hypot(vx, vy) / params.c_switch, params, walls)


def test_the_wall_stands_at_the_run_off_areas_edge_less_the_ball_radius():
    assert (WALLS.half_x_m, WALLS.half_y_m) == pytest.approx((WALL_X, WALL_Y), abs=1e-12)
    div_a = Walls.of_field(FieldConfig.preset("division_a"), restitution=0.3)
    assert (div_a.half_x_m, div_a.half_y_m, div_a.restitution) == pytest.approx((6.3 - 0.02135, 4.8 - 0.02135, 0.3))


def test_a_ball_rolled_straight_at_the_wall_bounces_by_hand():
    """Rolling at 2 m/s from x = 3 along +x. Touchdown after D = WALL_X - 3 at v1 = sqrt(4 - 2 * 0.3 * D); the wall
    sends back e v1 = 0.6 v1 while the spin still rolls towards the wall (-v1): the slip 1.6 v1 shrinks at
    2.5 * (1 + 1 / 0.4) = 8.75 m/s^2 and the ball ends rolling at (0.6 v1 - 0.4 v1) / 1.4 = v1 / 7."""
    ball = rolling(3.0, 0.0, 2.0, 0.0)
    d = WALL_X - 3.0
    v1 = math.sqrt(4.0 - 0.6 * d)
    t1 = (2.0 - v1) / 0.3
    assert ball.position_at(t1).tolist() == pytest.approx([WALL_X, 0.0], abs=1e-9)  # touchdown on the wall
    assert float(ball.speed_at(t1 - 1e-9)) == pytest.approx(v1, abs=1e-6)
    assert ball.velocity_at(t1 + 1e-9).tolist() == pytest.approx([-0.6 * v1, 0.0], abs=1e-6)  # e * normal
    slide_s = 1.6 * v1 / 8.75
    v_end = v1 / 7.0
    slide_m = 0.5 * (0.6 * v1 + v_end) * slide_s
    roll_m = v_end**2 / 0.6
    assert ball.stop_point.tolist() == pytest.approx([WALL_X - slide_m - roll_m, 0.0], abs=1e-9)
    assert ball.stop_time_s == pytest.approx(t1 + slide_s + v_end / 0.3, abs=1e-9)
    assert ball.stop_distance_m == pytest.approx(d + slide_m + roll_m, abs=1e-9)
    assert ball.phase_at(t1 + 0.5 * slide_s) == BallPhase.SLIDING
    assert ball.phase_at(t1 + slide_s + 0.01) == BallPhase.ROLLING
    assert ball.phase_at(ball.stop_time_s) == BallPhase.STOPPED
    # Without the wall the same ball would rest 6.67 m on, far beyond it.
    assert rolling(3.0, 0.0, 2.0, 0.0, walls=None).stop_point[0] == pytest.approx(3.0 + 4.0 / 0.6)


def test_restitution_zero_leaves_a_ball_rolled_straight_at_the_wall_there():
    ball = rolling(3.0, 1.0, 2.0, 0.0, walls=Walls.of_field(DIV_B, restitution=0.0))
    assert ball.stop_point.tolist() == pytest.approx([WALL_X, 1.0], abs=1e-12)
    assert ball.stop_time_s == pytest.approx((2.0 - math.sqrt(4.0 - 0.6 * (WALL_X - 3.0))) / 0.3)


def _integrate(x, y, vx, vy, spin_x, spin_y, walls, params, dt=1e-4):
    """Brute force: the point ball's velocity v and its spin's rolling velocity u stepped in time. The slip
    v - u decays (carpet friction |a_slide| on v, |a_slide| / k on u); without slip the ball rolls at a_roll;
    at a wall the normal speed is reversed times e and the speed along it cut by friction, u unchanged."""
    a_s, a_r, k = -params.a_slide_mps2, -params.a_roll_mps2, walls.inertia_factor
    p, v, u = [x, y], [vx, vy], [spin_x, spin_y]
    half = (walls.half_x_m, walls.half_y_m)
    for _ in range(1_000_000):
        sx, sy = v[0] - u[0], v[1] - u[1]
        s = math.hypot(sx, sy)
        before = list(v)
        if s > a_s * (1.0 + 1.0 / k) * dt:
            v = [v[0] - a_s * sx / s * dt, v[1] - a_s * sy / s * dt]
            u = [u[0] + a_s / k * sx / s * dt, u[1] + a_s / k * sy / s * dt]
        else:  # the slip vanishes within the step: v + k u is kept
            v = [(v[0] + k * u[0]) / (1.0 + k), (v[1] + k * u[1]) / (1.0 + k)]
            speed = math.hypot(*v)
            if speed <= a_r * dt:
                return p
            v = [c * (speed - a_r * dt) / speed for c in v]
            u = list(v)
        p = [p[0] + 0.5 * (before[0] + v[0]) * dt, p[1] + 0.5 * (before[1] + v[1]) * dt]
        for axis in (0, 1):
            if abs(p[axis]) > half[axis] and p[axis] * v[axis] > 0.0:
                p[axis] = math.copysign(half[axis], p[axis])
                vn, vt = abs(v[axis]), v[1 - axis]
                jn = (1.0 + walls.restitution) * vn
                jt = max(-walls.friction * jn, min(walls.friction * jn, -vt / (1.0 + 1.0 / k)))
                v[axis] = -math.copysign(walls.restitution * vn, v[axis])
                v[1 - axis] = vt + jt
    raise AssertionError("the brute-force ball never stopped")


@pytest.mark.parametrize(("start", "velocity", "v_shoot", "tol_m"), [
    ((3.0, 0.0), (2.0, 0.0), None, 2e-3),  # rolling, straight at the wall
    ((3.0, 0.0), (2.0, 1.0), None, 2e-3),  # rolling, obliquely
    ((2.0, 0.0), (4.0, 0.3), 4.0, 2e-3),  # a kick: slides, rolls, meets the wall
    ((3.0, 0.0), (5.0, 0.5), 5.0, 2e-3),  # a kick still sliding when it meets the wall
    ((-2.0, 1.0), (-3.0, -2.0), 3.6056, 2e-3),  # to the other end
    # into a corner: the second wall comes during the slide off the first, whose curve the piece takes as
    # its chord (exact at the ends)
    ((3.5, 2.5), (2.0, 1.0), None, 0.05),
])
def test_the_stop_point_after_bounces_agrees_with_brute_force_integration(start, velocity, v_shoot, tol_m):
    speed = math.hypot(*velocity)
    v_shoot = speed / MODEL.c_switch if v_shoot is None else max(v_shoot, speed)
    ball = BallTrajectory(start, velocity, v_shoot, MODEL, WALLS)
    assert len(ball.pieces) >= 3  # it met a wall
    k = WALLS.inertia_factor
    v_switch = min(speed, MODEL.c_switch * v_shoot)
    spin = speed if v_switch == speed else ((1.0 + k) * v_switch - speed) / k  # v + k spin kept while sliding
    u = np.array(velocity) / speed * spin
    truth = _integrate(*start, *velocity, *u, WALLS, MODEL)
    assert abs(truth[0]) <= WALL_X and abs(truth[1]) <= WALL_Y
    assert math.dist(ball.stop_point, truth) <= tol_m


def test_the_pieces_are_one_continuous_path_answered_alike_by_every_query():
    ball = BallTrajectory((2.0, 1.0), (4.0, 2.0), 5.0, MODEL, WALLS)
    assert len(ball.pieces) >= 4
    t = np.linspace(0.0, ball.stop_time_s + 0.5, 701)
    positions = ball.position_at(t)
    assert (np.abs(positions) <= [WALL_X + 1e-9, WALL_Y + 1e-9]).all()  # never beyond the wall
    steps = np.linalg.norm(np.diff(positions, axis=0), axis=1)
    assert steps.max() < 5.0 * (t[1] - t[0]) + 1e-9  # no jump at a bounce
    for start, piece in ball.pieces[1:]:  # each piece starts where the one before ended
        assert ball.position_at(start).tolist() == pytest.approx([piece.x_m, piece.y_m], abs=1e-9)
    # arrays and scalars, distance and its inverse, the same ball later
    some = t[::37]
    assert ball.position_at(some).ravel().tolist() == pytest.approx(
        np.ravel([ball.position_at(float(x)) for x in some]).tolist())
    assert ball.speed_at(some).tolist() == pytest.approx([ball.speed_at(float(x)) for x in some])
    distance = ball.distance_at(some)
    assert (np.diff(ball.distance_at(t)) >= -1e-12).all()
    moving = some < ball.stop_time_s
    assert ball.time_to_distance(distance[moving]).tolist() == pytest.approx(some[moving].tolist(), abs=1e-9)
    assert math.isinf(ball.time_to_distance(ball.stop_distance_m + 0.01))
    later = ball.advanced(0.9)
    assert later.position_at(some).ravel().tolist() == pytest.approx(ball.position_at(some + 0.9).ravel().tolist(),
                                                                     abs=1e-9)
    assert later.stop_point.tolist() == pytest.approx(ball.stop_point.tolist(), abs=1e-12)
    at_rest = ball.advanced(ball.stop_time_s + 1.0)
    assert at_rest.stop_time_s == 0.0 and at_rest.phase == BallPhase.STOPPED
    assert at_rest.position_m.tolist() == pytest.approx(ball.stop_point.tolist(), abs=1e-12)
    assert pickle.loads(pickle.dumps(later)).stop_point.tolist() == later.stop_point.tolist()
    assert ball.within(None).stop_point.tolist() == pytest.approx(BallTrajectory((2.0, 1.0), (4.0, 2.0), 5.0,
                                                                                  MODEL).stop_point.tolist())
    assert ball.table.shape == (len(ball.pieces), 16)


def test_a_ball_in_the_run_off_area_comes_back_in_off_the_wall():
    """Beyond the side line and heading out: straight, it never enters the field; off the wall it does."""
    straight = rolling(0.0, 3.2, 1.0, 3.0, walls=None)
    assert straight.time_in_field(DIV_B) == (math.inf, math.inf)
    ball = rolling(0.0, 3.2, 1.0, 3.0)
    t_in, t_out = ball.time_in_field(DIV_B)
    assert 0.0 < t_in < math.inf
    assert ball.position_at(t_in)[1] == pytest.approx(3.0, abs=1e-9)
    assert t_out == math.inf or t_out > t_in


@pytest.mark.parametrize(("start", "velocity", "spin_ratio", "tol_m"), [
    ((3.0, 0.0), (2.0, 0.0), None, 0.01),  # rolling straight at the wall
    ((3.0, 0.0), (2.0, 1.0), None, 0.01),  # rolling obliquely
    ((2.0, 0.0), (4.0, 0.3), -0.4, 0.01),  # a kick (backspin: c_switch 0.6) sliding into the wall
    ((3.5, 2.5), (2.0, 1.0), None, 0.25),  # a corner: the first wall's friction spins the ball (wz), unmodelled
])
def test_the_simulator_and_the_prediction_agree_where_the_ball_stops_after_the_wall(start, velocity, spin_ratio,
                                                                                      tol_m):
    from erforce_sim.ball import BallState
    from erforce_sim.world import World

    world = World(DIV_B, [], seed=0)
    r = world.ball_params.radius_m
    vx, vy = velocity
    speed = math.hypot(vx, vy)
    ratio = 1.0 if spin_ratio is None else spin_ratio  # spin as rolling velocity / velocity
    world.set_ball_state(BallState(*start, vx, vy, wx=-ratio * vy / r, wy=ratio * vx / r))
    while world.ball_state().speed_mps > 0.0 and world.t_s < 30.0:
        world.step(0.01)
    b = world.ball_state()
    v_shoot = speed / MODEL.c_switch if spin_ratio is None else speed
    ball = BallTrajectory(start, velocity, v_shoot, MODEL, WALLS)
    assert math.dist((b.x, b.y), ball.stop_point) <= tol_m


def _kick_frames(predictor, x0, y0, vx, vy, n=8, t0=1.0):
    frame = None
    for k in range(n):
        frame = predictor.ball_frame(t0 + 0.01 * k, x0 + vx * 0.01 * k, y0 + vy * 0.01 * k)
    return frame


def test_the_predictors_stop_point_lies_inside_the_wall():
    predictor = BallPredictor(PredictorConfig(num_robots=1))
    frame = _kick_frames(predictor, 2.0, 1.0, 4.0, 1.5)
    x, y = frame.stop_point_m
    assert abs(x) <= WALL_X + 1e-9 and abs(y) <= WALL_Y + 1e-9
    straight = frame.trajectory.within(None).stop_point
    assert straight[0] > WALL_X + 1.0  # what it used to publish
    # the field of the world in effect (here SSL geometry's Division A) places the wall
    predictor.set_vision_geometry(field=FieldConfig.preset("division_a"))
    frame = _kick_frames(predictor, 2.0, 1.0, 4.0, 1.5, t0=3.0)
    x, y = frame.stop_point_m
    assert 4.8 < x <= 6.3 - 0.02135 + 1e-9 and abs(y) <= 4.8


def test_walls_refuse_bad_numbers():
    for bad in (dict(half_x_m=0.0, half_y_m=1.0), dict(half_x_m=1.0, half_y_m=1.0, restitution=1.5),
                dict(half_x_m=1.0, half_y_m=1.0, restitution=math.nan),
                dict(half_x_m=1.0, half_y_m=1.0, friction=-1.0)):
        with pytest.raises(ValueError):
            Walls(**bad)
    with pytest.raises(ValueError):
        BallTrajectory((0.0, 0.0), (1.0, 0.0), 1.0, MODEL, walls="division_b")
    with pytest.raises(ValueError):
        PredictorConfig(wall_restitution=-0.1)
