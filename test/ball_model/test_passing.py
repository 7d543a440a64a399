"""The passing game's decisions (erforce_ball_model.passing.decisions), from hand-computed cases."""

import dataclasses
import itertools
import math

import numpy as np
import pytest

from erforce_ball_model.ball_model import BallModelParams, BallTrajectory, ChipParams
from erforce_ball_model.catch_time import CatchSearch, RobotLimits
from erforce_ball_model.passing.decisions import (
    PassConfig,
    PassOption,
    evaluate_passes,
    kick_speed_for,
    press_targets,
    select_pass,
)

MODEL = BallModelParams(a_slide_mps2=-2.5, a_roll_mps2=-0.3, c_switch=0.6)
OFFSET = 0.0815
CFG = PassConfig()


def test_kick_speed_arriving_while_rolling():
    """2 m, 1.5 m/s left: sliding would need sqrt(1.5^2 + 2*2.5*2) = 3.5 m/s, but 0.6*3.5 = 2.1 > 1.5, so the
    ball rolls on arrival: v0^2 = (2.25 + 2*0.3*2) / (0.36 + 0.64*0.3/2.5) = 3.45 / 0.4368."""
    v0 = kick_speed_for(2.0, 1.5, MODEL)
    assert v0 == pytest.approx(math.sqrt(3.45 / 0.4368), rel=1e-12)
    ball = BallTrajectory((0.0, 0.0), (v0, 0.0), v0, MODEL)  # the forward model agrees
    assert float(ball.speed_at(ball.time_to_distance(2.0))) == pytest.approx(1.5, abs=1e-9)


def test_kick_speed_arriving_while_sliding():
    """0.5 m, 3 m/s left: v0 = sqrt(9 + 2*2.5*0.5) = sqrt(11.5) = 3.391; 0.6*3.391 = 2.03 < 3: still sliding."""
    v0 = kick_speed_for(0.5, 3.0, MODEL)
    assert v0 == pytest.approx(math.sqrt(11.5), rel=1e-12)
    ball = BallTrajectory((0.0, 0.0), (v0, 0.0), v0, MODEL)
    assert float(ball.speed_at(ball.time_to_distance(0.5))) == pytest.approx(3.0, abs=1e-9)


def test_kick_speed_edge_and_bad_input():
    assert kick_speed_for(0.0, 2.0, MODEL) == pytest.approx(2.0)
    with pytest.raises(ValueError, match="finite"):
        kick_speed_for(-1.0, 1.0, MODEL)
    with pytest.raises(ValueError, match="finite"):
        kick_speed_for(1.0, math.nan, MODEL)


def _option(receiver, t_receiver, t_opponent):
    return PassOption(receiver, 3.0, 0.0, t_receiver, t_opponent, 0 if math.isfinite(t_opponent) else None)


def test_select_pass_takes_the_earliest_safe_catch():
    options = [_option(1, 1.0, 1.2),  # margin 0.2 < 0.3: unsafe although earliest
               _option(2, 1.5, 3.0),  # safe, margin 1.5
               _option(3, 1.3, 1.7),  # safe, margin 0.4, earlier: chosen
               _option(4, 1.4, math.inf)]  # no opponent can catch it: safe
    assert select_pass(options, CFG).receiver == 3


def test_select_pass_without_a_safe_one_takes_the_largest_margin():
    options = [_option(1, 1.0, 0.5), _option(2, 2.0, 2.1), _option(3, math.inf, 5.0)]
    chosen = select_pass(options, CFG)
    assert chosen.receiver == 2 and chosen.margin_s == pytest.approx(0.1) and not chosen.safe(CFG)
    assert select_pass([_option(1, math.inf, 1.0)], CFG) is None
    assert select_pass([], CFG) is None


def _search(n):
    return CatchSearch(n, RobotLimits(4.5, 2.5), dribbler_offset_m=OFFSET, unbounded=True)


