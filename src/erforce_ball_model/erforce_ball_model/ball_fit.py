"""ball_fit: measure the two-phase ball model on recorded games (SSL log files, or t,x,y CSV files).

Per file (one field): the ball's track is taken from the vision records (cameras merged; of several
candidates the one nearest the previous ball wins, else the one most cameras see), cut into shots at
kicks (``identification``'s ``ShotAccumulator``: the ball at rest, then a kick), and each shot is checked:

* a *ricochet* (a maneuver of a moving ball that is no kick) starts no shot, and a shot that does
  not lie on one line (perpendicular rms above ``max_line_rms_m``) is left out: both are counted;
* a *chip* (a ball detection above ``chip_height_m`` during the shot; SSL-Vision gives a height only
  for chipped balls in simulators and some setups) is left out and counted.

The straight kicks fit (a_slide, a_roll, c_switch) with standard errors (``identification.fit_shots``).
Then both models predict each kick from the tracked state (``BallTracker`` with the model) at every
frame after the kick, and the distance to the observed ball ``horizon`` seconds later is the
prediction error: the paper's two-phase model with the fitted parameters, against one constant
deceleration (the one that stops a kicked ball where the fitted two-phase model stops it).
Output: a table per file, the error table per horizon, and a PNG of error against horizon.
"""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from erforce_ball_model.ball_model import BallModelParams, BallTrajectory
from erforce_ball_model.figures import finish_figure
from erforce_ball_model.identification import FitResult, Shot, ShotAccumulator, fit_shots, load_csv
from erforce_ball_model.tracking import BallTracker, UpdateStatus

HORIZONS_S = (0.25, 0.5, 1.0, 2.0)
MOVING_MPS = 0.1  # a ball slower than this is at rest for the ricochet count
MAX_BALL_JUMP_M = 1.0  # candidates farther from the last ball than this are other objects, not it


@dataclass
class BallTrack:
    """The ball per vision frame: time [s since the first frame], position [m], height [m] (0 if unknown)."""

    t_s: np.ndarray
    xy_m: np.ndarray
    z_m: np.ndarray
    t0_s: float = 0.0
    geometry_model: BallModelParams | None = None  # the ball model the log's geometry declares
    undecodable: int = 0


def track_from_log(path: str | Path) -> BallTrack:
    """The ball track of an SSL log's vision records (SSL_WrapperPacket, message type VISION_2014),
    decoded and checked by the bridge's decoder (``erforce_interfaces.ssl.ssl_vision.decode_wrapper``)."""
    from erforce_interfaces.ssl.ssl_log import LogReader, MessageType
    from erforce_interfaces.ssl.ssl_vision import SslDecodeError, decode_wrapper

    frames: dict[float, list[tuple[float, float, float, float]]] = {}
    geometry_model = None
    undecodable = 0
    for rec in LogReader(path):
        if rec.message_type != MessageType.VISION_2014:
            continue
        try:
            packet = decode_wrapper(rec.payload)
        except SslDecodeError:
            undecodable += 1
            continue
        if packet.geometry is not None and packet.geometry.ball_model is not None:
            m = packet.geometry.ball_model
            geometry_model = BallModelParams(m.a_slide_mps2, m.a_roll_mps2, m.c_switch)
        if packet.frame is None:
            continue
        key = round(packet.frame.t_capture_s, 4)  # cameras capture together: one frame of the field
        frames.setdefault(key, []).extend((b.x_m, b.y_m, b.z_m, b.confidence) for b in packet.frame.balls)
    times = sorted(frames)
    t_out, xy_out, z_out = [], [], []
    last = None
    for t in times:
        cands = frames[t]
        if not cands:
            continue

        def near(c, cands=cands):  # the candidates of one object: a ball in an overlap is seen twice
            return [o for o in cands if math.hypot(o[0] - c[0], o[1] - c[1]) < 0.1]

        def support(c):  # confidence summed over the cameras that see it
            return sum(o[3] for o in near(c))

        best = None
        if last is not None:
            best = min(cands, key=lambda c: math.hypot(c[0] - last[0], c[1] - last[1]))
            if math.hypot(best[0] - last[0], best[1] - last[1]) > MAX_BALL_JUMP_M:
                best = None  # the ball was placed elsewhere
        if best is None:
            best = max(cands, key=support)
        same = near(best)
        x, y = float(np.mean([c[0] for c in same])), float(np.mean([c[1] for c in same]))
        last = (x, y)
        t_out.append(t)
        xy_out.append(last)
        z_out.append(max(c[2] for c in same))
    if not t_out:
        raise ValueError(f"{path}: no ball detections in the log")
    t = np.array(t_out)
    return BallTrack(t - t[0], np.array(xy_out), np.array(z_out), float(t[0]), geometry_model, undecodable)


