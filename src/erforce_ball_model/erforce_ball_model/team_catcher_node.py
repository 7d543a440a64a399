"""team_catcher: the catchers of many robots in one process.

The same contract as one ``catcher`` per robot: per robot in ``robot_ids`` it reads ``odom`` (or, with
``tracked_poses``, its row of ``/robots/tracked``) and ``ball_detected``, its catch time and point from its
row of ``/ball/catches``, the ball's topics once for all, and publishes each robot's ``cmd_vel`` at
``rate_hz``. Each robot runs its own receiver.Receiver; with ``as_team`` only the robot that can catch
first drives to the ball (receiver.team_receiver).

With ``team`` ``opponents`` it drives the opponents under ``/opponent_<id>/``: the interceptor of the
simulated second team. With ``press_lanes`` it also reads the other team's tracked poses and, while one of
them holds the ball, sends its robots onto the passing lanes; the decisions are
passing.player.PressingTeam's.

One timer and one sampled batch of every input per tick (executor.run_sampled), instead of a process, a
timer and seven subscriptions' callbacks per robot. The parameters are the catcher's (``team_robot_ids`` aside).
"""

from __future__ import annotations

from nav_msgs.msg import Odometry
from std_msgs.msg import Bool, Float64, Float64MultiArray, String

from erforce_ball_model import catcher_node
from erforce_ball_model.ball_model import BallModelParams
from erforce_ball_model.passing.decisions import PassConfig
from erforce_ball_model.passing.player import PressingTeam, new_poses
from erforce_interfaces.runtime.executor import run_sampled, sample_only
from erforce_interfaces.runtime.node_support import (
    SchemaNode,
    WorldField,
    contract_publisher,
    contract_subscription,
    run_node,
)
from erforce_interfaces.runtime.param_schema import HostSchema, load_schema
from erforce_interfaces.wire import contract
from erforce_interfaces.wire.conversions import (
    ConversionError,
    ball_phase_from_msg,
    ball_state_from_msg,
    float64_from_msg,
    odometry_from_msg,
    twist_msg,
)
from erforce_interfaces.wire.tables import catches_from_msg, model_in_use_from_msg, tracked_robots_from_msg

# the catcher's parameters under their own names; team_robot_ids is robot_ids and as_team here
SCHEMA = HostSchema(load_schema("erforce_ball_model", "team_catcher"), {
    "": (catcher_node.SCHEMA, ("team_robot_ids",)),
})


def build(config):
    """The catcher's (config, dribbler offset, robot radius, field) for every robot and the pressing's PassConfig
    (None: no pressing) (ValueError when invalid)."""
    own, hosted = config
    ids = list(own.robot_ids)
    if not ids or len(set(ids)) != len(ids):
        raise ValueError(f"robot_ids: need distinct ids, at least one, got {ids}")
    passing = PassConfig(press_fraction=own.press_fraction) if own.press_lanes else None
    return (*catcher_node.build_config(hosted[""]), passing)


