"""Our team's AI in the passing game, one AI tick at a time (passing.player.PassingPlayer), fed by hand: when the
holder kicks and how hard, how a pass ends (completed, intercepted, lost), and what it asks of the referee."""

import math

import numpy as np
import pytest

from erforce_ball_model.ball_model import BallModelParams, ChipParams
from erforce_ball_model.passing.decisions import PassConfig
from erforce_ball_model.passing.player import (
    HELD_DISTANCE_M,
    PassingPlayer,
    PassRecord,
    PlayerConfig,
    PressingTeam,
    launch_direction,
)
from erforce_ball_model.receiver import CatcherConfig, catch_twist, wrap_angle
from erforce_interfaces.wire.robot_config import FieldConfig, RobotConfig

ROBOT = RobotConfig()
FIELD = FieldConfig.preset("division_a")
OFFSET = ROBOT.dribbler_offset_m  # 0.0815 m

# Two of ours on the x axis, 3 m apart, facing each other: robot 0 at the origin holds the ball at its
# dribbler (0.0815, 0); robot 1 at (3, 0) receives facing the ball, its dribbler at 3 - 0.0815. The ball
# travels d = 3 - 2 * 0.0815 = 2.837 m and must arrive at 1.5 m/s (PassConfig.arrive_speed_mps). With the
# default model (slides at 2.5 m/s^2 down to 0.6 v0, then rolls at 0.3 m/s^2) it slides 0.64 v0^2 / 5 and
# rolls (0.36 v0^2 - 1.5^2) / 0.6: 0.728 v0^2 - 3.75 = 2.837, v0 = 3.0080 m/s; it arrives after
# 0.4 v0 / 2.5 + (0.6 v0 - 1.5) / 0.3 = 1.4970 s.
D_M = 3.0 - 2.0 * OFFSET
V0 = math.sqrt((D_M + 3.75) / 0.728)
ARRIVAL_S = 0.4 * V0 / 2.5 + (0.6 * V0 - 1.5) / 0.3


# The scenes written for flat passes (a chip would go over the opponents on the lanes).
FLAT_ONLY = PlayerConfig(passing=PassConfig(chip_angle_deg=0.0))


CHIP_MODEL = ChipParams()  # the predictor's chip model at its defaults


def player_with(ours, theirs=(), cfg=None, trusted=None, chip_model=CHIP_MODEL):
    """A player that has seen every robot at rest at (x, y, yaw) and holds the ball at robot 0 from t = 0
    (``trusted``: the model it trusts, as a new game on a new time line keeps it; None: the default), told the
    chip model in use ``chip_model`` (None: none has come)."""
    cfg = PlayerConfig() if cfg is None else cfg
    p = PassingPlayer(cfg, len(ours), len(theirs), FIELD, OFFSET, ROBOT.robot_radius_m, BallModelParams(), trusted,
                      chip_model)
    for i, pose in enumerate((*ours, *theirs)):
        p.on_robot(i, 0.0, pose, (0.0, 0.0))
    p.on_ball(0.0, (OFFSET, 0.0), (0.0, 0.0))
    p.start(0.0, 0)
    assert p.ball_request == 0
    p.ball_placed(0.0)
    p.on_barrier(0, 0.0, True)
    return p


def kicked(p, t_kick=0.5, turn=False):
    """Tick until robot 0 kicks (it may not before hold_min_s); the kick's time. ``turn``: robot 0 faces its
    chosen pass at once (as if it had turned)."""
    for t in np.arange(0.0, t_kick + 1e-9, 0.02):
        commands = p.tick(float(t))
        if commands.kicks:
            return float(t), commands
        if turn and p.choice is not None:
            p.on_robot(0, float(t), (0.0, 0.0, p.choice[1].direction_rad), (0.0, 0.0))
    raise AssertionError("no kick")


def test_the_holder_kicks_after_hold_min_s_with_the_speed_that_arrives_receivable():
    p = player_with([(0.0, 0.0, 0.0), (3.0, 0.0, math.pi)])
    assert p.holder == 0 and p.dribblers() == {0: True, 1: False}
    t, commands = kicked(p)
    assert t == pytest.approx(0.4)  # hold_min_s; it faces the pass already
    assert commands.kicks == {0: pytest.approx(V0, abs=1e-3)}
    # the ball leaves the holder's dribbler; the receiver's holds it when it comes
    assert commands.dribblers == {0: False, 1: True}
    passer, choice = p.choice
    assert (passer, choice.receiver) == (0, 1) and choice.direction_rad == pytest.approx(0.0, abs=1e-9)
    assert choice.receiver_catch_s == pytest.approx(ARRIVAL_S, abs=1e-3)
    assert math.isinf(choice.opponent_catch_s) and choice.safe(PassConfig())


