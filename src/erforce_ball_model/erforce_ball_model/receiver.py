"""The receive skill of the paper's Fig. 6: drive to the predicted catch point, face the
requested direction, arrive in time.

No rclpy: ``Receiver`` is one robot's behaviour over time (the catcher node feeds it the robot's and
the ball's state and the predictor's catch point and time, and publishes the Twist its ``tick``
returns, robot frame); the functions below are its steps.

Where to receive (``choose_target``): a robot on the ball's line stands still; else it goes to the
nearest point on the line, at or beyond its projection, that it reaches ``receive_slack_s`` before the
ball (``receive_point``: robust to a robot that lags its plan); else to the predictor's catch point,
which has no slack. In a team (``team_receiver``) only the robot that can catch first receives.

The approach follows robotTimeToPos's model (``v = min(v_max, sqrt(2 a_max d))``, arriving at rest),
from the pose the robot will have when the command acts: the measured pose carried the loop's delay
ahead with the tracked velocity, so that a robot does not brake late and take the ball on its side.

``heading_loop``: a P-law on an integrating yaw behind a delay D has the phase margin pi/2 - K D. The
loop takes D as the pose's age plus ``command_lead_s``, predicts the heading over it with the tracked
yaw rate and caps the gain at ``heading_gain_delay_max`` / D (phase margin 87 deg at K D = 0.5; the
nominal 8 /s where the delay is small). docs/decisions/0023 has the reasoning.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from erforce_ball_model.ball_model import BallModelParams, BallTrajectory, ChipParams, ball_time_to_distance
from erforce_ball_model.catch_time import (
    MAX_RECEIVE_ANGLE_RAD,
    ROBOT_A_MAX_MPS2,
    ROBOT_V_MAX_MPS,
    can_reach,
    contact_offset,
    receive_facing,
)
from erforce_ball_model.chip_model import ChipTrajectory, flying_ball
from erforce_interfaces.runtime.param_schema import schema_defaults
from erforce_interfaces.wire.robot_config import FieldConfig

_DEFAULTS = schema_defaults("erforce_ball_model", "catcher")

CATCH_TIME_NEVER = -1.0  # the catch time that means "no catch" (erforce_interfaces.wire.contract)


@dataclass(frozen=True)
class CatcherConfig:
    # The robot's limits for catching; the ball predictor plans with the same (plus a reaction
    # time), so the catch it predicts is the one this drives. The velocity controller allows
    # 6 m/s^2 and the traction limit of this wheel layout is 4-6 m/s^2 depending on direction.
    a_max_mps2: float = ROBOT_A_MAX_MPS2  # the planner's limits (catch_time): the predictor plans with them
    v_max_mps: float = ROBOT_V_MAX_MPS
    w_max_radps: float = _DEFAULTS["w_max_radps"]
    heading_gain_per_s: float = _DEFAULTS["heading_gain_per_s"]
    # inside this the robot holds still (above the 2 mm vision noise)
    arrive_tolerance_m: float = _DEFAULTS["arrive_tolerance_m"]
    # no turning for smaller errors: vision yaw noise is ~0.01 rad
    heading_deadband_rad: float = _DEFAULTS["heading_deadband_rad"]
    # The heading loop's delay beyond the pose's age: the AI tick, the velocity loop (heading_loop).
    command_lead_s: float = _DEFAULTS["command_lead_s"]
    # the heading gain times the loop's delay at most (heading_loop)
    heading_gain_delay_max: float = _DEFAULTS["heading_gain_delay_max"]
    # The approach aims for rest at the target with this fraction of a_max: the robot realized
    # about 2.2 m/s^2 sideways in the simulated Fig. 6 scene (traction, velocity-loop lag), and a
    # profile planned with more overshoots the catch point across the ball's line. 0.5 caught
    # earlier and more often than 0.6-0.85 in the in-process closed loop of the demo scenes.
    braking_margin: float = _DEFAULTS["braking_margin"]
    # Receive: once the dribbler is on the incoming ball's line, stand still and let the
    # ball come. The first-catch point ahead has no slack by definition; chasing it moves
    # the robot towards the ball and makes every arrive-at-rest catch infeasible.
    receive_line_tolerance_m: float = _DEFAULTS["receive_line_tolerance_m"]
    # Take the receive point on the ball's line only when the robot gets there this much before
    # the ball (ballRollTime of the two-phase model): control lag and vision latency.
    receive_slack_s: float = _DEFAULTS["receive_slack_s"]
    # A committed robot (see choose_target) keeps blocking the ball's line only when its projection
    # on it is this close: it nearly made it. Farther off, chasing the line deflects bank shots.
    commit_distance_m: float = _DEFAULTS["commit_distance_m"]
    # Receiver (over time): inputs older than stale_after_s count as missing; a ball faster than
    # min_ball_speed_mps that has also travelled engage_distance_m from where it rested engages (vision
    # noise fakes speed, above all right after a ball appears, but not travel); an engaged robot gives up
    # once the ball rested disengage_after_rest_s; a robot that had a target within commit_s is committed
    # (choose_target); in a team the receiver keeps the ball until another robot's catch time is
    # team_switch_margin_s earlier.
    stale_after_s: float = _DEFAULTS["stale_after_s"]
    min_ball_speed_mps: float = _DEFAULTS["min_ball_speed_mps"]
    engage_distance_m: float = _DEFAULTS["engage_distance_m"]
    fetch_resting_ball: bool = _DEFAULTS["fetch_resting_ball"]
    disengage_after_rest_s: float = _DEFAULTS["disengage_after_rest_s"]
    commit_s: float = _DEFAULTS["commit_s"]
    team_switch_margin_s: float = _DEFAULTS["team_switch_margin_s"]

    def __post_init__(self) -> None:
        for name in ("a_max_mps2", "v_max_mps", "w_max_radps", "heading_gain_per_s", "arrive_tolerance_m"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0.0):
                raise ValueError(f"{name} must be finite and > 0, got {v!r}")
        if not (math.isfinite(self.command_lead_s) and 0.0 <= self.command_lead_s <= 1.0):
            raise ValueError(f"command_lead_s must be in [0, 1], got {self.command_lead_s!r}")
        if not (math.isfinite(self.heading_gain_delay_max) and 0.0 < self.heading_gain_delay_max < 0.5 * math.pi):
            raise ValueError(f"heading_gain_delay_max must be in (0, pi/2), got {self.heading_gain_delay_max!r}")
        if not (math.isfinite(self.heading_deadband_rad) and 0.0 <= self.heading_deadband_rad < math.pi):
            raise ValueError(f"heading_deadband_rad must be in [0, pi), got {self.heading_deadband_rad!r}")
        if not (math.isfinite(self.receive_line_tolerance_m) and self.receive_line_tolerance_m >= 0.0):
            raise ValueError(f"receive_line_tolerance_m must be finite and >= 0, got {self.receive_line_tolerance_m!r}")
        for name in ("receive_slack_s", "commit_distance_m", "min_ball_speed_mps", "engage_distance_m",
                     "disengage_after_rest_s", "commit_s", "team_switch_margin_s"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0.0):
                raise ValueError(f"{name} must be finite and >= 0, got {v!r}")
        if not (math.isfinite(self.stale_after_s) and self.stale_after_s > 0.0):
            raise ValueError(f"stale_after_s must be finite and > 0, got {self.stale_after_s!r}")
        if not (0.0 < self.braking_margin <= 1.0):
            raise ValueError(f"braking_margin must be in (0, 1], got {self.braking_margin!r}")


RECEIVE_SEARCH_M = 1.5  # receive_point looks this far along the ball's line beyond the robot's projection
RECEIVE_STEP_M = 0.05


def wrap_angle(angle_rad: float) -> float:
    """Angle in [-pi, pi)."""
    return (angle_rad + math.pi) % (2.0 * math.pi) - math.pi


def field_to_robot(velocity_field: np.ndarray, yaw_rad: float) -> np.ndarray:
    """Rotate a field-frame planar vector into the robot frame (base_link)."""
    c, s = math.cos(yaw_rad), math.sin(yaw_rad)
    vx, vy = float(velocity_field[0]), float(velocity_field[1])
    return np.array([c * vx + s * vy, -s * vx + c * vy])


def approach_velocity(position: np.ndarray, target: np.ndarray, cfg: CatcherConfig) -> np.ndarray:
    """Field-frame velocity that reaches ``target`` at rest as fast as the limits allow."""
    delta = np.asarray(target, dtype=float) - np.asarray(position, dtype=float)
    distance = float(np.hypot(delta[0], delta[1]))
    if distance <= cfg.arrive_tolerance_m:
        return np.zeros(2)
    speed = min(cfg.v_max_mps, math.sqrt(2.0 * cfg.a_max_mps2 * cfg.braking_margin * distance))
    return delta / distance * speed


def pose_delay_s(now: float, stamp_s: float, cfg: CatcherConfig) -> float:
    """The heading loop's delay for a pose measured at ``stamp_s``: its age (a stamp from the future counts as
    fresh, one older than stale as stale) plus ``cfg.command_lead_s``."""
    return min(max(now - stamp_s, 0.0), cfg.stale_after_s) + cfg.command_lead_s


def heading_loop(yaw_rad: float, yaw_rate_radps: float, delay_s: float, cfg: CatcherConfig) -> tuple[float, float]:
    """(the heading predicted ``delay_s`` ahead [rad], the heading gain for that delay [1/s]) for a pose
    whose heading and tracked yaw rate reach the robot's turning ``delay_s`` late (module docstring)."""
    delay_s = max(float(delay_s), 0.0)
    gain = cfg.heading_gain_per_s
    if delay_s > 0.0:
        gain = min(gain, cfg.heading_gain_delay_max / delay_s)
    turned = yaw_rate_radps * delay_s
    return (wrap_angle(yaw_rad + turned) if turned else yaw_rad), gain  # as measured, to the last bit, when at rest


