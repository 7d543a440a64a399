"""passing_game: our team's AI for the paper's passing game on the graph (passing.player.PassingPlayer).

It reads what the ball predictor publishes: the tracked ball (``/ball/state``, ``/ball/v_shoot``, the ball and
chip models in use), every robot's pose and velocity (its row of ``/robots/tracked``, taken when its stamp changed), our
robots' catch times and points (their rows of ``/ball/catches``), and every robot's light barrier (the
opponents' tell an interception, as a referee sees it). Each AI tick (``rate_hz``, simulated time) it feeds
PassingPlayer and publishes our robots' ``cmd_vel``, a ``kick`` when the holder kicks and each ``dribbler``
when it changes. Each ended pass is logged as one line and published on ``/pass/records``; the chosen pass
on ``/pass/choice`` whenever it changes. With ``place_ball`` it also does the referee's part: the ball at the
holder's dribbler on ``/sim/set_ball`` at the start and after an interception, a loss or a drop.

The opponents are not driven here (on the graph: their team_catcher). The receiver receives facing its
next target where it can, so the predictor's catch point (facing the ball) is a fallback a few centimetres
off. This module converts messages and publishes; the decisions are passing_player's.
"""

from __future__ import annotations

import math

import numpy as np
from nav_msgs.msg import Odometry
from rclpy.node import Node
from std_msgs.msg import Bool, Float64, Float64MultiArray, String

from erforce_ball_model import catcher_node
from erforce_ball_model.ball_model import BallModelParams, ChipParams
from erforce_ball_model.catch_time import load_kernels
from erforce_ball_model.passing.decisions import PassConfig, PassOption
from erforce_ball_model.passing.player import PassingPlayer, PassRecord, PlayerConfig, new_poses
from erforce_interfaces.runtime.executor import run_sampled, sample_only
from erforce_interfaces.runtime.node_support import (
    NodeParams,
    ThrottledWarner,
    WorldField,
    contract_publisher,
    contract_subscription,
    run_node,
)
from erforce_interfaces.runtime.param_schema import HostSchema, fields_for, load_schema
from erforce_interfaces.wire import contract
from erforce_interfaces.wire.conversions import (
    ConversionError,
    ball_phase_from_msg,
    ball_state_from_msg,
    float64_from_msg,
    odometry_msg,
    twist_msg,
)
from erforce_interfaces.wire.tables import (
    catches_from_msg,
    model_in_use_from_msg,
    table_from_msg,
    table_msg,
    tracked_robots_from_msg,
)

SCHEMA = HostSchema(load_schema("erforce_ball_model", "passing_game"), {
    "": (catcher_node.SCHEMA, ("team_robot_ids",)),
})
BALL_PLACE_MARGIN_M = 0.002  # the ball is put this far in front of the dribbler's touch point
DRIBBLER_REPEAT_S = 1.0  # every dribbler command again this often (a restarted plant learns them)
START_PATIENCE_S = 5.0  # robots not tracked this long after the node's first tick are named in a warning


def build(config):
    """(PlayerConfig, field, dribbler offset [m], robot radius [m]) for the node's config (ValueError when invalid)."""
    own, hosted = config
    if own.start_holder >= own.num_robots:
        raise ValueError(f"start_holder {own.start_holder} is not one of the {own.num_robots} robots")
    catcher, offset, radius, field = catcher_node.build_config(hosted[""])
    passing = PassConfig(**fields_for(PassConfig, own, press_fraction=PassConfig().press_fraction))
    player = PlayerConfig(**fields_for(PlayerConfig, own, passing=passing, catcher=catcher))
    return player, field, offset, radius