def test_a_holder_turns_to_its_pass_no_faster_than_turn_rate_and_kicks_only_once_aimed():
    """Robot 0 faces away (yaw pi/2) from its only teammate at (3, 0): it turns at turn_rate_radps (3 rad/s)
    and cannot kick before it has turned pi/2 (0.52 s at that rate), however long it has held the ball."""
    p = player_with([(0.0, 0.0, 0.5 * math.pi), (3.0, 0.0, math.pi)])
    p.on_robot(0, 0.5, (0.0, 0.0, 0.5 * math.pi), (0.0, 0.0))  # a fresh pose: the nominal gain, 8 /s
    commands = p.tick(0.5)
    assert not commands.kicks
    assert commands.twists[0][2] == pytest.approx(-3.0)
    assert commands.twists[0][:2] == pytest.approx([0.0, 0.0], abs=1e-9)  # it turns in place
    assert commands.twists[1] == pytest.approx([0.0, 0.0, 0.0])
    p.on_robot(0, 0.52, (0.0, 0.0, 0.02), (0.0, 0.0))  # within aim_tolerance_rad (0.03)
    assert p.tick(0.52).kicks


def test_a_pass_completed_by_its_receiver_makes_it_the_holder():
    p = player_with([(0.0, 0.0, 0.0), (3.0, 0.0, math.pi)])
    t_kick, _ = kicked(p)
    p.on_ball(t_kick + 0.1, (0.5, 0.0), (2.5, 0.0))
    p.tick(t_kick + 0.1)
    p.on_barrier(1, t_kick + 1.5, True)
    p.check(t_kick + 1.52)
    (record,) = p.records
    assert (record.outcome, record.caught_by, record.passer, record.receiver) == ("completed", "robot_1", 0, 1)
    assert record.actual_catch_s == pytest.approx(1.5)  # the barrier's time, not the check's
    assert record.rated_safe and record.predicted_catch_s == pytest.approx(ARRIVAL_S, abs=1e-3)
    assert p.holder == 1 and p.dribblers() == {0: False, 1: True} and p.ball_request is None


def test_the_passers_own_barrier_ends_no_pass_right_after_its_kick():
    p = player_with([(0.0, 0.0, 0.0), (3.0, 0.0, math.pi)])
    t_kick, _ = kicked(p)
    p.on_barrier(0, t_kick + 0.01, False)
    p.on_barrier(0, t_kick + 0.02, True)  # the ball still at the kicker: passer_blind_s (0.5 s)
    p.on_ball(t_kick + 0.02, (0.1, 0.0), (3.0, 0.0))
    p.check(t_kick + 0.02)
    assert p.passing and not p.records


def test_an_interception_is_recorded_and_the_ball_asked_back_at_our_robot_farthest_from_the_opponents():
    """Three of ours, one opponent at (1.5, 2): robot 2 at (0, -3) is farther from it (5.22 m) than robot 0
    (2.5 m) and robot 1 at (3, 0) (2.5 m), so the ball goes back to robot 2."""
    ours = [(0.0, 0.0, 0.0), (3.0, 0.0, math.pi), (0.0, -3.0, 0.5 * math.pi)]
    p = player_with(ours, [(1.5, 2.0, -0.5 * math.pi)])
    t_kick, _ = kicked(p, t_kick=2.0, turn=True)
    receiver = p.choice[1].receiver
    p.on_ball(t_kick + 0.2, (0.6, 0.0), (2.5, 0.0))
    p.on_barrier(3, t_kick + 0.6, True)  # world index 3: opponent_0
    p.check(t_kick + 0.62)
    (record,) = p.records
    assert (record.outcome, record.caught_by, record.receiver) == ("intercepted", "opponent_0", receiver)
    assert record.actual_catch_s == pytest.approx(0.6)
    assert f"opponent_0 caught at 0.60 s, {record.predicted_catch_s - 0.6:+.2f} s before our predicted catch" in (
        record.line())
    assert p.ball_request == 2 and p.holder is None and p.resets == 1
    assert not any(p.dribblers().values())
    p.ball_placed(t_kick + 0.7)
    assert p.holder == 2 and p.dribblers()[2]


def test_a_ball_that_rests_before_anybody_catches_it_is_lost():
    p = player_with([(0.0, 0.0, 0.0), (3.0, 0.0, math.pi)])
    t_kick, _ = kicked(p)
    p.on_ball(t_kick + 1.0, (2.0, 0.0), (0.0, 0.0))  # at rest (below rest_speed_mps 0.05)
    p.check(t_kick + 1.0)
    p.check(t_kick + 1.4)
    assert not p.records  # not yet rest_for_s (0.5 s)
    p.check(t_kick + 1.52)
    (record,) = p.records
    assert (record.outcome, record.caught_by, record.actual_catch_s) == ("lost", None, None)
    assert p.ball_request == 0  # no opponents: robot 0


def test_a_holder_whose_barrier_stays_dark_dropped_the_ball():
    """The barrier is trusted from hold_min_s (0.4 s) on; dark for more than drop_after_s (0.3 s) after that: a
    drop."""
    p = player_with([(0.0, 0.0, 0.5 * math.pi), (3.0, 0.0, math.pi)])
    p.on_barrier(0, 0.05, False)
    for t in (0.1, 0.38, 0.42, 0.6, 0.7):
        p.tick(t)
        assert p.drops == 0 and p.holder == 0
    p.tick(0.74)
    assert p.drops == 1 and p.ball_request == 0 and p.holder is None


