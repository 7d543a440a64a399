"""catcher: the receive behaviour of the paper's Fig. 6 for one robot, as a ROS 2 node.

Runs in the robot's namespace. It reads its robot's catch time and catch point from the
ball predictor and drives there with ``cmd_vel``, facing the incoming ball (the
predictor computed the catch for that facing), unless a nearer place to receive on the
ball's line has time to spare (receiver.receive_point). It holds still when no catch is possible
or its inputs are stale, and once the light barrier sees the ball. The behaviour is
erforce_ball_model.receiver.Receiver; this node only feeds it and publishes its Twist.

In a team (``team_robot_ids``) it also reads the teammates' catch times, and only the robot that
can catch the ball first drives to it (receiver.team_receiver); the others hold.

It acts only in its ``rate_hz`` tick, on the newest inputs, so it does not wake for each of
the ~6 messages per vision frame: its subscriptions are sampled at the tick
(erforce_interfaces.runtime.executor.sample_only / run_sampled), in the order they were sent, and an
input's arrival time, by which its staleness is judged, is the tick that took it.
"""

from __future__ import annotations

from nav_msgs.msg import Odometry
from std_msgs.msg import Bool, Float64, Float64MultiArray, String

from erforce_ball_model.ball_model import BallModelParams, ChipParams
from erforce_ball_model.receiver import CatcherConfig, Receiver
from erforce_interfaces.runtime.executor import run_sampled, sample_only
from erforce_interfaces.runtime.node_support import (
    SchemaNode,
    ThrottledWarner,
    WorldField,
    contract_publisher,
    contract_subscription,
    run_node,
)
from erforce_interfaces.runtime.param_schema import fields_for, load_schema
from erforce_interfaces.wire import contract
from erforce_interfaces.wire.conversions import (
    ConversionError,
    ball_phase_from_msg,
    ball_state_from_msg,
    float64_from_msg,
    odometry_from_msg,
    point_from_msg,
    twist_msg,
)
from erforce_interfaces.wire.robot_config import FieldConfig, field_from_setting
from erforce_interfaces.wire.tables import chip_model_from_msg, model_in_use_from_msg

SCHEMA = load_schema("erforce_ball_model", "catcher")


def build_config(config) -> tuple[CatcherConfig, float, float, FieldConfig | None]:
    """(catcher config, dribbler offset [m], robot radius [m], the field the parameter names (None: the world's,
    node_support.WorldField)) for a config object of the schema."""
    robot = config.robot
    return (CatcherConfig(**fields_for(CatcherConfig, config)), robot.dribbler_offset_m, robot.robot_radius_m,
            field_from_setting(config.field))


def chip_model_of(msg: Float64MultiArray, warn: ThrottledWarner) -> ChipParams | None:
    """The chip model of a /ball/chip_model_params message; None, with a throttled warning naming it, when it
    is none (the reader keeps the one it has)."""
    try:
        return ChipParams(*chip_model_from_msg(msg))
    except (ConversionError, ValueError) as exc:
        warn.warn("chip_model_params", f"rejected {contract.BALL_CHIP_MODEL_PARAMS.name}: {exc}")
        return None


