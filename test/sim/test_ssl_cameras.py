"""The plant's SSL-Vision cameras: which camera sees what, stamps and latencies, geometry, how each camera errs."""

import math
from dataclasses import replace

import numpy as np
import pytest
from scipy.stats import binom, chi2

from erforce_ball_model.ball_model import ChipParams
from erforce_interfaces.ssl.ssl_vision import BallModelFromVision, ChipModelFromVision, decode_wrapper
from erforce_interfaces.wire.robot_config import FieldConfig
from erforce_sim.ball import BallParams
from erforce_sim.camera_views import CameraViews
from erforce_sim.plant_setup import PlantSetup, build_world
from erforce_sim.sensors import BallDetection, RobotDetection, VisionFrame, VisionParams, VisionSystem
from erforce_sim.ssl_cameras import (
    BENCH_CAMERAS,
    CAMERA_MODELS,
    ERFORCE_REALISTIC,
    SslCameraSplitter,
    chip_model_of,
    field_geometry,
    ground_point,
    quadrant_cameras,
)

FIELD = FieldConfig.preset("division_b")  # 9 x 6 m, walls 0.3 m outside the lines


def test_four_quadrants_overlap_across_the_axes_and_cover_up_to_the_walls():
    cams = quadrant_cameras(FIELD, overlap_m=0.5)
    assert [c.camera_id for c in cams] == [0, 1, 2, 3]
    assert sum(c.sees(0.0, 0.0) for c in cams) == 4  # the centre: all four
    assert sum(c.sees(0.2, 2.0) for c in cams) == 2  # within 0.25 m of x = 0: two
    assert sum(c.sees(0.3, 2.0) for c in cams) == 1
    for corner in ((4.8, 3.3), (-4.8, 3.3), (4.8, -3.3), (-4.8, -3.3)):
        assert sum(c.sees(*corner) for c in cams) == 1
    assert not any(c.sees(4.81, 0.0) for c in cams)


def test_a_wider_overlap_widens_what_a_camera_sees_not_where_it_hangs():
    """ER-Force's 1 m past each axis is a 2 m band: at x = 0.9 two cameras, at 1.1 one; the cameras stay above
    (+-2.275, +-1.525), the centres of the quadrants at the 0.5 m overlap ((4.8 - 0.25) / 2, (3.3 - 0.25) / 2)."""
    cams = quadrant_cameras(FIELD, overlap_m=2.0)
    assert sum(c.sees(0.9, 2.0) for c in cams) == 2 and sum(c.sees(1.1, 2.0) for c in cams) == 1
    assert sum(c.sees(0.9, 0.9) for c in cams) == 4
    poses = field_geometry(FIELD, cams, None).cameras
    assert [v for p in poses for v in (p.x_m, p.y_m)] == pytest.approx(
        [-2.275, 1.525, 2.275, 1.525, -2.275, -1.525, 2.275, -1.525], abs=1e-12)


def test_each_camera_sends_what_it_sees_with_its_own_latency():
    cams = quadrant_cameras(FIELD, extra_latencies_s=(0.0, 0.002, 0.001, 0.003))
    splitter = SslCameraSplitter(cams, FIELD, BallModelFromVision(-2.5, -0.3, 0.6), latency_s=0.015,
                                 realism=BENCH_CAMERAS.noise_free(), clock_offset_s=1000.0)
    frame = VisionFrame(1, 2.0, 2.015, (BallDetection(0.1, 1.0),),
                        (RobotDetection("blue", 0, -2.0, 1.0, 0.5), RobotDetection("blue", 1, 2.0, -1.0, -0.5)))
    packets = splitter.packets(frame)
    assert [release for release, _ in packets] == pytest.approx([2.015, 2.017, 2.016, 2.018])
    decoded = [decode_wrapper(data).frame for _, data in packets]
    for k, f in enumerate(decoded):
        assert f.camera_id == k and f.frame_number == 1
        assert f.t_capture_s == 1002.0 and f.t_sent_s == pytest.approx(1000.0 + packets[k][0])
    # the ball at x = 0.1, y = 1: in the upper two cameras (0: x < 0.25, 1: x > -0.25); robots one each
    assert [len(f.balls) for f in decoded] == [1, 1, 0, 0]
    assert decoded[0].balls[0].x_m == pytest.approx(0.1) and decoded[0].balls[0].y_m == pytest.approx(1.0)
    assert [[r.robot_id for r in f.robots] for f in decoded] == [[0], [], [], [1]]
    assert decoded[0].robots[0].theta_rad == pytest.approx(0.5)


