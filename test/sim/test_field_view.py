"""The field view's core (erforce_sim.view.field_view): what a frame says, from hand-built messages.

Path numbers are worked by hand from the two-phase kinematics (module docstring of ball_model):
a ball at 2 m/s with v_shoot 2 m/s and the default model (a_slide -2.5, a_roll -0.3 m/s^2,
c_switch 0.6) switches at 1.2 m/s after (2 - 1.2) / 2.5 = 0.32 s and 2 * 0.32 - 1.25 * 0.32^2
= 0.512 m, then rolls 1.2 / 0.3 = 4 s and 1.2 * 4 - 0.15 * 16 = 2.4 m: it stops 2.912 m on, at 4.32 s.
"""

from __future__ import annotations

import json
import math
import struct
from types import SimpleNamespace

import numpy as np
import pytest
from geometry_msgs.msg import Twist
from rclpy.serialization import serialize_message
from std_msgs.msg import Bool, Float64, Float64MultiArray, String

from erforce_ball_model.passing.decisions import PassConfig, PassOption
from erforce_interfaces.wire import contract as c
from erforce_interfaces.wire.clouds import BallTrack, ball_track_cdr
from erforce_interfaces.wire.conversions import float64_cdr, odometry_cdr, odometry_msg, point_cdr
from erforce_interfaces.wire.robot_config import FieldConfig
from erforce_interfaces.wire.stamps import StampFilter
from erforce_interfaces.wire.tables import table_msg
from erforce_sim.demo.passing_report import GameBag, pass_choice_cdr
from erforce_sim.in_process.passing_game import GameConfig
from erforce_sim.view.bag_replay import BagReplay
from erforce_sim.view.field_view import (
    PATH_MARK_PERIOD_S,
    STAMP_MAX_JUMP_S,
    WorldState,
    decode_frame_bytes,
    view_topic,
)
from erforce_sim.view.field_view_node import decode

FIELD = FieldConfig.preset("division_b")


def ball_state(state: WorldState, t: float, xy, v) -> None:
    assert state.apply(c.BALL_STATE.name, odometry_cdr(t, (*xy, 0.0), (*v, 0.0)))


def robot(state: WorldState, robot_id: int, t: float, pose, catch_time=None, catch_point=None) -> None:
    assert state.apply(c.GROUND_TRUTH_ODOM.for_robot(robot_id), odometry_cdr(t, pose, (0.0, 0.0, 0.0)))
    if catch_time is not None:
        assert state.apply(c.CATCH_TIME.for_robot(robot_id), float64_cdr(catch_time))
    if catch_point is not None:
        assert state.apply(c.CATCH_POINT.for_robot(robot_id), point_cdr(t, catch_point))


def test_topics_of_the_view_are_recognised_by_name():
    assert view_topic("/robot_3/catch_time") == (c.CATCH_TIME, 3)
    assert view_topic("/ball/state") == (c.BALL_STATE, None)
    for other in ("/robot_x/catch_time", "/robot_3/cmd_vel", "/robot_3/vision_pose", "/clock", "/robot_3",
                  "catch_time", ""):
        assert view_topic(other) is None


def test_the_predicted_path_is_the_ball_models_sliding_and_rolling_stretches():
    state = WorldState(FIELD)
    assert state.apply(c.BALL_V_SHOOT.name, float64_cdr(2.0))
    ball_state(state, 1.0, (1.0, -1.0), (0.0, 2.0))  # along +y
    path = state.frame()["path"]
    assert path["start"] == [1.0, -1.0]
    assert path["switch"] == pytest.approx([1.0, -1.0 + 0.512], abs=1e-4)
    assert path["stop"] == pytest.approx([1.0, -1.0 + 2.912], abs=1e-4)
    assert path["switch_time"] == pytest.approx(0.32, abs=1e-4)
    assert path["stop_time"] == pytest.approx(4.32, abs=1e-4)
    assert len(path["marks"]) == 17  # every 0.25 s up to 4.32 s
    # at 0.25 s the ball still slides: 2 * 0.25 - 1.25 * 0.0625 = 0.421875 m
    assert path["marks"][0] == pytest.approx([1.0, -1.0 + 0.421875], abs=1e-4)


def test_the_predicted_path_reflects_off_the_fields_wall():
    """Rolling at 2 m/s along +x from x = 3 on Division B: it meets the wall (4.5 + 0.3 m less the ball's radius)
    at v1 = sqrt(4 - 0.6 * d), comes off it and stops inside (test_ball_walls derives the numbers); the page gets
    the first stretch to the wall, its speeds and the turns, the binary frame the same."""
    state = WorldState(FIELD)
    assert state.apply(c.BALL_V_SHOOT.name, float64_cdr(2.0 / 0.6))
    ball_state(state, 1.0, (3.0, 0.5), (2.0, 0.0))
    frame = state.frame()
    path = frame["path"]
    wall_x = 4.8 - 0.02135
    v1 = math.sqrt(4.0 - 0.6 * (wall_x - 3.0))
    assert path["wall"] == pytest.approx([wall_x, 0.5], abs=1e-4)
    assert path["wall_time"] == pytest.approx((2.0 - v1) / 0.3, abs=1e-4)
    assert path["wall_speed"] == pytest.approx(v1, abs=1e-4)
    assert path["stop"][0] < wall_x - 0.1 and path["stop"] == frame["stop_point"]
    assert len(path["corners"]) == 1  # where the slide off the wall ends
    assert all(abs(x) <= wall_x + 1e-9 for x, _ in path["marks"])
    assert path["stop_time"] > path["wall_time"] and len(path["marks"]) == int(path["stop_time"] / 0.25)
    decoded = decode_frame_bytes(state.frame_bytes())["path"]  # not rounded to 0.1 mm as the dict frame
    path.pop("marks")
    assert decoded.keys() == path.keys()
    for key, value in path.items():
        assert np.ravel(decoded[key]).tolist() == pytest.approx(np.ravel(value).tolist(), abs=1e-4), key

