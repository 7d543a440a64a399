"""The passing game played in one process: a team passes along a chain, opponents try to intercept.

No DDS, deterministic per seed, like the demo's scenes: the world with every robot under motion control
(runner.InProcessRunner, both teams), the ball predictor's object (predictor.BallPredictor) on every vision
frame for all robots, and the AI at a 50 Hz tick. Our team is passing.player.PassingPlayer, the object the
``passing_game`` node runs on the graph; the opponents are passing.player.PressingTeam, the object the
opponents' ``team_catcher`` runs (``press_lanes``). Both are fed what vision tracks; this runner performs
their commands and the referee's part (the ball put back at a robot) on the world. Each pass is reported
as it ends (``PassRecord``, with the true ball path).

- our team: passing.player.PassingPlayer, the same object the ``passing_game`` node runs on the graph
  (its docstring says how the holder picks and kicks a pass and how the receiver receives), fed with
  the predictor's tracked robots, ball and catch times and with every light barrier; this runner
  performs its commands (twists, kicks, dribblers) and its requests (the ball put back at a robot,
  the referee's job) on the world, and receives with the predictor's search facing the way the
  receiver faces (``PassingPlayer.receive_facing``);
- the opponents: passing.player.PressingTeam, the same object the opponents' ``team_catcher`` runs
  on the graph (``press_lanes``): they wait on the passing lanes while one of ours holds the ball
  (passing.decisions.press_targets) and run receiver.Receiver as a team once it rolls (the first of them to
  the ball goes), fed with the tracked robots and ball, their catch times and light barriers.

Each pass is reported as it ends (``PassRecord``, with the true ball path).

Vision reaches the predictor as the plant's ``vision:=ros`` frames bring it to the graph's: the ball as the camera
that takes it sees it, with that camera's position, the other cameras' views as sightings, each robot as the first
camera that reports it (camera_views, the cameras as ``GameConfig.cameras`` makes them err), and each
kick's elevation and commanded speed as a kick hint, as the ball_predictor node takes the kick commands. A chipped
pass flies over the opponents (passing.decisions.evaluate_passes); the predictor's chip (``BallFrame.chip``) is
passed on as it is. With ``GameConfig.true_chip`` the game hands the AI the simulator's true ball while it is in the
air and the predictor has no chip, as a chip (its catch table from the predictor's search on it): what a perfect
chip tracker would say.

    python -m erforce_sim.in_process.passing_game --team 11 --opponents 3 --passes 20 --seed 1 --plot passes.png

No rclpy import.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from erforce_ball_model.catch_time import RobotLimits
from erforce_ball_model.chip_model import ChipTrajectory, flying_ball
from erforce_ball_model.passing.decisions import PassConfig
from erforce_ball_model.passing.player import PassingPlayer, PassRecord, PlayerConfig, PressingTeam, summary
from erforce_ball_model.predictor import BallPredictor, PredictorConfig
from erforce_ball_model.receiver import CatcherConfig
from erforce_interfaces.runtime.lockstep import TICK_PERIOD_S
from erforce_interfaces.runtime.param_schema import schema_defaults
from erforce_interfaces.wire.robot_config import TEAM_SIZE, FieldConfig, RobotConfig
from erforce_sim.camera_views import CameraViews
from erforce_sim.in_process.runner import InProcessRunner
from erforce_sim.plant_setup import PlantSetup
from erforce_sim.sensors import VisionFrame
from erforce_sim.ssl_cameras import CameraRealism

_PLANT = schema_defaults("erforce_sim", "plant")

__all__ = ["GameConfig", "PassRecord", "PassingGame", "plot_passes", "setup_for", "summary"]

# Division A (12 x 9 m). Our team: the first ``team_size`` of these; robot 0 starts with the ball.
TEAM_POSITIONS = ((-4.5, 0.0), (-3.0, -2.5), (-3.0, 2.5), (-1.5, 0.0), (0.0, -3.0), (0.0, 3.0), (1.5, 0.0),
                  (3.0, -2.5), (3.0, 2.5), (4.5, -1.0), (4.5, 1.5))
OPPONENT_POSITIONS = ((-1.8, 1.5), (1.0, -1.5), (2.5, 1.2), (-1.0, -1.6), (3.8, 0.2), (-3.8, 1.2))


@dataclass(frozen=True)
class GameConfig:
    team_size: int = TEAM_SIZE
    opponents: int = 3
    passes: int = 10  # the game ends after this many passes
    field_preset: str = "division_a"
    control_period_s: float = TICK_PERIOD_S  # the graph's lockstep tick
    ai_rate_hz: float = 50.0
    settle_s: float = 0.3  # the trackers learn every robot before the first decision
    player: PlayerConfig = field(default_factory=PlayerConfig)  # our team's AI
    team_positions: tuple[tuple[float, float], ...] = TEAM_POSITIONS  # the first team_size play
    opponent_positions: tuple[tuple[float, float], ...] = OPPONENT_POSITIONS
    true_chip: bool = False  # a ball in the air reaches the AI as the simulator's true chip (module docstring)
    hint_speed: bool = True  # the kick hints carry the commanded speed, as the predictor node's do
    cameras: CameraRealism = PlantSetup.cameras  # how the cameras err: the plant's camera_model (no object offset)

    def __post_init__(self) -> None:
        if not 2 <= self.team_size <= len(self.team_positions):
            raise ValueError(f"team_size must be in [2, {len(self.team_positions)}], got {self.team_size!r}")
        if not 0 <= self.opponents <= len(self.opponent_positions):
            raise ValueError(f"opponents must be in [0, {len(self.opponent_positions)}], got {self.opponents!r}")
        if self.passes < 1:
            raise ValueError(f"passes must be >= 1, got {self.passes!r}")

    @property
    def passing(self) -> PassConfig:
        return self.player.passing

    @property
    def catcher(self) -> CatcherConfig:
        return self.player.catcher


def setup_for(cfg: GameConfig, seed: int) -> PlantSetup:
    team = cfg.team_positions[:cfg.team_size]
    ball = team[0]
    poses = tuple((x, y, math.atan2(ball[1] - y, ball[0] - x) if (x, y) != ball else 0.0) for x, y in team)
    opps = tuple((x, y, math.atan2(ball[1] - y, ball[0] - x)) for x, y in cfg.opponent_positions[:cfg.opponents])
    return PlantSetup(field_preset=cfg.field_preset, robot_poses=poses, controlled=(True,), opponent_poses=opps,
                      control_period_s=cfg.control_period_s, seed=seed, cameras=cfg.cameras)


class PassingGame:
    """One game (module docstring); ``play`` returns the passes, ``on_pass`` sees each as it ends and
    ``on_tick`` the game after every control tick (a recorder)."""

    def __init__(self, cfg: GameConfig, seed: int = _PLANT["seed"], on_pass: Callable[[PassRecord], None] | None = None,
                 on_tick: Callable[[PassingGame], None] | None = None) -> None:
        self.cfg, self.seed, self.on_pass, self.on_tick = cfg, seed, on_pass, on_tick
        self.setup = setup_for(cfg, seed)
        self.runner = InProcessRunner(self.setup)
        self.world = self.runner.world
        self.field = FieldConfig.preset(cfg.field_preset)
        self.robot = RobotConfig()
        self.n_team, self.n_opp = cfg.team_size, cfg.opponents
        n = self.n_team + self.n_opp
        cc = cfg.catcher
        limits = RobotLimits(cc.a_max_mps2, cc.v_max_mps)
        self.predictor = BallPredictor(PredictorConfig(num_robots=n, field=self.field, limits=limits,
                                                       dribbler_offset_m=self.robot.dribbler_offset_m,
                                                       reaction_s=cfg.passing.reaction_s,
                                                       receiving=[True] * self.n_team + [False] * self.n_opp))
        self._predictor_config = self.predictor.config
        self.player = PassingPlayer(cfg.player, self.n_team, self.n_opp, self.field, self.robot.dribbler_offset_m,
                                    self.robot.robot_radius_m, self.predictor.model,
                                    chip_model=self.predictor.chip_model)
        self.cameras = CameraViews.quadrants(self.field, cfg.cameras, seed=seed)  # the plant's vision:=ros cameras
        self._t_vision_s: float | None = None  # the newest vision stamp: a kick's hint goes at it, as on the graph
        self.runner.vision_listeners.append(self._on_frame)
        self.poses = self.player.poses  # tracked, from vision (the opponents' AI reads them too)
        self.velocities = self.player.velocities
        self.opponents = PressingTeam(cfg.catcher, self.robot.dribbler_offset_m, self.robot.robot_radius_m, self.field,
                                      range(self.n_opp), passing=cfg.passing, n_other=self.n_team,
                                      model=self.predictor.model, chip_model=self.predictor.chip_model,
                                      intercepts=True)
        # what the AI was last told the models in use are (the graph's /ball/model_params, /ball/chip_model_params)
        self._model_sent, self._chip_model_sent = self.predictor.model, self.predictor.chip_model
        self.frame_costs_s: list[float] = []  # CPU of BallPredictor.ball_frame for all robots, per vision frame
        self._facing: tuple[int, float] | None = None  # the receive facing the predictor searches with
        self._dribblers = dict.fromkeys(range(self.n_team), False)
        self._path: list[tuple[float, float]] = []  # the true ball path of the pass that rolls
        self._records: list[PassRecord] = []

    @property
    def records(self) -> list[PassRecord]:
        return self._records

    @property
    def resets(self) -> int:
        return self.player.resets

    @property
    def drops(self) -> int:
        return self.player.drops

    @property
    def choice(self):
        return self.player.choice

    # -------------------------------------------------------------------- vision -> predictor -> AI
    def _index(self, team: str, robot_id: int) -> int:
        return self.n_team + robot_id if team == self.setup.opponent_color else robot_id

    def _on_frame(self, frame: VisionFrame) -> None:
        now, t = frame.t_release_s, frame.t_capture_s
        player = self.player
        seen = self.cameras.frame_views(frame)
        for r in seen.robots:
            i = self._index(r.team, r.robot_id)
            tracker = self.predictor.robot_frame(i, t, r.x, r.y, r.theta)
            if tracker is None:
                continue
            player.on_robot(i, now, (*tracker.position_m, tracker.heading_rad), tracker.velocity_mps)
            if i >= self.n_team:
                self.opponents.on_odom(i - self.n_team, now, self.poses[i], self.velocities[i])
            else:
                self.opponents.on_other_robot(i, now, self.poses[i])
        self._t_vision_s = t
        views = seen.balls
        for b in views[:1]:
            t0 = time.thread_time()
            answer = self.predictor.ball_frame(t, b.x_m, b.y_m, camera_m=b.camera[1:])
            for other in views[1:]:
                self.predictor.ball_sighting(t, other.x_m, other.y_m, other.camera[1:])
            self.frame_costs_s.append(time.thread_time() - t0)
            if answer is None:
                continue
            answer = self._chip_answer(answer, now)
            traj = answer.trajectory
            chip = isinstance(traj, ChipTrajectory)
            model = traj.roll.params if chip else traj.params
            if model is not self._model_sent:  # the model in use changed: as /ball/model_params on the graph
                self._model_sent = model
                player.on_model(model)
                self.opponents.on_model(model)
            chip_model = self.predictor.chip_model
            if chip_model is not self._chip_model_sent:
                self._chip_model_sent = chip_model
                player.on_chip_model(chip_model)
                self.opponents.on_chip_model(chip_model)
            for i, ct, point in zip(answer.catch_robots, answer.catch_times_s, answer.catch_points_m, strict=True):
                if i < self.n_team:
                    player.on_catch(i, now, ct, point)
            v_shoot = None if chip else traj.floats.v_shoot_mps
            player.on_ball_phase(answer.phase)  # as /ball/phase, before /ball/state
            self.opponents.on_ball_phase(answer.phase)
            player.on_ball(now, traj.position_m, traj.velocity_mps, v_shoot)
            opponents = self.opponents
            for i, ct, point in zip(answer.catch_robots, answer.catch_times_s, answer.catch_points_m, strict=True):
                if i >= self.n_team:
                    opponents.on_catch_time(i - self.n_team, now, ct)
                    if point is not None:
                        opponents.on_catch_point(i - self.n_team, now, np.array(point))
            opponents.on_ball(now, traj.position_m, traj.velocity_mps)
            if v_shoot is not None:
                opponents.on_v_shoot(now, v_shoot)

    def _chip_answer(self, answer, now: float):
        """The predictor's chip, when it tracks one, as the ball; with ``true_chip`` the simulator's true ball while it
        is in the air (module docstring)."""
        if answer.chip is not None:
            return dataclasses.replace(answer, trajectory=answer.chip)  # its catch table is the chip's already
        if not self.cfg.true_chip:
            return answer
        b = self.world.ball_state()
        chip = flying_ball((b.x, b.y, b.z), (b.vx, b.vy, b.vz), self.predictor.chip_model, self.predictor.model)
        if chip is None:
            return answer
        robots, times, points = self.predictor.catches(now, chip)
        return dataclasses.replace(answer, trajectory=chip, catch_robots=robots, catch_times_s=times,
                                   catch_points_m=points)

    # -------------------------------------------------------------------- the referee's and the world's part
    def _apply(self, now: float) -> None:
        """The player's dribblers, its request for the ball, the predictor's receive facing, the passes it ended."""
        player, world = self.player, self.world
        for i, on in player.dribblers().items():
            if on != self._dribblers[i]:
                world.set_dribbler(i, on)
                self._dribblers[i] = on
        facing = player.receive_facing
        if facing != self._facing:
            self._facing = facing
            cfg = self._predictor_config
            if facing is not None:
                fixed, rad = cfg.facing_fixed.copy(), cfg.facing_rad.copy()
                fixed[facing[0]], rad[facing[0]] = True, facing[1]
                cfg = dataclasses.replace(cfg, facing_fixed=fixed, facing_rad=rad)
            self.predictor.configure(cfg)
        while len(self._records) < len(player.records):
            record = dataclasses.replace(player.records[len(self._records)], ball_path=tuple(self._path))
            self._records.append(record)
            self._path = []
            if self.on_pass is not None:
                self.on_pass(record)
        if player.ball_request is not None and len(self._records) < self.cfg.passes:
            r = world.robot_state(player.ball_request)
            reach = self.robot.dribbler_offset_m + 0.002
            world.place_ball(r.x + reach * math.cos(r.theta), r.y + reach * math.sin(r.theta))
            player.ball_placed(now)
            self._apply(now)

    # -------------------------------------------------------------------- the loop
    def play(self) -> list[PassRecord]:
        cfg, runner, world, player = self.cfg, self.runner, self.world, self.player
        self._records = []
        ticks_per_ai = max(1, round(1.0 / (cfg.ai_rate_hz * cfg.control_period_s)))
        h0 = self.setup.robot_poses[0]
        reach = self.robot.dribbler_offset_m + 0.002
        world.place_ball(h0[0] + reach * math.cos(h0[2]), h0[1] + reach * math.sin(h0[2]))
        runner.run(cfg.settle_s)
        player.start(runner.t_s, 0)
        self._apply(runner.t_s)
        n = self.n_team + self.n_opp
        while len(self._records) < cfg.passes:
            now = runner.t_s
            if runner.tick_index % ticks_per_ai == 0:
                commands = player.tick(now)
                for i, speed in commands.kicks.items():
                    world.set_dribbler(i, False)
                    self._dribblers[i] = False
                    angle_deg = commands.kick_angles.get(i, 0.0)
                    world.kick(i, speed, armed_for_s=0.1, angle_deg=angle_deg)
                    if self._t_vision_s is not None and speed > 0.0:
                        self.predictor.kick_hint(self._t_vision_s, angle_deg, speed if cfg.hint_speed else None)
                self._apply(now)
                twists = {i: np.zeros(3) for i in range(n)}
                twists.update(commands.twists)
                twists.update({self.n_team + j: t for j, t in self.opponents.tick(now).items()})
                for i, twist in twists.items():
                    runner.command(i, twist)
                if player.passing:
                    b = world.ball_state()
                    self._path.append((b.x, b.y))
            runner.tick()
            now = runner.t_s
            for i, seen in enumerate(world.light_barriers()):
                player.on_barrier(i, now, seen)
                if i >= self.n_team:
                    self.opponents.on_barrier(i - self.n_team, seen)
            player.check(now)
            self._apply(now)
            if self.on_tick is not None:
                self.on_tick(self)
        return self._records


def plot_passes(records: list[PassRecord], field_config: FieldConfig, path, title: str = "") -> None:
    """A field plot of every pass: the true ball path, coloured by outcome, numbered at the kick."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(10, 7.5))
    hx, hy = field_config.half_length_m, field_config.half_width_m
    ax.plot([-hx, hx, hx, -hx, -hx], [-hy, -hy, hy, hy, -hy], color="0.5")
    colors = {"completed": "tab:green", "intercepted": "tab:red", "lost": "tab:orange"}
    for r in records:
        if not r.ball_path:
            continue
        xy = np.array(r.ball_path)
        ax.plot(xy[:, 0], xy[:, 1], color=colors[r.outcome], lw=1.5, ls="-" if r.rated_safe else "--")
        ax.annotate(str(r.index), xy[0], fontsize=8)
    for outcome, c in colors.items():
        ax.plot([], [], color=c, label=outcome)
    ax.plot([], [], color="0.3", ls="--", label="rated unsafe")
    ax.set_aspect("equal")
    ax.set_xlabel("x [m] (field)")
    ax.set_ylabel("y [m]")
    ax.legend(loc="upper right")
    ax.set_title(title or "passes: true ball path, numbered at the kick")
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m erforce_sim.in_process.passing_game",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("--team", type=int, default=TEAM_SIZE, help="our robots (2..11)")
    parser.add_argument("--opponents", type=int, default=3)
    parser.add_argument("--passes", type=int, default=10)
    parser.add_argument("--seed", type=int, default=_PLANT["seed"])
    parser.add_argument("--plot", help="write a field plot of every pass here (PNG)")
    parser.add_argument("--chip-angle", type=float, default=PassConfig().chip_angle_deg,
                        help="chip passes at this elevation [deg] (0: flat passes only)")
    parser.add_argument("--true-chip", action="store_true",
                        help="a ball in the air reaches the AI as the simulator's true chip while the predictor has "
                             "none")
    args = parser.parse_args(argv)
    player = PlayerConfig(passing=dataclasses.replace(PassConfig(), chip_angle_deg=args.chip_angle))
    cfg = GameConfig(team_size=args.team, opponents=args.opponents, passes=args.passes, player=player,
                     true_chip=args.true_chip)
    game = PassingGame(cfg, args.seed, on_pass=lambda r: print(r.line(), flush=True))
    wall0 = time.perf_counter()
    records = game.play()
    wall = time.perf_counter() - wall0
    s = summary(records, cfg.passing)
    costs = np.array(game.frame_costs_s) * 1e3
    print(f"{s['completed']}/{s['passes']} completed, {s['intercepted']} intercepted, {s['lost']} lost; "
          f"rated safe {s['rated_safe']}, of them completed {s['safe_completed']}; {game.resets} ball(s) put back "
          f"({game.drops} dropped by the holder); "
          f"{game.runner.t_s:.1f} s simulated in {wall:.1f} s; predictor per vision frame "
          f"({cfg.team_size + cfg.opponents} robots), CPU: median {np.median(costs):.3f} ms, "
          f"p99 {np.percentile(costs, 99):.3f} ms")
    if args.plot:
        plot_passes(records, game.field, args.plot)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
