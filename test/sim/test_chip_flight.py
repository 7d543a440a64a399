"""Chip kicks in the simulator: the ball flies as the projectile, bounces by restitution and friction,
rolls out, passes over robots below it and hits them when low."""

import itertools
import math

import pytest

from erforce_ball_model.ball_model import ChipParams
from erforce_ball_model.chip_model import ChipTrajectory
from erforce_interfaces.wire.robot_config import FieldConfig, RobotConfig
from erforce_sim.ball import LANDED_VZ_MPS, BallParams, BallState
from erforce_sim.world import World
from erforce_sim.world_types import RobotSpec

G = 9.81
FIELD = FieldConfig.preset("division_b")
TOUCH_X = -1.0 + RobotConfig().dribbler_offset_m  # ball centre touching the dribbler of a robot at x = -1


def chipped(speed=4.0, angle_deg=45.0, others=(), dribbler=False):
    """A robot at (-1, 0) facing +x chips the ball lying at its dribbler (its bar running with ``dribbler``);
    (world, launch state)."""
    robots = [RobotSpec(x=-1.0), *(RobotSpec(x=x, robot_id=k + 1) for k, x in enumerate(others))]
    w = World(FIELD, robots, BallState(TOUCH_X, 0.0), seed=0)
    w.set_dribbler(0, dribbler)
    result = w.kick(0, speed, angle_deg=angle_deg)
    assert result.fired
    return w, w.ball_state()


def run_for(w, duration_s):
    """Step ``w`` by ``duration_s`` in equal steps of at most 0.05 s."""
    n = math.ceil(duration_s / 0.05)
    for _ in range(n):
        w.step(duration_s / n)


def test_the_chip_plate_launches_at_the_angle():
    _, b = chipped(4.0, 40.0)
    assert b.vz == pytest.approx(4.0 * math.sin(math.radians(40.0)), abs=1e-12)
    assert math.hypot(b.vx, b.vy) == pytest.approx(4.0 * math.cos(math.radians(40.0)), abs=1e-12)
    assert b.wx == b.wy == 0.0


@pytest.mark.parametrize(("speed", "angle_deg"), [(2.0, 30.0), (4.0, 45.0), (6.0, 60.0)])
def test_flight_is_the_projectile_apex_and_touchdown_within_1_mm(speed, angle_deg):
    w, b = chipped(speed, angle_deg)
    t_flight, apex = 2.0 * b.vz / G, b.vz**2 / (2.0 * G)
    t0 = w.t_s
    run_for(w, 0.5 * t_flight)
    top = w.ball_state()
    assert top.z == pytest.approx(apex, abs=1e-3)
    assert top.x == pytest.approx(b.x + b.vx * 0.5 * t_flight, abs=1e-3)
    run_for(w, 0.5 * t_flight - 1e-4)  # just before the touchdown: still falling, nearly down
    before = w.ball_state()
    assert before.vz < 0.0 and before.z < b.vz * 1e-4 + 1e-9
    assert before.x + before.vx * 1e-4 == pytest.approx(b.x + b.vx * t_flight, abs=1e-3)
    w.step(2e-4)  # just after: bounced
    after = w.ball_state()
    assert after.vz > 0.0 and w.t_s - t0 == pytest.approx(t_flight + 1e-4)


def test_the_first_bounce_by_hand():
    # no spin at the touchdown: friction (up to 0.5 * 1.566 * vz, above the sticking value) stops the slip:
    # v' = v - v / (1 + m r^2 / I) = v (1 - 1/3.5) for a solid ball; then it rolls (no slip)
    w, b = chipped(4.0, 45.0)
    run_for(w, 2.0 * b.vz / G + 1e-4)
    s = w.ball_state()
    assert math.hypot(s.vx, s.vy) == pytest.approx(math.hypot(b.vx, b.vy) * (1.0 - 1.0 / 3.5), rel=1e-9)
    assert s.vz + G * 1e-4 == pytest.approx(0.566 * b.vz, abs=1e-9)
    assert w.ball_slip_mps() == pytest.approx(0.0, abs=1e-9)


