"""ball_predictor over DDS: ball state and stop point, catch times, online identification, bad input.

Observations are generated here from an independent closed form of the two-phase model (a kick
from rest) and fed frame by frame, each answered before the next is sent. Expected catch times
come from a brute-force search with the 1D bang-bang robot time (the robot is at rest on the
ball's line, so the 2D problem is 1D).
"""

import gc
import math
import re
import struct

import numpy as np
import pytest
import rclpy
from geometry_msgs.msg import PointStamped
from nav_msgs.msg import Odometry
from rclpy.serialization import serialize_message
from sensor_msgs.msg import PointCloud2, PointField
from std_msgs.msg import Bool, Float64, Float64MultiArray, String

from erforce_ball_model import ball_predictor_node
from erforce_ball_model.ball_predictor_node import BallPredictorNode
from erforce_ball_model.receiver import CatcherConfig
from erforce_interfaces.wire import contract
from erforce_interfaces.wire.clouds import ball_track_from_msg, vision_robots_cdr
from erforce_interfaces.wire.conversions import odometry_from_msg, point_from_msg, stamp_to_seconds
from erforce_interfaces.wire.robot_config import RobotConfig
from erforce_interfaces.wire.tables import table_from_msg, table_msg, tracked_robots_from_msg

pytestmark = pytest.mark.integration

NODE = "/ball_predictor"
FPS = 70.0
OFFSET_M = RobotConfig().dribbler_offset_m
A_SLIDE, A_ROLL, C_SWITCH = 2.5, 0.3, 0.6  # the node's defaults (magnitudes), paper Sec. 5.2


def kicked(tau, v0, a_slide=A_SLIDE, a_roll=A_ROLL, c_switch=C_SWITCH):
    """(distance [m], speed [m/s]) ``tau`` seconds after a kick from rest at ``v0``."""
    tau = np.maximum(np.asarray(tau, dtype=float), 0.0)
    v_sw = c_switch * v0
    t_sw = (v0 - v_sw) / a_slide
    ts = np.minimum(tau, t_sw)
    tr = np.clip(tau - t_sw, 0.0, v_sw / a_roll)
    dist = v0 * ts - 0.5 * a_slide * ts**2 + v_sw * tr - 0.5 * a_roll * tr**2
    speed = np.where(tau <= t_sw, v0 - a_slide * ts, v_sw - a_roll * tr)
    return dist, np.maximum(speed, 0.0)


def stop_distance(v0, a_slide=A_SLIDE, a_roll=A_ROLL, c_switch=C_SWITCH):
    v_sw = c_switch * v0
    return (v0**2 - v_sw**2) / (2.0 * a_slide) + v_sw**2 / (2.0 * a_roll)


def shot_frames(t_start, p0, direction, v0, rest_frames=10, tail_s=0.3, **model):
    """Frame stamps and positions: ``rest_frames`` at rest, then a kick between two frames."""
    u = np.asarray(direction, dtype=float) / np.hypot(*direction)
    t_kick = t_start + (rest_frames - 0.5) / FPS
    v_sw = model.get("c_switch", C_SWITCH) * v0
    t_stop = (v0 - v_sw) / model.get("a_slide", A_SLIDE) + v_sw / model.get("a_roll", A_ROLL)
    t = t_start + np.arange(round((t_kick - t_start + t_stop + tail_s) * FPS)) / FPS
    dist, speed = kicked(t - t_kick, v0, **model)
    return t, np.asarray(p0) + dist[:, None] * u, speed[:, None] * u, t_kick


def robot_time_1d(d_m, a_max, v_max):
    """Bang-bang time from rest to rest over ``d_m`` (triangle or trapezoid profile)."""
    d = np.abs(d_m)
    return np.where(d <= v_max**2 / a_max, 2.0 * np.sqrt(d / a_max), d / v_max + v_max / a_max)


# Test times are relative and start at 1.0 s; the node sees them shifted, so the handshake frame (below)
# comes first and 1.5 s earlier: more than max_gap_s (every test starts with a freshly initialized ball
# filter) and less than the time rule's largest step (erforce_interfaces.wire.stamps: the first frame counts).
T_SHIFT_S = 5.0


def stamp_s(msg):
    return round(stamp_to_seconds(msg.header.stamp) - T_SHIFT_S, 6)


def ball_msg(t_s, x, y):
    return robots_msg(t_s, [(contract.VISION_BALL_CODE, 0.0, float(x), float(y), 0.0)])


def robots_msg(t_s, rows):
    """/vision/robots built by hand from the contract's description (the conversions would refuse NaN):
    rows of (team code, robot id, x, y, yaw) become points of float64 x, y, z, yaw, team, robot_id (the ball:
    team code 0, id and yaw 0)."""
    msg = PointCloud2()
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(round(t_s * 1e9), 10**9)
    msg.header.frame_id = contract.FIELD_FRAME
    msg.height, msg.width = 1, len(rows)
    msg.fields = [PointField(name=name, offset=8 * k, datatype=PointField.FLOAT64, count=1)
                  for k, name in enumerate(("x", "y", "z", "yaw", "team", "robot_id"))]
    msg.point_step, msg.row_step = 48, 48 * len(rows)
    msg.data = b"".join(struct.pack("<6d", x, y, 0.0, yaw, team, robot_id) for team, robot_id, x, y, yaw in rows)
    msg.is_dense = True
    return msg


