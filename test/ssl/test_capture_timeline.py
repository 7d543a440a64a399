"""The capture timeline (time_source: capture) on synthetic camera streams whose numbers are written out here.

A world runs at ``rate`` world seconds per receiver second. Camera c captures every 1/60 s of world time
(phase ``phase_c``) and reads it on its own clock, ``t_capture = world + clock_c``; it sends 4 ms of world
time later, and the datagram arrives 1 ms of wall time after that (the same delay for every camera). The
first camera to arrive founds the timeline, so every camera's frames belong at ``world + clock_founder``.
"""

from __future__ import annotations

import math
from itertools import pairwise

import numpy as np
import pytest

from erforce_ball_model.ball_model import BallModelParams
from erforce_ball_model.predictor import BallPredictor, PredictorConfig
from erforce_interfaces.ssl.vision_time import CaptureTimeline, ClockJump, PaceCheck, VisionClock

PERIOD_S = 1.0 / 60.0
LATENCY_S = 0.004  # capture to send, world time
DELAY_S = 0.001  # send to receive, wall time
PHASES_S = (0.0, 0.004, 0.009, 0.013)


def frames(rate: float, clocks: tuple[float, ...], world_from: float, world_to: float, wall_at_world_from: float):
    """(wall, camera, t_capture, t_sent, world capture time) of every camera's frames captured in
    [world_from, world_to), in order of arrival."""
    out = []
    for camera, (clock, phase) in enumerate(zip(clocks, PHASES_S, strict=True)):
        k = math.ceil((world_from - phase) / PERIOD_S - 1e-9)
        while (world := k * PERIOD_S + phase) < world_to:
            wall = wall_at_world_from + (world + LATENCY_S - world_from) / rate + DELAY_S
            out.append((wall, camera, world + clock, world + LATENCY_S + clock, world))
            k += 1
    return sorted(out)


def run(timeline: CaptureTimeline, stream) -> list[tuple[int, float, float, float]]:
    """(camera, world time, t_capture, stamp) of the accepted frames; checks the timeline's now as it goes."""
    accepted, newest = [], -math.inf
    for wall, camera, t_capture, t_sent, world in stream:
        try:
            stamp = timeline.stamp(camera, t_capture, t_sent, wall)
        except ClockJump:
            stamp = None
        now = timeline.newest_s
        assert now is not None and math.isfinite(now) and now >= newest  # what /clock says never goes back
        newest = now
        if stamp is not None:
            accepted.append((camera, world, t_capture, stamp))
    return accepted


def check_cameras(accepted, founder_clock: float, settled_after: float, tolerance_s: float = 1e-6) -> None:
    """Per camera: stamps strictly increase; once calibrated (world time after ``settled_after``), each lies
    at world + founder's clock, so consecutive stamps are as far apart as the captures (on one line of the
    camera's clock: apart as far as in world time)."""
    by_camera: dict[int, list] = {}
    for camera, world, t_capture, stamp in accepted:
        by_camera.setdefault(camera, []).append((world, t_capture, stamp))
    for camera, rows in by_camera.items():
        for (w0, t0, s0), (w1, t1, s1) in pairwise(rows):
            assert s1 > s0, camera
            if w1 > settled_after and t1 - t0 == pytest.approx(w1 - w0, abs=1e-9):
                assert s1 - s0 == pytest.approx(t1 - t0, abs=tolerance_s), camera
        for world, _, stamp in rows:
            if world > settled_after:
                assert stamp == pytest.approx(world + founder_clock, abs=tolerance_s), (camera, world)


@pytest.mark.parametrize("rate", [0.6, 2.0])
def test_four_cameras_with_their_own_clocks_land_on_one_timeline(rate):
    clocks = (100.0, 100.3, 98.8, 100.0)  # cameras 0 and 3 share a clock; 1 and 2 do not
    timeline = CaptureTimeline()
    accepted = run(timeline, frames(rate, clocks, 0.0, 3.0, 50.0))
    assert len(accepted) == 4 * 180  # nothing refused
    assert accepted[0][3] == 100.0  # camera 0 arrives first: its clock is the timeline's
    check_cameras(accepted, 100.0, settled_after=1.0)
    assert [timeline.offset_s(c) for c in range(4)] == pytest.approx([0.0, -0.3, 1.2, 0.0], abs=1e-6)
    assert timeline.offset_s(3) == 0.0  # the same clock as camera 0: its offset exactly
    assert timeline.newest_s == pytest.approx(100.0 + 179 * PERIOD_S + PHASES_S[3])


