"""World API: validation, determinism, collisions, energy bookkeeping, never non-finite state."""

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from erforce_interfaces.wire.robot_config import FieldConfig, RobotConfig
from erforce_sim.ball import BallState
from erforce_sim.world import World
from erforce_sim.world_types import PhysicsParams, RobotSpec

CFG = RobotConfig()
FIELD = FieldConfig.preset("division_b")  # walls at |x| <= 4.8, |y| <= 3.3


def test_placement_outside_walls_is_rejected_clearly():
    w = World(FIELD, [RobotSpec()], seed=0)
    with pytest.raises(ValueError, match="outside the field walls"):
        w.place_robot(0, 4.75, 0.0, 0.0)  # centre inside the wall but the body is not
    with pytest.raises(ValueError, match="outside the field walls"):
        w.place_ball(0.0, -3.3)
    with pytest.raises(ValueError, match="outside the field walls"):
        World(FIELD, [RobotSpec(x=10.0)])
    w.place_robot(0, 4.8 - 0.09, 3.3 - 0.09, 1.0)  # exactly touching is allowed
    w.place_ball(4.8 - 0.02135, 0.0)
    for bad in (float("nan"), float("inf")):
        with pytest.raises(ValueError):
            w.place_robot(0, bad, 0.0, 0.0)
        with pytest.raises(ValueError):
            w.place_ball(0.0, 0.0, vx=bad)
    with pytest.raises(ValueError, match="plausible"):
        w.place_robot(0, 0.0, 0.0, 0.0, vx=1e9)
    with pytest.raises(ValueError):
        w.place_ball(0.0, 0.0, spin_ratio=3.0)


def test_step_validation():
    w = World(FIELD, [RobotSpec()], seed=0)
    for bad in (0.0, -0.001, float("nan"), float("inf"), 1.0):
        with pytest.raises(ValueError):
            w.step(bad)
    assert w.t_s == 0.0
    w.step(0.001)
    assert w.t_s == pytest.approx(0.001)


def test_constructor_validation():
    with pytest.raises(ValueError, match="duplicate"):
        World(FIELD, [RobotSpec(x=-1.0), RobotSpec(x=1.0)])
    with pytest.raises(ValueError):
        RobotSpec(team="red")
    with pytest.raises(ValueError):
        RobotSpec(kicker_plate="convex")
    with pytest.raises(ValueError):
        PhysicsParams(substep_hz=5000.0)
    with pytest.raises(ValueError):
        PhysicsParams(traction_damping_nspm=float("nan"))
    with pytest.raises(ValueError):
        World(FIELD, [RobotSpec()], seed=-1)


def test_index_of_and_state_accessors():
    w = World(FIELD, [RobotSpec(x=-1.0), RobotSpec(x=1.0, team="blue", robot_id=3)], BallState(0.5, 0.5), seed=0)
    assert w.index_of("blue", 3) == 1
    with pytest.raises(ValueError):
        w.index_of("blue", 4)
    assert w.robot_state(1).x == 1.0
    assert w.ball_state() == BallState(0.5, 0.5)
    assert w.wheel_speeds_radps(0).shape == (4,)


def test_robot_stays_inside_walls_and_robots_do_not_overlap():
    w = World(FIELD, [RobotSpec(x=3.0, y=0.0), RobotSpec(x=4.0, y=0.05, robot_id=1)], seed=0)
    a = np.array(CFG.wheel_angles_rad)
    forward = -np.sin(a) / np.max(np.abs(np.sin(a)))
    w.set_duty(0, forward)
    for _ in range(3000):
        w.step(0.001)
        r0, r1 = w.robot_state(0), w.robot_state(1)
        assert r0.x <= 4.8 - 0.09 + 1e-9 and r1.x <= 4.8 - 0.09 + 1e-9
        assert math.hypot(r0.x - r1.x, r0.y - r1.y) >= 0.18 - 0.01  # at most a substep of overlap
    assert w.robot_state(1).x > 4.2  # robot 0 pushed robot 1 towards the wall


def coasting_world() -> World:
    specs = [RobotSpec(x=4.4, y=2.0, theta=0.5), RobotSpec(x=4.0, y=2.05, robot_id=1, kicker_plate="curved")]
    w = World(FIELD, specs, seed=0)
    w.place_ball(3.5, 2.0, 5.0, 0.3, spin_ratio=0.0)  # sliding into robot 1
    w.place_robot(0, 4.4, 2.0, 0.5, vx=2.5, vy=1.0, w=4.0)  # towards the corner
    w.place_robot(1, 4.0, 2.05, 0.0, vx=3.0, vy=0.0, w=-3.0)  # chasing robot 0
    # spin the motors up so currents and wheel slip start non-zero, then coast with duty 0
    w.set_duty(0, [0.5, -0.7, 0.9, -0.2])
    w.set_duty(1, [-0.4, 0.6, 0.3, 0.8])
    for _ in range(20):
        w.step(0.001)
    w.set_duty(0, [0.0] * 4)
    w.set_duty(1, [0.0] * 4)
    return w


