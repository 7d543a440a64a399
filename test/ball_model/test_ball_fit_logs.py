"""ball_fit on logs: the plant's known ball parameters come back within 5 % from a log it wrote; kicks,
chips and ricochets are told apart; cameras are merged and false candidates ignored; the two-phase model
predicts better than a constant deceleration; the command line writes its table and PNG."""

import math

import numpy as np
import pytest

from erforce_ball_model import ball_fit
from erforce_ball_model.ball_model import BallModelParams, BallTrajectory
from erforce_interfaces.ssl.ssl_log import LogWriter, MessageType
from erforce_interfaces.ssl.ssl_proto import ssl_vision_wrapper_pb2
from erforce_sim.ball import BallParams
from erforce_sim.demo.ssl_game_log import GameConfig, write_game_log
from erforce_sim.drivetrain import GRAVITY_MPS2

FRAME_S = 1.0 / 60.0


@pytest.fixture(scope="module")
def plant_log(tmp_path_factory):
    """60 s of the plant's ball with parameters unlike the defaults: c_switch = (2.5 - 0.2) / 3.5."""
    ball = BallParams(mu_slide=3.2 / GRAVITY_MPS2, mu_roll=0.42 / GRAVITY_MPS2)
    config = GameConfig(duration_s=60.0, seed=3, ball=ball, kick_spin_ratio=-0.2)
    path = tmp_path_factory.mktemp("logs") / "plant.log.gz"
    summary = write_game_log(path, config)
    return path, summary


def test_identification_recovers_the_plants_parameters_within_5_percent(plant_log):
    path, summary = plant_log
    true = summary.true_model
    assert (true.a_slide_mps2, true.a_roll_mps2, true.c_switch) == pytest.approx((-3.2, -0.42, 2.3 / 3.5))
    track = ball_fit.track_from_log(path)
    assert track.geometry_model == true  # the log's geometry declares the plant's model
    report = ball_fit.analyse("plant", track)
    assert len(report.cut.straight) >= 0.8 * summary.shots
    fit = report.fit.params
    for name in ("a_slide_mps2", "a_roll_mps2", "c_switch"):
        assert getattr(fit, name) == pytest.approx(getattr(true, name), rel=0.05), name
    assert report.fit.a_roll_std < 0.05 * abs(true.a_roll_mps2)
    # the paper's model beats one constant deceleration from 0.5 s on
    two, const = report.errors["two-phase"], report.errors["constant deceleration"]
    for h in (0.5, 1.0, 2.0):
        assert np.median(two[h]) < 0.5 * np.median(const[h]), h


def test_constant_deceleration_stops_where_the_two_phase_model_does():
    p = BallModelParams(-2.5, -0.3, 0.6)
    c = ball_fit.constant_deceleration(p)
    # by hand: slide 5 -> 3 m/s at 2.5 m/s^2 is 3.2 m, roll 3 m/s at 0.3 m/s^2 is 15 m: 18.2 m = 25 / (2 |a|)
    assert c.a_roll_mps2 == pytest.approx(-25.0 / (2 * 18.2))
    assert float(BallTrajectory((0, 0), (5.0, 0), 5.0, c).stop_distance_m) == pytest.approx(18.2)


def _segment(t0, start, velocity, duration_s, rest_s=0.5):
    """Ball at rest at ``start`` for rest_s, then kicked with ``velocity``: frames (t, x, y)."""
    out = []
    for k in range(round(rest_s / FRAME_S)):
        out.append((t0 + k * FRAME_S, *start))
    traj = BallTrajectory(start, velocity, math.hypot(*velocity), BallModelParams())
    t_kick = t0 + rest_s
    for k in range(round(duration_s / FRAME_S)):
        out.append((t_kick + k * FRAME_S, *traj.position_at(k * FRAME_S)))
    return out


