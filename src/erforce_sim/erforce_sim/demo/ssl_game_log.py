"""ssl_game_log: write a synthetic game from our plant's ball physics as an SSL log file.

The ball is the plant's (erforce_sim.world: sliding with backspin, rolling, walls). A kicker plays
it: the ball is placed at rest, lies still for ``rest_s``, and is kicked flat with a random speed
and direction (``place_ball`` with the kick's spin ratio) such that the two-phase model says it stops
inside the field; the next kick comes ``rest_s`` after it stopped (or after ``max_shot_s``).
The plant's vision (noise, dropouts, latency) observes it. Twelve scripted robots (6 per team,
smooth loops, no contacts: simulating their drive trains would cost 20x the ball) fill the frames,
so packets have a game's size. The plant's four quadrant cameras (``ssl_cameras``) each send their
part of every frame as an ``SSL_WrapperPacket`` (``VISION_2014`` records, the shared encoder of
``erforce_interfaces.ssl.ssl_vision``); a geometry packet (field size, cameras and the true ball model as
``SSL_BallModelStraightTwoPhase``) goes out once a second, a referee message (``REFBOX_2013``) at 10 Hz.

The true ball parameters are known: a_slide = -mu_slide g, a_roll = -mu_roll g, and
c_switch = BallParams.switch_ratio(kick spin ratio); ``ball_fit`` should recover them.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from erforce_ball_model.ball_model import BallModelParams, BallTrajectory
from erforce_interfaces.runtime.param_schema import schema_defaults
from erforce_interfaces.ssl.ssl_log import LogWriter, MessageType
from erforce_interfaces.ssl.ssl_proto import ssl_gc_referee_message_pb2
from erforce_interfaces.ssl.ssl_vision import (
    BallCandidate,
    BallModelFromVision,
    CameraFrame,
    RobotSighting,
    encode_frame,
    encode_geometry,
)
from erforce_interfaces.wire.robot_config import BALL_A_ROLL_MPS2, BALL_A_SLIDE_MPS2, FIELD_PRESET, FieldConfig
from erforce_sim.ball import BallParams
from erforce_sim.sensors import VisionParams
from erforce_sim.ssl_cameras import field_geometry, quadrant_cameras
from erforce_sim.world import World

_PLANT = schema_defaults("erforce_sim", "plant")

EPOCH_S = 1_700_000_000.0  # the vision host's clock at game time 0 (t_capture is wall time)
ROBOTS_PER_TEAM = 6
REFEREE_PERIOD_S = 0.1
GEOMETRY_PERIOD_S = 1.0


@dataclass(frozen=True)
class GameConfig:
    duration_s: float = 600.0
    field_preset: str = FIELD_PRESET
    seed: int = _PLANT["seed"]
    ball: BallParams = field(default_factory=BallParams)
    kick_spin_ratio: float = _PLANT["kick_spin_ratio"]
    kick_speed_mps: tuple[float, float] = (1.0, 4.5)
    rest_s: float = 0.5
    max_shot_s: float = 15.0
    vision: VisionParams = field(default_factory=lambda: VisionParams(rate_hz=60.0))
    step_s: float = 0.005

    def __post_init__(self) -> None:
        if not (math.isfinite(self.duration_s) and 0.0 < self.duration_s <= 24 * 3600.0):
            raise ValueError(f"duration_s must be in (0, 86400], got {self.duration_s!r}")
        lo, hi = self.kick_speed_mps
        if not 0.1 <= lo <= hi <= 8.0:
            raise ValueError(f"kick_speed_mps must satisfy 0.1 <= low <= high <= 8, got {self.kick_speed_mps!r}")
        if not -1.0 <= self.kick_spin_ratio <= 1.0:
            raise ValueError(f"kick_spin_ratio must be in [-1, 1], got {self.kick_spin_ratio!r}")

    @property
    def true_model(self) -> BallModelParams:
        """The two-phase parameters the plant's ball follows."""
        return BallModelParams(-self.ball.a_slide_mps2, -self.ball.a_roll_mps2,
                               self.ball.switch_ratio(self.kick_spin_ratio))


@dataclass(frozen=True)
class GameSummary:
    path: Path
    duration_s: float
    shots: int
    records: int
    true_model: BallModelParams


