"""Chipped ball (chip_model): projectile closed forms by hand, a brute-force integration, the hand-over."""

import math
import pickle

import numpy as np
import pytest

from erforce_ball_model.ball_model import BallModelParams, BallPhase, ChipParams
from erforce_ball_model.chip_model import ChipTrajectory

G = 9.81
P = ChipParams(damping_xy_first_hop=0.75, damping_xy_other_hops=0.95, min_hop_vz_mps=0.45)  # a field's


def test_first_flight_is_the_projectile_by_hand():
    # 5 m/s at 40 deg, heading 30 deg left of +x, from (1, -2) on the carpet
    v, pitch, yaw = 5.0, math.radians(40.0), math.radians(30.0)
    vh, vz = v * math.cos(pitch), v * math.sin(pitch)
    chip = ChipTrajectory((1.0, -2.0, 0.0), (vh * math.cos(yaw), vh * math.sin(yaw), vz), ChipParams())
    t_flight = 2.0 * vz / G
    assert chip.touchdown_times_s[0] == pytest.approx(t_flight, abs=1e-12)
    np.testing.assert_allclose(chip.touchdown_points_m[0],
                               [1.0 + vh * t_flight * math.cos(yaw), -2.0 + vh * t_flight * math.sin(yaw)], atol=1e-12)
    assert chip.apex_height_m == pytest.approx(vz**2 / (2.0 * G), abs=1e-12)
    assert chip.position_at(0.5 * t_flight)[2] == pytest.approx(vz**2 / (2.0 * G), abs=1e-12)
    np.testing.assert_allclose(chip.velocity_at(0.5 * t_flight), [vh * math.cos(yaw), vh * math.sin(yaw), 0.0],
                               atol=1e-12)
    np.testing.assert_allclose(chip.position_at(0.0), [1.0, -2.0, 0.0])


def test_bounces_by_hand():
    chip = ChipTrajectory((0.0, 0.0, 0.0), (4.0, 0.0, 4.0), P)
    t1 = 8.0 / G
    vz2, vx2 = 0.566 * 4.0, 0.75 * 4.0  # first bounce: damping_z and damping_xy_first_hop
    t2 = t1 + 2.0 * vz2 / G
    vz3, vx3 = 0.566 * vz2, 0.95 * vx2  # then damping_xy_other_hops
    np.testing.assert_allclose(chip.touchdown_times_s[:3], [t1, t2, t2 + 2.0 * vz3 / G], atol=1e-12)
    np.testing.assert_allclose(chip.touchdown_points_m[1], [4.0 * t1 + vx2 * (t2 - t1), 0.0], atol=1e-12)
    np.testing.assert_allclose(chip.velocity_at(t1), [vx2, 0.0, vz2], atol=1e-12)  # just after the bounce
    np.testing.assert_allclose(chip.velocity_at(t2 + 1e-9), [vx3, 0.0, vz3 - G * 1e-9], atol=1e-9)
    # hops end at the first bounce leaving < min_hop_vz_mps: 4 * 0.566^n < 0.45 first at n = 4
    assert len(chip.hops) == 4 and 4.0 * 0.566**3 >= P.min_hop_vz_mps > 4.0 * 0.566**4


def test_start_in_the_air_falling():
    # dropped from 0.5 m with 1 m/s down: lands when 0.5 - t - g t^2 / 2 = 0
    chip = ChipTrajectory((0.0, 0.0, 0.5), (2.0, 0.0, -1.0), P)
    t_land = (-1.0 + math.sqrt(1.0 + 2.0 * G * 0.5)) / G
    assert chip.touchdown_times_s[0] == pytest.approx(t_land, abs=1e-12)
    assert chip.apex_height_m == 0.5
    assert chip.velocity_at(t_land)[2] == pytest.approx(0.566 * (1.0 + G * t_land), abs=1e-12)


ROLL = BallModelParams()


def brute_force(state, t_end, params=P, ball=ROLL, dt=1e-5):
    """The same hops and roll, integrated in small steps (exact under constant acceleration), bounce at the
    step's zero crossing; the roll at the rolling deceleration. Samples every 1000 steps."""
    x, y, z, vx, vy, vz = state
    bounces, flying, out = 0, True, []
    for k in range(round(t_end / dt) + 1):
        if k % 1000 == 0:
            out.append((k * dt, x, y, z))
        if flying:
            z_new = z + vz * dt - 0.5 * G * dt * dt
            if z_new < 0.0:  # lands inside this step: fly to the touchdown, bounce, go on for the rest
                tau = (vz + math.sqrt(vz * vz + 2.0 * G * z)) / G
                v_land = G * tau - vz
                x, y = x + vx * tau, y + vy * tau
                damping = params.damping_xy_first_hop if bounces == 0 else params.damping_xy_other_hops
                vx, vy, vz, z = vx * damping, vy * damping, params.damping_z * v_land, 0.0
                bounces += 1
                if vz < params.min_hop_vz_mps:
                    flying = False
                    rest = dt - tau
                else:
                    rest = dt - tau
                    z, vz = vz * rest - 0.5 * G * rest * rest, vz - G * rest
                x, y = x + vx * rest, y + vy * rest
            else:
                x, y, z, vz = x + vx * dt, y + vy * dt, z_new, vz - G * dt
        else:
            s = math.hypot(vx, vy)
            s_new = max(s + ball.a_roll_mps2 * dt, 0.0)
            if s > 0.0:
                x, y = x + vx / s * 0.5 * (s + s_new) * dt, y + vy / s * 0.5 * (s + s_new) * dt
                vx, vy = vx / s * s_new, vy / s * s_new
    return np.array(out)