def test_energy_never_increases_without_input_including_collisions():
    w = coasting_world()
    energies = [w.energy()]
    for _ in range(1500):
        w.step(0.001)
        energies.append(w.energy())
    totals = np.array([e.total_j for e in energies])
    assert totals[0] > 1.0 and energies[0].magnetic_j > 0.0
    increases = np.diff(totals)
    assert increases.max() <= 1e-9 * totals[0]
    assert totals[-1] < 0.2 * totals[0]


def test_energy_collisions_happened_in_coasting_scenario():
    # guards the energy test above: its scenario really contains wall, robot and ball contacts
    w = coasting_world()
    hit_wall = robots_touched = ball_touched = False
    for _ in range(1500):
        w.step(0.001)
        r0, r1, b = w.robot_state(0), w.robot_state(1), w.ball_state()
        hit_wall |= r0.x >= 4.8 - 0.09 - 1e-6 or r0.y >= 3.3 - 0.09 - 1e-6
        robots_touched |= math.hypot(r0.x - r1.x, r0.y - r1.y) <= 0.18 + 1e-6
        ball_touched |= min(math.hypot(b.x - r.x, b.y - r.y) for r in (r0, r1)) <= 0.09 + 0.02135 + 1e-6
    assert hit_wall and robots_touched and ball_touched


def test_deterministic_for_seed():
    def run():
        w = coasting_world()
        for _ in range(200):
            w.step(0.001)
        return w.robot_state(0), w.robot_state(1), w.ball_state(), w.poll_vision()

    assert run() == run()


duty = st.floats(min_value=-3.0, max_value=3.0, allow_nan=False)
position = st.tuples(st.floats(-4.7, 4.7), st.floats(-3.2, 3.2), st.floats(-10.0, 10.0))
action = st.one_of(
    st.tuples(st.just("duty"), st.integers(0, 1), st.lists(duty, min_size=4, max_size=4)),
    st.tuples(st.just("kick"), st.integers(0, 1), st.floats(0.0, 20.0), st.floats(-1.0, 1.0)),
    st.tuples(st.just("robot"), st.integers(0, 1), position, st.floats(-5.0, 5.0), st.floats(-5.0, 5.0)),
    # |v| <= 14.1 * sqrt(2) < 20 m/s, World's plausibility limit (beyond it place_ball refuses, tested elsewhere)
    st.tuples(st.just("ball"), position, st.floats(-14.1, 14.1), st.floats(-14.1, 14.1), st.floats(-1.0, 1.0)),
    st.tuples(st.just("dribble"), st.integers(0, 1), st.booleans()),
)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(actions=st.lists(action, min_size=1, max_size=8), dt=st.sampled_from([0.0005, 0.001, 0.004]))
def test_random_inputs_never_produce_non_finite_state(actions, dt):
    w = World(FIELD, [RobotSpec(x=-0.5), RobotSpec(x=0.5, robot_id=1)], BallState(0.0, 0.2), seed=1)
    for act in actions:
        kind = act[0]
        if kind == "duty":
            w.set_duty(act[1], act[2])
        elif kind == "kick":
            w.kick(act[1], act[2], spin_ratio=act[3], armed_for_s=0.05)
        elif kind == "robot":
            (x, y, th) = act[2]
            w.place_robot(act[1], x, y, th, vx=act[3], vy=act[4])
        elif kind == "ball":
            (x, y, _) = act[1]
            w.place_ball(x, y, act[2], act[3], spin_ratio=act[4])
        else:
            w.set_dribbler(act[1], act[2])
        for _ in range(10):
            w.step(dt)
        assert w.all_finite()
        assert math.isfinite(w.energy().total_j)
        b = w.ball_state()
        assert abs(b.x) <= 4.8 and abs(b.y) <= 3.3


def test_implausible_placements_are_refused_with_the_limit_in_the_message():
    w = World(FIELD, [RobotSpec(x=-0.5)], BallState(0.0, 0.2), seed=1)
    with pytest.raises(ValueError, match="exceeds the plausible limit 20"):
        w.place_ball(0.0, 0.0, 15.0, 15.0)  # 21.2 m/s
    with pytest.raises(ValueError, match="place_robot: vx"):
        w.place_robot(0, 0.0, 0.0, 0.0, vx=25.0)
    assert w.all_finite()