def catch_twist(pose: np.ndarray, target: np.ndarray, facing_rad: float, cfg: CatcherConfig,
                heading_gain_per_s: float | None = None) -> np.ndarray:
    """Twist [vx, vy, wz] in the robot frame that drives the robot centre to ``target``
    while turning to ``facing_rad`` (the direction the dribbler should point); the heading gain
    ``heading_gain_per_s`` (None: the config's)."""
    pose = np.asarray(pose, dtype=float)
    if pose.shape != (3,) or not np.all(np.isfinite(pose)):
        raise ValueError(f"pose must be 3 finite values [x, y, yaw], got {pose!r}")
    target = np.asarray(target, dtype=float)
    if target.shape != (2,) or not np.all(np.isfinite(target)) or not math.isfinite(facing_rad):
        raise ValueError("target and facing must be finite")
    v_field = approach_velocity(pose[:2], target, cfg)
    v_robot = field_to_robot(v_field, pose[2])
    heading_error = wrap_angle(facing_rad - pose[2])
    if abs(heading_error) <= cfg.heading_deadband_rad:
        heading_error = 0.0
    gain = cfg.heading_gain_per_s if heading_gain_per_s is None else heading_gain_per_s
    wz = float(np.clip(gain * heading_error, -cfg.w_max_radps, cfg.w_max_radps))
    return np.array([v_robot[0], v_robot[1], wz])