def test_brute_force_integration_agrees():
    state = (0.3, 0.2, 0.0, 2.5, -1.0, 3.5)
    ref = brute_force(state, 4.0)
    chip = ChipTrajectory(state[:3], state[3:], P)
    got = chip.position_at(ref[:, 0])
    np.testing.assert_allclose(got, ref[:, 1:], atol=1e-5)  # the roll's steps add ~2 um over 4 s


def test_hand_over_to_rolling_is_continuous():
    chip = ChipTrajectory((0.0, 0.0, 0.0), (3.0, 1.0, 3.5), P)
    t = chip.roll_start_s
    assert t == chip.touchdown_times_s[-1]
    before, after = chip.position_at(t - 1e-9), chip.position_at(t + 1e-9)
    np.testing.assert_allclose(before, after, atol=1e-8)
    np.testing.assert_allclose(chip.position_at(t), [*chip.touchdown_points_m[-1], 0.0], atol=1e-12)
    last = chip.hops[-1]
    np.testing.assert_allclose(chip.velocity_at(t + 1e-9)[:2], 0.95 * np.array([last.vx_mps, last.vy_mps]),
                               atol=1e-8)
    assert chip.velocity_at(t)[2] == 0.0
    assert chip.roll.phase is BallPhase.ROLLING  # the hops spun it up: it rolls, it does not slide
    assert chip.stop_time_s == pytest.approx(t + 0.95 * math.hypot(last.vx_mps, last.vy_mps) / 0.3)
    np.testing.assert_allclose(chip.position_at(100.0)[:2], chip.stop_point)


def test_time_below_catch_height():
    chip = ChipTrajectory((0.0, 0.0, 0.0), (2.0, 0.0, 5.0), P)
    t_low = chip.time_below_height_s()
    assert chip.position_at(t_low)[2] == pytest.approx(0.15, abs=1e-9)
    assert chip.velocity_at(t_low)[2] < 0.0
    z = chip.position_at(np.linspace(t_low, chip.roll_start_s + 1.0, 20001))[:, 2]
    assert z.max() <= 0.15 + 1e-12
    assert chip.position_at(t_low - 1e-6)[2] > 0.15
    # a hop that never reaches h: 0; a high h: 0; h = 0: the hand-over
    assert ChipTrajectory((0.0, 0.0, 0.0), (1.0, 0.0, 1.0), P).time_below_height_s() == 0.0
    assert chip.time_below_height_s(10.0) == 0.0
    assert chip.time_below_height_s(0.0) == pytest.approx(chip.roll_start_s)


def test_arrays_and_a_ball_on_the_ground():
    chip = ChipTrajectory((0.0, 0.0, 0.0), (3.0, 0.0, 3.0), P)
    t = np.linspace(0.0, 3.0, 12).reshape(3, 4)
    got = chip.position_at(t)
    assert got.shape == (3, 4, 3)
    np.testing.assert_allclose(got[1, 2], chip.position_at(float(t[1, 2])))
    rolling = ChipTrajectory((1.0, 1.0, 0.0), (2.0, 0.0, 0.0), P)
    assert rolling.hops == () and rolling.roll_start_s == 0.0
    np.testing.assert_allclose(rolling.position_at(1.0), [1.0 + 2.0 - 0.15, 1.0, 0.0])


def test_bad_input_and_immutability():
    with pytest.raises(ValueError, match="position_m"):
        ChipTrajectory((0.0, 0.0), (1.0, 0.0, 1.0), P)
    with pytest.raises(ValueError, match="velocity_mps"):
        ChipTrajectory((0.0, 0.0, 0.0), (math.nan, 0.0, 1.0), P)
    with pytest.raises(ValueError, match="height z"):
        ChipTrajectory((0.0, 0.0, -0.1), (1.0, 0.0, 1.0), P)
    with pytest.raises(ValueError, match="damping_z"):
        ChipParams(damping_z=1.0)
    with pytest.raises(ValueError, match="g_mps2"):
        ChipParams(g_mps2=0.0)
    with pytest.raises(ValueError, match="max_receive_height_m: must be <= max_catch_height_m"):
        ChipParams(max_catch_height_m=0.1, max_receive_height_m=0.12)  # a ball it can take, it can stop
    chip = ChipTrajectory((0.0, 0.0, 0.0), (3.0, 0.0, 3.0), P)
    with pytest.raises(ValueError, match="t_s"):
        chip.position_at(-1.0)
    with pytest.raises(ValueError, match="height_m"):
        chip.time_below_height_s(math.nan)
    with pytest.raises(AttributeError):
        chip.roll_start_s = 0.0
    copy = pickle.loads(pickle.dumps(chip))
    np.testing.assert_array_equal(copy.touchdown_points_m, chip.touchdown_points_m)


