"""The plant's SSL-Vision cameras: which camera sees what, stamps and latencies, geometry."""

import pytest

from erforce_ball_model.ball_model import ChipParams
from erforce_interfaces.ssl.ssl_vision import BallModelFromVision, ChipModelFromVision, decode_wrapper
from erforce_interfaces.wire.robot_config import FieldConfig
from erforce_sim.ball import BallParams
from erforce_sim.plant_setup import PlantSetup, build_world
from erforce_sim.sensors import BallDetection, RobotDetection, VisionFrame, VisionParams
from erforce_sim.ssl_cameras import BENCH_CAMERAS, SslCameraSplitter, chip_model_of, ground_point, quadrant_cameras

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
