"""Kick hints with the commanded speed: the kicker's launch as a prior that the cameras correct (chip_tracking).

Frames at 70 Hz from one camera 4 m above the field, without noise unless said; every expected number is derived
here from the projectile (touchdown distance ``2 tan(a) v_g^2 / g``) and the camera's ray."""

from __future__ import annotations

import math

import numpy as np
import pytest

from erforce_ball_model.ball_model import BallTrajectory, ChipParams
from erforce_ball_model.chip_model import ChipTrajectory
from erforce_ball_model.predictor import BallPredictor, PredictorConfig
from erforce_interfaces.wire.robot_config import FieldConfig, RobotConfig

G = 9.81
DT = 1.0 / 70.0
FIELD = FieldConfig.preset("division_b")
NOISE_M = 0.002  # ChipDetectorConfig.noise_m: the weight of a sighting
RATIO = 0.1  # the schema's kick_speed_std_ratio


def seen(x, y, z, camera):
    """Where a camera sees a ball at height z on the ground (the ray through it)."""
    cx, cy, cz = camera
    return cx + (x - cx) * cz / (cz - z), cy + (y - cy) * cz / (cz - z)


def run(truth, t_kick, camera, hint=None, frames=60, noise_m=0.0, seed=0, cameras=None):
    """The predictor fed the ball at rest where ``truth`` starts, kicked at ``t_kick`` (None: never); ``hint`` (t,
    angle, speed) given before the first frame after its time. The frames (t, chip or None)."""
    predictor = BallPredictor(PredictorConfig(num_robots=1, field=FIELD))
    rng = np.random.default_rng(seed)
    out = []
    for k in range(frames):
        t = k * DT
        if hint is not None and hint[0] <= t < hint[0] + DT:
            predictor.kick_hint(*hint)
        tau = -1.0 if t_kick is None else t - t_kick
        x, y, z = (truth.position_at(max(tau, 0.0)).tolist() + [0.0])[:3]
        nx, ny = rng.normal(0.0, noise_m, 2)
        for i, c in enumerate(cameras or [camera]):
            if i == 0:
                frame = predictor.ball_frame(t, *seen(x + nx, y + ny, z, c), camera_m=c)
            else:
                predictor.ball_sighting(t, *seen(x + nx, y + ny, z, c), c)
        out.append((t, None if frame is None else frame.chip, predictor))
    return out


def first_chip(frames):
    return next(((t, chip) for t, chip, _ in frames if chip is not None), (None, None))


def test_a_hinted_chips_first_touchdown_comes_from_the_command():
    """A robot at (1, -0.5) m heading 30 deg chips 4 m/s at 45 deg; the ball lay at its dribbler, 0.0815 m ahead.
    With the commanded speed the chip is reported at the second frame of the new motion (two sightings: the flight
    is known up to its direction) with the command's first touchdown, 2 tan(45) (4 cos 45)^2 / g = 1.6310 m along
    the heading from the ball; with the angle alone the fit needs four sightings. (The kick is 4 ms before frame 10,
    which moves the ball 11 mm: the flat filter takes that for noise, its new motion starts at frame 11.)"""
    heading = math.radians(30.0)
    u = np.array([math.cos(heading), math.sin(heading)])
    ball = np.array([1.0, -0.5]) + RobotConfig().dribbler_offset_m * u
    v_ground = 4.0 * math.cos(math.radians(45.0))
    truth = ChipTrajectory((*ball, 0.0), (*(v_ground * u), v_ground), ChipParams())
    camera = (2.0, 1.0, 4.0)
    t_kick = 10 * DT - 0.004
    touchdown = ball + 2.0 * v_ground**2 / G * u
    assert touchdown.tolist() == pytest.approx([2.4831, 0.3562], abs=1e-4)

    frames = run(truth, t_kick, camera, (t_kick, 45.0, 4.0))
    assert frames[-1][2].chip_detector.t_start_s == pytest.approx(11 * DT)
    t_speed, chip = first_chip(frames)
    assert t_speed == pytest.approx(12 * DT)
    assert chip.touchdown_points_m[0].tolist() == pytest.approx(touchdown.tolist(), abs=0.002)
    t_angle, _ = first_chip(run(truth, t_kick, camera, (t_kick, 45.0, None)))
    assert t_angle == pytest.approx(14 * DT)


