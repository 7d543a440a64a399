"""Per-camera offsets from what two cameras see at one capture (camera_alignment.CameraAlignment): the estimate
converges to the offsets within the bound its noise and sample count give, a ball in the air never feeds it,
and a ground ball's corrected sightings from two cameras agree."""

from __future__ import annotations

import math

import numpy as np
import pytest

from erforce_ball_model.camera_alignment import CameraAlignment
from erforce_interfaces.ssl.ssl_vision import decode_wrapper
from erforce_interfaces.wire.robot_config import FieldConfig
from erforce_sim.sensors import RobotDetection, VisionFrame
from erforce_sim.ssl_cameras import ERFORCE_REALISTIC, SslCameraSplitter

G = 9.81
ROBOT_NOISE_M = 0.0013
BALL_NOISE_M = 0.0014
PERIOD_S = 1.0 / 70.0
CAMERAS = {0: (-2.25, 1.5, 4.0), 3: (2.25, 1.5, 4.0)}  # two cameras of one overlap (|x| < 1 m both see)
OFFSETS = {0: np.array([-0.015, 0.008]), 3: np.array([0.015, -0.008])}  # zero mean: the estimate is these
ROBOTS = ((0, 1, 0.2, 1.0), (0, 2, -0.5, 2.2), (1, 1, 0.7, 0.4), (1, 5, 0.0, 1.8))


def feed_robots(alignment, captures, rng, offsets=OFFSETS, t0_s=0.0):
    """Both cameras see ROBOTS standing still at each capture, each shifted by its offset plus its own noise."""
    for k in range(captures):
        t = t0_s + k * PERIOD_S
        for camera_id, offset in offsets.items():
            rows = [(team, rid, x + offset[0] + rng.normal(0.0, ROBOT_NOISE_M),
                     y + offset[1] + rng.normal(0.0, ROBOT_NOISE_M)) for team, rid, x, y in ROBOTS]
            alignment.frame(camera_id, t, rows)


def test_converges_to_the_offsets_within_the_noise_bound():
    """d = p_0 - p_3 = o_0 - o_3 + e, e ~ N(0, 2 s^2) per axis; with zero-mean gauge o_0 = mean(d) / 2, whose
    standard deviation is sqrt(2 s^2 / N) / 2 = s / sqrt(2 N) for N differences."""
    alignment = CameraAlignment()
    captures = 50
    feed_robots(alignment, captures, np.random.default_rng(7))
    n = captures * len(ROBOTS)
    assert alignment.samples(0, 3) == n
    sigma_m = ROBOT_NOISE_M / math.sqrt(2 * n)
    for camera_id, offset in OFFSETS.items():
        estimate = np.array(alignment.offset_m(camera_id))
        assert np.all(np.abs(estimate - offset) <= 4.0 * sigma_m), (estimate, offset, sigma_m)
        # the stated uncertainty: s estimated from the 2 (N - 1) residuals (relative spread ~4 %)
        assert alignment.uncertainty_m(camera_id) == pytest.approx(sigma_m, rel=0.15)


def test_offsets_are_relative_to_their_mean():
    """Offsets with a common shift: the estimate is each minus the mean (only differences are observable)."""
    shifted = {c: o + np.array([0.03, -0.02]) for c, o in OFFSETS.items()}
    alignment = CameraAlignment()
    feed_robots(alignment, 50, np.random.default_rng(8), shifted)
    bound_m = 4.0 * ROBOT_NOISE_M / math.sqrt(2 * 50 * len(ROBOTS))
    for camera_id, offset in OFFSETS.items():
        assert np.all(np.abs(np.array(alignment.offset_m(camera_id)) - offset) <= bound_m)


def test_unknown_cameras_and_moving_robots_between_unsynchronised_captures():
    """A camera never paired has no offset and infinite uncertainty; a robot moving 2 m/s between two cameras'
    captures 3 ms apart (6 mm, beyond max_motion_m) does not pair, one standing still does."""
    alignment = CameraAlignment(max_capture_gap_s=0.004, max_motion_m=0.002)
    assert alignment.offset_m(5) == (0.0, 0.0) and alignment.uncertainty_m(5) == math.inf
    for k in range(3):
        t = k * PERIOD_S
        alignment.frame(0, t, [(0, 1, 2.0 * t, 1.0), (0, 2, 0.3, 1.0)])
        alignment.frame(3, t + 0.003, [(0, 1, 2.0 * (t + 0.003), 1.0), (0, 2, 0.3, 1.0)])
    # camera 3 knows robot 2's speed (0) from its second frame on; robot 1's is 2 m/s
    assert alignment.samples(0, 3) == 2


def _in_air(x0, y0, vx, vy, vz, tau):
    return x0 + vx * tau, y0 + vy * tau, vz * tau - 0.5 * G * tau * tau


