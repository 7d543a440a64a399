"""Light barrier (paper Sec. 3) and vision frames: geometry, latency, noise, dropouts, seeding."""

import math

import numpy as np
import pytest

from erforce_interfaces.wire.robot_config import FieldConfig, RobotConfig
from erforce_sim.kicker import beam_hit
from erforce_sim.sensors import LightBarrierParams, VisionParams
from erforce_sim.world import World
from erforce_sim.world_types import RobotSpec

CFG = RobotConfig()
FIELD = FieldConfig.preset("division_b")
R_BALL = 0.02135


def test_beam_hit_geometry():
    # beam at x = 0.07, spanning |y| <= 0.035; ball radius 0.02135
    assert beam_hit(0.0815, 0.0, R_BALL, 0.07, 0.035)
    assert not beam_hit(0.0815 + 0.011, 0.0, R_BALL, 0.07, 0.035)  # 22.5 mm from the beam: no
    # lateral: the circle reaches the segment end when |y| - chord/2 <= 0.035
    dx = 0.0115
    half_chord = math.sqrt(R_BALL**2 - dx**2)
    assert beam_hit(0.07 + dx, 0.035 + half_chord - 1e-6, R_BALL, 0.07, 0.035)
    assert not beam_hit(0.07 + dx, 0.035 + half_chord + 1e-6, R_BALL, 0.07, 0.035)


def test_light_barrier_sees_ball_in_dribbler_with_latency():
    w = World(FIELD, [RobotSpec(x=-1.0)], light_barrier=LightBarrierParams(latency_s=0.005), seed=0)
    assert not w.light_barrier(0)
    w.place_ball(-1.0 + CFG.dribbler_offset_m, 0.0)
    # the beam is sampled at the end of each step (first at t = 1 ms) and shown 5 ms later
    for _ in range(5):
        w.step(0.001)
        assert not w.light_barrier(0)
    w.step(0.001)
    assert w.light_barrier(0)
    w.place_ball(1.0, 1.0)
    for _ in range(5):
        w.step(0.001)
        assert w.light_barrier(0)
    w.step(0.001)
    assert not w.light_barrier(0)


def test_light_barrier_false_flips_seeded():
    def run(seed):
        w = World(FIELD, [RobotSpec(x=-1.0)], light_barrier=LightBarrierParams(false_flip_prob=0.2), seed=seed)
        out = []
        for _ in range(1000):
            w.step(0.001)
            out.append(w.light_barrier(0))
        return np.array(out)

    a = run(3)
    assert 0.15 < a.mean() < 0.25  # ball far away: every True is a false flip
    assert np.array_equal(a, run(3))
    assert not np.array_equal(a, run(4))


def test_light_barrier_params_validation():
    for kw in ({"latency_s": -0.1}, {"false_flip_prob": 1.5}, {"beam_depth_m": float("nan")}):
        with pytest.raises(ValueError):
            LightBarrierParams(**kw)


def make_vision_world(seed=0, **vp):
    specs = [RobotSpec(x=1.0, y=0.5, theta=0.3), RobotSpec(x=-1.0, team="blue", robot_id=2)]
    w = World(FIELD, specs, vision=VisionParams(**vp), seed=seed)
    w.place_ball(0.2, -0.3)
    return w


def collect(w, seconds):
    frames = []
    for _ in range(round(seconds * 1000)):
        w.step(0.001)
        frames += w.poll_vision()
    return frames


def test_vision_rate_latency_and_release():
    w = make_vision_world(rate_hz=70.0, latency_s=0.02, ball_dropout_prob=0.0, robot_dropout_prob=0.0)
    frames = []
    for _ in range(1000):
        w.step(0.001)
        new = w.poll_vision()
        for f in new:
            assert f.t_release_s <= w.t_s + 1e-9  # never early
            assert w.t_s - f.t_release_s < 0.001 + 1e-9  # released at the first poll after it is due
        frames += new
    caps = np.array([f.t_capture_s for f in frames])
    # frames captured at k / 70 s (to the 0.1 ms substep), released 20 ms later
    assert len(frames) == len([k for k in range(71) if k / 70.0 + 0.02 <= 1.0 + 1e-9])
    assert np.allclose(caps, np.arange(len(frames)) / 70.0, atol=1e-4 + 1e-12)
    assert all(f.t_release_s - f.t_capture_s == pytest.approx(0.02) for f in frames)
    assert [f.frame_number for f in frames] == list(range(len(frames)))


def test_vision_noise_and_dropouts():
    w = make_vision_world(
        position_noise_m=0.003, orientation_noise_rad=0.02, ball_dropout_prob=0.3, robot_dropout_prob=0.1
    )
    frames = collect(w, 4.0)
    n = len(frames)
    ball_seen = sum(len(f.balls) for f in frames)
    assert abs(ball_seen / n - 0.7) < 0.1
    yellow = [r for f in frames for r in f.robots if r.team == "yellow"]
    assert abs(len(yellow) / n - 0.9) < 0.07
    xs = np.array([r.x for r in yellow])
    ths = np.array([r.theta for r in yellow])
    assert xs.mean() == pytest.approx(1.0, abs=0.001)
    assert xs.std() == pytest.approx(0.003, rel=0.2)
    assert ths.std() == pytest.approx(0.02, rel=0.2)
    bx = np.array([b.x for f in frames for b in f.balls])
    assert bx.std() == pytest.approx(0.003, rel=0.25)


def test_vision_deterministic_per_seed():
    a = collect(make_vision_world(seed=5), 0.3)
    b = collect(make_vision_world(seed=5), 0.3)
    c = collect(make_vision_world(seed=6), 0.3)
    assert a == b
    assert a != c


def test_vision_poll_rejects_time_going_backwards():
    w = make_vision_world()
    w.step(0.01)
    w.vision.poll(0.01)
    with pytest.raises(ValueError, match="backwards"):
        w.vision.poll(0.005)
    with pytest.raises(ValueError):
        w.vision.poll(float("nan"))


def test_vision_params_validation():
    for kw in ({"rate_hz": 0.0}, {"latency_s": -1.0}, {"ball_dropout_prob": 2.0}, {"position_noise_m": float("inf")}):
        with pytest.raises(ValueError):
            VisionParams(**kw)
