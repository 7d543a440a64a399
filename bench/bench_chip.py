"""Chip tracking: chipped and flat kicks through the simulator's cameras into the ball predictor.

Each kick starts from rest at a random point of division B (at least 1 m inside the field lines, in a random
direction): a chip at 1-6 m/s and 30-60 deg, or a flat kick at 1-6.5 m/s. The ball's true path is the model's
closed form (chip_model.ChipTrajectory, ball_model.BallTrajectory; the simulator flies a chip to within 1 mm
of it). The world's vision (erforce_sim.sensors.VisionSystem: 70 Hz) takes each frame and the four quadrant
cameras (erforce_sim.ssl_cameras, 4 m high) project the ball onto the ground as SSL-Vision does and encode the
SSL datagrams, which are decoded again. How the cameras err is ``--cameras``: ``erforce`` (the default;
ERFORCE_REALISTIC, ER-Force's simulator's "Realistic" preset, a league team's documented model of SSL-Vision: one
detection per camera, 1.4 mm and 5 % missed balls per camera on its own, 1 m overlap past each axis, cameras
projecting 0.1 m off the geometry's positions, 2 cm offset per camera) or ``bench`` (BENCH_CAMERAS, our older
model: the world's 2 mm noise and 2 % dropouts shared by the cameras, 0.5 mm each, 0.5 m overlap).
Per capture, in the order the cameras send, the first camera's ball goes to ``BallPredictor.ball_frame`` (the
bridge's ball) and every other camera's to ``ball_sighting``, each with the camera's position from the geometry.
By default (``--no-align`` leaves it out) five robots stand in the cameras' overlaps (seen through the same cameras,
with their robot noise and misses) and every camera's ball goes through ``camera_alignment.CameraAlignment`` first,
learnt per kick from nothing (the robots and the ball at rest before the kick): each camera's offset off its balls,
as the bridge's ``camera_alignment`` does on a field (docs/decisions/0038).

Rows: the share of chips detected within 0.15 s of the kick (also with the same chips seen without noise: the
ceiling the cameras' geometry leaves the detector); the share of flat kicks ever reported as a chip
(within 1 s); the error of the first touchdown point the predictor's chip has 0.1 s after the detection
(median and p90 over the detected chips); the chips missed within 0.15 s by apex height (with and without
noise); the detection delay (median, p90); the predictor's time per vision frame (ball_frame and ball_sighting
for every camera's ball of one capture; mean, p99), as the thread's CPU time (a shared machine's load does not
inflate it).
``python bench/bench_chip.py [--quick] [--seed N] [--cameras erforce|bench] [--without ERROR ...] [--min-gain G]
[--kick-hints [--hint-speed-error R]] [--no-align] [--no-noise-free]`` (``--without position_error`` /
``object_offset``: the camera model without that fixed error) (``--kick-hints``: the kicker's angle reaches the
predictor at each kick, BallPredictor.kick_hint; the chips' and the flat kicks' alike; ``--hint-speed-error R``: the
hint carries the commanded speed too, the true launch speed times ``1 + R z``, z standard normal per kick: 0 is a
kicker that meets its command) (``--no-align``: no robots, each camera's balls as it reports them)
(``--no-noise-free``: without the rows of the same chips seen without noise, a third of the run).
"""

from __future__ import annotations

import argparse
import itertools
import math
import sys
import time
from dataclasses import replace

import numpy as np
from table import markdown_table

from erforce_ball_model.ball_model import BallTrajectory, ChipParams
from erforce_ball_model.camera_alignment import CameraAlignment
from erforce_ball_model.chip_model import ChipTrajectory
from erforce_ball_model.chip_tracking import ChipDetectorConfig
from erforce_ball_model.predictor import BallPredictor, PredictorConfig
from erforce_ball_model.tracking import TrackerConfig
from erforce_interfaces.ssl.ssl_vision import decode_wrapper
from erforce_interfaces.wire.robot_config import FieldConfig
from erforce_sim.sensors import VisionParams, VisionSystem
from erforce_sim.ssl_cameras import CAMERA_MODELS, ERFORCE_REALISTIC, CameraRealism, SslCameraSplitter