def track_from_csv(path: str | Path) -> BallTrack:
    t, x, y = load_csv(path)
    return BallTrack(t - t[0], np.column_stack([x, y]), np.zeros_like(t), float(t[0]))


@dataclass
class ShotCut:
    straight: list[Shot] = field(default_factory=list)
    ricochets: int = 0
    chips: int = 0
    not_straight: int = 0


def line_rms_m(shot: Shot) -> float:
    """Rms distance of the shot's points from their principal line."""
    centred = shot.xy_m - shot.xy_m.mean(axis=0)
    _, sv, _ = np.linalg.svd(centred, full_matrices=False)
    return float(sv[-1] / math.sqrt(len(centred)))


def cut_shots(track: BallTrack, chip_height_m: float = 0.05, max_line_rms_m: float = 0.01) -> ShotCut:
    acc = ShotAccumulator()
    out = ShotCut()
    for t, (x, y) in zip(track.t_s, track.xy_m, strict=True):
        moving_before = acc.tracker.initialized and float(np.hypot(*acc.tracker.velocity_mps)) > MOVING_MPS
        status = acc.add(t, x, y)
        # a moving ball that changes its motion without a kick; a ball placed elsewhere at rest is none
        if status == UpdateStatus.MANEUVER and not acc.tracker.kicked and moving_before:
            out.ricochets += 1
    acc.finish()
    for shot in acc.shots:
        inside = (track.t_s >= shot.t_s[0]) & (track.t_s <= shot.t_s[-1])
        if np.max(track.z_m[inside], initial=0.0) > chip_height_m:
            out.chips += 1
        elif line_rms_m(shot) > max_line_rms_m:
            out.not_straight += 1
        else:
            out.straight.append(shot)
    return out


def constant_deceleration(params: BallModelParams) -> BallModelParams:
    """One constant deceleration, as BallModelParams (no sliding phase: c_switch 1), that stops a kicked
    ball where the two-phase ``params`` stop it (the same stop distance for every kick speed)."""
    stop_1mps = float(BallTrajectory((0.0, 0.0), (1.0, 0.0), 1.0, params).stop_distance_m)
    a = -1.0 / (2.0 * stop_1mps)
    return BallModelParams(2.0 * a, a, 1.0)


def prediction_errors(shots: list[Shot], params: BallModelParams, horizons=HORIZONS_S,
                      settle_frames: int = 3) -> dict[float, np.ndarray]:
    """Distances [m] between the model's prediction from each tracked state after a kick and the ball
    observed ``horizon`` seconds later (observations interpolated in time), per horizon."""
    errors: dict[float, list[float]] = {h: [] for h in horizons}
    for shot in shots:
        tracker = BallTracker(params)
        since_kick = None
        t, xy = shot.t_s, shot.xy_m
        for i in range(t.size):
            status = tracker.update(t[i], xy[i, 0], xy[i, 1])
            if status == UpdateStatus.MANEUVER and tracker.kicked:
                since_kick = 0
            elif since_kick is not None and status == UpdateStatus.ACCEPTED:
                since_kick += 1
            if since_kick is None or since_kick < settle_frames or status != UpdateStatus.ACCEPTED:
                continue
            trajectory = tracker.trajectory()
            for h in horizons:
                target = t[i] + h
                if target > t[-1]:
                    continue
                actual = (np.interp(target, t, xy[:, 0]), np.interp(target, t, xy[:, 1]))
                predicted = trajectory.position_at(h)
                errors[h].append(math.hypot(predicted[0] - actual[0], predicted[1] - actual[1]))
    return {h: np.array(v) for h, v in errors.items()}


