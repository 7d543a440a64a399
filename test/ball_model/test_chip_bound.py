"""bench/bench_chip_bound.py: the squared noise distance from a kick's sightings to the nearest ground kick."""

import math
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "bench"))

import bench_chip_bound as bound

from erforce_ball_model.ball_model import BallTrajectory, ChipParams
from erforce_ball_model.chip_model import ChipTrajectory

T_KICK_S = 0.3 + 0.004


def _one_camera(height_m: float | None = None):
    """The first quadrant camera, seeing everything: one sighting per frame."""
    position, _ = bound.cameras_of(height_m=height_m)[0]
    return [(position, lambda x, y: True)]


def _radial_chip(camera) -> ChipTrajectory:
    """A chip launched at the camera's nadir, away from it at 2 m/s and 45 deg."""
    (cx, cy, _), _ = camera[0]
    v = 2.0 / math.sqrt(2.0)
    return ChipTrajectory((cx, cy, 0.0), (v, 0.0, v), ChipParams())


def test_a_ground_kick_lies_on_the_ground_kicks():
    ball = BallTrajectory((0.5, 0.4), (3.0, -1.0), math.hypot(3.0, -1.0))
    sightings = bound.kick_sightings(ball, T_KICK_S, _one_camera())
    d2, info = bound.distance_sq(sightings, bound.Noise())
    assert d2 < 1e-8
    assert info["theta"][1:3] == pytest.approx((0.5, 0.4), abs=1e-6)


def test_a_ball_at_rest_is_seen_where_it_lies():
    ball = BallTrajectory((0.5, 0.4), (0.0, 0.0), 0.0)
    sightings = bound.kick_sightings(ball, T_KICK_S, _one_camera())
    assert np.allclose(sightings.xy_m, (0.5, 0.4))
    # frames every 1/70 s from 0 to the kick + 0.15 s: 0.454 * 70 = 31.8 -> 32 frames
    assert len(sightings.t_s) == 32


def test_whitening_is_the_inverse_covariance_of_two_cameras_sharing_the_world_noise():
    ball = BallTrajectory((0.0, 0.0), (0.0, 0.0), 0.0)
    cameras = bound.cameras_of(views=4)[:2]
    sightings = bound.kick_sightings(ball, T_KICK_S, cameras)
    w = bound.whitening(sightings, bound.Noise(world_m=0.002, camera_m=0.0005))
    s2, c2 = 0.002**2, 0.0005**2
    inverse = np.array([[s2 + c2, -s2], [-s2, s2 + c2]]) / (c2 * (c2 + 2.0 * s2))  # by hand, 2x2
    assert (w.T @ w)[:2, :2] == pytest.approx(inverse, rel=1e-9)
    assert np.count_nonzero((w.T @ w)[:2, 2:]) == 0  # frames are independent


def test_a_chip_from_the_nadir_nears_the_ground_kicks_as_the_camera_rises():
    d2 = []
    for height_m in (4.0, 8.0, 1000.0):
        camera = _one_camera(height_m)
        sightings = bound.kick_sightings(_radial_chip(camera), T_KICK_S, camera)
        d2.append(bound.distance_sq(sightings, bound.Noise())[0])
    assert 0.0 < d2[2] < d2[1] < d2[0]


def test_one_camera_distance_scales_with_the_inverse_noise_variance():
    camera = _one_camera()
    sightings = bound.kick_sightings(_radial_chip(camera), T_KICK_S, camera)
    d2 = bound.distance_sq(sightings, bound.Noise(world_m=0.002, camera_m=0.0))[0]
    half = bound.distance_sq(sightings, bound.Noise(world_m=0.001, camera_m=0.0))[0]
    assert half == pytest.approx(4.0 * d2, rel=1e-6)