def test_an_opponent_on_the_lane_makes_a_pass_unsafe_and_the_free_teammate_is_chosen():
    """Ball at the origin (passer 0 behind it). Teammate 1 at (2, 0) has an opponent standing at (1, 0) on its
    lane: the ball reaches that opponent's dribbler first, so its margin is negative. Teammate 2 at (0, 2)
    is free (the opponent is 2.2 m from its lane's end and behind its line), and is chosen."""
    team = np.array([[-0.1, 0.0], [2.0, 0.0], [0.0, 2.0]])
    opponents = np.array([[1.0, 0.0]])
    flat_only = PassConfig(chip_angle_deg=0.0)
    options = evaluate_passes((0.0, 0.0), team, np.zeros_like(team), opponents, np.zeros_like(opponents), [1, 2],
                              _search(4), MODEL, flat_only, OFFSET)
    by = {o.receiver: o for o in options}
    assert by[1].margin_s < 0.0 and by[1].first_opponent == 0
    assert by[2].safe(CFG)
    assert select_pass(options, CFG).receiver == 2
    # The receiver receives where it stands: its catch is the ball's arrival at its dribbler, 1.9185 m, at
    # 1.5 m/s, rolling (v0 * 0.6 > 1.5): t = t_switch + (v_switch - 1.5) / 0.3.
    o = by[2]
    v0 = o.kick_speed_mps
    t_arrive = (v0 - 0.6 * v0) / 2.5 + (0.6 * v0 - 1.5) / 0.3
    assert o.receiver_catch_s == pytest.approx(t_arrive, abs=1e-9)
    assert o.direction_rad == pytest.approx(math.pi / 2)
    assert o.kick_speed_mps == pytest.approx(kick_speed_for(2.0 - OFFSET, CFG.arrive_speed_mps, MODEL))


def test_an_opponent_beside_the_lane_blocks_the_pass_with_its_body():
    """Opponent standing at (1, 0.1) beside the lane from the origin to teammate 1 at (3, 0). Its dribbler cannot
    meet the ball (robotTimeToBall: it only gets the ball at rest, far later), but its body is on the path: the
    ball's centre comes within robot + ball radius (0.11135 m) of its centre after 1 - sqrt(0.11135^2 - 0.1^2)
    = 0.95101 m. With a reaction time longer than that (0.5 s) it does not move: the ball, still sliding there,
    takes t = (v0 - sqrt(v0^2 - 2 * 2.5 * 0.95101)) / 2.5 to it, and the pass is no longer safe."""
    cfg = dataclasses.replace(CFG, reaction_s=0.5, chip_angle_deg=0.0)  # the flat pass's rating
    team = np.array([[-0.1, 0.0], [3.0, 0.0]])
    opponents = np.array([[1.0, 0.1]])
    radius = 0.09 + 0.02135

    def option(block_radius_m):
        (o,) = evaluate_passes((0.0, 0.0), team, np.zeros_like(team), opponents, np.zeros_like(opponents), [1],
                               _search(3), MODEL, cfg, OFFSET, block_radius_m=block_radius_m)
        return o

    catch_only, blocked = option(0.0), option(radius)
    assert catch_only.safe(cfg) and catch_only.opponent_catch_s > 2.0
    v0 = blocked.kick_speed_mps
    along = 1.0 - math.sqrt(radius ** 2 - 0.1 ** 2)
    assert 0.6 * v0 < math.sqrt(v0 ** 2 - 2.0 * 2.5 * along)  # still sliding there
    assert blocked.opponent_catch_s == pytest.approx((v0 - math.sqrt(v0 ** 2 - 2.0 * 2.5 * along)) / 2.5, abs=1e-6)
    assert blocked.first_opponent == 0 and not blocked.safe(cfg)
    assert blocked.receiver_catch_s == catch_only.receiver_catch_s  # the receiver still needs the real catch
    # a blocker further off than its reach before the ball comes changes nothing
    far = evaluate_passes((0.0, 0.0), team, np.zeros_like(team), np.array([[1.0, 1.5]]), np.zeros((1, 2)), [1],
                          _search(3), MODEL, cfg, OFFSET, block_radius_m=radius)[0]
    plain = evaluate_passes((0.0, 0.0), team, np.zeros_like(team), np.array([[1.0, 1.5]]), np.zeros((1, 2)), [1],
                            _search(3), MODEL, cfg, OFFSET)[0]
    assert far.opponent_catch_s == plain.opponent_catch_s