FIELD = FieldConfig.preset("division_b")
VISION = VisionParams()
NOISE_FREE_VISION = VisionParams(position_noise_m=0.0, ball_dropout_prob=0.0)
DETECT_WITHIN_S = 0.15
TOUCHDOWN_AFTER_S = 0.1
RUN_S = 1.0  # after the kick
REST_S = 0.3  # the ball lies still this long before the kick
LOW_M = 0.05
APEX_BANDS_M = (0.03, 0.1, 0.2)  # the missed chips are split by their apex height at these


# with the alignment (the default): robots standing where two cameras (four at the centre) see them, within both
# presets' bands, as on a real field, where the robots are what the cameras of an overlap both see most of the time
STANDING_ROBOTS = (("blue", 0, 0.1, 2.0, 0.0), ("blue", 1, -0.1, -2.0, 0.0), ("yellow", 0, 3.0, -0.1, 0.0),
                   ("yellow", 1, -3.0, 0.1, 0.0), ("yellow", 2, 0.15, -0.15, 0.0))
FIXED_ERRORS = ("position_error", "object_offset")  # CameraRealism's fixed errors a run may leave out (--without)


def camera_model(name: str, without: tuple[str, ...] = ()) -> CameraRealism:
    """The camera model ``name`` (ssl_cameras.CAMERA_MODELS) without the fixed errors ``without``, named so."""
    model = CAMERA_MODELS[name]
    if not without:
        return model
    return replace(model, name=f"{name} without {' and '.join(without)}", **{f"{e}_m": 0.0 for e in without})


def _random_kick(rng: np.random.Generator, chip: bool):
    """The true ball after the kick: a ChipTrajectory or a BallTrajectory from a random point and direction."""
    x = rng.uniform(-FIELD.half_length_m + 1.0, FIELD.half_length_m - 1.0)
    y = rng.uniform(-FIELD.half_width_m + 1.0, FIELD.half_width_m - 1.0)
    heading = rng.uniform(-math.pi, math.pi)
    if chip:
        speed, angle = rng.uniform(1.0, 6.0), math.radians(rng.uniform(30.0, 60.0))
        v_ground = speed * math.cos(angle)
        return ChipTrajectory((x, y, 0.0), (v_ground * math.cos(heading), v_ground * math.sin(heading),
                                            speed * math.sin(angle)), ChipParams())
    speed = rng.uniform(1.0, 6.5)
    return BallTrajectory((x, y), (speed * math.cos(heading), speed * math.sin(heading)), speed)


def _truth_at(ball, t_s: float) -> tuple[float, float, float]:
    p = ball.position_at(max(t_s, 0.0)).tolist()
    return (p[0], p[1], p[2] if len(p) == 3 else 0.0)