def pass_choice_rows(choice: tuple[int, PassOption] | None, cfg: PassConfig) -> list[tuple]:
    """The rows of /pass/choice (contract.PASS_CHOICE_COLUMNS) for a passer and its chosen pass; none for None."""
    if choice is None:
        return []
    passer, o = choice
    never = contract.PASS_NO_OPPONENT_S
    nobody = o.first_opponent is None or not math.isfinite(o.opponent_catch_s)
    return [(passer, o.receiver, o.kick_speed_mps, o.direction_rad, min(o.receiver_catch_s, never),
             never if nobody else o.opponent_catch_s, -1 if nobody else o.first_opponent,
             never if nobody else max(o.margin_s, -never), cfg.safe_margin_s, 1.0 if o.safe(cfg) else 0.0)]


def record_row(record: PassRecord) -> list[float]:
    """One row of contract.PASS_RECORD_COLUMNS for a record (robot indices as PassingPlayer counts them)."""
    never = contract.PASS_NO_OPPONENT_S
    team, caught = 0.0, -1
    if record.caught_by is not None:
        name, _, k = record.caught_by.rpartition("_")
        team = contract.OURS.code if name == "robot" else contract.OPPONENTS.code
        caught = int(k)
    return [record.index, record.t_kick_s, record.passer, record.receiver, record.kick_speed_mps,
            min(record.predicted_catch_s, never), min(record.opponent_predicted_s, never),
            -1 if record.first_opponent is None else record.first_opponent, 1.0 if record.rated_safe else 0.0,
            contract.PASS_OUTCOMES.index(record.outcome), team, caught,
            -1.0 if record.actual_catch_s is None else record.actual_catch_s,
            -1 if record.facing_target is None else record.facing_target, record.kick_angle_deg]


def record_from_row(row) -> PassRecord:
    """The PassRecord of a row of contract.PASS_RECORD_COLUMNS (without the ball path)."""
    v = dict(zip(contract.PASS_RECORD_COLUMNS, (float(x) for x in row), strict=True))
    never = contract.PASS_NO_OPPONENT_S
    caught_by = None
    if v["caught_team"] in (contract.OURS.code, contract.OPPONENTS.code):
        team = contract.OURS if v["caught_team"] == contract.OURS.code else contract.OPPONENTS
        caught_by = team.namespace(int(v["caught_id"]))
    return PassRecord(
        int(v["index"]), v["t_kick_s"], int(v["passer_id"]), int(v["receiver_id"]), v["kick_speed_mps"],
        math.inf if v["predicted_catch_s"] >= never else v["predicted_catch_s"],
        math.inf if v["opponent_predicted_s"] >= never else v["opponent_predicted_s"],
        None if v["first_opponent"] < 0 else int(v["first_opponent"]), v["rated_safe"] > 0.5,
        contract.PASS_OUTCOMES[int(v["outcome"])], caught_by,
        None if caught_by is None else v["actual_catch_s"], (),
        None if v["facing_target"] < 0 else int(v["facing_target"]), v["kick_angle_deg"])


def records_from_msg(msg: Float64MultiArray) -> list[PassRecord]:
    return [record_from_row(row) for row in table_from_msg(msg, contract.PASS_RECORD_COLUMNS)]


