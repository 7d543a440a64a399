"""The passing game's decisions (the paper's motivation in Sec. 5: who of all robots, ours and theirs,
reaches a rolling ball first): which teammate to pass to, how hard to kick, and where the opponents go.

No rclpy. A pass is judged by robotTimeToBall (catch_time.catch_after_reaction, the predictor's own
question) for every robot on the field, on the ball the kick would make:

- ``kick_speed_for`` inverts the two-phase model (ball_model.py): the kick speed at which the ball
  still has ``arrive_speed_mps`` after ``distance_m``. Sliding until ``c v0``, then rolling::

      arrive while sliding:  v0^2 = v_a^2 + 2 |a_slide| d                        (v_a >= c v0)
      arrive while rolling:  v0^2 = (v_a^2 + 2 |a_roll| d) / (c^2 + (1 - c^2) |a_roll| / |a_slide|)

  A ball that arrives slower is easy to receive but gives the opponents time; the speed at the
  receiver is the receivable one (``PassConfig.arrive_speed_mps``), the kick speed follows.
- ``evaluate_passes`` builds, per candidate receiver, the ball the kick makes and runs one
  robotTimeToBall for the whole field: the earliest opponent's catch time, and whether the receiver
  can catch it at all. The receiver receives where it stands, turning in place to its receive facing
  (receiver.Receiver: on the ball's line it stands still), so the kick aims at where its dribbler will
  be and its catch is the ball's arrival there (ballRollTime), later than its robotTimeToBall, which
  runs to meet the ball. The receive facing is the one the receiver will take: towards its next
  target (``next_targets``) when catch_time.receive_facing allows, else against the ball; the
  receiver's robotTimeToBall runs with the offset pointing that way (the paper's targetpos).
  An opponent also stops the ball with its body: with ``block_radius_m`` (robot radius plus ball
  radius) its time is the earlier of its robotTimeToBall and its block time
  (catch_time.robot_time_to_block: its body on the ball's path before the ball is there, before the
  ball reaches the receiver), so a pass past an opponent standing near the lane is not rated safe.
  The receiver still needs the real catch. ``margin_s`` = opponent - arrival; a pass is safe when the
  margin is at least ``PassConfig.safe_margin_s``.
- A chip (``PassConfig.chip_angle_deg`` > 0; chip_model.ChipTrajectory with the predictor's chip model, the one
  it tracks chips with) is rated the same way, on the chip the kick would make, with ChipParams' two heights: an
  opponent stops it with its body where it is at most ``max_catch_height_m`` plus ``chip_clearance_m`` high
  (robotTimeToBall on its low windows), so one under its flight cannot; the clearance is the plan's margin over
  the interception height (a body taller than the league's 0.15 m, as grSim's 0.167 m; a ball that slows in the
  air comes down lower than the fixed-loss model says); the receiver takes it with its dribbler only once it stays
  at most ``max_receive_height_m`` high (the light barrier's beam), so a chip still hopping at a few centimetres would
  bounce off it. It is kicked so that it stays that low from ``chip_settle_fraction`` of the way to the
  receiver on (``chip_speed_for``: the hops in closed form), and is rated only when it has settled by the time
  it reaches the receiver's dribbler. Per receiver the flat pass is played when it is safe, else the chip when
  that is safe, else the one with the larger margin.
- ``select_pass``: of the safe passes the one whose catch comes earliest; when none is safe, the
  one with the largest margin (rated unsafe; the caller may still play it).
- ``press_targets``: where opponents wait while a robot of ours holds the ball: each covers the
  passing lane to the teammate nearest to it, ``PassConfig.press_fraction`` of the way from the
  ball. While the ball rolls they run receiver.Receiver (the first of them to the ball goes).
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from erforce_ball_model.ball_model import BallModelParams, BallTrajectory, ChipParams
from erforce_ball_model.catch_time import (
    MAX_RECEIVE_ANGLE_RAD,
    ROBOT_REACTION_S,
    CatchKind,
    CatchSearch,
    RobotLimits,
    catch_after_reaction,
    contact_offset,
    receive_facing,
    robot_time_to_block,
)
from erforce_ball_model.chip_model import ChipTrajectory, chip_settle_distance
from erforce_interfaces.runtime.param_schema import check_finite_fields, schema_defaults
from erforce_interfaces.wire.robot_config import SSL_MAX_KICK_MPS

_DEFAULTS = schema_defaults("erforce_ball_model", "passing_game")


@dataclass(frozen=True)
class PassConfig:
    arrive_speed_mps: float = _DEFAULTS["arrive_speed_mps"]  # ball speed at the receiver's dribbler
    min_kick_mps: float = _DEFAULTS["min_kick_mps"]
    max_kick_mps: float = SSL_MAX_KICK_MPS
    # a safe pass: every opponent's catch comes this much after the receiver's
    safe_margin_s: float = _DEFAULTS["safe_margin_s"]
    min_distance_m: float = _DEFAULTS["min_distance_m"]  # no pass to a teammate closer than this to the ball
    max_distance_m: float = _DEFAULTS["max_distance_m"]
    # everybody reacts to the kick this late (the predictor's reaction time)
    reaction_s: float = ROBOT_REACTION_S
    # an opponent waits this far along the lane from the ball to its teammate
    press_fraction: float = schema_defaults("erforce_ball_model", "team_catcher")["press_fraction"]
    chip_angle_deg: float = _DEFAULTS["chip_angle_deg"]  # a chip's elevation (the kicker's kick_angle); 0: flat only
    chip_settle_fraction: float = _DEFAULTS["chip_settle_fraction"]  # a chip stays low from this far along the pass
    chip_step_back_m: float = _DEFAULTS["chip_step_back_m"]  # ... or this far behind the receiver, which steps back
    # a chip is rated as if the opponents stood this much taller than the interception height (max_catch_height_m)
    chip_clearance_m: float = _DEFAULTS["chip_clearance_m"]

    def __post_init__(self) -> None:
        check_finite_fields(self, ("arrive_speed_mps", "min_kick_mps", "max_kick_mps", "min_distance_m",
                                   "max_distance_m"), 0.0, lower_open=True)
        if self.min_kick_mps > self.max_kick_mps or self.min_distance_m > self.max_distance_m:
            raise ValueError("min_kick_mps <= max_kick_mps and min_distance_m <= max_distance_m, please")
        check_finite_fields(self, ("safe_margin_s", "reaction_s", "chip_step_back_m", "chip_clearance_m"), 0.0)
        check_finite_fields(self, ("press_fraction",), 0.0, 1.0)
        check_finite_fields(self, ("chip_angle_deg",), 0.0, 90.0, upper_open=True)
        check_finite_fields(self, ("chip_settle_fraction",), 0.0, 1.0, lower_open=True)


def kick_speed_for(distance_m: float, arrive_speed_mps: float, params: BallModelParams) -> float:
    """Kick speed v0 after which the ball has ``arrive_speed_mps`` left at ``distance_m`` (module docstring)."""
    d, va = float(distance_m), float(arrive_speed_mps)
    if not (math.isfinite(d) and d >= 0.0 and math.isfinite(va) and va >= 0.0):
        raise ValueError(f"distance_m and arrive_speed_mps must be finite and >= 0, got {distance_m!r}, "
                         f"{arrive_speed_mps!r}")
    a_s, a_r, c = abs(params.a_slide_mps2), abs(params.a_roll_mps2), params.c_switch
    v0 = math.sqrt(va * va + 2.0 * a_s * d)
    if va >= c * v0:  # still sliding on arrival
        return v0
    return math.sqrt((va * va + 2.0 * a_r * d) / (c * c + (1.0 - c * c) * a_r / a_s))


def chip_speed_for(distance_m: float, angle_deg: float, params: ChipParams, min_mps: float, max_mps: float) -> float:
    """Kick speed of a chip at ``angle_deg`` that stays at most ``params.max_receive_height_m`` high from
    ``distance_m`` along the carpet on (``chip_settle_distance``, non-decreasing in the speed): the fastest such
    within [min_mps, max_mps], by bisection (the bound that is nearest when it cannot be met)."""
    lo, hi = min_mps, max_mps
    if chip_settle_distance(lo, angle_deg, params) >= distance_m:
        return lo
    if chip_settle_distance(hi, angle_deg, params) <= distance_m:
        return hi
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if chip_settle_distance(mid, angle_deg, params) <= distance_m else (lo, mid)
    return lo


@dataclass(frozen=True)
class PassOption:
    receiver: int  # index into the team
    kick_speed_mps: float
    direction_rad: float  # kick direction in `field`
    receiver_catch_s: float  # the ball at the receiver's dribbler, from the kick; inf: it cannot catch it
    opponent_catch_s: float  # the earliest opponent's robotTimeToBall or block, the reaction time included; inf: none
    first_opponent: int | None  # index into the opponents
    receive_facing_rad: float = math.nan  # the receiver's dribbler direction at the catch (in `field`)
    kick_angle_deg: float = 0.0  # 0: a flat pass; else a chip at this elevation

    @property
    def margin_s(self) -> float:
        if math.isinf(self.receiver_catch_s):
            return -math.inf
        return self.opponent_catch_s - self.receiver_catch_s

    def safe(self, cfg: PassConfig) -> bool:
        return self.margin_s >= cfg.safe_margin_s


def select_pass(options: Sequence[PassOption], cfg: PassConfig) -> PassOption | None:
    """Of the safe options the earliest catch (ties: the larger margin, then the lower receiver); when
    none is safe, the largest margin; None when there is no option a receiver can catch."""
    able = [o for o in options if math.isfinite(o.receiver_catch_s)]
    if not able:
        return None
    safe = [o for o in able if o.safe(cfg)]
    if safe:
        return min(safe, key=lambda o: (o.receiver_catch_s, -o.margin_s, o.receiver))
    return max(able, key=lambda o: (o.margin_s, -o.receiver_catch_s, -o.receiver))


def _times(result, reaction_s: float) -> np.ndarray:
    kind, t = result.kind, result.time_s
    return np.where(kind == int(CatchKind.NEVER), math.inf, t + reaction_s)


def evaluate_passes(
    ball_xy,
    team_xy: np.ndarray,
    team_vel: np.ndarray,
    opponents_xy: np.ndarray,
    opponents_vel: np.ndarray,
    candidates: Sequence[int],
    search: CatchSearch,
    params: BallModelParams,
    cfg: PassConfig,
    dribbler_offset_m: float,
    next_targets: Mapping[int, Sequence[float]] | None = None,
    max_receive_angle_rad: float = MAX_RECEIVE_ANGLE_RAD,
    receiver_search: CatchSearch | None = None,
    from_passer_centre: bool = False,
    chip_params: ChipParams | None = None,
    block_radius_m: float = 0.0,
) -> list[PassOption]:
    """One PassOption per candidate teammate in reach (module docstring).

    ``from_passer_centre``: ``ball_xy`` is the passer's centre and each pass starts where it is kicked from,
    at the passer's dribbler turned to that pass (``dribbler_offset_m`` ahead of the centre along it): the
    rating does not change while the passer turns.

    ``search`` is a CatchSearch for ``len(team_xy) + len(opponents_xy)`` robots (teammates first);
    every robot faces the incoming ball, as the predictor assumes, but a candidate with a next target
    (``next_targets``: candidate -> [x, y]) receives facing it within ``max_receive_angle_rad``
    (catch_time.receive_facing); everybody reacts ``cfg.reaction_s`` late. With ``receiver_search`` (a
    CatchSearch like ``search`` for ``1 + len(opponents_xy)`` robots) each pass searches only the receiver
    and the opponents, the robots it is judged by: the same numbers, as robotTimeToBall is per robot.
    A pass that is not safe flat is rated as a chip too (``cfg.chip_angle_deg``), with the chip model in use
    ``chip_params`` (the predictor's; None: not known, no chip is rated); the option is the chip when that is
    safe or has the larger margin (``kick_angle_deg``).
    ``block_radius_m`` > 0: an opponent's body within this distance of the ball's centre stops it
    (``_block_times``); 0: the opponents' catches only (the paper's rating).
    """
    team_xy, opponents_xy = np.asarray(team_xy, dtype=float), np.asarray(opponents_xy, dtype=float)
    next_targets = {} if next_targets is None else next_targets
    robots = _PassRobots.of(team_xy, team_vel, opponents_xy, opponents_vel, search, receiver_search, cfg,
                            next_targets)
    ball = origin = np.asarray(ball_xy, dtype=float)
    options = []
    for j in candidates:
        centre = team_xy[j]
        if from_passer_centre:
            reach_m = math.dist(centre, origin)
            if reach_m <= dribbler_offset_m:
                continue  # within the passer's own dribbler: no pass
            ball = origin + dribbler_offset_m * (centre - origin) / reach_m
        distance = math.dist(centre, ball)
        if not cfg.min_distance_m <= distance <= cfg.max_distance_m:
            continue
        ball, u, receive_rad, contact_m = _receive_geometry(
            centre, ball, origin, distance, next_targets[j] if j in next_targets else None, dribbler_offset_m,
            max_receive_angle_rad, from_passer_centre)
        options.append(_pass_option(robots, j, ball, u, receive_rad, contact_m, params, cfg, chip_params,
                                    opponents_xy, opponents_vel, block_radius_m))
    return options


@dataclass
class _PassRobots:
    """The robots a pass is rated against (teammates first, then the opponents) and the searches that rate it
    (evaluate_passes); ``narrow``: each pass searches only its receiver and the opponents."""

    pos: np.ndarray
    vel: np.ndarray
    n_team: int
    search: CatchSearch
    cfg: PassConfig
    next_targets: Mapping[int, Sequence[float]]
    facing_fixed: np.ndarray
    facing: np.ndarray
    narrow: bool
    receiving: np.ndarray | None = None  # teammates receive a chip, the opponents stop it (catch_time)
    receiver_search: CatchSearch | None = None
    sub_pos: np.ndarray | None = None
    sub_vel: np.ndarray | None = None
    sub_fixed: np.ndarray | None = None
    sub_facing: np.ndarray | None = None
    sub_receiving: np.ndarray | None = None

    @classmethod
    def of(cls, team_xy: np.ndarray, team_vel, opponents_xy: np.ndarray, opponents_vel, search: CatchSearch,
           receiver_search: CatchSearch | None, cfg: PassConfig,
           next_targets: Mapping[int, Sequence[float]]) -> _PassRobots:
        n_team = len(team_xy)
        pos = np.concatenate([team_xy, opponents_xy]).reshape(-1, 2)
        vel = np.concatenate([np.asarray(team_vel, dtype=float),
                              np.asarray(opponents_vel, dtype=float)]).reshape(-1, 2)
        if search.num_robots != len(pos):
            raise ValueError(f"search is for {search.num_robots} robots, the field has {len(pos)}")
        # a robot that is not finite makes the whole field's search refuse the pass (ValueError): left to it
        narrow = receiver_search is not None and bool(np.isfinite(pos).all() and np.isfinite(vel).all())
        robots = cls(pos, vel, n_team, search, cfg, next_targets, np.zeros(len(pos), dtype=bool),
                     np.zeros(len(pos)), narrow, np.arange(len(pos)) < n_team)
        if narrow:
            if receiver_search.num_robots != 1 + len(opponents_xy):
                raise ValueError(f"receiver_search is for {receiver_search.num_robots} robots, the receiver and the "
                                 f"opponents are {1 + len(opponents_xy)}")
            # row 0: the receiver's, set per pass; then the opponents
            robots.receiver_search = receiver_search
            robots.sub_pos = np.concatenate([pos[:1], pos[n_team:]])
            robots.sub_vel = np.concatenate([vel[:1], vel[n_team:]])
            robots.sub_fixed = np.zeros(len(robots.sub_pos), dtype=bool)
            robots.sub_facing = np.zeros(len(robots.sub_pos))
            robots.sub_receiving = np.arange(len(robots.sub_pos)) == 0
        return robots

    def rate(self, traj, j: int, receive_rad: float) -> tuple[float, np.ndarray]:
        """(the receiver ``j``'s robotTimeToBall, every opponent's), reaction included, on the ball ``traj``."""
        cfg = self.cfg
        if self.narrow:
            self.sub_pos[0], self.sub_vel[0] = self.pos[j], self.vel[j]
            self.sub_fixed[0], self.sub_facing[0] = j in self.next_targets, receive_rad
            times = _times(catch_after_reaction(self.receiver_search, traj, self.sub_pos, self.sub_vel,
                                                cfg.reaction_s, self.sub_fixed, self.sub_facing, 0.1,
                                                self.sub_receiving), cfg.reaction_s)
            return times[0], times[1:]
        self.facing_fixed[j], self.facing[j] = j in self.next_targets, receive_rad
        try:
            times = _times(catch_after_reaction(self.search, traj, self.pos, self.vel, cfg.reaction_s,
                                                self.facing_fixed, self.facing, 0.1, self.receiving), cfg.reaction_s)
        finally:
            self.facing_fixed[j] = False
        return times[j], times[self.n_team:]


def _receive_geometry(centre: np.ndarray, ball: np.ndarray, origin: np.ndarray, distance: float,
                      next_target: Sequence[float] | None, dribbler_offset_m: float, max_receive_angle_rad: float,
                      from_passer_centre: bool) -> tuple[np.ndarray, np.ndarray, float, float]:
    """(kick point, pass direction, the receiver's facing, ball travel to its dribbler) of a pass to the robot at
    ``centre``: facing the ball, or its ``next_target`` within ``max_receive_angle_rad`` (evaluate_passes)."""
    u = (centre - ball) / distance
    receive_rad = math.atan2(-u[1], -u[0])
    aim = centre - dribbler_offset_m * u  # the dribbler's centre, facing the ball
    if next_target is not None:
        for _ in range(3):  # the facing moves the aim by at most the offset: a fixed point, reached fast
            receive_rad = receive_facing(u, centre, next_target, max_receive_angle_rad)
            aim = centre + contact_offset(receive_rad, dribbler_offset_m)
            if from_passer_centre:  # the kick point turns with the pass: on the line from the centre to aim
                ball = origin + dribbler_offset_m * (aim - origin) / math.dist(aim, origin)
            u = (aim - ball) / math.dist(aim, ball)
    contact_m = float((aim - ball) @ u)  # ball travel to the receiver's dribbler
    return ball, u, receive_rad, contact_m


def _pass_option(robots: _PassRobots, j: int, ball: np.ndarray, u: np.ndarray, receive_rad: float,
                 contact_m: float, params: BallModelParams, cfg: PassConfig, chip_params: ChipParams | None,
                 opponents_xy: np.ndarray, opponents_vel, block_radius_m: float) -> PassOption:
    """The pass to ``j`` rated flat, and as a chip when that is not safe (evaluate_passes)."""
    v0 = min(max(kick_speed_for(contact_m, cfg.arrive_speed_mps, params), cfg.min_kick_mps), cfg.max_kick_mps)
    traj = BallTrajectory.of_floats(float(ball[0]), float(ball[1]), float(u[0] * v0), float(u[1] * v0), v0, params)
    receiver_time, opp = robots.rate(traj, j, receive_rad)
    arrival_s = float(traj.time_to_distance(contact_m))
    if block_radius_m > 0.0 and len(opp):  # an opponent's body on the flat ball's path stops it too
        opp = np.minimum(opp, _block_times(traj, arrival_s, opponents_xy, opponents_vel, robots.search,
                                           robots.n_team, block_radius_m, cfg.reaction_s))
    option = _option(j, v0, u, arrival_s if math.isfinite(receiver_time) else math.inf, opp, receive_rad, 0.0)
    if chip_params is not None and cfg.chip_angle_deg > 0.0 and not option.safe(cfg):
        # settled before the receiver's dribbler, or behind it where the receiver steps back to take it
        for settle_m in (cfg.chip_settle_fraction * contact_m, contact_m + 0.5 * cfg.chip_step_back_m,
                         contact_m + cfg.chip_step_back_m)[:3 if cfg.chip_step_back_m > 0.0 else 1]:
            lob = _chip_option(robots, j, ball, u, receive_rad, contact_m, settle_m, params, cfg, chip_params,
                               opponents_xy, opponents_vel, block_radius_m)
            if lob.safe(cfg) or lob.margin_s > option.margin_s:
                option = lob
            if option.safe(cfg):
                break
    return option


def _chip_option(robots: _PassRobots, j: int, ball: np.ndarray, u: np.ndarray, receive_rad: float, contact_m: float,
                 settle_m: float, params: BallModelParams, cfg: PassConfig, chip_params: ChipParams,
                 opponents_xy: np.ndarray, opponents_vel, block_radius_m: float) -> PassOption:
    """The pass to ``j`` as the chip that stays low enough to receive from ``settle_m`` along it on: taken where
    the receiver stands (its dribbler ``contact_m`` on) when it has settled by then, else where the receiver meets
    it once it has (robotTimeToBall, receiving: it steps back along the line)."""
    over = dataclasses.replace(chip_params, max_catch_height_m=chip_params.max_catch_height_m + cfg.chip_clearance_m)
    chip, v0 = _chip_pass(ball, u, settle_m, cfg, params, over)  # the same flight; the opponents stand taller
    receiver_time, opp = robots.rate(chip, j, receive_rad)
    arrival_s = math.inf
    if math.isfinite(receiver_time):
        arrival_s = float(chip.ground_track().time_to_distance(contact_m))
        if arrival_s < chip.time_below_height_s(chip_params.max_receive_height_m):
            arrival_s = receiver_time if settle_m > contact_m else math.inf  # else it would bounce off
    if block_radius_m > 0.0 and len(opp):  # where it is low, an opponent's body stops it too
        opp = np.minimum(opp, _chip_block_times(chip, arrival_s, opponents_xy, opponents_vel, robots.search,
                                                robots.n_team, block_radius_m, cfg.reaction_s))
    return _option(j, v0, u, arrival_s, opp, receive_rad, cfg.chip_angle_deg)


def _option(j: int, v0: float, u: np.ndarray, arrival_s: float, opp: np.ndarray, receive_rad: float,
            angle_deg: float) -> PassOption:
    first = int(np.argmin(opp)) if len(opp) and math.isfinite(opp.min()) else None
    return PassOption(int(j), v0, math.atan2(u[1], u[0]), arrival_s, math.inf if first is None else float(opp[first]),
                      first, receive_rad, angle_deg)


def _chip_pass(ball: np.ndarray, u: np.ndarray, settle_m: float, cfg: PassConfig, params: BallModelParams,
               chip_params: ChipParams) -> tuple[ChipTrajectory, float]:
    """The chip along ``u`` that stays low enough to receive from ``settle_m`` on."""
    v0 = chip_speed_for(settle_m, cfg.chip_angle_deg, chip_params, cfg.min_kick_mps, cfg.max_kick_mps)
    a = math.radians(cfg.chip_angle_deg)
    vxy = v0 * math.cos(a)
    return ChipTrajectory((float(ball[0]), float(ball[1]), 0.0), (float(u[0] * vxy), float(u[1] * vxy),
                                                                  v0 * math.sin(a)), chip_params, params), v0


@functools.lru_cache(maxsize=8)
def _their_limits(search: CatchSearch, n_team: int) -> RobotLimits:
    """The opponents' limits of ``search`` (robots from ``n_team`` on): fixed for a search, made once (the
    limits' copy and checks cost more than a compiled block search)."""
    limits = search.limits
    return RobotLimits(limits.a_max_mps2[n_team:], limits.v_max_mps[n_team:])


def _block_times(traj: BallTrajectory, arrival_s: float, opponents_xy, opponents_vel, search: CatchSearch,
                 n_team: int, radius_m: float, reaction_s: float) -> np.ndarray:
    """Each opponent's block time of the pass (catch_time.robot_time_to_block, with the opponents' limits of
    ``search``) before the ball reaches the receiver (``arrival_s``); inf: it cannot. Compiled when ``search``
    is (its kernels="background" runs Python until they are loaded)."""
    theirs = _their_limits(search, n_team)
    return robot_time_to_block(traj, opponents_xy, opponents_vel, theirs, radius_m, arrival_s, reaction_s=reaction_s,
                               kernels="now" if search.compiled else "background")


def _chip_block_times(chip: ChipTrajectory, arrival_s: float, opponents_xy, opponents_vel, search: CatchSearch,
                      n_team: int, radius_m: float, reaction_s: float) -> np.ndarray:
    """``_block_times`` of a chip: within each of its windows low enough to stop it (at most
    ``max_catch_height_m``: ``low_windows_s``) before it reaches the receiver, on its ground track from then."""
    out = np.full(len(opponents_xy), math.inf)
    theirs = _their_limits(search, n_team)
    for a, b in chip.low_windows_s():
        if a >= min(arrival_s, chip.stop_time_s):
            break
        track = (chip.advanced(a) if a > 0.0 else chip).ground_track()
        out = np.minimum(out, robot_time_to_block(track, opponents_xy, opponents_vel, theirs, radius_m,
                                                  min(b, arrival_s), reaction_s=reaction_s, t_start_s=a,
                                                  kernels="now" if search.compiled else "background"))
    return out


def press_targets(ball_xy, team_xy: np.ndarray, opponents_xy: np.ndarray, holder: int | None,
                  cfg: PassConfig) -> np.ndarray:
    """Where each opponent waits while our ``holder`` has the ball: on the lane from the ball to a
    teammate (not the holder), ``cfg.press_fraction`` of the way. Opponent and teammate are paired
    greedily, the closest pair first, each teammate covered once while there are enough of them."""
    ball = np.asarray(ball_xy, dtype=float)
    team_xy, opponents_xy = np.asarray(team_xy, dtype=float), np.asarray(opponents_xy, dtype=float)
    others = [k for k in range(len(team_xy)) if k != holder]
    targets = opponents_xy.copy()
    if not others:
        return targets
    free_opps = set(range(len(opponents_xy)))
    while free_opps:  # one round per len(others) opponents: more opponents than lanes double up
        free_mates = set(others)
        pairs = sorted((math.dist(opponents_xy[o], team_xy[m]), o, m) for o in free_opps for m in others)
        for _, o, m in pairs:
            if o in free_opps and m in free_mates:
                targets[o] = ball + cfg.press_fraction * (team_xy[m] - ball)
                free_opps.discard(o)
                free_mates.discard(m)
    return targets
