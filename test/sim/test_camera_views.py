"""The plant's ROS vision through its cameras: which camera takes the ball, where each sees it, sightings."""

import statistics

import pytest

from erforce_interfaces.wire.robot_config import FieldConfig
from erforce_sim.camera_views import BallView, CameraViews
from erforce_sim.sensors import BallDetection
from erforce_sim.ssl_cameras import BENCH_CAMERAS, SslCameraSplitter, quadrant_cameras

FIELD = FieldConfig.preset("division_b")  # 9 x 6 m, walls 0.3 m outside the lines: inside the walls 9.6 x 6.6 m
# quadrants overlapping 0.25 m across each axis; each camera 4 m above the middle of its rectangle:
# x (-4.8 + 0.25) / 2 = -2.275 or (4.8 - 0.25) / 2 = 2.275, y -+1.525
CAMERA = {0: (0, -2.275, 1.525, 4.0), 1: (1, 2.275, 1.525, 4.0), 2: (2, -2.275, -1.525, 4.0),
          3: (3, 2.275, -1.525, 4.0)}


def views_of(x, y, z=0.0, noise_m=0.0):
    return CameraViews(FIELD, camera_noise_m=noise_m).ball_views(BallDetection(x, y, z))


def test_a_ball_on_the_ground_is_where_it_lies_for_the_one_camera_above_its_quadrant():
    assert views_of(1.0, 1.0) == [BallView(CAMERA[1], 1.0, 1.0)]
    assert views_of(-3.0, -2.0) == [BallView(CAMERA[2], -3.0, -2.0)]


def test_the_camera_whose_frame_comes_first_takes_the_ball_and_the_others_sight_it():
    # the centre is in all four rectangles; the SSL frames' extra latencies 0, 2, 1, 3 ms order them 0, 2, 1, 3
    assert [v.camera for v in views_of(0.0, 0.0)] == [CAMERA[0], CAMERA[2], CAMERA[1], CAMERA[3]]
    assert all((v.x_m, v.y_m) == (0.0, 0.0) for v in views_of(0.0, 0.0))


def test_a_ball_in_the_air_is_seen_along_each_cameras_ray_and_the_cameras_disagree():
    # 0.1 m up at (0, 1), between cameras 0 and 1: from each scaled by 4 / 3.9 away from the point below it
    views = views_of(0.0, 1.0, 0.1)
    y = 1.525 - 0.525 * 40.0 / 39.0
    assert [v.camera for v in views] == [CAMERA[0], CAMERA[1]]
    assert (views[0].x_m, views[0].y_m) == pytest.approx((2.275 / 39.0, y), abs=1e-12)
    assert (views[1].x_m, views[1].y_m) == pytest.approx((-2.275 / 39.0, y), abs=1e-12)
    # 0.5 m up over the centre each camera sees it 8/7 as far out: 0.325 m past the axis, outside its rectangle
    assert views_of(0.0, 0.0, 0.5) == []
    assert views_of(1.0, 1.0, 4.0) == [] and views_of(1.0, 1.0, 9.0) == []  # as high as the cameras: in none


def test_the_same_cameras_as_the_ssl_geometry_and_its_views():
    splitter = SslCameraSplitter(quadrant_cameras(FIELD), FIELD, None, realism=BENCH_CAMERAS.noise_free())
    poses = {(p.camera_id, p.x_m, p.y_m, p.z_m) for p in splitter.geometry.cameras}
    assert poses == set(CAMERA.values())


def test_each_camera_adds_its_own_noise():
    cams = CameraViews(FIELD, camera_noise_m=0.01, seed=3)
    diffs = []
    for _ in range(4000):
        a, b = cams.ball_views(BallDetection(0.0, 1.0))  # cameras 0 and 1, no projection on the ground
        diffs.append(a.x_m - b.x_m)
    # independent draws: the difference has sqrt(2) times the noise (the standard error of the estimate ~1 %)
    assert statistics.fmean(diffs) == pytest.approx(0.0, abs=0.001)
    assert statistics.stdev(diffs) == pytest.approx(0.01 * 2**0.5, rel=0.05)
    again = CameraViews(FIELD, camera_noise_m=0.01, seed=3).ball_views(BallDetection(0.0, 1.0))
    assert again == CameraViews(FIELD, camera_noise_m=0.01, seed=3).ball_views(BallDetection(0.0, 1.0))