@pytest.mark.parametrize("rate", [0.6, 2.0])
def test_a_gap_of_three_seconds_moves_the_timeline_by_the_capture_time(rate):
    clocks = (100.0, 100.3, 98.8, 100.0)
    timeline = CaptureTimeline()
    before = run(timeline, frames(rate, clocks, 0.0, 2.0, 50.0))
    held = timeline.newest_s
    wall_end = 50.0 + 2.0 / rate
    # vision stops for 3 s of wall time; the world runs on meanwhile (rate * 3 s)
    after = run(timeline, frames(rate, clocks, 2.0 + 3.0 * rate, 4.0 + 3.0 * rate, wall_end + 3.0))
    assert len(after) == 4 * 120  # nothing refused after the gap
    check_cameras(before + after, 100.0, settled_after=1.0)
    # the last frame before: camera 3's at 119 / 60 + 0.013 s; the first after: camera 0's at 2 + 3 rate
    # (a whole number of periods at both rates)
    assert after[0][3] - held == pytest.approx(2.0 + 3.0 * rate - (119 * PERIOD_S + PHASES_S[3]), abs=1e-9)


def test_a_paused_world_holds_the_timeline():
    clocks = (100.0, 100.0, 100.0, 100.0)
    timeline = CaptureTimeline()
    before = run(timeline, frames(1.0, clocks, 0.0, 1.0, 50.0))
    after = run(timeline, frames(1.0, clocks, 1.0, 2.0, 61.0))  # 10 s of wall time, no world time
    check_cameras(before + after, 100.0, settled_after=0.0)
    assert after[0][3] - before[-1][3] == pytest.approx(PHASES_S[0] + PERIOD_S - PHASES_S[3])


def test_a_camera_clock_stepping_back_a_little_drops_frames_until_it_passes_its_last():
    timeline = CaptureTimeline()
    for k in range(10):
        assert timeline.stamp(0, 5.0 + 0.01 * k, 5.0 + 0.01 * k, 1.0 + 0.01 * k) == pytest.approx(5.0 + 0.01 * k)
    # the clock steps back by 25 ms: 4.985, 4.995 are not after 5.09 ... 5.005 is
    with pytest.raises(ClockJump, match="before the camera.s newest frame"):
        timeline.stamp(0, 5.1 - 0.025, 5.1 - 0.025, 1.1)
    with pytest.raises(ClockJump):
        timeline.stamp(0, 5.09 - 0.0, 5.09, 1.11)  # a repeat
    assert timeline.stamp(0, 5.095, 5.095, 1.12) == pytest.approx(5.095)  # 5 ms after the last stamp
    assert timeline.jumps_confirmed == 0


@pytest.mark.parametrize("step_s", [-7.0, 40.0])
def test_one_camera_clock_jumping_is_measured_again_once_confirmed(step_s):
    clocks = (100.0, 100.3, 98.8, 100.0)
    rate = 0.6
    timeline = CaptureTimeline()
    accepted = run(timeline, frames(rate, clocks, 0.0, 2.0, 50.0))
    jumped = list(clocks)
    jumped[2] += step_s
    stream = frames(rate, tuple(jumped), 2.0, 5.0, 50.0 + 2.0 / rate)
    later = run(timeline, stream)
    refused = [f for f in stream if f[1] == 2 and not any(a[0] == 2 and a[1] == f[4] for a in later)]
    # refused until 5 frames over 0.2 s of receive time: the world's 0.6x makes that 0.12 s of camera 2's
    # frames, 8 frames (the 5th spans 4 / 60 / 0.6 = 0.11 s)
    assert len(refused) == 8
    assert timeline.jumps_confirmed == 1
    assert timeline.offset_s(2) == pytest.approx(1.2 - step_s, abs=1e-6)
    check_cameras(accepted + later, 100.0, settled_after=1.0)