class PassingGameNode(Node):
    warm_up = staticmethod(load_kernels)

    def __init__(self) -> None:
        super().__init__("passing_game")
        self._warn = ThrottledWarner(self)
        self._params = NodeParams(self, SCHEMA, build)
        own = self._params.config[0]
        self._own = own
        n, m = self._n, self._m = own.num_robots, own.num_opponents
        self._field = WorldField(self, self._params.config[1][""].field,
                                 lambda _field: self._set_config(self._params.built), self._warn)
        self._player = self._new_player()
        self._dribbler_radps = own.dribbler_radps
        self._robots = [(contract.OURS, i) for i in range(n)] + [(contract.OPPONENTS, j) for j in range(m)]
        q = contract
        ours = contract.OURS
        self._cmd_pubs = [contract_publisher(self, q.CMD_VEL, ours.topic(q.CMD_VEL, i)) for i in range(n)]
        self._kick_pubs = [contract_publisher(self, q.KICK, ours.topic(q.KICK, i)) for i in range(n)]
        self._kick_angle_pubs = [contract_publisher(self, q.KICK_ANGLE, ours.topic(q.KICK_ANGLE, i)) for i in range(n)]
        self._kick_angles = [None] * n  # the kick_angle last sent per robot [deg]
        self._dribbler_pubs = [contract_publisher(self, q.DRIBBLER, ours.topic(q.DRIBBLER, i)) for i in range(n)]
        self._set_ball_pub = contract_publisher(self, q.SIM_SET_BALL) if own.place_ball else None
        self._records_pub = contract_publisher(self, q.PASS_RECORDS)
        self._choice_pub = contract_publisher(self, q.PASS_CHOICE)
        self._choice_sent: object = ()  # the choice last published (() : none yet)
        self._moving = [True] * n  # the last cmd_vel was not a stop (so the first tick stops every robot)
        self._dribblers: list[bool | None] = [None] * n
        self._dribblers_sent_at = -math.inf
        self._first_seen: float | None = None
        self._waiting_since: float | None = None
        self._started = False
        self._reported = 0
        self._inputs = [sample_only(contract_subscription(self, topic, callback, raw=raw))
                        for topic, callback, raw in ((q.BALL_STATE, self._on_ball, True),
                                                     (q.BALL_PHASE, self._on_phase, False),
                                                     (q.BALL_V_SHOOT, self._on_v_shoot, True),
                                                     (q.BALL_MODEL_PARAMS, self._on_model_params, False),
                                                     (q.BALL_CHIP_MODEL_PARAMS, self._on_chip_model_params, False))]
        for k, (team, j) in enumerate(self._robots):
            sub = contract_subscription(self, q.BALL_DETECTED, lambda msg, k=k: self._on_barrier(k, msg),
                                        team.topic(q.BALL_DETECTED, j))
            self._inputs.append(sample_only(sub))
        # a table row -> the player's robot index (ours first, then the opponents), and its stamp last fed
        self._row_index = {(team.code, j): k for k, (team, j) in enumerate(self._robots)}
        self._fed_stamps = [None] * (n + m)
        self._inputs.append(sample_only(contract_subscription(self, q.ROBOTS_TRACKED, self._on_tracked, raw=True)))
        self._inputs.append(sample_only(contract_subscription(self, q.BALL_CATCHES, self._on_catches, raw=True)))
        self._v_shoot: float | None = None
        self._batch_now = self._now_s()  # the time of the inputs' batch (_tick)
        self._timer = self.create_timer(1.0 / self._params.config[1][""].rate_hz, self._tick)
        self._params.on_change(self._set_config)
        self.get_logger().info(f"passing_game: robot_0 .. robot_{n - 1} pass, {m} opponent(s); the ball starts at "
                               f"robot_{own.start_holder}")

    def _new_player(self, model: BallModelParams | None = None, trusted_model: BallModelParams | None = None,
                    chip_model: ChipParams | None = None) -> PassingPlayer:
        player, _field, offset, radius = self._params.built
        return PassingPlayer(player, self._n, self._m, self._field.field, offset, radius, model, trusted_model,
                             chip_model)

    def _set_config(self, built) -> None:
        player, _field, offset, radius = built
        self._field.set_setting(self._params.config[1][""].field)
        self._player.configure(player, self._field.field, offset, radius)
        self._dribbler_radps = self._params.config[0].dribbler_radps
        self._dribblers_sent_at = -math.inf  # the new speed at the next tick

    def on_clock_restart(self) -> None:
        """A new /clock time line (node_support.guard_clock): a new game, with the predictor's models (transient
        local: not sent again) and the model it trusts (a new time line is no evidence against it)."""
        player = self._player
        self._player = self._new_player(player.model, player.trusted_model, player.chip_model)
        self._first_seen, self._waiting_since, self._started, self._reported = None, None, False, 0
        self._fed_stamps = [None] * (self._n + self._m)
        self._dribblers_sent_at = -math.inf

    def _send_kick_angle(self, player, robot: int | None = None, angle_deg: float | None = None) -> None:
        """The kicker's angle, sent before the kick it is for: the holder's chosen pass's while it turns to it (so
        that it is in force long before the kick), or ``angle_deg`` for ``robot``'s kick now; only on a change."""
        if robot is None:
            if player.holder is None or player.choice is None:
                return
            robot, angle_deg = player.holder, player.choice[1].kick_angle_deg
        if self._kick_angles[robot] != angle_deg:
            self._kick_angles[robot] = angle_deg
            self._kick_angle_pubs[robot].publish(Float64(data=float(angle_deg)))

    def _now_s(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    def _name(self, k: int) -> str:
        team, j = self._robots[k]
        return team.namespace(j)

    # ------------------------------------------------------------------ inputs (taken at the tick)
    def _on_ball(self, msg: Odometry | bytes) -> None:
        ball = self._warn.convert(msg, "ball state", ball_state_from_msg)
        if ball is not None:
            self._player.on_ball(self._batch_now, ball[1], ball[2], self._v_shoot)

    def _on_phase(self, msg: String) -> None:
        phase = self._warn.convert(msg, "phase", ball_phase_from_msg)
        if phase is not None:
            self._player.on_ball_phase(phase)

    def _on_v_shoot(self, msg: Float64 | bytes) -> None:
        self._v_shoot = self._warn.convert(msg, "v_shoot", float64_from_msg)

    def _on_model_params(self, msg: Float64MultiArray) -> None:
        try:
            self._player.on_model(BallModelParams(*model_in_use_from_msg(msg)))
        except (ConversionError, IndexError, ValueError) as exc:
            self._warn.warn("model_params", f"rejected model_params: {exc}")

    def _on_chip_model_params(self, msg: Float64MultiArray) -> None:
        chip_model = catcher_node.chip_model_of(msg, self._warn)
        if chip_model is not None:
            self._player.on_chip_model(chip_model)

    def _on_tracked(self, msg: bytes) -> None:
        rows = self._warn.convert(msg, "/robots/tracked", tracked_robots_from_msg)
        if not rows:
            return
        now = self._batch_now
        for k, row in new_poses(rows, self._row_index, self._fed_stamps):
            self._player.on_robot(k, now, row.pose, row.velocity, row.stamp_s)

    def _on_catches(self, msg: bytes) -> None:
        catches = self._warn.convert(msg, "/ball/catches", lambda m: catches_from_msg(m, contract.OURS))
        if catches:
            self._player.on_catches(self._batch_now, catches)

    def _on_barrier(self, k: int, msg: Bool) -> None:
        self._player.on_barrier(k, self._batch_now, msg.data)

    # ------------------------------------------------------------------ the AI tick
    def _tick(self) -> None:
        # one clock read for the batch: the sampled inputs all run at this tick (the clock stands meanwhile)
        self._batch_now = self._now_s()
        run_sampled(self._inputs)
        now = self._batch_now
        player = self._player
        if not self._started:
            self._start(now)
            return
        self._serve_ball_request(now)
        try:
            commands = player.tick(now)
        except ValueError as exc:  # a decision that cannot be made from these inputs: everybody stops
            self._warn.warn("tick", f"no decision: {exc}")
            commands = None
        if commands is not None:
            self._send_kick_angle(player)
            for i, speed in commands.kicks.items():
                angle = commands.kick_angles.get(i, 0.0)
                self._send_kick_angle(player, i, angle)
                self._kick_pubs[i].publish(Float64(data=float(speed)))
                chip = f" (chip {angle:g} deg)" if angle > 0.0 else ""
                self.get_logger().info(f"robot_{i} kicks {speed:.2f} m/s{chip} to robot_{player.choice[1].receiver}")
            for i, twist in commands.twists.items():
                moving = bool(np.any(twist))
                if moving or self._moving[i]:
                    self._cmd_pubs[i].publish(twist_msg(twist))
                self._moving[i] = moving
        else:
            for i in range(self._n):
                self._cmd_pubs[i].publish(twist_msg((0.0, 0.0, 0.0)))
        if player.notice:
            self._warn.warn("no pass", player.notice)
        if player.stalled:
            self._warn.warn("stalled", player.stalled)
        if player.receiver is not None and player.receiver.notice:
            self._warn.warn("receiver", f"receiver: {player.receiver.notice}")
        self._send_dribblers(now)
        self._report()
        self._serve_ball_request(now)
        choice = player.choice
        if choice != self._choice_sent:
            self._choice_sent = choice
            columns = contract.PASS_CHOICE_COLUMNS
            rows = np.array(pass_choice_rows(choice, player.cfg.passing), dtype=float).reshape(-1, len(columns))
            self._choice_pub.publish(table_msg(rows, columns))

    def _start(self, now: float) -> None:
        """The game starts once the world's field is known, every robot has been tracked settle_s and, with
        place_ball, someone takes the placements (the plant, or a simulator's bridge that may start after vision
        already flows)."""
        if self._field.field is None:  # the world's field is not known yet (said once at start)
            return
        placer_missing = self._set_ball_pub is not None and self._set_ball_pub.get_subscription_count() == 0
        if not self._player.seen.all() or placer_missing:
            self._first_seen = None
            if self._waiting_since is None:
                self._waiting_since = now
            elif now - self._waiting_since > START_PATIENCE_S:
                missing = [self._name(k) for k in np.flatnonzero(~self._player.seen)]
                if missing:
                    self._warn.warn("start", f"the game waits for the tracked pose (/robots/tracked) of "
                                    f"{', '.join(missing)}: are they on the field and num_robots / num_opponents "
                                    "right?")
                else:
                    self._warn.warn("start", f"the game waits for a reader of {contract.SIM_SET_BALL.name} to place "
                                    "the ball (the plant or ssl_sim_bridge; place_ball false: a person places it)")
            return
        if self._first_seen is None:
            self._first_seen = now
        if now - self._first_seen >= self._own.settle_s:
            self._started = True
            self._player.start(now, self._own.start_holder)
            self.get_logger().info(f"the game starts: the ball to robot_{self._own.start_holder}")
            self._serve_ball_request(now)

    def _serve_ball_request(self, now: float) -> None:
        """The referee's part: the ball at the requested robot's dribbler (or, without place_ball, wait for it)."""
        player = self._player
        k = player.ball_request
        if k is None:
            return
        if self._set_ball_pub is None:
            if player.barriers[k]:
                player.ball_placed(now)
                self._send_dribblers(now)
            return
        x, y, yaw = player.poses[k]
        reach = player.dribbler_offset_m + BALL_PLACE_MARGIN_M
        xy = (x + reach * math.cos(yaw), y + reach * math.sin(yaw))
        self._set_ball_pub.publish(odometry_msg(now, (*xy, 0.0), (0.0, 0.0, 0.0), "ball"))
        self.get_logger().info(f"ball placed at robot_{k} ({xy[0]:.2f}, {xy[1]:.2f})")
        player.ball_placed(now)
        self._send_dribblers(now)

    def _send_dribblers(self, now: float) -> None:
        wanted = self._player.dribblers()
        repeat = now - self._dribblers_sent_at >= DRIBBLER_REPEAT_S
        for i, on in wanted.items():
            if repeat or on != self._dribblers[i]:
                self._dribbler_pubs[i].publish(Float64(data=self._dribbler_radps if on else 0.0))
                self._dribblers[i] = on
        if repeat:
            self._dribblers_sent_at = now

    def _report(self) -> None:
        records = self._player.records
        while self._reported < len(records):
            record = records[self._reported]
            self._reported += 1
            self.get_logger().info(record.line())
            self._records_pub.publish(table_msg(np.array([record_row(record)]),
                                                contract.PASS_RECORD_COLUMNS))


def main(args: list[str] | None = None) -> int:
    return run_node(PassingGameNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
