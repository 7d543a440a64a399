"""ball_predictor: ball and robot tracking plus catch-time prediction (paper Sec. 5) as a ROS 2 node.

Serves all robots from one process; the per-frame work is predictor.BallPredictor (tracking,
robot freshness, the reaction time, robotTimeToBall for the team, the model in use and online
identification), the same object the in-process scenes and the bench run. Every ``/vision/ball``
frame is answered with each fresh robot's ``/robot_<i>/catch_time`` and ``catch_point`` (first:
what the robots act on), then the ball state, phase, stop point, v_shoot and the uncertain flag.
All outputs carry the observation's stamp; catch times count from it. ``/robot_<i>/vision_pose``
is answered with ``/robot_<i>/odom``.

``/ball/model_params`` is the model in use as state (transient local): published at start and
whenever it changes (a parameter, an accepted fit), and after every online fit with its result.

Bad input (non-finite, outside the field, stamps not increasing) is dropped with a throttled
warning and answered with nothing. This module converts messages and publishes; no maths here.
"""

from __future__ import annotations

import inspect
import math
import os
import time
from typing import Any

from rclpy.node import Node
from std_msgs.msg import Bool, String

from erforce_ball_model.ball_model import BallModelParams
from erforce_ball_model.catch_time import CatchSearch, RobotLimits
from erforce_ball_model.catcher import CatcherConfig
from erforce_ball_model.predictor import BallFrame, BallPredictor, FrameTimes, PredictorConfig
from erforce_ball_model.tracking import TrackerConfig
from erforce_interfaces import contract
from erforce_interfaces.conversions import (
    MAX_ABS_VALUE,
    ConversionError,
    float64_cdr,
    odometry_cdr,
    point_cdr,
    point_from_msg,
    pose2d_from_msg,
    seconds_to_stamp,
    table_msg,
)
from erforce_interfaces.executor import run_sampled
from erforce_interfaces.node_support import (
    ParamSpec,
    ThrottledWarner,
    contract_publisher,
    contract_subscription,
    declare_params,
    robot_config_from_params,
    robot_param_specs,
    run_node,
    sample_clock,
)
from erforce_interfaces.robot_config import FieldConfig

# Node defaults are the cores' defaults.
_MODEL = BallModelParams()
_TRACK = TrackerConfig()
_CATCHER = CatcherConfig()  # the robot limits: what the catcher drives with
_GRID_STEP_S = inspect.signature(CatchSearch).parameters["grid_step_s"].default

FACING_MODES = ("towards_ball", "fixed")