def test_the_predictors_ball_track_gives_the_ball_path_phase_and_speeds_in_one_message():
    """The case above from /ball/track alone (seen at (1.01, -0.98), rolling, uncertain); a second track 0.2 s
    on, slower than the model (2 - 2.5 * 0.2 = 1.5 m/s), keeps the speed curve; one refused changes nothing."""
    state = WorldState(FIELD, stamp_filters={})
    track = BallTrack(1.0, 1.0, -1.0, 0.0, 2.0, 2.0, 1.01, -0.98, "rolling", True)
    assert state.apply(c.BALL_TRACK.name, ball_track_cdr(track))
    frame = state.frame()
    assert frame["ball"] == {"phase": "rolling", "v_shoot": 2.0, "uncertain": True, "seen": [1.01, -0.98],
                             "state": [1.0, -1.0, 0.0, 2.0]}
    assert frame["path"]["switch"] == pytest.approx([1.0, -1.0 + 0.512], abs=1e-4)
    assert frame["stop_point"] == pytest.approx([1.0, -1.0 + 2.912], abs=1e-4)
    assert frame["speed"] == {"t": 1.0, "filtered": 2.0, "model": 2.0}
    assert decode_frame_bytes(state.frame_bytes())["ball"] == frame["ball"]
    later = track._replace(t_s=1.2, y_m=-0.65, vy_mps=1.4, phase="sliding", uncertain=False)
    assert state.apply(c.BALL_TRACK.name, ball_track_cdr(later))
    frame = state.frame()
    assert (frame["ball"]["phase"], frame["ball"]["uncertain"]) == ("sliding", False)
    assert frame["speed"] == {"t": 1.2, "filtered": 1.4, "model": pytest.approx(1.5, abs=1e-4)}
    assert decode_frame_bytes(state.frame_bytes())["ball"]["phase"] == "sliding"  # the page's part sent anew
    assert not state.apply(c.BALL_TRACK.name, ball_track_cdr(later)[:-40])
    assert state.frame()["ball"] == frame["ball"] and state.rejected == 1


def test_the_path_uses_the_model_the_predictor_publishes():
    """In use: a_slide -5, a_roll -0.5, c_switch 0.5. From 2 m/s: switch at 1 m/s after 0.2 s and
    2 * 0.2 - 2.5 * 0.04 = 0.3 m, then 1 / 0.5 = 2 s rolling over 1 * 2 - 0.25 * 4 = 1 m: stop at 1.3 m."""
    state = WorldState(FIELD)
    rows = [[-5.0, -0.5, 0.5], [-2.4, -0.31, 0.61], [0.1, 0.01, 0.02]]  # in_use, fit, std_error
    assert state.apply(c.BALL_MODEL_PARAMS.name, table_msg(rows, c.BALL_MODEL_PARAM_LABELS, "in_use,fit,std_error"))
    assert state.apply(c.BALL_V_SHOOT.name, float64_cdr(2.0))
    ball_state(state, 1.0, (0.0, 0.0), (2.0, 0.0))
    frame = state.frame()
    assert frame["path"]["switch"] == pytest.approx([0.3, 0.0], abs=1e-4)
    assert frame["path"]["stop"] == pytest.approx([1.3, 0.0], abs=1e-4)
    assert frame["model"] == {"a_slide": -5.0, "a_roll": -0.5, "c_switch": 0.5}


def test_a_short_path_has_no_marks_but_its_ends():
    """From 0.5 m/s, rolling already (v_shoot 2: 0.5 <= 0.6 * 2): it stops 0.5^2 / 0.6 = 0.41667 m on after 1.6667 s."""
    state = WorldState(FIELD)
    assert state.apply(c.BALL_V_SHOOT.name, float64_cdr(2.0))
    ball_state(state, 1.0, (0.0, 0.0), (0.0, -0.5))
    path = state.frame()["path"]
    assert path["switch"] == [0.0, 0.0] and path["stop"] == pytest.approx([0.0, -0.41667], abs=1e-4)
    assert len(path["marks"]) == 6 and path["stop_time"] == pytest.approx(1.6667, abs=1e-4)
    state.apply(c.BALL_STATE.name, odometry_cdr(1.1, (0.0, 0.0, 0.0), (0.0, -0.05, 0.0)))  # 0.1667 s: no mark
    path = state.frame()["path"]
    assert path["marks"] == [] and path["stop"] == pytest.approx([0.0, -0.05**2 / 0.6], abs=1e-4)


def test_a_ball_at_rest_has_no_path():
    state = WorldState(FIELD)
    ball_state(state, 1.0, (0.5, 0.5), (0.0, 0.0))
    assert state.frame()["path"] is None


def test_the_receiver_is_the_teams_earliest_catcher_and_its_target_its_catch_point():
    state = WorldState(FIELD, opponent_ids=frozenset({1}))
    robot(state, 0, 1.0, (0.0, 0.0, 0.0), 1.2, (0.5, 0.0))
    robot(state, 1, 1.0, (1.0, 0.0, 0.0), 0.1, (1.0, 0.1))  # an opponent is earlier: not ours
    robot(state, 2, 1.0, (2.0, 0.0, 0.0), 0.8, (2.0, 0.2))
    frame = state.frame()
    assert frame["receiver"] == {"id": 2, "target": [2.0, 0.2], "catch_time": 0.8}
    assert [(r["id"], r["team"]) for r in frame["robots"]] == [(0, "ours"), (1, "opponent"), (2, "ours")]
    # robot_2 cannot catch any more: robot_0 receives; "never" shows no catch point
    robot(state, 2, 1.1, (2.0, 0.0, 0.0), c.CATCH_TIME_NEVER)
    frame = state.frame()
    assert frame["receiver"]["id"] == 0
    robot_2 = next(r for r in frame["robots"] if r["id"] == 2)
    assert robot_2["catch_time"] == c.CATCH_TIME_NEVER and robot_2["catch_point"] is None