class Rig:
    def __init__(self, graph, **params):
        params.setdefault("num_robots", 2)
        self.graph = graph
        # robot i: ours, then the opponents (as the node's core has them)
        robots = [(contract.OURS, i) for i in range(params["num_robots"])]
        robots += [(contract.OPPONENTS, j) for j in range(params.get("num_opponents", 0))]
        self.n, self.robots = len(robots), robots
        self.node = graph.start_node("erforce_ball_model", "ball_predictor", params=params)
        probe = graph.probe
        q = contract
        self.state = probe.subscribe(q.BALL_STATE.name, Odometry, q.BALL_STATE.qos)
        self.phase = probe.subscribe(q.BALL_PHASE.name, String, q.BALL_PHASE.qos)
        self.stop = probe.subscribe(q.BALL_STOP_POINT.name, PointStamped, q.BALL_STOP_POINT.qos)
        self.v_shoot = probe.subscribe(q.BALL_V_SHOOT.name, Float64, q.BALL_V_SHOOT.qos)
        self.uncertain = probe.subscribe(q.BALL_UNCERTAIN.name, Bool, q.BALL_UNCERTAIN.qos)
        self.model_params = probe.subscribe(q.BALL_MODEL_PARAMS.name, Float64MultiArray, q.BALL_MODEL_PARAMS.qos)
        self.catch_time = [probe.subscribe(team.topic(q.CATCH_TIME, i), Float64, q.CATCH_TIME.qos)
                           for team, i in robots]
        self.catch_point = [probe.subscribe(team.topic(q.CATCH_POINT, i), PointStamped, q.CATCH_POINT.qos)
                            for team, i in robots]
        self.odom = [probe.subscribe(team.topic(q.ODOM, i), Odometry, q.ODOM.qos) for team, i in robots]
        self.catches = probe.subscribe(q.BALL_CATCHES.name, Float64MultiArray, q.BALL_CATCHES.qos)
        self.track = probe.subscribe(q.BALL_TRACK.name, PointCloud2, q.BALL_TRACK.qos)
        self.tracked = probe.subscribe(q.ROBOTS_TRACKED.name, Float64MultiArray, q.ROBOTS_TRACKED.qos)
        self.robots_pub = probe.wait_for_subscribers(q.VISION_ROBOTS.name, PointCloud2, timeout_s=20.0,
                                                     qos=q.VISION_ROBOTS.qos)
        self.ball_pub = self.robots_pub  # a frame of the ball alone
        # Our readers must have matched the node's writers, or the first answers are lost.
        readers = [s for s in probe.node.subscriptions
                   if s.topic_name.startswith(("/ball/", "/robot_", "/opponent_", "/robots/"))]
        probe.spin_until(lambda: all(s.get_publisher_count() > 0 for s in readers), 20.0, "node publishers")
        # ... and the node's writers ours (not observable from here): a handshake frame, resent until answered.
        for attempt in range(20):
            self.ball_pub.publish(ball_msg(T_SHIFT_S - 0.5 + 0.001 * attempt, 0.0, 0.0))
            try:
                probe.spin_until(lambda: self.state and self.uncertain, 1.0, "handshake")
                break
            except TimeoutError:
                continue
        probe.spin_for(0.2)
        assert self.state, "ball_predictor never answered"
        for received in (self.state, self.phase, self.stop, self.v_shoot, self.uncertain, self.track):
            received.clear()

    def ball(self, t_s, x, y, answered=True):
        """Send one frame; wait for its last message (uncertain) or make sure nothing comes."""
        before = len(self.uncertain), len(self.state)
        self.ball_pub.publish(ball_msg(t_s + T_SHIFT_S, x, y))
        probe = self.graph.probe
        if answered:
            probe.spin_until(lambda: len(self.uncertain) > before[0] and len(self.state) > before[1], 10.0,
                             f"answer to the frame at {t_s}")
            assert stamp_s(self.state[-1]) == round(t_s, 6)
        else:
            probe.spin_for(0.3)
            assert (len(self.uncertain), len(self.state)) == before, f"frame at {t_s} must not be answered"

    def robot(self, i, t_s, x, y, yaw, answered=True):
        """Rig robot ``i`` alone in a /vision/robots message."""
        self.robots_frame(t_s, [(i, x, y, yaw)], answered={i} if answered else set())

    def robots_frame(self, t_s, poses, answered, others=()):
        """One /vision/robots message: rig robots (index, x, y, yaw) and ``others`` given as rows (team code,
        id, x, y, yaw); wait for the odom of each rig robot in ``answered``, make sure the rest get none."""
        before = [len(odom) for odom in self.odom]
        rows = [(self.robots[i][0].code, self.robots[i][1], x, y, yaw) for i, x, y, yaw in poses]
        self.robots_pub.publish(robots_msg(t_s + T_SHIFT_S, rows + list(others)))
        probe = self.graph.probe
        if answered:
            probe.spin_until(lambda: all(len(self.odom[i]) > before[i] for i in answered), 10.0,
                             f"odom of rig robots {sorted(answered)}")
        probe.spin_for(0.3 if len(answered) < max(len(poses), 1) else 0.0)
        assert [len(odom) - b for odom, b in zip(self.odom, before, strict=True)] == [
            int(i in answered) for i in range(self.n)]

    def settle(self):
        self.graph.probe.spin_for(0.2)  # the catch messages of the last frame

    def all_finite(self):
        odoms = self.state + [m for msgs in self.odom for m in msgs]
        points = self.stop + [m for msgs in self.catch_point for m in msgs]
        floats = self.v_shoot + [m for msgs in self.catch_time for m in msgs]
        ok = all(np.isfinite(odometry_from_msg(m)[1]).all() and np.isfinite(odometry_from_msg(m)[2]).all()
                 for m in odoms)
        ok &= all(np.isfinite(point_from_msg(m)[1]).all() for m in points)
        return ok and all(math.isfinite(m.data) for m in floats)


def test_rolling_ball_state_stop_point_and_phases_match_the_closed_form(ros_graph):
    rig = Rig(ros_graph)
    v0, p0, u = 2.0, np.array([-2.0, 0.5]), np.array([0.8, -0.6])
    t, xy, vel, t_kick = shot_frames(1.0, p0, u, v0)
    for ti, (x, y) in zip(t, xy, strict=True):
        rig.ball(ti, x, y)
    rig.settle()
    assert len(rig.state) == len(t)
    phases = [m.data for m in rig.phase]
    assert phases[0] == "unknown" and set(phases) <= set(contract.BALL_PHASES)
    assert phases[5] == "stopped" and phases[-1] == "stopped"  # before the kick and after the stop

    stop_true = p0 + stop_distance(v0) * u  # 2.912 m along u
    t_switch = t_kick + (1.0 - C_SWITCH) * v0 / A_SLIDE  # 0.32 s after the kick
    t_stop = t_switch + C_SWITCH * v0 / A_ROLL
    checked = 0
    for k, ti in enumerate(t):
        _, pose, velocity, _ = odometry_from_msg(rig.state[k])
        if t_kick + 0.1 < ti < t_switch - 0.05:
            assert phases[k] == "sliding"
        if t_switch + 0.3 < ti < t_stop - 0.5:  # rolling, settled after the switch
            assert phases[k] == "rolling"
            assert np.hypot(*(velocity[:2] - vel[k])) < 0.02
            assert np.hypot(*(pose[:2] - xy[k])) < 0.005
            assert np.hypot(*(point_from_msg(rig.stop[k])[1] - stop_true)) < 0.02
            assert rig.v_shoot[k].data == pytest.approx(v0, rel=0.03)
            checked += 1
    assert checked > 150
    assert not rig.uncertain[-1].data
    assert all(len(c) == 0 for c in rig.catch_time)  # no robot seen: no catch outputs
    # /ball/track (best effort) says what the five topics say, and the observation answered
    by_stamp = {odometry_from_msg(m)[0]: k for k, m in enumerate(rig.state)}
    assert len(rig.track) >= 0.9 * len(t)
    for track in map(ball_track_from_msg, rig.track):
        k = by_stamp[track.t_s]
        _, pose, velocity, _ = odometry_from_msg(rig.state[k])
        assert (track.x_m, track.y_m, track.vx_mps, track.vy_mps) == (*pose[:2], *velocity[:2])
        assert (track.v_shoot_mps, track.phase, track.uncertain) == (
            rig.v_shoot[k].data, phases[k], rig.uncertain[k].data)
        assert (track.seen_x_m, track.seen_y_m) == tuple(xy[k])
    assert rig.all_finite()