def on_receive_line(pose: np.ndarray, ball_xy: np.ndarray, ball_velocity: np.ndarray, dribbler_offset_m: float,
                    tolerance_m: float, facing_rad: float | None = None) -> bool:
    """True when the ball is coming at the robot's dribbler: the dribbler centre lies within
    ``tolerance_m`` of the ball's line of travel, ahead of the ball. The dribbler of the robot as it
    stands, or once it faces ``facing_rad`` (it turns in place)."""
    pose = np.asarray(pose, dtype=float)
    v = np.asarray(ball_velocity, dtype=float)
    speed = float(np.hypot(v[0], v[1]))
    if speed < 1e-6:
        return False
    direction = v / speed
    dribbler = pose[:2] + contact_offset(pose[2] if facing_rad is None else facing_rad, dribbler_offset_m)
    rel = dribbler - np.asarray(ball_xy, dtype=float)
    along = float(rel @ direction)
    across = abs(float(rel[0] * direction[1] - rel[1] * direction[0]))
    return along > 0.0 and across <= tolerance_m


def line_intercept(robot_xy: np.ndarray, ball_xy: np.ndarray, ball_velocity: np.ndarray,
                   dribbler_offset_m: float, facing_rad: float | None = None) -> np.ndarray | None:
    """Where the robot centre must stand to block the incoming ball's line, nearest to it.

    Facing the ball (``facing_rad`` None): the robot's own projection onto the ball's line of travel,
    at least one dribbler offset ahead of the ball (receive_point's candidate). Facing ``facing_rad``:
    its dribbler's projection, at or ahead of the ball, and the centre one offset back from it
    (catch_time.contact_offset). None when the ball is not moving or has already passed the robot.
    """
    v = np.asarray(ball_velocity, dtype=float)
    speed = float(np.hypot(v[0], v[1]))
    if speed < 1e-6:
        return None
    direction = v / speed
    ball = np.asarray(ball_xy, dtype=float)
    robot = np.asarray(robot_xy, dtype=float)
    along = float((robot - ball) @ direction)
    if along <= 0.0:
        return None
    if facing_rad is None:
        return ball + direction * max(along, dribbler_offset_m)
    offset = contact_offset(facing_rad, dribbler_offset_m)
    return ball + direction * max(float((robot + offset - ball) @ direction), 0.0) - offset