def test_a_running_dribbler_does_not_hold_back_the_kicked_ball():
    # A robot's dribbler runs while it holds the ball and aims; the kick comes first, the command that stops the
    # bar may come later (on the graph they are two topics). The kicked ball leaves the bar: the chip lands where
    # the projectile does, 2 v^2 sin(a) cos(a) / g = 1.631 m on for 4 m/s at 45 deg, at v cos(a) = 2.828 m/s,
    # without spin, so the first bounce keeps 1 - 1/3.5 of it (test_the_first_bounce_by_hand).
    w, b = chipped(4.0, 45.0, dribbler=True)
    run_for(w, 2.0 * b.vz / G - 1e-4)
    s = w.ball_state()
    assert s.x + s.vx * 1e-4 == pytest.approx(b.x + 2.0 * 4.0**2 * 0.5 / G, abs=1e-3)
    assert math.hypot(s.vx, s.vy) == pytest.approx(4.0 * math.cos(math.radians(45.0)), abs=1e-9)
    w.step(2e-4)
    assert math.hypot(w.ball_state().vx, w.ball_state().vy) == pytest.approx(
        4.0 * math.cos(math.radians(45.0)) * (1.0 - 1.0 / 3.5), abs=1e-9)
    # a flat kick likewise: the ball runs as if the bar had stopped before the kick
    paths = []
    for dribbler in (False, True):
        w = World(FIELD, [RobotSpec(x=-1.0)], BallState(TOUCH_X, 0.0), seed=0)
        w.set_dribbler(0, dribbler)
        assert w.kick(0, 4.0).fired
        run_for(w, 0.05)
        s = w.ball_state()
        paths.append((s.x, s.vx, s.wy))
    assert paths[1] == pytest.approx(paths[0], abs=1e-12)
    assert paths[0][1] == pytest.approx(4.0 - 2.5 * 0.05, abs=1e-9)  # 50 ms sliding at the paper's 2.5 m/s^2
    # the shot is past the bar: a ball that comes back to it is held again
    run_for(w, 0.5)
    assert w.ball_state().x > 0.5
    w.place_ball(TOUCH_X + 0.5, 0.0, vx=-3.0)
    run_for(w, 1.0)
    assert w.ball_in_dribbler(0) and math.hypot(w.ball_state().vx, w.ball_state().vy) < 0.05
    # a shot with the bar stopped, the ball put back at the bar, the bar started: the robot backs off with the ball
    w.set_dribbler(0, False)
    w.place_ball(TOUCH_X, 0.0)
    assert w.kick(0, 4.0).fired
    run_for(w, 0.5)
    w.place_ball(TOUCH_X, 0.0)
    w.set_dribbler(0, True)
    w.place_robot(0, -1.0, 0.0, 0.0, vx=-0.5)
    run_for(w, 0.1)
    assert w.robot_state(0).x < -1.02 and w.ball_in_dribbler(0)


@pytest.mark.parametrize("speed_mps", [1.0, 2.0, 3.0])
def test_the_running_dribbler_still_holds_a_ball_that_comes_in_and_bounces(speed_mps):
    # a pass into the robot's front bounces back at ball_robot_restitution (0.4) times its speed, faster than a
    # held ball ever moves: the bar takes it all the same (only the kicker's own shot leaves it)
    w = World(FIELD, [RobotSpec(x=-1.0)], BallState(TOUCH_X + 0.5, 0.0, vx=-speed_mps), seed=0)
    w.set_dribbler(0, True)
    run_for(w, 1.0)
    assert w.ball_in_dribbler(0) and math.hypot(w.ball_state().vx, w.ball_state().vy) < 0.05


def test_hops_end_and_the_ball_rolls_out_at_the_rolling_deceleration():
    w, b = chipped(4.0, 45.0)
    # vz after n bounces: 0.566^n vz0; the hops end below LANDED_VZ_MPS: after the hops' total time
    n = math.ceil(math.log(LANDED_VZ_MPS / b.vz) / math.log(0.566))
    t_hops = sum(2.0 * b.vz * 0.566**k / G for k in range(n))
    w.step(0.1)
    while w.t_s < t_hops + 0.01:
        w.step(min(0.05, t_hops + 0.01 - w.t_s))
    s1 = w.ball_state()
    assert s1.z == 0.0 and s1.vz == 0.0
    w.step(0.1)
    s2 = w.ball_state()
    assert math.hypot(s2.vx, s2.vy) == pytest.approx(math.hypot(s1.vx, s1.vy) - 0.3 * 0.1, abs=1e-9)


def test_a_chip_flies_over_a_robot_and_a_low_ball_hits_it():
    # a robot 1 m ahead: the 45 deg chip at 4 m/s is ~0.39 m up there and passes
    w, b = chipped(4.0, 45.0, others=(0.0,))
    run_for(w, 2.0 * b.vz / G - 0.01)
    assert w.ball_state().x > 0.3 and w.ball_state().vx > 0.0
    # a flat 2 m/s shot hits it and comes back
    w = World(FIELD, [RobotSpec(x=-1.0), RobotSpec(x=0.0, robot_id=1)], BallState(TOUCH_X, 0.0), seed=0)
    assert w.kick(0, 2.0).fired
    for _ in range(60):
        w.step(0.01)
    assert w.ball_state().vx < 0.0