def test_a_flat_balls_state_carries_the_filters_variances_on_both_covariance_diagonals(ros_graph):
    """A ball at rest, 12 frames at 60 Hz, the first more than max_gap_s (1 s) after the handshake: the filter
    starts over there, x with variance r = position_noise_m^2 (4e-6 m^2), v with 1 (m/s)^2. The second frame is one
    constant-velocity Kalman step of dt = 1/60 s (q = accel_noise_psd 0.05): predicted a = r + dt^2 + q dt^3 / 3,
    b = dt + q dt^2 / 2, c = 1 + q dt, then var_x = a r / (a + r), var_v = c - b^2 / (a + r); each frame after it
    knows the velocity better. Only x, y (pose) and vx, vy (twist) have variances; the rest is 0."""
    rig = Rig(ros_graph, num_robots=1, position_noise_m=0.002, accel_noise_psd=0.05)
    dt, r, q = 1.0 / 60.0, 0.002**2, 0.05
    for k in range(12):
        rig.ball(0.6 + k * dt, 0.5, -0.2)
    pose_var, twist_var = [], []
    for msg in rig.state:
        pose, twist = np.reshape(msg.pose.covariance, (6, 6)), np.reshape(msg.twist.covariance, (6, 6))
        assert np.count_nonzero(pose - np.diag(np.diag(pose))) == np.count_nonzero(twist - np.diag(np.diag(twist))) == 0
        assert pose[0, 0] == pose[1, 1] and twist[0, 0] == twist[1, 1] and not pose[2:].any() and not twist[2:].any()
        pose_var.append(pose[0, 0])
        twist_var.append(twist[0, 0])
    dt = stamp_to_seconds(rig.state[1].header.stamp) - stamp_to_seconds(rig.state[0].header.stamp)  # in whole ns
    a, b, c = r + dt**2 + q * dt**3 / 3.0, dt + q * dt**2 / 2.0, 1.0 + q * dt
    assert (pose_var[0], twist_var[0]) == pytest.approx((r, 1.0), rel=1e-12)
    assert (pose_var[1], twist_var[1]) == pytest.approx((a * r / (a + r), c - b * b / (a + r)), rel=1e-9)
    assert (np.diff(twist_var[1:]) < 0.0).all()


def test_the_published_stop_point_lies_inside_the_field_wall(ros_graph):
    """Kicked at 3 m/s straight at the +x wall of Division B (4.5 + 0.3 m less the ball's radius 21.35 mm), which
    the straight model passes by 2.8 m: with wall_restitution 0 the ball stays where it meets the wall."""
    rig = Rig(ros_graph, wall_restitution=0.0)
    v0, p0 = 3.0, np.array([1.0, 0.5])
    wall_x = 4.5 + 0.3 - 0.02135
    assert p0[0] + stop_distance(v0) > wall_x + 2.7
    t, xy, _, t_kick = shot_frames(1.0, p0, (1.0, 0.0), v0)
    sent = [ti for ti, (x, _) in zip(t, xy, strict=True) if x < wall_x - 0.5]  # frames before the wall
    for ti in sent:
        rig.ball(ti, *xy[list(t).index(ti)])
    rig.settle()
    stops = [point_from_msg(m)[1] for m in rig.stop]
    assert len(stops) == len(sent) and all(s[0] <= wall_x + 1e-9 for s in stops)
    moving = [s for ti, s in zip(sent, stops, strict=True) if ti > t_kick + 0.2]
    assert len(moving) > 20
    assert all(s[0] == pytest.approx(wall_x, abs=1e-6) and s[1] == pytest.approx(0.5, abs=0.01) for s in moving)

@pytest.mark.parametrize("a_max", [3.0, 0.005])
def test_robot_on_the_path_facing_the_ball_catches_it_when_brute_force_says(ros_graph, a_max):
    """Ball kicked along +x at 2 m/s from x = -2; robot at rest at x = 0.5 on its line (default facing:
    against the ball's motion, so the dribbler points to -x and touches the ball at x = 0.5 - offset)."""
    v_max, x_robot = 2.0, 0.5
    # With a_max = 5 mm/s^2 the catch window is only a T^2 / (2 v_ball) >= 11 ms wide: use a 2 ms grid.
    rig = Rig(ros_graph, num_robots=1, robot_a_max_mps2=a_max, robot_v_max_mps=v_max, robot_timeout_s=100.0,
              grid_step_s=0.01 if a_max > 1.0 else 0.002, reaction_s=0.0)  # the brute force has no reaction time
    v0, p0 = 2.0, np.array([-2.0, 0.0])
    t, xy, _, t_kick = shot_frames(1.0, p0, (1.0, 0.0), v0)
    for ts in (0.90, 0.95):
        rig.robot(0, ts, x_robot, 0.0, math.pi)
    _, pose, velocity, _ = odometry_from_msg(rig.odom[0][-1])
    assert np.allclose(pose[:2], [x_robot, 0.0]) and math.cos(pose[2]) == pytest.approx(-1.0)
    assert np.allclose(velocity, 0.0)
    x_dribbler = x_robot - OFFSET_M
    for ti, (x, y) in zip(t, xy, strict=True):
        rig.ball(ti, x, y)
        if x > x_dribbler + 0.2:
            break
    rig.settle()
    times = [m.data for m in rig.catch_time[0]]
    assert len(times) == len(rig.state)

    # Brute force: first s with robot_time(distance from robot to the catch position at s) <= s.
    s = np.arange(0.0, 3.0, 1e-4)  # 0.1 ms resolution
    t_switch = t_kick + (1.0 - C_SWITCH) * v0 / A_SLIDE
    checked = 0
    for k, ti in enumerate(t[: len(times)]):
        if not t_kick + 0.15 < ti < t_kick + 0.9:  # the kick is detected and the ball still far away
            continue
        if t_switch - 0.03 < ti < t_switch + 0.12:
            continue  # the filter lags the switch to rolling by a few mm/s for ~0.1 s (up to 13 ms in T)
        ball_x = p0[0] + kicked(ti + s - t_kick, v0)[0]
        robot_x_needed = ball_x + OFFSET_M  # robot centre behind the dribbler
        feasible = robot_time_1d(robot_x_needed - x_robot, a_max, v_max) <= s
        assert feasible.any()
        expected = s[np.argmax(feasible)]
        t_drib = s[np.argmax(ball_x >= x_dribbler)]  # ball reaches the resting robot's dribbler
        assert expected <= t_drib
        assert times[k] == pytest.approx(expected, abs=0.003)
        if a_max < 0.01:
            # A robot that can hardly move catches when the ball arrives, minus the little it can
            # still meet it: 2 sqrt(v_ball (T - s) / a) <= s gives T - s <= a T^2 / (4 v_ball).
            v_ball = kicked(ti + t_drib - t_kick, v0)[1]
            early = t_drib - times[k]
            assert -0.002 < early < a_max * t_drib**2 / (4.0 * v_ball) + 0.002
        else:
            assert times[k] < t_drib - 0.1  # it drives towards the ball instead
        point = rig.catch_point[0][k]
        assert stamp_s(point) == round(ti, 6)
        catch_x = p0[0] + kicked(ti + expected - t_kick, v0)[0] + OFFSET_M
        assert point_from_msg(point)[1] == pytest.approx([catch_x, 0.0], abs=0.01)
        checked += 1
    assert checked > 40
    assert rig.all_finite()