@dataclass
class FieldReport:
    name: str
    cut: ShotCut
    fit: FitResult | None
    geometry_model: BallModelParams | None
    errors: dict[str, dict[float, np.ndarray]]  # model name -> horizon -> errors [m]
    note: str = ""


def analyse(name: str, track: BallTrack, horizons=HORIZONS_S) -> FieldReport:
    cut = cut_shots(track)
    if not cut.straight:
        return FieldReport(name, cut, None, track.geometry_model, {}, "no straight kick found")
    fit = fit_shots(cut.straight)
    models = {"two-phase": fit.params, "constant deceleration": constant_deceleration(fit.params)}
    errors = {label: prediction_errors(cut.straight, p, horizons) for label, p in models.items()}
    return FieldReport(name, cut, fit, track.geometry_model, errors)


def report_markdown(reports: list[FieldReport], horizons=HORIZONS_S) -> str:
    rows = ["| field (file) | kicks used | ricochets | chips | not straight | a_slide [m/s²] | a_roll [m/s²] "
            "| c_switch | log's geometry model |", "|---|---|---|---|---|---|---|---|---|"]
    for r in reports:
        c = r.cut
        if r.fit is None:
            fit_cells = f"{r.note} | | "
        else:
            p, f = r.fit.params, r.fit
            fit_cells = (f"{p.a_slide_mps2:.3f} ± {f.a_slide_std:.3f} | {p.a_roll_mps2:.4f} ± {f.a_roll_std:.4f} "
                         f"| {p.c_switch:.3f} ± {f.c_switch_std:.3f}")
        g = r.geometry_model
        geometry = "—" if g is None else f"{g.a_slide_mps2:g}, {g.a_roll_mps2:g}, {g.c_switch:g}"
        rows.append(f"| {r.name} | {len(c.straight)} | {c.ricochets} | {c.chips} | {c.not_straight} | "
                    f"{fit_cells} | {geometry} |")
    rows += ["", "Prediction error, median (90th percentile) [cm] over every frame after a kick:", "",
             "| field (file) | model | " + " | ".join(f"{h:g} s" for h in horizons) + " |",
             "|---|---|" + "---|" * len(horizons)]
    for r in reports:
        for label, per_h in r.errors.items():
            cells = []
            for h in horizons:
                e = per_h.get(h, np.array([]))
                cells.append("—" if e.size == 0 else
                             f"{100 * np.median(e):.1f} ({100 * np.percentile(e, 90):.1f}), n={e.size}")
            rows.append(f"| {r.name} | {label} | " + " | ".join(cells) + " |")
    return "\n".join(rows)


def plot(reports: list[FieldReport], path: Path, horizons=HORIZONS_S) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    for r in reports:
        for (label, per_h), style in zip(r.errors.items(), ("o-", "s--"), strict=False):
            hs = [h for h in horizons if per_h[h].size]
            ax.plot(hs, [100 * np.median(per_h[h]) for h in hs], style, label=f"{r.name}: {label}")
    ax.set_xlabel("prediction horizon [s]")
    ax.set_ylabel("median prediction error [cm]")
    ax.set_title("Ball prediction error: two-phase vs constant deceleration")
    finish_figure(fig, ax, path, fontsize=7)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="ball_fit", description=__doc__.splitlines()[0])
    parser.add_argument("files", nargs="+", type=Path, help="SSL log files (plain or .gz), or t,x,y CSV files")
    parser.add_argument("--png", type=Path, default=Path("ball_fit.png"), help="plot of error against horizon")
    args = parser.parse_args(argv)
    reports = []
    for path in args.files:
        try:
            track = track_from_csv(path) if path.suffix == ".csv" else track_from_log(path)
            reports.append(analyse(path.name, track))
        except (OSError, ValueError) as exc:
            print(f"ball_fit: {path}: {exc}", file=sys.stderr)
            return 1
    print(report_markdown(reports))
    if any(r.errors for r in reports):
        plot(reports, args.png)
        print(f"\nplot: {args.png}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
