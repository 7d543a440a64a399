"""The receive skill: approach law, frames, heading."""

import math

import numpy as np
import pytest

from erforce_ball_model.ball_model import BallModelParams, BallTrajectory, ChipParams
from erforce_ball_model.chip_model import ChipTrajectory
from erforce_ball_model.receiver import (
    CatcherConfig,
    Receiver,
    approach_velocity,
    catch_twist,
    choose_target,
    field_to_robot,
    heading_loop,
    line_intercept,
    on_receive_line,
    receive_point,
    team_receiver,
    wrap_angle,
)
from erforce_interfaces.wire.robot_config import FieldConfig

CFG = CatcherConfig(a_max_mps2=3.0, v_max_mps=2.0, braking_margin=1.0)


def test_approach_speed_is_the_arrive_at_rest_profile():
    # 0.24 m away with a = 3 m/s^2: v = sqrt(2 * 3 * 0.24) = 1.2 m/s, below v_max
    v = approach_velocity(np.array([0.0, 0.0]), np.array([0.0, 0.24]), CFG)
    np.testing.assert_allclose(v, [0.0, 1.2])
    # far away: capped at v_max, pointing at the target
    v = approach_velocity(np.array([1.0, 1.0]), np.array([4.0, 5.0]), CFG)
    np.testing.assert_allclose(v, [2.0 * 0.6, 2.0 * 0.8])
    assert approach_velocity(np.zeros(2), np.array([0.001, 0.0]), CFG).tolist() == [0.0, 0.0]