def test_cut_shots_tells_kicks_chips_and_ricochets_apart():
    rng = np.random.default_rng(1)
    frames = _segment(0.0, (0.0, 0.0), (2.0, 0.0), 6.0)  # a straight kick to rest
    t1 = frames[-1][0] + FRAME_S
    chip = _segment(t1, (-2.0, 1.0), (0.0, -2.5), 6.0)  # a chip: lifted during its first half second
    chip_kick = t1 + 0.5
    t2 = chip[-1][0] + FRAME_S
    pre = _segment(t2, (1.0, -1.0), (3.0, 0.5), 0.8)  # kicked, then it bounces off something at 0.8 s
    x_hit, y_hit = pre[-1][1], pre[-1][2]
    after = BallTrajectory((x_hit, y_hit), (-1.5, 0.4), 1.6)
    bounce = [(pre[-1][0] + k * FRAME_S, *after.position_at(k * FRAME_S)) for k in range(1, 240)]
    rows = np.array(frames + chip + pre + bounce)
    z = np.where((rows[:, 0] > chip_kick + 0.05) & (rows[:, 0] < chip_kick + 0.5), 0.2, 0.0)
    xy = rows[:, 1:] + rng.normal(0.0, 0.001, (len(rows), 2))
    cut = ball_fit.cut_shots(ball_fit.BallTrack(rows[:, 0], xy, z))
    assert (cut.chips, cut.ricochets, cut.not_straight) == (1, 1, 0)
    assert len(cut.straight) == 2  # the first kick, and the second one up to its bounce
    assert cut.straight[1].t_s[-1] < pre[-1][0] + 3 * FRAME_S


def _packet(t, camera, balls, geometry=None, z_m=None):
    p = ssl_vision_wrapper_pb2.SSL_WrapperPacket()
    d = p.detection
    d.frame_number, d.t_capture, d.t_sent, d.camera_id = 0, t, t, camera
    for x, y in balls:
        b = d.balls.add(confidence=0.9, x=x * 1e3, y=y * 1e3, pixel_x=0.0, pixel_y=0.0)
        if z_m is not None:
            b.z = z_m * 1e3
    if geometry is not None:
        f = p.geometry.field
        f.field_length, f.field_width, f.goal_width, f.goal_depth, f.boundary_width = 9000, 6000, 1000, 180, 300
        m = p.geometry.models.straight_two_phase
        m.acc_slide, m.acc_roll, m.k_switch = geometry
    return p.SerializeToString()


def test_track_merges_cameras_and_ignores_false_candidates(tmp_path):
    path = tmp_path / "two_cameras.log"
    with LogWriter(path) as log:
        for k in range(20):
            t = 1000.0 + k * FRAME_S
            x = 0.1 * k
            # camera 1 lists a reflection at the field edge first; camera 0 sees the ball 2 mm apart
            log.write(int(t * 1e9), MessageType.VISION_2014, _packet(t, 1, [(4.4, 2.9), (x + 0.001, 0.0)]))
            log.write(int(t * 1e9), MessageType.VISION_2014,
                      _packet(t, 0, [(x - 0.001, 0.0)], geometry=(-3.0, -0.4, 0.7) if k == 5 else None,
                              z_m=0.15 if k == 7 else None))  # a chipped ball in the air, as simulators say
        log.write(int(2000 * 1e9), MessageType.VISION_2014, b"\xff\xff garbage")
    track = ball_fit.track_from_log(path)
    assert track.t_s == pytest.approx(np.arange(20) * FRAME_S, abs=1e-4)
    assert track.xy_m[:, 0] == pytest.approx(0.1 * np.arange(20), abs=1e-6)
    assert track.geometry_model == BallModelParams(-3.0, -0.4, 0.7)
    assert track.z_m[7] == pytest.approx(0.15) and track.z_m[6] == 0.0
    assert track.undecodable == 1


def test_cli_prints_the_tables_and_writes_the_png(plant_log, tmp_path, capsys):
    png = tmp_path / "fit.png"
    assert ball_fit.main([str(plant_log[0]), "--png", str(png)]) == 0
    out = capsys.readouterr().out
    assert "| plant.log.gz |" in out and "constant deceleration" in out and "2 s" in out
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_cli_refuses_a_file_that_is_no_log(tmp_path, capsys):
    bad = tmp_path / "x.log"
    bad.write_bytes(b"nothing")
    assert ball_fit.main([str(bad)]) == 1
    assert "not an SSL log file" in capsys.readouterr().err