def test_without_a_safe_pass_the_holder_waits_wait_for_safe_s_then_plays_the_best():
    """An opponent half-way on the only lane catches long before robot 1: the pass is rated unsafe; the holder
    keeps the ball 1.5 s (wait_for_safe_s), then plays it (flat passes only: a chip would go over)."""
    flat_only = PlayerConfig(passing=PassConfig(chip_angle_deg=0.0))
    p = player_with([(0.0, 0.0, 0.0), (3.0, 0.0, math.pi)], [(1.5, 0.0, math.pi)], flat_only)
    t_kick, _ = kicked(p, t_kick=3.0)
    assert t_kick == pytest.approx(1.5)
    choice = p.choice[1]
    assert not choice.safe(PassConfig()) and choice.first_opponent == 0 and choice.margin_s < 0.0


def test_with_an_opponent_on_the_only_lane_the_holder_chips_over_it_and_the_receiver_takes_it_low():
    """The scene above with chips and the opponent nearer the holder (0.6 m: a chip that settles before the
    receiver comes down low enough to stop a little over half-way): the chip is safe, so the holder kicks after
    hold_min_s with the kick angle; the receiver, fed the chip in the air (x, y, z), does not run under the flight
    to a point where the ball still hops above its dribbler."""
    p = player_with([(0.0, 0.0, 0.0), (3.0, 0.0, math.pi)], [(0.6, 0.0, math.pi)])
    t_kick, commands = kicked(p, t_kick=3.0)
    choice = p.choice[1]
    assert t_kick == pytest.approx(0.4) and choice.safe(PassConfig())
    assert commands.kick_angles == {0: PassConfig().chip_angle_deg}
    assert commands.kicks == {0: pytest.approx(choice.kick_speed_mps)}
    # the ball just kicked, 0.3 m on and rising: the receiver on its line stands still
    v = choice.kick_speed_mps / math.sqrt(2.0)
    p.on_ball(t_kick + 0.1, (OFFSET + 0.3, 0.0, 0.25), (v, 0.0, v - 9.81 * 0.1))
    twist = p.tick(t_kick + 0.1).twists[1]
    assert np.allclose(twist, 0.0)
    # the receiver stands beside the line instead: it goes to a point beyond where the chip comes down
    p.receiver.on_odom(t_kick + 0.12, (3.0, 0.4, math.pi), (0.0, 0.0))
    p.on_ball(t_kick + 0.12, (OFFSET + 0.35, 0.0, 0.27), (v, 0.0, v - 9.81 * 0.12))
    from erforce_ball_model.chip_model import ChipTrajectory
    from erforce_ball_model.receiver import choose_target

    chip = ChipTrajectory((OFFSET + 0.35, 0.0, 0.27), (v, 0.0, v - 9.81 * 0.12), ChipParams(), BallModelParams())
    target = choose_target(np.array([3.0, 0.4, math.pi]), np.zeros(2), chip.ground_track(), None, OFFSET,
                           PlayerConfig().catcher, FIELD, chip=chip)
    assert target is not None
    t_there = chip.ground_track().time_to_distance(float(target[0] - OFFSET - (OFFSET + 0.35)))
    t_settled = chip.time_below_height_s(ChipParams().max_receive_height_m)
    assert t_there >= t_settled
    assert target[0] - OFFSET >= chip.position_at(t_settled)[0] - 1e-9


G_MPS2 = 9.81


def test_the_holder_rates_and_its_receiver_takes_a_chip_with_the_chip_model_in_use():
    """The chip scene of the test before last (the opponent half-way, at 1.5 m) under a chip model that is not the
    defaults (a ball taken up to 0.11 m, softer bounces), and before any chip model has come. By hand, 45 deg: the
    ball travels 2.9185 - 0.0815 = 2.837 m to the receiver's dribbler and stays below h = 0.11 m from x =
    chip_settle_fraction of that on: only its first hop rises above h (the second to 0.4^2 of its apex), so
    x = v (v + sqrt(v^2 - 2 g h)) / g with v the horizontal (= vertical) speed, v^2 = g x^2 / (2 (x - h)), and the
    kick speed is sqrt(2) v. That hop comes down to 0.15 m well past the opponent: the chip is safe. The catch is
    the ball's arrival at 2.837 m: each hop lasts 2 vz / g at the horizontal speed it has (vz times damping_z, vxy
    times damping_xy_first_hop then damping_xy_other_hops at each bounce), the receiver takes it in the hop that
    crosses 2.837 m, where it is below h."""
    chip_model = ChipParams(damping_z=0.4, damping_xy_first_hop=0.8, damping_xy_other_hops=0.9,
                            max_receive_height_m=0.11)
    contact = 3.0 - 2.0 * OFFSET
    x = PassConfig().chip_settle_fraction * contact
    h = chip_model.max_receive_height_m
    v = math.sqrt(G_MPS2 * x * x / (2.0 * (x - h)))
    assert (0.4 * v) ** 2 / (2.0 * G_MPS2) < h  # the second hop stays below h
    travelled, t_s, vxy, vz, bounces = 0.0, 0.0, v, v, 0
    while True:  # hop by hop to the one that crosses the contact
        hop_s = 2.0 * vz / G_MPS2
        if travelled + vxy * hop_s >= contact:
            t_in = (contact - travelled) / vxy
            t_s += t_in
            z_there = vz * t_in - 0.5 * G_MPS2 * t_in**2
            break
        travelled, t_s = travelled + vxy * hop_s, t_s + hop_s
        vxy *= chip_model.damping_xy_first_hop if bounces == 0 else chip_model.damping_xy_other_hops
        vz *= chip_model.damping_z
        bounces += 1
    assert bounces == 1 and vz > chip_model.min_hop_vz_mps  # it comes in on its second hop, low, still hopping
    assert 0.0 <= z_there <= h

    unknown = player_with([(0.0, 0.0, 0.0), (3.0, 0.0, math.pi)], [(1.5, 0.0, math.pi)], chip_model=None)
    unknown.tick(0.1)
    assert unknown.choice[1].kick_angle_deg == 0.0  # no chip model: flat passes only
    p = player_with([(0.0, 0.0, 0.0), (3.0, 0.0, math.pi)], [(1.5, 0.0, math.pi)], chip_model=None)
    p.on_chip_model(chip_model)
    _, commands = kicked(p, t_kick=3.0)
    choice = p.choice[1]
    assert commands.kick_angles == {0: 45.0} and choice.safe(PassConfig())
    assert choice.kick_speed_mps == pytest.approx(math.sqrt(2.0) * v, abs=1e-6)
    assert choice.receiver_catch_s == pytest.approx(t_s, abs=1e-6)
    assert p.receiver.chip_model is chip_model  # its receiver predicts the chip with it too
    other = ChipParams(max_catch_height_m=0.2)
    p.on_chip_model(other)  # a new one while the ball flies: the receiver takes that
    assert p.receiver.chip_model is other


