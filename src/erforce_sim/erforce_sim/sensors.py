"""Simulated sensors outside the motor boards: SSL-Vision-like camera frames and the light barrier
signal path (paper Sec. 3: a linear light barrier detects the ball in the dribbler).

Vision: frames at ``rate_hz`` (60-75 Hz in SSL, 70 Hz default), captured from ground truth at the
substep that crosses each capture time, stamped with that capture time and released ``latency_s``
later; Gaussian position/orientation noise and per-object dropouts, all from one seeded numpy
Generator, so runs repeat exactly for a seed. Frames are plain frozen dataclasses.

Light barrier: the geometric beam state (kicker.beam_hit) is sampled once per world step, delayed by
``latency_s`` and flipped with probability ``false_flip_prob`` per sample (seeded). No rclpy import.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np

from erforce_interfaces.runtime.param_schema import schema_defaults
from erforce_interfaces.wire.robot_config import VISION_NOISE_M

_PLANT = schema_defaults("erforce_sim", "plant")  # the plant node's defaults


def _check(name: str, value: float, lo: float, hi: float = math.inf, lo_open: bool = False) -> None:
    ok = isinstance(value, int | float) and math.isfinite(value) and (value > lo if lo_open else value >= lo)
    if not ok or value > hi:
        raise ValueError(f"{name}: must be finite in {'(' if lo_open else '['}{lo}, {hi}], got {value!r}")


@dataclass(frozen=True)
class VisionParams:
    rate_hz: float = _PLANT["vision_rate_hz"]
    latency_s: float = _PLANT["vision_latency_s"]
    position_noise_m: float = VISION_NOISE_M
    orientation_noise_rad: float = 0.01
    ball_dropout_prob: float = _PLANT["vision_dropout"]
    robot_dropout_prob: float = 0.01

    def __post_init__(self) -> None:
        _check("VisionParams.rate_hz", self.rate_hz, 0.0, 1000.0, lo_open=True)
        _check("VisionParams.latency_s", self.latency_s, 0.0, 10.0)
        _check("VisionParams.position_noise_m", self.position_noise_m, 0.0, 1.0)
        _check("VisionParams.orientation_noise_rad", self.orientation_noise_rad, 0.0, math.pi)
        _check("VisionParams.ball_dropout_prob", self.ball_dropout_prob, 0.0, 1.0)
        _check("VisionParams.robot_dropout_prob", self.robot_dropout_prob, 0.0, 1.0)


@dataclass(frozen=True)
class BallDetection:
    x: float
    y: float
    z: float = 0.0  # true height of the centre above its resting height (a camera sees it projected: ssl_cameras)


@dataclass(frozen=True)
class RobotDetection:
    team: str
    robot_id: int
    x: float
    y: float
    theta: float


@dataclass(frozen=True)
class VisionFrame:
    frame_number: int
    t_capture_s: float  # world time the image was taken
    t_release_s: float  # world time the frame becomes available (capture + latency)
    balls: tuple[BallDetection, ...]
    robots: tuple[RobotDetection, ...]


class VisionSystem:
    """Captures frames from ground truth and releases them after the latency (``poll``)."""

    def __init__(self, params: VisionParams, rng: np.random.Generator) -> None:
        self.params = params
        self._rng = rng
        self._period = 1.0 / params.rate_hz
        self._frame_number = 0
        self.next_capture_s = 0.0
        self._pending: deque[VisionFrame] = deque()
        self._last_poll_s = -math.inf

    def capture(
        self,
        t_s: float,
        ball_xy: tuple[float, float],
        robots: list[tuple[str, int, float, float, float]],
        ball_z_m: float = 0.0,
    ) -> None:
        """Take one frame now (called by World at the substep crossing ``next_capture_s``)."""
        p, rng = self.params, self._rng
        balls: tuple[BallDetection, ...] = ()
        if rng.random() >= p.ball_dropout_prob:
            nx, ny = rng.normal(0.0, p.position_noise_m, 2) if p.position_noise_m > 0 else (0.0, 0.0)
            balls = (BallDetection(ball_xy[0] + float(nx), ball_xy[1] + float(ny), ball_z_m),)
        dets = []
        for team, rid, x, y, th in robots:
            if rng.random() < p.robot_dropout_prob:
                continue
            if p.position_noise_m > 0:
                nx, ny = rng.normal(0.0, p.position_noise_m, 2)
            else:
                nx = ny = 0.0
            nth = rng.normal(0.0, p.orientation_noise_rad) if p.orientation_noise_rad > 0 else 0.0
            th_m = math.remainder(th + float(nth), 2.0 * math.pi)
            dets.append(RobotDetection(team, rid, x + float(nx), y + float(ny), th_m))
        self._pending.append(VisionFrame(self._frame_number, t_s, t_s + p.latency_s, balls, tuple(dets)))
        self._frame_number += 1
        self.next_capture_s = self._frame_number * self._period

    def poll(self, now_s: float) -> list[VisionFrame]:
        """Frames whose release time is <= now_s, oldest first (each returned once)."""
        if not math.isfinite(now_s):
            raise ValueError(f"poll: now_s must be finite, got {now_s!r}")
        if now_s < self._last_poll_s:
            raise ValueError(f"poll: time went backwards ({now_s} < {self._last_poll_s})")
        self._last_poll_s = now_s
        out = []
        while self._pending and self._pending[0].t_release_s <= now_s + 1e-12:
            out.append(self._pending.popleft())
        return out


@dataclass(frozen=True)
class LightBarrierParams:
    beam_depth_m: float = 0.012  # beam in front of the robot's front face, into the touching ball
    latency_s: float = 0.0
    false_flip_prob: float = 0.0  # per sample (one sample per world step)

    def __post_init__(self) -> None:
        _check("LightBarrierParams.beam_depth_m", self.beam_depth_m, 0.0, 0.1)
        _check("LightBarrierParams.latency_s", self.latency_s, 0.0, 1.0)
        _check("LightBarrierParams.false_flip_prob", self.false_flip_prob, 0.0, 1.0)


class LightBarrierSignal:
    """Delay line + false flips for one robot's beam signal."""

    def __init__(self, params: LightBarrierParams, rng: np.random.Generator) -> None:
        self.params = params
        self._rng = rng
        self._history: deque[tuple[float, bool]] = deque()
        self._last_delayed = False
        self.value = False

    def sample(self, t_s: float, beam_interrupted: bool) -> None:
        p = self.params
        self._history.append((t_s, beam_interrupted))
        # the output is the newest sample that is at least latency_s old
        delayed = None
        while self._history and self._history[0][0] <= t_s - p.latency_s + 1e-12:
            delayed = self._history.popleft()[1]
        if delayed is None:
            delayed = self._last_delayed
        self._last_delayed = delayed
        flip = p.false_flip_prob > 0.0 and self._rng.random() < p.false_flip_prob
        self.value = (not delayed) if flip else delayed
