"""The passing game in one process (erforce_sim.in_process.passing_game): deterministic per seed, a chain of
completed passes, and an interception counted and explained."""

import dataclasses
import itertools
import math

import pytest

from erforce_ball_model.passing.decisions import PassConfig
from erforce_ball_model.passing.player import PlayerConfig
from erforce_sim.in_process.passing_game import GameConfig, PassingGame, summary

FLAT = PlayerConfig(passing=PassConfig(chip_angle_deg=0.0))  # flat passes only: what the two-phase model says
SMALL = GameConfig(team_size=3, opponents=1, passes=3, player=FLAT)


def test_a_seed_repeats_exactly():
    cfg = dataclasses.replace(SMALL, passes=1)
    assert PassingGame(cfg, seed=3).play() == PassingGame(cfg, seed=3).play()


def test_passes_go_along_a_chain_and_arrive_when_predicted():
    """Three of ours, one opponent far from the lanes' receivers: every pass completes, the receiver of
    one pass kicks the next, and the light barrier sees the ball when the two-phase model said the ball
    reaches the receiver's dribbler (the receiver steps onto the line, a little towards the ball)."""
    records = PassingGame(SMALL, seed=1).play()
    assert [r.outcome for r in records] == ["completed"] * 3
    for before, after in itertools.pairwise(records):
        assert after.passer == before.receiver and after.receiver != before.passer  # on along the chain
    for r in records:
        assert r.caught_by == f"robot_{r.receiver}"
        assert r.actual_catch_s == pytest.approx(r.predicted_catch_s, abs=0.15)
    s = summary(records, SMALL.passing)
    assert s["completed"] == 3 and s["safe_completed"] == s["rated_safe"]


def test_an_opponent_on_the_only_lane_intercepts_and_the_record_says_why():
    """Two of ours 3 m apart with an opponent half-way on the line between them: the only pass is rated
    unsafe (the opponent's catch comes before ours), it is played, and the opponent intercepts it."""
    cfg = GameConfig(team_size=2, opponents=1, passes=1, team_positions=((-4.5, 0.0), (-1.5, 0.0)),
                     opponent_positions=((-3.0, 0.4),), player=FLAT)
    (record,) = PassingGame(cfg, seed=0).play()
    assert not record.rated_safe and record.margin_s < 0.0 and record.first_opponent == 0
    assert record.outcome == "intercepted" and record.caught_by == "opponent_0"
    assert record.actual_catch_s < record.predicted_catch_s
    assert "predicted first opponent opponent_0" in record.line()


def test_with_chips_the_pass_over_the_opponent_on_the_only_lane_is_safe_and_completes():
    """The interception scene above with chips on, which may settle behind the receiver (chip_step_back_m): the
    flat pass is not safe, and a chip that settles before the receiver comes down low enough to stop half-way,
    so the holder chips over the opponent (45 deg) to settle behind it, rated safe, and the receiver steps back
    and takes the ball once it is low."""
    step_back = PlayerConfig(passing=PassConfig(chip_step_back_m=0.5))
    cfg = GameConfig(team_size=2, opponents=1, passes=1, team_positions=((-4.5, 0.0), (-1.5, 0.0)),
                     opponent_positions=((-3.0, 0.4),), true_chip=True, player=step_back)
    (record,) = PassingGame(cfg, seed=0).play()
    assert record.kick_angle_deg == pytest.approx(45.0)
    assert record.rated_safe and record.outcome == "completed" and record.caught_by == "robot_1"


def test_the_passing_scenario_writes_the_plot_the_summary_and_a_bag(tmp_path):
    """``./run demo --scenario passing --in-process``: each pass on the terminal, and report/<time>/ with passes.png,
    summary.md (a row per pass) and a rosbag2/MCAP bag of the ground truth of every robot and the pass events."""
    from rosbags.rosbag2 import Reader

    from erforce_sim.demo.demo import main

    assert main(["--scenario", "passing", "--in-process", "--team", "2", "--opponents", "1", "--passes", "1",
                 "--seed", "0", "--out", str(tmp_path)]) == 0
    (report,) = tmp_path.iterdir()
    assert (report / "passes.png").stat().st_size > 10_000
    summary_text = (report / "summary.md").read_text()
    assert "| 1 | robot_0 | robot_1 |" in summary_text
    with Reader(report / "bag") as bag:
        counts = {c.topic: c.msgcount for c in bag.connections}
    assert counts["/sim/events"] == 1
    for topic in ("/clock", "/ground_truth/ball", "/robot_0/ground_truth/odom", "/robot_1/ground_truth/odom",
                  "/opponent_0/ground_truth/odom"):
        assert counts[topic] > 100  # 100 Hz over more than a second


def test_receivers_receive_facing_their_next_target():
    """Three of ours, one opponent: at the light-barrier moment of every pass received facing a next target,
    the receiver's heading (ground truth) points at that teammate within 0.1 rad (the game's aim tolerance is
    0.03 rad, the catcher's heading deadband 0.03 rad), where facing the incoming ball would be more than
    0.3 rad off (about 30 deg here)."""
    headings = {}

    def on_tick(game):
        r = game.records[-1] if game.records else None
        if r is not None and r.index not in headings and r.outcome == "completed" and r.facing_target is not None:
            me, them = game.world.robot_state(r.receiver), game.world.robot_state(r.facing_target)
            (x0, y0), (x1, y1) = r.ball_path[0], r.ball_path[-1]
            headings[r.index] = (me.theta, math.atan2(them.y - me.y, them.x - me.x), math.atan2(y0 - y1, x0 - x1))

    records = PassingGame(SMALL, seed=1, on_tick=on_tick).play()
    assert [r.outcome for r in records] == ["completed"] * 3
    assert len(headings) >= 2
    for theta, towards_target, towards_ball in headings.values():
        assert abs(math.remainder(theta - towards_target, 2.0 * math.pi)) < 0.1
        assert abs(math.remainder(towards_ball - towards_target, 2.0 * math.pi)) > 0.3