def test_teammates_out_of_range_are_no_option():
    team = np.array([[0.0, 0.0], [0.5, 0.0], [7.0, 0.0]])
    opponents = np.array([[0.0, 3.0]])
    options = evaluate_passes((0.0, 0.0), team, np.zeros_like(team), opponents, np.zeros_like(opponents), [1, 2],
                              _search(4), MODEL, CFG, OFFSET)
    assert options == []


def test_press_targets_cover_one_lane_each_then_double_up():
    """Ball at the origin with robot 0; mates at (2, 0) and (0, 2); half way along the lanes are (1, 0) and
    (0, 1). The opponent nearest to (2, 0) takes that lane, the other the second; a third doubles up on the
    lane of the mate nearest to it."""
    team = np.array([[0.0, 0.0], [2.0, 0.0], [0.0, 2.0]])
    opponents = np.array([[2.2, 0.1], [0.1, 1.5], [3.0, 0.0]])
    targets = press_targets((0.0, 0.0), team, opponents, 0, CFG)
    np.testing.assert_allclose(targets, [[1.0, 0.0], [0.0, 1.0], [1.0, 0.0]])


def test_a_receiver_with_a_next_target_is_rated_facing_it_and_the_kick_aims_at_its_dribbler():
    """Ball at the origin, teammate 1 at (3, 0), its next target at (2, 0.8): 38.7 deg off the ball's way
    back (180 deg), inside the 45 deg receive angle, so it receives facing f = atan2(0.8, -1). Its dribbler
    is then at (3, 0) + 0.0815 (cos f, sin f) = (2.93636, 0.05091): the kick aims there, 0.01734 rad left of
    +x, and its catch is the ball's arrival after 2.93680 m at 1.5 m/s. A next target straight up from it is
    90 deg off: it is rated facing the ball, the kick aims at its centre as without a target."""
    team = np.array([[-0.1, 0.0], [3.0, 0.0], [2.0, 0.8]])
    opponents = np.array([[0.0, -3.0]])
    facing = math.atan2(0.8, -1.0)
    aim = np.array([3.0 + OFFSET * math.cos(facing), OFFSET * math.sin(facing)])
    np.testing.assert_allclose(aim, [2.93636, 0.05091], atol=1e-5)
    (o,) = evaluate_passes((0.0, 0.0), team, np.zeros_like(team), opponents, np.zeros_like(opponents), [1],
                           _search(4), MODEL, CFG, OFFSET, {1: team[2]})
    assert o.receive_facing_rad == pytest.approx(facing)
    assert o.direction_rad == pytest.approx(math.atan2(aim[1], aim[0]), abs=1e-12)
    assert o.direction_rad == pytest.approx(0.01734, abs=1e-5)
    assert o.kick_speed_mps == pytest.approx(kick_speed_for(math.hypot(*aim), CFG.arrive_speed_mps, MODEL))
    v0 = o.kick_speed_mps
    assert o.receiver_catch_s == pytest.approx((v0 - 0.6 * v0) / 2.5 + (0.6 * v0 - 1.5) / 0.3, abs=1e-9)
    (up,) = evaluate_passes((0.0, 0.0), team, np.zeros_like(team), opponents, np.zeros_like(opponents), [1],
                            _search(4), MODEL, CFG, OFFSET, {1: (3.0, 2.0)})
    assert up.direction_rad == pytest.approx(0.0, abs=1e-12)
    assert abs(math.remainder(up.receive_facing_rad - math.pi, 2.0 * math.pi)) < 1e-12
    assert up.kick_speed_mps == pytest.approx(kick_speed_for(3.0 - OFFSET, CFG.arrive_speed_mps, MODEL))


