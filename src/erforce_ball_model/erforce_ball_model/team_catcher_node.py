"""team_catcher: the catchers of many robots in one process.

The same contract as one ``catcher`` per robot (each in its namespace ``robot_<id>``, with
``team_robot_ids`` the list): per robot in ``robot_ids`` it reads ``odom``, ``catch_time``,
``catch_point`` and ``ball_detected`` under ``/robot_<id>/``, the ball's topics once for all, and
publishes each robot's ``cmd_vel`` at ``rate_hz``. Each robot runs its own catcher.Receiver; with
``as_team`` they form a team in which only the robot that can catch the ball first drives to it
(catcher.team_receiver), as the per-robot catchers with ``team_robot_ids`` do.

With ``team`` ``opponents`` it drives the opponents under ``/opponent_<id>/`` (contract.Team) from the
predictor's catch times for them: the interceptor of the simulated second team.

One timer and one sampled take of every input per tick, instead of a process, a timer and seven
subscriptions' wakes per robot; it spins on DirectExecutor (unless ERFORCE_EXECUTOR says otherwise), on
which the sampled inputs wake nothing. The parameters are the catcher's (``team_robot_ids`` aside).
"""

from __future__ import annotations

import os

from nav_msgs.msg import Odometry
from rclpy.node import Node
from std_msgs.msg import Bool, Float64, Float64MultiArray

from erforce_ball_model import catcher_node
from erforce_ball_model.ball_model import BallModelParams
from erforce_ball_model.catcher import Receiver
from erforce_interfaces import contract
from erforce_interfaces.conversions import (
    ConversionError,
    float64_from_msg,
    model_in_use_from_msg,
    odometry_from_msg,
    point_from_msg,
    twist_msg,
)
from erforce_interfaces.executor import EXECUTOR_ENV, run_sampled, sample_only
from erforce_interfaces.node_support import (
    NodeParams,
    ThrottledWarner,
    contract_publisher,
    contract_subscription,
    run_node,
)
from erforce_interfaces.param_schema import HostSchema, load_schema

# the catcher's parameters under their own names; team_robot_ids is robot_ids and as_team here
SCHEMA = HostSchema(load_schema("erforce_ball_model", "team_catcher"), {
    "": (catcher_node.SCHEMA, ("team_robot_ids",)),
})


def build(config):
    """The catcher's (config, dribbler offset, robot radius, field) for every robot (ValueError when invalid)."""
    own, hosted = config
    ids = list(own.robot_ids)
    if not ids or len(set(ids)) != len(ids):
        raise ValueError(f"robot_ids: need distinct ids, at least one, got {ids}")
    return catcher_node.build_config(hosted[""])


