"""The demo's scenes, how a scene is scored, and the scenes played in one process.

``default_scenes`` is the sequence ``./run demo`` plays over DDS (erforce_sim.demo.demo): the paper's
Fig. 6, then kicks from 1 to 6.5 m/s by robot_1's curved plate at robot_0, passing it, and one off
the side wall. ``reachable`` decides from the ball's true path whether a robot could have caught it.

``play_in_process`` plays a scene with the whole stack in one process and no DDS: the plant and
robot_0's motion control (runner.InProcessRunner: the same cores, order and one-tick setpoint
delay as the lockstep graph), the ball predictor on every vision frame as it is released (the
node's own predictor.BallPredictor object: tracking, robotTimeToBall after the reaction time), and robot_0's catcher
(receiver.Receiver) at its 50 Hz tick. A seed fixes everything, so a run repeats exactly: this is
where the catcher is tuned and its behaviour tested, seconds for what takes the DDS graph minutes.
What it leaves out: DDS delivery and scheduling (the predictor's output reaches the catcher at once),
the predictor's online identification, and the teammates of ``--receivers``.

    python -m erforce_sim.in_process.scenes --seeds 20        # every scene, 20 seeds: caught, contact times

No rclpy import.
"""

from __future__ import annotations

import argparse
import math
from dataclasses import dataclass

import numpy as np

from erforce_ball_model.catch_time import RobotLimits, robot_time_to_pos
from erforce_ball_model.predictor import BallPredictor, PredictorConfig
from erforce_ball_model.receiver import CATCH_TIME_NEVER, CatcherConfig, Receiver
from erforce_interfaces.runtime.lockstep import TICK_PERIOD_S
from erforce_interfaces.runtime.param_schema import schema_defaults
from erforce_interfaces.wire.robot_config import FIELD_PRESET, FieldConfig, RobotConfig
from erforce_sim.in_process.runner import InProcessRunner
from erforce_sim.plant_setup import PlantSetup
from erforce_sim.sensors import VisionFrame, VisionParams

_PLANT = schema_defaults("erforce_sim", "plant")
_CATCHER = schema_defaults("erforce_ball_model", "catcher")
_GAME = schema_defaults("erforce_ball_model", "passing_game")

RECEIVER, KICKER = 0, 1
# --receivers 2 and 3 add these receivers, in this order; their catchers form a team with robot_0's (the
# first to the ball receives). They wait at these poses in every scene, downfield of robot_0.
TEAMMATE_POSES = {2: (2.5, -1.0, math.pi), 3: (2.5, 1.0, math.pi)}
REACTION_S = PredictorConfig.reaction_s  # vision latency + tracking before a robot can react (reachability)
PREDICTION_LEAD_S = 0.3  # the prediction compared with the truth: made this long before the contact


@dataclass(frozen=True)
class Scene:
    name: str
    receiver_pose: tuple[float, float, float]
    kicker_pose: tuple[float, float, float] = (-3.5, -2.0, 0.0)
    ball: tuple[float, float, float, float] | None = None  # a rolling ball (x, y, vx, vy); None: kick
    kick_speed_mps: float = 0.0
    timeout_s: float = 5.0


def _kick_scene(name: str, speed: float, kicker_xy, aim_xy, receiver_pose, timeout_s: float = 5.0) -> Scene:
    yaw = math.atan2(aim_xy[1] - kicker_xy[1], aim_xy[0] - kicker_xy[0])
    return Scene(name, receiver_pose, (kicker_xy[0], kicker_xy[1], yaw), None, speed, timeout_s)


def default_scenes(field_config: FieldConfig) -> list[Scene]:
    """Fig. 6, then kicks from 1 to 6.5 m/s: straight, passing, and one off the wall."""
    k = (-3.0, 0.0)
    r = (1.0, 0.0, math.pi)
    wall_y = field_config.wall_half_width_m
    receiver_wall = (0.5, 1.6, math.pi)
    mirror = (receiver_wall[0], 2 * wall_y - receiver_wall[1])  # aim at the mirror image: bank shot
    return [
        Scene(
            "Fig. 6: ball rolls right at 2.0 m/s, robot at rest catches facing left",
            (-0.5, 0.3, math.pi),
            (-3.5, -2.0, 0.0),
            (-2.0, 0.0, 2.0, 0.0),
            0.0,
            4.0,
        ),
        _kick_scene("kick 1.0 m/s straight", 1.0, (-1.0, 0.0), r[:2], r, 6.0),
        _kick_scene("kick 2.0 m/s passing 0.5 m beside", 2.0, k, (1.0, 0.5), r),
        _kick_scene("kick 3.0 m/s straight", 3.0, k, r[:2], r),
        _kick_scene("kick 3.5 m/s off the side wall", 3.5, k, mirror, receiver_wall),
        _kick_scene("kick 4.0 m/s passing 0.4 m beside", 4.0, k, (1.0, -0.4), r),
        _kick_scene("kick 5.0 m/s straight", 5.0, k, r[:2], r),
        _kick_scene("kick 5.5 m/s passing 0.3 m beside", 5.5, k, (1.0, 0.3), r),
        _kick_scene("kick 6.5 m/s straight", 6.5, k, r[:2], r),
    ]