def _seen(ball, camera_id):
    """Camera ``camera_id``'s ball: where its ray through the ball meets the ground, plus its offset."""
    x, y, z = ball
    cx, cy, cz = CAMERAS[camera_id]
    s = cz / (cz - z)
    return cx + (x - cx) * s + OFFSETS[camera_id][0], cy + (y - cy) * s + OFFSETS[camera_id][1]


CHIPS = [(x0, y0, v * math.cos(h), v * math.sin(h), vz)
         for x0 in (-0.9, 0.0, 0.6) for y0 in (0.6, 1.5, 2.4) for v in (0.0, 0.5, 2.0) for h in (0.0, 2.0)
         for vz in (0.3, 1.0, 2.5, 4.0)]


@pytest.mark.parametrize("noise_m", [0.0, BALL_NOISE_M])
def test_a_ball_in_the_air_never_feeds_the_estimate(noise_m):
    """Chips (straight up too) seen by both cameras of an overlap through their whole flight: no difference is
    taken. The same ball lying still is taken (the test can fail)."""
    rng = np.random.default_rng(9)
    for x0, y0, vx, vy, vz in CHIPS:
        alignment = CameraAlignment()
        flight_s = 2.0 * vz / G
        for k in range(1, int(flight_s / PERIOD_S) + 1):
            ball = _in_air(x0, y0, vx, vy, vz, k * PERIOD_S)
            for camera_id in CAMERAS:
                x, y = _seen(ball, camera_id)
                alignment.frame(camera_id, k * PERIOD_S, balls=[(x + rng.normal(0.0, noise_m) if noise_m else x,
                                                                 y + rng.normal(0.0, noise_m) if noise_m else y)])
        assert alignment.samples(0, 3) == 0, (x0, y0, vx, vy, vz)
        for k in range(30):  # then lying still where it started, 0.43 s
            for camera_id in CAMERAS:
                alignment.frame(camera_id, 10.0 + k * PERIOD_S, balls=[_seen((x0, y0, 0.0), camera_id)])
        assert alignment.samples(0, 3) > 0


def test_corrected_sightings_of_a_ground_ball_in_an_overlap_agree():
    """After 50 captures of the robots, a ball at rest in the overlap seen 200 times: the cameras' raw sightings
    differ by o_0 - o_3 (3.4 cm); the corrected ones by noise only, mean within 4 standard deviations of
    sqrt(2 s_ball^2 / 200 + 2 s_robot^2 / N) (each camera's noise, and the estimate's error of o_0 - o_3)."""
    rng = np.random.default_rng(10)
    alignment = CameraAlignment()
    feed_robots(alignment, 50, rng)
    raw, corrected = [], []
    for k in range(200):
        seen = {}
        for camera_id in CAMERAS:
            x, y = _seen((0.3, 1.2, 0.0), camera_id)
            seen[camera_id] = (x + rng.normal(0.0, BALL_NOISE_M), y + rng.normal(0.0, BALL_NOISE_M))
            alignment.frame(camera_id, 1.0 + k * PERIOD_S, balls=[seen[camera_id]])
        raw.append(np.subtract(seen[0], seen[3]))
        corrected.append(np.subtract(alignment.correct(0, *seen[0]), alignment.correct(3, *seen[3])))
    assert np.linalg.norm(np.mean(raw, axis=0)) == pytest.approx(np.linalg.norm(OFFSETS[0] - OFFSETS[3]), abs=0.001)
    bound_m = 4.0 * math.sqrt(2 * BALL_NOISE_M**2 / 200 + 2 * ROBOT_NOISE_M**2 / (50 * len(ROBOTS)))
    assert np.all(np.abs(np.mean(corrected, axis=0)) <= bound_m)


def test_learns_the_simulated_cameras_offsets_from_robots_in_the_overlaps():
    """ER-Force's "Realistic" cameras without noise (ssl_cameras): robots in the overlap bands give each camera's
    object offset exactly, less the mean over the four."""
    field = FieldConfig.preset("division_b")
    splitter = SslCameraSplitter.quadrants(field, None, ERFORCE_REALISTIC.noise_free())
    robots = (RobotDetection("blue", 0, 0.1, 2.0, 0.0), RobotDetection("yellow", 0, 3.0, -0.1, 0.0),
              RobotDetection("yellow", 1, -3.0, 0.1, 0.0), RobotDetection("blue", 1, -0.1, -2.0, 0.0))
    alignment = CameraAlignment()
    for k in range(3):
        frame = VisionFrame(k, k * PERIOD_S, k * PERIOD_S, (), robots)
        for _, data in splitter.packets(frame):
            det = decode_wrapper(data).detection
            alignment.frame(det.camera_id, det.t_capture_s, [r[:4] for r in det.robots.tolist()])
    truth = np.array([splitter.realism.object_offset(c) for c in splitter.projecting_cameras])
    truth -= truth.mean(axis=0)
    for camera_id, offset in enumerate(truth):
        assert alignment.offset_m(camera_id) == pytest.approx(tuple(offset), abs=1e-4)  # SSL's mm resolution