def test_a_ball_in_the_air_is_seen_on_the_ground_along_the_camera_ray():
    # halfway up to a camera 4 m high: twice as far from the point below it; on the ground: where it is
    assert ground_point(1.0, 0.5, 2.0, (0.0, 0.0, 4.0)) == pytest.approx((2.0, 1.0))
    assert ground_point(1.0, 0.5, 0.0, (0.0, 0.0, 4.0)) == (1.0, 0.5)
    with pytest.raises(ValueError, match="camera height"):
        ground_point(1.0, 0.5, 4.0, (0.0, 0.0, 4.0))
    # division B quadrants: camera 0 above (-2.275, 1.525), camera 1 above (2.275, 1.525), both 4 m up
    splitter = SslCameraSplitter(quadrant_cameras(FIELD), FIELD, None, realism=BENCH_CAMERAS.noise_free())
    low = [decode_wrapper(d).frame.balls for _, d in splitter.packets(
        VisionFrame(1, 2.0, 2.015, (BallDetection(0.0, 1.0, 0.1),), ()))]
    # 0.1 m up: scaled by 4 / 3.9 from each camera: x = -+2.275 / 39, y = 1.525 - 0.525 * 40 / 39
    assert [len(b) for b in low] == [1, 1, 0, 0]
    assert (low[0][0].x_m, low[0][0].y_m) == pytest.approx((2.275 / 39.0, 1.525 - 0.525 * 40.0 / 39.0), abs=1e-6)
    assert (low[1][0].x_m, low[1][0].y_m) == pytest.approx((-2.275 / 39.0, 1.525 - 0.525 * 40.0 / 39.0), abs=1e-6)
    high = [decode_wrapper(d).frame.balls for _, d in splitter.packets(
        VisionFrame(2, 2.1, 2.115, (BallDetection(1.0, 1.0, 0.5),), ()))]
    # 0.5 m up: camera 1 sees it at 2.275 - 1.275 * 8 / 7, 1.525 - 0.525 * 8 / 7; camera 0's ray lands outside
    assert [len(b) for b in high] == [0, 1, 0, 0]
    assert (high[1][0].x_m, high[1][0].y_m) == pytest.approx((2.275 - 1.275 * 8 / 7, 1.525 - 0.6), abs=1e-6)


def test_the_geometry_packet_carries_the_field_cameras_and_ball_models():
    cams = quadrant_cameras(FIELD)
    splitter = SslCameraSplitter(cams, FIELD, BallModelFromVision(-2.5, -0.3, 0.6),
                                 chip_model=ChipModelFromVision(0.5, 0.7, 0.9))
    geometry = decode_wrapper(splitter.geometry_packet()).geometry
    assert (geometry.length_m, geometry.width_m, geometry.boundary_m) == (9.0, 6.0, 0.3)
    assert geometry.ball_model == BallModelFromVision(-2.5, -0.3, 0.6)
    assert geometry.chip_model == ChipModelFromVision(0.5, 0.7, 0.9)
    assert [c.camera_id for c in geometry.cameras] == [0, 1, 2, 3]
    assert all(c.z_m == 4.0 for c in geometry.cameras)