def receive_point(
    robot_xy: np.ndarray,
    robot_velocity: np.ndarray,
    ball: BallTrajectory,
    dribbler_offset_m: float,
    cfg: CatcherConfig,
    field: FieldConfig | None = None,
    robot_radius_m: float = 0.0,
    slack_s: float | None = None,
    facing_rad: float | None = None,
    chip: ChipTrajectory | None = None,
    intercepts: bool = False,
) -> np.ndarray | None:
    """The nearest place to receive the ball on its line that the robot reaches with time to spare.

    ``chip``: the ball is in the air (``ball`` is its ground track): only points where it arrives low enough
    to take are candidates (``chip_within_reach``; ``intercepts``: to stop it with the body).

    Candidates are robot centre targets with the dribbler on the ball's line, facing the ball (or
    ``facing_rad``: the centre one contact_offset back from the line, line_intercept):
    the robot's projection onto the line and points further along it, every
    ``RECEIVE_STEP_M`` up to ``RECEIVE_SEARCH_M``. The first one is returned where the robot,
    by robotTimeToPos with the catcher's limits from its present velocity, arrives
    ``slack_s`` (default ``cfg.receive_slack_s``) before the ball (ballRollTime of the two-phase model), that the
    ball reaches before it stops and that lies on the field. None when there is none or the
    ball is not coming (not moving, already past).

    Plain Python per candidate (catch_time.can_reach, the exact sign of robotTimeToPos against the
    budget), nearest first up to the first hit: a few dozen cases per tick need no numba, so the
    catcher starts without it.
    """
    projection = line_intercept(robot_xy, ball.position_m, ball.velocity_mps, dribbler_offset_m, facing_rad)
    if projection is None:
        return None
    start, u = ball.position_m, ball.direction
    offset = -dribbler_offset_m * u if facing_rad is None else contact_offset(facing_rad, dribbler_offset_m)
    # ball travel to the dribbler, from the projection on
    contact_m = float((projection + offset - start) @ u) + np.arange(0.0, RECEIVE_SEARCH_M + 1e-9, RECEIVE_STEP_M)
    targets = start + contact_m[:, None] * u - offset
    contact_m = np.maximum(contact_m, 0.0)
    ok = np.ones(len(contact_m), dtype=bool)
    if field is not None:
        inside = field.half_length_m - robot_radius_m, field.half_width_m - robot_radius_m
        ok &= (np.abs(targets[:, 0]) <= inside[0]) & (np.abs(targets[:, 1]) <= inside[1])
    slack = cfg.receive_slack_s if slack_s is None else slack_s
    robot_xy, robot_velocity = np.asarray(robot_xy, dtype=float), np.asarray(robot_velocity, dtype=float)
    for i in np.flatnonzero(ok):
        if chip is None:
            t_ball = ball_time_to_distance(ball.floats, float(contact_m[i]))  # +inf where it stops short
        else:  # the track's pieces lie on one line (no walls)
            t_ball = float(ball.time_to_distance(float(contact_m[i])))
        if t_ball == math.inf:
            break  # and so do all farther points
        if chip is not None and not chip_within_reach(chip, t_ball, intercepts):
            continue  # it flies over this point, or hops off the dribbler
        if can_reach(targets[i] - robot_xy, robot_velocity, t_ball - slack, cfg.a_max_mps2, cfg.v_max_mps):
            return targets[i]
    return None