def test_advanced_is_the_same_ball_later():
    chip = ChipTrajectory((0.5, -0.5, 0.0), (3.0, 2.0, 4.0), P)
    t = np.linspace(0.0, 5.0, 501)
    for dt in (0.0, 0.3, chip.touchdown_times_s[0], 1.0, chip.roll_start_s, chip.roll_start_s + 0.7, 20.0):
        later = chip.advanced(dt)
        np.testing.assert_allclose(later.position_at(t), chip.position_at(t + dt), atol=1e-9)
        np.testing.assert_allclose(later.velocity_at(t + 1e-7), chip.velocity_at(t + dt + 1e-7), atol=1e-9)
        assert later.time_below_height_s(0.1) == pytest.approx(max(chip.time_below_height_s(0.1) - dt, 0.0))
        copy = pickle.loads(pickle.dumps(later))  # its hops so far stay counted
        np.testing.assert_array_equal(copy.position_at(t), later.position_at(t))


def test_a_state_after_the_first_bounce_damps_its_next_bounce_as_a_later_one():
    # 4 m/s vertical and along +x (test_bounces_by_hand): rebuilt 0.05 s after the first touchdown from its state,
    # the second bounce keeps damping_xy_other_hops (0.95) of vx2 = 0.75 * 4, not damping_xy_first_hop (0.75)
    launched = ChipTrajectory((0.0, 0.0, 0.0), (4.0, 0.0, 4.0), P)
    t1, t_state = 8.0 / G, 8.0 / G + 0.05
    vz2, vx2 = 0.566 * 4.0, 0.75 * 4.0
    state = (launched.position_at(t_state), launched.velocity_at(t_state))
    np.testing.assert_allclose(state[1], [vx2, 0.0, vz2 - G * 0.05], atol=1e-12)
    rebuilt = ChipTrajectory(*state, P, bounced=True)
    t2_after = t1 + 2.0 * vz2 / G - t_state  # the second touchdown, from the state's time
    assert rebuilt.touchdown_times_s[0] == pytest.approx(t2_after, abs=1e-12)
    np.testing.assert_allclose(rebuilt.velocity_at(t2_after + 1e-9)[0], 0.95 * vx2, atol=1e-12)
    t = np.linspace(0.0, 6.0, 601)
    np.testing.assert_allclose(rebuilt.position_at(t), launched.position_at(t + t_state), atol=1e-9)
    assert rebuilt.bounced and not launched.bounced
    assert not launched.advanced(t1 - 0.01).bounced and launched.advanced(t_state).bounced
    assert pickle.loads(pickle.dumps(launched.advanced(t_state))).bounced
    # taken as a fresh kick, it would damp by 0.75 again
    fresh = ChipTrajectory(*state, P)
    np.testing.assert_allclose(fresh.velocity_at(t2_after + 1e-9)[0], 0.75 * vx2, atol=1e-12)
    # the carried covariance's bounce (sensitivity_at) uses the same damping: a change of vx at the state
    eps = 1e-6
    nudged = ChipTrajectory(state[0], state[1] + np.array([eps, 0.0, 0.0]), P, bounced=True)
    t_after = t2_after + 0.02
    derivative = (nudged.velocity_at(t_after)[0] - rebuilt.velocity_at(t_after)[0]) / eps
    assert rebuilt.sensitivity_at(t_after)[3, 3] == pytest.approx(0.95, abs=1e-6) == pytest.approx(derivative)


def test_the_settle_distance_by_hand():
    # 4 m/s up and along the carpet (45 deg) under P: flights leave at vz = 4 * 0.566^k (k = 0..3; the 5th
    # bounce leaves 0.41 < 0.45 m/s); the 4th's apex 0.7253^2 / 2g = 0.0268 m is the last above a ball radius,
    # so the ball settles when it comes down through h in that flight
    from erforce_ball_model.chip_model import chip_settle_distance

    h = P.max_receive_height_m
    vz = [4.0 * 0.566**k for k in range(4)]
    vxy = [4.0, 4.0 * 0.75, 4.0 * 0.75 * 0.95, 4.0 * 0.75 * 0.95**2]
    assert vz[3] ** 2 / (2.0 * G) > h > (0.566 * vz[3]) ** 2 / (2.0 * G)
    tau = (vz[3] + math.sqrt(vz[3] ** 2 - 2.0 * G * h)) / G
    by_hand = sum(v * 2.0 * w / G for v, w in zip(vxy[:3], vz[:3], strict=True)) + vxy[3] * tau
    assert chip_settle_distance(4.0 * math.sqrt(2.0), 45.0, P) == pytest.approx(by_hand, abs=1e-12)
    chip = ChipTrajectory((0.0, 0.0, 0.0), (4.0, 0.0, 4.0), P)
    t = chip.time_below_height_s(h)
    assert chip.position_at(t).tolist() == pytest.approx([by_hand, 0.0, h], abs=1e-12)
    assert chip_settle_distance(0.1, 45.0, P) == 0.0  # never above a ball radius