class TeamCatcherNode(Node):
    def __init__(self) -> None:
        super().__init__("team_catcher")
        self._warn = ThrottledWarner(self)
        self._params = NodeParams(self, SCHEMA, build)
        self._values = self._params.values
        ids = [int(i) for i in self._values["robot_ids"]]
        team = contract.TEAMS[self._values["team"]]
        self._names = {i: team.namespace(i) for i in ids}
        self._team = ids if self._values["as_team"] else ()
        self._receivers: dict[int, Receiver] = {}
        self.on_clock_restart()
        q = contract
        self._cmd_pubs = {i: contract_publisher(self, q.CMD_VEL, team.topic(q.CMD_VEL, i)) for i in ids}
        # the frequent inputs serialized, as in the catcher: only the newest of each is decoded
        self._inputs = [sample_only(contract_subscription(self, topic, callback, raw=raw))
                        for topic, callback, raw in ((q.BALL_STATE, self._on_ball, True),
                                                     (q.BALL_V_SHOOT, self._on_v_shoot, True),
                                                     (q.BALL_MODEL_PARAMS, self._on_model_params, False))]
        for i in ids:
            for topic, callback, raw in ((q.ODOM, self._on_odom, True), (q.CATCH_TIME, self._on_catch_time, True),
                                         (q.CATCH_POINT, self._on_catch_point, True),
                                         (q.BALL_DETECTED, self._on_barrier, False)):
                sub = contract_subscription(self, topic, lambda m, i=i, cb=callback: cb(i, m), team.topic(topic, i),
                                            raw=raw)
                self._inputs.append(sample_only(sub))
        self._timer = self.create_timer(1.0 / self._values["rate_hz"], self._tick)
        self.get_logger().info(f"team_catcher: {team.name}, robots {ids}{' as a team' if self._team else ''}")
        self._params.on_change(self._set_config)

    def _set_config(self, built) -> None:
        for receiver in self._receivers.values():
            receiver.set_config(*built)

    def on_clock_restart(self) -> None:
        """A new /clock time line (node_support.guard_clock): the inputs' arrival times are void."""
        self._receivers = {i: Receiver(*self._params.built, robot_id=i, team_robot_ids=self._team)
                           for i in (int(i) for i in self._values["robot_ids"])}

    def _now_s(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    def _on_ball(self, msg: Odometry | bytes) -> None:
        ball = self._warn.convert(msg, "ball state", odometry_from_msg)
        if ball is not None:
            now = self._now_s()
            for receiver in self._receivers.values():
                receiver.on_ball(now, ball[1], ball[2])

    def _on_v_shoot(self, msg: Float64 | bytes) -> None:
        v_shoot = self._warn.convert(msg, "v_shoot", float64_from_msg)
        if v_shoot is not None:
            now = self._now_s()
            for receiver in self._receivers.values():
                receiver.on_v_shoot(now, v_shoot)

    def _on_model_params(self, msg: Float64MultiArray) -> None:
        try:
            params = BallModelParams(*model_in_use_from_msg(msg))
        except (ConversionError, IndexError, ValueError) as exc:
            self._warn.warn("model_params", f"rejected model_params: {exc}")
            return
        for receiver in self._receivers.values():
            receiver.on_model(params)

    def _on_odom(self, robot: int, msg: Odometry | bytes) -> None:
        odom = self._warn.convert(msg, f"{self._names[robot]} odom", odometry_from_msg)
        if odom is not None:
            self._receivers[robot].on_odom(self._now_s(), odom[1], odom[2])

    def _on_catch_time(self, robot: int, msg: bytes) -> None:
        seconds = self._warn.convert(msg, f"{self._names[robot]} catch_time", float64_from_msg)
        if seconds is None:
            return
        now = self._now_s()
        for i, receiver in self._receivers.items():
            if i == robot:
                receiver.on_catch_time(now, seconds)
            else:
                receiver.on_teammate_catch_time(robot, now, seconds)

    def _on_catch_point(self, robot: int, msg: bytes) -> None:
        point = self._warn.convert(msg, f"{self._names[robot]} catch_point", point_from_msg)
        if point is not None:
            self._receivers[robot].on_catch_point(self._now_s(), point[1])

    def _on_barrier(self, robot: int, msg: Bool) -> None:
        if self._receivers[robot].on_barrier(msg.data):
            self.get_logger().info(f"{self._names[robot]} light barrier: ball received")

    def _tick(self) -> None:
        run_sampled(self._inputs)
        now = self._now_s()
        for i, receiver in self._receivers.items():
            twist = receiver.tick(now)
            if receiver.notice:
                self._warn.warn(f"tick{i}", f"{self._names[i]}: {receiver.notice}")
            self._cmd_pubs[i].publish(twist_msg(twist))


def main(args: list[str] | None = None) -> int:
    # Every input is sampled by the timer: on DirectExecutor they wait in rmw and wake nothing, where
    # EventsExecutor wakes and takes each message as it comes (about 12 per vision frame for 3 robots).
    return run_node(TeamCatcherNode, args, os.environ.get(EXECUTOR_ENV) or "direct")


if __name__ == "__main__":
    raise SystemExit(main())