def scripted_robots(t_s: float, field_config: FieldConfig) -> list[tuple[str, int, float, float, float]]:
    """(team, id, x, y, heading) of the extras: each drives a loop of 0.4 m radius around its post."""
    out = []
    hx, hy = 0.7 * field_config.half_length_m, 0.7 * field_config.half_width_m
    for team, side in (("yellow", 1.0), ("blue", -1.0)):
        for k in range(ROBOTS_PER_TEAM):
            cx = side * hx * (0.25 + 0.75 * (k % 3) / 2.0)
            cy = hy * (-0.6 if k < 3 else 0.6)
            phase = 0.3 * t_s + k
            out.append((team, k, cx + 0.4 * math.cos(phase), cy + 0.4 * math.sin(phase),
                        math.remainder(phase + math.pi / 2, 2 * math.pi)))
    return out


def frame_packets(frame, robots, cameras, frame_numbers: list[int], latency_s: float) -> list[bytes]:
    """One detection datagram per camera for a world frame (the shared SSL-Vision encoder)."""
    out = []
    t_capture = EPOCH_S + frame.t_capture_s
    for k, cam in enumerate(cameras):
        balls = tuple(BallCandidate(b.x, b.y, 0.95) for b in frame.balls if cam.sees(b.x, b.y))
        seen = tuple(RobotSighting(team, rid, x, y, th, 0.9) for team, rid, x, y, th in robots if cam.sees(x, y))
        frame_numbers[k] += 1
        out.append(encode_frame(CameraFrame(cam.camera_id, frame_numbers[k], t_capture, t_capture + latency_s,
                                            balls, seen)))
    return out


def referee_packet(t_s: float, duration_s: float, counter: int) -> bytes:
    ref = ssl_gc_referee_message_pb2.Referee()
    ref.packet_timestamp = int((EPOCH_S + t_s) * 1e6)
    second_half = t_s >= 0.5 * duration_s
    ref.stage = ref.NORMAL_SECOND_HALF if second_half else ref.NORMAL_FIRST_HALF
    ref.stage_time_left = int(((1.0 if second_half else 0.5) * duration_s - t_s) * 1e6)
    ref.command = ref.FORCE_START
    ref.command_counter = counter
    ref.command_timestamp = int(EPOCH_S * 1e6)
    for team, name in ((ref.yellow, "ER-Force sim yellow"), (ref.blue, "ER-Force sim blue")):
        team.name = name
        team.score = team.red_cards = team.yellow_cards = team.goalkeeper = 0
        team.timeouts, team.timeout_time = 4, 300_000_000
    ref.source_identifier = "erforce_sim.demo.ssl_game_log"
    return ref.SerializeToString()


class Kicker:
    """Places and kicks the ball: kicks whose two-phase stop point lies inside the field."""

    def __init__(self, config: GameConfig, field_config: FieldConfig, rng: np.random.Generator) -> None:
        self.config = config
        self.field = field_config
        self.rng = rng
        self.model = config.true_model

    def next_kick(self) -> tuple[float, float, float, float]:
        """x, y, vx, vy of a kick from rest that stops inside the field lines (0.3 m margin)."""
        hx, hy = self.field.half_length_m - 0.3, self.field.half_width_m - 0.3
        lo, hi = self.config.kick_speed_mps
        for _ in range(1000):
            x, y = self.rng.uniform(-hx, hx), self.rng.uniform(-hy, hy)
            speed, angle = self.rng.uniform(lo, hi), self.rng.uniform(-math.pi, math.pi)
            vx, vy = speed * math.cos(angle), speed * math.sin(angle)
            stop = BallTrajectory((x, y), (vx, vy), speed, self.model).stop_point
            if abs(stop[0]) < hx and abs(stop[1]) < hy:
                return x, y, vx, vy
        raise RuntimeError("no kick that stops inside the field: kick speeds too high for this field")