def test_a_team_limits_who_receives():
    state = WorldState(FIELD, team_ids=frozenset({0}))
    robot(state, 0, 1.0, (0.0, 0.0, 0.0), 1.2, (0.5, 0.0))
    robot(state, 1, 1.0, (1.0, 0.0, 0.0), 0.3, (1.0, 0.1))  # the kicker: no catcher of the team
    assert state.frame()["receiver"]["id"] == 0


def test_robots_poses_headings_and_staleness():
    state = WorldState(FIELD)
    robot(state, 4, 1.0, (1.5, -0.5, math.pi / 2))
    assert state.apply(c.ODOM.for_robot(7), odometry_cdr(1.0, (0.2, 0.3, -1.0), (0.0, 0.0, 0.0)))  # tracked only
    frame = state.frame()
    assert [(r["id"], r["pose"], r["truth"]) for r in frame["robots"]] == [
        (4, [1.5, -0.5, round(math.pi / 2, 4)], True), (7, [0.2, 0.3, -1.0], False)]
    ball_state(state, 1.0 + 1.5, (0.0, 0.0), (0.0, 0.0))  # 1.5 s later nothing new of either robot
    assert state.frame()["robots"] == []


def test_live_stamps_follow_the_time_rule():
    """A lone backwards or far-future stamp is refused; a new time line (a restarted simulator, here a
    filter that takes any jump as one) forgets the old line's newer robots and ball."""
    # the default filter for every topic but robot 4's true pose, which keeps its old line however slow the test
    state = WorldState(FIELD, stamp_filters={
        c.GROUND_TRUTH_ODOM.for_robot(4): StampFilter(STAMP_MAX_JUMP_S, silence_s=60.0, dead_s=60.0)})
    robot(state, 4, 10.0, (1.5, -0.5, 0.0))
    robot(state, 5, 10.0, (0.5, 0.5, 0.0))
    ball_state(state, 10.0, (0.0, 0.0), (0.0, 0.0))
    for stray in (0.0, 10.0 + 10.5, 9.0):  # back, more than STAMP_MAX_JUMP_S (10 s) on, back
        assert not state.apply(c.GROUND_TRUTH_ODOM.for_robot(4), odometry_cdr(stray, (3.0, 3.0, 0.0), (0, 0, 0)))
    assert state.rejected == 3
    assert [(r["id"], r["pose"]) for r in state.frame()["robots"]] == [(4, [1.5, -0.5, 0.0]), (5, [0.5, 0.5, 0.0])]
    assert state.frame()["t"] == 10.0

    state.stamp_filters[c.GROUND_TRUTH_ODOM.for_robot(4)] = restarting = StampFilter(silence_s=0.0, dead_s=0.0)
    restarting.offer(10_000_000_000)
    robot(state, 4, 0.5, (2.0, 1.0, 0.0))  # the new line: robot 5 and the ball are of the old one
    frame = state.frame()
    assert frame["t"] == 0.5
    assert [(r["id"], r["pose"]) for r in frame["robots"]] == [(4, [2.0, 1.0, 0.0])]
    assert "state" not in frame["ball"]


def test_a_replay_takes_the_bags_stamps_as_they_are():
    state = WorldState(FIELD)  # no stamp_filters: a bag's gaps and seeks are not a broken time line
    robot(state, 4, 10.0, (1.5, -0.5, 0.0))
    robot(state, 4, 30.0, (1.0, 0.0, 0.0))
    assert state.frame()["robots"][0]["pose"] == [1.0, 0.0, 0.0]


def test_a_robots_tracked_pose_is_left_untaken_once_its_true_pose_arrives():
    state = WorldState(FIELD)
    assert state.takes(c.ODOM.for_robot(3)) and state.takes(c.GROUND_TRUTH_ODOM.for_robot(3))
    assert state.apply(c.ODOM.for_robot(3), odometry_cdr(1.0, (0.2, 0.3, 0.0), (0.0, 0.0, 0.0)))
    assert state.takes(c.ODOM.for_robot(3))  # tracked only, so far
    robot(state, 3, 1.0, (1.0, 1.0, 0.0))
    assert not state.takes(c.ODOM.for_robot(3))
    assert state.takes(c.ODOM.for_robot(4)) and state.takes(c.CATCH_TIME.for_robot(3))
    assert not state.takes("/robot_3/cmd_vel")


def test_motor_currents_and_the_limit_flags_per_wheel():
    state = WorldState(FIELD)
    robot(state, 0, 1.0, (0.0, 0.0, 0.0))
    status = [[1.0, 0.9, 0.0, 0.0], [1.4, 0.5, 1.0, 1.0], [0.2, 1.0, 0.0, 0.0], [0.3, 1.0, 0.0, 0.0]]
    assert state.apply(c.MOTOR_STATUS.for_robot(0), table_msg(status, c.MOTOR_STATUS_COLUMNS, "wheels"))
    truth = [[1.5, 40.0, 10.0], [-2.0, 45.0, -3.0], [0.1, 30.0, 1.0], [0.0, 30.0, 0.0]]
    assert state.apply(c.GROUND_TRUTH_MOTORS.for_robot(0), table_msg(truth, c.GROUND_TRUTH_MOTOR_COLUMNS, "wheels"))
    r = state.frame()["robots"][0]
    assert r["avg_current"] == [1.0, 1.4, 0.2, 0.3]
    assert r["limit_active"] == [False, True, False, False]
    assert r["current"] == [1.5, -2.0, 0.1, 0.0]
    assert state.frame()["current_limit"] == 1.3


