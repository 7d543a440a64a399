"""Our team's AI in the passing game, one AI tick at a time: the functional core shared by the
in-process game (erforce_sim.in_process.passing_game) and the ``passing_game`` node.

No rclpy and no access to the physics: ``PassingPlayer`` is fed what a real AI sees, as it arrives (tracked
robots ``on_robot``, the tracked ball ``on_ball``, catch times and points ``on_catch``, the ball model
``on_model`` and the chip model ``on_chip_model`` in use (the predictor's), light barriers ``on_barrier``, the
opponents' too: how an interception is told, as a referee would), and ``tick(now)`` returns every robot's
``Commands`` (twist, kick, dribbler).

- The holder evaluates a pass to every teammate (passing.decisions.evaluate_passes), turns to the earliest safe
  catch (passing.decisions.select_pass) and kicks once it held the ball ``hold_min_s`` and aims within
  ``aim_tolerance_rad``, at the speed that arrives receivable; without a safe pass it waits
  ``wait_for_safe_s``. It keeps its receiver while it turns (``switch_margin_s``, ``keep_choice_s``).
- With no pass in reach at all (e.g. a latched ball model that stops every kick short) it waits
  ``no_option_wait_s`` and falls back (``fallback_choice``) to ``trusted_model``, then to any teammate, then
  to the nominal model;
  ``notice`` and ``stalled`` say why, for the caller's throttled warning (docs/decisions/0024).
- Each teammate's next target is refreshed one teammate per AI tick; the receiver runs receiver.Receiver
  facing it where the angle allows (``receive_facing``) and, once its barrier sees the ball, holds it.

A pass ends at a light-barrier edge (ours: completed; an opponent's: intercepted) or when the ball rests
``rest_for_s`` or ``pass_timeout_s`` runs out (lost), and is appended to ``records``. What only a referee
or the simulator does stays outside: ``ball_request`` names the robot to put the ball at, and the caller
reports it with ``ball_placed``.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from erforce_ball_model.ball_model import BallModelParams, ChipParams
from erforce_ball_model.catch_time import MAX_RECEIVE_ANGLE_RAD, CatchSearch, RobotLimits
from erforce_ball_model.passing.decisions import PassConfig, PassOption, evaluate_passes, press_targets, select_pass
from erforce_ball_model.receiver import (
    CatcherConfig,
    Receiver,
    catch_twist,
    heading_loop,
    pose_delay_s,
    wrap_angle,
)
from erforce_interfaces.runtime.param_schema import check_finite_fields, schema_defaults
from erforce_interfaces.wire.robot_config import BALL_RADIUS_M, FieldConfig

_DEFAULTS = schema_defaults("erforce_ball_model", "passing_game")

ANY_DISTANCE_M = (1e-3, 1e3)  # the passing distances of the last fallback: any teammate



def launch_direction(heading_rad: float, yaw_rate_radps: float, velocity_mps, ground_speed_mps: float,
                     dribbler_offset_m: float) -> float:
    """The direction [rad, ``field``] a kicked ball leaves in along the carpet: the kick's ground speed along the
    robot's heading plus the velocity the ball had on the dribbler, the robot's own and its turn's (the yaw rate
    times the dribbler's offset, sideways). A passer still turning at 2 rad/s sends a 2.8 m/s pass
    atan(0.102 * 2 / 2.8) = 4.2 deg to the side it turns to: at 2.5 m, 18 cm beside its receiver."""
    c, s = math.cos(heading_rad), math.sin(heading_rad)
    side = yaw_rate_radps * dribbler_offset_m
    vx = ground_speed_mps * c - side * s + float(velocity_mps[0])
    vy = ground_speed_mps * s + side * c + float(velocity_mps[1])
    return math.atan2(vy, vx)


def _model_text(m: BallModelParams) -> str:
    return f"a_slide {m.a_slide_mps2:g}, a_roll {m.a_roll_mps2:g} m/s^2, c_switch {m.c_switch:g}"


def feed_catches(now: float, catches, on_time, on_point) -> None:
    """Catches of one frame ((robot, catch time, point or None: never) each) as the per-robot topics bring
    them: every time (``on_time(robot, now, seconds)``), then every point (``on_point(robot, now, point)``)."""
    for robot, seconds, _ in catches:
        on_time(robot, now, seconds)
    for robot, _, point in catches:
        if point is not None:
            on_point(robot, now, point)

def new_poses(rows, index: dict, fed) -> list[tuple[int, object]]:
    """The rows of a /robots/tracked table (conversions.TrackedRobot, in its order) that bring a robot a new pose,
    as (the robot's index, row): ``index`` maps (team code, robot id) to the index (a row of a robot not in it is
    skipped), ``fed`` (a list or dict by index) holds each index's stamp last fed and is updated. A row whose
    stamp did not change since is the pose already fed (the table repeats every tracked robot at every frame),
    so each pose is fed once, as its odom brought it."""
    out = []
    for row in rows:
        k = index.get((row.team, row.robot_id))
        if k is not None and row.stamp_s != fed[k]:
            fed[k] = row.stamp_s
            out.append((k, row))
    return out


@dataclass(frozen=True)
class PlayerConfig:
    hold_min_s: float = _DEFAULTS["hold_min_s"]  # a new holder settles the ball this long before it kicks
    aim_tolerance_rad: float = _DEFAULTS["aim_tolerance_rad"]
    # a holder turns at most this fast (the dribbler keeps the ball)
    turn_rate_radps: float = _DEFAULTS["turn_rate_radps"]
    max_receive_angle_rad: float = MAX_RECEIVE_ANGLE_RAD  # receive facing the next target within this
    # a holder changes its chosen receiver for one this much earlier ...
    switch_margin_s: float = _DEFAULTS["switch_margin_s"]
    keep_choice_s: float = _DEFAULTS["keep_choice_s"]  # ... or safe where it is not, once that has held this long
    # a holder that has not kicked this long is warned about (``stalled``)
    stall_warn_s: float = _DEFAULTS["stall_warn_s"]
    # a holder without a safe pass keeps the ball this long, then plays the best
    wait_for_safe_s: float = _DEFAULTS["wait_for_safe_s"]
    pass_timeout_s: float = _DEFAULTS["pass_timeout_s"]
    rest_speed_mps: float = _DEFAULTS["rest_speed_mps"]  # a pass whose ball is slower than this for rest_for_s is lost
    rest_for_s: float = _DEFAULTS["rest_for_s"]
    # the barrier flips falsely now and then: a drop is a ball away this long
    drop_after_s: float = _DEFAULTS["drop_after_s"]
    # the passer's own barrier ends no pass this soon after its kick
    passer_blind_s: float = _DEFAULTS["passer_blind_s"]
    # a holder with no pass in reach this long plays the fallback (fallback_choice)
    no_option_wait_s: float = _DEFAULTS["no_option_wait_s"]
    passing: PassConfig = field(default_factory=PassConfig)
    catcher: CatcherConfig = field(default_factory=CatcherConfig)

    def __post_init__(self) -> None:
        check_finite_fields(self, ("hold_min_s", "aim_tolerance_rad", "wait_for_safe_s", "switch_margin_s",
                                   "keep_choice_s", "stall_warn_s", "rest_speed_mps", "rest_for_s", "drop_after_s",
                                   "passer_blind_s", "no_option_wait_s"), 0.0)
        check_finite_fields(self, ("turn_rate_radps", "pass_timeout_s"), 0.0, lower_open=True)
        check_finite_fields(self, ("max_receive_angle_rad",), 0.0, 0.5 * math.pi, upper_open=True)


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
    ball_path: tuple[tuple[float, float], ...] = ()  # ball positions every AI tick
    facing_target: int | None = None  # the teammate the receiver received facing (None: it faced the ball)
    kick_angle_deg: float = 0.0  # 0: a flat pass; else a chip at this elevation

    @property
    def margin_s(self) -> float:
        return self.opponent_predicted_s - self.predicted_catch_s

    def line(self) -> str:
        """One line for the terminal."""
        actual = "—" if self.actual_catch_s is None else f"{self.actual_catch_s:.2f} s"
        margin = "∞" if math.isinf(self.margin_s) else f"{self.margin_s:+.2f} s"
        rated = "safe" if self.rated_safe else "UNSAFE"
        chip = f" chip {self.kick_angle_deg:.0f} deg" if self.kick_angle_deg > 0.0 else ""
        text = (f"pass {self.index:2d}  robot_{self.passer} -> robot_{self.receiver}  "
                f"{self.kick_speed_mps:.2f} m/s{chip}  "
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


@dataclass
class Commands:
    """One AI tick's commands for our robots 0 .. n_team - 1."""

    twists: dict[int, np.ndarray]  # [vx, vy, wz] in the robot frame (base_link) [m/s, rad/s]
    kicks: dict[int, float]  # robot -> kick now with this ball speed [m/s]
    dribblers: dict[int, bool]  # every robot's dribbler: on / off
    kick_angles: dict[int, float] = field(default_factory=dict)  # robot -> its kick's chip angle [deg] (absent: 0)