def test_ball_leaving_the_field_far_from_the_robot_is_never_caught(ros_graph):
    """division_b: goal line at x = 4.5. Ball kicked from (3.0, 2.0) along +x at 4 m/s leaves after
    ~0.4 s; the robot at (-4, -2.5) is 7 m away, which takes it more than 3.5 s at 2 m/s. Seen in the run-off
    area, heading for the wall (4.8 m less the ball's radius), the ball comes back off it into the field and
    rests there: then the robot can fetch it."""
    rig = Rig(ros_graph, num_robots=1, robot_timeout_s=100.0, robot_a_max_mps2=3.0, robot_v_max_mps=2.0)
    rig.robot(0, 0.9, -4.0, -2.5, 0.0)
    t, xy, _, t_kick = shot_frames(1.0, (3.0, 2.0), (1.0, 0.0), 4.0)
    sent = 0
    for ti, (x, y) in zip(t, xy, strict=True):
        if x > 4.5 + 0.2:  # the frames a real ball gives before the wall
            break
        rig.ball(ti, x, y)
        sent += 1
    rig.settle()
    times = [m.data for m in rig.catch_time[0]]
    assert len(times) == sent
    inside = [c for c, ti, (x, _) in zip(times, t, xy, strict=False) if ti > t_kick + 0.1 and x <= 4.5 - 0.05]
    assert len(inside) >= 10 and all(c == contract.CATCH_TIME_NEVER for c in inside)
    run_off = [c for c, (x, _) in zip(times, xy, strict=False) if x > 4.5 + 0.05]
    assert len(run_off) >= 3 and all(c > 3.5 for c in run_off)
    assert times[0] > 0.0  # the resting ball before the kick can be fetched
    n_never = sum(c == contract.CATCH_TIME_NEVER for c in times)
    assert len(rig.catch_point[0]) == len(times) - n_never  # "never" has no catch point
    assert rig.all_finite()


def test_no_robots_seen_gives_no_catch_outputs_until_one_is_seen(ros_graph):
    """Our robot_1 and the opponents' opponent_0 (rig index 2) answered alike, each under its namespace."""
    rig = Rig(ros_graph, num_robots=2, num_opponents=1)
    for k in range(5):
        rig.ball(1.0 + k / FPS, 1.0, 1.0)
    rig.settle()
    assert all(len(c) == 0 for c in rig.catch_time) and all(len(c) == 0 for c in rig.catch_point)
    assert len(rig.catches) == 0
    # One message: robot_1 at rest 1 m left of a resting ball, facing it, and robots the node does not serve
    # (ours beyond num_robots, an opponent beyond num_opponents), skipped; then, stamped earlier (another
    # camera's frame, late), opponent_0 at rest 2 m above the ball, facing it: each robot has its own time line.
    rig.robots_frame(1.06, [(1, 0.0, 1.0, 0.0)], {1},
                     others=[(contract.OURS.code, 2, 2.0, 2.0, 0.0), (contract.OPPONENTS.code, 1, -2.0, 0.0, 0.0)])
    rig.robots_frame(1.05, [(2, 1.0, 3.0, -math.pi / 2)], {2})
    rig.ball(1.08, 1.0, 1.0)
    rig.settle()
    assert len(rig.catch_time[0]) == 0 and len(rig.catch_time[1]) == 1 and len(rig.catch_time[2]) == 1
    # resting ball: after the reaction time (0.1 s default), drive 1 - offset m (the opponent 2 - offset m)
    # from rest to rest with the catcher's limits (the node's defaults)
    for i, distance_m, point in ((1, 1.0 - OFFSET_M, (1.0 - OFFSET_M, 1.0)),
                                 (2, 2.0 - OFFSET_M, (1.0, 1.0 + OFFSET_M))):
        expected = 0.1 + float(robot_time_1d(distance_m, CatcherConfig().a_max_mps2, CatcherConfig().v_max_mps))
        assert rig.catch_time[i][0].data == pytest.approx(expected, abs=1e-3)
        assert point_from_msg(rig.catch_point[i][0])[1] == pytest.approx(point, abs=1e-3)
    assert rig.odom[2][-1].child_frame_id == "opponent_0/base_link"
    # the table: the same in one message, with each robot's team, id and pose (at rest: no extrapolation)
    ros_graph.probe.spin_until(lambda: len(rig.catches) == 1, 10.0, "/ball/catches")
    rows = table_from_msg(rig.catches[0], contract.CATCH_TABLE_COLUMNS).tolist()
    assert rows == [pytest.approx([team.code, 1 if team is contract.OURS else 0, x, y, yaw, 0.0, 0.0,
                                   rig.catch_time[i][0].data, *point_from_msg(rig.catch_point[i][0])[1]], abs=1e-9)
                    for i, team, x, y, yaw in ((1, contract.OURS, 0.0, 1.0, 0.0),
                                               (2, contract.OPPONENTS, 1.0, 3.0, -math.pi / 2))]

    # A frame's ball and robots in one message: the ball is answered first, so robot_0, first seen in it, has
    # no catch time for that ball frame, and one for the next
    before = len(rig.state), len(rig.odom[0])
    ball_and_robot_0 = [(contract.VISION_BALL_CODE, 0.0, 1.0, 1.0, 0.0), (contract.OURS.code, 0, -1.0, 1.0, 0.0)]
    rig.robots_pub.publish(robots_msg(1.10 + T_SHIFT_S, ball_and_robot_0))
    ros_graph.probe.spin_until(lambda: len(rig.state) > before[0] and len(rig.odom[0]) > before[1], 10.0,
                               "the ball and robot_0 of one message")
    rig.settle()
    assert len(rig.catch_time[0]) == 0 and len(rig.catch_time[1]) == 2 and len(rig.catch_time[2]) == 2
    rig.ball(1.12, 1.0, 1.0)
    rig.settle()
    assert len(rig.catch_time[0]) == 1


def test_bad_observations_are_dropped_with_a_warning_and_nothing_non_finite_is_published(ros_graph):
    rig = Rig(ros_graph, num_robots=1, robot_timeout_s=100.0)
    rig.robot(0, 0.9, -1.0, 0.0, 0.0)
    rig.ball(1.00, 0.0, 0.0)
    rig.ball(1.01, 0.0, 0.0)
    rig.ball(1.02, math.nan, 0.0, answered=False)
    rig.node.wait_for_output("rejected vision/robots: ball: x is not finite", timeout_s=5.0)
    rig.ball(1.03, 0.0, math.inf, answered=False)
    rig.ball(1.04, 1e9, 0.0, answered=False)
    rig.ball(1.05, 9.0, 0.0, answered=False)  # division_b: |x| <= 4.5 + 0.5
    rig.node.wait_for_output("rejected vision/ball outside the field", timeout_s=5.0)
    # Rejected frames do not keep the time line alive: after dead_s (1 s) of them the next stamp, even one
    # from the past, would start a new line (erforce_interfaces.wire.stamps). A good frame first.
    rig.ball(1.05, 0.0, 0.0)
    rig.ball(0.50, 0.0, 0.0, answered=False)  # a lone stamp from the past
    rig.node.wait_for_output(r"rejected vision/ball: stamp 5\.500000 s is before the newest accepted", timeout_s=5.0)
    rig.ball(1.05, 0.0, 0.0, answered=False)  # repeated stamp: on the line, but not after the previous frame
    rig.ball(1.06, 0.0, 0.0)  # the node goes on where it was
    _, pose, velocity, _ = odometry_from_msg(rig.state[-1])
    assert np.allclose(pose[:2], 0.0, atol=1e-9) and np.allclose(velocity[:2], 0.0, atol=1e-9)

    rig.robot(0, 0.95, math.nan, 0.0, 0.0, answered=False)
    rig.node.wait_for_output("rejected vision/robots: robot 0: x is not finite", timeout_s=5.0)
    rig.robot(0, 0.96, 20.0, 0.0, 0.0, answered=False)
    rig.node.wait_for_output("robot_0: rejected robot pose outside the field", timeout_s=5.0)
    rig.robot(0, 0.965, -1.0, 0.0, 0.0)  # the time line alive again, as for the ball
    rig.robot(0, 0.80, -1.0, 0.0, 0.0, answered=False)
    rig.node.wait_for_output(r"rejected vision/robots \(robot_0\): stamp 5\.800000 s is before", timeout_s=5.0)
    rig.robots_frame(0.966, [(0, -1.0, 0.0, 0.0)], set(), others=[(3.0, 0, -1.0, 0.0, 0.0)])  # no team 3: refused
    rig.robot(0, 0.97, -1.0, 0.0, 0.0)
    # A frame whose ball is good and one of whose robots is not: the ball, read first, is answered; the robots are
    # refused together (robot 0, good in itself, gets no odom).
    probe, before_state, before_odom = rig.graph.probe, len(rig.state), len(rig.odom[0])
    rig.robots_pub.publish(robots_msg(1.07 + T_SHIFT_S, [(contract.VISION_BALL_CODE, 0.0, 0.0, 0.0, 0.0),
                                                          (contract.OURS.code, 0.0, -1.0, 0.0, 0.0),
                                                          (3.0, 0.0, -1.0, 0.0, 0.0)]))
    probe.spin_until(lambda: len(rig.state) > before_state, 10.0, "the ball of a frame with a refused robot")
    assert stamp_s(rig.state[-1]) == 1.07
    probe.spin_for(0.3)
    assert len(rig.odom[0]) == before_odom
    rig.settle()
    assert len(rig.catch_time[0]) == 5 and rig.all_finite()  # the ball frames at 1.00, 1.01, 1.05, 1.06, 1.07
    assert rig.node.alive()