def choose_target(
    pose: np.ndarray,
    robot_velocity: np.ndarray,
    ball: BallTrajectory | None,
    catch_point: np.ndarray | None,
    dribbler_offset_m: float,
    cfg: CatcherConfig,
    field: FieldConfig | None = None,
    robot_radius_m: float = 0.0,
    committed: bool = False,
    facing_rad: float | None = None,
    chip: ChipTrajectory | None = None,
    intercepts: bool = False,
) -> np.ndarray | None:
    """Where the robot centre goes (to face the ball, or ``facing_rad`` once it turned), in this order:
    stay when the dribbler is already on the incoming ball's line; the nearest receive point with time
    to spare (for a ``committed`` robot: reached at all before the ball); the predicted catch point
    (None when the predictor has none); when ``committed``, the robot's projection on the ball's line
    if it is within ``cfg.commit_distance_m``; else hold (None).

    ``chip``: the ball is in the air, ``ball`` its ground track: the robot stays on its line only where the ball
    comes low enough to take (``chip_within_reach``), else receive_point takes it where it does (a chip that
    settles behind the receiver: it steps back along the line).
    ``ball`` is the moving ball's trajectory (None when it rests: the velocity of a resting ball is
    vision noise in a random direction, its "line" means nothing). ``committed``: the robot was
    driving to a target for this ball moments ago. Its plan can turn infeasible on the way (it
    lags, arrives fast); holding then brakes it wherever it is, often across the line, while
    blocking the line may still catch. Chasing the line from farther away only gets in the ball's
    way: it deflects a ball that a wall would have returned. The slack is what starts a receive; a
    robot on its way keeps it while it still gets there first. With the slack, the Fig. 6 robot a few
    centimetres before the line (moving, so with 0.1 s to spare, not 0.15 s) was sent to the
    predicted catch of a later window, turned and ran from the ball, which then hit its side: in
    the demo's Fig. 6 scene played in one process (erforce_sim.in_process.scenes), 5 of 20 seeds caught the
    ball only after that, against 0 of 20 with this hysteresis.
    """
    if ball is not None:
        if on_receive_line(pose, ball.position_m, ball.velocity_mps, dribbler_offset_m, cfg.receive_line_tolerance_m,
                           facing_rad) and (chip is None or chip_within_reach(chip, _time_to_dribbler(
                               pose, ball, dribbler_offset_m, facing_rad), intercepts)):
            return np.asarray(pose[:2], dtype=float)
        target = receive_point(pose[:2], robot_velocity, ball, dribbler_offset_m, cfg, field, robot_radius_m,
                               slack_s=0.0 if committed else None, facing_rad=facing_rad, chip=chip,
                               intercepts=intercepts)
        if target is not None:
            return target
    if catch_point is not None:
        return catch_point
    if committed and ball is not None:
        block = line_intercept(pose[:2], ball.position_m, ball.velocity_mps, dribbler_offset_m, facing_rad)
        if block is not None and math.dist(block, pose[:2]) <= cfg.commit_distance_m:
            return block
    return None


def chip_within_reach(chip: ChipTrajectory, t_s: float, intercepts: bool = False) -> bool:
    """Whether a robot takes the chip at ``t_s``: a receiver once it stays at most ``max_receive_height_m`` high
    (light barrier and dribbler bar; earlier, near a touchdown, it hops up over the bar or off the robot's front),
    an interceptor (``intercepts``) where it is at most ``max_catch_height_m`` high (its body stops it)."""
    if intercepts:
        return bool(chip.position_at(t_s)[2] <= chip.params.max_catch_height_m)
    return t_s >= chip.time_below_height_s(chip.params.max_receive_height_m)


def _time_to_dribbler(pose: np.ndarray, track: BallTrajectory, dribbler_offset_m: float,
                      facing_rad: float | None) -> float:
    """When the ball on ``track`` (a chip's ground track: straight pieces on one line) reaches the dribbler of the
    robot at ``pose`` (facing ``facing_rad``, None: as it stands)."""
    dribbler = pose[:2] + contact_offset(pose[2] if facing_rad is None else facing_rad, dribbler_offset_m)
    along = float((dribbler - track.position_m) @ track.direction)
    return float(track.time_to_distance(max(along, 0.0)))