def test_the_receiver_and_opponents_search_gives_the_whole_fields_options():
    """evaluate_passes with ``receiver_search`` (the receiver and the 3 opponents searched) against the plain
    whole-field search, on a hand-built field of 6 teammates: one receiver with a next target, one out of
    reach, an opponent on a lane, robots moving. robotTimeToBall is per robot: every option equal, bit for bit."""
    team = np.array([[-0.1, 0.0], [2.0, 0.0], [0.0, 2.5], [-2.0, 1.0], [7.5, 0.0], [1.5, -2.0]])
    team_vel = np.array([[0.0, 0.0], [0.3, -0.2], [0.0, 0.5], [-0.4, 0.0], [0.0, 0.0], [0.2, 0.2]])
    opponents = np.array([[1.0, 0.05], [-1.0, 2.0], [2.5, -1.5]])
    opp_vel = np.array([[0.0, 0.0], [0.5, 0.0], [-0.3, 0.4]])
    for cfg, targets in itertools.product((CFG, PassConfig(chip_angle_deg=0.0)), ({}, {2: team[1], 5: team[3]})):
        plain = evaluate_passes((0.0, 0.0), team, team_vel, opponents, opp_vel, [1, 2, 3, 4, 5], _search(9), MODEL,
                                cfg, OFFSET, targets, chip_params=ChipParams())
        narrow = evaluate_passes((0.0, 0.0), team, team_vel, opponents, opp_vel, [1, 2, 3, 4, 5], _search(9), MODEL,
                                 cfg, OFFSET, targets, receiver_search=_search(4), chip_params=ChipParams())
        assert [o.receiver for o in plain] == [1, 2, 3, 5]  # 4 is 7.5 m away
        assert narrow == plain
        by = {o.receiver: o for o in plain}
        # the lane to 1 is covered half-way: a chip that settles before the receiver comes down low enough to
        # stop (0.15 m) about half-way and hits it (test_a_chip_over_an_opponent_half_way... steps back instead)
        assert by[1].first_opponent == 0 and by[1].margin_s < 0.0
    with pytest.raises(ValueError, match="receiver_search is for 3 robots"):
        evaluate_passes((0.0, 0.0), team, team_vel, opponents, opp_vel, [1], _search(9), MODEL, CFG, OFFSET,
                        receiver_search=_search(3))


def test_a_robot_not_finite_is_refused_with_or_without_the_receiver_search():
    """A teammate that is not a candidate but has a NaN velocity: the whole field's search refuses it, and so
    does evaluate_passes with the receiver search (it leaves such a field to the whole search)."""
    team = np.array([[-0.1, 0.0], [2.0, 0.0], [0.0, 2.5]])
    team_vel = np.array([[0.0, 0.0], [0.0, 0.0], [math.nan, 0.0]])
    opponents = np.array([[1.0, 3.0]])
    for extra in ({}, {"receiver_search": _search(2)}):
        with pytest.raises(ValueError, match="must be finite"):
            evaluate_passes((0.0, 0.0), team, team_vel, opponents, np.zeros_like(opponents), [1], _search(4), MODEL,
                            CFG, OFFSET, **extra)


def _hops_by_hand(vxy: float, vz: float, p: ChipParams) -> list[tuple[float, float, float, float]]:
    """(start time, start distance, horizontal speed, vertical speed) of each hop of a chip kicked from the ground,
    from ChipParams' definition: a hop lasts 2 vz / g; a bounce keeps damping_z of vz and damping_xy_first_hop,
    then damping_xy_other_hops, of vxy; one leaving less than min_hop_vz_mps ends them."""
    hops, t, x = [], 0.0, 0.0
    while vz >= p.min_hop_vz_mps:
        hops.append((t, x, vxy, vz))
        t, x = t + 2.0 * vz / p.g_mps2, x + vxy * 2.0 * vz / p.g_mps2
        vxy *= p.damping_xy_first_hop if len(hops) == 1 else p.damping_xy_other_hops
        vz *= p.damping_z
    return hops