class TeamCatcherNode(SchemaNode):
    def __init__(self) -> None:
        super().__init__("team_catcher", SCHEMA, build)
        ids = [int(i) for i in self._values["robot_ids"]]
        team = self._side = contract.TEAMS[self._values["team"]]
        self._names = {i: team.namespace(i) for i in ids}
        other = contract.OURS if team is contract.OPPONENTS else contract.OPPONENTS
        n_other = self._values["num_other_robots"] if self._values["press_lanes"] else 0
        self._team: PressingTeam | None = None
        self._field = WorldField(self, self._values["field"], lambda _field: self._set_config(self._params.built),
                                 self._warn)
        self.on_clock_restart()
        q = contract
        self._cmd_pubs = {i: contract_publisher(self, q.CMD_VEL, team.topic(q.CMD_VEL, i)) for i in ids}
        # the frequent inputs serialized, as in the catcher: only the newest of each is decoded
        self._inputs = [sample_only(contract_subscription(self, topic, callback, raw=raw))
                        for topic, callback, raw in ((q.BALL_STATE, self._on_ball, True),
                                                     (q.BALL_PHASE, self._on_phase, False),
                                                     (q.BALL_V_SHOOT, self._on_v_shoot, True),
                                                     (q.BALL_MODEL_PARAMS, self._on_model_params, False),
                                                     (q.BALL_CHIP_MODEL_PARAMS, self._on_chip_model_params, False))]
        tracked_poses = self._values["tracked_poses"]
        for i in ids:
            inputs = ((q.BALL_DETECTED, self._on_barrier, False),)
            if not tracked_poses:
                inputs = ((q.ODOM, self._on_odom, True), *inputs)
            for topic, callback, raw in inputs:
                sub = contract_subscription(self, topic, lambda m, i=i, cb=callback: cb(i, m), team.topic(topic, i),
                                            raw=raw)
                self._inputs.append(sample_only(sub))
        # a /robots/tracked row -> (own robot or None, the other team's index or None)
        self._own_index = {(team.code, i): i for i in ids} if tracked_poses else {}
        self._inputs.append(sample_only(contract_subscription(self, q.BALL_CATCHES, self._on_catches, raw=True)))
        self._other_index = {(other.code, k): k for k in range(n_other)}
        if n_other or tracked_poses:
            self._inputs.append(sample_only(contract_subscription(self, q.ROBOTS_TRACKED, self._on_tracked, raw=True)))
        self._batch_now = self._now_s()  # the time of the inputs' batch (_tick)
        self._timer = self.create_timer(1.0 / self._values["rate_hz"], self._tick)
        as_team = " as a team" if self._values["as_team"] else ""
        press = f", pressing the passing lanes of {other.name} (robots 0 .. {n_other - 1})" if n_other else ""
        self.get_logger().info(f"team_catcher: {team.name}, robots {ids}{as_team}{press}")
        self._params.on_change(self._set_config)

    def _set_config(self, built) -> None:
        cfg, offset, radius, _field, passing = built
        self._field.set_setting(self._values["field"])
        self._team.set_config(cfg, offset, radius, self._field.field, passing)

    def on_clock_restart(self) -> None:
        """A new /clock time line (node_support.guard_clock): the inputs' arrival times are void."""
        v = self._values
        cfg, offset, radius, _field, passing = self._params.built
        n_other = v["num_other_robots"] if passing is not None else 0
        # the predictor's model (transient local: not sent again for a new time line) goes on
        model, chip_model = (None, None) if self._team is None else (self._team.model, self._team.chip_model)
        # the opponents stop a chip with their body, as the ball predictor plans their catches
        self._team = PressingTeam(cfg, offset, radius, self._field.field, v["robot_ids"], v["as_team"], passing,
                                  n_other, model, chip_model, intercepts=v["team"] == "opponents")
        self._other_stamps: list[float | None] = [None] * n_other  # the stamp of each row last fed
        self._own_stamps = dict.fromkeys(int(i) for i in v["robot_ids"])  # likewise, with tracked_poses

    def _now_s(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    def _on_ball(self, msg: Odometry | bytes) -> None:
        ball = self._warn.convert(msg, "ball state", ball_state_from_msg)
        if ball is not None:
            self._team.on_ball(self._batch_now, ball[1], ball[2])

    def _on_phase(self, msg: String) -> None:
        phase = self._warn.convert(msg, "phase", ball_phase_from_msg)
        if phase is not None:
            self._team.on_ball_phase(phase)

    def _on_v_shoot(self, msg: Float64 | bytes) -> None:
        v_shoot = self._warn.convert(msg, "v_shoot", float64_from_msg)
        if v_shoot is not None:
            self._team.on_v_shoot(self._batch_now, v_shoot)

    def _on_model_params(self, msg: Float64MultiArray) -> None:
        try:
            params = BallModelParams(*model_in_use_from_msg(msg))
        except (ConversionError, IndexError, ValueError) as exc:
            self._warn.warn("model_params", f"rejected model_params: {exc}")
            return
        self._team.on_model(params)

    def _on_chip_model_params(self, msg: Float64MultiArray) -> None:
        chip_model = catcher_node.chip_model_of(msg, self._warn)
        if chip_model is not None:
            self._team.on_chip_model(chip_model)

    def _on_odom(self, robot: int, msg: Odometry | bytes) -> None:
        odom = self._warn.convert(msg, f"{self._names[robot]} odom", odometry_from_msg)
        if odom is not None:
            self._team.on_odom(robot, self._batch_now, odom[1], odom[2], odom[0])

    def _on_tracked(self, msg: bytes) -> None:
        rows = self._warn.convert(msg, "/robots/tracked", tracked_robots_from_msg)
        if not rows:
            return
        now = self._batch_now
        for i, row in new_poses(rows, self._own_index, self._own_stamps):
            self._team.on_odom(i, now, row.pose, row.velocity, row.stamp_s)
        for k, row in new_poses(rows, self._other_index, self._other_stamps):
            self._team.on_other_robot(k, now, row.pose)

    def _on_catches(self, msg: bytes) -> None:
        catches = self._warn.convert(msg, "/ball/catches", lambda m: catches_from_msg(m, self._side))
        if catches:
            self._team.on_catches(self._batch_now, catches)

    def _on_barrier(self, robot: int, msg: Bool) -> None:
        if self._team.on_barrier(robot, msg.data):
            self.get_logger().info(f"{self._names[robot]} light barrier: ball received")

    def _tick(self) -> None:
        # one clock read for the batch: the sampled inputs all run at this tick (the clock stands meanwhile)
        self._batch_now = self._now_s()
        run_sampled(self._inputs)
        if self._field.field is None:  # the world's field is not known yet: judge nothing, stand
            for pub in self._cmd_pubs.values():
                pub.publish(twist_msg((0.0, 0.0, 0.0)))
            return
        for i, twist in self._team.tick(self._batch_now).items():
            if i in self._team.notices:
                self._warn.warn(f"tick{i}", f"{self._names[i]}: {self._team.notices[i]}")
            self._cmd_pubs[i].publish(twist_msg(twist))


def main(args: list[str] | None = None) -> int:
    return run_node(TeamCatcherNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