def run_kick(ball, seed: int, detector: ChipDetectorConfig | None = None, hint_deg: float | None = None,
             noise_free: bool = False, cameras: CameraRealism = ERFORCE_REALISTIC,
             hint_speed_mps: float | None = None, align: bool = True) -> dict:
    """One kick through cameras and predictor: when a chip was first reported (from the kick) and the first
    touchdown point the predictor had then and ``TOUCHDOWN_AFTER_S`` after that. ``hint_deg``: the kicker's word
    (its angle, 0 flat; ``hint_speed_mps`` its commanded speed) goes to the predictor at the kick's time, before the
    first frame after it. ``noise_free``: neither the world's vision nor the cameras add noise or drop a ball (the
    cameras' fixed errors stay). ``align``: STANDING_ROBOTS stand on the field and every camera's ball goes through
    a CameraAlignment fed with what the cameras see (robots, the ball at rest), learning from nothing at the first
    frame."""
    rng = np.random.default_rng(seed)
    vision = VisionSystem(NOISE_FREE_VISION if noise_free else cameras.world_vision(VISION), rng)
    splitter = SslCameraSplitter.quadrants(FIELD, None, cameras.noise_free() if noise_free else cameras, seed=seed)
    # the predictor knows each camera where the geometry reports it
    poses = {c.camera_id: (c.x_m, c.y_m, c.z_m) for c in splitter.geometry.cameras}
    # the predictor is told the cameras' noise, as a field's position_noise_m would be set to its vision's
    noise_m = cameras.sighting_noise_m(VISION)
    config = PredictorConfig(num_robots=1, field=FIELD, tracker=TrackerConfig(position_noise_m=noise_m),
                             chip_detector=replace(detector or ChipDetectorConfig(), noise_m=noise_m))
    predictor = BallPredictor(config)
    alignment = CameraAlignment() if align else None
    robots = list(STANDING_ROBOTS) if align else []
    t_kick = REST_S + rng.uniform(0.0, 1.0 / VISION.rate_hz)
    detected_s, touchdown, first_touchdown = None, None, None
    period = 1.0 / VISION.rate_hz
    cost_s = []  # the predictor's CPU time per vision frame (every camera's ball of the capture)
    two_views = 0  # frames within DETECT_WITHIN_S of the kick with the ball from two cameras or more
    for k in range(int((REST_S + RUN_S) * VISION.rate_hz)):
        t = k * period
        if hint_deg is not None and t_kick <= t < t_kick + period:
            predictor.kick_hint(t_kick, hint_deg, hint_speed_mps)
        x, y, z = _truth_at(ball, t - t_kick)
        vision.capture(t, (x, y), robots, z)
        frame = vision.poll(t + VISION.latency_s)[0]
        packets = sorted(splitter.packets(frame), key=lambda p: p[0])
        detections = [decode_wrapper(d).detection for _, d in packets]
        if alignment is not None:
            for det in detections:
                alignment.frame(det.camera_id, det.t_capture_s, [r[:4] for r in det.robots.tolist()],
                                [b[:2] for b in det.balls.tolist()])
            sightings = [(*alignment.correct(det.camera_id, bx, by), poses[det.camera_id]) for det in detections
                         for bx, by, *_ in det.balls.tolist()]
        else:
            sightings = [(bx, by, poses[det.camera_id]) for det in detections for bx, by, *_ in det.balls.tolist()]
        two_views += len(sightings) >= 2 and 0.0 <= t - t_kick <= DETECT_WITHIN_S
        t0 = time.thread_time()
        for i, (bx, by, camera) in enumerate(sightings):
            if i == 0:
                answer = predictor.ball_frame(t, bx, by, camera_m=camera)
            else:
                predictor.ball_sighting(t, bx, by, camera)
        if sightings:
            cost_s.append(time.thread_time() - t0)
            if answer is not None and answer.chip is not None and detected_s is None:
                detected_s = t
                first_touchdown = predictor.chip_detector.launch.touchdown_points_m[0]
            if detected_s is not None and touchdown is None and t >= detected_s + TOUCHDOWN_AFTER_S - 1e-9:
                launch = predictor.chip_detector.launch
                touchdown = None if launch is None else launch.touchdown_points_m[0]
    out = {"delay_s": None if detected_s is None else detected_s - t_kick, "touchdown_error_m": None,
           "first_touchdown_error_m": None, "frame_cost_s": cost_s, "two_views": two_views}
    if isinstance(ball, ChipTrajectory):
        for key, point in (("touchdown_error_m", touchdown), ("first_touchdown_error_m", first_touchdown)):
            if point is not None:
                out[key] = float(np.hypot(*(point - ball.touchdown_points_m[0])))
    return out


def _hint(ball, hints: bool) -> float | None:
    if not hints:
        return None
    if isinstance(ball, ChipTrajectory):
        vx, vy, vz = ball.velocity_mps.tolist()
        return math.degrees(math.atan2(vz, math.hypot(vx, vy)))
    return 0.0


def _commanded(balls: list, error: float | None, seed: int) -> list[float | None]:
    """The speed each kick was commanded at (None: the hint carries none): its launch speed times 1 + error z."""
    if error is None:
        return [None] * len(balls)
    z = np.random.default_rng(seed + 7_000_000).standard_normal(len(balls))
    return [float(np.linalg.norm(b.velocity_mps)) * (1.0 + error * zk) for b, zk in zip(balls, z, strict=True)]


