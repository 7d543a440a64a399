"""The multi-camera tracker against synthetic SSL-Vision: 4 overlapping cameras, each at its own rate
and latency, delivered in arrival order (so capture times come out of order), false ball candidates
and a camera that drops out. The true ball path is written here from the two-phase model's
definition (constant decelerations, switch at c_switch * v0), independent of ball_model."""

from __future__ import annotations

import itertools
import math
import random

from hypothesis import given, settings
from hypothesis import strategies as st

from erforce_ball_model.ball_model import BallModelParams
from erforce_ball_model.tracking import UpdateStatus
from erforce_ball_model.vision_tracking import VisionTracker, VisionTrackingConfig
from erforce_interfaces.wire.robot_config import FieldConfig

FIELD = FieldConfig(9.0, 6.0, 0.3)
PARAMS = BallModelParams(-2.5, -0.3, 0.6)
# (camera_id, rate_hz, latency_s, phase_s, x range, y range): quadrants overlapping by 0.5 m
CAMERAS = [
    (0, 75.0, 0.012, 0.000, (-5.0, 0.25), (-0.25, 3.5)),
    (1, 70.0, 0.020, 0.004, (-0.25, 5.0), (-0.25, 3.5)),
    (2, 65.0, 0.015, 0.009, (-5.0, 0.25), (-3.5, 0.25)),
    (3, 60.0, 0.030, 0.002, (-0.25, 5.0), (-3.5, 0.25)),
]
KICK_T_S, V0_MPS, START = 0.5, 4.0, (-1.0, 0.5)
REFLECTION = (4.5, 3.0)  # at the field corner, in camera 1's view
SPARE_BALL = (-4.7, -3.2)  # resting in the run-off area, in camera 2's view


def true_ball(t_s: float) -> tuple[float, float]:
    """Kicked along +x at KICK_T_S: slides at a_slide down to 0.6 v0, then rolls at a_roll to rest."""
    if t_s <= KICK_T_S:
        return START
    tau = t_s - KICK_T_S
    a1, a2, v_switch = 2.5, 0.3, 0.6 * V0_MPS
    t1 = (V0_MPS - v_switch) / a1
    if tau <= t1:
        s = V0_MPS * tau - 0.5 * a1 * tau**2
    else:
        s1 = V0_MPS * t1 - 0.5 * a1 * t1**2
        tr = min(tau - t1, v_switch / a2)
        s = s1 + v_switch * tr - 0.5 * a2 * tr**2
    return START[0] + s, START[1]


def frames(duration_s: float, drop_camera: tuple[int, float, float] | None = None, seed: int = 3):
    """All camera frames in arrival order: (arrival, camera, t_capture, balls)."""
    rng = random.Random(seed)
    out = []
    for cam, rate, latency, phase, (x0, x1), (y0, y1) in CAMERAS:
        k = 0
        while (t := phase + k / rate) < duration_s:
            k += 1
            if drop_camera and drop_camera[0] == cam and drop_camera[1] <= t < drop_camera[2]:
                continue
            balls = []
            bx, by = true_ball(t)
            if x0 <= bx <= x1 and y0 <= by <= y1:
                balls.append((bx + rng.gauss(0, 0.002), by + rng.gauss(0, 0.002), 0.9))
            if cam == 1 and k % 3 == 0:
                balls.append((*REFLECTION, 0.4))
            if cam == 2:
                balls.append((*SPARE_BALL, 0.95))
            rng.shuffle(balls)
            out.append((t + latency, cam, t, balls))
    out.sort()
    return out


def run(tracker: VisionTracker, stream):
    """The ball's stream: every observation but another camera's sighting of an instant already taken."""
    used = []
    for _arrival, cam, t, balls in stream:
        ball, _ = tracker.frame(cam, t, balls)
        if ball is not None and not ball.sighting:
            used.append(ball)
    return used