def team_receiver(catch_times_s: Mapping[int, float], previous: int | None, switch_margin_s: float) -> int | None:
    """The robot of a team that receives the ball: the one with the earliest catch time (robotTimeToBall).

    ``catch_times_s`` maps robot id to its catch time; a robot that cannot catch the ball (``inf``, or a
    negative time such as CATCH_TIME_NEVER) or is not known is left out. The ``previous`` receiver keeps
    the role unless another robot is earlier by more than ``switch_margin_s``: every robot of the team
    decides alone, from predictions that jitter frame by frame, and a role that flaps makes two robots
    start and stop. Ties go to the lower id. None when nobody can catch the ball.
    """
    if not (math.isfinite(switch_margin_s) and switch_margin_s >= 0.0):
        raise ValueError(f"switch_margin_s must be finite and >= 0, got {switch_margin_s!r}")
    able = {i: t for i, t in catch_times_s.items() if 0.0 <= t < math.inf}  # NaN fails both comparisons
    if not able:
        return None
    first = min(able, key=lambda i: (able[i], i))
    if previous in able and able[previous] <= able[first] + switch_margin_s:
        return previous
    return first


class Receiver:
    """One robot's receive behaviour over time: what the catcher node does, without ROS.

    Feed it what arrives, each with the robot time it arrived (``on_*``), and ask ``tick(now)`` for
    the Twist [vx, vy, wz] (robot frame) at the command rate. Inputs older than ``stale_after_s``
    count as missing. The robot engages when the ball moves, holds once its light barrier sees the
    ball (and disengages), and gives up once the ball rested ``disengage_after_rest_s``; a ball engages
    it once it moves and has travelled ``engage_distance_m`` from where it last rested, and after a
    catch only a ball that rested since (a pass is received once: a ball that bounces off the dribbler
    or is carried away is the next skill's). While
    engaged it drives to ``choose_target``, facing the incoming ball as the predictor assumed, or, given
    where it passes on (``on_next_target``), facing that target when ``receive_facing`` allows (the
    paper's robotTimeToBall with targetpos; the predictor's search must then face the same way). In a
    team (``team_robot_ids``, its own id among them) it drives only while ``team_receiver`` names it,
    or nobody can catch the ball by the predictions (then each robot judges alone). A chip is taken once it
    stays low enough for the dribbler; with ``intercepts`` (an opponent that only has to stop the ball) where
    it is low enough for the body (chip_within_reach). ``notice`` says what the last call could not use, for the
    node's throttled log (None: nothing).
    """

    def __init__(self, cfg: CatcherConfig, dribbler_offset_m: float, robot_radius_m: float = 0.0,
                 field: FieldConfig | None = None, robot_id: int | None = None, team_robot_ids=(),
                 intercepts: bool = False) -> None:
        team = {int(i) for i in team_robot_ids}
        if team and robot_id not in team:
            raise ValueError(f"team_robot_ids {sorted(team)}: robot {robot_id} is not one of them")
        self.set_config(cfg, dribbler_offset_m, robot_radius_m, field)
        self.robot_id = robot_id
        self.intercepts = bool(intercepts)
        self._teammates = {i: (-math.inf, CATCH_TIME_NEVER) for i in team - {robot_id}}
        self._receiver: int | None = None  # the team's receiver as this robot last decided
        self._pose = None  # (t, [x, y, yaw], field velocity [vx, vy])
        self._pose_timing = (-math.inf, 0.0)  # (the pose's stamp, its tracked yaw rate [rad/s])
        self._catch_time = None  # (t, seconds or CATCH_TIME_NEVER)
        self._catch_point = None  # (t, [x, y])
        self._ball = None  # (t, position, velocity)
        self._height = (0.0, 0.0)  # the ball's (z, vz) with the newest state: in the air when either is > 0
        self._chip_model: ChipParams | None = None  # the predictor's chip model (on_chip_model); None: not yet
        self._rest_position = None  # where the ball was last seen at rest
        self._received = False  # caught, and the ball not seen at rest since
        self._v_shoot = None  # (t, m/s)
        self._model = BallModelParams()
        self._holding_ball = False
        self._engaged = False
        self._ball_moving_at = -math.inf
        self._target_at = -math.inf
        self._next_target = None  # where it passes on after the catch ([x, y]), None: face the ball
        self._max_receive_angle_rad = MAX_RECEIVE_ANGLE_RAD
        self.notice: str | None = None

    def set_config(self, cfg: CatcherConfig, dribbler_offset_m: float, robot_radius_m: float = 0.0,
                   field: FieldConfig | None = None) -> None:
        self.cfg, self.field = cfg, field
        self.dribbler_offset_m, self.robot_radius_m = dribbler_offset_m, robot_radius_m

    # -- inputs -----------------------------------------------------------------------------------
    def on_odom(self, now: float, pose, velocity, stamp_s: float | None = None) -> None:
        """The filtered robot pose [x, y, yaw] and field velocity [vx, vy] or [vx, vy, wz] (its yaw rate
        [rad/s]), measured at ``stamp_s`` (None: ``now``) on the clock of ``now``."""
        velocity = np.asarray(velocity, dtype=float)
        self._pose = (now, np.asarray(pose, dtype=float), velocity[:2])
        yaw_rate = float(velocity[2]) if velocity.shape[0] > 2 and math.isfinite(velocity[2]) else 0.0
        stamp = now if stamp_s is None or not math.isfinite(stamp_s) else float(stamp_s)
        self._pose_timing = (stamp, yaw_rate)

    def on_catch_time(self, now: float, seconds: float) -> None:
        self._catch_time = (now, float(seconds))

    def on_catch_point(self, now: float, point) -> None:
        self._catch_point = (now, np.asarray(point, dtype=float))

    def on_teammate_catch_time(self, robot: int, now: float, seconds: float) -> None:
        if robot in self._teammates:
            self._teammates[robot] = (now, float(seconds))

    def on_ball(self, now: float, position, velocity) -> None:
        """The tracked ball: [x, y] and [vx, vy], or with its height: [x, y, z] and [vx, vy, vz] (a chip in the
        air is received where it is low again, chip_model.flying_ball)."""
        position, velocity = np.asarray(position, dtype=float), np.asarray(velocity, dtype=float)
        airborne = len(position) > 2 and len(velocity) > 2
        self._height = (float(position[2]), float(velocity[2])) if airborne else (0.0, 0.0)
        position, velocity = position[:2], velocity[:2]
        self._ball = (now, position, velocity)
        if math.hypot(velocity[0], velocity[1]) < self.cfg.min_ball_speed_mps:
            self._rest_position = position
            self._received = False
            return
        self._ball_moving_at = now
        rest = self._rest_position
        if self._holding_ball or self._received:
            return
        if rest is None or math.dist(position, rest) >= self.cfg.engage_distance_m:
            self._engaged = True

    def on_v_shoot(self, now: float, v_shoot_mps: float) -> None:
        self._v_shoot = (now, float(v_shoot_mps))

    def on_next_target(self, point, max_receive_angle_rad: float = MAX_RECEIVE_ANGLE_RAD) -> None:
        """Where this robot passes the ball on once it has it ([x, y] in ``field``; None: nowhere known), and
        how far from the ball's way back it may face it to receive (catch_time.receive_facing)."""
        if not (math.isfinite(max_receive_angle_rad) and 0.0 <= max_receive_angle_rad < 0.5 * math.pi):
            raise ValueError(f"max_receive_angle_rad must be in [0, pi/2), got {max_receive_angle_rad!r}")
        self._next_target = None if point is None else np.asarray(point, dtype=float)[:2]
        self._max_receive_angle_rad = max_receive_angle_rad

    def facing(self, pose, ball: BallTrajectory | None) -> float:
        """The dribbler direction it receives with: towards the next target within the receive angle
        (catch_time.receive_facing), else against the ball; its heading when the ball rests."""
        if ball is None:
            return float(pose[2])
        if self._next_target is None:
            return math.atan2(-ball.velocity_mps[1], -ball.velocity_mps[0])
        return receive_facing(ball.direction, pose[:2], self._next_target, self._max_receive_angle_rad)

    def on_model(self, params: BallModelParams) -> None:
        """The ball model the predictor uses (it may identify its own)."""
        self._model = params

    @property
    def model(self) -> BallModelParams:
        """The ball model it predicts the ball with (the defaults until ``on_model``)."""
        return self._model

    def on_chip_model(self, params: ChipParams) -> None:
        """The chip model the predictor uses (/ball/chip_model_params): a ball in the air is predicted with it."""
        self._chip_model = params

    @property
    def chip_model(self) -> ChipParams | None:
        """The chip model it predicts a ball in the air with (None until ``on_chip_model``: such a ball is taken
        as rolling where its shadow is, with a ``notice``)."""
        return self._chip_model

    def on_barrier(self, detected: bool) -> bool:
        """The light barrier; True on the rising edge (the ball is received)."""
        edge = bool(detected) and not self._holding_ball
        if edge:
            self._engaged = False
            self._received = True
        self._holding_ball = bool(detected)
        return edge

    # -- decision ---------------------------------------------------------------------------------
    def _fresh(self, stamped, now: float) -> bool:
        return stamped is not None and now - stamped[0] <= self.cfg.stale_after_s

    def tick(self, now: float) -> np.ndarray:
        """The Twist to command now (zeros: hold)."""
        self.notice = None
        cfg = self.cfg
        if now - self._ball_moving_at > cfg.disengage_after_rest_s:
            self._engaged = False
        active = self._engaged or cfg.fetch_resting_ball
        if not (active and self._fresh(self._pose, now) and not self._holding_ball and self._receives(now)):
            self._target_at = -math.inf  # a commitment is to one ball in flight
            return np.zeros(3)
        _, measured, velocity = self._pose
        # Decide and steer from the pose the robot will have when this command acts (module docstring):
        # from the measured one, a robot arriving fast brakes a loop delay late and overshoots its target.
        stamp, yaw_rate = self._pose_timing
        delay_s = pose_delay_s(now, stamp, cfg)
        yaw, gain = heading_loop(float(measured[2]), yaw_rate, delay_s, cfg)
        pose = np.array([measured[0] + velocity[0] * delay_s, measured[1] + velocity[1] * delay_s, yaw])
        ball = self._moving_ball(now)
        chip = self._chip(now) if ball is not None else None
        if chip is not None:
            ball = chip.ground_track()
        predicted = (self._fresh(self._catch_point, now) and self._fresh(self._catch_time, now)
                     and self._catch_time[1] != CATCH_TIME_NEVER)
        facing = self.facing(pose, ball)
        target = choose_target(pose, velocity, ball, self._catch_point[1] if predicted else None,
                               self.dribbler_offset_m, cfg, self.field, self.robot_radius_m,
                               committed=now - self._target_at <= cfg.commit_s,
                               facing_rad=None if self._next_target is None else facing, chip=chip,
                               intercepts=self.intercepts)
        if target is None:
            return np.zeros(3)
        self._target_at = now
        try:
            return catch_twist(pose, target, facing, cfg, gain)
        except ValueError as exc:
            self.notice = f"no command: {exc}"
            return np.zeros(3)

    def _receives(self, now: float) -> bool:
        if not self._teammates:
            return True
        times = {i: t for i, (arrived, t) in self._teammates.items() if now - arrived <= self.cfg.stale_after_s}
        if self._fresh(self._catch_time, now):
            times[self.robot_id] = self._catch_time[1]
        self._receiver = team_receiver(times, self._receiver, self.cfg.team_switch_margin_s)
        return self._receiver is None or self._receiver == self.robot_id

    def _chip(self, now: float) -> ChipTrajectory | None:
        """The ball in the air (its newest state has a height or rises), else None."""
        (_, position, velocity), (z, vz) = self._ball, self._height
        if self._chip_model is None:
            if z > 0.0 or vz > 0.0:
                self.notice = "the ball is in the air but no chip model has come (/ball/chip_model_params)"
            return None
        try:
            return flying_ball((*position, max(z, 0.0)), (*velocity, vz), self._chip_model, self._model)
        except ValueError as exc:
            self.notice = f"ball state in the air not usable: {exc}"
            return None

    def _moving_ball(self, now: float) -> BallTrajectory | None:
        """The ball's future from the newest state; None when it rests, is stale or is not usable."""
        if not self._fresh(self._ball, now):
            return None
        _, position, velocity = self._ball
        if math.hypot(velocity[0], velocity[1]) < self.cfg.min_ball_speed_mps:
            return None
        v_shoot = self._v_shoot[1] if self._fresh(self._v_shoot, now) else 0.0  # 0: raised to the speed
        try:
            return BallTrajectory(position, velocity, max(v_shoot, 0.0), self._model)
        except ValueError as exc:
            self.notice = f"ball state not usable: {exc}"
            return None