PARAMS = (
    ParamSpec("num_robots", 11, "robots robot_0 .. robot_{n-1} served by this node", min=1, max=64, read_only=True),
    ParamSpec("a_slide_mps2", _MODEL.a_slide_mps2, "sliding deceleration (< 0, |a_slide| > |a_roll|) [m/s^2]",
              min=-100.0, max=0.0),
    ParamSpec("a_roll_mps2", _MODEL.a_roll_mps2, "rolling deceleration (< 0) [m/s^2]", min=-100.0, max=0.0),
    ParamSpec("c_switch", _MODEL.c_switch, "v_switch / v_shoot, in (0, 1]", min=0.0, max=1.0),
    ParamSpec("field", "division_b", "field preset: division_a (12 x 9 m) | division_b (9 x 6 m)"),
    ParamSpec(
        "field_margin_m",
        0.0,
        "the catch search ends where the ball crosses the field lines extended by this [m]",
        min=-1.0,
        max=2.0,
    ),
    ParamSpec(
        "vision_reject_margin_m",
        0.5,
        "observations farther than this outside the field lines are rejected (walls at 0.3 m) [m]",
        min=0.0,
        max=5.0,
    ),
    ParamSpec(
        "robot_a_max_mps2", _CATCHER.a_max_mps2, "robot acceleration limit of robotTimeToPos [m/s^2]; the catcher "
        "drives with the same", min=1e-3, max=50.0),
    ParamSpec("robot_v_max_mps", _CATCHER.v_max_mps, "robot speed limit of robotTimeToPos [m/s]", min=1e-3, max=20.0),
    ParamSpec("reaction_s", 0.1, "robot reaction time: vision latency, tracking and control lag; a robot starts "
              "to act on a prediction this much later [s]", min=0.0, max=1.0),
    ParamSpec(
        "facing_mode",
        ["towards_ball"],
        "per robot (or one for all): towards_ball (dribbler against the ball's motion; towards the ball "
        "when it rests) | fixed (facing_rad)",
    ),
    ParamSpec(
        "facing_rad",
        [math.pi],
        "per robot (or one for all): dribbler direction in `field` for facing_mode fixed [rad]",
        min=-2.0 * math.pi,
        max=2.0 * math.pi,
    ),
    ParamSpec(
        "rest_speed_mps",
        0.1,
        "a slower filtered ball is reported stopped and faced from the robot (vision noise keeps the "
        "estimate of a resting ball at a few cm/s) [m/s]",
        min=0.0,
        max=1.0,
    ),
    ParamSpec(
        "robot_timeout_s",
        1.0,
        "a robot not seen for this long (vision stamps) gets no catch outputs [s]",
        min=0.001,
        max=3600.0,
    ),
    ParamSpec("grid_step_s", _GRID_STEP_S, "sampling step of the catch search (Algorithm 2) [s]", min=1e-4, max=0.5),
    ParamSpec("position_noise_m", _TRACK.position_noise_m, "ball vision noise, standard deviation [m]",
              min=1e-5, max=0.5),
    ParamSpec(
        "accel_noise_psd",
        _TRACK.accel_noise_psd,
        "ball process noise beyond the two-phase model [(m/s^2)^2/Hz]",
        min=1e-6,
        max=1e4,
    ),
    ParamSpec("gate_sigma", _TRACK.gate_sigma, "innovation gate of the ball filter [sigma]", min=1.0, max=100.0),
    ParamSpec(
        "kick_threshold_mps", _TRACK.kick_threshold_mps, "speed gain that counts as a kick [m/s]", min=0.01, max=10.0
    ),
    ParamSpec(
        "ricochet_angle_rad",
        _TRACK.ricochet_angle_rad,
        "direction change that counts as a ricochet [rad]",
        min=0.01,
        max=math.pi,
    ),
    ParamSpec("max_gap_s", _TRACK.max_gap_s, "a longer gap between frames restarts the ball filter [s]",
              min=0.01, max=60.0),
    ParamSpec("max_ball_speed_mps", _TRACK.max_ball_speed_mps,
              "two vision frames further apart than this speed allows are not one motion (a ball put down "
              "elsewhere, a false detection): the newer is held back [m/s]", min=1.0, max=100.0),
    ParamSpec("online_identification", False, "fit a_slide, a_roll, c_switch from completed shots and use them"),
    ParamSpec("ident_min_shots", 3, "shots needed before a fit may replace the model", min=1, max=50),
    ParamSpec(
        "ident_max_std_a_slide_mps2", 0.1, "accept a fit when the std error of a_slide is below [m/s^2]",
        min=0.0, max=10.0,
    ),
    ParamSpec(
        "ident_max_std_a_roll_mps2", 0.02, "accept a fit when the std error of a_roll is below [m/s^2]",
        min=0.0, max=10.0,
    ),
    ParamSpec("ident_max_std_c_switch", 0.03, "accept a fit when the std error of c_switch is below",
              min=0.0, max=1.0),
    ParamSpec(
        "timing_log_every",
        0,
        "log the in-node processing time (median, p99) of every N ball frames, to the last catch time "
        "published and to the end of the frame; 0 = off",
        min=0,
        max=1_000_000,
    ),
) + robot_param_specs()


def build_config(values: dict[str, Any]) -> PredictorConfig:
    """The node configuration for a complete set of parameter values (raises ValueError when invalid)."""
    unknown = sorted({m for m in values["facing_mode"] if m not in FACING_MODES})
    if unknown:
        raise ValueError(f"facing_mode must be towards_ball or fixed, got {', '.join(map(repr, unknown))}")
    return PredictorConfig(
        num_robots=values["num_robots"],
        model=BallModelParams(values["a_slide_mps2"], values["a_roll_mps2"], values["c_switch"]),
        tracker=TrackerConfig(
            position_noise_m=values["position_noise_m"],
            accel_noise_psd=values["accel_noise_psd"],
            gate_sigma=values["gate_sigma"],
            kick_threshold_mps=values["kick_threshold_mps"],
            ricochet_angle_rad=values["ricochet_angle_rad"],
            max_gap_s=values["max_gap_s"],
            max_ball_speed_mps=values["max_ball_speed_mps"],
        ),
        field=FieldConfig.preset(values["field"]),
        field_margin_m=values["field_margin_m"],
        vision_reject_margin_m=values["vision_reject_margin_m"],
        limits=RobotLimits(values["robot_a_max_mps2"], values["robot_v_max_mps"]),
        reaction_s=values["reaction_s"],
        facing_fixed=[m == "fixed" for m in values["facing_mode"]],
        facing_rad=list(values["facing_rad"]),
        dribbler_offset_m=robot_config_from_params(values).dribbler_offset_m,
        rest_speed_mps=values["rest_speed_mps"],
        grid_step_s=values["grid_step_s"],
        robot_timeout_s=values["robot_timeout_s"],
        online_identification=values["online_identification"],
        ident_min_shots=values["ident_min_shots"],
        ident_max_std=(
            values["ident_max_std_a_slide_mps2"],
            values["ident_max_std_a_roll_mps2"],
            values["ident_max_std_c_switch"],
        ),
        timing_log_every=values["timing_log_every"],
    )