BAD_PARAMS = [
    ("a_slide_mps2", 0.0), ("a_slide_mps2", 2.5), ("a_slide_mps2", -0.2),  # |a_slide| must exceed |a_roll|
    ("a_roll_mps2", 0.0), ("a_roll_mps2", 0.3), ("a_roll_mps2", math.nan),
    ("c_switch", 0.0), ("c_switch", -0.6), ("c_switch", 1.5),
    ("field", "division_c"), ("robot_a_max_mps2", 0.0), ("robot_v_max_mps", -2.0), ("grid_step_s", 0.0),
    ("facing_mode", ["sideways"]), ("facing_mode", ["fixed", "fixed", "fixed"]), ("facing_rad", [math.inf]),
    ("num_robots", 5),  # read-only
    ("chip_damping_z", 1.0), ("chip_damping_xy_first_hop", 1.2), ("chip_min_hop_vz_mps", 0.0),
    ("chip_max_catch_height_m", -0.1), ("chip_max_catch_height_m", math.nan),
    ("chip_max_receive_height_m", -0.01), ("chip_max_receive_height_m", math.inf),
    ("chip_max_receive_height_m", 0.9), ("chip_max_catch_height_m", 0.01),  # reception above interception
]


def test_bad_parameters_are_rejected_and_the_old_value_kept(ros_graph):
    rig = Rig(ros_graph, num_robots=2)
    probe = ros_graph.probe
    # the robot limits default to what the catcher drives with
    assert probe.get_parameter(NODE, "robot_a_max_mps2") == CatcherConfig().a_max_mps2
    assert probe.get_parameter(NODE, "robot_v_max_mps") == CatcherConfig().v_max_mps
    for name, value in BAD_PARAMS:
        before = probe.get_parameter(NODE, name)
        result = probe.set_parameter(NODE, name, value)
        assert not result.successful, (name, value)
        assert probe.get_parameter(NODE, name) == before, name
    rig.ball(1.0, 0.5, 0.5)
    # A valid change is taken: a fixed facing of +x for both robots; the catch point of a resting
    # ball is then the ball minus the offset along x.
    assert probe.set_parameter(NODE, "facing_mode", ["fixed"]).successful
    assert probe.set_parameter(NODE, "facing_rad", [0.0]).successful
    assert probe.set_parameter(NODE, "a_roll_mps2", -0.4).successful
    assert probe.get_parameter(NODE, "a_roll_mps2") == -0.4
    rig.robot(0, 1.005, -1.0, 0.5, 0.0)
    rig.ball(1.01, 0.5, 0.5)
    rig.settle()
    assert point_from_msg(rig.catch_point[0][-1])[1] == pytest.approx([0.5 - OFFSET_M, 0.5], abs=1e-6)
    assert rig.all_finite()


def test_online_identification_replaces_the_model_with_the_fitted_one(ros_graph):
    true = {"a_slide": 3.0, "a_roll": 0.4, "c_switch": 0.65}  # not the node's defaults
    rig = Rig(ros_graph, num_robots=1, online_identification=True, ident_min_shots=2)
    rng = np.random.default_rng(5)
    t0, x = 1.0, -4.0
    for sign in (1.0, -1.0, 1.0):
        t, xy, _, _ = shot_frames(t0, (x, 0.3), (sign, 0.0), 3.0, rest_frames=12, **true)
        noisy = xy + rng.normal(0.0, 0.001, xy.shape)
        for ti, (xi, yi) in zip(t, noisy, strict=True):
            rig.ball(ti, xi, yi)
        t0, x = t[-1] + 1.0 / FPS, xy[-1, 0]
    ros_graph.probe.spin_until(lambda: len(rig.model_params) >= 3, 20.0, "the model at start and two fits")
    rig.node.wait_for_output("online identification: now using", timeout_s=10.0)
    table = table_from_msg(rig.model_params[-1], contract.BALL_MODEL_PARAM_LABELS)
    assert rig.model_params[-1].layout.dim[0].label == "in_use,fit,std_error"
    in_use, fit, std = table
    assert np.all(std < [0.1, 0.02, 0.03])
    # The fit is unbiased with the spread it reports (over 40 noise seeds offline: mean a_slide -3.007,
    # sd 0.021 for two shots), so it must lie within 4 of its own standard errors of the truth; which
    # fit is last here (two or three shots) depends on timing.
    truth = np.array([-true["a_slide"], -true["a_roll"], true["c_switch"]])
    assert np.all(np.abs(fit - truth) <= 4.0 * std), (fit, std)
    assert np.array_equal(in_use, fit)


def test_model_in_use_is_latched_at_start_and_follows_a_parameter_change(ros_graph):
    rig = Rig(ros_graph, num_robots=1)
    probe = ros_graph.probe
    probe.spin_until(lambda: rig.model_params, 10.0, "the model in use at start")
    first = rig.model_params[-1]
    assert first.layout.dim[0].label == "in_use"
    assert table_from_msg(first, contract.BALL_MODEL_PARAM_LABELS)[0] == pytest.approx([-A_SLIDE, -A_ROLL, C_SWITCH])
    assert probe.set_parameter(NODE, "a_roll_mps2", -0.5).successful
    probe.spin_until(lambda: len(rig.model_params) >= 2, 10.0, "the changed model")
    assert table_from_msg(rig.model_params[-1], contract.BALL_MODEL_PARAM_LABELS)[0] == pytest.approx(
        [-A_SLIDE, -0.5, C_SWITCH])
    # A reader that joins late gets the model in use at once (transient local), not the first one.
    late = probe.subscribe(contract.BALL_MODEL_PARAMS.name, Float64MultiArray, contract.BALL_MODEL_PARAMS.qos)
    probe.spin_until(lambda: late, 10.0, "the latched model")
    assert len(late) == 1
    assert table_from_msg(late[0], contract.BALL_MODEL_PARAM_LABELS)[0] == pytest.approx([-A_SLIDE, -0.5, C_SWITCH])