def test_a_ball_in_the_air_is_not_kicked_and_bad_angles_are_refused():
    w, _ = chipped(4.0, 45.0)
    w.place_robot(0, w.ball_state().x - RobotConfig().dribbler_offset_m, 0.0, 0.0)
    w.step(0.05)  # ~0.13 m up
    w.place_robot(0, w.ball_state().x - RobotConfig().dribbler_offset_m, 0.0, 0.0)
    assert not w.ball_in_dribbler(0)
    assert not w.kick(0, 3.0).fired
    for angle in (-1.0, 90.0, math.nan):
        with pytest.raises(ValueError, match="angle_deg"):
            w.kick(0, 3.0, angle_deg=angle)
    with pytest.raises(ValueError, match="floor_restitution"):
        BallParams(floor_restitution=1.0)
    with pytest.raises(ValueError, match="BallState.z"):
        BallState(0.0, 0.0, z=-0.1)


def test_energy_in_flight_is_kept_and_bounces_only_lose_it():
    w, _ = chipped(5.0, 50.0)
    energies = [w.energy().ball_j]
    for _ in range(150):
        w.step(0.01)
        energies.append(w.energy().ball_j)
    assert all(b <= a + 1e-9 for a, b in itertools.pairwise(energies))
    assert energies[-1] < 0.5 * energies[0]


def test_the_world_s_vision_frames_carry_the_ball_s_height():
    w, _ = chipped(4.0, 45.0)
    run_for(w, 0.2)
    frames = w.poll_vision()
    heights = [f.balls[0].z for f in frames if f.balls]
    assert max(heights) > 0.2 and min(heights) >= 0.0


def test_the_plant_s_chip_is_the_chip_model_s_with_its_defaults():
    # ChipParams' defaults are this plant's ball: both read restitution 0.566 and the hops' end speed from
    # robot_config; the plant's friction must then give what the model assumes: the first bounce stops the
    # slip of a ball without spin (1 - 1/3.5 of its speed kept), later ones find it rolling (all kept), then
    # it rolls at the carpet's a_roll
    w, b = chipped(3.0, 60.0)  # rests ~2.5 m on, before the wall (the model has none)
    model = ChipTrajectory((b.x, b.y, 0.0), (b.vx, b.vy, b.vz), ChipParams())
    assert len(model.hops) > 5
    t0 = w.t_s
    for t_touch, point in zip(model.touchdown_times_s[:4], model.touchdown_points_m[:4], strict=True):
        run_for(w, t_touch - 1e-4 - (w.t_s - t0))
        s = w.ball_state()
        assert s.vz < 0.0
        assert math.dist((s.x + s.vx * 1e-4, s.y + s.vy * 1e-4), point) < 1e-3
    for t in (model.roll_start_s + 0.5, model.stop_time_s + 0.5):
        run_for(w, t - (w.t_s - t0))
        s = w.ball_state()
        assert math.dist((s.x, s.y, s.z), model.position_at(t)) < 2e-3


def test_a_ball_above_the_dribbler_does_not_break_the_light_barrier():
    seen = []
    for z in (0.0, 0.3):
        w = World(FIELD, [RobotSpec(x=-1.0)], BallState(TOUCH_X, 0.0, z=z), seed=0)
        run_for(w, 0.05)  # 0.3 m up falls 0.012 m in that time
        seen.append(w.light_barrier(0))
    assert seen == [True, False]


@pytest.mark.parametrize("speed", [3.5, 4.0, 4.5, 5.0])
def test_a_standing_receiver_takes_a_chip_once_its_hops_stay_below_a_ball_radius(speed):
    """ChipParams' reception height is what this plant's robot takes: a robot facing the chip with its dribbler
    bar running holds the ball when its dribbler stands 5 cm beyond where the model says the hops stay below
    max_receive_height_m (a ball radius: the beam and the bar sit at a resting ball's centre), and the ball bounces
    off it when its dribbler stands 10 cm before that point, where the ball still hops higher."""
    assert ChipParams().max_receive_height_m == BallParams().radius_m
    a = math.radians(45.0)
    model = ChipTrajectory((TOUCH_X, 0.0, 0.0), (speed * math.cos(a), 0.0, speed * math.sin(a)), ChipParams())
    x_settle = float(model.ground_track().position_at(model.time_below_height_s(ChipParams().max_receive_height_m))[0])
    held = []
    for dribbler_x in (x_settle + 0.05, x_settle - 0.1):
        receiver = RobotSpec(x=dribbler_x + RobotConfig().dribbler_offset_m, theta=math.pi, robot_id=1)
        w = World(FIELD, [RobotSpec(x=-1.0), receiver], BallState(TOUCH_X, 0.0), seed=0)
        w.set_dribbler(1, True)
        assert w.kick(0, speed, angle_deg=45.0).fired
        run_for(w, model.stop_time_s + 1.0)
        s = w.ball_state()
        held.append(w.light_barrier(1) and math.hypot(s.vx, s.vy) < 0.05)
    assert held == [True, False]