def test_the_plant_says_its_chip_model_and_it_is_the_chip_models_default():
    """The simulator's ball bounces with floor_restitution 0.566 and, chipped without spin, keeps 1 / (1 + 0.4) of
    its horizontal speed at the first bounce (a solid sphere that stops slipping), all of it after: what its
    geometry packet says, and the predictor's chip defaults (the same ball)."""
    chip = chip_model_of(BallParams())
    assert chip == ChipModelFromVision(0.566, 1.0 / 1.4, 1.0)
    defaults = ChipParams()
    assert (chip.damping_z, chip.damping_xy_first_hop, chip.damping_xy_other_hops) == pytest.approx(
        (defaults.damping_z, defaults.damping_xy_first_hop, defaults.damping_xy_other_hops), abs=1e-15)
    hollow = chip_model_of(BallParams(floor_restitution=0.4, inertia_factor=2.0 / 3.0))  # keeps 1 / (1 + 2/3)
    assert (hollow.damping_z, hollow.damping_xy_first_hop, hollow.damping_xy_other_hops) == pytest.approx(
        (0.4, 0.6, 1.0), abs=1e-15)


@pytest.mark.parametrize("ours", ["blue", "yellow"])
def test_each_team_goes_out_in_its_colour_with_its_own_ids(ours):
    """The plant's world with two of ours and one opponent (team_color ``ours``): every camera frame names our
    robots 0 and 1 in our colour and the opponent 0 in the other, as the SSL bridge's team_color reads them."""
    theirs = "yellow" if ours == "blue" else "blue"
    setup = PlantSetup(robot_poses=((-2.0, 1.0, 0.0), (2.0, -1.0, 0.0)), opponent_poses=((-2.0, -1.0, 0.0),),
                       our_color=ours, vision=VisionParams(robot_dropout_prob=0.0, ball_dropout_prob=0.0))
    world = build_world(setup)
    world.step(0.05)
    splitter = SslCameraSplitter(quadrant_cameras(FIELD), FIELD, None, realism=BENCH_CAMERAS.noise_free())
    seen = set()
    for frame in world.poll_vision():
        for _, data in splitter.packets(frame):
            seen |= {(r.team, r.robot_id, round(r.x_m), round(r.y_m)) for r in decode_wrapper(data).frame.robots}
    assert seen == {(ours, 0, -2, 1), (ours, 1, 2, -1), (theirs, 0, -2, -1)}


# Camera realism: the bench's shared model and ER-Force's "Realistic" per-camera model (ssl_cameras.CameraRealism)

BALL_IN_OVERLAP = (0.0, 1.5)  # seen by the upper two cameras (0: x < h, 1: x > -h) in both models, by no other
# what ER-Force's simulator's Realistic preset (config/simulator-realism/Realistic.txt) and its source say
ERF_BALL_NOISE_M, ERF_MISSING_BALL, ERF_OVERLAP_PAST_AXIS_M, ERF_POSITION_ERROR_M, ERF_OFFSET_M = (
    0.0014, 0.05, 1.0, 0.1, 0.02)
ERF_ERROR_VISION_AXES = (0.7, -0.3, 0.05)  # their (0.3, 0.7, 0.05) in vision's axes (x = their y, y = -their x)
# the plant's ROS vision takes no object offset (camera_views): ER-Force's preset without it, on both paths
ERFORCE_NO_OFFSET = replace(ERFORCE_REALISTIC, name="erforce without offset", object_offset_m=0.0)
MODELS = {**CAMERA_MODELS, ERFORCE_NO_OFFSET.name: ERFORCE_NO_OFFSET}
# (vision path, camera model): the SSL splitter's packets, decoded, and the plant's ROS views (camera_views)
PATHS_AND_MODELS = [("ssl", "bench"), ("ssl", "erforce"), ("ssl", ERFORCE_NO_OFFSET.name), ("ros", "bench"),
                    ("ros", ERFORCE_NO_OFFSET.name)]