def test_robots_stepped_together_move_exactly_as_each_alone():
    """World advances its contact-free robots in one compiled call; each robot's numbers are those of a world
    with that robot alone (far from the others and the ball, nothing couples them)."""
    poses = [(-3.0, -2.0, 0.3), (0.0, 2.0, -1.2), (3.0, -2.0, 2.5)]
    duties = [[0.3, -0.2, 0.25, -0.1], [-0.4, 0.4, 0.1, 0.2], [0.05, 0.05, -0.05, -0.05]]
    ball = BallState(0.0, 0.0)
    together = World(FIELD, [RobotSpec(x=x, y=y, theta=t, robot_id=k) for k, (x, y, t) in enumerate(poses)], ball)
    together.set_duties(np.arange(3), np.array(duties))
    alone = [World(FIELD, [RobotSpec(x=x, y=y, theta=t)], ball) for x, y, t in poses]
    for w, d in zip(alone, duties, strict=True):
        w.set_duty(0, d)
    for _ in range(300):
        together.step(0.001)
        for w in alone:
            w.step(0.001)
    for k, w in enumerate(alone):
        assert together.robot_state(k) == w.robot_state(0)  # bit for bit
    assert together.robot_state(0).vx != 0.0  # and they did move


def test_the_batch_sensor_and_duty_calls_are_the_per_robot_calls():
    physics = PhysicsParams(wheel_speed_noise_radps=0.5, current_noise_a=0.1)
    specs = [RobotSpec(x=-2.0 + 2.0 * k, robot_id=k) for k in range(3)]
    a, b = (World(FIELD, specs, physics=physics, seed=4) for _ in range(2))
    duties = np.array([[0.2, 0.2, 0.2, 0.2], [1.5, -2.0, 0.1, 0.0], [0.0, 0.0, 0.0, -1.0]])
    assert a.set_duties([0, 1, 2], duties) == 2  # 1.5 and -2.0 clamped
    assert [b.set_duty(k, duties[k]) for k in range(3)] == [0, 2, 0]
    assert a.clamped_duty_count(1) == b.clamped_duty_count(1) == 2
    for w in (a, b):
        w.step(0.01)
    speeds, currents = a.wheel_sensors([2, 0])
    for row, k in enumerate([2, 0]):  # the same noise draws, robot after robot
        np.testing.assert_array_equal(speeds[row], b.wheel_speeds_radps(k))
        np.testing.assert_array_equal(currents[row], b.motor_currents_a(k))
    with pytest.raises(ValueError, match="finite"):
        a.set_duties([0], np.array([[0.1, math.nan, 0.0, 0.0]]))
    with pytest.raises(ValueError, match="shape"):
        a.set_duties([0, 1], np.zeros((2, 3)))


def test_a_ball_resting_before_the_flat_front_is_no_contact_candidate_one_within_kick_reach_is():
    """A robot lies inside its circle and behind its flat front face. A ball at rest 18 mm before the face is
    inside the circle's reach but cannot touch within a tick: no contact candidate (so the robot is not
    stepped substep by substep with it). 3 mm before the face (within kick_touch_tolerance_m, where kicks and
    the dribbler act) or at the same centre distance beside the round side, it is one."""
    r_ball = 0.02135  # the default ball's radius [m] (BallParams)
    front_x = CFG.dribbler_offset_m - r_ball  # the flat face, as World builds the outline
    dt = 0.002
    cases = [  # robot yaw, ball (x, y) relative to the robot at the origin, candidate?
        (0.0, (front_x + r_ball + 0.018, 0.0), False),
        (0.0, (front_x + r_ball + 0.003, 0.0), True),
        (0.0, (0.0, front_x + r_ball + 0.018), True),  # beside: 9.5 mm outside the circle
        (math.pi / 2, (0.0, front_x + r_ball + 0.018), False),  # turned to face it
    ]
    assert math.hypot(front_x + r_ball + 0.018, 0.0) < CFG.robot_radius_m + r_ball  # inside the circle's reach
    for yaw, (bx, by), expected in cases:
        w = World(FIELD, [RobotSpec(x=0.0, y=0.0, theta=yaw)], seed=0)
        assert w.ball_params.radius_m == r_ball
        w.place_ball(bx, by)
        _, _, _, ball_robots = w._contact_candidates(dt)
        assert (ball_robots == [0]) is expected, (yaw, bx, by)
