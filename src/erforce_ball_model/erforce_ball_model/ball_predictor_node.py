"""ball_predictor: ball and robot tracking plus catch-time prediction (paper Sec. 5) as a ROS 2 node.

Serves all robots from one process. Every ``/vision/ball`` frame runs the ball tracker
(tracking.BallTracker: v_shoot, phase, ricochets) and answers with the ball state, phase,
stop point, v_shoot and the uncertain flag, and, for every robot whose pose is known,
``/robot_<i>/catch_time`` and ``catch_point`` from one robotTimeToBall run for the team
(catch_time.CatchSearch, Algorithm 2). All outputs carry the observation's stamp;
catch times count from it. ``/robot_<i>/vision_pose`` feeds one RobotTracker per robot and
is answered with ``/robot_<i>/odom``.

With ``online_identification`` the frames also feed identification.ShotAccumulator; each
completed shot triggers a refit in a worker thread, the result goes out on
``/ball/model_params`` and replaces the model in use once its standard errors are small
enough. Setting a model parameter by hand puts that value back in use.

Bad input (non-finite, outside the field, stamps not increasing) is dropped with a
throttled warning and answered with nothing. All maths is in the cores.
"""

from __future__ import annotations

import concurrent.futures
import math
import os
import time
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from rclpy.node import Node
from std_msgs.msg import Bool, Float64MultiArray, String

from erforce_ball_model.ball_model import BallModelParams, BallPhase, BallTrajectory
from erforce_ball_model.catch_time import CatchKind, CatchSearch, RobotLimits, catch_after_reaction
from erforce_ball_model.identification import FitResult, ShotAccumulator, fit_shots
from erforce_ball_model.tracking import BallTracker, RobotTracker, TrackerConfig, UpdateStatus
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
    NodeParams,
    ThrottledWarner,
    check_stamp,
    contract_publisher,
    contract_subscription,
    run_node,
    sample_clock,
)
from erforce_interfaces.param_schema import load_schema
from erforce_interfaces.robot_config import FieldConfig
from erforce_interfaces.stamps import StampFilter, StampVerdict

SCHEMA = load_schema("erforce_ball_model", "ball_predictor")

_NEVER = int(CatchKind.NEVER)
PHASE_NAMES = {BallPhase.SLIDING: "sliding", BallPhase.ROLLING: "rolling", BallPhase.STOPPED: "stopped"}


@dataclass(frozen=True, eq=False)
class PredictorConfig:
    """Everything the node computes with, built and validated from the parameter values."""

    num_robots: int
    model: BallModelParams
    tracker: TrackerConfig
    field: FieldConfig
    field_margin_m: float
    vision_reject_margin_m: float
    limits: RobotLimits
    reaction_s: float
    facing_fixed: np.ndarray  # (R,) bool: fixed heading instead of towards the ball
    facing_rad: np.ndarray  # (R,)
    dribbler_offset_m: float
    rest_speed_mps: float
    grid_step_s: float
    robot_timeout_s: float
    online_identification: bool
    ident_min_shots: int
    ident_max_std: tuple[float, float, float]
    timing_log_every: int


def _per_robot(name: str, values: list, n: int) -> list:
    values = list(values)
    if len(values) == 1:
        return values * n
    if len(values) != n:
        raise ValueError(f"{name}: need one value or one per robot ({n}), got {len(values)}")
    return values


def build_config(c) -> PredictorConfig:
    """The node configuration for a config object of the schema (raises ValueError when invalid)."""
    n = c.num_robots
    modes = _per_robot("facing_mode", c.facing_mode, n)
    return PredictorConfig(
        num_robots=n,
        model=BallModelParams(c.a_slide_mps2, c.a_roll_mps2, c.c_switch),
        tracker=TrackerConfig(
            position_noise_m=c.position_noise_m,
            accel_noise_psd=c.accel_noise_psd,
            gate_sigma=c.gate_sigma,
            kick_threshold_mps=c.kick_threshold_mps,
            ricochet_angle_rad=c.ricochet_angle_rad,
            max_gap_s=c.max_gap_s,
            max_ball_speed_mps=c.max_ball_speed_mps,
        ),
        field=FieldConfig.preset(c.field),
        field_margin_m=c.field_margin_m,
        vision_reject_margin_m=c.vision_reject_margin_m,
        limits=RobotLimits(c.robot_a_max_mps2, c.robot_v_max_mps),
        reaction_s=c.reaction_s,
        facing_fixed=np.array([m == "fixed" for m in modes]),
        facing_rad=np.array(_per_robot("facing_rad", c.facing_rad, n), dtype=float),
        dribbler_offset_m=c.robot.dribbler_offset_m,
        rest_speed_mps=c.rest_speed_mps,
        grid_step_s=c.grid_step_s,
        robot_timeout_s=c.robot_timeout_s,
        online_identification=c.online_identification,
        ident_min_shots=c.ident_min_shots,
        ident_max_std=(c.ident_max_std_a_slide_mps2, c.ident_max_std_a_roll_mps2, c.ident_max_std_c_switch),
        timing_log_every=c.timing_log_every,
    )