def reachable(
    ball_truth: np.ndarray,
    t_start: float,
    t_end: float,
    start_xy: np.ndarray,
    limits: RobotLimits,
    dribbler_offset_m: float,
    field_config: FieldConfig,
    reaction_s: float = REACTION_S,
) -> bool:
    """Could a robot at rest at ``start_xy`` have met the true ball path in time?

    ``ball_truth`` rows are (t, x, y, vx, vy). The robot, facing the incoming ball, must
    stand one dribbler offset ahead of the ball when it arrives, inside the field, and
    needs robotTimeToPos plus a reaction delay to get there. Independent of the predictor.
    """
    if ball_truth.size == 0:
        return False
    truth = ball_truth[(ball_truth[:, 0] >= t_start) & (ball_truth[:, 0] <= t_end)]
    if len(truth) < 2:
        return False
    velocity = truth[:, 3:5]
    speed = np.hypot(velocity[:, 0], velocity[:, 1])
    ahead = np.where(speed[:, None] > 1e-3, velocity / np.maximum(speed, 1e-9)[:, None], 0.0)
    targets = truth[:, 1:3] + ahead * dribbler_offset_m
    inside = (np.abs(truth[:, 1]) <= field_config.half_length_m) & (np.abs(truth[:, 2]) <= field_config.half_width_m)
    t_robot = robot_time_to_pos(np.asarray(start_xy, dtype=float), np.zeros(2), targets, limits)
    return bool(np.any(inside & (t_robot + reaction_s <= truth[:, 0] - t_start)))


def compared_prediction(predictions, t_start_s: float, contact_s: float | None) -> float | None:
    """The prediction a scene compares with its contact, as an absolute time; None for "never" or none.

    ``predictions`` are (observation time, catch time after it) pairs, CATCH_TIME_NEVER for "never". The
    newest made at least PREDICTION_LEAD_S before the contact (a useful lead for a receiver); for a ball
    not caught (or caught sooner), the first made PREDICTION_LEAD_S after the scene started.
    """
    if contact_s is not None and contact_s - t_start_s >= PREDICTION_LEAD_S:
        chosen = max((p for p in predictions if t_start_s <= p[0] <= contact_s - PREDICTION_LEAD_S), default=None)
    else:
        chosen = min((p for p in predictions if p[0] >= t_start_s + PREDICTION_LEAD_S), default=None)
    if chosen is None or chosen[1] == CATCH_TIME_NEVER:
        return None
    return chosen[0] + chosen[1]


# ----------------------------------------------------------------------------- in one process
@dataclass(frozen=True)
class InProcessResult:
    """Times in seconds after the kick (or the rolling ball's release), as the demo reports them."""

    scene: Scene
    seed: int
    contact_s: float | None  # robot_0's light barrier, rising edge; None: not caught before the timeout
    predicted_s: float | None  # the newest catch time made PREDICTION_LEAD_S before the contact (or after
    #                             the kick when not caught); None: "never"
    reachable: bool


def play_in_process(scene: Scene, seed: int = _PLANT["seed"], catcher: CatcherConfig | None = None,
                    field_preset: str = FIELD_PRESET, control_period_s: float = TICK_PERIOD_S,
                    catcher_rate_hz: float = _CATCHER["rate_hz"], settle_s: float = _GAME["settle_s"],
                    vision: VisionParams | None = None) -> InProcessResult:
    """Play one scene with the stack in one process (module docstring); deterministic for a seed.

    The catcher's limits are also the predictor's planning limits, as in demo.launch.yaml. The
    bodies rest ``settle_s`` before the kick, so that the trackers know them. ``vision``: the
    cameras' rate, latency and noise (None: the plant's defaults); a longer latency stands in for
    the graph's (vision over UDP, the bridge, DDS hops).
    """
    field = FieldConfig.preset(field_preset)
    robot = RobotConfig()
    cfg = catcher or CatcherConfig()
    runner = InProcessRunner(PlantSetup(field_preset=field_preset, robot_poses=(scene.receiver_pose, scene.kicker_pose),
                                        controlled=(True, False), ball=(0.0, 0.0, 0.0, 0.0),
                                        control_period_s=control_period_s, seed=seed, robot=robot,
                                        vision=vision or VisionParams()))
    world = runner.world
    kx, ky, kyaw = scene.kicker_pose
    reach = robot.dribbler_offset_m + 0.002
    start_xy = (kx + reach * math.cos(kyaw), ky + reach * math.sin(kyaw)) if scene.ball is None else scene.ball[:2]
    world.place_ball(*start_xy)
    predictor = _Predictor(cfg, robot, field, Receiver(cfg, robot.dribbler_offset_m, robot.robot_radius_m, field))
    runner.vision_listeners.append(predictor.on_frame)
    ticks_per_command = max(1, round(1.0 / (catcher_rate_hz * control_period_s)))

    def run_until(t_end_s: float, stop=lambda: False) -> None:
        while runner.t_s < t_end_s - 1e-9 and not stop():
            if runner.tick_index % ticks_per_command == 0:
                runner.command(RECEIVER, predictor.receiver.tick(runner.t_s))
            runner.tick()
            predictor.record_barrier(runner.t_s, world.light_barrier(RECEIVER))

    run_until(settle_s)
    t_start = runner.t_s
    if scene.ball is None:
        world.kick(KICKER, scene.kick_speed_mps, armed_for_s=0.1)
    else:
        world.place_ball(*scene.ball)
    truth = []
    edges_before = len(predictor.barrier_edges)

    def caught() -> bool:
        b = world.ball_state()
        truth.append((runner.t_s, b.x, b.y, b.vx, b.vy))
        return len(predictor.barrier_edges) > edges_before

    run_until(t_start + scene.timeout_s, caught)
    contact = predictor.barrier_edges[edges_before] if len(predictor.barrier_edges) > edges_before else None
    predicted = compared_prediction(predictor.predictions, t_start, contact)
    limits = RobotLimits(cfg.a_max_mps2, cfg.v_max_mps)
    could = contact is not None or reachable(np.array(truth), t_start, runner.t_s, np.array(scene.receiver_pose[:2]),
                                             limits, robot.dribbler_offset_m, field)
    return InProcessResult(scene, seed, None if contact is None else contact - t_start,
                           None if predicted is None else predicted - t_start, could)


