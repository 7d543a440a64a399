"""What the predictor reports of a chip's height: the fitted flight's covariance, the flight within the kicker's
limits, and the first height of a chip seen by one camera (chip_fits.flight_covariance, within_kicker_limits,
ChipTrajectory.sensitivity_at, BallFrame.chip_covariance)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from erforce_ball_model.ball_model import ChipParams
from erforce_ball_model.chip_fits import ChipFit, flight_covariance, within_kicker_limits
from erforce_ball_model.chip_model import ChipTrajectory
from erforce_ball_model.predictor import BallPredictor, PredictorConfig
from erforce_interfaces.wire.robot_config import FieldConfig

G = 9.81
NOISE_M = 0.002
CAMERA = (2.25, 1.5, 4.0)
# (x0, y0, vx, vy, vz, t_launch): a chip along +x at 4 m/s, 60 deg, launched at 0.5 s from (1.0, 1.8)
LAUNCH = (1.0, 1.8, 2.0, 0.0, 4.0 * math.sin(math.radians(60.0)), 0.5)


def seen(p, t_s, camera=CAMERA):
    """Where the camera sees the ball of the flight ``p`` at ``t_s`` (at rest at its launch point before),
    written out here: the ray from the camera through the ball meets the ground."""
    x0, y0, vx, vy, vz, t_launch = p
    tau = max(t_s - t_launch, 0.0)
    x, y, z = x0 + vx * tau, y0 + vy * tau, vz * tau - 0.5 * G * tau * tau
    cx, cy, cz = camera
    return cx + (x - cx) * cz / (cz - z), cy + (y - cy) * cz / (cz - z)


def sightings(times, p=LAUNCH, camera=CAMERA):
    return np.array([(t, *seen(p, t, camera), *camera) for t in times])


def fit_of(p):
    return ChipFit(p[5], p[0], p[1], p[2], p[3], p[4], 0.0, 0.0)


def test_the_flights_covariance_is_the_cameras_noise_through_its_projection():
    # sigma^2 (J^T J)^-1 with J the derivative of where the camera sees the ball (finite differences of `seen`)
    # over the six unknowns: 5 frames at rest, then 8 at 70 Hz (the launch 3 ms after a frame)
    times = np.r_[0.5 - 0.003 - np.arange(5)[::-1] / 70.0, 0.5 - 0.003 + np.arange(1, 9) / 70.0]
    rows = sightings(times)
    cov = flight_covariance(rows, fit_of(LAUNCH), None, G, NOISE_M)
    jac = np.zeros((2 * len(times), 6))
    for j in range(6):
        step = np.zeros(6)
        step[j] = 1e-6
        hi = np.array([seen(np.add(LAUNCH, step), t) for t in times])
        lo = np.array([seen(np.subtract(LAUNCH, step), t) for t in times])
        jac[:, j] = ((hi - lo) / 2e-6).T.reshape(-1)  # all x, then all y (the order does not matter)
    expected = NOISE_M**2 * np.linalg.inv(jac.T @ jac)
    assert cov == pytest.approx(expected, rel=1e-5, abs=1e-12)
    # one camera: to first order it sees v + k vz (k = (p0 - c) / cz, here (-0.3125, 0.075)), so vz is known
    # poorly (> 1 m/s from 8 frames) and the ground speed trades with it along -k: vx by 0.3125 per m/s of vz
    std = np.sqrt(np.diag(cov))
    assert std[4] > 1.0
    assert cov[2, 4] / (std[2] * std[4]) > 0.99 and cov[3, 4] / (std[3] * std[4]) < -0.99
    assert std[2] / std[4] == pytest.approx(0.3125, rel=0.2) and std[3] / std[4] == pytest.approx(0.075, rel=0.2)


def test_at_a_known_elevation_the_flight_has_five_unknowns():
    # a kick hint's fit (vz = tan(60 deg) |v|): the same projection's Jacobian over (x0, y0, vx, vy, t_launch)
    tan_angle = math.tan(math.radians(60.0))
    times = np.r_[0.5 - 0.003 - np.arange(5)[::-1] / 70.0, 0.5 - 0.003 + np.arange(1, 5) / 70.0]
    cov = flight_covariance(sightings(times), fit_of(LAUNCH), None, G, NOISE_M, tan_angle=tan_angle)

    def seen_at_angle(q, t):
        x0, y0, vx, vy, t_launch = q
        return seen((x0, y0, vx, vy, tan_angle * math.hypot(vx, vy), t_launch), t)

    free = np.array([LAUNCH[0], LAUNCH[1], LAUNCH[2], LAUNCH[3], LAUNCH[5]])
    jac = np.zeros((2 * len(times), 5))
    for j in range(5):
        step = np.zeros(5)
        step[j] = 1e-6
        hi = np.array([seen_at_angle(free + step, t) for t in times])
        lo = np.array([seen_at_angle(free - step, t) for t in times])
        jac[:, j] = ((hi - lo) / 2e-6).T.reshape(-1)
    expected = NOISE_M**2 * np.linalg.inv(jac.T @ jac)
    keep = [0, 1, 2, 3, 5]
    assert cov[np.ix_(keep, keep)] == pytest.approx(expected, rel=1e-5, abs=1e-12)
    # along +x vz moves with vx alone: var(vz) = tan^2 var(vx); far surer than the free fit's from these frames
    assert cov[4, 4] == pytest.approx(tan_angle**2 * cov[2, 2], rel=1e-9)
    free_cov = flight_covariance(sightings(times), fit_of(LAUNCH), None, G, NOISE_M)
    assert 5.0 * math.sqrt(cov[4, 4]) < math.sqrt(free_cov[4, 4])


def test_every_sighting_twice_halves_the_variances():
    # sigma^2 / N: the same sightings from a second camera at the same place double N
    times = np.r_[0.49, 0.495, 0.5 + np.arange(1, 8) / 70.0]
    rows = sightings(times)
    once = flight_covariance(rows, fit_of(LAUNCH), None, G, NOISE_M)
    twice = flight_covariance(np.concatenate([rows, rows]), fit_of(LAUNCH), None, G, NOISE_M)
    assert twice == pytest.approx(once / 2.0, rel=1e-9, abs=1e-15)


def test_a_fit_explaining_its_sightings_worse_than_the_noise_widens_by_its_residual():
    times = np.r_[0.49, 0.495, 0.5 + np.arange(1, 8) / 70.0]
    rows = sightings(times)
    exact = flight_covariance(rows, fit_of(LAUNCH), None, G, NOISE_M)
    # every sighting 10 noise standard deviations off in x, alternately: the residual's sigma replaces the noise
    off = rows.copy()
    off[:, 1] += 10.0 * NOISE_M * (-1.0) ** np.arange(len(rows))
    widened = flight_covariance(off, fit_of(LAUNCH), None, G, NOISE_M)
    assert np.all(np.diag(widened) > 10.0 * np.diag(exact))


def test_the_sensitivity_along_the_hops_is_the_flights_derivative():
    params = ChipParams()
    start = np.array([1.0, 1.8, 0.0, 2.0, 0.5, 3.0])  # (x, y, z, vx, vy, vz)
    chip = ChipTrajectory(start[:3], start[3:], params)
    first, second = chip.touchdown_times_s[:2]
    for t in (0.1, 0.5 * first, first + 0.3 * (second - first)):  # in the first flight and after a bounce
        numeric = np.zeros((6, 6))
        for j in range(6):
            step = np.zeros(6)
            step[j] = 1e-6
            if j == 2:  # a ball a little above the ground: only upwards
                plus = ChipTrajectory(start[:3] + step[:3], start[3:], params)
                numeric[:, j] = (np.r_[plus.position_at(t), plus.velocity_at(t)]
                                 - np.r_[chip.position_at(t), chip.velocity_at(t)]) / 1e-6
                continue
            hi = ChipTrajectory(start[:3] + step[:3], start[3:] + step[3:], params)
            lo = ChipTrajectory(start[:3] - step[:3], start[3:] - step[3:], params)
            numeric[:, j] = (np.r_[hi.position_at(t), hi.velocity_at(t)]
                             - np.r_[lo.position_at(t), lo.velocity_at(t)]) / 2e-6
        assert chip.sensitivity_at(t) == pytest.approx(numeric, abs=2e-4), t
    with pytest.raises(ValueError, match="in the air"):
        chip.sensitivity_at(chip.roll_start_s + 0.1)


def test_a_fit_within_the_kickers_limits_stays_and_one_beyond_them_moves_in():
    launch = np.array(LAUNCH)
    small = np.diag([1e-6, 1e-6, 1e-4, 1e-4, 1e-4, 1e-6])
    mean, cov = within_kicker_limits(launch, small, 15.0, 75.0)
    assert np.array_equal(mean, launch) and np.array_equal(cov, small)
    # vz known to +-2 m/s only, at 7 m/s: most of it is beyond 6.5 m/s (with vx 2 m/s: vz <= 6.185 m/s); the mean
    # of what is left is below that, and the distance the limits moved it counts in its variance
    fast = launch.copy()
    fast[4] = 7.0
    wide = small.copy()
    wide[4, 4] = 4.0
    mean, cov = within_kicker_limits(fast, wide, 15.0, 75.0)
    assert 2.0 < mean[4] < math.sqrt(6.5**2 - 4.0)
    assert (mean[4] - 7.0) ** 2 < cov[4, 4] < (mean[4] - 7.0) ** 2 + 4.0
    # the rest (uncorrelated with vz here) stays within a third of its standard error (1 mm, 1 ms)
    assert mean[[0, 1, 5]] == pytest.approx(launch[[0, 1, 5]], abs=3e-4)
    assert within_kicker_limits(np.r_[launch[:4], 30.0, launch[5]], small, 15.0, 75.0) is None


FIELD = FieldConfig.preset("division_b")
CHIP = ChipTrajectory((1.0, 1.8, 0.0), (2.0, 0.0, LAUNCH[4]), ChipParams())  # the demo graph's chip
APEX_M = LAUNCH[4] ** 2 / (2.0 * G)


def first_reported_height(seed: int):
    """The plant's vision (2 mm) and the +x +y quadrant camera (0.5 mm) see CHIP, one camera's ball per capture
    into the predictor; the first frame with phase chip and z above 5 cm: (z, true z, z's standard error)."""
    from erforce_interfaces.ssl.ssl_vision import decode_wrapper
    from erforce_sim.sensors import VisionParams, VisionSystem
    from erforce_sim.ssl_cameras import SslCameraSplitter, quadrant_cameras

    rng = np.random.default_rng(seed)
    vision_params = VisionParams()
    vision = VisionSystem(vision_params, rng)
    splitter = SslCameraSplitter(quadrant_cameras(FIELD), FIELD, None, seed=seed)
    cameras = {c.camera_id: (c.x_m, c.y_m, c.z_m) for c in splitter.geometry.cameras}
    predictor = BallPredictor(PredictorConfig(num_robots=1, field=FIELD))
    period = 1.0 / vision_params.rate_hz
    t_kick = 0.3 + rng.uniform(0.0, period)
    for k in range(int((t_kick + CHIP.touchdown_times_s[0]) / period)):
        t = k * period
        x, y, z = CHIP.position_at(max(t - t_kick, 0.0)).tolist()
        vision.capture(t, (x, y), [], z)
        frames = vision.poll(t + vision_params.latency_s)
        packets = sorted(splitter.packets(frames[0]), key=lambda p: p[0]) if frames else []
        balls = [(bx, by, cameras[d.camera_id]) for d in (decode_wrapper(p).detection for _, p in packets)
                 for bx, by, *_ in d.balls.tolist()]
        if not balls:
            continue
        frame = predictor.ball_frame(t, balls[0][0], balls[0][1], camera_m=balls[0][2])
        if frame is not None and frame.phase == "chip" and frame.z_m > 0.05:
            return frame.z_m, float(CHIP.position_at(t - t_kick)[2]), frame.z_std_m
    return None


def test_the_first_height_of_a_chip_one_camera_sees_is_one_its_flight_can_have():
    # test_chip_on_the_graph's chip: a height between the ground and the apex (+5 cm) in >= 99 % of the seeds, and
    # its error within 3 of its own standard errors
    results = [first_reported_height(seed) for seed in range(300)]
    seen_chips = [r for r in results if r is not None]
    assert len(seen_chips) >= 285
    within = sum(0.0 < z <= APEX_M + 0.05 for z, _, _ in seen_chips)
    assert within >= 0.99 * len(seen_chips), sorted(z for z, _, _ in seen_chips)[-5:]
    honest = sum(abs(z - truth) <= 3.0 * std for z, truth, std in seen_chips)
    assert honest >= 0.99 * len(seen_chips)
