"""Kicker plates (paper Sec. 2.2): flat plate deviates ~12 deg at 3 cm, the curved plate kicks straight."""

import math

import numpy as np
import pytest

from erforce_interfaces.wire.robot_config import FieldConfig, RobotConfig
from erforce_sim.kicker import KickerPlate, deviation_table
from erforce_sim.world import World
from erforce_sim.world_types import PhysicsParams, RobotSpec

CFG = RobotConfig()
FIELD = FieldConfig.preset("division_b")
R_BALL = 0.02135
OFFSETS = np.linspace(0.0, 0.035, 8)


def test_deviation_table_flat_vs_curved():
    rows = deviation_table(OFFSETS)
    for offset, flat_deg, curved_deg in rows:
        assert flat_deg == pytest.approx(12.0 * offset / 0.03, abs=1e-9)  # linear, 12 deg at 3 cm
        assert abs(curved_deg) < 1.0
    assert rows[-1][1] == pytest.approx(14.0)


def test_flat_deviation_is_odd_and_outward():
    flat = KickerPlate.make("flat", 0.035)
    assert flat.deviation_rad(0.02, R_BALL) > 0.0  # ball on the left leaves to the left
    assert flat.deviation_rad(-0.02, R_BALL) == pytest.approx(-flat.deviation_rad(0.02, R_BALL))


def test_curved_plate_is_concave_and_cancels_bending():
    curved = KickerPlate.make("curved", 0.035)
    ys = np.linspace(0.0, 0.04, 9)
    depth = [curved.surface(y)[0] for y in ys]
    assert depth[0] == 0.0
    assert np.all(np.diff(depth) > 0.0)  # edges stand forward: concave
    # small-angle check of the design: normal angle ~ -compliance * y, depth ~ compliance y^2 / 2
    k = math.radians(12.0) / 0.03
    assert curved.surface(0.01)[1] == pytest.approx(-k * 0.01, rel=0.01)
    assert curved.surface(0.02)[0] == pytest.approx(k * 0.02**2 / 2, rel=0.05)


def test_curved_plate_with_wrong_compliance_leaves_residual():
    curved = KickerPlate.make("curved", 0.035)
    k = math.radians(12.0) / 0.03
    residual = math.degrees(curved.deviation_rad(0.03, R_BALL, compliance_rad_per_m=1.2 * k))
    assert 1.5 < residual < 3.0  # 20 % stiffer-than-designed error leaves ~0.2 * 12 deg


def test_plate_validation():
    with pytest.raises(ValueError):
        KickerPlate.make("round", 0.035)
    with pytest.raises(ValueError):
        KickerPlate.make("flat", float("nan"))
    with pytest.raises(ValueError):
        KickerPlate.make("flat", 0.035).deviation_rad(float("inf"), R_BALL)


def world_with_ball_on_plate(plate: str, offset_m: float, theta: float = 0.4) -> World:
    w = World(FIELD, [RobotSpec(theta=theta, kicker_plate=plate)], seed=0)
    d = CFG.dribbler_offset_m
    c, s = math.cos(theta), math.sin(theta)
    w.place_ball(c * d - s * offset_m, s * d + c * offset_m)
    return w


@pytest.mark.parametrize(
    ("plate", "offset", "expected_deg"),
    [("flat", 0.03, 12.0), ("flat", -0.015, -6.0), ("curved", 0.03, 0.0), ("curved", -0.035, 0.0)],
)
def test_world_kick_direction(plate, offset, expected_deg):
    w = world_with_ball_on_plate(plate, offset)
    assert w.ball_in_dribbler(0)
    res = w.kick(0, 4.0)
    assert res.fired and not res.clamped
    assert res.offset_m == pytest.approx(offset)
    b = w.ball_state()
    assert b.speed_mps == pytest.approx(4.0)
    direction = math.degrees(math.atan2(b.vy, b.vx) - 0.4)
    assert direction == pytest.approx(expected_deg, abs=1.0 if plate == "curved" else 1e-6)
    # by default the kick gives the ball backspin w r / v = -0.4 (the paper's c_switch 0.6): it slides
    # first, its contact point at (1 + 0.4) * 4 m/s
    assert w.ball_slip_mps() == pytest.approx(5.6)
    # recoil: momentum of ball + robot is conserved by the kick
    r = w.robot_state(0)
    assert CFG.mass_kg * r.vx + 0.046 * b.vx == pytest.approx(0.0, abs=1e-12)