def test_a_restarted_simulator_continues_the_timeline_once_confirmed():
    """Every camera's clock starts again at 0: the timeline goes on one frame after its newest stamp, and the
    cameras share the new line's offset."""
    rate = 2.0
    clocks = (50.0, 50.0, 50.0, 50.0)
    timeline = CaptureTimeline()
    before = run(timeline, frames(rate, clocks, 0.0, 1.0, 10.0))
    newest = timeline.newest_s
    restarted = (-1.0, -1.0, -1.0, -1.0)  # world 1.0 reads 0.0: the simulator's clock starts at 0
    after = run(timeline, frames(rate, restarted, 1.0, 4.0, 10.0 + 1.0 / rate))
    assert timeline.jumps_confirmed == 4
    # the first camera to confirm (5 frames spanning 0.2 s of wall time, 0.4 s of world time at 2x) has no
    # other camera free of a suspected jump: its line's first frame (at its phase) lands one period after the
    # newest stamp, and the other cameras, measured against it, share its offset
    first = after[0]
    new_offset = newest + PERIOD_S - PHASES_S[first[0]]
    assert first[2] >= 0.4 and first[3] == pytest.approx(first[2] + new_offset, abs=1e-9)
    assert [timeline.offset_s(c) for c in range(4)] == pytest.approx([new_offset] * 4, abs=1e-9)
    check_cameras(after, new_offset - 1.0, settled_after=2.5)  # t_capture = world - 1
    check_cameras(before, 50.0, settled_after=0.6)  # 30 frames calibrate


def test_wrong_settings_are_named():
    with pytest.raises(ValueError, match="CaptureTimeline"):
        CaptureTimeline(jump_s=0.0)
    with pytest.raises(ValueError, match="camera_id"):
        CaptureTimeline().stamp(40, 1.0, 1.0, 1.0)


@pytest.mark.parametrize("rate", [0.6, 2.0])
def test_the_ball_after_a_gap_starts_from_where_it_is(rate):
    """A ball rolling at 1.5 m/s (rolling deceleration a_roll) is seen by one camera, vision stops for 3 s of
    wall time and resumes: the ball's state from the first frames after the gap lies within the vision noise
    of the true ball, stopped by then (1.5 / 0.3 = 5 s of rolling: at 0.6x it still rolls)."""
    a_roll = BallModelParams().a_roll_mps2
    v0 = 1.5

    def truth(t):  # rolling since t = 0 from x = -3 along +x: x = -3 + v0 t + a t^2 / 2 until it stops
        t = min(t, -v0 / a_roll)
        return -3.0 + v0 * t + 0.5 * a_roll * t * t, v0 + a_roll * t

    timeline = CaptureTimeline()
    predictor = BallPredictor(PredictorConfig(num_robots=1))
    stream = [f for f in frames(rate, (7.0,) * 4, 0.0, 1.0, 20.0) if f[1] == 0]
    stream += [f for f in frames(rate, (7.0,) * 4, 1.0 + 3.0 * rate, 1.5 + 3.0 * rate, 20.0 + 1.0 / rate + 3.0)
               if f[1] == 0]
    last = None
    for wall, camera, t_capture, t_sent, world in stream:
        stamp = timeline.stamp(camera, t_capture, t_sent, wall)
        x, _ = truth(world)
        frame = predictor.ball_frame(stamp, x, 0.0)
        if frame is not None:
            last = (world, frame)
    world, frame = last
    x_true, v_true = truth(world)
    state = frame.trajectory.floats
    assert abs(state.x_m - x_true) <= 0.01 and abs(state.y_m) <= 0.01
    assert abs(state.speed_mps - v_true) <= 0.05