def test_a_chip_goes_over_an_opponent_near_the_passer_and_settles_before_the_receiver():
    """The scene above with the opponent nearer the passer, at (0.4, 0): the flat pass to teammate 1 is unsafe, a
    45 deg chip over the opponent is safe. By hand (``_hops_by_hand``): the chip stays below the reception height
    (a ball radius) from chip_settle_fraction of the way to the receiver's dribbler (2 - 0.0815 m) on, the last
    hop above it coming down through it there; the receiver's catch is the ball's arrival at its dribbler, in the
    hop that crosses it; over the opponent's body (0.4 +- 0.11 m) the ball is above the interception height.
    Without a chip model (none has come from the predictor) no chip is rated."""
    team = np.array([[-0.1, 0.0], [2.0, 0.0], [0.0, 2.0]])
    opponents = np.array([[0.4, 0.0]])
    unknown = evaluate_passes((0.0, 0.0), team, np.zeros_like(team), opponents, np.zeros_like(opponents), [1, 2],
                              _search(4), MODEL, CFG, OFFSET, block_radius_m=0.11)
    assert [o.kick_angle_deg for o in unknown] == [0.0, 0.0] and not unknown[0].safe(CFG)
    options = evaluate_passes((0.0, 0.0), team, np.zeros_like(team), opponents, np.zeros_like(opponents), [1, 2],
                              _search(4), MODEL, CFG, OFFSET, chip_params=ChipParams(), block_radius_m=0.11)
    by = {o.receiver: o for o in options}
    o = by[1]
    assert o.kick_angle_deg == 45.0 and o.safe(CFG) and o.direction_rad == pytest.approx(0.0)
    assert by[2].kick_angle_deg == 0.0  # safe flat: no chip
    p = ChipParams()
    g, r, h = p.g_mps2, p.max_receive_height_m, p.max_catch_height_m
    v = o.kick_speed_mps / math.sqrt(2.0)
    hops = _hops_by_hand(v, v, p)
    _, x_k, vxy_k, vz_k = [hop for hop in hops if hop[3] ** 2 / (2.0 * g) > r][-1]  # the last hop above r
    x_settle = x_k + vxy_k * (vz_k + math.sqrt(vz_k**2 - 2.0 * g * r)) / g
    contact = 2.0 - OFFSET
    assert x_settle == pytest.approx(CFG.chip_settle_fraction * contact, abs=1e-6)
    t_c, x_c, vxy_c, _ = [hop for hop in hops if hop[1] <= contact][-1]
    assert o.receiver_catch_s == pytest.approx(t_c + (contact - x_c) / vxy_c, abs=1e-9)
    for x in (0.4 - 0.11, 0.4 + 0.11):  # over the opponent's body, in the first hop
        t = x / v
        assert v * t - 0.5 * g * t * t > h
    assert select_pass(options, CFG).receiver in (1, 2)


def test_a_chip_over_an_opponent_half_way_settles_behind_the_receiver_which_steps_back():
    """The opponent half-way, at (1, 0.05): the chip that settles before the receiver (``chip_settle_fraction``)
    comes down low enough to stop about half-way and would hit it; the one that settles behind the receiver
    (half a ``chip_step_back_m``, then a whole one, here 0.5 m; by default 0: none) flies farther. By hand
    (``_hops_by_hand``): its hops stay below the reception height from a point behind the receiver's dribbler
    (2 - 0.0815 m) on, 0.25 or 0.5 m behind; the receiver's catch is where it meets the ball after that, when the
    ball is low."""
    team = np.array([[-0.1, 0.0], [2.0, 0.0], [0.0, 2.5]])
    opponents = np.array([[1.0, 0.05]])
    cfg = dataclasses.replace(CFG, chip_step_back_m=0.5)
    (where_it_stands,) = evaluate_passes((0.0, 0.0), team, np.zeros_like(team), opponents, np.zeros_like(opponents),
                                         [1], _search(4), MODEL, CFG, OFFSET, chip_params=ChipParams(),
                                         block_radius_m=0.11)
    assert CFG.chip_step_back_m == 0.0 and not where_it_stands.safe(CFG)
    (o,) = evaluate_passes((0.0, 0.0), team, np.zeros_like(team), opponents, np.zeros_like(opponents), [1],
                           _search(4), MODEL, cfg, OFFSET, chip_params=ChipParams(), block_radius_m=0.11)
    assert o.kick_angle_deg == 45.0 and o.safe(cfg)
    p = ChipParams()
    g, r = p.g_mps2, p.max_receive_height_m
    v = o.kick_speed_mps / math.sqrt(2.0)
    hops = _hops_by_hand(v, v, p)
    t_k, x_k, vxy_k, vz_k = [hop for hop in hops if hop[3] ** 2 / (2.0 * g) > r][-1]  # the last hop above r
    t_settle = t_k + (vz_k + math.sqrt(vz_k**2 - 2.0 * g * r)) / g
    x_settle = x_k + vxy_k * (t_settle - t_k)
    contact = 2.0 - OFFSET
    assert x_settle == pytest.approx(contact + 0.25, abs=1e-6) or x_settle == pytest.approx(contact + 0.5, abs=1e-6)
    assert o.receiver_catch_s >= t_settle
    t_c, x_c, vxy_c, _ = [hop for hop in hops if hop[0] <= o.receiver_catch_s][-1]
    assert contact < x_c + vxy_c * (o.receiver_catch_s - t_c) <= contact + 0.5 + 1e-9


