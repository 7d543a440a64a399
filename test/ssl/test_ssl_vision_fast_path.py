"""erforce_ball_model.vision_fast_path: the compiled pass from a datagram's bytes to /vision/robots' bytes agrees
with the general path (decode_wrapper, VisionClock, VisionTracker.frame_indices, the points,
vision_robots_points_cdr) on every datagram of a long, eventful stream, byte for byte, with the camera alignment
(cameras with known offsets) and without; and it hands back, untouched, whatever it does not take (garbage,
truncations, absurd counts, NaN and huge coordinates), never crashing or writing non-finite values. With cameras
that agree, the alignment moves what the bridge publishes by no more than its estimate's uncertainty."""

from __future__ import annotations

import math
import random

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from erforce_ball_model.ball_model import BallModelParams
from erforce_ball_model.camera_alignment import CameraAlignment
from erforce_ball_model.vision_fast_path import (
    PASS_BAD_STAMP,
    PASS_CLOCK_JUMP,
    PASS_DONE,
    PASS_FALLBACK,
    PASS_GENERAL,
    PASS_T_CAPTURE_BACK,
    PASS_TIMELINE_JUMP,
    FramePass,
    camera_table,
    frame_points,
)
from erforce_ball_model.vision_tracking import BALL_SIGHTING, BALL_UPDATE, MAX_ROBOT_ID, VisionTracker
from erforce_interfaces.ssl.ssl_proto import ssl_vision_wrapper_pb2 as wrap
from erforce_interfaces.ssl.ssl_vision import (
    BallCandidate,
    CameraFrame,
    FieldGeometry,
    RobotSighting,
    SslDecodeError,
    decode_wrapper,
    encode_frame,
    encode_geometry,
)
from erforce_interfaces.ssl.vision_time import (
    CAPTURE_OLD,
    CAPTURE_RESTART,
    TIME_CAPTURE,
    TIME_ESTIMATE,
    CaptureOrder,
    CaptureTimeline,
    ClockJump,
    VisionClock,
)
from erforce_interfaces.wire import contract
from erforce_interfaces.wire.clouds import vision_cloud_from_msg, vision_frame_from_msg, vision_robots_points_cdr
from erforce_interfaces.wire.robot_config import FieldConfig

FIELD = FieldConfig.preset("division_a")
OURS, N_OURS = 0.0, 11  # blue


class Pipeline:
    """A clock, a capture order, a capture timeline and a tracker as the bridge holds them, with pose reader counts
    by side and id; stamps from the time source ``mode``."""

    def __init__(self, mode: int = TIME_ESTIMATE, model: BallModelParams | None = None, align: bool = False) -> None:
        self.mode = mode
        self.alignment = CameraAlignment() if align else None
        self.clock = VisionClock()
        self.timeline = CaptureTimeline(self.clock.jump_s)
        self.order = CaptureOrder(self.clock.jump_s)
        self.restarts = 0
        self.tracker = VisionTracker(FIELD, model)
        self.readers = np.zeros((2, MAX_ROBOT_ID + 1), np.int64)
        self.points = np.empty((66, 6))
        # the geometry knows cameras 4-7 (4 m above their rectangles of eventful_stream, where the ball goes), not 0-3
        self.cameras = camera_table()
        for cam in range(4, 8):
            self.cameras[cam, :4] = 1.0, -6.25 + 3.125 * (cam - 4 + 0.5), 2.375, 4.0


