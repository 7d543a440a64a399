"""catcher: the receive behaviour of the paper's Fig. 6 for one robot, as a ROS 2 node.

Runs in the robot's namespace. It reads its robot's catch time and catch point from the
ball predictor and drives there with ``cmd_vel``, facing the incoming ball (the
predictor computed the catch for that facing), unless a nearer place to receive on the
ball's line has time to spare (catcher.receive_point). It holds still when no catch is possible
or its inputs are stale, and once the light barrier sees the ball. The maths is in
erforce_ball_model.catcher.

In a team (``team_robot_ids``) it also reads the teammates' catch times, and only the robot that
can catch the ball first drives to it (catcher.team_receiver); the others hold.

It acts only in its ``rate_hz`` tick, on the newest inputs, so it does not wake for each of
the ~6 messages per vision frame: its subscriptions are sampled at the tick
(erforce_interfaces.executor.sample_only / run_sampled), in the order they were sent, and an
input's arrival time, by which its staleness is judged, is the tick that took it.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from nav_msgs.msg import Odometry
from rclpy.node import Node
from std_msgs.msg import Bool, Float64, Float64MultiArray

from erforce_ball_model.ball_model import BallModelParams, BallTrajectory
from erforce_ball_model.catcher import CatcherConfig, catch_twist, choose_target, team_receiver
from erforce_interfaces import contract
from erforce_interfaces.conversions import (
    ConversionError,
    float64_from_msg,
    odometry_from_msg,
    point_from_msg,
    table_from_msg,
    twist_msg,
)
from erforce_interfaces.executor import run_sampled, sample_only
from erforce_interfaces.node_support import (
    ParamSpec,
    ThrottledWarner,
    contract_publisher,
    contract_subscription,
    declare_params,
    robot_config_from_params,
    robot_param_specs,
    run_node,
)
from erforce_interfaces.robot_config import FieldConfig

_CC = CatcherConfig()
MODEL_IN_USE_ROW = contract.BALL_MODEL_PARAM_ROWS.index("in_use")

PARAMS = (
    ParamSpec("rate_hz", 50.0, "cmd_vel rate (robot time) [Hz], like an SSL AI's", min=1.0, max=1000.0),
    ParamSpec(
        "a_max_mps2",
        _CC.a_max_mps2,
        "acceleration of the approach profile [m/s^2]; keep equal to the ball predictor's robot limit",
        min=0.01,
        max=50.0,
    ),
    ParamSpec(
        "v_max_mps",
        _CC.v_max_mps,
        "speed of the approach profile [m/s]; keep equal to the ball predictor's robot limit",
        min=0.01,
        max=10.0,
    ),
    ParamSpec("w_max_radps", _CC.w_max_radps, "turn rate limit [rad/s]", min=0.01, max=50.0),
    ParamSpec("heading_gain_per_s", _CC.heading_gain_per_s, "heading error to turn rate [1/s]", min=0.01, max=100.0),
    ParamSpec(
        "arrive_tolerance_m", _CC.arrive_tolerance_m, "hold still this close to the target [m]", min=1e-4, max=1.0
    ),
    ParamSpec(
        "braking_margin",
        _CC.braking_margin,
        "fraction of a_max used for braking (velocity-loop lag)",
        min=0.05,
        max=1.0,
    ),
    ParamSpec(
        "stale_after_s",
        0.25,
        "inputs older than this (robot time) stop the robot [s]",
        min=0.01,
        max=10.0,
    ),
    ParamSpec("min_ball_speed_mps", 0.1, "a ball faster than this engages the catcher [m/s]", min=0.0, max=10.0),
    ParamSpec("fetch_resting_ball", False, "also drive to a ball that is not moving"),
    ParamSpec(
        "disengage_after_rest_s",
        2.0,
        "an engaged catcher gives up after the ball rested this long [s]",
        min=0.0,
        max=60.0,
    ),
    ParamSpec(
        "heading_deadband_rad",
        _CC.heading_deadband_rad,
        "no turning for smaller heading errors [rad]",
        min=0.0,
        max=1.0,
    ),
    ParamSpec(
        "receive_line_tolerance_m",
        _CC.receive_line_tolerance_m,
        "stand still once the dribbler is this close to the incoming ball's line [m]",
        min=0.0,
        max=0.5,
    ),
    ParamSpec(
        "receive_slack_s",
        _CC.receive_slack_s,
        "receive on the ball's line (at the robot's projection or further along) when the robot gets there this "
        "much before the ball, by the two-phase model (else drive to the predicted catch point) [s]",
        min=0.0,
        max=5.0,
    ),
    ParamSpec(
        "commit_s",
        0.3,
        "a robot that had a target for the moving ball this recently keeps blocking the ball's line when its "
        "plan turns infeasible (it lags, arrives fast) instead of holding; 0 = hold [s]",
        min=0.0,
        max=5.0,
    ),
    ParamSpec(
        "commit_distance_m",
        _CC.commit_distance_m,
        "a committed robot blocks the ball's line only when its projection on it is this close [m]",
        min=0.0,
        max=5.0,
    ),
    ParamSpec("field", "division_b", "field preset: division_a | division_b (receive points stay inside it)"),
    ParamSpec(
        "team_robot_ids",
        [],
        "robot ids of the team's catchers, this robot's included (it runs in namespace robot_<id>): only the "
        "one that can catch the ball first receives, the others hold; empty = this robot alone",
        min=0,
        max=1_000_000,
        read_only=True,
        empty_array_of=int,
    ),
    ParamSpec(
        "team_switch_margin_s",
        0.1,
        "the team's receiver keeps the ball until another robot's catch time is this much earlier [s]",
        min=0.0,
        max=5.0,
    ),
) + robot_param_specs()


def build_config(values: dict[str, Any]) -> tuple[CatcherConfig, float, float, FieldConfig]:
    """(catcher config, dribbler offset [m], robot radius [m], field) for a complete set of parameter values."""
    config = CatcherConfig(
        **{
            k: values[k]
            for k in (
                "a_max_mps2",
                "v_max_mps",
                "w_max_radps",
                "heading_gain_per_s",
                "arrive_tolerance_m",
                "braking_margin",
                "receive_line_tolerance_m",
                "heading_deadband_rad",
                "receive_slack_s",
                "commit_distance_m",
            )
        }
    )
    robot = robot_config_from_params(values)
    return config, robot.dribbler_offset_m, robot.robot_radius_m, FieldConfig.preset(values["field"])


class CatcherNode(Node):
    def __init__(self) -> None:
        super().__init__("catcher")
        self._warn = ThrottledWarner(self)
        self._config = _CC
        self._values = declare_params(self, PARAMS, build_config, self._set_config)
        self._pose = None  # (t_s, [x, y, yaw])
        self._velocity = np.zeros(2)  # field frame [m/s], with the pose
        self._target = None  # (t_s, [x, y])
        self._catch_time = None  # (t_s of arrival, seconds or CATCH_TIME_NEVER)
        self._ball_velocity = None  # (t_s, [vx, vy])
        self._ball_position = None  # [x, y]
        self._v_shoot = None  # (t_s, m/s)
        self._ball_model = BallModelParams()  # the predictor's model in use
        self._holding_ball = False
        self._engaged = False
        self._ball_moving_at = -math.inf  # robot time the ball was last seen moving
        self._target_at = -math.inf  # robot time a target was last chosen
        q = contract
        self._cmd_pub = contract_publisher(self, q.CMD_VEL)
        # catch_time and catch_point come serialized, as the predictor publishes them (conversions'
        # codec reads both forms)
        self._inputs = [
            sample_only(contract_subscription(self, topic, callback, raw=raw))
            for topic, callback, raw in (
                (q.ODOM, self._on_odom, False),
                (q.CATCH_TIME, self._on_catch_time, True),
                (q.CATCH_POINT, self._on_catch_point, True),
                (q.BALL_STATE, self._on_ball, False),
                (q.BALL_V_SHOOT, self._on_v_shoot, False),
                (q.BALL_MODEL_PARAMS, self._on_model_params, False),
                (q.BALL_DETECTED, self._on_barrier, False),
            )
        ]
        self._team = self._team_inputs(self._values["team_robot_ids"])
        self._receiver = None  # the team's receiver as this robot last decided
        self._timer = self.create_timer(1.0 / self._values["rate_hz"], self._tick)

    def _team_inputs(self, team_ids) -> dict[int, list]:
        """The teammates' catch times ({id: [robot time of arrival, seconds]}), sampled at the tick."""
        team = {int(i) for i in team_ids}
        if not team:
            return {}
        self._own_id = contract.robot_id_of_namespace(self.get_namespace())
        if self._own_id is None or self._own_id not in team:
            raise ValueError(f"team_robot_ids {sorted(team)}: a team catcher runs in the namespace of one of its "
                             f"robots (robot_<id>), this one runs in '{self.get_namespace()}'")
        times = {i: [-math.inf, contract.CATCH_TIME_NEVER] for i in team if i != self._own_id}
        for i in times:
            sub = contract_subscription(self, contract.CATCH_TIME, lambda m, i=i: self._on_team_catch_time(i, m),
                                        contract.CATCH_TIME.for_robot(i), raw=True)
            self._inputs.append(sample_only(sub))
        return times

    def _set_config(self, built: tuple[CatcherConfig, float, float, FieldConfig]) -> None:
        self._config, self._dribbler_offset_m, self._robot_radius_m, self._field = built

    def _now_s(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    def _on_odom(self, msg: Odometry) -> None:
        try:
            _t, pose, velocity, _ = odometry_from_msg(msg)
        except ConversionError as exc:
            self._warn.warn("odom", f"rejected odom: {exc}")
            return
        self._pose = (self._now_s(), pose)
        self._velocity = velocity[:2]

    def _stamped(self, msg, what: str, convert):
        """(robot time of arrival, converted value), or None with a throttled warning for a bad message."""
        try:
            return self._now_s(), convert(msg)
        except ConversionError as exc:
            self._warn.warn(what, f"rejected {what}: {exc}")
            return None

    def _on_catch_time(self, msg: bytes) -> None:
        self._catch_time = self._stamped(msg, "catch_time", float64_from_msg) or self._catch_time

    def _on_catch_point(self, msg: bytes) -> None:
        self._target = self._stamped(msg, "catch_point", lambda m: np.array(point_from_msg(m)[1])) or self._target

    def _on_team_catch_time(self, robot: int, msg: bytes) -> None:
        stamped = self._stamped(msg, f"robot_{robot} catch_time", float64_from_msg)
        if stamped is not None:
            self._team[robot][:] = stamped

    def _on_v_shoot(self, msg: Float64) -> None:
        self._v_shoot = self._stamped(msg, "v_shoot", float64_from_msg) or self._v_shoot

    def _on_model_params(self, msg: Float64MultiArray) -> None:
        try:
            row = table_from_msg(msg, contract.BALL_MODEL_PARAM_LABELS)[MODEL_IN_USE_ROW]
            self._ball_model = BallModelParams(*row.tolist())
        except (ConversionError, IndexError, ValueError) as exc:
            self._warn.warn("model_params", f"rejected model_params: {exc}")

    def _on_ball(self, msg: Odometry) -> None:
        try:
            _, pose, velocity, _ = odometry_from_msg(msg)
        except ConversionError as exc:
            self._warn.warn("ball", f"rejected ball state: {exc}")
            return
        now = self._now_s()
        self._ball_position = pose[:2]
        self._ball_velocity = (now, velocity[:2])
        if math.hypot(velocity[0], velocity[1]) >= self._values["min_ball_speed_mps"]:
            self._ball_moving_at = now
            if not self._holding_ball:
                self._engaged = True

    def _on_barrier(self, msg: Bool) -> None:
        if msg.data and not self._holding_ball:
            self.get_logger().info("light barrier: ball received")
            self._engaged = False
        self._holding_ball = bool(msg.data)

    def _fresh(self, stamped, now: float) -> bool:
        return stamped is not None and now - stamped[0] <= self._values["stale_after_s"]

    def _tick(self) -> None:
        run_sampled(self._inputs)
        now = self._now_s()
        twist = (0.0, 0.0, 0.0)
        if now - self._ball_moving_at > self._values["disengage_after_rest_s"]:
            self._engaged = False
        active = self._engaged or self._values["fetch_resting_ball"]
        if active and self._fresh(self._pose, now) and not self._holding_ball and self._receives(now):
            target = self._choose_target(now)
            if target is not None:
                pose, facing = self._pose[1], self._facing(now)
                try:
                    twist = catch_twist(pose, target, facing, self._config)
                except ValueError as exc:
                    self._warn.warn("twist", f"no command: {exc}")
                    twist = (0.0, 0.0, 0.0)
        else:
            self._target_at = -math.inf  # a commitment is to one ball in flight
        self._cmd_pub.publish(twist_msg(twist))

    def _receives(self, now: float) -> bool:
        """Alone, always; in a team, when it is the team's receiver, or nobody can catch the ball by the
        predictions (then each robot judges alone, as on the ball's line)."""
        if not self._team:
            return True
        stale_s = self._values["stale_after_s"]
        times = {i: t for i, (t_arrived, t) in self._team.items() if now - t_arrived <= stale_s}
        if self._fresh(self._catch_time, now):
            times[self._own_id] = self._catch_time[1]
        self._receiver = team_receiver(times, self._receiver, self._values["team_switch_margin_s"])
        return self._receiver is None or self._receiver == self._own_id

    def _facing(self, now: float) -> float:
        """Face the incoming ball, as the predictor assumed; keep the heading otherwise."""
        if self._fresh(self._ball_velocity, now):
            vx, vy = self._ball_velocity[1]
            if math.hypot(vx, vy) >= self._values["min_ball_speed_mps"]:
                return math.atan2(-vy, -vx)
        return self._pose[1][2]

    def _choose_target(self, now: float):
        """catcher.choose_target with the newest inputs; stale ones count as missing."""
        predicted = (
            self._fresh(self._target, now)
            and self._fresh(self._catch_time, now)
            and self._catch_time[1] != contract.CATCH_TIME_NEVER
        )
        committed = now - self._target_at <= self._values["commit_s"]
        target = choose_target(self._pose[1], self._velocity, self._moving_ball(now),
                               self._target[1] if predicted else None, self._dribbler_offset_m, self._config,
                               self._field, self._robot_radius_m, committed)
        if target is not None:
            self._target_at = now
        return target

    def _moving_ball(self, now: float) -> BallTrajectory | None:
        """The ball's future from the newest state, or None when it rests or is not known."""
        if not (self._fresh(self._ball_velocity, now) and self._ball_position is not None):
            return None
        velocity = self._ball_velocity[1]
        if math.hypot(*velocity) < self._values["min_ball_speed_mps"]:
            return None
        v_shoot = self._v_shoot[1] if self._fresh(self._v_shoot, now) else 0.0  # 0: raised to the speed
        try:
            return BallTrajectory(self._ball_position, velocity, max(v_shoot, 0.0), self._ball_model)
        except ValueError as exc:
            self._warn.warn("ball", f"ball state not usable: {exc}")
            return None


def main(args: list[str] | None = None) -> int:
    return run_node(CatcherNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