def test_the_cameras_override_a_wrong_commanded_speed():
    """Commanded 4 m/s at 45 deg, the ball leaves at 3.4 m/s (a kicker 15 % short, 1.5 of its standard deviations).
    The fit weighs the command as one more equation of weight w = noise / (ratio v_g,cmd): linearised, its ground
    speed is off the truth by delta = Delta w^2 / (w^2 + S), Delta = (4 - 3.4) cos 45 = 0.424 m/s, S the sightings'
    information on the speed, at least sum (tau_i - mean tau)^2 for a ball moving away from the camera's nadir (a
    line's slope with its intercept free; the projection only stretches the seen path). After n frames
    S = n (n^2 - 1) / 12 dt^2; w^2 = (0.002 / 0.2828)^2 = 5.0e-5. n = 8: S = 8.57e-3, delta <= 2.5 mm/s and the
    touchdown 2 tan(a) v_g^2 / g off by 4 v_g delta / g <= 2.4 mm (bounds doubled: the linearisation). At the first
    report (n = 2, S = 1.0e-4) the touchdown lies between the truth's and the command's, nearer the truth."""
    camera = (0.0, 0.0, 4.0)  # above the launch point: the ball moves away from the nadir
    v_true, v_cmd = 3.4 * math.cos(math.radians(45.0)), 4.0 * math.cos(math.radians(45.0))
    truth = ChipTrajectory((0.0, 0.0, 0.0), (v_true, 0.0, v_true), ChipParams())
    t_kick = 10 * DT - 0.004
    d_true, d_cmd = 2.0 * v_true**2 / G, 2.0 * v_cmd**2 / G
    w2, delta = (NOISE_M / (RATIO * v_cmd)) ** 2, v_cmd - v_true
    assert w2 == pytest.approx(5.0e-5, rel=1e-3) and delta == pytest.approx(0.4243, abs=1e-4)
    frames = run(truth, t_kick, camera, (t_kick, 45.0, 4.0), frames=20)
    t_start = frames[-1][2].chip_detector.t_start_s
    t_first, chip = first_chip(frames)
    assert t_first == pytest.approx(t_start + DT)
    x_first = float(chip.touchdown_points_m[0][0])
    assert d_true < x_first < 0.5 * (d_true + d_cmd)
    n = 8  # sightings of the new motion
    s = n * (n * n - 1) / 12.0 * DT * DT
    bound_vg = 2.0 * delta * w2 / (w2 + s)
    assert bound_vg == pytest.approx(4.9e-3, abs=1e-4)
    _, chip8, _ = frames[round(t_start / DT) + n - 1]  # the chip reported then (in the air: its ground speed kept)
    assert float(np.hypot(*chip8.velocity_mps[:2])) == pytest.approx(v_true, abs=bound_vg)
    assert float(chip8.touchdown_points_m[0][0]) == pytest.approx(d_true, abs=4.0 * v_true * bound_vg / G + 1e-3)


def test_a_hint_without_a_kick_makes_no_chip():
    """The kicker says it chipped 4 m/s at 45 deg, but the ball lies still (2 mm noise) for a second, then rolls
    away flat 0.3 s after the hint (outside hint_window_s): no frame ever reports a chip."""
    rest = BallTrajectory((1.0, 0.5), (0.0, 0.0), 0.0)
    frames = run(rest, None, (0.0, 0.0, 4.0), (10 * DT, 45.0, 4.0), frames=70, noise_m=0.002, seed=3)
    assert all(chip is None for _, chip, _ in frames)
    flat = BallTrajectory((1.0, 0.5), (3.0, 0.0), 3.0)
    frames = run(flat, 10 * DT + 0.3, (0.0, 0.0, 4.0), (10 * DT, 45.0, 4.0), frames=70, noise_m=0.002, seed=3)
    assert all(chip is None for _, chip, _ in frames)


