"""Chip detection and reconstruction (chip_tracking, chip_fits); the predictor's chip (BallFrame.chip, hand-over)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from erforce_ball_model import chip_fits
from erforce_ball_model.ball_model import BallModelParams, BallTrajectory, ChipParams
from erforce_ball_model.chip_fits import Sighting, fit_flight, fit_flight_at_angle, triangulate_height
from erforce_ball_model.chip_model import ChipTrajectory
from erforce_ball_model.chip_tracking import ChipDetector
from erforce_ball_model.predictor import BallPredictor, PredictorConfig

G = 9.81
CAMERAS = ((-3.0, 0.0, 4.0), (3.0, 1.0, 4.0))


def seen(x, y, z, camera):
    """Where a camera sees a ball at height z on the ground (the ray through it), written out here."""
    cx, cy, cz = camera
    return cx + (x - cx) * cz / (cz - z), cy + (y - cy) * cz / (cz - z)


def chip_sightings(times, cameras=CAMERAS, vx=2.0, vz=3.0):
    """A chip launched at t = 0 from the origin along +x, seen by every camera at each time."""
    return [(t, *seen(vx * t, 0.0, vz * t - 0.5 * G * t * t, c), c) for t in times for c in cameras]


def test_two_cameras_triangulate_the_height():
    # At t = 0.2 s the ball is at x = 0.4 m, z = 3 * 0.2 - 9.81 / 2 * 0.04 = 0.4038 m: the cameras at x = -3 and
    # x = 3 see it at 0.4 + 3.4 * 0.4038 / 3.5962 = 0.78177 m and 3 - 2.6 * 4 / 3.5962 = 0.10801 m.
    assert seen(0.4, 0.0, 0.4038, CAMERAS[0])[0] == pytest.approx(0.78177, abs=1e-5)
    detector = ChipDetector(None, ChipParams())
    detector.start(0.05, before=(0.0, 0.0, 0.0, 0.0, 0.0))
    for t, x, y, camera in chip_sightings([0.05, 0.1, 0.15, 0.2]):
        detector.add(t, x, y, camera)
    chip = detector.chip_at(0.2)
    assert chip is not None and detector.detected_at_s <= 0.2
    assert chip.position_m.tolist() == pytest.approx([0.4, 0.0, 0.4038], abs=1e-6)
    assert chip.velocity_mps.tolist() == pytest.approx([2.0, 0.0, 3.0 - G * 0.2], abs=1e-6)
    # launched at 0 from the origin; first touchdown after 2 vz / g = 0.6116 s, at x = 1.2232 m
    assert detector.fit.t_launch_s == pytest.approx(0.0, abs=1e-9)
    assert detector.launch.touchdown_points_m[0].tolist() == pytest.approx([2.0 * 6.0 / G, 0.0], abs=1e-6)


def test_a_captures_other_cameras_are_judged_once_with_it(monkeypatch):
    """Three cameras per capture: sightings added without a judgement (another camera's of the same instant) are
    judged together when the next capture's first one comes: two judgements per capture instead of three, the same
    chip, detected as of the same capture."""
    cameras = (*CAMERAS, (0.0, -3.0, 4.0))
    judged = []
    original = ChipDetector._judge
    monkeypatch.setattr(ChipDetector, "_judge", lambda self, t_s: (judged.append(t_s), original(self, t_s)))
    detectors = []
    for deferred in (False, True):
        judged.clear()
        detector = ChipDetector(None, ChipParams())
        detector.start(0.05, before=(0.0, 0.0, 0.0, 0.0, 0.0))
        for t, x, y, camera in chip_sightings([0.05 + 0.01 * k for k in range(8)], cameras=cameras):
            detector.add(t, x, y, camera, judge=not deferred or camera == cameras[0])
        detector.judge_pending()
        detectors.append((detector, len(judged)))
    (each, n_each), (once, n_once) = detectors
    assert (n_each, n_once) == (3 * 8, 2 * 8)
    assert once.detected_at_s == each.detected_at_s
    assert once.fit == pytest.approx(each.fit, abs=1e-9)
    assert once.fit.vz_mps == pytest.approx(3.0, abs=1e-6)


def test_the_flight_fit_is_the_projectile_behind_the_rays():
    rows = np.array([(t, x, y, *c) for t, x, y, c in chip_sightings([0.02, 0.06, 0.1], cameras=CAMERAS[:1])])
    fit = fit_flight(rows, 0.0, (0.0, 0.0), G, 0.002)
    assert (fit.x_m, fit.y_m, fit.vx_mps, fit.vy_mps, fit.vz_mps) == pytest.approx((0.0, 0.0, 2.0, 0.0, 3.0),
                                                                                    abs=1e-9)
    assert fit.rss_m2 == pytest.approx(0.0, abs=1e-20)


def test_the_flight_at_a_known_angle_is_the_projectile_from_fewer_unknowns():
    """vx 2, vz 3: tan(angle) = 1.5; one camera, three sightings (six equations, four unknowns)."""
    rows = np.array([(t, x, y, *c) for t, x, y, c in chip_sightings([0.02, 0.04, 0.06], cameras=CAMERAS[:1])])
    fit = fit_flight_at_angle(rows, 0.0, None, G, 0.002, tan_angle=1.5)
    assert (fit.x_m, fit.y_m, fit.vx_mps, fit.vy_mps, fit.vz_mps) == pytest.approx((0.0, 0.0, 2.0, 0.0, 3.0),
                                                                                    abs=1e-6)
    assert fit.rss_m2 == pytest.approx(0.0, abs=1e-12) and fit.vz_std_mps > 0.0


def low_chip_detector(hint_deg, vx=2.0, vz=0.4):
    """A low chip (vz 0.4 m/s: 8 mm high at its apex, 82 ms in the air), seen by one camera at 70 Hz from the
    first frame after the kick, with the kicker's hint (None: none) given at the kick."""
    detector = ChipDetector(None, ChipParams())
    if hint_deg is not None:
        detector.hint(0.0, hint_deg)
    detector.start(1.0 / 70.0, before=(0.0, 0.0, 0.0, 0.0, 0.0))
    for t, x, y, camera in chip_sightings([k / 70.0 for k in range(1, 6)], CAMERAS[:1], vx=vx, vz=vz):
        detector.add(t, x, y, camera)
    return detector


def test_a_chip_hint_tells_a_chip_too_low_to_see():
    """Without the hint the low chip's sightings fit a ground ball as well (not a chip by the 5th); with the
    kicker's angle, atan(0.4 / 2) = 11.3 deg, it is taken at the 4th sighting with its vertical speed."""
    assert low_chip_detector(None).fit is None
    detector = low_chip_detector(math.degrees(math.atan2(0.4, 2.0)))
    assert detector.detected_at_s == pytest.approx(4.0 / 70.0)
    assert detector.fit.vz_mps == pytest.approx(0.4, abs=0.02)
    assert detector.hint_angle_deg == pytest.approx(11.31, abs=0.01)


def test_a_hint_belongs_only_to_the_motion_just_after_it():
    detector = ChipDetector(None, ChipParams())
    detector.hint(0.0, 45.0)
    detector.start(0.2, before=None)  # 0.2 s later: another motion (hint_window_s 0.1)
    assert detector.hint_angle_deg is None
    detector.hint(0.15, 45.0)  # late news of the current motion's kick
    assert detector.hint_angle_deg == 45.0
    with pytest.raises(ValueError, match="angle"):
        detector.hint(0.3, 90.0)
    with pytest.raises(ValueError, match="angle"):
        detector.hint(float("nan"), 10.0)


def test_a_flat_hint_does_not_make_a_ground_kick_a_chip():
    """A ground kick with a flat hint stays a ground ball (the hint raises the evidence a chip needs)."""
    detector = ChipDetector(None, ChipParams())
    detector.hint(0.0, 0.0)
    detector.start(1.0 / 70.0, before=(0.0, 0.0, 0.0, 0.0, 0.0))
    ball = BallTrajectory((0.0, 0.0), (3.0, 0.0), 3.0)
    for k in range(1, 20):
        x, y = ball.position_at(k / 70.0).tolist()
        detector.add(k / 70.0, x, y, CAMERAS[0])
    assert detector.hint_angle_deg == 0.0 and detector.fit is None


@settings(max_examples=60, deadline=None)
@given(x=st.floats(-4.0, 4.0), y=st.floats(-2.5, 2.5), heading=st.floats(-math.pi, math.pi),
       speed=st.floats(0.3, 6.5), t_kick=st.floats(0.0, 1.0 / 70.0),
       cameras=st.lists(st.tuples(st.floats(-4.5, 4.5), st.floats(-3.0, 3.0), st.floats(3.0, 6.0)),
                        min_size=1, max_size=2))
def test_a_flat_kick_is_never_a_chip(x, y, heading, speed, t_kick, cameras):
    ball = BallTrajectory((x, y), (speed * math.cos(heading), speed * math.sin(heading)), speed)
    detector = ChipDetector(None, ChipParams())
    for k in range(1, 30):  # 70 Hz, from the first frame after the kick
        t = k / 70.0
        if t < t_kick:
            continue
        if detector.t_start_s is None:
            detector.start(t, before=(0.0, x, y, 0.0, 0.0))
        px, py = ball.position_at(t - t_kick).tolist()
        for camera in cameras:
            detector.add(t, px, py, camera)
        assert detector.fit is None and detector.chip_at(t) is None


def test_the_predictor_carries_the_chip_and_hands_it_over_to_the_flat_filter():
    predictor = BallPredictor(PredictorConfig(num_robots=1))
    camera, other = (-1.5, 1.0, 4.0), (3.0, -1.5, 4.0)
    dt = 1.0 / 70.0
    for k in range(10):  # at rest at the origin
        assert predictor.ball_frame(k * dt, 0.0, 0.0, camera_m=camera) is not None
    t_kick = 10 * dt - 0.004
    vx, vz = 2.5, 2.5  # 3.54 m/s at 45 deg along +x
    truth = ChipTrajectory((0.0, 0.0, 0.0), (vx, 0.0, vz), ChipParams())
    frames = []
    for k in range(10, 140):
        t = k * dt
        x, y, z = truth.position_at(max(t - t_kick, 0.0)).tolist()
        frames.append(predictor.ball_frame(t, *seen(x, y, z, camera), camera_m=camera))
        predictor.ball_sighting(t, *seen(x, y, z, other), other)  # an overlapping camera of the same instant
    chips = [f for f in frames if f is not None and f.chip is not None]
    assert chips and chips[0].t_s - t_kick <= 0.05  # two cameras: at the 4th sighting
    first = chips[0]
    assert first.phase == "chip"
    tau = first.t_s - t_kick
    assert first.z_m == pytest.approx(vz * tau - 0.5 * G * tau * tau, abs=0.01)
    assert first.vz_mps == pytest.approx(vz - G * tau, abs=0.1)
    assert first.stop_point_m == pytest.approx(tuple(first.chip.stop_point.tolist()))
    # the first touchdown: 2 vz / g = 0.51 s after the kick, at x = vx * 0.51 = 1.274 m
    assert predictor.chip_detector.launch.touchdown_points_m[0].tolist() == pytest.approx([1.274, 0.0], abs=0.02)
    # after the hops the chip rolls: no chip any more, the flat filter rolls on from the chip's roll
    launch, t_launch = predictor.chip_detector.launch, predictor.chip_detector.fit.t_launch_s
    # "chip" until the first touchdown (2 vz / g after the launch), "hopping" from it until the roll
    t_down = t_launch + launch.touchdown_times_s[0]
    in_air = [f for f in chips if f.t_s < t_launch + launch.roll_start_s]
    assert {f.phase for f in in_air if f.t_s < t_down} == {"chip"}
    assert {f.phase for f in in_air if f.t_s > t_down} == {"hopping"}
    after = [f for f in frames if f is not None and f.t_s > t_launch + launch.roll_start_s]
    assert after and all(f.chip is None and f.phase not in ("chip", "hopping") and f.z_m == 0.0 for f in after)
    handed = after[0]
    roll = launch.roll.advanced(handed.t_s - t_launch - launch.roll_start_s)
    assert handed.trajectory.position_m.tolist() == pytest.approx(roll.position_m.tolist(), abs=1e-9)
    assert handed.trajectory.velocity_mps.tolist() == pytest.approx(roll.velocity_mps.tolist(), abs=1e-9)
    assert handed.phase == "rolling"


def test_a_bad_sighting_is_refused_by_name():
    detector = ChipDetector(None, ChipParams())
    with pytest.raises(ValueError, match="camera"):
        detector.add(0.0, math.nan, 0.0, (0.0, 0.0, 4.0))
    with pytest.raises(ValueError, match="camera"):
        detector.add(0.0, 0.0, 0.0, (0.0, 0.0, 0.0))


def test_two_cameras_at_one_instant_give_the_flights_height():
    """A chip (2 m/s along +y, 3 m/s up from (0.5, -0.3)) seen by both cameras: at every instant the height from
    the two ground points is the projectile's, vz t - g t^2 / 2."""
    truth = ChipTrajectory((0.5, -0.3, 0.0), (0.0, 2.0, 3.0), ChipParams())
    for t in (0.01, 0.1, 0.3, 0.55):
        x, y, z = truth.position_at(t).tolist()
        assert z == pytest.approx(3.0 * t - 0.5 * G * t * t, abs=1e-12)
        a, b = (Sighting(t, *seen(x, y, z, c), *c) for c in CAMERAS)
        height_m, m_per_m = triangulate_height(a, b)
        assert height_m == pytest.approx(z, abs=1e-9)
        # k = (Ga - ca) / 4 - (Gb - cb) / 4 = (cb - ca) / (4 - z): the baseline (6, 1) seen from the ball's height
        assert m_per_m == pytest.approx((4.0 - z) / math.hypot(6.0, 1.0), rel=1e-9)
    ground = Sighting(0.0, 1.0, 1.0, *CAMERAS[0]), Sighting(0.0, 1.0, 1.0, *CAMERAS[1])
    assert triangulate_height(*ground)[0] == 0.0
    assert triangulate_height(ground[0], ground[0]) == (0.0, math.inf)  # one camera twice: no height


def kick_sightings(truth, t_kick, cameras, noise_m=0.0, seed=0, frames=(-7, 12)):
    """70 Hz frames of a ball at rest where ``truth`` starts, kicked at ``t_kick``: (t, x, y, camera) per camera
    that sees it, with Gaussian noise per frame (as the world's vision) and none per camera."""
    rng = np.random.default_rng(seed)
    out = []
    for k in range(*frames):
        t = k / 70.0
        x, y, z = (truth.position_at(max(t - t_kick, 0.0)).tolist() + [0.0])[:3]
        nx, ny = rng.normal(0.0, noise_m, 2)
        out += [(t, *seen(x + nx, y + ny, z, c), c) for c in cameras]
    return out


def feed(detector, sightings, t_first):
    """The sightings in order; the kick starts (the flat filter's new motion) at ``t_first``. The frame when the
    detector first held a chip (None: never)."""
    for t, x, y, camera in sightings:
        if t >= t_first and detector.t_start_s is None:
            detector.start(t_first, before=(t_first - 1.0 / 70.0, 0.0, 0.0, 0.0, 0.0))
        detector.add(t, x, y, camera)
    return detector.detected_at_s


def test_two_cameras_take_a_chip_at_their_first_judgement():
    """Both cameras see the chip: the second frame after the kick holds four new sightings (the least a judgement
    takes), and at 14 ms after the launch the ball is 3 cm up: the cameras disagree by centimetres."""
    truth = ChipTrajectory((0.0, 0.0, 0.0), (2.0, 0.0, 2.5), ChipParams())
    t_kick = 0.004
    detector = ChipDetector(None, ChipParams())
    detected = feed(detector, kick_sightings(truth, t_kick, CAMERAS), t_first=1.0 / 70.0)
    assert detected == pytest.approx(2.0 / 70.0)
    assert detector.fit.t_launch_s == pytest.approx(t_kick, abs=5e-4)


def test_the_launch_point_is_where_the_ball_lay():
    """The flat filter's last state may already hold the kick's first frame (here 5 mm and 0.35 m/s off): the old
    motion's own sightings at rest pin the launch point, to a fraction of a millimetre without noise."""
    truth = ChipTrajectory((1.0, 0.5, 0.0), (2.0, 1.0, 2.0), ChipParams())
    detector = ChipDetector(None, ChipParams())
    sightings = kick_sightings(truth, 0.003, CAMERAS[:1], frames=(-7, 16))
    for t, x, y, camera in sightings:
        if t >= 2.0 / 70.0 and detector.t_start_s is None:
            detector.start(2.0 / 70.0, before=(1.0 / 70.0, 1.005, 0.5, 0.35, 0.0))
        detector.add(t, x, y, camera)
    assert detector.fit is not None
    assert (detector.fit.x_m, detector.fit.y_m) == pytest.approx((1.0, 0.5), abs=5e-4)
    assert detector.launch.touchdown_points_m[0].tolist() == pytest.approx(truth.touchdown_points_m[0].tolist(),
                                                                           abs=0.01)


def test_one_camera_sees_a_chip_within_a_few_frames():
    """One camera, 2 mm of noise per frame, 20 seeds: a chip at 3.5 m/s and 45 deg passing the camera sideways (1.5 m
    off its nadir) is taken within 9 frames (0.13 s) of the kick, every time. (Early on the height only tilts the
    seen path, as another heading would: the curve gravity bends into it, g 1.5 m / (2 4 m) t^2 sideways, tells it.)"""
    camera = (0.0, 1.5, 4.0)
    v = 3.5 / math.sqrt(2.0)
    truth = ChipTrajectory((-0.5, 0.0, 0.0), (v, 0.0, v), ChipParams())
    for seed in range(20):
        detector = ChipDetector(None, ChipParams())
        detected = feed(detector, kick_sightings(truth, 0.005, [camera], 0.002, seed, frames=(-7, 20)), 2.0 / 70.0)
        assert detected is not None and detected - 0.005 <= 9.0 / 70.0, seed


def test_noisy_flat_kicks_are_never_chips():
    """Flat kicks from rest, 1-6.5 m/s in any direction, 2 mm of noise per frame, one camera or two: over 40 seeded
    runs of 0.3 s none is taken for a chip."""
    rng = np.random.default_rng(7)
    cameras = ((-2.25, 1.5, 4.0), (2.25, 1.5, 4.0))
    for seed in range(40):
        speed, heading = rng.uniform(1.0, 6.5), rng.uniform(-math.pi, math.pi)
        start = (rng.uniform(-1.0, 1.0), rng.uniform(0.0, 3.0))
        truth = BallTrajectory(start, (speed * math.cos(heading), speed * math.sin(heading)), speed)
        detector = ChipDetector(None, ChipParams())
        used = cameras[: 1 + seed % 2]
        assert feed(detector, kick_sightings(truth, 0.006, used, 0.002, seed, frames=(-7, 21)), 2.0 / 70.0) is None


def test_a_ball_placed_elsewhere_mid_flight_does_not_carry_the_chip_away():
    """A chip at (2, 0, 2) m/s from the origin (apex v_z^2 / 2g = 0.204 m at 0.204 s, first touchdown at
    2 v_z / g = 0.408 s and 0.815 m) is detected; at 0.2 s, still in the air, the ball is placed at rest at (-4, 3) m
    and both cameras see it there. No flight a chip kicker launches explains those sightings: the chip the detector
    holds stays the one it saw fly (its height at most the apex, its hops those of the true flight), never one that
    leaves the field."""
    truth = ChipTrajectory((0.0, 0.0, 0.0), (2.0, 0.0, 2.0), ChipParams())
    t_kick, t_placed, placed = 0.004, 0.2, (-4.0, 3.0)
    sightings = [s for s in kick_sightings(truth, t_kick, CAMERAS, frames=(-7, 70)) if s[0] < t_placed]
    sightings += [(k / 70.0, *seen(*placed, 0.0, c), c) for k in range(math.ceil(t_placed * 70.0), 70)
                  for c in CAMERAS]
    detector = ChipDetector(None, ChipParams())
    assert feed(detector, [s for s in sightings if s[0] < t_placed], t_first=1.0 / 70.0) is not None
    for t, x, y, camera in (s for s in sightings if s[0] >= t_placed):
        detector.add(t, x, y, camera)
        fit = detector.fit
        assert math.hypot(fit.vx_mps, fit.vy_mps, fit.vz_mps) <= detector.config.max_launch_speed_mps, t
        chip = detector.chip_at(t)
        if chip is not None:  # the flight it saw, as that flight goes on (hops included)
            assert chip.position_m[2] <= 0.21, t
            assert chip.position_m.tolist() == pytest.approx(truth.position_at(t - t_kick).tolist(), abs=0.03), t


def test_a_ball_placed_elsewhere_just_after_a_hinted_kick_is_no_chip():
    """The kicker says it chipped at 45 deg; the ball (2, 0, 2) m/s from the origin is seen for one frame after the
    kick, then lies at rest at (-4, 3) m. A flight at 45 deg from the origin through those ground points needs tens of
    m/s and misses the sightings by metres: no chip is taken from them, and none the detector ever holds is faster
    than the launch speed sqrt(2^2 + 2^2) = 2.83 m/s (the true chip, once its own frames explain it)."""
    truth = ChipTrajectory((0.0, 0.0, 0.0), (2.0, 0.0, 2.0), ChipParams())
    t_kick, placed = 0.004, (-4.0, 3.0)
    sightings = kick_sightings(truth, t_kick, CAMERAS, frames=(-7, 2))
    sightings += [(k / 70.0, *seen(*placed, 0.0, c), c) for k in range(2, 70) for c in CAMERAS[:1]]
    detector = ChipDetector(None, ChipParams())
    detector.hint(t_kick, 45.0)
    for t, x, y, camera in sightings:
        if t >= 1.0 / 70.0 and detector.t_start_s is None:
            detector.start(1.0 / 70.0, before=(0.0, 0.0, 0.0, 0.0, 0.0))
        detector.add(t, x, y, camera)
        chip = detector.chip_at(t)
        if chip is not None:
            assert float(np.linalg.norm(detector.launch.velocity_mps)) <= math.hypot(2.0, 2.0) + 0.01, t
            assert chip.position_m.tolist() == pytest.approx(truth.position_at(t - t_kick).tolist(), abs=0.03), t


def test_a_kick_the_flat_filter_saw_late_starts_where_the_ball_left():
    """A flat kick at 2 m/s at t = 3 ms from rest: at 1/70 s the ball is 2 (1/70 - 0.003) - 1.25 (...)^2 = 22.4 mm
    off, beyond moved_sigma (5) times 2 mm. The flat filter reports the new motion only at 4/70 s; the kick's
    sightings start at 1/70 s, and the launch time searched ends there."""
    truth = BallTrajectory((0.3, 0.2), (2.0, 0.0), 2.0)
    detector = ChipDetector(None, ChipParams())
    for t, x, y, camera in kick_sightings(truth, 0.003, CAMERAS[:1], frames=(-9, 4)):
        detector.add(t, x, y, camera)
    assert truth.position_at(1.0 / 70.0 - 0.003)[0] - 0.3 == pytest.approx(
        2.0 * (1.0 / 70.0 - 0.003) - 1.25 * (1.0 / 70.0 - 0.003) ** 2, abs=1e-12)
    detector.start(4.0 / 70.0, before=(3.0 / 70.0, 0.33, 0.2, 1.2, 0.0))
    assert detector.t_start_s == pytest.approx(1.0 / 70.0)
    # at rest: no kick before the filter's word
    rest = ChipDetector(None, ChipParams())
    for t, x, y, camera in kick_sightings(truth, 1.0, CAMERAS[:1], noise_m=0.002, frames=(-9, 4)):
        rest.add(t, x, y, camera)
    rest.start(4.0 / 70.0, before=(3.0 / 70.0, 0.3, 0.2, 0.0, 0.0))
    assert rest.t_start_s == pytest.approx(4.0 / 70.0)


def test_a_flight_steeper_than_a_chip_kicker_launches_is_judged_at_the_bound():
    """A ball thrown up at 80 deg (1 m/s along +x, vz 5.67 m/s), seen by one camera beside its path without noise:
    the free flight is exact but no chip kicker launches it (max_elevation_deg 75); the flight judged is the best
    one at 74.5 deg (BOUND_INSIDE_DEG inside the bound), which explains the sightings worse than the free one and
    better than a ground kick."""
    vz = math.tan(math.radians(80.0))
    detector = ChipDetector(None, ChipParams())
    detector.start(1.0 / 70.0, before=(0.0, 0.0, 0.0, 0.0, 0.0))
    for t, x, y, camera in chip_sightings([k / 70.0 for k in range(1, 9)], ((0.0, 1.5, 4.0),), vx=1.0, vz=vz):
        detector.add(t, x, y, camera)
    rows = np.array(detector._rows)
    free = detector._best_flight(rows)
    assert math.degrees(math.atan2(free.vz_mps, free.vx_mps)) == pytest.approx(80.0, abs=1e-3)
    judged = detector._flight(rows)
    v_ground = math.hypot(judged.vx_mps, judged.vy_mps)
    assert math.degrees(math.atan2(judged.vz_mps, v_ground)) == pytest.approx(74.5, abs=0.05)
    assert free.rss_m2 < judged.rss_m2 < detector._best_ground(rows)


def test_the_batched_fit_at_an_angle_is_each_launch_times_own():
    """_flights_at_angle over several launch times gives what fit_flight_at_angle gives for each alone."""
    rng = np.random.default_rng(3)
    rows = np.array([(t, x + rng.normal(0, 0.002), y + rng.normal(0, 0.002), *c)
                     for t, x, y, c in chip_sightings([0.02, 0.04, 0.06, 0.08], cameras=CAMERAS[:1])])
    times = [-0.004, 0.0, 0.003]
    theta, vz_std, rss = chip_fits.flights_at_angle(rows, times, None, G, 0.002, 1.5, 3, (0.0, 0.0))
    for j, t0 in enumerate(times):
        one = fit_flight_at_angle(rows, t0, None, G, 0.002, tan_angle=1.5)
        assert theta[j].tolist() == pytest.approx([one.x_m, one.y_m, one.vx_mps, one.vy_mps, one.vz_mps], abs=1e-12)
        assert (vz_std[j], rss[j]) == pytest.approx((one.vz_std_mps, one.rss_m2), rel=1e-9)


# A short chip, written out by hand: launched at t = 0 from (0.5, 0.3) along +x at 1.5 m/s with vz = g * 0.1 / 2 =
# 0.4905 m/s (18 deg up), it lands at T1 = 2 vz / g = 0.1 s at x = 0.65 m; the bounce keeps 5/7 of the ground speed
# (1.071429 m/s) and 0.566 of vz (0.277623 m/s), so the second hop lasts 2 * 0.277623 / 9.81 = 0.0566 s.
SHORT_PARAMS = ChipParams(damping_z=0.566, damping_xy_first_hop=5.0 / 7.0, damping_xy_other_hops=1.0)
SHORT_V, SHORT_VZ, SHORT_T1 = 1.5, 0.4905, 0.1
SHORT_CAMERA = (0.5, -2.0, 4.0)  # beside the kick


def short_chip_at(t):
    """The short chip's (x, y, z) at ``t`` (at rest before 0), through its second hop."""
    if t <= 0.0:
        return 0.5, 0.3, 0.0
    if t <= SHORT_T1:
        return 0.5 + SHORT_V * t, 0.3, SHORT_VZ * t - 0.5 * G * t * t
    d = t - SHORT_T1
    assert d <= 2.0 * 0.566 * SHORT_VZ / G
    return 0.65 + d * SHORT_V * 5.0 / 7.0, 0.3, 0.566 * SHORT_VZ * d - 0.5 * G * d * d


def short_sightings(position_at, frames=range(-8, 11)):
    """Noise-free 70 Hz frames (at 5 ms + k / 70 s) of one camera."""
    return [(0.005 + k / 70.0, *seen(*position_at(0.005 + k / 70.0), SHORT_CAMERA)) for k in frames]


def test_a_short_chip_is_taken_through_its_first_bounce(monkeypatch):
    """The short chip from one camera beside it: before it lands the free flight's vz is not yet sure; within three
    frames after its touchdown (0.1336 s) the bounce (a step down in ground speed, a lower flight) tells it, fitted
    with the launch at 0, vz 0.4905 and the touchdown at x = 0.65 (to 0.04 m/s and 1 cm: taken early, the fitted
    bounce is held HOP_SEEN_AFTER_S before the last sighting). Without the fit through the bounce the same
    sightings are not taken (the free flight through them is no flight a chip kicker launches)."""
    def run():
        detector = ChipDetector(None, SHORT_PARAMS)
        for t, x, y in short_sightings(short_chip_at):
            if t > 0.0 and detector.t_start_s is None:
                detector.start(t, before=(t - 1.0 / 70.0, 0.5, 0.3, 0.0, 0.0))
            detector.add(t, x, y, SHORT_CAMERA)
        return detector

    detector = run()
    assert SHORT_T1 < detector.detected_at_s <= 0.005 + 9.0 / 70.0  # within the third frame after the bounce
    assert detector.fit.t_launch_s == pytest.approx(0.0, abs=1e-3)
    assert detector.fit.vz_mps == pytest.approx(SHORT_VZ, abs=0.04)
    assert detector.launch.touchdown_points_m[0].tolist() == pytest.approx([0.65, 0.3], abs=0.01)
    monkeypatch.setattr(ChipDetector, "_landed_chip", lambda self, rows, fit: None)
    assert run().detected_at_s is None


def test_a_flat_kick_as_fast_as_the_short_chip_is_no_chip():
    """A ground kick from the short chip's point at its ground speed (1.5 m/s), the same camera, 0.3 s: no chip (its
    speed falls steadily, 2.5 m/s^2 while it slides, where the chip's drops by 2/7 at once)."""
    truth = BallTrajectory((0.5, 0.3), (SHORT_V, 0.0), SHORT_V)
    detector = ChipDetector(None, SHORT_PARAMS)
    for t, x, y in short_sightings(lambda t: (*truth.position_at(max(t, 0.0)).tolist(), 0.0), range(-8, 22)):
        if t > 0.0 and detector.t_start_s is None:
            detector.start(t, before=(t - 1.0 / 70.0, 0.5, 0.3, 0.0, 0.0))
        detector.add(t, x, y, SHORT_CAMERA)
        assert detector.fit is None


def test_the_hop_fit_lands_and_bounces_the_chip_as_computed_by_hand():
    """The fit through the bounce at the true launch time and touchdown time: the launch, the touchdown point
    (0.65, 0.3) and the velocity after the bounce (1.5 * 5/7, 0, 0.566 * 0.4905 = 0.277623) to 1e-5 (the hop tables
    are linear between ms steps: a parabola's chord is off by g (1 ms)^2 / 8 = 1.2e-6 m)."""
    rows = np.array([(t, x, y, *SHORT_CAMERA) for t, x, y in short_sightings(short_chip_at)])
    tables = chip_fits.hop_tables(SHORT_PARAMS, BallModelParams())
    hop = int(np.argmin(np.abs(chip_fits.HOP_T1_S - SHORT_T1)))
    assert chip_fits.HOP_T1_S[hop] == pytest.approx(SHORT_T1, abs=1e-12)
    fit = chip_fits.fit_hop_flight(rows, 0.0, hop, tables, None, G)
    assert [fit.x_m, fit.y_m, fit.vx_mps, fit.vy_mps, fit.vz_mps] == pytest.approx([0.5, 0.3, 1.5, 0.0, SHORT_VZ],
                                                                                   abs=1e-5)
    chip = ChipTrajectory((fit.x_m, fit.y_m, 0.0), (fit.vx_mps, fit.vy_mps, fit.vz_mps), SHORT_PARAMS)
    assert chip.touchdown_times_s[0] == pytest.approx(SHORT_T1, abs=1e-9)
    assert chip.touchdown_points_m[0].tolist() == pytest.approx([0.65, 0.3], abs=1e-5)
    assert chip.velocity_at(SHORT_T1 + 1e-9).tolist() == pytest.approx([1.0714286, 0.0, 0.277623 - G * 1e-9],
                                                                       abs=1e-5)
    assert fit.rss_m2 < 1e-10


def test_a_slow_kick_the_flat_filter_missed_starts_from_the_sightings():
    """A ball at rest, then a chip at 0.8 m/s ground speed (vz 0.7 m/s: 2.5 cm high) seen by one camera beside it
    that the flat filter never reports (no ``start``): the sightings 5 noise (10 mm) off the resting ball start the
    kick, and it is taken as a chip within 0.15 s. A ball at rest with 2 mm of noise starts nothing."""
    truth = ChipTrajectory((0.5, 0.3, 0.0), (0.8, 0.0, 0.7), ChipParams())
    detector = ChipDetector(None, ChipParams())
    for t, x, y, camera in kick_sightings(truth, 0.004, [(0.5, -2.0, 4.0)], frames=(-10, 12)):
        detector.add(t, x, y, camera)
    assert 0.004 < detector.t_start_s <= 3.0 / 70.0  # 8 mm, 20 mm, 31 mm from where it lay at 1, 2, 3 / 70 s
    assert detector.detected_at_s is not None and detector.detected_at_s - 0.004 <= 0.15
    assert detector.fit.vz_mps == pytest.approx(0.7, abs=0.02)
    rest = ChipDetector(None, ChipParams())
    for t, x, y, camera in kick_sightings(truth, 10.0, CAMERAS, noise_m=0.002, seed=3, frames=(-10, 60)):
        rest.add(t, x, y, camera)
    assert rest.t_start_s is None and rest.fit is None


def test_a_start_the_ball_did_not_follow_does_not_hold_the_next_kick():
    """A ball at rest whose sightings stray 15 mm for two frames (7.5 noise: a start from the sightings), then lie
    where they were: once the sightings since that start span 0.1 s at rest it is forgotten, and a chip kicked 0.13 s
    after it (2.8 m/s, 45 deg, one camera beside it) starts its own kick and is taken within 0.15 s. Held, that start
    would have kept the chip's sightings in its own collection until 0.17 s."""
    truth = ChipTrajectory((0.5, 0.3, 0.0), (2.0, 0.0, 2.0), ChipParams())
    camera = (0.5, -2.0, 4.0)
    detector = ChipDetector(None, ChipParams())
    starts = []
    for t, x, y, cam in kick_sightings(truth, 0.004, [camera], frames=(-20, 12)):
        stray = 0.015 if -9.5 / 70.0 < t < -7.5 / 70.0 else 0.0
        detector.add(t, x + stray, y, cam)
        if detector.t_start_s is not None and detector.t_start_s not in starts:
            starts.append(detector.t_start_s)
    assert starts[0] == pytest.approx(-9.0 / 70.0)  # the stray start
    assert 0.004 < detector.t_start_s <= 2.0 / 70.0
    assert detector.detected_at_s is not None and detector.detected_at_s - 0.004 <= 0.15