@dataclass
class _Pass:
    t_kick_s: float
    passer: int
    choice: PassOption
    facing_target: int | None
    planned_next: int | None
    model: BallModelParams  # the model it was planned with
    path: list = field(default_factory=list)
    rest_since: float | None = None


class PassingPlayer:
    """Our team's decisions in the passing game (module docstring)."""

    def __init__(self, cfg: PlayerConfig, n_team: int, n_opponents: int, field_config: FieldConfig,
                 dribbler_offset_m: float, robot_radius_m: float, model: BallModelParams | None = None,
                 trusted_model: BallModelParams | None = None, chip_model: ChipParams | None = None) -> None:
        if n_team < 2 or n_opponents < 0:
            raise ValueError(f"need at least 2 of ours and no negative number of opponents, got {n_team}, "
                             f"{n_opponents}")
        self.n_team, self.n_opp = n_team, n_opponents
        self.model = BallModelParams() if model is None else model
        # the model the last completed pass was planned with (fallback_choice); a new game keeps the old one's
        self.trusted_model = self.model if trusted_model is None else trusted_model
        # the predictor's chip model (on_chip_model); None: not known yet, no chip is rated
        self.chip_model = chip_model
        n = n_team + n_opponents
        self.receiver: Receiver | None = None  # our receiver's skill while a pass rolls
        self.configure(cfg, field_config, dribbler_offset_m, robot_radius_m)
        self.poses = np.zeros((n, 3))  # tracked, from vision
        self.velocities = np.zeros((n, 2))
        self.yaw_rates = np.zeros(n)  # tracked [rad/s]
        self.pose_stamps = np.zeros(n)  # when each pose was measured [s]
        self.seen = np.zeros(n, dtype=bool)
        self.ball_xy = np.zeros(2)
        self.ball_velocity = np.zeros(2)
        self.ball_phase = "unknown"  # /ball/phase (on_ball_phase)
        self.barriers = np.zeros(n, dtype=bool)
        self.records: list[PassRecord] = []
        self.resets = 0  # balls asked back after a loss, an interception or a drop
        self.drops = 0  # of them: a holder lost the ball before it kicked
        self.ball_request: int | None = None  # put the ball at this robot's dribbler, then call ball_placed
        self._edges: list[tuple[int, float]] = []  # rising barrier edges not yet judged
        self._holder: int | None = None
        self._hold_since = 0.0
        self._barrier_lost_at: float | None = None
        self._choice: PassOption | None = None
        self._choice_model = self.model  # the model self._choice was planned with
        self._no_option_since: float | None = None  # the holder has had no pass in reach since
        self.notice: str | None = None  # what the last tick fell back on and why (None: nothing)
        self.stalled: str | None = None  # why the holder has not kicked after stall_warn_s (None: not that long)
        self._better_since: float | None = None  # another pass than the kept receiver's is better since
        self._pass: _Pass | None = None
        self._last_passer: int | None = None
        self._next_targets: dict[int, int] = {}  # teammate -> the teammate it would pass on to
        self._refresh = 0  # the next teammate whose next target is refreshed
        self._prefer: int | None = None  # the new holder's planned next target
        self._dribblers = dict.fromkeys(range(n_team), False)

    def configure(self, cfg: PlayerConfig, field_config: FieldConfig | None, dribbler_offset_m: float,
                  robot_radius_m: float) -> None:
        """New settings, from the next decision on (a receiver on its way keeps its skill's new settings too).
        ``field_config`` None: the world's field is not known yet; no pass is searched (start waits for it)."""
        self.cfg, self.field = cfg, field_config
        self.dribbler_offset_m, self.robot_radius_m = dribbler_offset_m, robot_radius_m
        cc = cfg.catcher
        limits = RobotLimits(cc.a_max_mps2, cc.v_max_mps)
        self.pass_search = self.receiver_search = None
        if field_config is not None:
            self.pass_search = CatchSearch(self.n_team + self.n_opp, limits, dribbler_offset_m=dribbler_offset_m,
                                           field=field_config)
            # a pass is judged by its receiver and the opponents: the search runs for them only (evaluate_passes)
            self.receiver_search = CatchSearch(1 + self.n_opp, limits, dribbler_offset_m=dribbler_offset_m,
                                               field=field_config)
        if self.receiver is not None:
            self.receiver.set_config(cc, dribbler_offset_m, robot_radius_m, field_config)

    # -------------------------------------------------------------------- state for observers
    @property
    def holder(self) -> int | None:
        return self._holder

    @property
    def passing(self) -> bool:
        return self._pass is not None

    @property
    def choice(self) -> tuple[int, PassOption] | None:
        """The pass chosen now and its passer: the holder's choice while it holds the ball, the pass being
        played while the ball rolls; None before a holder has chosen and after a pass ended."""
        if self._pass is not None:
            return self._pass.passer, self._pass.choice
        if self._holder is not None and self._choice is not None:
            return self._holder, self._choice
        return None

    @property
    def receive_facing(self) -> tuple[int, float] | None:
        """While a pass rolls to a receiver that receives facing its next target: (receiver, that facing
        [rad] in ``field``), for a predictor that searches its catch with the same facing."""
        p = self._pass
        if p is None or p.facing_target is None:
            return None
        return p.choice.receiver, wrap_angle(p.choice.receive_facing_rad)

    # -------------------------------------------------------------------- inputs
    def on_robot(self, i: int, now: float, pose, velocity, stamp_s: float | None = None) -> None:
        """Robot ``i``'s tracked pose [x, y, yaw] and field velocity [vx, vy] (and yaw rate [rad/s]), measured
        at ``stamp_s`` (None: now; ours first, then the opponents)."""
        velocity = np.asarray(velocity, dtype=float)
        self.poses[i] = np.asarray(pose, dtype=float)[:3]
        self.velocities[i] = velocity[:2]
        self.yaw_rates[i] = velocity[2] if velocity.shape[0] > 2 else 0.0
        self.pose_stamps[i] = now if stamp_s is None else stamp_s
        self.seen[i] = True
        if self.receiver is not None and self._pass is not None and i == self._pass.choice.receiver:
            self._feed_receiver(i, now)

    def on_ball(self, now: float, position, velocity, v_shoot_mps: float | None = None) -> None:
        """The tracked ball: [x, y] and [vx, vy], or [x, y, z] and [vx, vy, vz] (a ball in the air, z of its
        centre above its rest: the receiver takes a chip where it is low, receiver.Receiver)."""
        self.ball_xy = np.asarray(position, dtype=float)[:2].copy()
        self.ball_velocity = np.asarray(velocity, dtype=float)[:2].copy()
        if self.receiver is not None:
            self.receiver.on_ball(now, position, velocity)
            if v_shoot_mps is not None:
                self.receiver.on_v_shoot(now, v_shoot_mps)

    def on_ball_phase(self, phase: str) -> None:
        """The predictor's /ball/phase (Receiver.on_ball_phase)."""
        self.ball_phase = phase
        if self.receiver is not None:
            self.receiver.on_ball_phase(phase)

    def on_catch(self, i: int, now: float, catch_time_s: float, catch_point=None) -> None:
        """The predictor's catch time (CATCH_TIME_NEVER: never) and, when given, point for our robot ``i``."""
        if self.receiver is not None and self._pass is not None and i == self._pass.choice.receiver:
            self.receiver.on_catch_time(now, catch_time_s)
            if catch_point is not None:
                self.receiver.on_catch_point(now, np.asarray(catch_point, dtype=float))

    def on_catch_point(self, i: int, now: float, catch_point) -> None:
        """The predictor's catch point for our robot ``i`` (where its catch time comes apart from it)."""
        if self.receiver is not None and self._pass is not None and i == self._pass.choice.receiver:
            self.receiver.on_catch_point(now, np.asarray(catch_point, dtype=float))

    def on_catches(self, now: float, catches) -> None:
        """The predictor's catches of one frame for our robots, as (robot, catch time, point or None: never) in
        its order (conversions.catches_from_msg): each time (on_catch), then each point (on_catch_point), as
        the per-robot topics bring them; robots beyond the team are not ours."""
        feed_catches(now, [c for c in catches if 0 <= c[0] < self.n_team], self.on_catch, self.on_catch_point)

    def on_model(self, params: BallModelParams) -> None:
        self.model = params
        if self.receiver is not None:
            self.receiver.on_model(params)

    def on_chip_model(self, params: ChipParams) -> None:
        """The chip model in use (the predictor's): passes are rated and chips received with it from now on."""
        self.chip_model = params
        if self.receiver is not None:
            self.receiver.on_chip_model(params)

    def on_barrier(self, i: int, now: float, detected: bool) -> None:
        """Robot ``i``'s light barrier (ours first, then the opponents); a rising edge is judged at ``check``."""
        detected = bool(detected)
        if detected and not self.barriers[i]:
            self._edges.append((i, now))
        self.barriers[i] = detected

    # -------------------------------------------------------------------- the game
    def start(self, now: float, holder: int = 0) -> None:
        """The game begins: ask for the ball at ``holder``."""
        self.ball_request = holder

    def ball_placed(self, now: float) -> None:
        """The ball asked for (``ball_request``) is at that robot's dribbler: it holds it."""
        if self.ball_request is None:
            raise ValueError("ball_placed without a ball_request")
        holder, self.ball_request = self.ball_request, None
        self._edges = []
        self._take_ball(holder, now)

    def dribblers(self) -> dict[int, bool]:
        return dict(self._dribblers)

    def tick(self, now: float) -> Commands:
        """The AI tick: judge what happened since the last one (``check``), then every robot's command."""
        self.check(now)
        self.notice = self.stalled = None
        cfg = self.cfg
        twists = {i: np.zeros(3) for i in range(self.n_team)}
        kicks: dict[int, float] = {}
        kick_angles: dict[int, float] = {}
        if self._holder is not None and self.ball_request is None:
            h = self._holder
            self._update_next_targets(h, all_of_them=False)
            choice = self._choose(h, now)
            if choice is None:
                choice = self.fallback_choice(h, now)
            else:
                self._no_option_since = None
            if choice is not None:
                pose, gain, aimed = self._aim(h, choice, now)
                twist = catch_twist(pose, pose[:2], choice.direction_rad, cfg.catcher, gain)
                twist[2] = float(np.clip(twist[2], -cfg.turn_rate_radps, cfg.turn_rate_radps))
                twists[h] = twist
                patient = not choice.safe(cfg.passing) and now - self._hold_since < cfg.wait_for_safe_s
                if aimed and not patient and now - self._hold_since >= cfg.hold_min_s and self.barriers[h]:
                    kicks[h] = choice.kick_speed_mps
                    if choice.kick_angle_deg > 0.0:
                        kick_angles[h] = choice.kick_angle_deg
                    self._kick(h, choice, now)
                    twists[h] = np.zeros(3)
            if not kicks:
                self.stalled = self._stall_notice(h, choice, now)
        if self._pass is not None:
            self._pass.path.append((float(self.ball_xy[0]), float(self.ball_xy[1])))
            if self.receiver is not None:
                twists[self._pass.choice.receiver] = self.receiver.tick(now)
        return Commands(twists, kicks, self.dribblers(), kick_angles)

    def _aim(self, h: int, choice: PassOption, now: float) -> tuple[np.ndarray, float, bool]:
        """The holder's pose as its next command finds it ([x, y] and its heading predicted over the loop's delay)
        with the heading gain for that delay (receiver.heading_loop, as a receiver turns), and whether a kick now
        leaves along the pass within ``aim_tolerance_rad``. The ball leaves between the heading measured now (a robot
        that stops turning as it kicks) and ``launch_direction`` from the heading predicted over the delay (one that
        turns on): both must lie within the tolerance, so a robot still turning fast does not kick."""
        cc = self.cfg.catcher
        yaw_rate = float(self.yaw_rates[h])
        heading, gain = heading_loop(float(self.poses[h, 2]), yaw_rate, pose_delay_s(now, self.pose_stamps[h], cc), cc)
        ground = choice.kick_speed_mps * math.cos(math.radians(choice.kick_angle_deg))
        leaves = launch_direction(heading, yaw_rate, self.velocities[h], ground, self.dribbler_offset_m)
        tolerance = self.cfg.aim_tolerance_rad
        aimed = (abs(wrap_angle(choice.direction_rad - leaves)) <= tolerance
                 and abs(wrap_angle(choice.direction_rad - float(self.poses[h, 2]))) <= tolerance)
        return np.array([self.poses[h, 0], self.poses[h, 1], heading]), gain, aimed

    def check(self, now: float) -> None:
        """Light-barrier edges end a pass; a ball that rests or a time that is up loses it; a holder whose
        barrier stays dark lost the ball."""
        edges, self._edges = self._edges, []
        p = self._pass
        if p is not None:
            others = [i for i, _ in edges if i != p.passer or now - p.t_kick_s > self.cfg.passer_blind_s]
            if others:
                ours = [i for i in others if i < self.n_team]
                catcher = ours[0] if ours else others[0]
                at = next(t for i, t in edges if i == catcher)
                self._end_pass("completed" if catcher < self.n_team else "intercepted", catcher, at)
                return
            if math.hypot(*self.ball_velocity) < self.cfg.rest_speed_mps:
                p.rest_since = p.rest_since if p.rest_since is not None else now
            else:
                p.rest_since = None
            if now - p.t_kick_s > self.cfg.pass_timeout_s or (
                    p.rest_since is not None and now - p.rest_since > self.cfg.rest_for_s):
                self._end_pass("lost", None, now)
        elif self._holder is not None and self.ball_request is None:
            if self.barriers[self._holder] or now - self._hold_since < self.cfg.hold_min_s:
                self._barrier_lost_at = None
            elif self._barrier_lost_at is None:
                self._barrier_lost_at = now
            elif now - self._barrier_lost_at > self.cfg.drop_after_s:
                self.drops += 1
                self._restart()

    # -------------------------------------------------------------------- decisions
    def _options(self, holder: int, model: BallModelParams | None = None,
                 passing: PassConfig | None = None, candidates: list[int] | None = None) -> list[PassOption]:
        """Every pass from ``holder`` under ``model`` and ``passing`` (None: the model in use, the config's) to
        ``candidates`` (None: ``_candidates``), each judged from the pose it is kicked from (the ball at the
        dribbler turned to it), whatever the yaw now."""
        n = self.n_team
        targets = {j: self.poses[k, :2] for j, k in self._next_targets.items()}
        candidates = self._candidates(holder) if candidates is None else candidates
        return evaluate_passes(self.poses[holder, :2], self.poses[:n, :2], self.velocities[:n],
                               self.poses[n:, :2], self.velocities[n:], candidates, self.pass_search,
                               self.model if model is None else model, self.cfg.passing if passing is None else passing,
                               self.dribbler_offset_m, targets, self.cfg.max_receive_angle_rad, self.receiver_search,
                               from_passer_centre=True, chip_params=self.chip_model,
                               block_radius_m=self.robot_radius_m + BALL_RADIUS_M)

    def fallback_choice(self, holder: int, now: float) -> PassOption | None:
        """The pass of a holder that has no pass in reach under the model in use (module docstring): None
        for ``no_option_wait_s``; then the best pass under ``trusted_model``, else the best to any teammate
        whatever its distance (the one it had the ball from included) under the trusted model, then under the
        nominal one (``BallModelParams()``: the carpet's), else None (it holds the ball). Sets ``notice``."""
        if self._no_option_since is None:
            self._no_option_since = now
        waited = now - self._no_option_since
        if waited < self.cfg.no_option_wait_s:
            return None
        m = self.model
        why = (f"robot_{holder}: no pass in reach for {waited:.1f} s under the ball model in use ({_model_text(m)})")
        anywhere = dataclasses.replace(self.cfg.passing, min_distance_m=ANY_DISTANCE_M[0],
                                       max_distance_m=ANY_DISTANCE_M[1])
        everybody = [k for k in range(self.n_team) if k != holder]
        tried: list[BallModelParams] = []
        for model, named in ((self.trusted_model, "the model of the last completed pass"),
                             (BallModelParams(), "the nominal model")):
            if model in tried:
                continue
            tried.append(model)
            planned = f"planned with {named} ({_model_text(model)})"
            best, what = None if model == m else select_pass(self._options(holder, model), self.cfg.passing), planned
            if best is None:
                best = select_pass(self._options(holder, model, anywhere, everybody), self.cfg.passing)
                what = "a pass outside the passing distances" + ("" if model == m else f", {planned}")
            if best is not None:
                self.notice = f"{why}: {what} to robot_{best.receiver}"
                self._choice, self._choice_model = best, model
                return best
        self.notice = (f"{why}, not even outside the passing distances, nor under the model of the last completed "
                       f"pass or the nominal model: it holds the ball")
        return None

    def _next_target(self, holder: int, j: int) -> int | None:
        """Where teammate ``j`` would pass on once it has the ball from ``holder`` (select_pass from where it
        stands, every robot facing the ball; None: no teammate in reach)."""
        n = self.n_team
        others = [k for k in range(n) if k not in (holder, j)]
        options = evaluate_passes(self.poses[j, :2], self.poses[:n, :2], self.velocities[:n], self.poses[n:, :2],
                                  self.velocities[n:], others, self.pass_search, self.model, self.cfg.passing,
                                  self.dribbler_offset_m, receiver_search=self.receiver_search,
                                  chip_params=self.chip_model, block_radius_m=self.robot_radius_m + BALL_RADIUS_M)
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

    def _choose(self, holder: int, now: float) -> PassOption | None:
        """The holder's pass: the best (select_pass), but a holder turning to a receiver stays with it until another
        has been better for ``keep_choice_s`` on end: earlier by ``switch_margin_s`` at the same rating, or rated
        safe and catchable where the kept pass is not (ratings flicker as robots move and opponents press the
        lanes: a holder that followed each flicker would turn back and forth and never aim). A kept receiver that
        drops out of the options is left at once."""
        cfg = self.cfg
        options = self._options(holder)
        best = select_pass(options, cfg.passing)
        kept = self._choice.receiver if self._choice is not None else self._prefer  # a new holder: its plan
        same = None if kept is None else next((o for o in options if o.receiver == kept), None)
        if same is None or best is None or best.receiver == kept:
            self._better_since = None
        else:
            worse = (math.isinf(same.receiver_catch_s)
                     or (best.safe(cfg.passing) and not same.safe(cfg.passing)))
            earlier = (same.safe(cfg.passing) == best.safe(cfg.passing)
                       and best.receiver_catch_s + cfg.switch_margin_s < same.receiver_catch_s)
            if not (worse or earlier):
                self._better_since = None
            elif self._better_since is None:
                self._better_since = now
            if self._better_since is None or now - self._better_since < cfg.keep_choice_s:
                best = same
        self._choice, self._choice_model = best, self.model
        return best

    def _stall_notice(self, holder: int, choice: PassOption | None, now: float) -> str | None:
        """Why a holder that has kept the ball ``stall_warn_s`` has not kicked yet (None: not that long)."""
        held_s = now - self._hold_since
        if held_s < self.cfg.stall_warn_s:
            return None
        if choice is None:
            why = "no pass chosen"
        elif not self.barriers[holder]:
            why = "its light barrier does not see the ball"
        else:
            off = abs(wrap_angle(choice.direction_rad - self.poses[holder, 2]))
            rated = "safe" if choice.safe(self.cfg.passing) else "unsafe"
            why = (f"its pass to robot_{choice.receiver} ({rated}) is {off:.3f} rad off its yaw (aim_tolerance_rad "
                   f"{self.cfg.aim_tolerance_rad:g})")
        return f"robot_{holder} has held the ball {held_s:.1f} s without kicking: {why}"

    def _kick(self, holder: int, choice: PassOption, now: float) -> None:
        self._holder, self._last_passer = None, holder
        self._dribblers = dict.fromkeys(range(self.n_team), False)
        self._dribblers[choice.receiver] = True
        receiver = Receiver(self.cfg.catcher, self.dribbler_offset_m, self.robot_radius_m, self.field)
        receiver.on_model(self._choice_model)
        if self.chip_model is not None:
            receiver.on_chip_model(self.chip_model)
        receiver.on_ball_phase(self.ball_phase)
        self.receiver = receiver
        self._feed_receiver(choice.receiver, now)
        k = None
        ball_rad = choice.direction_rad + math.pi
        if abs(math.remainder(choice.receive_facing_rad - ball_rad, 2.0 * math.pi)) > 1e-9:
            k = self._next_targets[choice.receiver]  # it receives facing its next target
            receiver.on_next_target(self.poses[k, :2], self.cfg.max_receive_angle_rad)
        self._pass = _Pass(now, holder, choice, k, self._next_targets.get(choice.receiver), self._choice_model)

    def _feed_receiver(self, i: int, now: float) -> None:
        self.receiver.on_odom(now, self.poses[i], (*self.velocities[i], self.yaw_rates[i]), self.pose_stamps[i])

    def _end_pass(self, outcome: str, caught_by: int | None, now: float) -> None:
        p, choice = self._pass, self._pass.choice
        name = None if caught_by is None else (
            f"robot_{caught_by}" if caught_by < self.n_team else f"opponent_{caught_by - self.n_team}")
        self.records.append(PassRecord(
            len(self.records) + 1, p.t_kick_s, p.passer, choice.receiver, choice.kick_speed_mps,
            choice.receiver_catch_s, choice.opponent_catch_s, choice.first_opponent, choice.safe(self.cfg.passing),
            outcome, name, None if caught_by is None else now - p.t_kick_s, tuple(p.path), p.facing_target,
            choice.kick_angle_deg))
        self._pass, self.receiver = None, None
        self._dribblers = dict.fromkeys(range(self.n_team), False)
        if outcome == "completed":
            self.trusted_model = p.model
            self._take_ball(caught_by, now, p.planned_next if caught_by == choice.receiver else None)
        else:
            self._restart()

    def _take_ball(self, holder: int, now: float, planned_next: int | None = None) -> None:
        self._holder, self._hold_since, self._choice, self._barrier_lost_at = holder, now, None, None
        self._no_option_since = self._better_since = None
        self._prefer = planned_next
        self._dribblers = dict.fromkeys(range(self.n_team), False)
        self._dribblers[holder] = True
        self._next_targets = {}
        self._update_next_targets(holder, all_of_them=True)

    def _restart(self) -> None:
        """Ask for the ball at the dribbler of our robot farthest from every opponent."""
        self.resets += 1
        self._last_passer = None
        self._holder, self._choice, self._no_option_since = None, None, None
        self._dribblers = dict.fromkeys(range(self.n_team), False)
        n = self.n_team
        if self.n_opp:
            opp = self.poses[n:, :2]
            self.ball_request = max(range(n), key=lambda k: float(np.min(np.hypot(*(opp - self.poses[k, :2]).T))))
        else:
            self.ball_request = 0


