"""The plant's ROS vision through its cameras: which camera takes the ball, where each sees it, sightings; the
same cameras as the SSL output's, erring as one CameraRealism says on both."""

import statistics
from dataclasses import replace

import pytest

from erforce_interfaces.ssl.ssl_vision import decode_wrapper
from erforce_interfaces.wire.robot_config import FieldConfig
from erforce_sim.camera_views import BallView, CameraViews
from erforce_sim.sensors import BallDetection, RobotDetection, VisionFrame
from erforce_sim.ssl_cameras import BENCH_CAMERAS, ERFORCE_REALISTIC, CameraRig, SslCameraSplitter, quadrant_cameras

FIELD = FieldConfig.preset("division_b")  # 9 x 6 m, walls 0.3 m outside the lines: inside the walls 9.6 x 6.6 m
# quadrants overlapping 0.25 m across each axis; each camera 4 m above the middle of its rectangle:
# x (-4.8 + 0.25) / 2 = -2.275 or (4.8 - 0.25) / 2 = 2.275, y -+1.525
CAMERA = {0: (0, -2.275, 1.525, 4.0), 1: (1, 2.275, 1.525, 4.0), 2: (2, -2.275, -1.525, 4.0),
          3: (3, 2.275, -1.525, 4.0)}


def frame_of(x, y, z=0.0, robots=()):
    return VisionFrame(0, 1.0, 1.015, (BallDetection(x, y, z),), tuple(robots))


def views_of(x, y, z=0.0):
    return list(CameraViews.quadrants(FIELD, BENCH_CAMERAS.noise_free()).frame_views(frame_of(x, y, z)).balls)


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
    cams = CameraViews.quadrants(FIELD, replace(BENCH_CAMERAS, ball_noise_m=0.01), seed=3)
    diffs = []
    for _ in range(4000):
        a, b = cams.frame_views(frame_of(0.0, 1.0)).balls  # cameras 0 and 1, no projection on the ground
        diffs.append(a.x_m - b.x_m)
    # independent draws: the difference has sqrt(2) times the noise (the standard error of the estimate ~1 %)
    assert statistics.fmean(diffs) == pytest.approx(0.0, abs=0.001)
    assert statistics.stdev(diffs) == pytest.approx(0.01 * 2**0.5, rel=0.05)
    again = CameraViews.quadrants(FIELD, replace(BENCH_CAMERAS, ball_noise_m=0.01), seed=3)
    assert again.frame_views(frame_of(0.0, 1.0)) == CameraViews.quadrants(
        FIELD, replace(BENCH_CAMERAS, ball_noise_m=0.01), seed=3).frame_views(frame_of(0.0, 1.0))


def test_each_robot_is_where_the_first_camera_that_reports_it_puts_it():
    """A robot at the centre is in all four rectangles: camera 0's report (its SSL frame comes first) stands for it;
    one in camera 3's quadrant alone is camera 3's; one that every camera misses is not in the frame."""
    rig = CameraRig.quadrants(FIELD, replace(BENCH_CAMERAS, robot_noise_m=0.01), seed=5)
    robots = (RobotDetection("blue", 0, 0.0, 0.0, 0.5), RobotDetection("yellow", 1, 3.0, -2.0, -1.0))
    frame = frame_of(1.0, 1.0, robots=robots)
    detections = rig.detect(frame)
    seen = CameraViews(rig).frame_views(frame, detections).robots
    first = detections[0][1][0]
    assert seen[0] == RobotDetection("blue", 0, first.x_m, first.y_m, 0.5) and (first.x_m, first.y_m) != (0.0, 0.0)
    assert [k for k in range(4) if any(r.team == "yellow" for r in detections[k][1])] == [3]
    last = detections[3][1][-1]
    assert seen[1] == RobotDetection("yellow", 1, last.x_m, last.y_m, -1.0) and len(seen) == 2
    blind = CameraViews.quadrants(FIELD, replace(ERFORCE_REALISTIC, object_offset_m=0.0, missing_robot_prob=1.0))
    assert blind.frame_views(frame).robots == ()


def test_a_camera_model_with_an_object_offset_is_refused_on_the_ros_vision():
    """ER-Force's 2 cm per camera is taken off only by the SSL bridge's alignment, which the ROS path lacks."""
    with pytest.raises(ValueError, match=r"'erforce' has a per-camera object offset \(0.02 m\).*SSL bridge"):
        CameraViews.quadrants(FIELD, ERFORCE_REALISTIC)
    CameraViews.quadrants(FIELD, replace(ERFORCE_REALISTIC, object_offset_m=0.0))


def test_both_outputs_show_one_draw_of_the_cameras():
    """With both outputs the plant detects once per frame: the ROS views are the SSL packets' balls, camera by
    camera in the order their frames come (0, 2, 1, 3), noise and misses alike."""
    rig = CameraRig.quadrants(FIELD, replace(ERFORCE_REALISTIC, object_offset_m=0.0), seed=9)
    views, splitter = CameraViews(rig), SslCameraSplitter.on_rig(rig, 0.015)
    compared = 0
    for k in range(200):
        frame = VisionFrame(k, k / 70.0, k / 70.0 + 0.015, (BallDetection(0.3, 0.4),), ())
        detections = rig.detect(frame)
        ssl = {}
        for _, data in splitter.packets(frame, detections):
            f = decode_wrapper(data).frame
            for b in f.balls:
                ssl[f.camera_id] = (b.x_m, b.y_m)
        ros = {v.camera[0]: (v.x_m, v.y_m) for v in views.frame_views(frame, detections).balls}
        assert ros.keys() == ssl.keys()
        assert [ros[c] for c in ssl] == [pytest.approx(ssl[c], abs=1e-6) for c in ssl]  # the SSL wire's float mm
        assert [v.camera[0] for v in views.frame_views(frame, detections).balls] == [
            c for c in (0, 2, 1, 3) if c in ssl]
        compared += len(ssl)
    assert compared > 600  # four cameras see (0.3, 0.4) in a 2 m band; 5 % missed each


def test_a_flying_ball_is_seen_from_where_the_camera_stands_with_the_camera_point_where_the_geometry_says():
    """ER-Force's cameras stand 0.1 m off their reported places, along (0.7, -0.3, 0.05) / |...| (vision's axes):
    camera 1, reported at (2.275, 1.525, 4), projects a ball 0.5 m up at (1, 1) from there, c + (p - c) cz / (cz -
    0.5); the view carries the reported place, as the SSL geometry does (the predictor's error on the SSL path too)."""
    norm = (0.7**2 + 0.3**2 + 0.05**2) ** 0.5
    cx, cy, cz = 2.275 - 0.1 * 0.7 / norm, 1.525 + 0.1 * 0.3 / norm, 4.0 - 0.1 * 0.05 / norm
    s = cz / (cz - 0.5)
    cams = CameraViews.quadrants(FIELD, replace(ERFORCE_REALISTIC, object_offset_m=0.0).noise_free())
    views = cams.frame_views(frame_of(1.0, 1.0, 0.5)).balls
    assert [v.camera for v in views] == [CAMERA[1]]
    assert (views[0].x_m, views[0].y_m) == pytest.approx((cx + (1.0 - cx) * s, cy + (1.0 - cy) * s), abs=1e-12)
    (bench,) = views_of(1.0, 1.0, 0.5)  # the bench's camera projects from its reported place
    assert bench.camera == CAMERA[1]
    assert (bench.x_m, bench.y_m) == pytest.approx((2.275 - 1.275 * 8.0 / 7.0, 1.525 - 0.525 * 8.0 / 7.0), abs=1e-12)