def test_a_record_goes_over_the_wire_and_back():
    from erforce_ball_model.passing.passing_game_node import record_from_row, record_row

    for record in (
        PassRecord(3, 12.5, 1, 4, 3.01, 1.5, 0.82, 1, False, "intercepted", "opponent_1", 1.66, (), None),
        PassRecord(4, 20.0, 4, 6, 2.9, 1.2, math.inf, None, True, "completed", "robot_6", 1.19, (), 9),
        PassRecord(5, 30.0, 6, 2, 2.9, 1.2, 2.0, 0, True, "lost", None, None, (), None),
        PassRecord(6, 31.0, 2, 3, 4.5, 0.9, math.inf, None, True, "completed", "robot_3", 1.2, (), None, 45.0),
    ):
        assert record_from_row(record_row(record)) == record


def test_the_nodes_parameter_defaults_are_the_cores():
    """One default per quantity: passing_game's schema says what PlayerConfig() and PassConfig() do."""
    import dataclasses

    from erforce_ball_model.passing import passing_game_node

    defaults = {s.name: s.default for s in passing_game_node.SCHEMA.specs}
    for cfg in (PlayerConfig(), PassConfig()):
        for f in dataclasses.fields(cfg):
            if f.name in defaults:
                assert defaults[f.name] == getattr(cfg, f.name), f.name
    built = passing_game_node.build(passing_game_node.SCHEMA.parse(defaults))
    assert built[0].passing == PassConfig() and built[0].hold_min_s == PlayerConfig().hold_min_s


# The opponents' side (PressingTeam): the other team's robot 0 at the origin facing +x holds the ball at its
# dribbler (OFFSET, 0); its teammates stand at (3, 0) and (0, 2). With press_fraction 0.5 the lanes' waiting
# points are the midpoints from the ball: (1.54075, 0) and (0.04075, 1). Of the pressing robots, 1 at
# (0.3, 1.5) is closest to (0, 2) (0.583 m; robot 0 at (1, 0.3) is 1.972 m from it): 1 takes that lane, 0 the
# one to (3, 0).
OTHERS = ((0.0, 0.0, 0.0), (3.0, 0.0, math.pi), (0.0, 2.0, -0.5 * math.pi))
PRESSERS = {0: (1.0, 0.3, 0.0), 1: (0.3, 1.5, 0.0)}
LANES = {0: ((OFFSET + 3.0) / 2.0, 0.0), 1: (OFFSET / 2.0, 1.0)}


def pressing_team(ball_xy=(OFFSET, 0.0), ball_v=(0.0, 0.0), press=True):
    team = PressingTeam(CatcherConfig(), OFFSET, ROBOT.robot_radius_m, FIELD, PRESSERS,
                        passing=PassConfig(press_fraction=0.5) if press else None, n_other=len(OTHERS))
    for k, pose in enumerate(OTHERS):
        team.on_other_robot(k, 0.0, pose)
    for i, pose in PRESSERS.items():
        team.on_odom(i, 0.0, pose, (0.0, 0.0))
    team.on_ball(0.0, ball_xy, ball_v)
    return team


def test_the_pressing_team_waits_on_the_passing_lanes_while_the_other_team_holds_the_ball():
    assert LANES[0] == pytest.approx((1.54075, 0.0))
    team = pressing_team()
    assert team.holder(0.02) == 0
    targets = team.press_targets(0.02)
    assert sorted(targets) == [0, 1]
    for i in PRESSERS:
        np.testing.assert_allclose(targets[i], LANES[i], atol=1e-12)
    twists = team.tick(0.02)
    for i, pose in PRESSERS.items():
        facing = math.atan2(-pose[1], OFFSET - pose[0])  # towards the ball
        np.testing.assert_allclose(twists[i], catch_twist(np.array(pose), np.array(LANES[i]), facing, CatcherConfig()))
        way = np.subtract(LANES[i], pose[:2])  # yaw 0: the robot frame is the field's
        assert twists[i][:2] @ way > 0.0 and abs(twists[i][0] * way[1] - twists[i][1] * way[0]) < 1e-9