HELD_DISTANCE_M = 0.05  # the ball this close to a robot's dribbler point (from tracked poses) ...
HELD_SPEED_MPS = 0.5  # ... and slower than this: that robot holds it (a pass leaves at min_kick_mps or faster)


class PressingTeam:
    """The opponents' decisions in the passing game, one AI tick at a time: a team of catchers that presses
    the passing lanes. The functional core shared by the in-process game (erforce_sim.in_process.passing_game)
    and the ``team_catcher`` node (``press_lanes``).

    Its robots (``robot_ids``) each run receiver.Receiver; with ``as_team`` they form a team in which only the
    robot that can catch a rolling ball first drives to it (receiver.team_receiver). With ``passing`` (a
    PassConfig: its ``press_fraction``) it also sees the other team's ``n_other`` robots (``on_other_robot``,
    tracked poses) and, while one of them holds the ball (the tracked ball slower than ``HELD_SPEED_MPS``
    and within ``HELD_DISTANCE_M`` of its dribbler point), sends each of its robots to its press target
    (passing.decisions.press_targets: on the lane from the ball to a teammate of the holder), facing the ball. Its
    inputs are fed as they arrive, each with the time it arrived; ``tick(now)`` returns every robot's
    Twist [vx, vy, wz] (robot frame; zeros: hold) and ``notices`` what a robot's receiver could not use.
    ``intercepts``: its robots only have to stop a chip, with their body (receiver.Receiver), as the opponents do.
    """

    def __init__(self, cfg: CatcherConfig, dribbler_offset_m: float, robot_radius_m: float,
                 field_config: FieldConfig | None, robot_ids, as_team: bool = True,
                 passing: PassConfig | None = None, n_other: int = 0, model: BallModelParams | None = None,
                 chip_model: ChipParams | None = None, intercepts: bool = False) -> None:
        ids = [int(i) for i in robot_ids]
        if len(set(ids)) != len(ids):  # none: a game without opponents
            raise ValueError(f"robot_ids: need distinct ids, got {ids}")
        if n_other < 0:
            raise ValueError(f"n_other must be >= 0, got {n_other!r}")
        team = ids if as_team else ()
        self.robot_ids = ids
        self.receivers = {i: Receiver(cfg, dribbler_offset_m, robot_radius_m, field_config, robot_id=i,
                                      team_robot_ids=team, intercepts=intercepts) for i in ids}
        self.on_model(BallModelParams() if model is None else model)
        self.chip_model: ChipParams | None = None  # the predictor's (on_chip_model); None: not known yet
        if chip_model is not None:
            self.on_chip_model(chip_model)
        self.poses: dict[int, tuple[float, np.ndarray]] = {}  # own robot -> (arrived, [x, y, yaw])
        self.other_poses = np.zeros((n_other, 3))
        self.other_seen = np.zeros(n_other, dtype=bool)
        self._ball: tuple[float, np.ndarray, np.ndarray] | None = None  # (arrived, position, velocity)
        self.notices: dict[int, str] = {}
        self.set_config(cfg, dribbler_offset_m, robot_radius_m, field_config, passing)

    def set_config(self, cfg: CatcherConfig, dribbler_offset_m: float, robot_radius_m: float,
                   field_config: FieldConfig | None, passing: PassConfig | None = None) -> None:
        self.cfg, self.dribbler_offset_m, self.passing = cfg, dribbler_offset_m, passing
        for receiver in self.receivers.values():
            receiver.set_config(cfg, dribbler_offset_m, robot_radius_m, field_config)

    # -------------------------------------------------------------------- inputs
    def on_ball(self, now: float, position, velocity) -> None:
        self._ball = (now, np.asarray(position, dtype=float)[:2].copy(), np.asarray(velocity, dtype=float)[:2].copy())
        for receiver in self.receivers.values():
            receiver.on_ball(now, position, velocity)

    def on_v_shoot(self, now: float, v_shoot_mps: float) -> None:
        for receiver in self.receivers.values():
            receiver.on_v_shoot(now, v_shoot_mps)

    def on_ball_phase(self, phase: str) -> None:
        """The predictor's /ball/phase (Receiver.on_ball_phase)."""
        for receiver in self.receivers.values():
            receiver.on_ball_phase(phase)

    def on_model(self, params: BallModelParams) -> None:
        """The ball model in use (the predictor's): every robot's receiver predicts with it."""
        self.model = params
        for receiver in self.receivers.values():
            receiver.on_model(params)

    def on_chip_model(self, params: ChipParams) -> None:
        """The chip model in use (the predictor's): every robot's receiver predicts a ball in the air with it."""
        self.chip_model = params
        for receiver in self.receivers.values():
            receiver.on_chip_model(params)

    def on_odom(self, robot: int, now: float, pose, velocity, stamp_s: float | None = None) -> None:
        """Own robot's tracked pose [x, y, yaw] and field velocity [vx, vy] (and yaw rate [rad/s]), measured
        at ``stamp_s`` (Receiver.on_odom)."""
        self.poses[robot] = (now, np.asarray(pose, dtype=float)[:3].copy())
        self.receivers[robot].on_odom(now, pose, velocity, stamp_s)

    def on_catch_time(self, robot: int, now: float, seconds: float) -> None:
        for i, receiver in self.receivers.items():
            if i == robot:
                receiver.on_catch_time(now, seconds)
            else:
                receiver.on_teammate_catch_time(robot, now, seconds)

    def on_catch_point(self, robot: int, now: float, point) -> None:
        self.receivers[robot].on_catch_point(now, point)

    def on_catches(self, now: float, catches) -> None:
        """The predictor's catches of one frame for this team, as (robot, catch time, point or None: never) in
        its order (conversions.catches_from_msg): each time, then each point, as the per-robot topics bring
        them; robots this team does not drive are skipped."""
        feed_catches(now, [c for c in catches if c[0] in self.receivers], self.on_catch_time, self.on_catch_point)

    def on_barrier(self, robot: int, detected: bool) -> bool:
        """Own robot's light barrier; True on the rising edge (it received the ball)."""
        return self.receivers[robot].on_barrier(detected)

    def on_other_robot(self, k: int, now: float, pose) -> None:
        """The other team's robot ``k`` (0 .. n_other - 1): its tracked pose [x, y, yaw]."""
        self.other_poses[k] = np.asarray(pose, dtype=float)[:3]
        self.other_seen[k] = True

    # -------------------------------------------------------------------- decision
    def holder(self, now: float) -> int | None:
        """The other team's robot that holds the ball now (module constants), None: nobody of them."""
        ball = self._ball
        if ball is None or now - ball[0] > self.cfg.stale_after_s or not self.other_seen.any():
            return None
        if math.hypot(*ball[2]) >= HELD_SPEED_MPS:
            return None
        seen = np.flatnonzero(self.other_seen)
        x, y, yaw = self.other_poses[seen].T
        d = self.dribbler_offset_m
        gaps = np.hypot(x + d * np.cos(yaw) - ball[1][0], y + d * np.sin(yaw) - ball[1][1])
        k = int(np.argmin(gaps))
        return int(seen[k]) if gaps[k] <= HELD_DISTANCE_M else None

    def press_targets(self, now: float) -> dict[int, np.ndarray]:
        """Own robot -> where it waits while the other team holds the ball (empty: nobody holds it, no
        pressing, or no fresh own pose)."""
        holder = None if self.passing is None else self.holder(now)
        if holder is None:
            return {}
        own = [i for i in self.robot_ids if i in self.poses and now - self.poses[i][0] <= self.cfg.stale_after_s]
        if not own:
            return {}
        seen = np.flatnonzero(self.other_seen)
        x, y, yaw = self.other_poses[holder]
        d = self.dribbler_offset_m
        ball = (x + d * math.cos(yaw), y + d * math.sin(yaw))
        targets = press_targets(ball, self.other_poses[seen, :2], np.array([self.poses[i][1][:2] for i in own]),
                                int(np.flatnonzero(seen == holder)[0]), self.passing)
        return dict(zip(own, targets, strict=True))

    def tick(self, now: float) -> dict[int, np.ndarray]:
        """Every own robot's Twist now: its press target while the other team holds the ball, else its receiver's."""
        self.notices = {}
        twists = {}
        for i, receiver in self.receivers.items():
            twists[i] = receiver.tick(now)
            if receiver.notice:
                self.notices[i] = receiver.notice
        targets = self.press_targets(now)
        if targets:
            ball = self._ball[1]
            for i, target in targets.items():
                pose = self.poses[i][1]
                try:
                    twists[i] = catch_twist(pose, target, math.atan2(ball[1] - pose[1], ball[0] - pose[0]), self.cfg)
                except ValueError as exc:
                    self.notices[i] = f"no command: {exc}"
                    twists[i] = np.zeros(3)
        return twists