def test_kick_needs_ball_in_dribbler_and_can_be_armed():
    w = World(FIELD, [RobotSpec()], seed=0)
    w.place_ball(0.5, 0.0, -1.5, 0.0)  # rolling towards the robot's front
    res = w.kick(0, 3.0, armed_for_s=1.0)
    assert not res.fired and res.armed
    assert w.ball_state().vx == -1.5
    fired_at = None
    for _ in range(600):
        w.step(0.001)
        if w.ball_state().vx > 0.0:
            fired_at = w.t_s
            break
    assert fired_at is not None
    assert w.ball_state().vx == pytest.approx(3.0, abs=0.05)
    # without arming a far ball is not kicked
    w2 = World(FIELD, [RobotSpec()], seed=0)
    w2.place_ball(0.5, 0.0)
    assert not w2.kick(0, 3.0).fired
    w2.step(0.01)
    assert w2.ball_state().vx == 0.0


@pytest.mark.parametrize(("gap_mm", "seen_and_kicked"), [(3.0, True), (8.0, True), (14.0, False)])
def test_the_kicker_reaches_every_ball_the_light_barrier_sees(gap_mm, seen_and_kicked):
    # The beam lies 12 mm before the face (LightBarrierParams.beam_depth_m): a ball resting with its surface
    # 3 or 8 mm before the face crosses it, one 14 mm before does not; the firmware kicks on a broken beam, so
    # the kicker fires exactly when the barrier sees the ball.
    w = World(FIELD, [RobotSpec()], seed=0)
    w.place_ball(CFG.dribbler_offset_m + gap_mm * 1e-3, 0.0)
    w.step(0.001)
    assert w.light_barrier(0) is seen_and_kicked
    assert w.kick(0, 3.0).fired is seen_and_kicked


def test_kick_spin_sets_switch_ratio():
    w = World(FIELD, [RobotSpec()], physics=PhysicsParams(kick_spin_ratio=-0.4), seed=0)
    w.place_ball(CFG.dribbler_offset_m, 0.0)
    w.kick(0, 5.0)
    b = w.ball_state()
    assert b.wy == pytest.approx(-0.4 * 5.0 / R_BALL)  # backspin about the rolling axis
    assert w.ball_slip_mps() == pytest.approx(1.4 * 5.0)


def test_kick_input_validation():
    w = world_with_ball_on_plate("flat", 0.0)
    for bad in (float("nan"), float("inf"), -1.0):
        with pytest.raises(ValueError):
            w.kick(0, bad)
    with pytest.raises(ValueError):
        w.kick(0, 3.0, spin_ratio=2.0)
    with pytest.raises(ValueError):
        w.kick(0, 3.0, armed_for_s=-1.0)
    res = w.kick(0, 50.0)
    assert res.clamped and res.speed_mps == PhysicsParams().kick_max_speed_mps
    assert w.ball_state().speed_mps == pytest.approx(8.0)


def test_dribbler_holds_the_ball():
    w = World(FIELD, [RobotSpec()], seed=0)
    w.place_ball(CFG.dribbler_offset_m + 0.001, 0.01, 0.3, 0.0)  # touching and rolling away slowly
    w.set_dribbler(0, True)
    for _ in range(300):
        w.step(0.001)
    assert w.ball_in_dribbler(0)
    w.set_dribbler(0, False)
    w.place_ball(CFG.dribbler_offset_m + 0.001, 0.01, 0.3, 0.0)
    for _ in range(300):
        w.step(0.001)
    assert not w.ball_in_dribbler(0)