def test_a_loose_ball_a_rolling_ball_or_no_pressing_sends_nobody_to_the_lanes():
    loose = pressing_team(ball_xy=(OFFSET + HELD_DISTANCE_M + 0.01, 0.0))
    assert loose.holder(0.02) is None and loose.press_targets(0.02) == {}
    assert all(not np.any(t) for t in loose.tick(0.02).values())  # a resting ball engages no receiver
    off = pressing_team(press=False)
    assert off.press_targets(0.02) == {} and all(not np.any(t) for t in off.tick(0.02).values())
    stale = pressing_team()
    assert stale.press_targets(CatcherConfig().stale_after_s + 0.01) == {}
    nobody = PressingTeam(CatcherConfig(), OFFSET, ROBOT.robot_radius_m, FIELD, (), passing=PassConfig(), n_other=3)
    assert nobody.tick(0.0) == {}  # a game without opponents
    with pytest.raises(ValueError, match="distinct"):
        PressingTeam(CatcherConfig(), OFFSET, ROBOT.robot_radius_m, FIELD, (1, 1))
    # A pass rolls from the holder towards (3, 0) at 3 m/s: the team's receivers take over, and only the one
    # with the earlier catch time (robot 0: 0.5 s against 1.2 s) drives.
    rolling = pressing_team(ball_xy=(0.3, 0.0), ball_v=(3.0, 0.0))
    assert rolling.holder(0.02) is None
    rolling.on_catch_time(0, 0.02, 0.5)
    rolling.on_catch_point(0, 0.02, (1.0, 0.0))
    rolling.on_catch_time(1, 0.02, 1.2)
    rolling.on_catch_point(1, 0.02, (2.0, 0.0))
    twists = rolling.tick(0.02)
    assert np.any(twists[0]) and not np.any(twists[1])


def test_team_catchers_press_fraction_default_is_the_cores():
    from erforce_ball_model import team_catcher_node

    defaults = {s.name: s.default for s in team_catcher_node.SCHEMA.specs}
    assert defaults["press_fraction"] == PassConfig().press_fraction and defaults["press_lanes"] is False


# A ball model under which no pass is in reach: the fastest kick (6.5 m/s) slides down to 3.9 m/s in
# (6.5^2 - 3.9^2) / (2 * 100) = 0.1352 m and rolls 3.9^2 / (2 * 50) = 0.1521 m: it rests 0.287 m from the
# holder, short of every teammate (at least min_distance_m = 0.8 m away). It passes BallModelParams' checks.
SHORT = BallModelParams(a_slide_mps2=-100.0, a_roll_mps2=-50.0, c_switch=0.6)


def test_a_holder_with_no_pass_in_reach_replans_with_the_model_of_its_last_completed_pass_after_the_wait():
    """Under SHORT the holder has no option: no choice, no kick, no notice for no_option_wait_s (1 s), although
    hold_min_s (0.4 s) is long past; then it plays the pass planned with the model it was built with (the
    default: V0, ARRIVAL_S as derived at the top), says why, and its receiver rolls the ball with that model."""
    p = player_with([(0.0, 0.0, 0.0), (3.0, 0.0, math.pi)], cfg=FLAT_ONLY)
    p.on_model(SHORT)
    for t in np.arange(0.0, 0.99, 0.02):
        commands = p.tick(float(t))
        assert not commands.kicks and p.choice is None and p.notice is None, t
        assert commands.twists[0] == pytest.approx([0.0, 0.0, 0.0])  # it holds the ball, dribbler on
        assert commands.dribblers[0]
    commands = p.tick(1.0)
    assert commands.kicks == {0: pytest.approx(V0, abs=1e-3)}
    passer, choice = p.choice
    assert (passer, choice.receiver) == (0, 1) and choice.receiver_catch_s == pytest.approx(ARRIVAL_S, abs=1e-3)
    assert "robot_0: no pass in reach for 1.0 s under the ball model in use (a_slide -100, a_roll -50" in p.notice
    assert "model of the last completed pass (a_slide -2.5, a_roll -0.3 m/s^2, c_switch 0.6) to robot_1" in p.notice
    assert p.receiver._model == BallModelParams()
    # the pass completes: planned with the default model, that model stays the trusted one
    p.on_barrier(1, 1.0 + ARRIVAL_S, True)
    p.check(1.0 + ARRIVAL_S)
    assert p.records[-1].outcome == "completed" and p.trusted_model == BallModelParams()


def test_a_pass_completed_under_the_model_in_use_makes_it_the_trusted_one():
    """A model that stops a kick later than the default (half its decelerations) is in use from the start: the
    first pass is planned with it, and once completed a fallback would re-plan with it."""
    slower = BallModelParams(a_slide_mps2=-1.25, a_roll_mps2=-0.15, c_switch=0.6)
    p = player_with([(0.0, 0.0, 0.0), (3.0, 0.0, math.pi)], cfg=FLAT_ONLY)
    p.on_model(slower)
    t_kick, commands = kicked(p)
    # it slides 0.64 v0^2 / 2.5 and rolls (0.36 v0^2 - 1.5^2) / 0.3: 1.456 v0^2 - 7.5 = d (v0 = 2.664 m/s, so
    # it rolls on arrival: 0.6 v0 > 1.5)
    assert commands.kicks[0] == pytest.approx(math.sqrt((D_M + 7.5) / 1.456), abs=1e-3)
    assert p.trusted_model == BallModelParams()
    p.on_barrier(1, t_kick + 2.0, True)
    p.check(t_kick + 2.0)
    assert p.records[-1].outcome == "completed" and p.trusted_model == slower