def general_path(p: Pipeline, data: bytes, t_receive: float):
    """What the bridge's general path publishes for a datagram: ("bad" | "t_capture_back" | "jump" | "stamp" |
    "nothing"), the message bytes, or ("general", robot rows, balls) for the node's per-robot path; and the ball
    observation."""
    try:
        packet = decode_wrapper(data)
    except SslDecodeError:
        return "bad", None
    if packet.geometry is not None:
        p.tracker.field = FieldConfig(packet.geometry.length_m, packet.geometry.width_m, packet.geometry.boundary_m)
    frame = packet.detection
    if frame is None:
        return "nothing", None
    verdict, _back_s = p.order.take(frame.camera_id, frame.t_capture_s)
    if verdict == CAPTURE_OLD:
        return "t_capture_back", None
    p.restarts += verdict == CAPTURE_RESTART
    try:
        if p.mode == TIME_CAPTURE:
            t_s = p.timeline.stamp(frame.camera_id, frame.t_capture_s, frame.t_sent_s, t_receive)
        else:
            t_s = p.clock.to_receiver(frame.camera_id, frame.t_capture_s, frame.t_sent_s, t_receive)
    except ClockJump as exc:  # the timeline's old frame is a t_capture_back as the order's
        return ("t_capture_back" if exc.kind == "t_capture_back" else "jump"), None
    if not (math.isfinite(t_s) and t_s >= 0.0):
        return "stamp", None
    balls, robots = frame.balls, frame.robots
    if p.alignment is not None:
        balls, robots = p.alignment.take(frame.camera_id, frame.t_capture_s, balls, robots)
    ball, used = p.tracker.frame_indices(frame.camera_id, t_s, balls, robots)
    if not len(used) and ball is None:
        return "nothing", ball
    action = 0 if ball is None else BALL_SIGHTING if ball.sighting else BALL_UPDATE
    n = frame_points(robots, used, OURS, N_OURS, p.readers, p.points, p.cameras[frame.camera_id], action,
                     ball.x_m if action else 0.0, ball.y_m if action else 0.0)
    if n < 0:
        return ("general", robots[used].tolist(), ball), ball
    if n == 0:
        return "nothing", ball
    return vision_robots_points_cdr(t_s, p.points[:n]), ball


def compiled_path(p: Pipeline, fp: FramePass, data: bytes, t_receive: float):
    """The same through the pass, finished as the bridge finishes it (ball filter, general path)."""
    status, n_bytes, action, t_s, ball_x, ball_y = fp.run(data, t_receive, p.mode)
    if status == PASS_FALLBACK:
        return general_path(p, data, t_receive)
    if status == PASS_T_CAPTURE_BACK:
        return "t_capture_back", None
    if status in (PASS_CLOCK_JUMP, PASS_TIMELINE_JUMP):
        return "jump", None
    if status == PASS_BAD_STAMP:
        return "stamp", None
    camera_id = int(fp.info[0])
    ball = p.tracker.use_ball(action, camera_id, t_s, ball_x, ball_y) if action else None
    if status == PASS_GENERAL:
        return ("general", fp.robots()[fp.used()].tolist(), ball), ball
    assert status == PASS_DONE
    n_points = int(fp.info[3])
    if action and ball is None:  # the ball written after the camera's point, if any: the frame without it
        at = int(n_points > 0 and fp.points[0, 4] == contract.VISION_CAMERA_CODE)
        points = np.delete(fp.points[:n_points], at, axis=0)
        return (vision_robots_points_cdr(t_s, points) if n_points > at + 1 else "nothing"), None
    if n_bytes == 0:
        return "nothing", ball
    assert n_bytes > 0
    return fp.message_view[:n_bytes].tobytes(), ball