def write_game_log(path: str | Path, config: GameConfig | None = None) -> GameSummary:
    config = config or GameConfig()
    field_config = FieldConfig.preset(config.field_preset)
    rng = np.random.default_rng(config.seed)
    world = World(field_config, [], ball_params=config.ball, vision=config.vision, seed=config.seed)
    cameras = quadrant_cameras(field_config)
    frame_numbers = [0] * len(cameras)
    model = config.true_model
    vision_model = BallModelFromVision(model.a_slide_mps2, model.a_roll_mps2, model.c_switch)
    geometry = encode_geometry(field_geometry(field_config, cameras, vision_model))
    kicker = Kicker(config, field_config, rng)
    latency_s = config.vision.latency_s
    shots = 0
    next_event_s = 0.0
    kick_due: tuple[float, float, float, float] | None = None
    shot_started_s = 0.0
    last_referee_s = -math.inf
    last_geometry_s = -math.inf
    with LogWriter(path) as log:
        while world.t_s < config.duration_s:
            t = world.t_s
            if kick_due is None and t >= next_event_s:
                kick_due = kicker.next_kick()  # place it now, kick after rest_s
                world.place_ball(kick_due[0], kick_due[1])
                next_event_s = t + config.rest_s
            elif kick_due is not None and t >= next_event_s:
                x, y, vx, vy = kick_due
                world.place_ball(x, y, vx, vy, spin_ratio=config.kick_spin_ratio)
                kick_due = None
                shots += 1
                shot_started_s = t
                next_event_s = math.inf
            elif next_event_s == math.inf:
                b = world.ball_state()
                if b.speed_mps == 0.0 or t - shot_started_s > config.max_shot_s:
                    next_event_s = t + config.rest_s
            world.step(config.step_s)
            for frame in world.poll_vision():
                receive_ns = round((EPOCH_S + frame.t_release_s) * 1e9)
                if frame.t_capture_s - last_geometry_s >= GEOMETRY_PERIOD_S:
                    last_geometry_s = frame.t_capture_s
                    log.write(receive_ns, MessageType.VISION_2014, geometry)
                robots = scripted_robots(frame.t_capture_s, field_config)
                for data in frame_packets(frame, robots, cameras, frame_numbers, latency_s):
                    log.write(receive_ns, MessageType.VISION_2014, data)
            if world.t_s - last_referee_s >= REFEREE_PERIOD_S:
                last_referee_s = world.t_s
                log.write(round((EPOCH_S + world.t_s) * 1e9), MessageType.REFBOX_2013,
                          referee_packet(world.t_s, config.duration_s, shots))
        records = log.records
    return GameSummary(Path(path), world.t_s, shots, records, config.true_model)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="ssl_game_log", description=__doc__.splitlines()[0])
    parser.add_argument("out", help="log file to write (.gz: compressed)")
    parser.add_argument("--duration-s", type=float, default=600.0, help="game length [s] (default 600)")
    parser.add_argument("--seed", type=int, default=_PLANT["seed"])
    parser.add_argument("--field", default=FIELD_PRESET, help="division_a | division_b")
    parser.add_argument("--a-slide", type=float, default=BALL_A_SLIDE_MPS2, help="true sliding deceleration [m/s^2]")
    parser.add_argument("--a-roll", type=float, default=BALL_A_ROLL_MPS2, help="true rolling deceleration [m/s^2]")
    parser.add_argument("--kick-spin-ratio", type=float, default=_PLANT["kick_spin_ratio"],
                        help="w r / v of a kick; c_switch = (2.5 + s) / 3.5 for the solid ball")
    args = parser.parse_args(argv)
    try:
        ball = BallParams.from_model(args.a_slide, args.a_roll)
        config = GameConfig(duration_s=args.duration_s, field_preset=args.field, seed=args.seed, ball=ball,
                            kick_spin_ratio=args.kick_spin_ratio)
        t0 = time.perf_counter()
        summary = write_game_log(args.out, config)
    except (OSError, ValueError, RuntimeError) as exc:
        print(f"ssl_game_log: {exc}", file=sys.stderr)
        return 1
    m = summary.true_model
    print(f"{summary.path}: {summary.duration_s:.1f} s, {summary.shots} kicks, {summary.records} records "
          f"in {time.perf_counter() - t0:.1f} s; true model a_slide {m.a_slide_mps2:g}, a_roll {m.a_roll_mps2:g}, "
          f"c_switch {m.c_switch:.4g}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