def test_a_chip_is_rated_with_a_clearance_over_an_opponent_under_its_descent():
    """grSim's chip model (its geometry's fixed-loss dampings 0.42 / 0.6 / 0.96) and an opponent that cannot move
    (limits near zero: it stops the ball only where the ball runs into its body) on the lane at (1.45, 0); the
    receiver at (2.5, 0). The 45 deg chip that settles at 0.9 of the way to the receiver's dribbler (2.5 - 0.0815 m;
    chip_settle_fraction) leaves at 4.161 m/s, 2.942 m/s each way. By hand: it lands 2 * 2.942^2 / 9.81 = 1.765 m out,
    past the opponent's body (1.45 +- 0.11 m), so the lowest it is over that body is where it leaves it, at 1.56 m
    (0.530 s): 2.942 * 0.530 - 9.81 / 2 * 0.530^2 = 0.181 m, above the interception height (0.15 m) but not above it
    plus the clearance (0.05 m). So the chip is safe without the clearance and unsafe with it, as grSim's 0.167 m
    robots make it."""
    grsim = dataclasses.replace(ChipParams(), damping_z=0.42, damping_xy_first_hop=0.6, damping_xy_other_hops=0.96)
    team = np.array([[-0.1, 0.0], [2.5, 0.0], [0.0, 2.5]])
    opponents = np.array([[1.45, 0.0]])
    limits = RobotLimits(np.array([4.5, 4.5, 4.5, 1e-6]), np.array([2.5, 2.5, 2.5, 1e-6]))
    search = CatchSearch(4, limits, dribbler_offset_m=OFFSET, unbounded=True)
    rated = {}
    for clearance_m in (0.0, CFG.chip_clearance_m):
        cfg = dataclasses.replace(CFG, chip_settle_fraction=0.9, chip_clearance_m=clearance_m)
        (rated[clearance_m],) = evaluate_passes((0.0, 0.0), team, np.zeros_like(team), opponents,
                                                np.zeros_like(opponents), [1], search, MODEL, cfg, OFFSET,
                                                chip_params=grsim, block_radius_m=0.11)
    without, with_clearance = rated[0.0], rated[CFG.chip_clearance_m]
    assert CFG.chip_clearance_m == 0.05
    assert without.kick_angle_deg == with_clearance.kick_angle_deg == 45.0
    assert without.kick_speed_mps == pytest.approx(4.161, abs=1e-3) == with_clearance.kick_speed_mps
    v = without.kick_speed_mps / math.sqrt(2.0)
    assert 2.0 * v * v / grsim.g_mps2 == pytest.approx(1.765, abs=1e-3)
    t = (1.45 + 0.11) / v
    height_m = v * t - 0.5 * grsim.g_mps2 * t * t
    assert t == pytest.approx(0.530, abs=1e-3) and height_m == pytest.approx(0.181, abs=1e-3)
    assert grsim.max_catch_height_m < height_m < grsim.max_catch_height_m + CFG.chip_clearance_m
    assert without.safe(CFG) and not with_clearance.safe(CFG)