@pytest.mark.parametrize("rate", [0.62, 0.98])
def test_a_world_not_paced_to_the_wall_clock_steps_the_estimate_and_not_the_timeline(rate):
    """grSim's t_capture is its simulated time. The estimate (VisionClock) maps it onto the wall clock: over 60 s
    of wall time its stamps span 60 s while the world moved 60 rate s (speeds come out scaled by the rate), and
    at 0.62x its offset, drifting by 0.38 s a second, catches up in steps of more than jump_s (0.25 s) between
    consecutive frames; PaceCheck names the pace. The timeline's stamps span the world's time, consecutive ones
    1/60 s apart."""
    clock, timeline, pace = VisionClock(), CaptureTimeline(), PaceCheck(0.3)
    stream = [f for f in frames(rate, (0.0,) * 4, 0.0, 60.0 * rate, 1000.0) if f[1] == 0]
    estimate, captured, texts = [], [], []
    for wall, camera, t_capture, t_sent, _world in stream:
        try:
            estimate.append(clock.to_receiver(camera, t_capture, t_sent, wall))
        except ClockJump:
            pass
        captured.append(timeline.stamp(camera, t_capture, t_sent, wall))
        if len(captured) % 600 == 0:  # every 10 s of wall time, as the bridge's statistics
            texts.append(pace.check(camera, clock.offset_s(camera), wall))
    wall_span, world_span = stream[-1][0] - stream[0][0], stream[-1][4] - stream[0][4]
    assert estimate[-1] - estimate[0] == pytest.approx(wall_span, abs=0.35)
    assert (np.diff(estimate).max() > 0.25) == (rate == 0.62)
    assert captured[-1] - captured[0] == pytest.approx(world_span, abs=1e-9)
    assert np.diff(captured) == pytest.approx(PERIOD_S, abs=1e-9)
    assert texts[-1] is not None and f"runs at {rate:.2f}x" in texts[-1]


def test_a_vision_host_paced_like_us_is_not_named():
    """A real vision host: its clock 1.7e9 s away, 20 ppm fast, the network's delay jittering by up to 3 ms."""
    clock, pace = VisionClock(), PaceCheck(0.3)
    rng = np.random.default_rng(1)
    texts = []
    for k in range(60 * 60):
        t_capture = 1.7e9 + k * PERIOD_S * (1 + 20e-6)
        wall = 5.0 + k * PERIOD_S + LATENCY_S + DELAY_S + rng.uniform(0.0, 0.003)
        clock.to_receiver(0, t_capture, t_capture + LATENCY_S, wall)
        if k % 600 == 599:
            texts.append(pace.check(0, clock.offset_s(0), wall))
    assert texts == [None] * 6


def test_the_ball_stopped_during_a_short_gap_is_not_extrapolated_past_it():
    """A ball rolling at 2 m/s along +x, seen at 60 Hz; vision stops for 0.5 s (less than max_gap_s), during
    which a robot stops the ball 0.3 m further on, about 0.7 m short of where the old motion would have taken
    it. The first frame after the gap, outside the filter's gate, gets no estimate (not the old motion carried
    over the gap); from the second on, the state starts where the ball is, at rest."""
    timeline = CaptureTimeline()
    predictor = BallPredictor(PredictorConfig(num_robots=1))
    x = -3.0
    for k in range(30):  # 0.5 s at 2 m/s (the rolling deceleration left out of the truth: a hand-pushed ball)
        stamp = timeline.stamp(0, 10.0 + k * PERIOD_S, 10.0 + k * PERIOD_S, 100.0 + k * PERIOD_S)
        x = -3.0 + 2.0 * k * PERIOD_S
        predictor.ball_frame(stamp, x, 0.0)
    stopped_at = x + 0.3
    answers = []
    for k in range(60, 64):  # 0.5 s later
        stamp = timeline.stamp(0, 10.0 + k * PERIOD_S, 10.0 + k * PERIOD_S, 100.0 + k * PERIOD_S)
        answers.append(predictor.ball_frame(stamp, stopped_at, 0.0))
    assert answers[0] is None
    for frame in answers[1:]:
        state = frame.trajectory.floats
        assert abs(state.x_m - stopped_at) <= 0.01 and state.speed_mps <= 0.1