class BallPredictorNode(Node):
    def __init__(self) -> None:
        super().__init__("ball_predictor")
        self._warn = ThrottledWarner(self)
        self._predictor: BallPredictor | None = None
        self._times = FrameTimes(0)
        self._values = declare_params(self, PARAMS, build_config, self._apply)
        predictor = self._predictor
        n = predictor.config.num_robots
        q = contract
        self._params_pub = contract_publisher(self, q.BALL_MODEL_PARAMS)
        self._publish_model()
        self._state_pub = contract_publisher(self, q.BALL_STATE)
        self._phase_pub = contract_publisher(self, q.BALL_PHASE)
        self._stop_pub = contract_publisher(self, q.BALL_STOP_POINT)
        self._v_shoot_pub = contract_publisher(self, q.BALL_V_SHOOT)
        self._uncertain_pub = contract_publisher(self, q.BALL_UNCERTAIN)
        self._odom_pubs = [contract_publisher(self, q.ODOM, q.ODOM.for_robot(i)) for i in range(n)]
        self._catch_time_pubs = [contract_publisher(self, q.CATCH_TIME, q.CATCH_TIME.for_robot(i)) for i in range(n)]
        self._catch_point_pubs = [
            contract_publisher(self, q.CATCH_POINT, q.CATCH_POINT.for_robot(i)) for i in range(n)
        ]
        self._phase_msg, self._uncertain_msg = String(), Bool()  # refilled every frame
        # Vision comes in and catch outputs go out serialized (conversions' codec): on the path
        # from a frame to its catch times rclpy's message objects cost more than the maths.
        contract_subscription(self, q.VISION_BALL, self._on_ball, raw=True)
        for i in range(n):
            contract_subscription(self, q.VISION_POSE, lambda m, i=i: self._on_robot(i, m), q.VISION_POSE.for_robot(i),
                                  raw=True)
        # Everything runs on vision stamps; ROS time only stamps the logs: no wake per /clock.
        self._clock_subs = sample_clock(self)
        model = predictor.model
        self.get_logger().info(
            f"ball_predictor: {n} robot(s), {self._values['field']}, a_slide {model.a_slide_mps2:g}, "
            f"a_roll {model.a_roll_mps2:g}, c_switch {model.c_switch:g} "
            f"(online identification {'on' if predictor.config.online_identification else 'off'})"
        )

    def _apply(self, config: PredictorConfig) -> None:
        if config.timing_log_every != self._times.every:
            self._times = FrameTimes(config.timing_log_every)  # a new window starts with the change
        if self._predictor is None:
            self._predictor = BallPredictor(config, warn=self._warn.warn, info=self.get_logger().info)
        elif self._predictor.configure(config):
            self._publish_model()

    def _publish_model(self) -> None:
        rows = self._predictor.model_rows()
        try:
            self._params_pub.publish(table_msg(rows, contract.BALL_MODEL_PARAM_LABELS,
                                               ",".join(contract.BALL_MODEL_PARAM_ROWS[:len(rows)])))
        except ConversionError as exc:
            self._warn.warn("model_params", f"model_params not published: {exc}")

    def _on_robot(self, robot: int, msg: bytes) -> None:
        try:
            t_s, pose = pose2d_from_msg(msg)
        except ConversionError as exc:
            self._warn.warn(f"pose{robot}", f"robot_{robot}: rejected vision_pose: {exc}")
            return
        tracker = self._predictor.robot_frame(robot, t_s, pose[0], pose[1], pose[2])
        if tracker is None:
            return
        vel = tracker.velocity_mps
        try:
            odom = odometry_cdr(
                t_s, (*tracker.position_m, tracker.heading_rad), (vel[0], vel[1], tracker.angular_velocity_radps),
                child_frame_id=contract.robot_frame(robot),
            )
        except ConversionError as exc:
            self._warn.warn(f"odom{robot}", f"robot_{robot}: odom not published: {exc}")
            return
        self._odom_pubs[robot].publish(odom)

    def _on_ball(self, msg: bytes) -> None:
        try:
            self._ball_frame(msg)
        finally:
            run_sampled(self._clock_subs)  # after the outputs: not on the latency path

    def _ball_frame(self, msg: bytes) -> None:
        start = time.perf_counter()
        try:
            t_s, xy = point_from_msg(msg)
        except ConversionError as exc:
            self._warn.warn("ball_invalid", f"rejected vision/ball: {exc}")
            return
        frame = self._predictor.ball_frame(t_s, xy[0], xy[1])
        if frame is None:
            return
        # Catch times go out first: they are what the robots act on, and each publish costs tens
        # of microseconds. The ball topics follow.
        catch_out = None
        try:
            catch_out = self._publish_catch_outputs(frame)
        except ValueError as exc:
            self._warn.warn("catch", f"no catch times for the frame at {t_s:.6f} s: {exc}")
        if catch_out is None:  # none went out
            catch_out = time.perf_counter()
        try:
            self._publish_ball_outputs(frame)
        except ValueError as exc:
            self._warn.warn("predict", f"no ball state for the frame at {t_s:.6f} s: {exc}")
        summary = self._times.add(catch_out - start, time.perf_counter() - start)
        if summary:
            self.get_logger().info(summary)
        if self._predictor.identify(frame) is not None:  # a fit finished
            self._publish_model()

    def _publish_ball_outputs(self, frame: BallFrame) -> None:
        """The ball topics; all are built (and checked) before the first goes out."""
        t_s, f = frame.t_s, frame.trajectory.floats
        state = odometry_cdr(t_s, (f.x_m, f.y_m, 0.0), (f.vx_mps, f.vy_mps, 0.0), child_frame_id="ball",
                             position_variance_m2=frame.position_variance_m2)
        stop_point = point_cdr(t_s, frame.stop_point_m)
        v_shoot = float64_cdr(f.v_shoot_mps)
        self._phase_msg.data = frame.phase
        self._uncertain_msg.data = frame.uncertain
        self._state_pub.publish(state)
        self._phase_pub.publish(self._phase_msg)
        self._stop_pub.publish(stop_point)
        self._v_shoot_pub.publish(v_shoot)
        self._uncertain_pub.publish(self._uncertain_msg)

    def _publish_catch_outputs(self, frame: BallFrame) -> float | None:
        """catch_time, then catch_point, of every fresh robot.

        All values are checked before the first publish (a bad one raises ValueError and nothing
        goes out); the catch times go out before the points are even serialized. Returns when the
        last catch time went out (perf_counter), None when no robot is fresh.
        """
        ids, points = frame.catch_robots, frame.catch_points_m
        if not ids:
            return None
        seconds_to_stamp(frame.t_s)  # the points' stamp
        for point in points:
            if point is not None and not (abs(point[0]) <= MAX_ABS_VALUE and abs(point[1]) <= MAX_ABS_VALUE):
                point_cdr(frame.t_s, point)  # raises, naming the value
        time_data = [float64_cdr(t) for t in frame.catch_times_s]
        time_pubs = self._catch_time_pubs
        for i, data in zip(ids, time_data, strict=True):
            time_pubs[i].publish(data)
        times_out = time.perf_counter()
        point_pubs = self._catch_point_pubs
        for i, point in zip(ids, points, strict=True):
            if point is not None:
                point_pubs[i].publish(point_cdr(frame.t_s, point))
        # The catch outputs' readers are often woken onto this CPU (the scheduler places a wakee
        # beside its waker) and would wait behind the rest of this frame: let them run first.
        os.sched_yield()
        return times_out

    def destroy_node(self) -> None:
        if self._predictor is not None:
            self._predictor.close()
        super().destroy_node()


def main(args: list[str] | None = None) -> int:
    return run_node(BallPredictorNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