def _erforce_offset(camera_xy: tuple[float, float]) -> tuple[float, float]:
    """ER-Force's per-camera offset of every object: 2 cm along the projecting camera's direction from the centre."""
    r = math.hypot(*camera_xy)
    return ERF_OFFSET_M * camera_xy[0] / r, ERF_OFFSET_M * camera_xy[1] / r


def _projecting_xy(nominal: tuple[float, float]) -> tuple[float, float]:
    norm = math.sqrt(sum(c * c for c in ERF_ERROR_VISION_AXES))
    return (nominal[0] - ERF_POSITION_ERROR_M * ERF_ERROR_VISION_AXES[0] / norm,
            nominal[1] - ERF_POSITION_ERROR_M * ERF_ERROR_VISION_AXES[1] / norm)


def _ball_errors(cameras, frames: int, seed: int = 3, path: str = "ssl") -> dict[int, dict[int, tuple[float, float]]]:
    """Per camera, per frame: (x, y) of what it reports of a ball at rest at BALL_IN_OVERLAP minus the truth, through
    the world's vision the model asks for (VisionSystem) and the splitter (``path`` ssl) or the ROS path's camera
    views (ros), as the plant and the bench run them."""
    params = cameras.world_vision(VisionParams())
    vision = VisionSystem(params, np.random.default_rng(seed))
    splitter = SslCameraSplitter.quadrants(FIELD, None, cameras, seed=seed)
    views = CameraViews.quadrants(FIELD, cameras, seed=seed) if path == "ros" else None
    out: dict[int, dict[int, tuple[float, float]]] = {k: {} for k in range(4)}
    for k in range(frames):
        t = k / params.rate_hz
        vision.capture(t, BALL_IN_OVERLAP, [])
        for frame in vision.poll(t + params.latency_s):
            if views is not None:
                seen = [(v.camera[0], v.x_m, v.y_m) for v in views.frame_views(frame).balls]
            else:
                frames = [decode_wrapper(data).frame for _, data in splitter.packets(frame)]
                seen = [(f.camera_id, b.x_m, b.y_m) for f in frames for b in f.balls]
            for camera_id, x, y in seen:
                out[camera_id][k] = (x - BALL_IN_OVERLAP[0], y - BALL_IN_OVERLAP[1])
    return out


def test_the_presets_are_the_cited_figures():
    assert (ERFORCE_REALISTIC.ball_noise_m, ERFORCE_REALISTIC.robot_noise_m) == (ERF_BALL_NOISE_M, 0.0013)
    assert (ERFORCE_REALISTIC.missing_ball_prob, ERFORCE_REALISTIC.missing_robot_prob) == (ERF_MISSING_BALL, 0.02)
    assert ERFORCE_REALISTIC.overlap_m == 2.0 * ERF_OVERLAP_PAST_AXIS_M  # a band 1 m either side of each axis
    assert (ERFORCE_REALISTIC.position_error_m, ERFORCE_REALISTIC.object_offset_m) == (0.1, ERF_OFFSET_M)
    assert not ERFORCE_REALISTIC.shared_world_noise
    # today's: the world's 2 mm and 2 % dropouts (VisionParams) shared, 0.5 mm per camera, 0.5 m overlap
    assert BENCH_CAMERAS.shared_world_noise and (BENCH_CAMERAS.ball_noise_m, BENCH_CAMERAS.overlap_m) == (0.0005, 0.5)
    assert (BENCH_CAMERAS.missing_ball_prob, BENCH_CAMERAS.position_error_m, BENCH_CAMERAS.object_offset_m) == (0, 0, 0)
    assert BENCH_CAMERAS.world_vision(VisionParams()) == VisionParams()
    world = ERFORCE_REALISTIC.world_vision(VisionParams())
    assert (world.position_noise_m, world.ball_dropout_prob, world.robot_dropout_prob) == (0.0, 0.0, 0.0)
    assert CAMERA_MODELS == {"bench": BENCH_CAMERAS, "erforce": ERFORCE_REALISTIC}
    with pytest.raises(ValueError, match="missing_ball_prob"):
        replace(ERFORCE_REALISTIC, missing_ball_prob=1.5)
    with pytest.raises(ValueError, match="ball_noise_m"):
        replace(ERFORCE_REALISTIC, ball_noise_m=-0.001)