def chip_models_rig(ros_graph):
    """A one-robot predictor and the /ball/chip_model_params it published, once the first has come."""
    rig = Rig(ros_graph, num_robots=1)
    models = ros_graph.probe.subscribe(contract.BALL_CHIP_MODEL_PARAMS.name, Float64MultiArray,
                                       contract.BALL_CHIP_MODEL_PARAMS.qos)
    ros_graph.probe.spin_until(lambda: models, 10.0, "the chip model in use at start")
    return rig, models


def test_chip_model_in_use_is_latched_at_start_and_follows_a_parameter_change(ros_graph):
    """/ball/chip_model_params carries ChipParams' fields in contract order: the defaults at start (the plant's ball:
    restitution 0.566, 1 / 1.4 of the speed kept at the first bounce, interception height 0.15 m, reception height a
    ball radius), then a changed interception height, then a changed reception height."""
    rig, models = chip_models_rig(ros_graph)
    probe, labels = ros_graph.probe, contract.BALL_CHIP_MODEL_PARAM_LABELS
    assert models[-1].layout.dim[0].label == "in_use"
    defaults = [9.81, 0.566, 1.0 / 1.4, 1.0, 0.05, 0.15, 0.02135]
    assert table_from_msg(models[-1], labels)[0].tolist() == pytest.approx(defaults, abs=1e-12)
    assert probe.set_parameter(NODE, "chip_max_catch_height_m", 0.25).successful
    probe.spin_until(lambda: len(models) >= 2, 10.0, "the changed chip model")
    assert table_from_msg(models[-1], labels)[0].tolist() == pytest.approx([*defaults[:5], 0.25, 0.02135], abs=1e-12)
    assert probe.set_parameter(NODE, "chip_max_receive_height_m", 0.03).successful
    probe.spin_until(lambda: len(models) >= 3, 10.0, "the changed reception height")
    assert table_from_msg(models[-1], labels)[0].tolist() == pytest.approx([*defaults[:5], 0.25, 0.03], abs=1e-12)
    assert probe.set_parameter(NODE, "a_roll_mps2", -0.4).successful  # not the chip model: not sent again
    probe.spin_until(lambda: len(rig.model_params) >= 2, 10.0, "the changed ball model")
    probe.spin_for(0.3)
    assert len(models) == 3


def test_ssl_geometrys_chip_model_becomes_the_chip_model_in_use_and_a_bad_one_is_refused(ros_graph):
    """/vision/chip_model (SSL geometry's chip_fixed_loss, grSim's 0.42, 0.6, 0.96) replaces the three dampings of
    /ball/chip_model_params; g, the minimum hop and the two heights stay the node's. One that makes no chip
    model (damping_z 1: it would hop for ever) is refused with a warning naming the topic, and the one in use kept."""
    rig, models = chip_models_rig(ros_graph)
    probe, labels = ros_graph.probe, contract.BALL_CHIP_MODEL_PARAM_LABELS
    geometry = probe.wait_for_subscribers(contract.VISION_CHIP_MODEL.name, Float64MultiArray, timeout_s=20.0,
                                          qos=contract.VISION_CHIP_MODEL.qos)
    geometry.publish(table_msg([[0.42, 0.6, 0.96]], contract.VISION_CHIP_MODEL_LABELS, "model"))
    probe.spin_until(lambda: len(models) >= 2, 10.0, "the geometry's chip model in use")
    in_use = [9.81, 0.42, 0.6, 0.96, 0.05, 0.15, 0.02135]
    assert table_from_msg(models[-1], labels)[0].tolist() == pytest.approx(in_use, abs=1e-12)
    geometry.publish(table_msg([[1.0, 0.6, 0.96]], contract.VISION_CHIP_MODEL_LABELS, "model"))
    probe.spin_until(lambda: "rejected SSL geometry's chip model" in rig.node.output(), 10.0, "the refusal")
    assert len(models) == 2


def test_a_bad_kick_angle_is_refused_with_a_throttled_warning_and_its_kick_is_no_hint(ros_graph):
    """kick_angle outside [0, 90) deg (not finite, negative, 90 or more): a warning naming the robot and the value,
    throttled; the robot's next kick is no hint to the chip detector (it never sees the angle), and the node
    answers on with finite outputs only."""
    rig = Rig(ros_graph, num_robots=1, robot_timeout_s=100.0)
    probe = ros_graph.probe
    q = contract
    angle = probe.wait_for_subscribers(q.KICK_ANGLE.for_robot(0), Float64, timeout_s=10.0, qos=q.KICK_ANGLE.qos)
    kick = probe.wait_for_subscribers(q.KICK.for_robot(0), Float64, timeout_s=10.0, qos=q.KICK.qos)
    rig.robot(0, 0.9, -1.0, 0.0, 0.0)
    rig.ball(1.00, 0.0, 0.0)
    for k, bad in enumerate((math.nan, -10.0, 90.0, math.inf, 120.0)):
        text = f"robot_0: rejected kick_angle {bad!r}"

        def warned(bad=bad, text=text) -> bool:  # resent until said (the warning of the one before may hold it)
            angle.publish(Float64(data=bad))
            probe.spin_for(0.05)
            return text in rig.node.output()

        probe.spin_until(warned, 10.0, text)
        kick.publish(Float64(data=3.0))
        rig.ball(1.01 + 0.01 * k, 0.0, 0.0)
    for _ in range(30):
        angle.publish(Float64(data=-1.0))

    def rejected() -> list[int]:
        """The count of refused angles each warning line reports (a throttled line says how many so far)."""
        return [int(n) for n in re.findall(r"rejected kick_angle .*\((\d+) so far\)", rig.node.output())]

    def counted() -> bool:  # one more every 0.1 s until a line reports the burst (the throttle's period is 2 s)
        angle.publish(Float64(data=-1.0))
        probe.spin_for(0.1)
        return max(rejected(), default=0) >= 20

    probe.spin_until(counted, 15.0, "a warning that counts the burst")
    lines = [line for line in rig.node.output().splitlines() if "rejected kick_angle" in line]
    assert len(lines) < max(rejected()) / 2, lines  # throttled: far fewer lines than refused angles
    rig.ball(1.1, 0.0, 0.0)
    rig.settle()
    assert "kick not taken as a hint" not in rig.node.output()
    assert rig.all_finite() and rig.node.alive()