def test_a_holder_that_trusts_a_model_with_no_pass_in_reach_either_replans_with_the_nominal_model():
    """Under SHORT in use and trusted (a pass was completed with it, or a new time line kept it), no pass is in
    reach under either, not even outside the passing distances: after no_option_wait_s the holder plays the pass
    planned with the nominal model (BallModelParams(): V0, ARRIVAL_S as derived at the top)."""
    p = player_with([(0.0, 0.0, 0.0), (3.0, 0.0, math.pi)], cfg=FLAT_ONLY, trusted=SHORT)
    p.on_model(SHORT)
    for t in np.arange(0.0, 0.99, 0.02):
        assert not p.tick(float(t)).kicks and p.choice is None, t
    commands = p.tick(1.0)
    assert commands.kicks == {0: pytest.approx(V0, abs=1e-3)}
    assert p.choice[1].receiver_catch_s == pytest.approx(ARRIVAL_S, abs=1e-3)
    assert "the nominal model (a_slide -2.5, a_roll -0.3 m/s^2, c_switch 0.6) to robot_1" in p.notice
    assert p.receiver._model == BallModelParams()


def test_a_holder_whose_only_other_teammate_is_out_of_reach_passes_back_after_the_wait():
    """Robot 0 passes to robot 1 (3 m away; robot 2, 4 m away, is later); then robot 2 stands on robot 1's
    dribbler, where no pass reaches it. A pass goes along the chain, not back to the passer, so robot 1 has no
    option; after no_option_wait_s it passes back to robot 0, 3 m away, under the model in use: V0 again."""
    p = player_with([(0.0, 0.0, 0.0), (3.0, 0.0, math.pi), (0.0, 4.0, 0.0)], cfg=FLAT_ONLY)
    t_kick, commands = kicked(p)
    assert commands.kicks == {0: pytest.approx(V0, abs=1e-3)} and p.choice[1].receiver == 1
    t_caught = t_kick + ARRIVAL_S
    p.on_barrier(1, t_caught, True)
    p.check(t_caught)
    assert p.records[-1].outcome == "completed"
    p.on_robot(0, t_caught, (0.0, 0.0, 0.0), (0.0, 0.0))
    p.on_robot(2, t_caught, (3.0 - 0.05, 0.0, 0.0), (0.0, 0.0))
    p.on_ball(t_caught, (3.0 - OFFSET, 0.0), (0.0, 0.0))
    for t in np.arange(t_caught, t_caught + 0.99, 0.02):
        assert not p.tick(float(t)).kicks, t
    for t in np.arange(t_caught + 1.0, t_caught + 3.0, 0.02):  # it turns to robot 0 first (pi at turn_rate)
        p.on_robot(1, float(t), (3.0, 0.0, math.pi), (0.0, 0.0))
        commands = p.tick(float(t))
        if commands.kicks:
            break
    assert commands.kicks == {1: pytest.approx(V0, abs=1e-3)} and p.choice[1].receiver == 0
    assert "a pass outside the passing distances to robot_0" in p.notice


def test_a_holder_whose_teammates_are_all_too_close_passes_outside_the_passing_distances_after_the_wait():
    """Robot 1 stands 0.5 m away, closer than min_distance_m (0.8 m): no option under any model. After
    no_option_wait_s the holder passes to it anyway: the ball travels d = 0.5 - 2 * 0.0815 = 0.337 m; it still
    slides on arrival at 1.5 m/s (1.5 >= 0.6 v0), so v0 = sqrt(1.5^2 + 2 * 2.5 * d) = 1.9837 m/s."""
    p = player_with([(0.0, 0.0, 0.0), (0.5, 0.0, math.pi)])
    assert not p.tick(0.98).kicks and p.choice is None
    commands = p.tick(1.0)
    assert not commands.kicks and p.choice is None  # the wait begins at the first tick without a pass
    commands = p.tick(1.98)
    assert commands.kicks == {0: pytest.approx(math.sqrt(1.5**2 + 5.0 * (0.5 - 2.0 * OFFSET)), abs=1e-3)}
    assert "no pass in reach for 1.0 s" in p.notice and "a pass outside the passing distances to robot_1" in p.notice


def test_a_ball_kicked_by_a_turning_robot_leaves_to_the_side_it_turns_to():
    """The ball on the dribbler moves with the robot's front: sideways at yaw rate times the dribbler offset. By
    hand: 2.8 m/s along a heading of 0 from a robot turning at +2 rad/s with the dribbler 0.102 m ahead leaves
    along atan2(0.204, 2.8) = 4.167 deg; the robot's own 0.5 m/s along -y takes it back to atan2(-0.296, 2.8)."""
    assert math.degrees(launch_direction(0.0, 2.0, (0.0, 0.0), 2.8, 0.102)) == pytest.approx(4.1670, abs=1e-4)
    assert math.degrees(launch_direction(0.0, 2.0, (0.0, -0.5), 2.8, 0.102)) == pytest.approx(-6.0346, abs=1e-4)
    # a heading of 90 deg turns all of it: the sideways part points along -x
    assert launch_direction(0.5 * math.pi, 2.0, (0.0, 0.0), 2.8, 0.102) == pytest.approx(
        0.5 * math.pi + math.atan2(0.204, 2.8))
    assert launch_direction(1.0, 0.0, (0.0, 0.0), 2.8, 0.102) == pytest.approx(1.0)  # at rest: its heading