def run(quick: bool = False, seed: int = 1, min_gain: float | None = None, hints: bool = False,
        cameras: CameraRealism = ERFORCE_REALISTIC, hint_speed_error: float | None = None,
        align: bool = True, noise_free: bool = True) -> list[dict]:
    """The table's rows; ``noise_free`` False leaves out the rows of the same chips without noise (a third of the
    run)."""
    n = 100 if quick else 500
    detector = ChipDetectorConfig() if min_gain is None else ChipDetectorConfig(min_gain=min_gain)
    rng = np.random.default_rng(seed)
    chip_balls = [_random_kick(rng, True) for _ in range(n)]
    flat_balls = [_random_kick(rng, False) for _ in range(n)]
    chip_speeds = _commanded(chip_balls, hint_speed_error if hints else None, seed)
    flat_speeds = _commanded(flat_balls, hint_speed_error if hints else None, seed + 1)
    chips = [run_kick(b, seed * 100_000 + k, detector, _hint(b, hints), cameras=cameras, hint_speed_mps=v,
                      align=align) for k, (b, v) in enumerate(zip(chip_balls, chip_speeds, strict=True))]
    flats = [run_kick(b, seed * 100_000 + n + k, detector, _hint(b, hints), cameras=cameras, hint_speed_mps=v,
                      align=align) for k, (b, v) in enumerate(zip(flat_balls, flat_speeds, strict=True))]
    clean = [run_kick(b, seed * 100_000 + k, detector, _hint(b, hints), noise_free=True, cameras=cameras,
                      hint_speed_mps=v, align=align)["delay_s"]
             for k, (b, v) in enumerate(zip(chip_balls, chip_speeds, strict=True))] if noise_free else []
    delays = np.array([c["delay_s"] for c in chips if c["delay_s"] is not None])
    within = np.sum(delays <= DETECT_WITHIN_S) if len(delays) else 0
    # a chip whose ball is below LOW_M by DETECT_WITHIN_S: its projected path differs from a ground ball's by about
    # the noise (2 mm) at most, whatever the detector; without a hint the rest is the fair share
    early = np.linspace(0.0, DETECT_WITHIN_S, 31)
    low = [float(np.max(b.position_at(early)[:, 2])) < LOW_M for b in chip_balls]
    rest = [c for c, is_low in zip(chips, low, strict=True) if not is_low]
    rest_within = sum(c["delay_s"] is not None and c["delay_s"] <= DETECT_WITHIN_S for c in rest)
    errors = np.array([c["touchdown_error_m"] for c in chips if c["touchdown_error_m"] is not None])
    first_errors = np.array([c["first_touchdown_error_m"] for c in chips if c["first_touchdown_error_m"] is not None])
    apex_m = [b.apex_height_m for b in chip_balls]
    missed = [c["delay_s"] is None or c["delay_s"] > DETECT_WITHIN_S for c in chips]
    missed_clean = [d is None or d > DETECT_WITHIN_S for d in clean]
    false_chips = sum(f["delay_s"] is not None for f in flats)
    cost_us = 1e6 * np.concatenate([k["frame_cost_s"] for k in chips + flats])
    note = f"{n} random kicks, seed {seed}, cameras {cameras.name}, min_gain {detector.min_gain:g}" + (
        ", kick hints" if hints else "") + (", camera alignment" if align else "")
    if hints and hint_speed_error is not None:
        note += f" with the commanded speed (off by {hint_speed_error:g} sd)"
    rows = [
        {"name": "chips detected within 0.15 s of the kick", "value": 100.0 * within / n, "unit": "%",
         "target": ">= 95", "note": note},
        {"name": "chips ever detected (within 1 s)", "value": 100.0 * len(delays) / n, "unit": "%", "target": "",
         "note": ""},
        {"name": f"chips below {100 * LOW_M:g} cm at 0.15 s", "value": 100.0 * sum(low) / n, "unit": "%",
         "target": "", "note": "within a few noise standard deviations of a ground ball by then"},
        {"name": "the other chips detected within 0.15 s", "value": 100.0 * rest_within / max(len(rest), 1),
         "unit": "%", "target": "", "note": f"{len(rest)} chips"},
        {"name": "chips missed within 0.15 s, by apex height", "value": 100.0 * sum(missed) / n, "unit": "%",
         "target": "", "note": _by_apex(apex_m, missed)},
        {"name": "... seen by one camera at a time", "value": 100.0 * sum(
            m and c["two_views"] == 0 for m, c in zip(missed, chips, strict=True)) / n, "unit": "%", "target": "",
         "note": f"of all chips {100.0 * sum(c['two_views'] == 0 for c in chips) / n:.1f} %; missed and detected "
         f"later (within 1 s): {100.0 * len(delays[delays > DETECT_WITHIN_S]) / n:.1f} %"},
        {"name": "flat kicks reported as a chip", "value": 100.0 * false_chips / n, "unit": "%", "target": "<= 1",
         "note": note},
        {"name": "first touchdown point error at detection, median", "value": float(np.median(first_errors)),
         "unit": "m", "target": "", "note": f"{len(first_errors)} chips"},
        {"name": "first touchdown point error at detection, p90", "value": float(np.percentile(first_errors, 90)),
         "unit": "m", "target": "", "note": ""},
        {"name": "first touchdown point error 0.1 s after detection, median", "value": float(np.median(errors)),
         "unit": "m", "target": "<= 0.15", "note": f"{len(errors)} chips"},
        {"name": "first touchdown point error 0.1 s after detection, p90",
         "value": float(np.percentile(errors, 90)), "unit": "m", "target": "", "note": ""},
        {"name": "detection delay after the kick, median", "value": float(np.median(delays)), "unit": "s",
         "target": "", "note": f"{len(delays)} detected"},
        {"name": "detection delay after the kick, p90", "value": float(np.percentile(delays, 90)), "unit": "s",
         "target": "", "note": ""},
        {"name": "predictor per vision frame (every camera's ball), mean", "value": float(np.mean(cost_us)),
         "unit": "us", "target": "", "note": f"{len(cost_us)} frames, chips and flat kicks"},
        {"name": "predictor per vision frame, p99", "value": float(np.percentile(cost_us, 99)), "unit": "us",
         "target": "", "note": ""},
    ]
    if noise_free:
        rows[4:4] = [{"name": "chips detected within 0.15 s without noise", "value": 100.0 * sum(
            d is not None and d <= DETECT_WITHIN_S for d in clean) / n, "unit": "%", "target": "",
            "note": "the same chips noise-free (fixed camera errors kept): what the cameras' geometry leaves this "
            "detector"}]
        rows[6:6] = [{"name": "... the same chips without noise", "value": 100.0 * sum(missed_clean) / n,
                      "unit": "%", "target": "", "note": _by_apex(apex_m, missed_clean)}]
    return rows