@pytest.mark.parametrize("source", ["ssl_geometry", "parameters"])
def test_a_new_model_filters_a_kick_as_a_predictor_started_with_it(ros_graph, source):
    """grSim's model (far from the defaults) comes while the ball lies still, from /vision/ball_model (SSL
    geometry) or set on the node's parameters at run time (ros2 param set); the node's
    answers to the kick that follows (3 m/s, that model, 2 mm noise) are those of the predictor's core started
    with the model: v_shoot and the stop point at every frame up to 1 s after the kick, within the tolerances
    test_predictor derives (the two differ only by their estimates of the ball at rest)."""
    from erforce_ball_model.ball_model import BallModelParams
    from erforce_ball_model.predictor import BallPredictor, PredictorConfig

    far = {"a_slide": 14.0, "a_roll": 0.7, "c_switch": 0.7}
    model = BallModelParams(-far["a_slide"], -far["a_roll"], far["c_switch"])
    rig = Rig(ros_graph, num_robots=1)
    probe = ros_graph.probe
    q = contract
    geometry = probe.wait_for_subscribers(q.VISION_BALL_MODEL.name, Float64MultiArray, timeout_s=20.0,
                                          qos=q.VISION_BALL_MODEL.qos)
    t, xy, _, t_kick = shot_frames(1.0, (-3.0, 0.3), (1.0, 0.0), 3.0, rest_frames=20, **far)
    keep = t <= t_kick + 1.0
    t, xy = t[keep], xy[keep] + np.random.default_rng(7).normal(0.0, 0.002, (int(keep.sum()), 2))
    pinned = BallPredictor(PredictorConfig(num_robots=1, model=model))
    compared = 0
    for k, (ti, (x, y)) in enumerate(zip(t, xy, strict=True)):
        if k == 10 and source == "ssl_geometry":
            geometry.publish(table_msg([[-14.0, -0.7, 0.7]], q.BALL_MODEL_PARAM_LABELS, "model"))
        if k == 10 and source == "parameters":  # in this order, each step is a valid model
            for name, value in (("a_slide_mps2", -14.0), ("a_roll_mps2", -0.7), ("c_switch", 0.7)):
                assert probe.set_parameter(NODE, name, value).successful
        if k == 10:
            probe.spin_until(lambda: table_from_msg(rig.model_params[-1], q.BALL_MODEL_PARAM_LABELS)[0].tolist()
                             == [-14.0, -0.7, 0.7], 10.0, "the new model in use")
        rig.ball(ti, x, y)
        want = pinned.ball_frame(stamp_to_seconds(ball_msg(ti + T_SHIFT_S, x, y).header.stamp), x, y)
        if ti > t_kick:
            assert abs(rig.v_shoot[-1].data - want.trajectory.v_shoot_mps) < 1e-5, (ti, rig.v_shoot[-1].data)
            assert math.dist(point_from_msg(rig.stop[-1])[1], want.stop_point_m) < 1e-4, ti
            compared += 1
    assert compared == 70  # 1 s at 70 Hz


def test_odom_follows_a_moving_robot(ros_graph):
    """Noise-free poses of a robot moving at (1.0, -0.5) m/s and turning at 2 rad/s through +-pi."""
    rig = Rig(ros_graph, num_robots=2)
    for k in range(40):
        t = 1.0 + k / FPS
        yaw = math.remainder(3.0 + 2.0 * (t - 1.0), 2.0 * math.pi)
        rig.robot(1, t, -1.0 + 1.0 * (t - 1.0), 0.5 - 0.5 * (t - 1.0), yaw)
    odom = rig.odom[1][-1]
    _, pose, velocity, _ = odometry_from_msg(odom)
    assert odom.child_frame_id == "robot_1/base_link" and odom.header.frame_id == contract.FIELD_FRAME
    assert stamp_s(odom) == round(1.0 + 39 / FPS, 6)
    assert pose[:2] == pytest.approx([-1.0 + 39 / FPS, 0.5 - 0.5 * 39 / FPS], abs=1e-3)
    assert velocity == pytest.approx([1.0, -0.5, 2.0], abs=0.05)
    assert len(rig.odom[0]) == 0 and rig.all_finite()


def test_the_tracked_table_carries_every_robot_seen_within_the_timeout_as_its_odom(ros_graph):
    """Our robots 0 and 1 in one frame, opponent_0 alone in the next: after each frame one table, every robot
    seen within robot_timeout_s (1 s, the node's default) in it, ours first, each row what that robot's newest
    odom carries. At 1.5 s past those frames robot_1 alone is seen: the others drop out of the table."""
    rig = Rig(ros_graph, num_robots=2, num_opponents=1)
    probe = ros_graph.probe
    rig.robots_frame(1.0, [(0, -1.0, 0.5, 0.25), (1, 2.0, -1.0, -2.0)], {0, 1})
    probe.spin_until(lambda: len(rig.tracked) == 1, 10.0, "the first /robots/tracked")
    assert [(r.team, r.robot_id) for r in tracked_robots_from_msg(rig.tracked[-1])] == [
        (contract.OURS.code, 0), (contract.OURS.code, 1)]
    rig.robots_frame(1.02, [(2, 3.0, 1.0, math.pi / 2)], {2})
    probe.spin_until(lambda: len(rig.tracked) == 2, 10.0, "the second /robots/tracked")
    rows = tracked_robots_from_msg(rig.tracked[-1])
    assert [(r.team, r.robot_id) for r in rows] == [(contract.OURS.code, 0), (contract.OURS.code, 1),
                                                    (contract.OPPONENTS.code, 0)]
    for i, row in enumerate(rows):
        stamp, pose, velocity, _ = odometry_from_msg(rig.odom[i][-1])
        assert row.stamp_s == stamp and row.pose[:2] == tuple(pose[:2]) and row.velocity == tuple(velocity)
        assert row.pose[2] == pytest.approx(pose[2], abs=1e-12)
    assert [r.stamp_s - T_SHIFT_S for r in rows] == pytest.approx([1.0, 1.0, 1.02], abs=1e-9)
    rig.robots_frame(2.52, [(1, 2.0, -1.0, -2.0)], {1})
    probe.spin_until(lambda: len(rig.tracked) == 3, 10.0, "the third /robots/tracked")
    assert [(r.team, r.robot_id) for r in tracked_robots_from_msg(rig.tracked[-1])] == [(contract.OURS.code, 1)]


def test_no_cyclic_collection_runs_between_a_frame_and_its_catch_times():
    """The cyclic GC is held off from a vision frame's start until its balls are answered, and is on again
    afterwards, also when answering fails. In-process: the node's callback is called directly."""
    rclpy.init()
    node = None
    try:
        node = BallPredictorNode()
        publish_catch_outputs = node._publish_catch_outputs
        gc_on_at_catch_outputs = []

        def recording(frame):
            gc_on_at_catch_outputs.append((gc.isenabled(), frame.catch_robots))
            return publish_catch_outputs(frame)

        node._publish_catch_outputs = recording
        # robot_0 seen first (a frame without a ball), then two frames whose ball it is answered for
        node._on_vision(vision_robots_cdr(1.0, [(contract.OURS.code, 0, 0.0, 1.0, 0.0)]))
        for k in (1, 2):
            node._on_vision(vision_robots_cdr(1.0 + k / FPS, [(contract.OURS.code, 0, 0.0, 1.0, 0.0)],
                                              balls=[(1.0, 1.0)]))
        assert gc_on_at_catch_outputs == [(False, [0]), (False, [0])]
        assert gc.isenabled()

        def failing(frame):
            raise RuntimeError("a publisher that fails")

        node._publish_catch_outputs = failing
        with pytest.raises(RuntimeError):
            node._on_vision(vision_robots_cdr(1.0 + 3 / FPS, [], balls=[(1.0, 1.0)]))
        assert gc.isenabled()
    finally:
        gc.enable()
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()