def eventful_stream(seed: int = 3, duration_s: float = 4.0, step_back_s: float = 0.0, offsets_m=None,
                    robot_noise_m: float = 0.0, camera_phase_s: float = 0.0017) -> list[tuple[bytes, float]]:
    """(datagram, receive time) of 8 cameras at 75 Hz: 22 robots, the ball kicked, out into the run-off area and
    put down elsewhere, reflections, robots without orientation or beyond our ids, duplicate ids, a camera's
    clock jumping forward, another's starting again, frames out of order, the same frame twice, a frame with more
    ball candidates than a frame keeps, garbage and a geometry packet; with ``step_back_s`` camera 6's clock goes
    back by that much for 0.5 s (t_capture and t_sent). ``offsets_m``: by camera, (x, y) it adds to everything it
    reports; ``robot_noise_m``: each camera's Gaussian noise on its robots; camera k captures ``k camera_phase_s``
    after camera 0."""
    rng = random.Random(seed)
    centres = [(rng.uniform(-5.0, 5.0), rng.uniform(-3.8, 3.8)) for _ in range(22)]
    out = []
    events = sorted((cam * camera_phase_s + k / 75.0, cam) for cam in range(8) for k in range(int(duration_s * 75)))
    for n, (t, cam) in enumerate(events):
        col, row = cam % 4, cam // 4
        x0, y0 = -6.25 + col * 3.125 - 0.3, -4.75 + row * 4.75 - 0.3
        x1, y1 = x0 + 3.125 + 0.6, y0 + 4.75 + 0.6
        if t < 1.0:
            ball = (-4.0 + 0.5 * t, 1.0)
        elif t < 2.0:
            ball = (-3.5 + 5.0 * (t - 1.0), 1.0 + 1.0 * (t - 1.0))  # kicked
        elif t < 2.6:
            ball = (1.5 + 2.0 * (t - 2.0), 2.0 + 5.0 * (t - 2.0))  # out over the side line
        else:
            ball = (-2.0, -2.0)  # put down elsewhere
        balls = []
        if x0 <= ball[0] <= x1 and y0 <= ball[1] <= y1 and n % 17:
            balls.append(BallCandidate(ball[0] + rng.gauss(0, 0.002), ball[1] + rng.gauss(0, 0.002), 0.9))
        for _ in range(n % 3):
            balls.append(BallCandidate(rng.uniform(x0, x1), rng.uniform(y0, y1), rng.choice((0.01, 0.3))))
        robots = []
        for k in range(22):
            team, rid = ("blue", k) if k < 11 else ("yellow", k - 11)
            cx, cy = centres[k]
            x, y = cx + 0.5 * math.cos(t + k), cy + 0.5 * math.sin(t + k)
            if x0 <= x <= x1 and y0 <= y <= y1:
                theta = None if (n + k) % 41 == 0 else math.remainder(t + k, 2 * math.pi)
                if robot_noise_m:
                    x, y = x + rng.gauss(0.0, robot_noise_m), y + rng.gauss(0.0, robot_noise_m)
                robots.append(RobotSighting(team, rid, x, y, theta, 1.0))
        if n % 29 == 0:
            robots.append(RobotSighting("blue", 12 + n % 5, 0.1, 0.2, 0.3, 1.0))  # beyond num_robots
        if n % 31 == 0 and robots:
            r = robots[0]
            robots.append(r._replace(x_m=r.x_m + 0.05))  # a duplicate id
        if n % 211 == 0:  # more candidates than a frame keeps: the first 32 count, the robots too
            balls += [BallCandidate(rng.uniform(x0, x1), rng.uniform(y0, y1), 0.3) for _ in range(40)]
        if offsets_m is not None:
            ox, oy = offsets_m[cam]
            balls = [b._replace(x_m=b.x_m + ox, y_m=b.y_m + oy) for b in balls]
            robots = [r._replace(x_m=r.x_m + ox, y_m=r.y_m + oy) for r in robots]
        t_capture = 100.0 + t
        t_sent = t_capture + 0.004
        if cam == 2 and 1.5 <= t < 2.5:
            t_sent -= 1.0  # the camera's clock jumps (refused until confirmed)
        if cam == 5 and t >= 3.0:  # the camera's clock starts again from 90 s
            t_capture, t_sent = t_capture - 10.0, t_sent - 10.0
        if cam == 6 and 3.0 <= t < 3.5:
            t_capture, t_sent = t_capture - step_back_s, t_sent - step_back_s
        t_receive = 1.7e9 + t + 0.004 + rng.uniform(0.0, 0.003)
        data = encode_frame(CameraFrame(cam, n, t_capture, t_sent, tuple(balls), tuple(robots)))
        out.append((data, t_receive))
        if n % 43 == 0:  # the same frame again
            out.append((data, t_receive + 0.001))
        if n % 97 == 0:
            out.append((data[: len(data) // 2], t_receive))
        if n % 101 == 0:
            out.append((bytes(rng.randrange(256) for _ in range(40)), t_receive))
        if n == 700:
            out.append((encode_geometry(FieldGeometry(12.0, 9.0, 0.3, 1.8, 0.18)), t_receive))
    for k in range(0, len(out) - 3, 11):  # some datagrams overtake each other
        out[k], out[k + 2] = out[k + 2], out[k]
    return out


# each camera's offset: 1-3 cm in every direction (a calibration's error), zero mean over the eight
CAMERA_OFFSETS_M = {cam: (0.02 * math.cos(0.8 * cam) + 0.01 * (cam % 2), 0.02 * math.sin(0.8 * cam) - 0.01)
                    for cam in range(8)}
_MEAN_OFFSET_M = np.mean(list(CAMERA_OFFSETS_M.values()), axis=0)
CAMERA_OFFSETS_M = {cam: (o[0] - _MEAN_OFFSET_M[0], o[1] - _MEAN_OFFSET_M[1]) for cam, o in CAMERA_OFFSETS_M.items()}


def bound_pass(p: Pipeline) -> FramePass:
    return FramePass(p.clock, p.tracker, p.readers, OURS, N_OURS, p.order, timeline=p.timeline, cameras=p.cameras,
                     alignment=p.alignment)


@pytest.mark.parametrize(("mode", "align"), [(TIME_ESTIMATE, False), (TIME_CAPTURE, False), (TIME_ESTIMATE, True),
                                             (TIME_CAPTURE, True)])
def test_the_pass_gives_the_general_paths_bytes_and_balls_on_an_eventful_stream(mode, align):
    """With ``align`` the cameras report everything off by CAMERA_OFFSETS_M: both paths learn the same offsets (the
    same arrays at the end, close to the true ones) and publish the same corrected bytes."""
    general, compiled = Pipeline(mode, align=align), Pipeline(mode, align=align)
    fp = bound_pass(compiled)
    outcomes = set()
    stream = eventful_stream(step_back_s=2.0 if mode == TIME_CAPTURE else 0.0,
                             offsets_m=CAMERA_OFFSETS_M if align else None)
    for k, (data, t_receive) in enumerate(stream):
        if k == 1500:  # a tool subscribes to one of our robots' vision_pose: its frames take the general path
            general.readers[0, 4] = compiled.readers[0, 4] = 1
        want, want_ball = general_path(general, data, t_receive)
        got, got_ball = compiled_path(compiled, fp, data, t_receive)
        assert got == want or repr(got) == repr(want), k  # repr: NaN (no orientation) equals NaN
        assert got_ball == want_ball, k
        outcomes.add(want if isinstance(want, str) else "general" if isinstance(want, tuple) else
                     "ball" if want_ball is not None else "robots")
        if isinstance(got, bytes):
            cloud = vision_cloud_from_msg(got)
            assert np.isfinite(cloud.balls).all() and np.isfinite(cloud.robots).all()
            # a camera the geometry knows names itself; its sighting of an instant taken comes only with it
            camera_id = decode_wrapper(data).detection.camera_id
            assert cloud.camera_id == (camera_id if camera_id >= 4 else None), k
            if len(cloud.sightings):
                outcomes.add("sighting")
                assert want_ball.sighting and cloud.sightings.tolist() == [[want_ball.x_m, want_ball.y_m]], k
    assert outcomes == {"bad", "t_capture_back", "jump", "nothing", "general", "ball", "robots", "sighting"}
    # camera 5's restart (and camera 6's step back with the timeline): passed on by the order, once each
    assert general.restarts == compiled.restarts == (1 if mode == TIME_ESTIMATE else 2)
    for name in ("frames", "late_balls", "false_candidates", "switches", "kicks"):
        assert getattr(compiled.tracker, name) == getattr(general.tracker, name), name
    assert general.tracker.switches >= 1 and general.tracker.late_balls >= 1
    if mode == TIME_ESTIMATE:  # camera 2's t_sent: the jump and the way back; camera 5's restart: each confirmed
        assert general.clock.jumps_confirmed == compiled.clock.jumps_confirmed == 3
    else:  # camera 5's restart; camera 6's clock back and forward again: each confirmed
        assert general.timeline.jumps_confirmed == compiled.timeline.jumps_confirmed == 3
        assert np.array_equal(general.timeline.cams, compiled.timeline.cams, equal_nan=True)
    if align:
        for a, b in zip(general.alignment.state(), compiled.alignment.state(), strict=True):
            assert np.array_equal(a, b, equal_nan=True)
        assert np.array_equal(general.alignment.offsets, compiled.alignment.offsets)
        # only differences are observable, within each set of cameras that share robots: the stream's are 0-1, 2-3
        # and 4-5-6-7; SSL's 1 mm steps, robots moving up to 0.85 mm between two cameras' captures
        paired = [(a, b) for a in range(8) for b in range(a + 1, 8) if compiled.alignment.samples(a, b) > 50]
        assert paired == [(0, 1), (2, 3), (4, 5), (5, 6), (6, 7)]
        for a, b in paired:
            want = np.subtract(CAMERA_OFFSETS_M[a], CAMERA_OFFSETS_M[b])
            got = np.subtract(compiled.alignment.offset_m(a), compiled.alignment.offset_m(b))
            assert np.all(np.abs(got - want) <= 2e-3), (a, b, got, want)


def test_with_cameras_that_agree_the_alignment_moves_what_is_published_by_no_more_than_its_uncertainty():
    """No offsets (our plant, grSim: every camera at one capture), each camera's robots with ER-Force's 1.3 mm noise:
    every robot and ball the aligned pass publishes lies within 4 standard deviations of the estimate (its stated
    uncertainty per axis for that camera) of what the pass without the alignment publishes from the same datagrams,
    with the same robots, once 0.2 s of captures are in (before, the stated uncertainty rests on a dozen
    differences' spread); at the end every camera's offset is within 4 of its standard deviations of zero."""
    raw, aligned = Pipeline(), Pipeline(align=True)
    passes = [bound_pass(p) for p in (raw, aligned)]
    compared = 0
    for data, t_receive in eventful_stream(robot_noise_m=0.0013, camera_phase_s=0.0):
        got = [compiled_path(p, fp, data, t_receive)[0] for p, fp in zip((raw, aligned), passes, strict=True)]
        if not isinstance(got[0], bytes):
            assert type(got[1]) is type(got[0])
            continue
        clouds = [vision_cloud_from_msg(g) for g in got]
        sd_m = aligned.alignment.uncertainty_m(decode_wrapper(data).detection.camera_id)  # of the offset taken off
        if t_receive < 1.7e9 + 0.2:
            continue
        assert np.array_equal(clouds[0].robots[:, :2], clouds[1].robots[:, :2])  # the same robots
        for a, b in ((clouds[0].robots[:, 2:4], clouds[1].robots[:, 2:4]), (clouds[0].balls, clouds[1].balls),
                     (clouds[0].sightings, clouds[1].sightings)):
            assert a.shape == b.shape
            moved_m = np.abs(a - b).max(initial=0.0)
            assert moved_m <= 4.0 * sd_m, (moved_m, sd_m)  # sd_m inf: a pair of one difference
        compared += 1
    assert compared > 1500
    for cam in range(8):
        sd_m = aligned.alignment.uncertainty_m(cam)
        assert sd_m < 3e-4 and np.all(np.abs(aligned.alignment.offset_m(cam)) <= 4.0 * sd_m), cam


def kick_stream(v0_mps: float, a_slide: float, a_roll: float, c_switch: float, seed: int = 4):
    """(datagram, receive time) of one camera at 70 Hz: a ball at rest at (-5, 0.3) for 0.5 s, then kicked along +x
    at ``v0_mps`` (the two-phase model's kinematics written out here: slide down to c_switch v0, then roll), 2 mm
    noise; and the index of the first datagram after the kick."""
    rng = random.Random(seed)
    t_kick, v_switch = 100.5, c_switch * v0_mps
    t_switch = (v0_mps - v_switch) / a_slide
    out = []
    for k in range(110):
        t = 100.0 + (k + 0.3) / 70.0
        tau = max(t - t_kick, 0.0)
        slide = min(tau, t_switch)
        roll = min(tau - slide, v_switch / a_roll)
        x = -5.0 + v0_mps * slide - 0.5 * a_slide * slide**2 + v_switch * roll - 0.5 * a_roll * roll**2
        ball = BallCandidate(x + rng.gauss(0.0, 0.002), 0.3 + rng.gauss(0.0, 0.002), 0.9)
        out.append((encode_frame(CameraFrame(0, k, t, t + 0.004, (ball,), ())), 1.7e9 + t + 0.005))
    return out, math.ceil((t_kick - 100.0) * 70.0 - 0.3)


def test_the_pass_filters_with_a_model_set_on_its_tracker_as_with_one_it_started_with():
    # The bridge sets the tracker's model from SSL geometry (grSim's here) while the compiled pass holds the filter's
    # arrays: from the change on, the pass filters as one built with that model (test_predictor derives the
    # tolerances: the two only differ by their estimates of the ball at rest before the kick).
    model = BallModelParams(-14.0, -0.7, 0.7)
    stream, first_kicked = kick_stream(3.0, 14.0, 0.7, 0.7)
    pinned, changed = Pipeline(model=model), Pipeline()
    passes = [FramePass(p.clock, p.tracker, p.readers, OURS, N_OURS, p.order) for p in (pinned, changed)]
    compared = 0
    for k, (data, t_receive) in enumerate(stream):
        if k == 17:  # half-way through the rest: the geometry packet arrives
            changed.tracker.params = model
        balls = [compiled_path(p, fp, data, t_receive)[1] for p, fp in zip((pinned, changed), passes, strict=True)]
        assert (balls[0] is None) == (balls[1] is None), k
        if balls[0] is not None and k >= first_kicked:
            want, got = (p.tracker.ball.trajectory() for p in (pinned, changed))
            assert abs(got.v_shoot_mps - want.v_shoot_mps) < 1e-5, k
            assert np.hypot(*(got.stop_point - want.stop_point)) < 1e-4, k
            compared += 1
    assert changed.tracker.params == model and compared > 60


def _detection(balls, robots, t_capture=100.0, camera_id=2) -> bytes:
    packet = wrap.SSL_WrapperPacket()
    det = packet.detection
    det.frame_number, det.t_capture, det.t_sent, det.camera_id = 7, t_capture, t_capture + 0.01, camera_id
    for x, y, c in balls:
        det.balls.add(confidence=c, x=x, y=y, pixel_x=0.0, pixel_y=0.0)
    for team, rid, x, y, theta in robots:
        r = (det.robots_blue if team == "blue" else det.robots_yellow).add(confidence=1.0, x=x, y=y, pixel_x=0.0,
                                                                           pixel_y=0.0)
        if rid is not None:
            r.robot_id = rid
        if theta is not None:
            r.orientation = theta
    return packet.SerializeToString()


floats = st.floats(allow_nan=True, allow_infinity=True, width=32)
fresh = Pipeline(align=True)
fresh_pass = FramePass(fresh.clock, fresh.tracker, fresh.readers, OURS, N_OURS, fresh.order,
                       alignment=fresh.alignment)


@settings(max_examples=300, deadline=None)
@given(
    balls=st.lists(st.tuples(floats, floats, floats), max_size=40),
    robots=st.lists(st.tuples(st.sampled_from(["blue", "yellow"]), st.one_of(st.none(), st.integers(0, 2**32 - 1)),
                              floats, floats, st.one_of(st.none(), floats)), max_size=70),
    t_capture=st.floats(allow_nan=True, allow_infinity=True),
    camera_id=st.integers(0, 2**32 - 1),
    cut=st.integers(0, 10_000),
    edit=st.tuples(st.integers(0, 10_000), st.integers(0, 255)),
)
def test_fuzz_what_the_pass_takes_is_valid_and_the_rest_is_handed_back_untouched(balls, robots, t_capture,
                                                                                    camera_id, cut, edit):
    data = _detection(balls, robots, t_capture, camera_id)
    edited = bytearray(data)
    edited[edit[0] % len(edited)] = edit[1]
    for chunk in (data, data[: cut % (len(data) + 1)], bytes(edited)):
        before = [a.copy() for a in (fresh.order.last_s, fresh.clock.window, fresh.clock.counts, fresh.tracker.hyps,
                                     fresh.tracker.counts, fresh.tracker.robot_tracks, *fresh.alignment.state())]
        status, n_bytes, action, t_s, ball_x, ball_y = fresh_pass.run(chunk, 1.7e9, TIME_ESTIMATE)
        if status == PASS_FALLBACK:  # nothing changed; the general path names the problem or drops a detection
            after = (fresh.order.last_s, fresh.clock.window, fresh.clock.counts, fresh.tracker.hyps,
                     fresh.tracker.counts, fresh.tracker.robot_tracks, *fresh.alignment.state())
            assert all(np.array_equal(a, b, equal_nan=True) for a, b in zip(before, after, strict=True))
            try:
                packet = decode_wrapper(chunk)
            except SslDecodeError:
                continue
            det = packet.detection
            restart = det is not None and det.camera_id < len(fresh.order.last_s) and (
                fresh.order.last_s[det.camera_id] - det.t_capture_s >= fresh.order.restart_s)
            assert packet.problems or packet.geometry is not None or det is None or len(det.robots) < len(
                robots) or restart
            continue
        # what the pass took, the runtime parses as a detection frame whose every detection is valid
        packet = decode_wrapper(chunk)
        assert packet.problems == [] and packet.detection is not None
        assert np.isfinite(fresh_pass.robots()[:, 2:4]).all() and np.isfinite(fresh.alignment.offsets).all()
        if status in (PASS_T_CAPTURE_BACK, PASS_CLOCK_JUMP, PASS_BAD_STAMP):
            continue
        assert math.isfinite(t_s) and math.isfinite(ball_x) and math.isfinite(ball_y)
        if status == PASS_DONE and n_bytes > 0:
            _t, msg_balls, msg_rows = vision_frame_from_msg(fresh_pass.message_view[:n_bytes].tobytes())
            assert np.isfinite(msg_balls).all() and np.isfinite(msg_rows).all()
        if action:
            fresh.tracker.use_ball(action, int(fresh_pass.info[0]), t_s, ball_x, ball_y)