def test_a_flat_ball_under_a_chip_hint_is_no_chip():
    """The kicker says it chipped 3 m/s at 45 deg; the ball rolls flat at 3 m/s. Two cameras see it on the ground at
    once: never a chip. One camera alone (above the kick, or 1.5 m to its side): its first frames may not tell the
    flat ball from the commanded chip (the commanded ground speed 2.12 m/s, stretched by the ray, can match 3 m/s),
    but by 0.2 s after the kick the hint is dropped (the cameras contradict it) and every frame from then on is as
    without a hint (the cameras' own judgement, which takes one of these ten for a chip by chance)."""
    flat = BallTrajectory((0.5, 0.0), (3.0, 0.0), 3.0)
    t_kick = 10 * DT - 0.004
    two = run(flat, t_kick, None, (t_kick, 45.0, 3.0), frames=50, noise_m=0.002,
              cameras=[(-1.5, 1.0, 4.0), (3.0, -1.5, 4.0)])
    assert all(chip is None for _, chip, _ in two)
    for seed in range(5):
        for camera in ((0.0, 0.0, 4.0), (0.0, 1.5, 4.0)):
            hinted = run(flat, t_kick, camera, (t_kick, 45.0, 3.0), frames=50, noise_m=0.002, seed=seed)
            alone = run(flat, t_kick, camera, None, frames=50, noise_m=0.002, seed=seed)
            late = [(a[1] is None, b[1] is None) for a, b in zip(hinted, alone, strict=True) if a[0] - t_kick >= 0.2]
            assert all(a == b for a, b in late), (seed, camera)
            assert hinted[-1][2].chip_detector.hint_angle_deg is None, (seed, camera)


def test_a_bad_commanded_speed_is_refused_by_name():
    predictor = BallPredictor(PredictorConfig(num_robots=1, field=FIELD))
    for bad in (0.0, -1.0, math.nan, math.inf):
        with pytest.raises(ValueError, match="speed"):
            predictor.kick_hint(0.0, 45.0, bad)


def test_the_commanded_speed_adds_to_the_flights_information():
    """The covariance of a commanded flight (flight_covariance with the speed prior): the command is one more
    measurement of the ground speed u . v with variance s^2, so that speed's variance is the scalar Kalman update of
    the sightings' own, var s^2 / (var + s^2) (noise-free sightings and an exact command: both fits' sigma is the
    noise)."""
    from erforce_ball_model.chip_fits import fit_flight_at_angle, flight_covariance

    camera = (2.0, 1.0, 4.0)
    v = 2.0
    rows = np.array([(t, *seen(v * max(t, 0.0), 0.0, max(v * t - 0.5 * G * t * t, 0.0), camera), *camera)
                     for t in (-0.03, -0.015, 0.012, 0.026, 0.04)])  # at rest at the origin, launched at 0
    fit = fit_flight_at_angle(rows, 0.0, None, G, NOISE_M, 1.0, speed_prior=(v, 0.2))
    assert (fit.vx_mps, fit.vz_mps) == pytest.approx((v, v), abs=1e-9)
    alone = flight_covariance(rows, fit, None, G, NOISE_M, tan_angle=1.0)
    commanded = flight_covariance(rows, fit, None, G, NOISE_M, tan_angle=1.0, speed_prior=(v, 0.2))
    var = alone[2, 2]  # the ground speed along +x
    assert commanded[2, 2] == pytest.approx(var * 0.04 / (var + 0.04), rel=1e-9)
    assert var > 1e-4  # the sightings alone leave it unsure enough for the command to count