def test_the_catch_table_goes_out_before_every_per_robot_catch_output(ros_graph):
    """The AI reads /ball/catches: per frame it leaves the node (DDS source timestamp) before any robot's
    catch_time and catch_point of that frame; the table's catch times are those of the per-robot topics."""
    rig = Rig(ros_graph, num_robots=2, num_opponents=1)
    node, q = ros_graph.probe.node, contract
    sent: dict[str, list[int]] = {}

    def stamps(name, msg_type, qos):
        sent[name] = []
        node.create_subscription(msg_type, name, lambda _m, info: sent[name].append(info["source_timestamp"]), qos)

    stamps(q.BALL_CATCHES.name, Float64MultiArray, q.BALL_CATCHES.qos)
    for team, i in rig.robots:
        stamps(team.topic(q.CATCH_TIME, i), Float64, q.CATCH_TIME.qos)
        stamps(team.topic(q.CATCH_POINT, i), PointStamped, q.CATCH_POINT.qos)
    readers = [s for s in node.subscriptions if s.topic_name in sent]
    ros_graph.probe.spin_until(lambda: all(s.get_publisher_count() > 0 for s in readers), 20.0, "node publishers")
    # all three robots at rest 1-2 m from a resting ball: every one can catch it (a point each)
    rig.robots_frame(1.0, [(0, -1.0, 1.0, 0.0), (1, 1.0, -1.0, math.pi / 2), (2, 2.0, 1.0, math.pi)], {0, 1, 2})
    frames = 5
    for k in range(frames):
        rig.ball(1.02 + k / FPS, 0.0, 1.0)
    ros_graph.probe.spin_until(lambda: all(len(v) >= frames for v in sent.values()), 10.0, "every catch output")
    tables = sent.pop(q.BALL_CATCHES.name)
    assert len(tables) == frames and all(len(v) == frames for v in sent.values())
    for k in range(frames):
        assert all(tables[k] < v[k] for v in sent.values()), f"frame {k}: a per-robot output before the table"
    rows = table_from_msg(rig.catches[-1], contract.CATCH_TABLE_COLUMNS)
    assert rows[:, 7].tolist() == [rig.catch_time[i][-1].data for i in range(3)]
def test_queued_frames_have_every_leading_ball_answered_before_their_robots(monkeypatch):
    """A burst: the frame that wakes the node and those queued behind it (taken with it). Every leading ball is
    answered (catch times out) before any of their robots is tracked; each stream stays in stamp order; from a
    frame with a ball after its robots (another writer's order) on, each frame is answered in turn.
    In-process: the node's callback is called directly with hand-built messages."""
    rclpy.init()
    node = None
    try:
        node = BallPredictorNode()
        events = []
        ball_frame, robot_frame = node._predictor.ball_frame, node._predictor.robot_frame
        publish_catch_outputs = node._publish_catch_outputs

        def on_ball(t_s, x, y, **kw):
            events.append(("ball", round(t_s, 6)))
            return ball_frame(t_s, x, y, **kw)

        def on_robot(robot, t_s, *args, **kw):
            events.append(("robot", round(t_s, 6)))
            return robot_frame(robot, t_s, *args, **kw)

        def on_catch(frame):
            events.append(("catch", round(frame.t_s, 6)))
            return publish_catch_outputs(frame)

        node._predictor.ball_frame, node._predictor.robot_frame = on_ball, on_robot
        node._publish_catch_outputs = on_catch
        ours = contract.OURS.code
        robot = [(ours, 0, 0.0, 1.0, 0.0)]
        queued = []
        monkeypatch.setattr(ball_predictor_node, "take_queued", lambda _sub: [(m, {}) for m in queued])
        node._on_vision(vision_robots_cdr(1.0, robot))  # robot_0 seen: ball frames get its catch time
        assert events == [("robot", 1.0)]

        def ball_last(t_s):  # robot point first, then the ball (another writer's order)
            return serialize_message(robots_msg(t_s, [*robot, (contract.VISION_BALL_CODE, 0.0, 1.0, 1.0, 0.0)]))

        for case, frames, expected in (
            ("a robot frame wakes the node, two ball frames queued behind it",
             [vision_robots_cdr(1.01, robot), vision_robots_cdr(1.02, robot, balls=[(1.0, 1.0)]),
              vision_robots_cdr(1.03, robot, balls=[(1.01, 1.0)])],
             ["ball 1.02", "catch 1.02", "ball 1.03", "catch 1.03", "robot 1.01", "robot 1.02", "robot 1.03"]),
            ("a frame with its ball after its robots ends the balls going first",
             [vision_robots_cdr(1.04, robot), vision_robots_cdr(1.05, robot, balls=[(1.02, 1.0)]), ball_last(1.06),
              vision_robots_cdr(1.07, robot, balls=[(1.03, 1.0)])],
             ["ball 1.05", "catch 1.05", "robot 1.04", "robot 1.05", "ball 1.06", "catch 1.06", "robot 1.06",
              "ball 1.07", "catch 1.07", "robot 1.07"]),
            ("nothing queued: the frame's ball, then its robots, as before",
             [vision_robots_cdr(1.08, robot, balls=[(1.04, 1.0)])], ["ball 1.08", "catch 1.08", "robot 1.08"]),
        ):
            events.clear()
            queued[:] = frames[1:]
            node._on_vision(frames[0])
            assert [f"{kind} {t:g}" for kind, t in events] == expected, case
        assert gc.isenabled()
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()


def test_a_robots_odom_carries_its_filters_variances_not_an_exact_states_zeros():
    """Two poses 0.02 s apart through the node (in-process): the CV filters' covariances by hand. Position (vision's
    sigma 2 mm, r = 4e-6 m^2, white acceleration q = 1 (m/s^2)^2/Hz): after the first frame P = diag(r, 1); predicted
    a = r + dt^2 + q dt^3 / 3, b = dt + q dt^2 / 2, c = 1 + q dt; corrected a r / (a + r), c - b^2 / (a + r). Heading
    the same with r = 1e-4 rad^2, q = 200 (rad/s^2)^2/Hz. Each on its diagonal, x and y alike; z, roll, pitch 0."""
    from rclpy.serialization import deserialize_message

    dt, r, q, r_h, q_h = 0.02, 0.002**2, 1.0, 0.01**2, 200.0

    def corrected(r, q):
        a, b, c = r + dt**2 + q * dt**3 / 3.0, dt + q * dt**2 / 2.0, 1.0 + q * dt
        return a * r / (a + r), c - b * b / (a + r)

    (var_pos, var_vel), (var_yaw, var_rate) = corrected(r, q), corrected(r_h, q_h)
    assert (var_pos, var_vel) == pytest.approx((3.9610e-6, 0.026396), rel=1e-4)  # the numbers, for a reader
    rclpy.init()
    node = None
    try:
        node = BallPredictorNode()
        sent = []
        node._odom_readers[0] = 1
        node._odom_pubs[0].publish = sent.append
        for k in range(2):
            node._on_vision(vision_robots_cdr(1.0 + k * dt, [(contract.OURS.code, 0, 0.5 + 0.01 * k, 1.0, 0.3)]))
        msg = deserialize_message(sent[-1], Odometry)
        pose, twist = np.array(msg.pose.covariance).reshape(6, 6), np.array(msg.twist.covariance).reshape(6, 6)
        assert np.diag(pose) == pytest.approx([var_pos, var_pos, 0.0, 0.0, 0.0, var_yaw], rel=1e-9)
        assert np.diag(twist) == pytest.approx([var_vel, var_vel, 0.0, 0.0, 0.0, var_rate], rel=1e-9)
        assert np.count_nonzero(pose - np.diag(np.diag(pose))) == np.count_nonzero(twist - np.diag(np.diag(twist))) == 0
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.shutdown()