def test_a_holder_still_turning_does_not_kick_though_it_faces_its_pass():
    """The pass of the first scene (robot 1 at (3, 0), straight along +x at V0 = 3.008 m/s). Robot 0 faces it
    exactly but still turns at +2 rad/s: over the command's lead (command_lead_s 0.04 s, the pose being fresh) it
    turns 0.08 rad on, and the ball leaves a further atan2(2 * 0.0815, 3.008) = 0.0541 rad to that side, 0.134 rad
    off the pass (aim_tolerance_rad 0.03): no kick. Facing -0.134 rad, the ball would leave along the pass if it
    turned on, but not if it stopped as it kicks: no kick either. Facing -0.005 rad and turning at 0.2 rad/s, the
    ball leaves between -0.005 and -0.005 + 0.008 + atan2(0.2 * 0.0815, 3.008) = 0.0084 rad: the kick."""
    lead_s = CatcherConfig().command_lead_s
    off = 2.0 * lead_s + math.atan2(2.0 * OFFSET, V0)
    assert off == pytest.approx(0.1341, abs=1e-4)
    p = player_with([(0.0, 0.0, 0.0), (3.0, 0.0, math.pi)])
    p.on_robot(0, 0.5, (0.0, 0.0, 0.0), (0.0, 0.0, 2.0), stamp_s=0.5)
    assert not p.tick(0.5).kicks
    p.on_robot(0, 0.52, (0.0, 0.0, -off), (0.0, 0.0, 2.0), stamp_s=0.52)
    assert not p.tick(0.52).kicks
    assert -0.005 + 0.2 * lead_s + math.atan2(0.2 * OFFSET, V0) == pytest.approx(0.0084, abs=1e-4)
    p.on_robot(0, 0.54, (0.0, 0.0, -0.005), (0.0, 0.0, 0.2), stamp_s=0.54)
    assert p.tick(0.54).kicks == {0: pytest.approx(V0, abs=1e-3)}


def turning_kick(p, deadline_s, dt_s=0.02, before_tick=None):
    """Tick until robot 0 kicks, turning it by each tick's commanded yaw rate with the ball at its dribbler (a
    plant that follows the command exactly), ``before_tick(k, t)`` first at each tick k; the kick's time, or None by
    ``deadline_s``."""
    for k, t in enumerate(np.arange(0.0, deadline_s + 1e-9, dt_s)):
        if before_tick is not None:
            before_tick(k, float(t))
        commands = p.tick(float(t))
        if commands.kicks:
            return float(t)
        x, y, yaw = p.poses[0]
        yaw = float(wrap_angle(yaw + commands.twists[0][2] * dt_s))
        p.on_robot(0, float(t) + dt_s, (x, y, yaw), (0.0, 0.0, commands.twists[0][2]))
        p.on_ball(float(t) + dt_s, (x + OFFSET * math.cos(yaw), y + OFFSET * math.sin(yaw)), (0.0, 0.0))
    return None


def test_a_holder_between_two_equal_receivers_in_opposite_directions_turns_to_one_and_kicks():
    # Robot 0 faces +y, its receivers 3 m away at +x and -x: the same pass mirrored, the same catch time. It
    # turns pi/2 (0.52 s at turn_rate_radps 3) and kicks: by hold_min_s + 0.52 s + settling, well before 1.5 s.
    p = player_with([(0.0, 0.0, 0.5 * math.pi), (3.0, 0.0, math.pi), (-3.0, 0.0, 0.0)])
    t = turning_kick(p, 1.5)
    assert t is not None and t >= 0.5 * math.pi / 3.0
    assert p.records == [] and p.passing and p.choice[1].receiver in (1, 2)


def test_a_kept_pass_whose_rating_flickers_unsafe_for_less_than_keep_choice_s_is_still_kicked():
    # Robot 0 faces +y between receivers 3 m away at +x (robot 1, its choice: the earlier) and 3.5 m away at -x
    # (robot 2). Opponent 3 stands off both lanes at (1.5, 3) but its track jumps onto robot 1's lane at (1.5, 0)
    # for 0.06 s of every 0.3 s (3 of 15 ticks): robot 1's pass is unsafe then, robot 2's is safe. Shorter than
    # keep_choice_s (0.3 s), the flicker does not turn robot 0 away: it turns pi/2 to robot 1 (0.52 s at 3 rad/s)
    # and kicks by 1.2 s. (Switching at each flicker and back, as robot 1 is earlier by more than switch_margin_s,
    # it would turn back and forth and never aim.)
    p = player_with([(0.0, 0.0, 0.5 * math.pi), (3.0, 0.0, math.pi), (-3.5, 0.0, 0.0)], [(1.5, 3.0, 0.0)], FLAT_ONLY)

    def flicker(k: int, t: float) -> None:
        on_lane = k % 15 >= 12
        p.on_robot(3, t, (1.5, 0.0 if on_lane else 3.0, 0.0), (0.0, 0.0))
        if on_lane:
            assert not next(o for o in p._options(0) if o.receiver == 1).safe(p.cfg.passing)

    kick_t = turning_kick(p, 1.2, before_tick=flicker)
    assert kick_t is not None and kick_t >= 0.5 * math.pi / 3.0
    assert p.choice[1].receiver == 1