def test_under_a_ball_model_with_no_pass_in_reach_the_ball_still_moves_after_no_option_wait_s():
    """Our AI told a model under which every kick rests 0.29 m from the holder (a_slide -100, a_roll -50 m/s^2:
    6.5^2 - 3.9^2 over 200 plus 3.9^2 over 100; a bad model on the latched topic, say) has no pass in reach. Its
    holder falls back after no_option_wait_s (1 s) on the model it was built with (the predictor's): the same
    pass as without the bad model, kicked 1 - hold_min_s = 0.6 s later (the plain kick comes at hold_min_s,
    facing its receiver from the start), and completed."""
    from erforce_ball_model.ball_model import BallModelParams

    cfg = GameConfig(team_size=2, opponents=0, passes=1, team_positions=((-4.5, 0.0), (-1.5, 0.0)), player=FLAT)
    (plain,) = PassingGame(cfg, seed=0).play()
    notices = set()
    game = PassingGame(cfg, seed=0, on_tick=lambda g: notices.add(g.player.notice))
    game.player.on_model(BallModelParams(a_slide_mps2=-100.0, a_roll_mps2=-50.0, c_switch=0.6))
    (record,) = game.play()
    wait = cfg.player.no_option_wait_s - cfg.player.hold_min_s
    assert record.t_kick_s == pytest.approx(plain.t_kick_s + wait, abs=0.021)  # one AI tick
    assert (record.passer, record.receiver, record.outcome) == (0, 1, "completed")
    assert record.kick_speed_mps == pytest.approx(plain.kick_speed_mps, abs=1e-3)
    assert record.actual_catch_s == pytest.approx(record.predicted_catch_s, abs=0.15)
    assert any(n and "robot_0: no pass in reach for 1.0 s" in n for n in notices), notices


def test_a_model_the_predictor_takes_mid_game_reaches_the_ai_at_its_next_answer():
    """In the game the predictor's model reaches the passing AI and the interceptors as /ball/model_params does on
    the graph: once, when it changes (SSL geometry here), from the next answered ball frame on."""
    from erforce_ball_model.ball_model import BallModelParams
    from erforce_sim.sensors import BallDetection, VisionFrame

    game = PassingGame(dataclasses.replace(SMALL, passes=1), seed=0)
    receivers = game.opponents.receivers.values()
    assert game.player.model == BallModelParams() and all(r.model == BallModelParams() for r in receivers)
    model = BallModelParams(-14.0, -0.7, 0.7)
    game.predictor.set_vision_geometry(model=model)
    game._on_frame(VisionFrame(0, 1.0, 1.02, (BallDetection(0.5, 0.2),), ()))
    assert game.player.model is model and all(r.model is model for r in receivers)


def test_through_the_cameras_the_predictor_finds_our_chip_itself():
    """The scene above with the ball seen through the plant's cameras and our kicks as hints (as in every in-process
    game), no true chip: the predictor reports the chip in the air from its own detector (a frame with a chip, the
    hint's angle and speed), and the chip over the opponent completes."""
    step_back = PlayerConfig(passing=PassConfig(chip_step_back_m=0.5))
    cfg = GameConfig(team_size=2, opponents=1, passes=1, team_positions=((-4.5, 0.0), (-1.5, 0.0)),
                     opponent_positions=((-3.0, 0.4),), player=step_back)
    game = PassingGame(cfg, seed=0)
    chips = []  # (the detector's launch, the hint's speed it used) at each frame
    game.runner.vision_listeners.append(lambda frame: chips.append((game.predictor.chip_detector.launch,
                                                                    game.predictor.chip_detector.hint_speed_mps)))
    (record,) = game.play()
    assert record.kick_angle_deg == pytest.approx(45.0)
    launch, hint_speed_mps = next(c for c in chips if c[0] is not None)
    vx, vy, vz = launch.velocity_mps.tolist()
    assert math.degrees(math.atan2(vz, math.hypot(vx, vy))) == pytest.approx(45.0, abs=1.0)
    assert hint_speed_mps == pytest.approx(record.kick_speed_mps, rel=1e-9)
    assert record.rated_safe and record.outcome == "completed" and record.caught_by == "robot_1"


def test_the_games_cameras_are_the_configs_camera_model():
    """GameConfig.cameras reaches the world's vision and the cameras the predictor sees through (the plant's
    vision:=ros ones): ER-Force's without the object offset draws its noise per camera, on a 2 m band; with the
    offset the ROS vision refuses it, as the plant does."""
    from erforce_sim.ssl_cameras import BENCH_CAMERAS, ERFORCE_REALISTIC

    assert PassingGame(SMALL).cameras.rig.realism is BENCH_CAMERAS
    erforce = ERFORCE_REALISTIC.without("object_offset")
    game = PassingGame(dataclasses.replace(SMALL, cameras=erforce), seed=2)
    assert game.cameras.rig.realism is erforce and game.world.vision.params.position_noise_m == 0.0
    assert game.cameras.rig.cameras[0].x_range_m[1] == pytest.approx(1.0)  # 1 m past the axis
    with pytest.raises(ValueError, match="object offset"):
        PassingGame(dataclasses.replace(SMALL, cameras=ERFORCE_REALISTIC))