def _by_apex(apex_m: list[float], missed: list[bool]) -> str:
    """Missed / all chips per apex band, e.g. "apex < 3 cm: 9/21, 3-10 cm: ..."."""
    edges = (0.0, *APEX_BANDS_M, math.inf)
    parts = []
    for lo, hi in itertools.pairwise(edges):
        band = [m for a, m in zip(apex_m, missed, strict=True) if lo <= a < hi]
        label = f"< {100 * hi:g} cm" if lo == 0.0 else f">= {100 * lo:g} cm" if hi == math.inf else \
            f"{100 * lo:g}-{100 * hi:g} cm"
        parts.append(f"{label}: {sum(band)}/{len(band)}")
    return "missed/all by apex: " + ", ".join(parts)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="100 kicks of each kind instead of 500")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--min-gain", type=float, default=None, help="ChipDetectorConfig.min_gain (a trade-off: "
                        "earlier detection against more flat kicks taken for chips)")
    parser.add_argument("--cameras", choices=sorted(CAMERA_MODELS), default=ERFORCE_REALISTIC.name,
                        help="how the simulated cameras err (erforce_sim.ssl_cameras.CAMERA_MODELS; erforce: one "
                        "detection per camera, as SSL-Vision)")
    parser.add_argument("--without", nargs="+", choices=FIXED_ERRORS, default=(),
                        help="leave these fixed errors out of the camera model")
    parser.add_argument("--kick-hints", action="store_true", help="the kicker tells the predictor each kick's "
                        "angle (0 flat) at the kick (BallPredictor.kick_hint)")
    parser.add_argument("--hint-speed-error", type=float, default=None, metavar="R", help="with --kick-hints: the "
                        "hint carries the commanded speed, the launch speed times 1 + R z (z standard normal)")
    parser.add_argument("--align", action=argparse.BooleanOptionalAction, default=True, help="robots stand in the "
                        "overlaps and each camera's offset, estimated from them (CameraAlignment), is taken off its "
                        "balls (--no-align: each camera's balls as it reports them)")
    parser.add_argument("--noise-free", action=argparse.BooleanOptionalAction, default=True, help="the same chips "
                        "without noise too (--no-noise-free: a third faster)")
    args = parser.parse_args(argv)
    t0 = time.perf_counter()
    print("\n".join(markdown_table(run(args.quick, args.seed, args.min_gain, args.kick_hints,
                                        camera_model(args.cameras, tuple(args.without)),
                                        args.hint_speed_error, args.align, args.noise_free))))
    print(f"\n(total {time.perf_counter() - t0:.1f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
