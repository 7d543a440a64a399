"""Ball from forces: the two-phase behaviour (paper Sec. 5) must emerge from friction physics."""

import math

import numpy as np
import pytest

from erforce_interfaces.wire.robot_config import FieldConfig
from erforce_sim.ball import BallParams, BallState
from erforce_sim.world import World

G = 9.81
FIELD = FieldConfig.preset("division_a")


def shoot(v0: float, spin_ratio: float = 0.0, ball_params: BallParams | None = None, dt: float = 0.001):
    """Free ball shot along +x; returns (times, speeds, slips) sampled every dt until it rests."""
    w = World(FIELD, [], ball_params=ball_params, seed=0)
    w.place_ball(-5.5, 0.0, v0, 0.0, spin_ratio=spin_ratio)
    ts, vs, slips = [0.0], [v0], [w.ball_slip_mps()]
    while w.ball_state().speed_mps > 0.0 and w.t_s < 30.0:
        w.step(dt)
        ts.append(w.t_s)
        vs.append(w.ball_state().speed_mps)
        slips.append(w.ball_slip_mps())
    return np.array(ts), np.array(vs), np.array(slips), w


def switch_speed(vs: np.ndarray, slips: np.ndarray, a_slide: float, a_roll: float, dt: float) -> float:
    """Speed at which slip vanished, reconstructed from the samples around the switch."""
    k = int(np.argmax(slips < 1e-9))  # first sample rolling
    v_prev = vs[k - 1]  # still sliding at the previous sample; it decelerates at a_slide for tau, then a_roll
    tau = (v_prev - vs[k] - a_roll * dt) / (a_slide - a_roll)
    return v_prev - a_slide * tau


@pytest.mark.parametrize(("factor", "expected"), [(0.4, 5.0 / 7.0), (2.0 / 3.0, 3.0 / 5.0)])
def test_switch_ratio_from_inertia(factor, expected):
    bp = BallParams(inertia_factor=factor)
    _, vs, slips, _ = shoot(4.0, ball_params=bp)
    v_switch = switch_speed(vs, slips, bp.a_slide_mps2, bp.a_roll_mps2, 0.001)
    # expected = 1 / (1 + I/(m r^2)) derived by hand: solid 5/7, hollow 3/5
    assert v_switch / 4.0 == pytest.approx(expected, abs=1e-4)


def test_backspin_moves_switch_ratio_to_paper_value():
    # s0 = w r / v = -0.4: slip0 = 1.4 v0, slip rate 3.5 a_slide -> t = 0.4 v0 / a_slide -> v = 0.6 v0
    _, vs, slips, _ = shoot(5.0, spin_ratio=-0.4)
    v_switch = switch_speed(vs, slips, 2.5, 0.3, 0.001)
    assert v_switch / 5.0 == pytest.approx(0.6, abs=1e-4)


def test_slide_and_roll_decelerations():
    ts, vs, slips, _ = shoot(3.3)
    sliding = slips > 1e-9
    rolling = (~sliding) & (vs > 0.05)
    a_slide = -np.polyfit(ts[sliding][:-1], vs[sliding][:-1], 1)[0]
    a_roll = -np.polyfit(ts[rolling][1:], vs[rolling][1:], 1)[0]
    assert a_slide == pytest.approx(0.255 * G, rel=2e-3)  # mu_slide g with mu_slide = 2.5/9.81
    assert a_roll == pytest.approx(0.3, rel=1e-3)


def test_rolling_deceleration_follows_configuration():
    bp = BallParams(mu_roll=0.05)
    ts, vs, slips, _ = shoot(2.0, spin_ratio=1.0, ball_params=bp)
    assert np.all(slips < 1e-9)
    moving = vs > 0.05
    assert -np.polyfit(ts[moving], vs[moving], 1)[0] == pytest.approx(0.05 * G, rel=1e-3)


def test_ball_stops_without_jitter():
    _, _, _, w = shoot(1.0, spin_ratio=1.0)
    rest = w.ball_state()
    # a rolling ball travels v^2 / (2 a_roll) before it stops
    assert rest.x - (-5.5) == pytest.approx(1.0 / (2 * 0.3), rel=1e-3)
    for _ in range(200):
        w.step(0.001)
        assert w.ball_state() == rest


def test_sliding_contact_point_slip_keeps_direction():
    w = World(FIELD, [], seed=0)
    w.set_ball_state(BallState(0.0, 0.0, 2.0, 1.0, wx=30.0, wy=-20.0))
    angle0 = math.atan2(1.0 + 0.02135 * 30.0, 2.0 - 0.02135 * -20.0)  # slip = v + w x (-r z)
    for _ in range(50):
        w.step(0.001)
        b = w.ball_state()
        sx, sy = b.vx - 0.02135 * b.wy, b.vy + 0.02135 * b.wx
        if math.hypot(sx, sy) < 1e-9:
            break
        assert math.atan2(sy, sx) == pytest.approx(angle0, abs=1e-9)


def test_wall_ricochet_reverses_normal_velocity_with_restitution():
    w = World(FIELD, [], seed=0)
    hx = FIELD.wall_half_length_m
    w.place_ball(hx - 0.1, 0.0, 2.0, 0.0, spin_ratio=1.0)
    v_before = None
    for _ in range(200):
        b = w.ball_state()
        w.step(0.0005)
        if w.ball_state().vx < 0 and v_before is None:
            v_before = b.vx
            v_after = w.ball_state().vx
    assert v_before is not None
    # restitution 0.6 on the normal velocity (a substep of friction at most changes it by a_slide*dt)
    assert -v_after / v_before == pytest.approx(0.6, abs=0.01)
    # the topspin now opposes the motion: the ball slides and the slip decays afterwards
    assert w.ball_slip_mps() >= 0.0
    assert w.ball_state().x < hx - 0.02135


def test_ball_energy_never_increases():
    w = World(FIELD, [], seed=0)
    w.place_ball(-5.5, 0.0, 5.0, 0.5, spin_ratio=-0.8)
    energies = [w.energy().total_j]
    while w.ball_state().speed_mps > 0.0:
        w.step(0.002)
        energies.append(w.energy().total_j)
    assert np.all(np.diff(energies) <= 1e-15)
    b = w.ball_state()  # at rest only the vertical spin from the wall contact is left
    assert energies[-1] == pytest.approx(0.5 * BallParams().inertia_kgm2 * b.wz**2, abs=1e-15)


@pytest.mark.parametrize("bad", [float("nan"), float("inf"), -0.1, 0.0])
def test_ball_params_reject_bad_values(bad):
    with pytest.raises(ValueError):
        BallParams(mu_slide=bad)
    with pytest.raises(ValueError):
        BallParams(radius_m=bad)


def test_ball_state_rejects_non_finite():
    with pytest.raises(ValueError):
        BallState(0.0, float("nan"))