def test_field_to_robot_rotation():
    # robot facing +y (yaw 90 deg): field +y is robot forward (+x), field +x is robot right (-y)
    np.testing.assert_allclose(field_to_robot(np.array([0.0, 1.0]), math.pi / 2), [1.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(field_to_robot(np.array([1.0, 0.0]), math.pi / 2), [0.0, -1.0], atol=1e-12)


def test_catch_twist_turns_the_short_way_and_saturates():
    twist = catch_twist(np.array([0.0, 0.0, math.radians(170)]), np.zeros(2), math.radians(-170), CFG)
    assert twist[2] == pytest.approx(CFG.heading_gain_per_s * math.radians(20))  # +20 deg, not -340
    twist = catch_twist(np.array([0.0, 0.0, 0.0]), np.zeros(2), math.pi / 2, CFG)
    assert twist[2] == CFG.w_max_radps


def test_wrap_angle():
    assert wrap_angle(3 * math.pi) == pytest.approx(-math.pi)


@pytest.mark.parametrize("bad", [math.nan, math.inf])
def test_bad_input_raises(bad):
    with pytest.raises(ValueError):
        catch_twist(np.array([bad, 0.0, 0.0]), np.zeros(2), 0.0, CFG)
    with pytest.raises(ValueError):
        catch_twist(np.zeros(3), np.array([0.0, bad]), 0.0, CFG)
    with pytest.raises(ValueError):
        CatcherConfig(a_max_mps2=bad)
    with pytest.raises(ValueError):
        CatcherConfig(v_max_mps=-1.0)


def test_receive_line():
    pose = np.array([1.0, 0.0, math.pi])  # facing -x; dribbler at x = 1 - 0.08
    ball, towards = np.array([-2.0, 0.01]), np.array([3.0, 0.0])
    assert on_receive_line(pose, ball, towards, 0.08, 0.02)  # 1 cm off the line, ahead
    assert not on_receive_line(pose, np.array([-2.0, 0.05]), towards, 0.08, 0.02)  # 5 cm off
    assert not on_receive_line(pose, ball, -towards, 0.08, 0.02)  # rolling away
    assert not on_receive_line(pose, np.array([2.0, 0.0]), towards, 0.08, 0.02)  # already past the dribbler
    assert not on_receive_line(pose, ball, np.zeros(2), 0.08, 0.02)  # at rest: nothing comes


def test_noise_sized_errors_do_not_move_the_robot():
    cfg = CatcherConfig()
    # 2 cm and 0.02 rad away: inside the arrive tolerance and the heading deadband
    twist = catch_twist(np.array([0.0, 0.0, 0.02]), np.array([0.01, 0.0]), 0.0, cfg)
    np.testing.assert_array_equal(twist, [0.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="heading_deadband_rad"):
        CatcherConfig(heading_deadband_rad=-0.1)


def test_line_intercept_is_the_robots_projection_onto_the_incoming_line():
    # ball at the origin rolling along +x; robot at (2, -0.3): stand at (2, 0)
    np.testing.assert_allclose(line_intercept(np.array([2.0, -0.3]), np.zeros(2), np.array([3.0, 0.0]), 0.08),
                               [2.0, 0.0])
    # diagonal line: projection of (0, 2) onto the 45 degree line is (1, 1)
    np.testing.assert_allclose(line_intercept(np.array([0.0, 2.0]), np.zeros(2), np.array([1.0, 1.0]), 0.08),
                               [1.0, 1.0])
    assert line_intercept(np.array([-1.0, 0.0]), np.zeros(2), np.array([3.0, 0.0]), 0.08) is None  # passed
    assert line_intercept(np.array([1.0, 0.0]), np.zeros(2), np.zeros(2), 0.08) is None  # not moving


def _rolling_ball(speed, x0=-2.0):
    """A ball at (x0, 0) rolling along +x at ``speed`` (already rolling: v_shoot = speed / c_switch)."""
    return BallTrajectory(np.array([x0, 0.0]), np.array([speed, 0.0]), speed / 0.6, BallModelParams())


def _roll_time(d, speed, a_roll=0.3):
    """Time for a rolling ball to cover d (d = v t - a t^2 / 2), inf if it stops first."""
    disc = speed * speed - 2.0 * a_roll * d
    return math.inf if disc < 0.0 else (speed - math.sqrt(disc)) / a_roll


def _first_receive_hand(robot, ball_x, speed, step=0.05, slack=0.15, a=4.5, offset=0.08):
    """Robot at rest: 2 sqrt(d / a) (triangle profile, below v_max here) to each point on the line."""
    for k in range(31):
        x = robot[0] + k * step
        d = math.hypot(x - robot[0], robot[1])
        if 2.0 * math.sqrt(d / a) + slack <= _roll_time(x - offset - ball_x, speed):
            return np.array([x, 0.0])
    return None


def test_receive_point_needs_slack_a_ball_that_arrives_and_the_field():
    cfg = CatcherConfig(a_max_mps2=4.5, v_max_mps=2.5, receive_slack_s=0.15)
    still = np.zeros(2)
    ball = _rolling_ball(4.0)
    # 0.3 m sideways: 2 sqrt(0.3 / 4.5) = 0.516 s, + 0.15 <= 0.751 s for the ball to roll 2.92 m: the projection.
    assert 0.516 + 0.15 < _roll_time(2.92, 4.0) < 0.752
    np.testing.assert_allclose(receive_point(np.array([1.0, 0.3]), still, ball, 0.08, cfg), [1.0, 0.0])
    # 0.42 m sideways: 0.611 + 0.15 > 0.751 at the projection; 5 cm further along the ball is later (0.764 s).
    got = receive_point(np.array([1.0, 0.42]), still, ball, 0.08, cfg)
    expected = _first_receive_hand((1.0, 0.42), -2.0, 4.0)
    assert expected is not None and expected[0] > 1.0
    np.testing.assert_allclose(got, expected, atol=1e-9)
    # 1.5 m sideways against a 6 m/s ball: 1.15 s + 0.15 never fits within the 1.5 m searched.
    assert _first_receive_hand((1.0, 1.5), -2.0, 6.0) is None
    assert receive_point(np.array([1.0, 1.5]), still, _rolling_ball(6.0), 0.08, cfg) is None
    # A 1 m/s ball stops after 1 / 0.6 = 1.67 m, short of every dribbler position: no.
    assert receive_point(np.array([1.0, 0.3]), still, _rolling_ball(1.0), 0.08, cfg) is None
    # Off the field (division B: |x| <= 4.5 - 0.09 for the centre): the projection at x = 4.45 is out.
    field = FieldConfig.preset("division_b")
    assert receive_point(np.array([4.45, 0.3]), still, ball, 0.08, cfg, field, 0.09) is None
    np.testing.assert_allclose(receive_point(np.array([4.35, 0.3]), still, ball, 0.08, cfg, field, 0.09),
                               [4.35, 0.0])
    # Moving away from the line at 2 m/s: braking alone takes 0.44 s and 0.44 m, coming back 0.74 m another
    # 0.81 s; + 0.15 is past the ball's 1.15 s to the farthest point searched (4.42 m): none fits.
    assert 0.44 + 0.81 + 0.15 > _roll_time(4.42, 4.0)
    assert receive_point(np.array([1.0, 0.3]), np.array([0.0, 2.0]), ball, 0.08, cfg) is None


def test_choose_target_prefers_the_line_then_the_receive_point_then_the_catch_point():
    cfg = CatcherConfig(a_max_mps2=4.5, v_max_mps=2.5, receive_slack_s=0.15)
    still = np.zeros(2)
    ball = _rolling_ball(4.0)
    catch_point = np.array([0.5, 0.2])
    # The dribbler (8 cm ahead of the centre, facing -x) is 1 cm off the line: stand still.
    on_line = np.array([1.08, 0.01, math.pi])
    np.testing.assert_allclose(choose_target(on_line, still, ball, catch_point, 0.08, cfg), on_line[:2])
    # 0.3 m off with time to spare: the receive point (its projection), not the catch point.
    np.testing.assert_allclose(choose_target(np.array([1.0, 0.3, math.pi]), still, ball, catch_point, 0.08, cfg),
                               [1.0, 0.0])
    # 1.5 m off a 6 m/s ball: no receive point; the predictor's catch point, else hold.
    far = np.array([1.0, 1.5, math.pi])
    fast = _rolling_ball(6.0)
    np.testing.assert_allclose(choose_target(far, still, fast, catch_point, 0.08, cfg), catch_point)
    assert choose_target(far, still, fast, None, 0.08, cfg) is None
    # Committed to this ball and 0.25 m off its line: block the line at the robot's projection rather
    # than brake where it is. 1.5 m off: too far, chasing the line would only get in the ball's way.
    near = np.array([1.0, 0.25, math.pi])
    assert choose_target(near, still, fast, None, 0.08, cfg) is None
    np.testing.assert_allclose(choose_target(near, np.array([0.0, 2.5]), fast, None, 0.08, cfg, committed=True),
                               [1.0, 0.0])
    assert choose_target(far, still, fast, None, 0.08, cfg, committed=True) is None
    # A resting ball (None) has no line: only the catch point counts, committed or not.
    assert choose_target(far, still, None, None, 0.08, cfg, committed=True) is None
    np.testing.assert_allclose(choose_target(far, still, None, catch_point, 0.08, cfg), catch_point)
    # The ball already passed the robot: nothing to block.
    behind = np.array([-2.5, 0.2, math.pi])
    assert choose_target(behind, still, fast, None, 0.08, cfg, committed=True) is None


def test_a_committed_robot_keeps_its_receive_point_without_the_slack():
    """Fig. 6 a moment before the line: the robot 4 cm off it, moving towards it at 0.6 m/s, brakes to rest
    exactly there (0.6^2 / (2 * 4.5) = 0.04 m) in 0.6 / 4.5 = 0.133 s. The ball, rolling at 2 m/s, needs
    (2 - sqrt(4 - 0.6 * 0.5)) / 0.3 = 0.255 s for the 0.5 m to the dribbler: 0.122 s to spare, less than
    the 0.15 s that starts a receive. A robot already on its way keeps the line; a new one takes the
    predicted catch point instead."""
    cfg = CatcherConfig(a_max_mps2=4.5, v_max_mps=2.5, receive_slack_s=0.15)
    pose, moving = np.array([-0.5, 0.04, math.pi]), np.array([0.0, -0.6])
    ball = _rolling_ball(2.0, x0=-0.5 - 0.08 - 0.5)
    assert _roll_time(0.5, 2.0) == pytest.approx(0.2549, abs=1e-4)
    later_window = np.array([0.2, 0.0])
    np.testing.assert_allclose(choose_target(pose, moving, ball, later_window, 0.08, cfg), later_window)
    np.testing.assert_allclose(choose_target(pose, moving, ball, later_window, 0.08, cfg, committed=True),
                               [-0.5, 0.0], atol=1e-12)
    # Committed or not, a receive point the robot cannot reach before the ball is no receive point.
    late = _rolling_ball(2.0, x0=-0.5 - 0.08 - 0.2)  # 0.2 m: (2 - sqrt(4 - 0.12)) / 0.3 = 0.101 s < 0.133 s
    np.testing.assert_allclose(choose_target(pose, moving, late, later_window, 0.08, cfg, committed=True),
                               later_window)


def test_team_receiver_is_the_first_to_the_ball_and_keeps_the_role_within_the_margin():
    never = -1.0  # CATCH_TIME_NEVER
    assert team_receiver({0: 1.2, 2: 0.9, 3: 1.5}, None, 0.1) == 2
    assert team_receiver({0: 1.2, 2: never, 3: math.inf}, None, 0.1) == 0  # who cannot catch is left out
    assert team_receiver({0: never, 2: math.nan}, None, 0.1) is None
    assert team_receiver({}, 3, 0.1) is None
    assert team_receiver({0: 1.0, 2: 1.0}, None, 0.1) == 0  # a tie goes to the lower id
    # The receiver keeps the ball while nobody is earlier by more than the margin ...
    assert team_receiver({0: 1.05, 2: 0.96}, 0, 0.1) == 0
    # ... and hands it over beyond it, or when it can no longer catch, or when it is not known.
    assert team_receiver({0: 1.07, 2: 0.96}, 0, 0.1) == 2
    assert team_receiver({0: never, 2: 1.5}, 0, 0.1) == 2
    assert team_receiver({2: 1.5, 3: 1.45}, 0, 0.1) == 3
    with pytest.raises(ValueError):
        team_receiver({0: 1.0}, None, -0.1)


# --- Receiver: the behaviour over time ---------------------------------------------------------
OFFSET = 0.08
RCFG = CatcherConfig(a_max_mps2=4.5, v_max_mps=2.5)


def _receiver(**kw):
    return Receiver(kw.pop("cfg", RCFG), OFFSET, **kw)


def _feed_fig6(rx: Receiver, now: float, ball_speed=2.0) -> None:
    """Robot at rest 0.3 m off the line of a ball rolling along +x, 1.5 m away: the line is the receive point."""
    rx.on_odom(now, [-0.5, 0.3, math.pi], [0.0, 0.0])
    rx.on_ball(now, [-2.0, 0.0], [ball_speed, 0.0])
    rx.on_v_shoot(now, ball_speed / 0.6)


def test_receiver_engages_on_a_moving_ball_and_drives_to_its_line():
    rx = _receiver()
    rx.on_odom(0.0, [-0.5, 0.3, math.pi], [0.0, 0.0])
    assert rx.tick(0.0).tolist() == [0.0, 0.0, 0.0]  # no ball yet: hold
    _feed_fig6(rx, 0.01)
    twist = rx.tick(0.02)
    # Facing -x, the field direction -y (towards the line) is the robot's +y; the approach speed to
    # the line 0.3 m away is min(2.5, sqrt(2 * 4.5 * 0.5 * 0.3)) = 1.162 m/s.
    np.testing.assert_allclose(twist, [0.0, math.sqrt(2 * 4.5 * 0.5 * 0.3), 0.0], atol=1e-9)


def test_receiver_engages_on_travel_not_on_noise():
    """Right after a ball appears its filtered velocity is noise of up to ~0.25 m/s while the ball lies
    still: only a ball that moved engage_distance_m (5 cm) from where it rested engages the robot."""
    rx = _receiver()
    rx.on_odom(0.0, [-0.5, 0.3, math.pi], [0.0, 0.0])
    rx.on_ball(0.0, [-2.0, 0.0], [0.0, 0.0])  # at rest
    for k, noise in enumerate(([0.10, 0.02], [0.24, -0.05], [-0.1, 0.2])):
        rx.on_ball(0.014 * (k + 1), [-2.0 + 0.002 * k, 0.001], noise)  # fast, but nowhere
        assert rx.tick(0.014 * (k + 1)).tolist() == [0.0, 0.0, 0.0]
    rx.on_ball(0.06, [-1.96, 0.0], [2.0, 0.0])  # kicked: 4 cm on
    assert rx.tick(0.06).tolist() == [0.0, 0.0, 0.0]
    rx.on_ball(0.07, [-1.94, 0.0], [2.0, 0.0])  # 6 cm
    assert np.any(rx.tick(0.07) != 0.0)


def test_receiver_holds_on_stale_inputs_and_after_the_catch():
    rx = _receiver()
    _feed_fig6(rx, 0.0)
    assert np.any(rx.tick(0.1) != 0.0)
    assert rx.tick(0.0 + RCFG.stale_after_s + 0.01).tolist() == [0.0, 0.0, 0.0]  # odom too old
    _feed_fig6(rx, 1.0)
    assert rx.on_barrier(True) and not rx.on_barrier(True)  # one rising edge
    assert rx.tick(1.01).tolist() == [0.0, 0.0, 0.0]  # holding the ball
    rx.on_barrier(False)
    assert rx.tick(1.02).tolist() == [0.0, 0.0, 0.0]  # disengaged by the catch
    _feed_fig6(rx, 1.03)  # the ball bounced off the dribbler, moving: received already, not chased
    assert rx.tick(1.04).tolist() == [0.0, 0.0, 0.0]
    rx.on_ball(1.05, [-2.0, 0.0], [0.0, 0.0])  # a ball at rest, then a new pass
    rx.on_ball(1.06, [-1.9, 0.0], [2.0, 0.0])
    assert np.any(rx.tick(1.07) != 0.0)


def test_receiver_gives_up_once_the_ball_rested():
    rx = _receiver()
    _feed_fig6(rx, 0.0)
    assert np.any(rx.tick(0.01) != 0.0)
    driving = []
    for t in np.arange(0.1, RCFG.disengage_after_rest_s + 0.3, 0.1):  # the ball lies still from t = 0.1
        rx.on_odom(t, [-0.5, 0.3, math.pi], [0.0, 0.0])
        rx.on_ball(t, [-1.0, 0.0], [0.0, 0.0])
        rx.on_catch_time(t, 0.5)
        rx.on_catch_point(t, [-1.08, 0.0])
        driving.append((round(t, 1), bool(np.any(rx.tick(t) != 0.0))))
    # A resting ball has no line, so the engaged robot drives to the catch point at the ball until the
    # ball rested disengage_after_rest_s = 2 s after it was last seen moving (t = 0).
    assert driving == [(round(t, 1), t <= 2.0) for t, _ in driving]


def test_receiver_in_a_team_drives_only_while_it_is_first_to_the_ball():
    rx = _receiver(robot_id=0, team_robot_ids=[0, 2])
    _feed_fig6(rx, 0.0)
    rx.on_catch_time(0.0, 0.9)
    rx.on_teammate_catch_time(2, 0.0, 0.5)  # robot_2 is earlier by more than the margin
    assert rx.tick(0.01).tolist() == [0.0, 0.0, 0.0]
    rx.on_teammate_catch_time(2, 0.02, -1.0)  # robot_2 can no longer catch it
    assert np.any(rx.tick(0.03) != 0.0)
    rx.on_teammate_catch_time(5, 0.04, 0.1)  # not a teammate: ignored
    assert np.any(rx.tick(0.05) != 0.0)
    with pytest.raises(ValueError, match="not one of them"):
        _receiver(robot_id=3, team_robot_ids=[0, 2])


def test_catch_time_never_is_the_contracts():
    from erforce_ball_model.receiver import CATCH_TIME_NEVER
    from erforce_interfaces.wire.contract import CATCH_TIME_NEVER as contract_never

    assert CATCH_TIME_NEVER == contract_never


UP_LEFT = math.radians(135.0)  # the dribbler faces up-left, 45 deg off a ball rolling along +x
SIDE = 0.08 / math.sqrt(2.0)  # the offset 0.08 m at 135 deg: (-SIDE, +SIDE) from the robot centre


def test_facing_the_target_the_dribbler_goes_on_the_line_and_the_centre_one_offset_back():
    """Ball rolling along +x on y = 0; the robot at (1, -0.3) receives facing 135 deg. Its dribbler (centre +
    (-SIDE, SIDE)) must be on the line, so its centre stands at y = -SIDE, and at x = 1: the dribbler's
    projection (1 - SIDE) plus SIDE. At rest it gets there (0.2434 m: 2 sqrt(0.2434 / 4.5) = 0.465 s,
    + 0.15 s slack) before the ball rolls the 2.943 m to the dribbler at 4 m/s (0.757 s)."""
    ball = _rolling_ball(4.0)
    assert 2.0 * math.sqrt((0.3 - SIDE) / 4.5) + 0.15 < _roll_time(3.0 - SIDE, 4.0)
    expected = [1.0, -SIDE]
    np.testing.assert_allclose(line_intercept(np.array([1.0, -0.3]), ball.position_m, ball.velocity_mps, 0.08,
                                              UP_LEFT), expected, atol=1e-12)
    np.testing.assert_allclose(receive_point(np.array([1.0, -0.3]), np.zeros(2), ball, 0.08, RCFG, facing_rad=UP_LEFT),
                               expected, atol=1e-12)
    # Standing there facing the ball (yaw pi), it is on the line once it turns to 135 deg, not before.
    pose = np.array([1.0, -SIDE, math.pi])
    assert on_receive_line(pose, ball.position_m, ball.velocity_mps, 0.08, 0.02, facing_rad=UP_LEFT)
    assert not on_receive_line(pose, ball.position_m, ball.velocity_mps, 0.08, 0.02)
    target = choose_target(pose, np.zeros(2), ball, None, 0.08, RCFG, facing_rad=UP_LEFT)
    np.testing.assert_array_equal(target, pose[:2])  # it stays and turns


def test_receiver_with_a_next_target_receives_facing_it_within_the_receive_angle():
    """The Fig. 6 feed (robot at (-0.5, 0.3) facing -x, ball from (-2, 0) along +x at 2 m/s) with a next
    target up-left at 150 deg from the robot: the robot turns to 150 deg (8/s * -30 deg = -4.19 rad/s) and
    drives its centre to (-0.5, -0.08 sin 150) = (-0.5, -0.04): 0.34 m along field -y, its +y, at
    sqrt(2 * 4.5 * 0.5 * 0.34) m/s. A target straight up (90 deg off the ball's way back) is beyond the
    receive angle: it faces the ball and drives to the line, as without a target."""
    rx = _receiver()
    _feed_fig6(rx, 0.0)
    target_150 = np.array([-0.5 - 1.0, 0.3 + math.tan(math.radians(30.0))])
    rx.on_next_target(target_150)
    twist = rx.tick(0.01)
    dy = 0.3 + 0.08 * math.sin(math.radians(150.0))
    assert 2.0 * math.sqrt(dy / 4.5) + 0.15 < _roll_time(1.5 - 0.08 * math.cos(math.radians(30.0)), 2.0)
    np.testing.assert_allclose(twist, [0.0, math.sqrt(2 * 4.5 * 0.5 * dy), 8.0 * math.radians(-30.0)], atol=1e-9)
    rx.on_next_target([-0.5, 3.0])
    np.testing.assert_allclose(rx.tick(0.02), [0.0, math.sqrt(2 * 4.5 * 0.5 * 0.3), 0.0], atol=1e-9)
    with pytest.raises(ValueError, match="max_receive_angle_rad"):
        rx.on_next_target([-0.5, 3.0], math.radians(90.0))


# --- the heading loop behind a delay -----------------------------------------------------------
def test_heading_loop_predicts_with_the_yaw_rate_and_lowers_the_gain_with_the_delay():
    cfg = CatcherConfig()  # heading gain 8 /s, gain times delay at most 0.5
    assert heading_loop(1.0, 2.0, 0.05, cfg) == pytest.approx((1.1, 8.0))  # 0.5 / 0.05 = 10 > 8: nominal
    assert heading_loop(1.0, 2.0, 0.25, cfg) == pytest.approx((1.5, 2.0))  # 0.5 / 0.25
    assert heading_loop(3.0, 2.0, 0.1, cfg) == pytest.approx((3.2 - 2.0 * math.pi, 5.0))  # wrapped
    assert heading_loop(1.0, 2.0, -0.1, cfg) == pytest.approx((1.0, 8.0))  # no delay: as measured


def _turn_behind_a_delay(compensated: bool, delay_s: float = 0.2, tick_s: float = 0.02, duration_s: float = 3.0):
    """The heading error [rad] every AI tick of a receiver (the Fig. 6 feed with a next target at 150 deg: it
    turns from 180 deg) on a first-order yaw plant (yaw' = the commanded wz, held for the tick) whose pose
    reaches the receiver ``delay_s`` late, stamped with its capture time and with the yaw rate then
    (``compensated``) or as it was before the heading loop knew of delays: stamped on arrival, no yaw rate."""
    rx = _receiver()
    rx.on_next_target(np.array([-1.5, 0.3 + math.tan(math.radians(30.0))]))
    lag = round(delay_s / tick_s)
    yaw, rate = [math.pi], [0.0]
    for k in range(round(duration_s / tick_s)):
        now, seen = k * tick_s, max(k - lag, 0)
        rx.on_ball(now, [-2.0, 0.0], [2.0, 0.0])
        rx.on_v_shoot(now, 2.0 / 0.6)
        if compensated:
            rx.on_odom(now, [-0.5, 0.3, yaw[seen]], [0.0, 0.0, rate[seen]], seen * tick_s)
        else:
            rx.on_odom(now, [-0.5, 0.3, yaw[seen]], [0.0, 0.0])
        wz = float(rx.tick(now)[2])
        rate.append(wz)
        yaw.append(yaw[-1] + wz * tick_s)
    return np.array([wrap_angle(y - math.radians(150.0)) for y in yaw])


def test_the_old_heading_law_oscillates_behind_a_delay_of_0_2_s():
    """Gain 8 /s on an integrating yaw behind the delay D = 0.2 s plus half a tick of hold (0.21 s): the loop
    K e^{-sD} / s reaches -180 deg at omega = pi / (2 D), where its gain is K D / (pi / 2) = 1.07 > 1: unstable.
    It swings (the turn rate saturates) with period 4 D = 0.84 s (the zero crossings 2 D = 0.42 s apart, to a
    tick) and never settles: its late swings exceed the first error, 30 deg."""
    error = _turn_behind_a_delay(compensated=False)
    t = np.arange(error.size) * 0.02
    crossings = t[1:][np.sign(error[1:]) != np.sign(error[:-1])]
    assert crossings.size >= 6
    np.testing.assert_allclose(np.diff(crossings), 0.42, atol=0.021)
    assert np.abs(error[t > 2.0]).max() > math.radians(30.0)


def test_the_heading_loop_compensated_for_the_delay_settles_without_overshoot():
    """The same turn with the pose's age known (0.2 s) and the tracked yaw rate: the loop's delay is taken as
    the age plus command_lead_s (0.24 s), the gain 0.5 / 0.24 = 2.08 /s, the heading predicted 0.24 s ahead.
    The loop K e^{-sD} (1 + sD) / s has its phase margin of 87 deg (receiver module docstring): no overshoot, a
    first-order response with time constant 1 / K after the dead time, so 30 deg (0.524 rad) comes within
    0.04 rad after 0.21 + ln(0.524 / 0.04) / 2.08 = 1.44 s at the latest and stays there; it stops inside the
    0.03 rad deadband."""
    error = _turn_behind_a_delay(compensated=True)
    t = np.arange(error.size) * 0.02
    assert error.min() >= 0.0  # never past the facing
    settle_s = 0.21 + math.log(math.radians(30.0) / 0.04) / (0.5 / 0.24)
    assert np.abs(error[t >= settle_s]).max() <= 0.04
    assert abs(error[-1]) <= RCFG.heading_deadband_rad


def test_a_pose_from_the_future_or_older_than_stale_bounds_the_prediction():
    """The pose's age counts from 0 (a stamp ahead of the clock) to stale_after_s (0.25 s): the yaw rate 1 rad/s
    predicts the heading 0.04 s (command_lead_s) or 0.29 s ahead, with the gain 8 /s or 0.5 / 0.29 /s."""
    for stamp_s, delay_s in ((5.0, 0.04), (-100.0, 0.29)):
        rx = _receiver()
        _feed_fig6(rx, 0.0)
        rx.on_next_target(np.array([-1.5, 0.3 + math.tan(math.radians(30.0))]))
        rx.on_odom(0.0, [-0.5, 0.3, math.pi], [0.0, 0.0, 1.0], stamp_s)
        yaw, gain = heading_loop(math.pi, 1.0, delay_s, RCFG)
        assert rx.tick(0.0)[2] == pytest.approx(gain * wrap_angle(math.radians(150.0) - yaw))


def test_the_approach_steers_from_the_pose_predicted_over_the_loops_delay():
    """The Fig. 6 receiver moving onto the ball's line at 0.8 m/s, its pose 0.01 s old: the delay is 0.01 +
    command_lead_s (0.04) = 0.05 s, over which it moves 0.04 m. From 0.2 m off the line it is commanded
    the arrive-at-rest speed for the 0.16 m left then, sqrt(2 * 4.5 * 0.5 * 0.16) = 0.849 m/s (0.949 from the
    measured pose); from 0.04 m off it will be on the line (dribbler within 0.02 m): it stops commanding."""
    for y_m, speed_mps in ((0.2, math.sqrt(2.0 * 4.5 * 0.5 * 0.16)), (0.04, 0.0)):
        rx = _receiver()
        _feed_fig6(rx, 0.0)
        rx.on_odom(0.0, [-0.5, y_m, math.pi], [0.0, -0.8], -0.01)
        twist = rx.tick(0.0)
        # facing -x, the field's -y is the robot's +y
        assert twist[:2] == pytest.approx([0.0, speed_mps], abs=1e-9), f"{y_m} m off the line"


def test_a_ball_in_the_air_on_ball_state_reaches_the_receiver_as_a_chip_and_the_ground_as_the_flat_ball():
    """/ball/state carries a chip's height and vertical speed in pose.position.z and twist.linear.z: the message
    and its bytes give [x, y, z], [vx, vy, vz] in the air, [x, y], [vx, vy] on the ground (and for a noisy
    height below 0)."""
    from nav_msgs.msg import Odometry
    from rclpy.serialization import serialize_message

    from erforce_interfaces.wire.conversions import ball_state_from_msg

    def state(z, vz):
        msg = Odometry()
        msg.header.frame_id = "field"
        msg.header.stamp.sec, msg.header.stamp.nanosec = 12, 500_000_000
        msg.pose.pose.position.x, msg.pose.pose.position.y, msg.pose.pose.position.z = 1.0, -2.0, z
        msg.pose.pose.orientation.w = 1.0
        msg.twist.twist.linear.x, msg.twist.twist.linear.y, msg.twist.twist.linear.z = 3.0, 0.5, vz
        return msg

    for msg in (state(0.3, -1.2), serialize_message(state(0.3, -1.2))):
        t, p, v = ball_state_from_msg(msg)
        assert (t, p.tolist(), v.tolist()) == (12.5, [1.0, -2.0, 0.3], [3.0, 0.5, -1.2])
    for z, vz in ((0.0, 0.0), (-0.002, 0.0)):
        t, p, v = ball_state_from_msg(serialize_message(state(z, vz)))
        assert (p.tolist(), v.tolist()) == ([1.0, -2.0], [3.0, 0.5])
    _, p, v = ball_state_from_msg(state(0.0, 2.0))  # just kicked upwards
    assert p.tolist() == [1.0, -2.0, 0.0] and v.tolist() == [3.0, 0.5, 2.0]


def test_a_chip_is_received_where_the_chip_model_in_use_says_it_is_low():
    """A ball chipped from (0, 0) at (3, 0, 3) m/s; the robot 3 cm beside its line at x = 1 faces it (no slack,
    no line tolerance). Its projection (1, 0) puts the dribbler at 1 - 0.0815 = 0.9185 m, where the ball is at
    t = 0.30617 s, 3 t - 9.81 t^2 / 2 = 0.4587 m high; the robot gets there (0.03 m from rest, a_max 4.5 m/s^2) in
    2 sqrt(0.03 / 4.5) = 0.163 s. Under a chip model whose reception height is 0.5 m (above the apex, 9 / 2g =
    0.4587 m: the ball is never too high to take) that is its target: it drives along field -y (robot frame +y)
    at sqrt(2 a_max braking_margin d) = sqrt(0.135) m/s; so does an interceptor (its body stops the ball) under an
    interception height of 0.5 m. Under the default model (0.15 m to stop it, a ball radius to take it) the ball
    flies over that point and every later one it reaches in time: it holds. Before a chip model has come, the
    ball is taken where its shadow is, with a notice."""
    cfg = CatcherConfig(receive_slack_s=0.0, receive_line_tolerance_m=0.0)
    offset = 0.0815

    def twist(chip_model, intercepts=False):
        receiver = Receiver(cfg, offset, intercepts=intercepts)
        if chip_model is not None:
            receiver.on_chip_model(chip_model)
        receiver.on_odom(1.0, (1.0, 0.03, math.pi), (0.0, 0.0), 1.0)
        receiver.on_ball(1.0, (0.0, 0.0, 0.0), (3.0, 0.0, 3.0))
        return receiver.tick(1.0), receiver.notice

    t = (1.0 - offset) / 3.0
    assert 3.0 * t - 4.905 * t * t == pytest.approx(0.4587, abs=1e-4)
    to_projection = (0.0, math.sqrt(2.0 * cfg.a_max_mps2 * cfg.braking_margin * 0.03), 0.0)
    high, notice = twist(ChipParams(max_catch_height_m=0.5, max_receive_height_m=0.5))
    assert high == pytest.approx(to_projection, abs=1e-9) and notice is None
    assert np.array_equal(twist(ChipParams(max_catch_height_m=0.5))[0], np.zeros(3))  # a receiver needs it lower
    assert twist(ChipParams(max_catch_height_m=0.5), intercepts=True)[0] == pytest.approx(to_projection, abs=1e-9)
    for intercepts in (False, True):
        default, notice = twist(ChipParams(), intercepts)
        assert np.array_equal(default, np.zeros(3)) and notice is None
    unknown, notice = twist(None)
    assert unknown == pytest.approx(to_projection, abs=1e-9) and "no chip model" in notice


def test_a_receiver_on_the_line_steps_back_to_where_a_chip_has_settled():
    """A chip kicked from (0, 0) at (3, 0, 3) m/s; by hand its hops (apexes 0.4587, 0.1470, 0.0471, 0.0151 m) stay
    below a ball radius (0.02135 m) from hop 2's descent through it on, at x_s = 1.8349 + 0.7418 + 2.1429 *
    (0.9611 + sqrt(0.9611^2 - 2 g 0.02135)) / g. A receiver facing it with its dribbler on the line 0.3 m before
    x_s does not stand (the ball would hop off its front there): it goes back along the line to a point where the
    ball is low for good; one whose dribbler is 0.3 m beyond x_s stands."""
    g, r = 9.81, ChipParams().max_receive_height_m
    vz = [3.0 * 0.566**k for k in range(4)]
    assert [v * v / (2.0 * g) for v in vz] == pytest.approx([0.4587, 0.1470, 0.0471, 0.0151], abs=1e-4)
    vxy1 = 3.0 / 1.4
    x2 = 3.0 * 2.0 * vz[0] / g + vxy1 * 2.0 * vz[1] / g
    assert (round(3.0 * 2.0 * vz[0] / g, 4), round(vxy1 * 2.0 * vz[1] / g, 4)) == (1.8349, 0.7418)
    x_s = x2 + vxy1 * (vz[2] + math.sqrt(vz[2] ** 2 - 2.0 * g * r)) / g
    cfg, offset = CatcherConfig(), 0.0815
    targets = []
    for dribbler_x in (x_s - 0.3, x_s + 0.3):
        receiver = Receiver(cfg, offset)
        receiver.on_chip_model(ChipParams())
        receiver.on_odom(1.0, (dribbler_x + offset, 0.0, math.pi), (0.0, 0.0), 1.0)
        receiver.on_ball(1.0, (0.0, 0.0, 0.0), (3.0, 0.0, 3.0))
        twist = receiver.tick(1.0)
        targets.append(twist)
    back, stands = targets
    assert back[1] == pytest.approx(0.0, abs=1e-9) and back[0] < 0.0  # robot frame -x: away from the ball
    assert np.array_equal(stands, np.zeros(3))


def test_a_chip_after_its_first_bounce_is_rebuilt_as_one_that_has_bounced():
    """/ball/state of a chip 0.05 s after its first touchdown (4 m/s up and along +x under the default model):
    with /ball/phase "hopping" the receiver's chip is the launched one later (its next bounce damps by
    damping_xy_other_hops), with "chip" (a stale phase) it would damp by damping_xy_first_hop again."""
    params = ChipParams()
    launched = ChipTrajectory((0.0, 0.0, 0.0), (4.0, 0.0, 4.0), params)
    t_state = launched.touchdown_times_s[0] + 0.05
    position, velocity = launched.position_at(t_state), launched.velocity_at(t_state)
    t = np.linspace(0.0, 3.0, 301)
    for phase, same in (("hopping", True), ("chip", False)):
        receiver = Receiver(CatcherConfig(), 0.0815)
        receiver.on_chip_model(params)
        receiver.on_ball_phase(phase)
        receiver.on_ball(1.0, position, velocity)
        chip = receiver._chip(1.0)
        gap_m = np.abs(chip.position_at(t) - launched.position_at(t + t_state)).max()
        assert (gap_m < 1e-9) == same, (phase, gap_m)


def test_a_phase_that_is_none_is_refused_by_name():
    from std_msgs.msg import String

    from erforce_interfaces.wire.conversions import ConversionError, ball_phase_from_msg

    assert ball_phase_from_msg(String(data="hopping")) == "hopping"
    for bad in ("", "HOPPING", "x" * 10_000):
        with pytest.raises(ConversionError, match="is none of unknown, sliding, rolling, stopped, chip, hopping"):
            ball_phase_from_msg(String(data=bad))