def test_the_true_ball_is_picked_among_false_candidates_and_its_kick_detected():
    stream = frames(2.5)
    assert any(f[2] < g[2] for f, g in zip(stream[1:], stream, strict=False))  # really out of order
    tracker = VisionTracker(FIELD, PARAMS)
    used = run(tracker, stream)
    times = [b.t_s for b in used]
    assert all(b > a for a, b in itertools.pairwise(times))
    errors = [math.dist((b.x_m, b.y_m), true_ball(b.t_s)) for b in used]
    assert max(errors) < 0.01  # 2 mm noise: never a false candidate (those are metres away)
    assert len(used) > 0.5 * sum(1 for f in stream if f[3] and any(c[2] == 0.9 for c in f[3]))
    assert tracker.kicks == 1 and tracker.ball.kick_count == 1
    # v_shoot from the frames after the kick: the kick speed within the noise
    assert abs(tracker.ball.v_shoot_mps - V0_MPS) < 0.15
    assert tracker.false_candidates > 0


def test_a_camera_dropping_out_loses_frames_not_the_ball():
    # camera 0 sees the ball at rest and the start of the kick; it drops out around the kick
    tracker = VisionTracker(FIELD, PARAMS)
    used = run(tracker, frames(2.0, drop_camera=(0, 0.3, 0.7)))
    errors = [math.dist((b.x_m, b.y_m), true_ball(b.t_s)) for b in used]
    assert max(errors) < 0.01
    assert any(0.7 <= b.t_s < 0.8 for b in used)  # back after the dropout
    assert tracker.switches == 0


def test_at_start_the_ball_inside_the_field_wins_over_the_one_in_the_run_off_area():
    tracker = VisionTracker(FIELD, PARAMS)
    outs = []
    for k in range(6):
        t = k / 60.0
        ball, _ = tracker.frame(0, t, [(*SPARE_BALL, 1.0), (0.3, 0.2, 0.5)])
        outs.append(ball)
    assert outs[:2] == [None, None]  # unconfirmed: nothing yet
    assert all(b is not None and (b.x_m, b.y_m) == (0.3, 0.2) for b in outs[2:])


def test_a_ball_put_down_elsewhere_is_followed_after_lost_after_s():
    config = VisionTrackingConfig(lost_after_s=0.1)
    tracker = VisionTracker(FIELD, PARAMS, config=config)
    for k in range(10):
        tracker.frame(0, k / 60.0, [(0.0, 0.0, 1.0)])
    switched_at = None
    for k in range(10, 40):
        ball, _ = tracker.frame(0, k / 60.0, [(2.0, 1.0, 1.0)])
        if ball is not None and switched_at is None:
            switched_at = k / 60.0
    # last seen at 9/60 s; the new place is confirmed after 3 frames, used once 0.1 s passed: the
    # first frame at or after 9/60 + 0.1 s, 15/60 s (up to rounding)
    assert 9 / 60 + 0.1 - 1e-9 <= switched_at <= 9 / 60 + 0.1 + 1 / 60 - 1e-9
    assert tracker.switches == 1


def test_two_cameras_at_the_same_instant_give_one_ball_and_one_sighting():
    """The second camera's ball of an instant taken is no update of the ball's stream, but its own view of that
    ball (a sighting, for the chip detector) when within sighting_gate_m of it; farther off, nothing."""
    tracker = VisionTracker(FIELD, PARAMS)
    for k in range(4):
        tracker.frame(0, k / 60.0, [(1.0, 1.0, 1.0)])
    a, _ = tracker.frame(0, 0.1, [(1.0, 1.0, 1.0)])
    b, _ = tracker.frame(1, 0.1, [(1.001, 1.0, 1.0)])
    assert a is not None and a.status == UpdateStatus.ACCEPTED and not a.sighting
    assert b == (0.1, 1.001, 1.0, 1, UpdateStatus.REJECTED_TIME, True) and tracker.late_balls == 1
    c, _ = tracker.frame(2, 0.1, [(1.0 + VisionTrackingConfig().sighting_gate_m + 0.01, 1.0, 1.0)])
    assert c is None and tracker.late_balls == 2


