"""The passing game played in one process: a team passes along a chain, opponents try to intercept.

Everything runs in one process with no DDS, deterministic per seed, like the demo's scenes
(erforce_sim.closed_loop.scenes): the plant with every robot under motion control (runner.InProcessRunner,
our team and the opponents, erforce_sim world), the ball predictor's object (predictor.BallPredictor)
on every vision frame for all robots of both teams, and the behaviours at a 50 Hz AI tick:

- the robot on the ball holds it with the dribbler, evaluates a pass to every teammate
  (passing.evaluate_passes: robotTimeToBall for the whole field on the ball each kick would make),
  turns to the pass it selects (passing.select_pass: the earliest safe catch), and kicks with
  the speed at which the ball arrives receivable (passing.kick_speed_for);
- each teammate's next target (where it would pass on from where it stands: select_pass over the
  others but the holder) is worked out when a robot takes the ball and refreshed one teammate per AI
  tick; a pass is rated with its receiver facing that target (evaluate_passes' next_targets);
- the receiver runs catcher.Receiver (the paper's Fig. 6 skill) and receives facing its next target
  where the receive angle allows (catch_time.receive_facing; the predictor's search faces the same
  way for it), else facing the ball; once it holds the ball it prefers that target and passes on;
- the opponents wait on the passing lanes while we hold the ball (passing.press_targets) and,
  once the ball rolls, run catcher.Receiver as a team: the first of them to the ball goes.

A pass ends when a light barrier sees the ball: our receiver (completed), another of ours
(completed, to that robot), an opponent (intercepted), or when the ball rests or the time is up
(lost). After an interception or a loss the ball is put at the dribbler of our robot farthest
from the opponents and the chain goes on. Each pass is reported as it ends (``PassRecord``).

    python -m erforce_sim.closed_loop.passing_game --team 11 --opponents 3 --passes 20 --seed 1 --plot passes.png

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

from erforce_ball_model.catch_time import MAX_RECEIVE_ANGLE_RAD, CatchSearch, RobotLimits
from erforce_ball_model.catcher import CatcherConfig, Receiver, catch_twist, wrap_angle
from erforce_ball_model.passing import PassConfig, PassOption, evaluate_passes, press_targets, select_pass
from erforce_ball_model.predictor import BallPredictor, PredictorConfig
from erforce_interfaces.robot_config import FieldConfig, RobotConfig
from erforce_sim.closed_loop.runner import InProcessRunner
from erforce_sim.sensors import VisionFrame
from erforce_sim.world import PlantSetup

# Division A (12 x 9 m). Our team: the first ``team_size`` of these; robot 0 starts with the ball.
TEAM_POSITIONS = ((-4.5, 0.0), (-3.0, -2.5), (-3.0, 2.5), (-1.5, 0.0), (0.0, -3.0), (0.0, 3.0), (1.5, 0.0),
                  (3.0, -2.5), (3.0, 2.5), (4.5, -1.0), (4.5, 1.5))
DROP_AFTER_S = 0.3  # a holder whose light barrier has not seen the ball this long lost it
OPPONENT_POSITIONS = ((-1.8, 1.5), (1.0, -1.5), (2.5, 1.2), (-1.0, -1.6), (3.8, 0.2), (-3.8, 1.2))


@dataclass(frozen=True)
class GameConfig:
    team_size: int = 11
    opponents: int = 3
    passes: int = 10  # the game ends after this many passes
    field_preset: str = "division_a"
    control_period_s: float = 0.002
    ai_rate_hz: float = 50.0
    hold_min_s: float = 0.4  # a new holder settles the ball this long before it kicks
    aim_tolerance_rad: float = 0.03
    turn_rate_radps: float = 3.0  # a holder turns at most this fast (the dribbler keeps the ball)
    max_receive_angle_rad: float = MAX_RECEIVE_ANGLE_RAD  # receive facing the next target within this
    switch_margin_s: float = 0.2  # a holder changes its chosen receiver for one this much earlier
    wait_for_safe_s: float = 1.5  # a holder without a safe pass keeps the ball this long, then plays the best
    pass_timeout_s: float = 6.0
    settle_s: float = 0.3  # the trackers learn every robot before the first decision
    passing: PassConfig = field(default_factory=PassConfig)
    catcher: CatcherConfig = field(default_factory=CatcherConfig)
    team_positions: tuple[tuple[float, float], ...] = TEAM_POSITIONS  # the first team_size play
    opponent_positions: tuple[tuple[float, float], ...] = OPPONENT_POSITIONS

    def __post_init__(self) -> None:
        if not 2 <= self.team_size <= len(self.team_positions):
            raise ValueError(f"team_size must be in [2, {len(self.team_positions)}], got {self.team_size!r}")
        if not 0 <= self.opponents <= len(self.opponent_positions):
            raise ValueError(f"opponents must be in [0, {len(self.opponent_positions)}], got {self.opponents!r}")
        if self.passes < 1:
            raise ValueError(f"passes must be >= 1, got {self.passes!r}")
        if not (math.isfinite(self.max_receive_angle_rad) and 0.0 <= self.max_receive_angle_rad < 0.5 * math.pi):
            raise ValueError(f"max_receive_angle_rad must be in [0, pi/2), got {self.max_receive_angle_rad!r}")


@dataclass(frozen=True)
class PassRecord:
    index: int
    t_kick_s: float
    passer: int
    receiver: int
    kick_speed_mps: float
    predicted_catch_s: float  # the ball at the receiver's dribbler as planned at the kick (from the kick)
    opponent_predicted_s: float  # the earliest opponent's (inf: none can)
    first_opponent: int | None
    rated_safe: bool
    outcome: str  # completed | intercepted | lost
    caught_by: str | None  # robot_<k> | opponent_<j>
    actual_catch_s: float | None  # light barrier edge, from the kick
    ball_path: tuple[tuple[float, float], ...] = ()  # true ball positions every 20 ms
    facing_target: int | None = None  # the teammate the receiver received facing (None: it faced the ball)

    @property
    def margin_s(self) -> float:
        return self.opponent_predicted_s - self.predicted_catch_s

    def line(self) -> str:
        """One line for the terminal."""
        actual = "—" if self.actual_catch_s is None else f"{self.actual_catch_s:.2f} s"
        margin = "∞" if math.isinf(self.margin_s) else f"{self.margin_s:+.2f} s"
        rated = "safe" if self.rated_safe else "UNSAFE"
        text = (f"pass {self.index:2d}  robot_{self.passer} -> robot_{self.receiver}  {self.kick_speed_mps:.2f} m/s  "
                f"catch predicted {self.predicted_catch_s:.2f} s, actual {actual}  margin {margin} ({rated})  "
                f"{self.outcome}")
        if self.caught_by and self.caught_by != f"robot_{self.receiver}":
            text += f" by {self.caught_by}"
        return text + self.explanation()

    def explanation(self) -> str:
        if self.outcome == "intercepted":
            opp = "no opponent" if self.first_opponent is None else f"opponent_{self.first_opponent}"
            pred = "never" if math.isinf(self.opponent_predicted_s) else f"{self.opponent_predicted_s:.2f} s"
            return (f"  [predicted first opponent {opp} at {pred}; {self.caught_by} caught at "
                    f"{self.actual_catch_s:.2f} s, {self.predicted_catch_s - self.actual_catch_s:+.2f} s before our "
                    f"predicted catch]")
        if self.outcome == "lost":
            return "  [nobody caught the ball]"
        return ""


def setup_for(cfg: GameConfig, seed: int) -> PlantSetup:
    team = cfg.team_positions[:cfg.team_size]
    ball = team[0]
    poses = tuple((x, y, math.atan2(ball[1] - y, ball[0] - x) if (x, y) != ball else 0.0) for x, y in team)
    opps = tuple((x, y, math.atan2(ball[1] - y, ball[0] - x)) for x, y in cfg.opponent_positions[:cfg.opponents])
    return PlantSetup(field_preset=cfg.field_preset, robot_poses=poses, controlled=(True,), opponent_poses=opps,
                      control_period_s=cfg.control_period_s, seed=seed)


class PassingGame:
    """One game (module docstring); ``play`` returns the passes, ``on_pass`` sees each as it ends and
    ``on_tick`` the game after every control tick (a recorder)."""

    def __init__(self, cfg: GameConfig, seed: int = 0, on_pass: Callable[[PassRecord], None] | None = None,
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
                                                       reaction_s=cfg.passing.reaction_s))
        self._predictor_config = self.predictor.config
        self._planned_next: int | None = None
        self.pass_search = CatchSearch(n, limits, dribbler_offset_m=self.robot.dribbler_offset_m, field=self.field)
        self.runner.vision_listeners.append(self._on_frame)
        self.poses = np.zeros((n, 3))  # tracked, from vision
        self.velocities = np.zeros((n, 2))
        self.receivers: dict[int, Receiver] = {}  # world index -> the skill, while a pass rolls
        self.frame_costs_s: list[float] = []  # CPU of BallPredictor.ball_frame for all robots, per vision frame
        self.records: list[PassRecord] = []
        self.resets = 0  # balls put back after a loss, an interception or a drop
        self.drops = 0  # of them: a holder lost the ball before it kicked
        self._barrier_lost_at: float | None = None
        self._holder: int | None = 0
        self._hold_since = 0.0
        self._choice: PassOption | None = None
        self._pass: dict | None = None
        self._last_passer: int | None = None
        self._next_targets: dict[int, int] = {}  # teammate -> the teammate it would pass on to
        self._refresh = 0  # the next teammate whose next target is refreshed
        self._prefer: int | None = None  # the new holder's planned next target
        self._barriers = [False] * n

    @property
    def choice(self) -> tuple[int, PassOption] | None:
        """The pass chosen now and its passer: the holder's choice while it holds the ball, the pass being
        played while the ball rolls; None before a holder has chosen and after a pass ended."""
        if self._pass is not None:
            return self._pass["passer"], self._pass["choice"]
        if self._holder is not None and self._choice is not None:
            return self._holder, self._choice
        return None

    # -------------------------------------------------------------------- vision -> predictor -> skills
    def _index(self, team: str, robot_id: int) -> int:
        return self.n_team + robot_id if team == self.setup.opponent_color else robot_id

    def _on_frame(self, frame: VisionFrame) -> None:
        now, t = frame.t_release_s, frame.t_capture_s
        for r in frame.robots:
            i = self._index(r.team, r.robot_id)
            tracker = self.predictor.robot_frame(i, t, r.x, r.y, r.theta)
            if tracker is None:
                continue
            self.poses[i] = (*tracker.position_m, tracker.heading_rad)
            self.velocities[i] = tracker.velocity_mps
            if i in self.receivers:
                self.receivers[i].on_odom(now, self.poses[i], self.velocities[i])
        for b in frame.balls[:1]:
            t0 = time.thread_time()
            answer = self.predictor.ball_frame(t, b.x, b.y)
            self.frame_costs_s.append(time.thread_time() - t0)
            if answer is None:
                continue
            times = dict(zip(answer.catch_robots, answer.catch_times_s, strict=True))
            points = dict(zip(answer.catch_robots, answer.catch_points_m, strict=True))
            traj = answer.trajectory
            for i, rx in self.receivers.items():
                if i in times:
                    rx.on_catch_time(now, times[i])
                    if points[i] is not None:
                        rx.on_catch_point(now, np.array(points[i]))
                for j in times:
                    if (j >= self.n_team) == (i >= self.n_team):
                        rx.on_teammate_catch_time(j, now, times[j])
                rx.on_ball(now, traj.position_m, traj.velocity_mps)
                rx.on_v_shoot(now, traj.floats.v_shoot_mps)

    # -------------------------------------------------------------------- decisions at the AI tick
    def _options(self, holder: int) -> list[PassOption]:
        ball = self.world.ball_state()
        n = self.n_team
        ball_xy = (ball.x, ball.y) if self._holder is None else self._ball_at_dribbler(holder)
        targets = {j: self.poses[k, :2] for j, k in self._next_targets.items()}
        return evaluate_passes(ball_xy, self.poses[:n, :2], self.velocities[:n], self.poses[n:, :2],
                               self.velocities[n:], self._candidates(holder), self.pass_search,
                               self.predictor.model, self.cfg.passing, self.robot.dribbler_offset_m,
                               targets, self.cfg.max_receive_angle_rad)

    def _next_target(self, holder: int, j: int) -> int | None:
        """Where teammate ``j`` would pass on once it has the ball from ``holder`` (select_pass from where it
        stands, every robot facing the ball; None: no teammate in reach)."""
        n = self.n_team
        others = [k for k in range(n) if k not in (holder, j)]
        options = evaluate_passes(self.poses[j, :2], self.poses[:n, :2], self.velocities[:n], self.poses[n:, :2],
                                  self.velocities[n:], others, self.pass_search, self.predictor.model,
                                  self.cfg.passing, self.robot.dribbler_offset_m)
        best = select_pass(options, self.cfg.passing)
        return None if best is None else best.receiver

    def _update_next_targets(self, holder: int, all_of_them: bool) -> None:
        """Every teammate's next target (``all_of_them``), or the next one in turn."""
        others = [k for k in range(self.n_team) if k != holder]
        if not all_of_them:
            self._refresh = (self._refresh + 1) % len(others)
            others = [others[self._refresh]]
        for j in others:
            k = self._next_target(holder, j)
            if k is None:
                self._next_targets.pop(j, None)
            else:
                self._next_targets[j] = k

    def _candidates(self, holder: int) -> list[int]:
        """Every teammate but the holder and, so that the ball travels along a chain, the one who passed
        to it (while there is another)."""
        others = [k for k in range(self.n_team) if k != holder]
        chain = [k for k in others if k != self._last_passer]
        return chain or others

    def _ball_at_dribbler(self, i: int) -> tuple[float, float]:
        x, y, yaw = self.poses[i]
        d = self.robot.dribbler_offset_m
        return x + d * math.cos(yaw), y + d * math.sin(yaw)

    def _choose(self, holder: int) -> PassOption | None:
        options = self._options(holder)
        best = select_pass(options, self.cfg.passing)
        kept = self._choice.receiver if self._choice is not None else self._prefer  # a new holder: its plan
        if kept is not None and best is not None and best.receiver != kept:
            same = next((o for o in options if o.receiver == kept), None)
            keep = (same is not None and same.safe(self.cfg.passing) == best.safe(self.cfg.passing)
                    and same.receiver_catch_s <= best.receiver_catch_s + self.cfg.switch_margin_s)
            if keep:
                best = same
        self._choice = best
        return best

    def _commands(self, now: float) -> dict[int, np.ndarray]:
        cfg, n = self.cfg, self.n_team
        commands = {i: np.zeros(3) for i in range(n + self.n_opp)}
        if self._holder is not None:
            h = self._holder
            self._update_next_targets(h, all_of_them=False)
            choice = self._choose(h)
            pose = self.poses[h]
            if choice is not None:
                twist = catch_twist(pose, pose[:2], choice.direction_rad, cfg.catcher)
                twist[2] = float(np.clip(twist[2], -cfg.turn_rate_radps, cfg.turn_rate_radps))
                commands[h] = twist
                aimed = abs(wrap_angle(choice.direction_rad - self.world.robot_state(h).theta)) <= cfg.aim_tolerance_rad
                patient = not choice.safe(cfg.passing) and now - self._hold_since < cfg.wait_for_safe_s
                if aimed and not patient and now - self._hold_since >= cfg.hold_min_s and self.world.light_barrier(h):
                    self._kick(h, choice, now)
                    commands[h] = np.zeros(3)
            targets = press_targets(self._ball_at_dribbler(h), self.poses[:n, :2], self.poses[n:, :2], h,
                                    cfg.passing)
            ball = self.world.ball_state()
            for j in range(self.n_opp):
                i = n + j
                facing = math.atan2(ball.y - self.poses[i, 1], ball.x - self.poses[i, 0])
                commands[i] = catch_twist(self.poses[i], targets[j], facing, cfg.catcher)
        for i, rx in self.receivers.items():
            commands[i] = rx.tick(now)
        return commands

    def _kick(self, holder: int, choice: PassOption, now: float) -> None:
        self.world.set_dribbler(holder, False)
        self.world.kick(holder, choice.kick_speed_mps, armed_for_s=0.1)
        self._holder, self._last_passer = None, holder
        cc = self.cfg.catcher
        offset, radius = self.robot.dribbler_offset_m, self.robot.robot_radius_m
        self.receivers = {choice.receiver: Receiver(cc, offset, radius, self.field)}
        opponents = list(range(self.n_team, self.n_team + self.n_opp))
        for i in opponents:
            self.receivers[i] = Receiver(cc, offset, radius, self.field, robot_id=i, team_robot_ids=opponents)
        for i in self.receivers:
            self.receivers[i].on_model(self.predictor.model)
            self.receivers[i].on_odom(now, self.poses[i], self.velocities[i])
        self.world.set_dribbler(choice.receiver, True)
        ball_rad = choice.direction_rad + math.pi
        k = None
        if abs(math.remainder(choice.receive_facing_rad - ball_rad, 2.0 * math.pi)) > 1e-9:
            # it receives facing its next target: the predictor's search (its catch point) faces the same way
            k = self._next_targets[choice.receiver]
            self.receivers[choice.receiver].on_next_target(self.poses[k, :2], self.cfg.max_receive_angle_rad)
            cfg = self.predictor.config
            fixed, facing = cfg.facing_fixed.copy(), cfg.facing_rad.copy()
            fixed[choice.receiver], facing[choice.receiver] = True, wrap_angle(choice.receive_facing_rad)
            self.predictor.configure(dataclasses.replace(cfg, facing_fixed=fixed, facing_rad=facing))
        self._planned_next = self._next_targets.get(choice.receiver)
        self._pass = {"t_kick": now, "passer": holder, "choice": choice, "path": [], "rest_since": None,
                      "facing_target": k}

    # -------------------------------------------------------------------- the loop
    def _end_pass(self, outcome: str, caught_by: int | None, now: float) -> None:
        p, choice = self._pass, self._pass["choice"]
        name = None if caught_by is None else (
            f"robot_{caught_by}" if caught_by < self.n_team else f"opponent_{caught_by - self.n_team}")
        record = PassRecord(len(self.records) + 1, p["t_kick"], p["passer"], choice.receiver, choice.kick_speed_mps,
                            choice.receiver_catch_s, choice.opponent_catch_s, choice.first_opponent,
                            choice.safe(self.cfg.passing), outcome, name,
                            None if caught_by is None else now - p["t_kick"], tuple(p["path"]), p["facing_target"])
        self.records.append(record)
        if self.on_pass is not None:
            self.on_pass(record)
        self._pass = None
        self.receivers = {}
        self.predictor.configure(self._predictor_config)
        for i in range(self.n_team):
            self.world.set_dribbler(i, False)
        if outcome == "completed":
            self._take_ball(caught_by, now, self._planned_next if caught_by == choice.receiver else None)
        else:
            self._restart(now)

    def _take_ball(self, holder: int, now: float, planned_next: int | None = None) -> None:
        self._holder, self._hold_since, self._choice, self._barrier_lost_at = holder, now, None, None
        self._prefer = planned_next
        self.world.set_dribbler(holder, True)
        self._next_targets = {}
        self._update_next_targets(holder, all_of_them=True)

    def _restart(self, now: float) -> None:
        """The ball to the dribbler of our robot farthest from every opponent."""
        self.resets += 1
        self._last_passer = None
        n = self.n_team
        truth = [self.world.robot_state(i) for i in range(n + self.n_opp)]
        if self.n_opp:
            far = max(range(n), key=lambda k: min(math.hypot(truth[k].x - truth[n + j].x, truth[k].y - truth[n + j].y)
                                                  for j in range(self.n_opp)))
        else:
            far = 0
        r = truth[far]
        reach = self.robot.dribbler_offset_m + 0.002
        self.world.place_ball(r.x + reach * math.cos(r.theta), r.y + reach * math.sin(r.theta))
        self._take_ball(far, now)

    def play(self) -> list[PassRecord]:
        cfg, runner, world = self.cfg, self.runner, self.world
        ticks_per_ai = max(1, round(1.0 / (cfg.ai_rate_hz * cfg.control_period_s)))
        h0 = self.setup.robot_poses[0]
        reach = self.robot.dribbler_offset_m + 0.002
        world.place_ball(h0[0] + reach * math.cos(h0[2]), h0[1] + reach * math.sin(h0[2]))
        runner.run(cfg.settle_s)
        self._take_ball(0, runner.t_s)
        while len(self.records) < cfg.passes:
            now = runner.t_s
            if runner.tick_index % ticks_per_ai == 0:
                for i, twist in self._commands(now).items():
                    runner.command(i, twist)
                if self._pass is not None:
                    b = world.ball_state()
                    self._pass["path"].append((b.x, b.y))
            runner.tick()
            self._check(runner.t_s)
            if self.on_tick is not None:
                self.on_tick(self)
        return self.records

    def _check(self, now: float) -> None:
        """Light-barrier edges end a pass; a holder that lost its ball gets it back."""
        world = self.world
        edges = []
        for i in range(self.n_team + self.n_opp):
            seen = world.light_barrier(i)
            if seen and not self._barriers[i]:
                edges.append(i)
            self._barriers[i] = seen
        p = self._pass
        if p is not None:
            others = [i for i in edges if i != p["passer"] or now - p["t_kick"] > 0.5]
            if others:
                ours = [i for i in others if i < self.n_team]
                catcher = ours[0] if ours else others[0]
                self._end_pass("completed" if catcher < self.n_team else "intercepted", catcher, now)
                return
            b = world.ball_state()
            if math.hypot(b.vx, b.vy) < 0.05:
                p["rest_since"] = p["rest_since"] if p["rest_since"] is not None else now
            else:
                p["rest_since"] = None
            if now - p["t_kick"] > self.cfg.pass_timeout_s or (
                    p["rest_since"] is not None and now - p["rest_since"] > 0.5):
                self._end_pass("lost", None, now)
        elif self._holder is not None:
            # The barrier flips falsely now and then (sensors.LightBarrierSignal): a drop is a ball away 0.3 s.
            if world.light_barrier(self._holder) or now - self._hold_since < self.cfg.hold_min_s:
                self._barrier_lost_at = None
            elif self._barrier_lost_at is None:
                self._barrier_lost_at = now
            elif now - self._barrier_lost_at > DROP_AFTER_S:
                self.drops += 1
                self._restart(now)


def summary(records: list[PassRecord], cfg: PassConfig) -> dict:
    safe = [r for r in records if r.rated_safe]
    return {
        "passes": len(records),
        "completed": sum(r.outcome == "completed" for r in records),
        "intercepted": sum(r.outcome == "intercepted" for r in records),
        "lost": sum(r.outcome == "lost" for r in records),
        "rated_safe": len(safe),
        "safe_completed": sum(r.outcome == "completed" for r in safe),
    }


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
    parser = argparse.ArgumentParser(prog="python -m erforce_sim.closed_loop.passing_game",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("--team", type=int, default=11, help="our robots (2..11)")
    parser.add_argument("--opponents", type=int, default=3)
    parser.add_argument("--passes", type=int, default=10)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--plot", help="write a field plot of every pass here (PNG)")
    args = parser.parse_args(argv)
    cfg = GameConfig(team_size=args.team, opponents=args.opponents, passes=args.passes)
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