def test_two_cameras_err_independently_on_one_ball_in_erforces_model_and_together_in_the_benchs():
    """Sample correlation of the two cameras' x errors over the frames both saw the ball: for independent errors its
    standard deviation is 1 / sqrt(n), so |r| < 4 / sqrt(n) (a false alarm about 6e-5); the bench's shared 2 mm
    against 0.5 mm each correlate them by 4 / (4 + 0.25) = 0.94."""
    for cameras, independent in ((ERFORCE_REALISTIC, True), (BENCH_CAMERAS, False)):
        errors = _ball_errors(cameras, 3000)
        both = sorted(set(errors[0]) & set(errors[1]))
        assert not errors[2] and not errors[3]
        n = len(both)
        r = float(np.corrcoef([errors[0][k][0] for k in both], [errors[1][k][0] for k in both])[0, 1])
        if independent:
            assert abs(r) < 4.0 / math.sqrt(n), (n, r)
        else:
            assert abs(r - 4.0 / 4.25) < 4.0 * (1.0 - (4.0 / 4.25) ** 2) / math.sqrt(n), (n, r)


@pytest.mark.parametrize(("path", "cameras"), PATHS_AND_MODELS)
def test_each_cameras_noise_is_its_models_figure(path, cameras):
    """Each camera's errors about their known mean (ER-Force: the camera's 2 cm offset; the bench and ER-Force's
    without it: none): the sum of squares over sigma^2 is chi-square with 2 n degrees of freedom (x and y), inside
    its 1e-4 tails; the same on the SSL path and the plant's ROS path."""
    model = MODELS[cameras]
    errors = _ball_errors(model, 2000, path=path)
    assert not errors[2] and not errors[3]
    if cameras == "bench":
        sigma, means = math.hypot(0.002, 0.0005), {0: (0.0, 0.0), 1: (0.0, 0.0)}
    elif cameras == ERFORCE_NO_OFFSET.name:
        sigma, means = ERF_BALL_NOISE_M, {0: (0.0, 0.0), 1: (0.0, 0.0)}
    else:
        sigma = ERF_BALL_NOISE_M
        means = {k: _erforce_offset(_projecting_xy((x, 1.525))) for k, x in ((0, -2.275), (1, 2.275))}
    for k in (0, 1):
        e = np.array(list(errors[k].values())) - means[k]
        dof = e.size
        s = float(np.sum(e**2)) / sigma**2
        assert chi2.ppf(1e-4, dof) < s < chi2.isf(1e-4, dof), (k, dof, s / dof)


@pytest.mark.parametrize(("path", "erforce"), [("ssl", ERFORCE_REALISTIC), ("ros", ERFORCE_NO_OFFSET)])
def test_each_camera_misses_the_ball_on_its_own_in_erforces_model(path, erforce):
    """Each camera loses the ball in 5 % of the frames (binomial, inside the 1e-4 tails), both at once in 0.25 %;
    the bench's 2 % dropouts are the world's: its two cameras lose the ball together, never one alone. The same on
    the SSL path and the plant's ROS path."""
    n = 4000
    errors = _ball_errors(erforce, n, path=path)
    for k in (0, 1):
        missed = n - len(errors[k])
        assert binom.ppf(1e-4, n, ERF_MISSING_BALL) <= missed <= binom.isf(1e-4, n, ERF_MISSING_BALL), (k, missed)
    both = n - len(set(errors[0]) | set(errors[1]))
    assert binom.ppf(1e-4, n, ERF_MISSING_BALL**2) <= both <= binom.isf(1e-4, n, ERF_MISSING_BALL**2), both
    bench = _ball_errors(BENCH_CAMERAS, n, path=path)
    assert set(bench[0]) == set(bench[1]) and binom.ppf(1e-4, n, 0.02) <= n - len(bench[0]) <= binom.isf(1e-4, n, 0.02)