def test_22_robots_from_overlapping_cameras_each_get_one_increasing_pose_stream():
    tracker = VisionTracker(FIELD, PARAMS)
    rng = random.Random(1)
    seen: dict[tuple[str, int], list[float]] = {}
    stream = []
    for cam, rate, latency, phase, (x0, x1), (y0, y1) in CAMERAS:
        for k in range(int(1.0 * rate)):
            t = phase + k / rate
            robots = []
            for team in ("blue", "yellow"):
                for rid in range(11):
                    x = -4.0 + 0.7 * rid + 0.5 * t  # 0.5 m/s along x
                    y = 1.0 if team == "blue" else -1.0
                    y += 0.01 * rid if cam % 2 else 0.0
                    if x0 <= x <= x1 and y0 <= y <= y1:
                        robots.append((team, rid, x + rng.gauss(0, 0.002), y, 0.1))
            if cam == 0:
                robots.append(("blue", 0, 4.0, 2.0, 0.0))  # a false duplicate of blue 0 far away
            stream.append((t + latency, cam, t, robots))
    stream.sort()
    for _arr, cam, t, robots in stream:
        _, poses = tracker.frame(cam, t, [], robots)
        for p in poses:
            seen.setdefault((p.team, p.robot_id), []).append(p.t_s)
            assert abs(p.x_m - (-4.0 + 0.7 * p.robot_id + 0.5 * p.t_s)) < 0.01  # never the false duplicate
    assert len(seen) == 22
    for stamps in seen.values():
        assert all(b > a for a, b in itertools.pairwise(stamps))


def test_a_robot_put_down_elsewhere_is_reseeded_after_two_agreeing_sightings():
    tracker = VisionTracker(FIELD, PARAMS)
    assert len(tracker.frame(0, 0.0, [], [("yellow", 3, 0.0, 0.0, None)])[1]) == 1
    assert tracker.frame(0, 0.02, [], [("yellow", 3, 3.0, 2.0, None)])[1] == []  # held back
    (pose,) = tracker.frame(0, 0.04, [], [("yellow", 3, 3.0, 2.0, None)])[1]
    assert (pose.x_m, pose.y_m) == (3.0, 2.0)


def test_a_ball_in_the_run_off_area_takes_over_only_after_the_track_is_long_gone():
    tracker = VisionTracker(FIELD, PARAMS)  # the ball filter restarts after 1 s (TrackerConfig.max_gap_s)
    for k in range(10):
        tracker.frame(0, k / 60.0, [(0.0, 0.0, 1.0)])
    used = []
    for k in range(10, 150):  # the ball on the field vanished; one lies in the run-off area
        ball, _ = tracker.frame(0, k / 60.0, [SPARE_BALL + (1.0,)])
        if ball is not None:
            used.append(k / 60.0)
    assert used and 9 / 60 + 1.0 - 1e-9 <= used[0] <= 9 / 60 + 1.0 + 1 / 60 + 1e-9


coordinate = st.floats(-20.0, 20.0) | st.just(math.nan) | st.just(math.inf)
frames_strategy = st.lists(
    st.tuples(
        st.integers(0, 7),
        st.floats(0.0, 5.0),
        st.lists(st.tuples(coordinate, coordinate, st.floats(0.0, 1.0)), max_size=4),
        st.lists(st.tuples(st.sampled_from(["blue", "yellow"]), st.integers(0, 3), coordinate, coordinate,
                           st.none() | st.floats(-math.pi, math.pi)), max_size=4),
    ),
    max_size=60,
)


@settings(max_examples=200, deadline=None)
@given(frames_strategy)
def test_any_frame_sequence_gives_finite_outputs_at_increasing_stamps(stream):
    tracker = VisionTracker(FIELD, PARAMS)
    last_ball = -math.inf
    last_robot: dict = {}
    for cam, t, balls, robots in stream:
        ball, poses = tracker.frame(cam, t, balls, robots)
        if ball is not None:
            assert math.isfinite(ball.x_m) and math.isfinite(ball.y_m) and ball.t_s > last_ball
            last_ball = ball.t_s
        for p in poses:
            assert math.isfinite(p.x_m) and math.isfinite(p.y_m)
            assert p.t_s > last_robot.get((p.team, p.robot_id), -math.inf)
            last_robot[(p.team, p.robot_id)] = p.t_s