def test_the_speed_plot_follows_the_model_from_the_kick():
    """Kicked at 3 m/s (v_shoot 3): 0.2 s later the model says 3 - 2.5 * 0.2 = 2.5 m/s (still sliding)."""
    state = WorldState(FIELD)
    ball_state(state, 1.0, (0.0, 0.0), (0.0, 0.0))
    assert "model" not in state.frame()["speed"]
    assert state.apply(c.BALL_V_SHOOT.name, float64_cdr(3.0))
    ball_state(state, 2.0, (0.0, 0.0), (3.0, 0.0))
    ball_state(state, 2.2, (0.55, 0.0), (2.45, 0.0))  # slower than the model: no new start
    speed = state.frame()["speed"]
    assert speed["model"] == pytest.approx(2.5, abs=1e-4)
    assert speed["filtered"] == pytest.approx(2.45)
    ball_state(state, 2.3, (0.8, 0.0), (4.0, 0.0))  # a second kick: the curve starts there
    assert state.frame()["speed"]["model"] == pytest.approx(4.0)


def test_the_speed_plot_goes_on_with_a_model_that_arrives_after_the_kick():
    """Kicked at 3 m/s at t 2.0; at 2.1 the predictor's model in use becomes a_slide -5 (SSL geometry, a fit):
    at 2.2 the curve says 3 - 5 * 0.2 = 2.0 m/s (still sliding: the switch is at 0.6 * 3 = 1.8 m/s), not the
    default's 2.5."""
    state = WorldState(FIELD)
    assert state.apply(c.BALL_V_SHOOT.name, float64_cdr(3.0))
    ball_state(state, 2.0, (0.0, 0.0), (3.0, 0.0))
    ball_state(state, 2.1, (0.29, 0.0), (2.5, 0.0))
    assert state.apply(c.BALL_MODEL_PARAMS.name, table_msg([[-5.0, -0.3, 0.6]], c.BALL_MODEL_PARAM_LABELS, "in_use"))
    ball_state(state, 2.2, (0.5, 0.0), (2.0, 0.0))
    assert state.frame()["speed"]["model"] == pytest.approx(2.0, abs=1e-4)