def model_params_table(fit: FitResult, in_use: BallModelParams) -> Float64MultiArray:
    rows = [
        [fit.params.a_slide_mps2, fit.params.a_roll_mps2, fit.params.c_switch],
        [fit.a_slide_std, fit.a_roll_std, fit.c_switch_std],
        [in_use.a_slide_mps2, in_use.a_roll_mps2, in_use.c_switch],
    ]
    return table_msg(rows, contract.BALL_MODEL_PARAM_LABELS, ",".join(contract.BALL_MODEL_PARAM_ROWS))


class _BallMessages(NamedTuple):
    """The ball topics' small messages, refilled every frame (the others go out serialized)."""

    phase: String
    uncertain: Bool


class BallPredictorNode(Node):
    def __init__(self) -> None:
        super().__init__("ball_predictor")
        self._warn = ThrottledWarner(self)
        self._config: PredictorConfig | None = None
        self._model: BallModelParams | None = None  # in use: configured or identified
        self._ball: BallTracker | None = None
        self._shots: ShotAccumulator | None = None
        self._fitted_shot = None  # the newest shot a fit was started with
        self._frame_times_s: list[tuple[float, float]] = []  # (to the catch times out, to the end)
        self._fit_pool = concurrent.futures.ThreadPoolExecutor(max_workers=1, thread_name_prefix="ball_fit")
        self._fit_future: concurrent.futures.Future | None = None
        self._search: CatchSearch | None = None  # robotTimeToBall for the team, rebuilt on a change
        self._params = NodeParams(self, SCHEMA, build_config)
        self._values = self._params.values
        self._apply(self._params.built)
        n = self._config.num_robots
        self._robots: list[RobotTracker | None] = [None] * n
        self._ball_stamps, self._robot_stamps = StampFilter(), [StampFilter() for _ in range(n)]
        # The trackers' state after their last accepted pose, (t_s, x, y, vx, vy) per robot (NaN
        # stamp: not seen yet), and the velocities as the array the catch search takes.
        self._robot_states = [(math.nan, 0.0, 0.0, 0.0, 0.0)] * n
        self._robot_vel_mps = np.zeros((n, 2))
        self._ball_msgs = _BallMessages(String(), Bool())
        q = contract
        self._state_pub = contract_publisher(self, q.BALL_STATE)
        self._phase_pub = contract_publisher(self, q.BALL_PHASE)
        self._stop_pub = contract_publisher(self, q.BALL_STOP_POINT)
        self._v_shoot_pub = contract_publisher(self, q.BALL_V_SHOOT)
        self._uncertain_pub = contract_publisher(self, q.BALL_UNCERTAIN)
        self._params_pub = contract_publisher(self, q.BALL_MODEL_PARAMS)
        self._odom_pubs = [contract_publisher(self, q.ODOM, q.ODOM.for_robot(i)) for i in range(n)]
        self._catch_time_pubs = [contract_publisher(self, q.CATCH_TIME, q.CATCH_TIME.for_robot(i)) for i in range(n)]
        self._catch_point_pubs = [
            contract_publisher(self, q.CATCH_POINT, q.CATCH_POINT.for_robot(i)) for i in range(n)
        ]
        # Vision comes in and catch outputs go out serialized (conversions' codec): on the path
        # from a frame to its catch times rclpy's message objects cost more than the maths.
        contract_subscription(self, q.VISION_BALL, self._on_ball, raw=True)
        for i in range(n):
            contract_subscription(self, q.VISION_POSE, lambda m, i=i: self._on_robot(i, m), q.VISION_POSE.for_robot(i),
                                  raw=True)
        # Everything runs on vision stamps; ROS time only stamps the logs: no wake per /clock.
        self._clock_subs = sample_clock(self)
        self.get_logger().info(
            f"ball_predictor: {n} robot(s), {self._values['field']}, a_slide {self._model.a_slide_mps2:g}, "
            f"a_roll {self._model.a_roll_mps2:g}, c_switch {self._model.c_switch:g} "
            f"(online identification {'on' if self._config.online_identification else 'off'})"
        )
        self._params.on_change(self._apply)

    # -------------------------------------------------------------- parameters
    def _apply(self, config: PredictorConfig) -> None:
        old = self._config
        self._config = config
        if old is None or config.model != old.model:
            self._model = config.model  # a hand-set model wins over an identified one
        self._search = CatchSearch(
            config.num_robots, config.limits, dribbler_offset_m=config.dribbler_offset_m, field=config.field,
            field_margin_m=config.field_margin_m, grid_step_s=config.grid_step_s,
        )
        if self._ball is None or config.tracker != old.tracker:
            self._ball = BallTracker(self._model, config.tracker)  # filter state is lost: re-seeds
        self._ball.params = self._model
        if old is None or config.timing_log_every != old.timing_log_every:
            self._frame_times_s.clear()  # a new window starts with the change
        if config.online_identification and (self._shots is None or config.tracker != old.tracker):
            self._shots = ShotAccumulator(tracker_config=config.tracker)
            self._fitted_shot = None
        elif not config.online_identification:
            self._shots = None
            self._fit_future = None  # a fit still running is not used

    # ------------------------------------------------------------------ robots
    def _on_robot(self, robot: int, msg: bytes) -> None:
        cfg = self._config
        try:
            t_s, pose = pose2d_from_msg(msg)
        except ConversionError as exc:
            self._warn.warn(f"pose{robot}", f"robot_{robot}: rejected vision_pose: {exc}")
            return
        if not cfg.field.contains(pose[0], pose[1], cfg.vision_reject_margin_m):
            self._warn.warn(f"pose{robot}", f"robot_{robot}: rejected vision_pose outside the field: "
                                            f"({pose[0]:.3f}, {pose[1]:.3f}) m")
            return
        verdict = check_stamp(self._robot_stamps[robot], round(t_s * 1e9), self._warn,
                              f"robot_{robot}/vision_pose", self)
        if verdict is StampVerdict.DROP:
            return
        tracker = None if verdict is StampVerdict.RESTART else self._robots[robot]
        tracker = tracker or RobotTracker()
        status = tracker.update(t_s, pose[0], pose[1], pose[2])
        if status == UpdateStatus.REJECTED_TIME:
            self._warn.warn(f"pose{robot}", f"robot_{robot}: rejected vision_pose: stamp {t_s:.6f} s is not "
                                            f"after the previous one {tracker.t_s:.6f} s")
            return
        if status == UpdateStatus.REJECTED_INVALID:
            self._warn.warn(f"pose{robot}", f"robot_{robot}: rejected vision_pose: invalid")
            return
        self._robots[robot] = tracker
        vel = tracker.velocity_mps
        self._robot_states[robot] = (tracker.t_s, *tracker.position_m.tolist(), *vel.tolist())
        self._robot_vel_mps[robot] = vel
        try:
            odom = odometry_cdr(
                t_s, (*tracker.position_m, tracker.heading_rad), (vel[0], vel[1], tracker.angular_velocity_radps),
                child_frame_id=contract.robot_frame(robot),
            )
        except ConversionError as exc:
            self._warn.warn(f"odom{robot}", f"robot_{robot}: odom not published: {exc}")
            return
        self._odom_pubs[robot].publish(odom)

    def _robots_now(self, t_s: float) -> tuple[list[int], np.ndarray]:
        """The robots fresh at ``t_s``, and all robots' positions then (constant-velocity extrapolation).

        Stale robots stay where they were last seen, never-seen ones at the origin: the search runs
        for the whole team in one call and their outputs are not published. A loop over 22 tuples
        is cheaper here than the numpy calls for the same.
        """
        timeout_s = self._config.robot_timeout_s
        fresh, rows = [], []
        for i, (t_i, x, y, vx, vy) in enumerate(self._robot_states):
            age_s = t_s - t_i
            if abs(age_s) <= timeout_s:  # NaN (never seen) is not
                fresh.append(i)
                rows.append((x + vx * age_s, y + vy * age_s))
            else:
                rows.append((x, y))
        return fresh, np.array(rows)

    # -------------------------------------------------------------------- ball
    def _on_ball(self, msg: bytes) -> None:
        try:
            self._ball_frame(msg)
        finally:
            run_sampled(self._clock_subs)  # after the outputs: not on the latency path

    def _ball_frame(self, msg: bytes) -> None:
        start = time.perf_counter()
        cfg = self._config
        try:
            t_s, xy = point_from_msg(msg)
        except ConversionError as exc:
            self._warn.warn("ball_invalid", f"rejected vision/ball: {exc}")
            return
        if not cfg.field.contains(xy[0], xy[1], cfg.vision_reject_margin_m):
            self._warn.warn("ball_outside", f"rejected vision/ball outside the field: ({xy[0]:.3f}, {xy[1]:.3f}) m")
            return
        verdict = check_stamp(self._ball_stamps, round(t_s * 1e9), self._warn, "vision/ball", self)
        if verdict is StampVerdict.DROP:
            return
        if verdict is StampVerdict.RESTART:
            self._ball = BallTracker(self._model, cfg.tracker)
            if self._shots is not None:
                self._shots = ShotAccumulator(tracker_config=cfg.tracker)
                self._fitted_shot = None
        ball = self._ball
        last_t = ball.t_s
        status = ball.update(t_s, xy[0], xy[1])
        if status == UpdateStatus.REJECTED_TIME:
            self._warn.warn("ball_time", f"rejected vision/ball: stamp {t_s:.6f} s is not after the previous one "
                                    f"{last_t:.6f} s (time went backwards or repeated)")
            return
        if status == UpdateStatus.REJECTED_INVALID:
            self._warn.warn("ball_invalid", "rejected vision/ball: invalid")
            return
        try:
            traj = ball.trajectory()
            if status == UpdateStatus.HELD_BACK:  # the filter waits for the next frame: predict to this stamp
                traj = traj.advanced(t_s - ball.t_s)
        except ValueError as exc:  # publish nothing for this frame (e.g. 100 m/s from two frames 1 us apart)
            self._warn.warn("predict", f"no prediction for the frame at {t_s:.6f} s: {exc}")
            return
        # Catch times go out first: they are what the robots act on, and each publish costs tens
        # of microseconds. The ball topics follow.
        catch_out = None
        try:
            catch_out = self._publish_catch_outputs(t_s, traj)
        except ValueError as exc:
            self._warn.warn("catch", f"no catch times for the frame at {t_s:.6f} s: {exc}")
        if catch_out is None:  # none went out
            catch_out = time.perf_counter()
        try:
            self._publish_ball_outputs(t_s, status, traj)
        except ValueError as exc:
            self._warn.warn("predict", f"no ball state for the frame at {t_s:.6f} s: {exc}")
        self._frame_done(catch_out - start, time.perf_counter() - start)
        if self._shots is not None:
            self._identify(t_s, xy)

    def _publish_ball_outputs(self, t_s: float, status: UpdateStatus, traj: BallTrajectory) -> None:
        """The ball topics; all are built (and checked) before the first goes out."""
        cfg, ball, f = self._config, self._ball, traj.floats
        if status == UpdateStatus.INITIALIZED:
            phase = "unknown"
        elif f.speed_mps <= cfg.rest_speed_mps:
            phase = "stopped"
        else:
            phase = PHASE_NAMES[traj.phase]
        stop = (f.x_m + f.ux * f.stop_distance_m, f.y_m + f.uy * f.stop_distance_m)
        msgs = self._ball_msgs
        state = odometry_cdr(t_s, (f.x_m, f.y_m, 0.0), (f.vx_mps, f.vy_mps, 0.0), child_frame_id="ball",
                             position_variance_m2=ball.position_variance_m2)
        stop_point = point_cdr(t_s, stop)
        v_shoot = float64_cdr(f.v_shoot_mps)
        msgs.phase.data = phase
        msgs.uncertain.data = bool(ball.uncertain)
        self._state_pub.publish(state)
        self._phase_pub.publish(msgs.phase)
        self._stop_pub.publish(stop_point)
        self._v_shoot_pub.publish(v_shoot)
        self._uncertain_pub.publish(msgs.uncertain)

    def _publish_catch_outputs(self, t_s: float, traj: BallTrajectory) -> float | None:
        """catch_time, then catch_point, of every fresh robot: one robotTimeToBall run for the team.

        All values are checked before the first publish (a bad one raises ValueError and nothing
        goes out); the catch times go out before the points are even serialized. Returns when the
        last catch time went out (perf_counter), None when no robot is fresh.
        """
        cfg = self._config
        ids, pos = self._robots_now(t_s)
        if not ids:
            return None
        catch = catch_after_reaction(self._search, traj, pos, self._robot_vel_mps, cfg.reaction_s, cfg.facing_fixed,
                                     cfg.facing_rad, cfg.rest_speed_mps)
        # Per robot in plain floats (22 values; numpy calls cost more than they save here). All are
        # checked before the first publish, with the checks of float64_cdr / point_cdr.
        kinds, times, points = catch.kind.tolist(), catch.time_s.tolist(), catch.robot_target_m.tolist()
        seconds_to_stamp(t_s)  # the points' stamp
        for i in ids:
            if kinds[i] == _NEVER:
                times[i] = contract.CATCH_TIME_NEVER  # and no catch point: catch_time says so
            else:
                times[i] += cfg.reaction_s
                x, y = points[i]
                if not (abs(x) <= MAX_ABS_VALUE and abs(y) <= MAX_ABS_VALUE):
                    point_cdr(t_s, points[i])  # raises, naming the value
        time_data = [float64_cdr(times[i]) for i in ids]
        time_pubs = self._catch_time_pubs
        for i, data in zip(ids, time_data, strict=True):
            time_pubs[i].publish(data)
        times_out = time.perf_counter()
        point_pubs = self._catch_point_pubs
        for i in ids:
            if kinds[i] != _NEVER:
                point_pubs[i].publish(point_cdr(t_s, points[i]))
        # The catch outputs' readers are often woken onto this CPU (the scheduler places a wakee
        # beside its waker) and would wait behind the rest of this frame: let them run first.
        os.sched_yield()
        return times_out

    def _frame_done(self, catch_out_s: float, elapsed_s: float) -> None:
        every = self._config.timing_log_every
        if every <= 0:
            return
        self._frame_times_s.append((catch_out_s, elapsed_s))
        if len(self._frame_times_s) >= every:
            catch_ms, ms = 1e3 * np.array(self._frame_times_s).T
            self._frame_times_s.clear()
            self.get_logger().info(
                f"ball frame processing over {ms.size} frames: median {np.median(ms):.3f} ms, "
                f"p99 {np.percentile(ms, 99):.3f} ms, max {ms.max():.3f} ms; catch times out after: median "
                f"{np.median(catch_ms):.3f} ms, p99 {np.percentile(catch_ms, 99):.3f} ms"
            )

    # ---------------------------------------------------------- identification
    def _identify(self, t_s: float, xy: np.ndarray) -> None:
        shots = self._shots
        shots.add(t_s, xy[0], xy[1])
        future = self._fit_future
        if future is not None and future.done():
            self._fit_future = None
            try:
                self._fit_done(future.result())
            except Exception as exc:  # too few points, singular fit, ...: the node goes on without it
                self._warn.warn("fit", f"online identification: fit failed: {exc}")
        if self._fit_future is None and shots.shots and shots.shots[-1] is not self._fitted_shot:
            self._fitted_shot = shots.shots[-1]  # refit once per completed shot, one fit at a time
            self._fit_future = self._fit_pool.submit(fit_shots, list(shots.shots), self._model)

    def _fit_done(self, fit: FitResult) -> None:
        cfg = self._config
        stds = (fit.a_slide_std, fit.a_roll_std, fit.c_switch_std)
        good = fit.num_shots >= cfg.ident_min_shots and all(
            math.isfinite(s) and s < limit for s, limit in zip(stds, cfg.ident_max_std, strict=True)
        )
        if good:
            self._model = fit.params
            self._ball.params = fit.params
            self.get_logger().info(
                f"online identification: now using a_slide {fit.params.a_slide_mps2:.4f}, a_roll "
                f"{fit.params.a_roll_mps2:.4f}, c_switch {fit.params.c_switch:.4f} ({fit.num_shots} shots)"
            )
        try:
            self._params_pub.publish(model_params_table(fit, self._model))
        except ConversionError as exc:
            self._warn.warn("fit", f"online identification: result not published: {exc}")

    def destroy_node(self) -> None:
        self._fit_pool.shutdown(wait=False, cancel_futures=True)
        super().destroy_node()


def main(args: list[str] | None = None) -> int:
    return run_node(BallPredictorNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