def test_a_flying_ball_is_projected_from_the_displaced_camera_while_the_geometry_reports_the_nominal_one():
    """ER-Force reports each camera 0.1 m off where it projects from. Camera 1 is reported above (2.275, 1.525) at
    4 m; it projects from (2.275, 1.525, 4) - 0.1 (0.7, -0.3, 0.05) / |(0.7, -0.3, 0.05)|. A ball at (1, 1) 0.5 m
    up lands on its ray at c + (p - c) cz / (cz - 0.5), plus the camera's 2 cm offset; on the ground the ball is
    where it is (plus the offset), whichever camera projects it."""
    model = ERFORCE_REALISTIC.noise_free()
    splitter = SslCameraSplitter.quadrants(FIELD, None, model)
    geometry = decode_wrapper(splitter.geometry_packet()).geometry
    assert [(c.x_m, c.y_m, c.z_m) for c in geometry.cameras][1] == pytest.approx((2.275, 1.525, 4.0), abs=1e-9)
    norm = math.sqrt(0.7**2 + 0.3**2 + 0.05**2)
    cx, cy = _projecting_xy((2.275, 1.525))
    cz = 4.0 - 0.1 * 0.05 / norm
    assert (cx, cy, cz) == pytest.approx((2.275 - 0.07 / norm, 1.525 + 0.03 / norm, 4.0 - 0.005 / norm), abs=1e-12)
    ox, oy = _erforce_offset((cx, cy))
    s = cz / (cz - 0.5)
    flying = decode_wrapper(splitter.packets(VisionFrame(1, 2.0, 2.015, (BallDetection(1.0, 1.0, 0.5),), ()))[1][1])
    (ball,) = flying.frame.balls
    assert (ball.x_m, ball.y_m) == pytest.approx((cx + (1.0 - cx) * s + ox, cy + (1.0 - cy) * s + oy), abs=1e-6)
    # the geometry's camera would have put it ~1.4 cm elsewhere: the error a predictor trusting it makes
    nominal = ground_point(1.0, 1.0, 0.5, (2.275, 1.525, 4.0))
    assert 0.005 < math.hypot(ball.x_m - ox - nominal[0], ball.y_m - oy - nominal[1]) < 0.03
    ground = decode_wrapper(splitter.packets(VisionFrame(2, 2.1, 2.115, (BallDetection(1.0, 1.0, 0.0),), ()))[1][1])
    (ball,) = ground.frame.balls
    assert (ball.x_m, ball.y_m) == pytest.approx((1.0 + ox, 1.0 + oy), abs=1e-6)


def test_a_sightings_noise_is_the_world_and_the_camera_together_or_the_camera_alone():
    # shared: sqrt(2^2 + 0.5^2) mm = 2.0616 mm; per camera: the camera's own 1.4 mm
    assert BENCH_CAMERAS.sighting_noise_m(VisionParams()) == pytest.approx(0.0020616, abs=1e-7)
    assert ERFORCE_REALISTIC.sighting_noise_m(VisionParams()) == ERF_BALL_NOISE_M


def test_a_camera_model_without_its_fixed_errors_keeps_its_noise_and_says_so():
    offset_free = ERFORCE_REALISTIC.without("object_offset")
    assert offset_free == replace(ERFORCE_REALISTIC, name="erforce without object_offset", object_offset_m=0.0)
    both = ERFORCE_REALISTIC.without("position_error", "object_offset")
    assert (both.position_error_m, both.object_offset_m, both.ball_noise_m) == (0.0, 0.0, ERF_BALL_NOISE_M)
    assert ERFORCE_REALISTIC.without() is ERFORCE_REALISTIC
    with pytest.raises(ValueError, match="'noise'"):
        ERFORCE_REALISTIC.without("noise")