def test_bad_messages_are_refused_counted_and_never_reach_the_frame():
    state = WorldState(FIELD)
    ball_state(state, 1.0, (0.5, 0.5), (1.0, 0.0))
    nan_ball = odometry_msg(1.1, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    nan_ball.pose.pose.position.x = math.nan
    assert not state.apply(c.BALL_STATE.name, nan_ball)
    assert not state.apply(c.BALL_STATE.name, b"\x00\x01\x00\x00garbage")
    assert not state.apply(c.CATCH_TIME.for_robot(0), Float64(data=math.inf))
    assert not state.apply(c.BALL_MODEL_PARAMS.name, table_msg([[1.0, 2.0, 3.0]], ("a", "b", "c")))
    assert state.apply(c.BALL_PHASE.name, String(data="flying"))  # not a phase: shown as unknown
    frame = state.frame()
    assert frame["ball"]["state"] == [0.5, 0.5, 1.0, 0.0] and frame["ball"]["phase"] == "unknown"
    assert frame["rejected"] == 4
    json.dumps(frame, allow_nan=False)


def _write_bag(path, messages) -> None:
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        connections = {}
        for t_ns, topic, type_name, msg in messages:
            if topic not in connections:
                connections[topic] = writer.add_connection(topic, type_name, typestore=store)
            writer.write(connections[topic], t_ns, serialize_message(msg))


def test_a_bag_replays_as_frames_at_any_time(tmp_path):
    """A ball rolling along x at 1 m/s, its truth every 10 ms from 1 s to 3 s; robot_0 sees it from 2 s."""
    messages = []
    for k in range(201):
        t = 1.0 + 0.01 * k
        messages.append((round(t * 1e9), c.GROUND_TRUTH_BALL.name, "nav_msgs/msg/Odometry",
                         odometry_msg(t, (t, 0.0, 0.0), (1.0, 0.0, 0.0))))
        if t >= 2.0:
            messages.append((round(t * 1e9), c.BALL_DETECTED.for_robot(0), "std_msgs/msg/Bool", Bool(data=True)))
    messages.append((round(3.0e9), "/robot_0/cmd_vel", "geometry_msgs/msg/Twist", Twist()))  # not the view's
    _write_bag(tmp_path / "bag", messages)
    replay = BagReplay(tmp_path / "bag", decode, FIELD, checkpoint_period_s=0.5)
    assert len(replay) == 201 + 101
    assert (replay.start_s, replay.end_s) == (1.0, 3.0)
    for t in (2.5, 1.25, 2.97, 1.0, 2.0, 1.6):  # forward, back, jumps
        frame = replay.frame_at(t)
        assert frame["ball"]["truth"][0] == pytest.approx(t, abs=1e-9)
        assert frame["replay"] == {"start": 1.0, "end": 3.0, "t": t}
    assert replay.frame_at(99.0)["ball"]["truth"][0] == 3.0  # clamped to the bag
    assert replay.frame_at(1.5)["ball"]["truth"][0] == 1.5
    with pytest.raises(ValueError):
        replay.frame_at(math.nan)
    assert not replay.frame_at(1.9)["robots"]  # robot_0 has no pose: not drawn, its light barrier kept
    assert replay.frame_at(2.5)["t"] == 2.5


def test_a_damaged_record_is_skipped_and_counted(tmp_path):
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    with Writer(tmp_path / "bag", version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        phase = writer.add_connection(c.BALL_PHASE.name, "std_msgs/msg/String",
                                      typestore=get_typestore(Stores.ROS2_JAZZY))
        writer.write(phase, 1_000_000_000, serialize_message(String(data="rolling")))
        writer.write(phase, 1_500_000_000, b"\x00\x01\x00\x00\xff\xff\xff\x7f")  # a string 2^31 long
        writer.write(phase, 2_000_000_000, serialize_message(String(data="stopped")))
    replay = BagReplay(tmp_path / "bag", decode, FIELD)
    assert (len(replay), replay.skipped) == (2, 1)
    assert replay.frame_at(1.7)["ball"]["phase"] == "rolling"
    assert replay.frame_at(2.0)["ball"]["phase"] == "stopped"


def test_an_empty_bag_is_a_clear_error(tmp_path):
    _write_bag(tmp_path / "bag", [(1, "/other", "std_msgs/msg/String", String(data="x"))])
    with pytest.raises(ValueError, match="no message of the view's topics"):
        BagReplay(tmp_path / "bag", decode, FIELD)


def test_the_foxglove_scene_draws_what_the_page_draws():
    from erforce_sim.view.foxglove_bridge import plots_message, scene_shapes, scene_update

    state = WorldState(FIELD, opponent_ids=frozenset({1}))
    robot(state, 0, 1.0, (1.0, 0.5, 0.25), 0.8, (0.5, 0.0))
    robot(state, 1, 1.0, (-1.0, -0.5, 0.0))
    assert state.apply(c.GROUND_TRUTH_BALL.name, odometry_cdr(1.0, (-0.5, 0.0, 0.0), (2.0, 0.0, 0.0)))
    assert state.apply(c.BALL_V_SHOOT.name, float64_cdr(2.0))
    ball_state(state, 1.0, (-0.5, 0.0), (2.0, 0.0))
    frame = state.frame()
    shapes = scene_shapes(frame)
    assert set(shapes) == {"field", "robots", "ball"}
    outline = shapes["field"]["lines"][1]  # the field lines: 9 x 6 m
    assert outline["loop"] and outline["points"] == [(-4.5, -3.0), (4.5, -3.0), (4.5, 3.0), (-4.5, 3.0)]
    bodies = shapes["robots"]["cylinders"]
    assert [(b["x"], b["y"], b["color"]) for b in bodies] == [(1.0, 0.5, "#2f7de1"), (-1.0, -0.5, "#f2d22e")]
    assert shapes["robots"]["arrows"][0]["yaw"] == 0.25
    assert [t["text"] for t in shapes["robots"]["texts"]] == ["0", "0: 0.80 s", "1"]
    assert shapes["ball"]["spheres"] == [{"x": -0.5, "y": 0.0, "diameter": 0.043, "color": "#ff8a00"}]
    sliding, rolling, cross, _, target = shapes["ball"]["lines"]  # the stop point's cross; robot_0's target
    assert sliding["points"] == [(-0.5, 0.0), (pytest.approx(-0.5 + 0.512), 0.0)]
    assert rolling["points"][1] == (pytest.approx(-0.5 + 2.912), 0.0)
    assert cross["points"] == [(pytest.approx(-0.5 + 2.912 - 0.06), -0.06), (pytest.approx(-0.5 + 2.912 + 0.06), 0.06)]
    assert target["loop"] and math.dist(target["points"][0], (0.5, 0.0)) == pytest.approx(0.1)
    assert len(scene_update(frame, 1_000_000_000).encode()) > 500  # the foxglove message builds and encodes
    assert plots_message(frame) == {"t": 1.0, "current_limit_a": 1.3, "robot": 0, "ball_speed_true": 2.0,
                                    "ball_speed_filtered": 2.0, "ball_speed_model": 2.0, "avg_current_a": []}


def catch_table(rows) -> Float64MultiArray:
    return table_msg(rows, c.CATCH_TABLE_COLUMNS)


OURS, THEIRS = c.OURS.code, c.OPPONENTS.code


def test_the_predictors_team_table_places_every_robot_and_its_catch():
    state = WorldState(FIELD)
    ball_state(state, 2.0, (0.0, 0.0), (1.0, 0.0))
    # robot 0 at (1, 2) facing -y moving at 3-4-5 m/s, catch at 0.75 s at (1, 0); robot 4 never catches;
    # opponent 0 would catch first (0.5 s), but is not our receiver
    assert state.apply(c.BALL_CATCHES.name, catch_table([[OURS, 0, 1.0, 2.0, -math.pi / 2, 0.3, 0.4, 0.75, 1.0, 0.0],
                                                         [OURS, 4, -1.0, 0.5, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0],
                                                         [THEIRS, 0, 0.5, 0.0, 0.0, 0.0, 0.0, 0.5, 0.6, 0.0]]))
    frame = state.frame()
    r0, r4, o0 = frame["robots"]
    assert (r0["id"], r0["pose"], r0["speed"], r0["truth"]) == (0, [1.0, 2.0, round(-math.pi / 2, 4)], 0.5, False)
    assert (r0["catch_time"], r0["catch_point"]) == (0.75, [1.0, 0.0])
    assert (r4["id"], r4["catch_time"], r4["catch_point"]) == (4, c.CATCH_TIME_NEVER, None)
    assert (o0["id"], o0["team"], o0["pose"], o0["catch_time"]) == ("o0", "opponent", [0.5, 0.0, 0.0], 0.5)
    assert frame["receiver"] == {"id": 0, "target": [1.0, 0.0], "catch_time": 0.75}
    # a true pose wins over the table's tracked one; the catch still comes from the table
    robot(state, 0, 2.0, (3.0, -1.0, 0.0))
    assert state.apply(c.BALL_CATCHES.name, catch_table([[OURS, 0, 1.0, 2.0, 0.0, 0.0, 0.0, 0.5, 2.0, -1.0]]))
    r0 = state.frame()["robots"][0]
    assert (r0["pose"], r0["truth"], r0["catch_time"], r0["catch_point"]) == ([3.0, -1.0, 0.0], True, 0.5, [2.0, -1.0])
    # robots the table no longer lists go stale like robots whose topics went quiet
    ball_state(state, 3.5, (0.0, 0.0), (1.0, 0.0))
    assert [r["id"] for r in state.frame()["robots"]] == []
    for bad in ([[OURS, -1, 0, 0, 0, 0, 0, 0.5, 0, 0]], [[OURS, 1.5, 0, 0, 0, 0, 0, 0.5, 0, 0]],
                [[3.0, 1, 0, 0, 0, 0, 0, 0.5, 0, 0]]):  # no such team
        assert not state.apply(c.BALL_CATCHES.name, catch_table(bad))
    assert not state.apply(c.BALL_CATCHES.name, table_msg([[0.0, 1.0]], ("robot_id", "x_m")))  # other columns
    assert state.rejected == 4


def test_opponents_in_their_own_namespace_are_drawn_as_opponents():
    assert view_topic("/opponent_2/ground_truth/odom") == (c.GROUND_TRUTH_ODOM, "o2")
    assert view_topic("/opponent_x/ground_truth/odom") is None
    state = WorldState(FIELD)
    assert state.apply("/opponent_2/ground_truth/odom", odometry_cdr(1.0, (0.5, 0.5, 0.0), (0.0, 0.0, 0.0)))
    assert state.apply("/opponent_2/catch_time", float64_cdr(0.2))  # an opponent is never our receiver
    robot(state, 10, 1.0, (1.0, 1.0, 0.0), 0.9, (1.0, 0.5))
    robot(state, 2, 1.0, (-1.0, 1.0, 0.0))
    frame = state.frame()
    assert [(r["id"], r["team"]) for r in frame["robots"]] == [(2, "ours"), (10, "ours"), ("o2", "opponent")]
    assert frame["receiver"]["id"] == 10


class _Game:
    """What GameBag reads of a PassingGame: two of ours at rest, one opponent, the ball, the choice."""

    n_team, n_opp = 2, 1
    cfg = GameConfig(team_size=2, opponents=1)
    poses = ((0.0, 1.0, 0.0), (2.0, -1.0, math.pi), (1.0, 0.5, 0.0))

    def __init__(self) -> None:
        self.runner = SimpleNamespace(t_ns=0)
        self.world = SimpleNamespace(
            ball_state=lambda: SimpleNamespace(x=0.09, y=1.0, vx=0.0, vy=0.0, wx=0.0, wy=0.0, wz=0.0),
            robot_state=lambda i: SimpleNamespace(x=self.poses[i][0], y=self.poses[i][1], theta=self.poses[i][2],
                                                  vx=0.0, vy=0.0, w=0.0))
        self.choice = None


def test_the_passing_games_choice_goes_into_its_bag_and_onto_the_page(tmp_path):
    """0 to 1 s in 10 ms steps: no choice until 0.3 s, then robot 0 to robot 1 with the opponent there
    1.4 s after the kick and our catch at 0.9 s (margin 0.5 s, safe at 0.3 s), from 0.6 s a pass no
    opponent reaches; the bag replays it as the page gets it."""
    game = _Game()
    bag = GameBag(tmp_path / "bag", game)
    contested = PassOption(receiver=1, kick_speed_mps=3.0, direction_rad=-0.7854, receiver_catch_s=0.9,
                           opponent_catch_s=1.4, first_opponent=0)
    free = PassOption(receiver=1, kick_speed_mps=2.5, direction_rad=-0.7854, receiver_catch_s=1.1,
                      opponent_catch_s=math.inf, first_opponent=None)
    for k in range(101):
        game.runner.t_ns = k * 10_000_000
        game.choice = None if k < 30 else (0, contested) if k < 60 else (0, free)
        bag.tick(game)
    bag.close()
    replay = BagReplay(tmp_path / "bag", decode, FIELD)
    assert replay.frame_at(0.2)["pass"] is None
    frame = replay.frame_at(0.45)
    assert frame["pass"] == {"passer": 0, "receiver": 1, "kick_speed": 3.0, "direction": -0.7854,
                             "receiver_catch": 0.9, "first_opponent": "o0", "opponent_catch": 1.4,
                             "margin": 0.5, "safe_margin": 0.3, "safe": True}
    assert [(r["id"], r["team"], r["pose"][:2]) for r in frame["robots"]] == [
        (0, "ours", [0.0, 1.0]), (1, "ours", [2.0, -1.0]), ("o0", "opponent", [1.0, 0.5])]
    late = replay.frame_at(0.8)["pass"]
    assert (late["first_opponent"], late["opponent_catch"], late["margin"], late["safe"]) == (None, None, None, True)
    # the bag holds a choice only when it changed: none, the contested pass, the free one
    assert sum(1 for topic, _ in replay._messages if topic == c.PASS_CHOICE.name) == 3


def test_an_unsafe_or_malformed_choice():
    state = WorldState(FIELD)
    cfg = PassConfig()
    risky = PassOption(receiver=3, kick_speed_mps=4.0, direction_rad=0.0, receiver_catch_s=1.0,
                       opponent_catch_s=1.1, first_opponent=2)
    assert state.apply(c.PASS_CHOICE.name, decode(c.PASS_CHOICE.type_name, pass_choice_cdr((5, risky), cfg)))
    choice = state.frame()["pass"]
    assert (choice["passer"], choice["receiver"], choice["margin"], choice["safe"]) == (5, 3, 0.1, False)
    assert state.apply(c.PASS_CHOICE.name, decode(c.PASS_CHOICE.type_name, pass_choice_cdr(None, cfg)))
    assert state.frame()["pass"] is None
    two_rows = table_msg([[0, 1, 2, 0, 1, 2, 0, 1, 0.3, 1]] * 2, c.PASS_CHOICE_COLUMNS)
    negative = table_msg([[-1, 1, 2, 0, 1, 2, 0, 1, 0.3, 1]], c.PASS_CHOICE_COLUMNS)
    assert not state.apply(c.PASS_CHOICE.name, two_rows) and not state.apply(c.PASS_CHOICE.name, negative)


def _approx_tree(value):
    """``value`` with every float compared at float32's precision for numbers of the field's size."""
    if isinstance(value, dict):
        return {k: _approx_tree(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_approx_tree(v) for v in value]
    if isinstance(value, float):
        return pytest.approx(value, abs=2e-6)
    return value


def test_the_binary_frame_says_what_the_frame_says():
    """Both teams, an opponent of its own namespace, motor currents, the team table, a rolling ball, a
    pass: decoded, the binary frame is frame() but for the path's marks (the page puts them on)."""
    state = WorldState(FIELD, opponent_ids=frozenset({7}))
    assert state.apply(c.BALL_V_SHOOT.name, float64_cdr(2.0))
    ball_state(state, 1.0, (1.0, -1.0), (0.0, 2.0))
    assert state.apply(c.GROUND_TRUTH_BALL.name, odometry_cdr(1.0, (1.01, -1.0, 0.0), (0.0, 2.1, 0.0)))
    assert state.apply(c.VISION_BALL.name, point_cdr(1.0, (1.02, -0.99)))
    assert state.apply(c.BALL_PHASE.name, String(data="sliding"))
    assert state.apply(c.BALL_CATCHES.name, catch_table([[OURS, 0, 1.0, 2.0, -math.pi / 2, 0.3, 0.4, 0.75, 1.0, 0.0],
                                                         [OURS, 4, -1.0, 0.5, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0],
                                                         [OURS, 7, 2.5, -2.0, 3.0, 0.0, 0.0, 0.4, 1.0, -0.5]]))
    robot(state, 2, 1.0, (-2.0, 1.5, 1.0))
    status = [[1.0, 0.9, 0.0, 0.0], [1.4, 0.5, 1.0, 1.0], [0.2, 1.0, 0.0, 0.0]]
    assert state.apply(c.MOTOR_STATUS.for_robot(2), table_msg(status, c.MOTOR_STATUS_COLUMNS, "wheels"))
    assert state.apply(c.BALL_DETECTED.for_robot(2), Bool(data=True))
    assert state.apply("/opponent_3/ground_truth/odom", odometry_cdr(1.0, (0.5, 0.5, 0.0), (0.0, 0.0, 0.0)))
    assert state.apply(c.SIM_EVENTS.name, String(data="kick fired"))
    choice = PassOption(receiver=2, kick_speed_mps=3.0, direction_rad=0.5, receiver_catch_s=0.9,
                        opponent_catch_s=1.4, first_opponent=3)
    assert state.apply(c.PASS_CHOICE.name, pass_choice_cdr((0, choice), PassConfig(safe_margin_s=0.3)))
    frame = state.frame()
    decoded = decode_frame_bytes(state.frame_bytes())
    assert frame["stop_point"] == frame["path"]["stop"]  # the view's own prediction, as the predictor's
    marks = frame["path"].pop("marks")
    assert decoded == _approx_tree(frame)
    assert [(r["id"], r["team"]) for r in decoded["robots"]] == [(0, "ours"), (2, "ours"), (4, "ours"),
                                                                  (7, "opponent"), ("o3", "opponent")]
    assert decoded["robots"][1]["avg_current"] == pytest.approx([1.0, 1.4, 0.2], abs=1e-6)
    assert decoded["robots"][1]["limit_active"] == [False, True, False] and decoded["robots"][1]["ball_detected"]
    # The page's marks: on each stretch the ball slows evenly from the speed at its start to the one at its
    # end. From 2 m/s to 1.2 m/s in 0.32 s, then to rest in 4 s (the module docstring's ball).
    path = decoded["path"]
    assert (path["speed"], path["switch_speed"]) == (2.0, pytest.approx(1.2))
    slide = math.dist(path["start"], path["switch"])
    for k, mark in enumerate(marks, start=1):
        t = k * PATH_MARK_PERIOD_S
        if t <= path["switch_time"]:
            d = path["speed"] * t - 0.5 * (path["speed"] - path["switch_speed"]) / path["switch_time"] * t**2
        else:
            roll = path["wall_time"] - path["switch_time"]  # the stop here: the ball meets no wall
            tr = t - path["switch_time"]
            d = slide + path["switch_speed"] * tr - 0.5 * (path["switch_speed"] - path["wall_speed"]) / roll * tr**2
        assert mark == pytest.approx([1.0, -1.0 + d], abs=1e-4)


def test_the_binary_frame_of_an_empty_world_and_a_damaged_one():
    state = WorldState(FIELD)
    frame = decode_frame_bytes(state.frame_bytes())
    assert frame == state.frame() and frame["robots"] == [] and frame["path"] is None
    data = state.frame_bytes()
    for bad in (b"", b"EFV2" + data[4:], data[:-8], data + bytes(4)):
        with pytest.raises(ValueError):
            decode_frame_bytes(bad)


def test_a_frame_of_robots_known_only_from_team_tables_is_the_same_built_from_the_table():
    """Robots known only from /ball/catches (robot 7 marked an opponent, and opponent 1 of the other team):
    the binary frame, built straight from the table, says what frame() says once the table is in every
    robot's view; a table that leaves a robot out, and a message about one robot, take the general way,
    with the same result."""
    state = WorldState(FIELD, opponent_ids=frozenset({7}))
    ball_state(state, 2.0, (0.0, 0.0), (1.0, 0.0))
    table = [[OURS, 4, -1.0, 0.5, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0],
             [THEIRS, 1, 3.0, 1.0, 0.0, 0.0, 0.0, 0.1, 2.0, 1.0],  # the earliest, but not ours
             [OURS, 0, 1.0, 2.0, -math.pi / 2, 0.3, 0.4, 0.75, 1.0, 0.0],
             [OURS, 7, 2.5, -2.0, 3.0, 0.0, 0.0, 0.2, 1.0, -0.5], [OURS, 2, 0.5, 0.5, 1.0, 0.0, 0.0, 0.6, 0.5, 0.1]]
    assert state.apply(c.BALL_CATCHES.name, catch_table(table))
    twin = WorldState(FIELD, opponent_ids=frozenset({7}))
    ball_state(twin, 2.0, (0.0, 0.0), (1.0, 0.0))
    assert twin.apply(c.BALL_CATCHES.name, catch_table(table))
    decoded = decode_frame_bytes(state.frame_bytes())
    frame = twin.frame()
    frame["path"].pop("marks")
    assert decoded == _approx_tree(frame)
    # robot 2 is the earliest of ours (7 is an opponent); robot 0 has the speed 0.5 of (0.3, 0.4)
    assert decoded["receiver"] == {"id": 2, "target": [0.5, pytest.approx(0.1)], "catch_time": pytest.approx(0.6)}
    assert [(r["id"], r["team"], r["catch_time"]) for r in decoded["robots"]] == [
        (0, "ours", 0.75), (2, "ours", pytest.approx(0.6)), (4, "ours", -1.0), (7, "opponent", pytest.approx(0.2)),
        ("o1", "opponent", pytest.approx(0.1))]
    assert decoded["robots"][0]["speed"] == pytest.approx(0.5)
    # a table without robot 4: robot 4 is still fresh and drawn from the table before
    for s in (state, twin):
        assert s.apply(c.BALL_CATCHES.name, catch_table(table[1:]))
    frame = twin.frame()
    frame["path"].pop("marks")
    assert decode_frame_bytes(state.frame_bytes()) == _approx_tree(frame)
    assert [r["id"] for r in frame["robots"]] == [0, 2, 4, 7, "o1"]
    for s in (state, twin):
        robot(s, 2, 2.0, (-2.0, 1.5, 1.0))
        assert s.apply(c.BALL_CATCHES.name, catch_table(table))
    frame = twin.frame()
    frame["path"].pop("marks")
    assert decode_frame_bytes(state.frame_bytes()) == _approx_tree(frame)
    assert frame["robots"][1]["pose"] == [-2.0, 1.5, 1.0] and frame["robots"][1]["truth"]


def test_team_tables_read_from_their_bytes_say_what_the_messages_say():
    """/ball/catches as the node takes it (CDR bytes): the tables after the first, of the same robots, are
    read in place; their values, a new robot, a value that is not finite or too large count as in the
    message."""
    rows = [[OURS, 0, 1.0, 2.0, -math.pi / 2, 0.3, 0.4, 0.75, 1.0, 0.0],
            [THEIRS, 0, 0.5, 0.0, 0.0, 0.0, 0.0, 0.5, 0.6, 0.0]]
    from_bytes, from_msg = WorldState(FIELD), WorldState(FIELD)
    for state in (from_bytes, from_msg):
        ball_state(state, 2.0, (0.0, 0.0), (1.0, 0.0))
    moved = [[OURS, 0, 1.5, 2.0, 0.0, 0.0, 0.0, 0.25, 1.5, 0.0], rows[1]]
    added = [*moved, [OURS, 3, -1.0, 0.5, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0]]
    for table in (rows, moved, added):
        assert from_bytes.apply(c.BALL_CATCHES.name, serialize_message(catch_table(table)))
        assert from_msg.apply(c.BALL_CATCHES.name, catch_table(table))
        assert from_bytes.frame() == from_msg.frame()
        assert from_bytes.frame_bytes() == from_msg.frame_bytes()
    r0 = from_bytes.frame()["robots"][0]
    assert (r0["pose"], r0["catch_time"], r0["catch_point"]) == ([1.5, 2.0, 0.0], 0.25, [1.5, 0.0])
    good = serialize_message(catch_table(added))
    nan, huge = bytearray(good), bytearray(good)
    nan[-8:] = struct.pack("<d", math.nan)  # the last row's catch_y
    huge[-8:] = struct.pack("<d", 2.0e9)
    assert not from_bytes.apply(c.BALL_CATCHES.name, bytes(nan))
    assert not from_bytes.apply(c.BALL_CATCHES.name, bytes(huge))
    assert from_bytes.rejected == 2
    assert from_bytes.apply(c.BALL_CATCHES.name, good)