class _Predictor:
    """The ball predictor (predictor.BallPredictor, the object the ball_predictor node runs) for robot_0,
    feeding robot_0's Receiver at each vision frame's release, as the node's outputs would reach the catcher."""

    def __init__(self, cfg: CatcherConfig, robot: RobotConfig, field: FieldConfig, receiver: Receiver) -> None:
        self.receiver = receiver
        self.predictor = BallPredictor(PredictorConfig(
            num_robots=1, field=field, limits=RobotLimits(a_max_mps2=cfg.a_max_mps2, v_max_mps=cfg.v_max_mps),
            dribbler_offset_m=robot.dribbler_offset_m))
        receiver.on_model(self.predictor.model)
        receiver.on_chip_model(self.predictor.chip_model)
        self._model_sent = self.predictor.model  # what the receiver was last told the model in use is
        self.predictions: list[tuple[float, float]] = []  # (frame capture time, catch time after it)
        self.barrier_edges: list[float] = []

    def record_barrier(self, t_s: float, detected: bool) -> None:
        if self.receiver.on_barrier(detected):
            self.barrier_edges.append(t_s)

    def on_frame(self, frame: VisionFrame) -> None:
        now, t = frame.t_release_s, frame.t_capture_s
        rx, predictor = self.receiver, self.predictor
        for r in frame.robots:
            if r.robot_id == RECEIVER and (tracker := predictor.robot_frame(RECEIVER, t, r.x, r.y, r.theta)):
                # stamped with the capture time, as the node's odometry: the catcher predicts over its age
                rx.on_odom(now, (*tracker.position_m, tracker.heading_rad), tracker.velocity_mps, t)
        for b in frame.balls[:1]:
            answer = predictor.ball_frame(t, b.x, b.y)
            if answer is None:
                continue
            if answer.catch_robots:  # robot_0 is fresh: catch time first, as the node publishes
                rx.on_catch_time(now, answer.catch_times_s[0])
                if answer.catch_points_m[0] is not None:
                    rx.on_catch_point(now, np.array(answer.catch_points_m[0]))
                self.predictions.append((t, answer.catch_times_s[0]))
            traj = answer.trajectory
            if traj.params is not self._model_sent:  # the model in use changed: as /ball/model_params on the graph
                self._model_sent = traj.params
                rx.on_model(traj.params)
            rx.on_ball(now, traj.position_m, traj.velocity_mps)
            rx.on_v_shoot(now, traj.floats.v_shoot_mps)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m erforce_sim.in_process.scenes",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=int, default=10, help="seeds 0 .. N-1 per scene")
    parser.add_argument("--scene", type=int, action="append", help="only this scene (index; repeatable)")
    args = parser.parse_args(argv)
    scenes = default_scenes(FieldConfig.preset("division_b"))
    print("| # | scene | caught | contact median / max [s] | |predicted - contact| median [ms] |")
    print("|---|---|---|---|---|")
    for i, scene in enumerate(scenes):
        if args.scene and i not in args.scene:
            continue
        results = [play_in_process(scene, seed) for seed in range(args.seeds)]
        contacts = [r.contact_s for r in results if r.contact_s is not None]
        errors = [abs(r.predicted_s - r.contact_s) * 1e3 for r in results
                  if r.contact_s is not None and r.predicted_s is not None]
        reach = sum(r.reachable for r in results)
        times = f"{np.median(contacts):.2f} / {max(contacts):.2f}" if contacts else "—"
        err = f"{np.median(errors):.0f}" if errors else "—"
        print(f"| {i + 1} | {scene.name} | {len(contacts)}/{reach} | {times} | {err} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