def test_a_kept_pass_is_not_left_for_an_earlier_one_whose_rating_flickers_safe_for_less_than_keep_choice_s():
    # The same robots, the flicker the other way round: opponent 3 stands on robot 1's lane at (1.5, 0) and steps
    # off it to (1.5, 3) for 0.06 s of every 0.3 s (3 of 15 ticks). Robot 0 starts on robot 2's pass (the only safe
    # one); robot 1's, earlier by more than switch_margin_s, is rated safe only in those short windows, never
    # keep_choice_s (0.3 s) on end, so robot 0 stays with robot 2: it turns pi/2 to -x (0.52 s at 3 rad/s) and kicks
    # by 1.2 s. (Following each safe flicker to robot 1 and back, as the opponents pressing the lanes made a holder
    # on grSim do, it would never aim.)
    p = player_with([(0.0, 0.0, 0.5 * math.pi), (3.0, 0.0, math.pi), (-3.5, 0.0, 0.0)], [(1.5, 0.0, 0.0)], FLAT_ONLY)

    def flicker(k: int, t: float) -> None:
        off_lane = k % 15 >= 12
        p.on_robot(3, t, (1.5, 3.0 if off_lane else 0.0, 0.0), (0.0, 0.0))
        if off_lane:
            one, two = (next(o for o in p._options(0) if o.receiver == i) for i in (1, 2))
            assert one.safe(p.cfg.passing) and one.receiver_catch_s + p.cfg.switch_margin_s < two.receiver_catch_s

    kick_t = turning_kick(p, 1.2, before_tick=flicker)
    assert kick_t is not None and kick_t >= 0.5 * math.pi / 3.0
    assert p.choice[1].receiver == 2


def test_a_holders_pass_is_rated_from_where_it_kicks_whatever_its_yaw_now():
    # The ball of each pass starts at the dribbler turned to it: (0.0815, 0) for robot 1 at +x, (-0.0815, 0) for
    # robot 2 at -x, whether robot 0 faces +x, +y or -x; each pass travels 3 - 2 * 0.0815 m, as D_M.
    ratings = []
    for yaw in (0.0, 0.5 * math.pi, math.pi):
        p = player_with([(0.0, 0.0, yaw), (3.0, 0.0, math.pi), (-3.0, 0.0, 0.0)], [(0.7, 0.4, 0.0)], FLAT_ONLY)
        ratings.append(sorted((o.receiver, o.receiver_catch_s, o.opponent_catch_s, o.kick_speed_mps)
                              for o in p._options(0)))
    assert ratings[0] == ratings[1] == ratings[2]
    (_, catch1_s, _, v1), (_, catch2_s, _, v2) = ratings[0]
    assert v1 == pytest.approx(V0, abs=1e-3) and v2 == pytest.approx(V0, abs=1e-3)
    assert catch1_s == pytest.approx(ARRIVAL_S, abs=1e-3) and catch2_s == pytest.approx(ARRIVAL_S, abs=1e-3)


def test_a_holder_that_has_not_kicked_after_stall_warn_s_says_why():
    # Robot 0 faces +y and never turns (its pose is never updated): its pass to robot 1 at +x stays pi/2 off.
    p = player_with([(0.0, 0.0, 0.5 * math.pi), (3.0, 0.0, math.pi)], cfg=FLAT_ONLY)
    stall_s = p.cfg.stall_warn_s
    assert stall_s == pytest.approx(4.0)
    for t in np.arange(0.0, stall_s + 0.1, 0.02):
        assert not p.tick(float(t)).kicks
        if t < stall_s - 1e-9:
            assert p.stalled is None
    assert p.stalled == ("robot_0 has held the ball 4.1 s without kicking: its pass to robot_1 (safe) is 1.571 rad "
                         "off its yaw (aim_tolerance_rad 0.03)")


def test_every_pressing_robot_receives_a_chip_with_the_chip_model_in_use():
    """The opponents' team: none before a chip model comes, then every receiver has the one in use, a new one
    replacing it (a ball in the air is predicted with it, receiver.Receiver)."""
    team = PressingTeam(CatcherConfig(), OFFSET, ROBOT.robot_radius_m, FIELD, (0, 1, 2))
    assert team.chip_model is None and all(r.chip_model is None for r in team.receivers.values())
    first, second = ChipParams(max_catch_height_m=0.2), ChipParams(damping_z=0.3)
    given = PressingTeam(CatcherConfig(), OFFSET, ROBOT.robot_radius_m, FIELD, (0, 1), chip_model=first)
    assert all(r.chip_model is first for r in given.receivers.values())
    given.on_chip_model(second)
    assert given.chip_model is second and all(r.chip_model is second for r in given.receivers.values())