class CatcherNode(SchemaNode):
    def __init__(self) -> None:
        super().__init__("catcher", SCHEMA, build_config)
        team = [int(i) for i in self._values["team_robot_ids"]]
        own_id = contract.robot_id_of_namespace(self.get_namespace())
        if team and own_id not in team:
            raise ValueError(f"team_robot_ids {sorted(team)}: a team catcher runs in the namespace of one of its "
                             f"robots (robot_<id>), this one runs in '{self.get_namespace()}'")
        self._team = (own_id, team)
        self._field = WorldField(self, self._values["field"], lambda _field: self._set_config(self._params.built),
                                 self._warn)
        self._receiver = self._new_receiver()
        q = contract
        self._cmd_pub = contract_publisher(self, q.CMD_VEL)
        # The frequent inputs come serialized, as the predictor publishes them (conversions' codec reads
        # both forms): an executor that takes every message would otherwise build each Odometry in Python,
        # of which a tick reads only the newest.
        self._inputs = [
            sample_only(contract_subscription(self, topic, callback, raw=raw))
            for topic, callback, raw in (
                (q.ODOM, self._on_odom, True),
                (q.CATCH_TIME, self._on_catch_time, True),
                (q.CATCH_POINT, self._on_catch_point, True),
                (q.BALL_STATE, self._on_ball, True),
                (q.BALL_PHASE, self._on_phase, False),
                (q.BALL_V_SHOOT, self._on_v_shoot, True),
                (q.BALL_MODEL_PARAMS, self._on_model_params, False),
                (q.BALL_CHIP_MODEL_PARAMS, self._on_chip_model_params, False),
                (q.BALL_DETECTED, self._on_barrier, False),
            )
        ]
        for i in set(team) - {own_id}:  # the teammates' catch times, for who receives
            sub = contract_subscription(self, q.CATCH_TIME, lambda m, i=i: self._on_teammate_catch_time(i, m),
                                        q.CATCH_TIME.for_robot(i), raw=True)
            self._inputs.append(sample_only(sub))
        self._timer = self.create_timer(1.0 / self._values["rate_hz"], self._tick)
        self._params.on_change(self._set_config)

    def _set_config(self, built: tuple[CatcherConfig, float, float, FieldConfig | None]) -> None:
        self._field.set_setting(self._values["field"])
        self._receiver.set_config(*built[:3], self._field.field)

    def _new_receiver(self) -> Receiver:
        own_id, team = self._team
        return Receiver(*self._params.built[:3], self._field.field, robot_id=own_id, team_robot_ids=team)

    def on_clock_restart(self) -> None:
        """A new /clock time line (node_support.guard_clock): the inputs' arrival times are void."""
        # the predictor's models (transient local: not sent again for a new time line)
        model, chip_model = self._receiver.model, self._receiver.chip_model
        self._receiver = self._new_receiver()
        self._receiver.on_model(model)
        if chip_model is not None:
            self._receiver.on_chip_model(chip_model)

    def _now_s(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    def _on_odom(self, msg: Odometry | bytes) -> None:
        odom = self._warn.convert(msg, "odom", odometry_from_msg)
        if odom is not None:
            self._receiver.on_odom(self._now_s(), odom[1], odom[2], odom[0])

    def _on_catch_time(self, msg: bytes) -> None:
        seconds = self._warn.convert(msg, "catch_time", float64_from_msg)
        if seconds is not None:
            self._receiver.on_catch_time(self._now_s(), seconds)

    def _on_teammate_catch_time(self, robot: int, msg: bytes) -> None:
        seconds = self._warn.convert(msg, f"robot_{robot} catch_time", float64_from_msg)
        if seconds is not None:
            self._receiver.on_teammate_catch_time(robot, self._now_s(), seconds)

    def _on_catch_point(self, msg: bytes) -> None:
        point = self._warn.convert(msg, "catch_point", point_from_msg)
        if point is not None:
            self._receiver.on_catch_point(self._now_s(), point[1])

    def _on_ball(self, msg: Odometry | bytes) -> None:
        ball = self._warn.convert(msg, "ball state", ball_state_from_msg)
        if ball is not None:
            self._receiver.on_ball(self._now_s(), ball[1], ball[2])

    def _on_phase(self, msg: String) -> None:
        phase = self._warn.convert(msg, "phase", ball_phase_from_msg)
        if phase is not None:
            self._receiver.on_ball_phase(phase)

    def _on_v_shoot(self, msg: Float64 | bytes) -> None:
        v_shoot = self._warn.convert(msg, "v_shoot", float64_from_msg)
        if v_shoot is not None:
            self._receiver.on_v_shoot(self._now_s(), v_shoot)

    def _on_model_params(self, msg: Float64MultiArray) -> None:
        try:
            self._receiver.on_model(BallModelParams(*model_in_use_from_msg(msg)))
        except (ConversionError, IndexError, ValueError) as exc:
            self._warn.warn("model_params", f"rejected model_params: {exc}")

    def _on_chip_model_params(self, msg: Float64MultiArray) -> None:
        chip_model = chip_model_of(msg, self._warn)
        if chip_model is not None:
            self._receiver.on_chip_model(chip_model)

    def _on_barrier(self, msg: Bool) -> None:
        if self._receiver.on_barrier(msg.data):
            self.get_logger().info("light barrier: ball received")

    def _tick(self) -> None:
        run_sampled(self._inputs)
        if self._field.field is None:  # the world's field is not known yet: judge nothing, stand
            self._cmd_pub.publish(twist_msg((0.0, 0.0, 0.0)))
            return
        twist = self._receiver.tick(self._now_s())
        if self._receiver.notice:
            self._warn.warn("tick", self._receiver.notice)
        self._cmd_pub.publish(twist_msg(twist))


def main(args: list[str] | None = None) -> int:
    return run_node(CatcherNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
