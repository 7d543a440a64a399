"""ball_predictor: ball and robot tracking plus catch-time prediction (paper Sec. 5) as a ROS 2 node.

One process serves all robots (and with ``num_opponents`` the opponents, under ``/opponent_<i>/``); the
per-frame work is predictor.BallPredictor, the same object the in-process scenes and the bench run.

Vision comes in on ``/vision/robots``, one message per frame, the ball first (after the camera that took
it, where the frame names one: its ball and its sightings of the same ball go to the chip detector with the
camera's position, docs/decisions/0035). The ball is read and answered before the robots are decoded,
and the frames queued behind the one that woke the node have their balls answered before any of their robots
(docs/decisions/0015). Each ball frame is answered with
the catches first, what the robots act on: ``/ball/catches`` (both teams, one table), then each robot's
``catch_time`` and ``catch_point``; then the ball's state, phase, stop point, v_shoot and uncertain flag,
and ``/ball/track`` for observers. Then the frame's robots, each judged by the time rule on its own,
answered with its ``odom``, and ``/robots/tracked`` (every robot seen within ``robot_timeout_s``). The
ball state and v_shoot always go out, every other output only while read. All carry the observation's
stamp; catch times count from it.

``/ball/model_params`` is the model in use as state (transient local): published at start, on every
change and after every online fit. Bad input (non-finite, outside the field, stamps not increasing) is
dropped with a throttled warning and answered with nothing. No maths here.
"""

from __future__ import annotations

import gc
import math
import os
import threading
import time

from std_msgs.msg import Bool, Float64, Float64MultiArray, String

from erforce_ball_model.ball_model import BallModelParams, ChipParams
from erforce_ball_model.catch_time import RobotLimits, load_kernels
from erforce_ball_model.chip_tracking import ChipDetectorConfig
from erforce_ball_model.predictor import BallFrame, BallPredictor, FrameTimes, PredictorConfig, chip_covariances
from erforce_ball_model.tracking import TrackerConfig
from erforce_ball_model.tracking import load_kernels as load_ball_filter_kernels
from erforce_interfaces.runtime.executor import run_sampled, take_queued
from erforce_interfaces.runtime.node_support import (
    SchemaNode,
    check_stamp,
    contract_publisher,
    contract_subscription,
    run_node,
    sample_clock,
)
from erforce_interfaces.runtime.param_schema import load_schema
from erforce_interfaces.ssl.ssl_sim import MAX_KICK_ANGLE_DEG
from erforce_interfaces.wire import contract
from erforce_interfaces.wire.clouds import (
    BallTrack,
    LeadingPoints,
    ball_track_cdr,
    vision_ball_after_robot,
    vision_cloud_from_msg,
    vision_leading_points,
)
from erforce_interfaces.wire.conversions import (
    MAX_ABS_VALUE,
    ConversionError,
    float64_cdr,
    odometry_cdr,
    point_cdr,
    seconds_to_stamp,
)
from erforce_interfaces.wire.robot_config import WAITING_FOR_GEOMETRY, FieldConfig, field_from_setting
from erforce_interfaces.wire.stamps import StampFilter, StampVerdict
from erforce_interfaces.wire.tables import (
    field_from_msg,
    table_cdr,
    table_from_msg,
    table_msg,
    tracked_robot_row,
    tracked_robots_cdr,
)

SCHEMA = load_schema("erforce_ball_model", "ball_predictor")


def _ours_then_opponents(name: str, values: list, n: int, m: int, opponents_value) -> list:
    """A per-robot parameter of our ``n`` robots (one value or one each), then ``opponents_value`` for ``m``."""
    if len(values) not in (1, n):
        raise ValueError(f"{name}: need one value or one per robot ({n}), got {len(values)}")
    return (list(values) * n if len(values) == 1 else list(values)) + [opponents_value] * m


def build_config(c) -> PredictorConfig:
    """The predictor's configuration for a config object of the schema (raises ValueError when invalid)."""
    n, m = c.num_robots, c.num_opponents
    return PredictorConfig(
        num_robots=n + m,
        model=BallModelParams(c.a_slide_mps2, c.a_roll_mps2, c.c_switch),
        chip=ChipParams(damping_z=c.chip_damping_z, damping_xy_first_hop=c.chip_damping_xy_first_hop,
                        damping_xy_other_hops=c.chip_damping_xy_other_hops, min_hop_vz_mps=c.chip_min_hop_vz_mps,
                        max_catch_height_m=c.chip_max_catch_height_m,
                        max_receive_height_m=c.chip_max_receive_height_m),
        tracker=TrackerConfig(
            position_noise_m=c.position_noise_m,
            accel_noise_psd=c.accel_noise_psd,
            gate_sigma=c.gate_sigma,
            kick_threshold_mps=c.kick_threshold_mps,
            ricochet_angle_rad=c.ricochet_angle_rad,
            max_gap_s=c.max_gap_s,
            max_ball_speed_mps=c.max_ball_speed_mps,
        ),
        field=field_from_setting(c.field),
        field_margin_m=c.field_margin_m,
        vision_reject_margin_m=c.vision_reject_margin_m,
        wall_restitution=c.wall_restitution,
        limits=RobotLimits(c.robot_a_max_mps2, c.robot_v_max_mps),
        reaction_s=c.reaction_s,
        # the opponents face towards the ball: they intercept
        facing_fixed=_ours_then_opponents("facing_mode", [mode == "fixed" for mode in c.facing_mode], n, m, False),
        facing_rad=_ours_then_opponents("facing_rad", list(c.facing_rad), n, m, math.pi),
        receiving=[True] * n + [False] * m,  # and stop a chip with their body (ChipParams' two heights)
        dribbler_offset_m=c.robot.dribbler_offset_m,
        rest_speed_mps=c.rest_speed_mps,
        grid_step_s=c.grid_step_s,
        robot_timeout_s=c.robot_timeout_s,
        online_identification=c.online_identification,
        ident_min_shots=c.ident_min_shots,
        ident_max_std=(c.ident_max_std_a_slide_mps2, c.ident_max_std_a_roll_mps2, c.ident_max_std_c_switch),
        timing_log_every=c.timing_log_every,
        use_vision_geometry=c.use_vision_geometry,
        # the chip detector weighs its sightings by the same vision noise and takes the same rest speed
        chip_detector=ChipDetectorConfig(noise_m=c.position_noise_m, kick_speed_std_ratio=c.kick_speed_std_ratio,
                                         rest_speed_mps=c.rest_speed_mps),
    )


# The line the node logs once its compiled search answers (kernels="background": until then a frame costs ~1 ms
# per robot); benches and tools wait for it before they measure.
COMPILED_SEARCH_LOADED = "catch times from the compiled search from now on"


class BallPredictorNode(SchemaNode):
    # A warm standby (node_support.run_node) loads numba, the compiled search and the ball filter's kernel
    # before they are needed: the node it becomes answers with them from its first frame.
    @staticmethod
    def warm_up() -> None:
        load_kernels()
        load_ball_filter_kernels()

    def __init__(self, vision_topic: bool = True) -> None:
        """``vision_topic`` False: no ``/vision/robots`` subscription; the process's SSL-Vision receiver hands each
        frame to ``answer_vision`` instead (erforce_ball_model.ssl_ball_predictor)."""
        super().__init__("ball_predictor", SCHEMA, build_config)
        # Frames may come on another thread than the executor's (answer_vision): one frame, parameter change or
        # geometry message at a time.
        self._lock = threading.Lock()
        # kernels="background": the first frames are answered by the search's loop as Python (about 1 ms per
        # robot) and numba and the compiled search load in a thread after the first answer: a restarted
        # predictor closes the loop about a second sooner, what the 3 s to heal on a busy machine depends on.
        predictor = self._predictor = BallPredictor(self._params.built, warn=self._warn.warn,
                                                    info=self.get_logger().info, kernels="background")
        self._times = FrameTimes(predictor.config.timing_log_every)
        self._said_compiled = False
        q = contract
        n = predictor.config.num_robots
        n_ours = self._values["num_robots"]
        # each core index as the graph knows it: ours first, then the opponents
        self._robots = [(q.OURS, i) if i < n_ours else (q.OPPONENTS, i - n_ours) for i in range(n)]
        self._names = [team.namespace(j) for team, j in self._robots]
        self._core_index = {(team.code, float(j)): i for i, (team, j) in enumerate(self._robots)}  # a table row's
        self._robot_topics = [f"vision/robots ({name})" for name in self._names]  # the time rule's name per robot
        # The time rule (erforce_interfaces.wire.stamps) per input stream, before the core sees a frame.
        self._ball_stamps, self._robot_stamps = StampFilter(), [StampFilter() for _ in range(n)]
        self._params_pub = contract_publisher(self, q.BALL_MODEL_PARAMS)
        self._publish_model()
        self._chip_pub = contract_publisher(self, q.BALL_CHIP_MODEL_PARAMS)
        self._publish_chip_model()
        self._state_pub = contract_publisher(self, q.BALL_STATE)
        # phase, stop point and the uncertain flag: sent while they have a reader
        self._tool_readers = [0, 0, 0]
        self._phase_pub = contract_publisher(self, q.BALL_PHASE, readers=(self._tool_readers, 0))
        self._stop_pub = contract_publisher(self, q.BALL_STOP_POINT, readers=(self._tool_readers, 1))
        self._v_shoot_pub = contract_publisher(self, q.BALL_V_SHOOT)
        self._uncertain_pub = contract_publisher(self, q.BALL_UNCERTAIN, readers=(self._tool_readers, 2))
        # the AI's (and the field view's) catch times in one message for both teams: while it has a reader
        self._catches_readers = [0]
        self._catches_pub = contract_publisher(self, q.BALL_CATCHES, readers=(self._catches_readers, 0))
        # the ball for observers (the field view) in one message instead of five topics: while it has a reader
        self._track_readers = [0]
        self._track_pub = contract_publisher(self, q.BALL_TRACK, readers=(self._track_readers, 0))
        # A robot's odom (the tracker's estimate, volatile) is built and sent only while something reads it:
        # in a full team most are unread, and each publish costs tens of microseconds per vision frame.
        self._odom_readers = [0] * n
        self._odom_pubs = [contract_publisher(self, q.ODOM, team.topic(q.ODOM, j), readers=(self._odom_readers, i))
                           for i, (team, j) in enumerate(self._robots)]
        # What the odoms carry, for every tracked robot in one message per frame (the AI's input): while it
        # has a reader. Each robot's row as of its last accepted pose (None: none yet).
        self._tracked_readers = [0]
        self._tracked_pub = contract_publisher(self, q.ROBOTS_TRACKED, readers=(self._tracked_readers, 0))
        self._tracked_rows: list[tuple | None] = [None] * n
        # Likewise a robot's catch time and catch point: the graph's readers (the passing game for ours, the
        # interceptor for the opponents) take them per robot, and an unread one costs the frame's latency.
        self._time_readers = [0] * n
        self._catch_time_pubs = [contract_publisher(self, q.CATCH_TIME, team.topic(q.CATCH_TIME, j),
                                                    readers=(self._time_readers, i))
                                 for i, (team, j) in enumerate(self._robots)]
        self._point_readers = [0] * n
        self._catch_point_pubs = [contract_publisher(self, q.CATCH_POINT, team.topic(q.CATCH_POINT, j),
                                                     readers=(self._point_readers, i))
                                  for i, (team, j) in enumerate(self._robots)]
        self._phase_msg, self._uncertain_msg = String(), Bool()  # refilled every frame
        # Vision comes in and catch outputs go out serialized (conversions' codec): on the path
        # from a frame to its catch times rclpy's message objects cost more than the maths.
        self._vision_sub = (contract_subscription(self, q.VISION_ROBOTS, self._on_vision, raw=True) if vision_topic
                            else None)
        contract_subscription(self, q.VISION_FIELD, self._on_vision_field)
        contract_subscription(self, q.VISION_BALL_MODEL, self._on_vision_ball_model)
        contract_subscription(self, q.VISION_CHIP_MODEL, self._on_vision_chip_model)
        # Our kick commands as the kicker's word for the chip detector (kick_hints). A command carries no stamp: the
        # hint takes the newest vision stamp, the predictor's clock (/clock's time in our world, capture time on
        # an outside one), which is at or before the kick. The opponents' commands are not ours to see.
        # the elevation last commanded per robot (before its kick); None: the last one was refused (no hint)
        self._kick_angles_deg: list[float | None] = [0.0] * n_ours
        self._t_vision_s: float | None = None  # the newest ball frame's stamp
        for i in range(n_ours):
            contract_subscription(self, q.KICK_ANGLE, lambda m, i=i: self._on_kick_angle(i, m),
                                  q.OURS.topic(q.KICK_ANGLE, i))
            contract_subscription(self, q.KICK, lambda m, i=i: self._on_kick(i, m), q.OURS.topic(q.KICK, i))
        # Everything runs on vision stamps; ROS time only stamps the logs: no wake per /clock.
        self._clock_subs = sample_clock(self)
        model = predictor.model
        self.get_logger().info(
            f"ball_predictor: {n_ours} robot(s) and {n - n_ours} opponent(s), {self._values['field']}, "
            f"a_slide {model.a_slide_mps2:g}, a_roll {model.a_roll_mps2:g}, c_switch {model.c_switch:g} "
            f"(online identification {'on' if predictor.config.online_identification else 'off'})"
        )
        if predictor.config.field is None:
            self.get_logger().info(WAITING_FOR_GEOMETRY)
        self._params.on_change(self._apply)

    def _apply(self, config: PredictorConfig) -> None:
        with self._lock:
            self._configure(config)

    def _configure(self, config: PredictorConfig) -> None:
        if config.timing_log_every != self._times.every:
            # A change ends the window (its summary is logged) and starts a new one: a bench measures
            # exactly the frames between two changes.
            summary = self._times.flush()
            if summary:
                self.get_logger().info(summary)
            self._times = FrameTimes(config.timing_log_every)
        chip_before = self._predictor.chip_model
        if self._predictor.configure(config):
            self._publish_model()
        if self._predictor.chip_model != chip_before:
            self._publish_chip_model()

    def _publish_model(self) -> None:
        rows = self._predictor.model_rows()
        try:
            self._params_pub.publish(table_msg(rows, contract.BALL_MODEL_PARAM_LABELS,
                                               ",".join(contract.BALL_MODEL_PARAM_ROWS[:len(rows)])))
        except ConversionError as exc:
            self._warn.warn("model_params", f"model_params not published: {exc}")

    def _publish_chip_model(self) -> None:
        chip = self._predictor.chip_model
        try:
            self._chip_pub.publish(table_msg([[getattr(chip, name) for name in contract.BALL_CHIP_MODEL_PARAM_LABELS]],
                                             contract.BALL_CHIP_MODEL_PARAM_LABELS, contract.BALL_MODEL_PARAM_ROWS[0]))
        except ConversionError as exc:
            self._warn.warn("chip_model_params", f"chip_model_params not published: {exc}")

    # ------------------------------------------------------------- SSL geometry
    # The predictor keeps them (also across parameter changes) and uses them while use_vision_geometry.
    def _on_vision_field(self, msg: Float64MultiArray) -> None:
        with self._lock:
            self._vision_field(msg)

    def _vision_field(self, msg: Float64MultiArray) -> None:
        try:
            field = field_from_msg(msg)
        except (ConversionError, ValueError) as exc:
            self._warn.warn("vision_field", f"rejected /vision/field: {exc}")
            return
        self._geometry(field, None)

    def take_geometry(self, field: FieldConfig, model: BallModelParams | None,
                      chip_dampings: dict[str, float] | None = None) -> None:
        """SSL geometry from a receiver in this process (any thread), handed over before its next frame."""
        with self._lock:
            self._geometry(field, model, chip_dampings)

    def _geometry(self, field: FieldConfig | None, model: BallModelParams | None,
                  chip_dampings: dict[str, float] | None = None) -> None:
        """Hand SSL geometry's parts (None: unchanged) to the predictor; publish and log what it changed."""
        field_before, chip_before = self._predictor.config.field, self._predictor.chip_model
        try:
            model_changed = self._predictor.set_vision_geometry(field=field, model=model, chip_dampings=chip_dampings)
        except ValueError as exc:
            self._warn.warn("vision_chip_model", f"rejected SSL geometry's chip model: {exc}")
            return
        if model_changed:
            self._publish_model()
            if model is not None:
                self.get_logger().info(f"ball model from SSL geometry: a_slide {model.a_slide_mps2:g}, a_roll "
                                       f"{model.a_roll_mps2:g}, c_switch {model.c_switch:g}")
        chip = self._predictor.chip_model
        if chip != chip_before:
            self._publish_chip_model()
            self.get_logger().info(f"chip model from SSL geometry: damping_z {chip.damping_z:g}, damping_xy_first_hop "
                                   f"{chip.damping_xy_first_hop:g}, damping_xy_other_hops "
                                   f"{chip.damping_xy_other_hops:g}")
        after = self._predictor.config.field
        if after != field_before:
            self.get_logger().info(f"field from SSL geometry: {after.length_m:g} x {after.width_m:g} m")

    def _on_vision_ball_model(self, msg: Float64MultiArray) -> None:
        with self._lock:
            self._vision_ball_model(msg)

    def _vision_ball_model(self, msg: Float64MultiArray) -> None:
        try:
            model = BallModelParams(*table_from_msg(msg, contract.BALL_MODEL_PARAM_LABELS)[0].tolist())
        except (ConversionError, ValueError, IndexError, TypeError) as exc:
            self._warn.warn("vision_model", f"rejected /vision/ball_model: {exc}")
            return
        self._geometry(None, model)

    def _on_vision_chip_model(self, msg: Float64MultiArray) -> None:
        with self._lock:
            try:
                row = table_from_msg(msg, contract.VISION_CHIP_MODEL_LABELS)[0].tolist()
            except (ConversionError, ValueError, IndexError) as exc:
                self._warn.warn("vision_chip_model", f"rejected /vision/chip_model: {exc}")
                return
            self._geometry(None, None, dict(zip(contract.VISION_CHIP_MODEL_LABELS, row, strict=True)))

    # ------------------------------------------------------------- kick hints
    def _on_kick_angle(self, robot: int, msg: Float64) -> None:
        """The elevation of the robot's next kick; one outside [0, MAX_KICK_ANGLE_DEG) is refused and the kick
        after it is no hint (the chip detector judges it from the cameras alone)."""
        angle = msg.data
        if not (math.isfinite(angle) and 0.0 <= angle < MAX_KICK_ANGLE_DEG):
            self._kick_angles_deg[robot] = None
            self._warn.warn(f"kick_angle{robot}", f"robot_{robot}: rejected kick_angle {angle!r}: an elevation in "
                            f"[0, {MAX_KICK_ANGLE_DEG:g}) deg, please; its kick is no hint to the chip detector")
            return
        self._kick_angles_deg[robot] = float(angle)

    def _on_kick(self, robot: int, msg: Float64) -> None:
        """A kick commanded: a hint for the chip detector at the newest vision stamp (none before the first frame),
        with the commanded speed (weighed by ``kick_speed_std_ratio``)."""
        speed = msg.data
        if not (self._values["kick_hints"] and math.isfinite(speed) and speed > 0.0):
            return
        with self._lock:
            if self._t_vision_s is None or self._kick_angles_deg[robot] is None:
                return
            try:
                self._predictor.kick_hint(self._t_vision_s, self._kick_angles_deg[robot], speed)
            except ValueError as exc:
                self._warn.warn(f"kick{robot}", f"robot_{robot}: kick not taken as a hint: {exc}")

    def _on_vision(self, msg: bytes) -> None:
        """A vision frame and every frame queued behind it: their balls (answered first), then their robots."""
        with self._lock:
            self._vision(msg, self._vision_sub)

    def answer_vision(self, msg: bytes) -> None:
        """One serialized ``/vision/robots`` frame from a receiver in this process (any thread): answered as one
        from the topic, its catch outputs published before this returns."""
        with self._lock:
            self._vision(msg, None)

    def _vision(self, msg: bytes, sub) -> None:
        start = time.perf_counter()
        # The balls are read from their fixed place at the front and answered before the robots are decoded (the
        # decode of 14-22 robots costs about as much as a tenth of the frame's work); a frame not in that form,
        # or whose ball fails the checks, is decoded whole first and refused whole, as before. This frame's
        # balls go first: nothing queued behind it is older.
        leading = vision_leading_points(msg)
        if leading is not None:
            self._leading_balls(start, leading)
        # Cameras deliver in bursts: a ball frame may wait behind other cameras' robot frames, each of which
        # costs a robot decode, tracking and odom publishes. The frames queued behind this one are taken with it
        # and their leading balls answered, in order, before any robots. That stops at a frame not in the
        # ball-first form or with a ball after its robots (another writer's order): from there each frame is
        # answered in turn, so the ball stream keeps the frames' order.
        frames = [(msg, None if leading is None else leading)]
        queued = take_queued(sub) if sub is not None else ()
        balls_first = bool(queued) and leading is not None and not vision_ball_after_robot(msg)
        for data, _info in queued:
            answered = None
            if balls_first:
                leading = vision_leading_points(data)
                balls_first = leading is not None and not vision_ball_after_robot(data)
                if balls_first:
                    self._leading_balls(start, leading)
                    answered = leading
            frames.append((data, answered))
        for data, answered in frames:
            self._frame_rest(start, data, answered)

    def _frame_rest(self, start: float, msg: bytes, answered: LeadingPoints | None) -> None:
        """A frame whose ``answered`` leading points were answered (None: none read yet): the rest of its balls and
        sightings, then its robots."""
        if answered is None:
            answered = vision_leading_points(msg)  # a frame from where the balls stopped going first
            if answered is not None:
                self._leading_balls(start, answered)
        try:
            cloud = vision_cloud_from_msg(msg)
        except ConversionError as exc:
            key = "ball_invalid" if str(exc).startswith(("ball", "camera", "sighting")) else "robots"
            self._warn.warn(key, f"rejected vision/robots: {exc}")  # each throttled on its own
            return
        n_balls, n_sightings = (0, 0) if answered is None else (len(answered.balls), len(answered.sightings))
        if len(cloud.balls) > n_balls or len(cloud.sightings) > n_sightings:  # after the robots (another writer's)
            self._balls(start, LeadingPoints(cloud.t_s, cloud.balls[n_balls:].tolist(), cloud.camera_m,
                                             cloud.sightings[n_sightings:].tolist()))
        if len(cloud.robots):
            self._robots_frame(cloud.t_s, cloud.robots)

    def _leading_balls(self, start: float, leading: LeadingPoints) -> None:
        """A frame's leading balls and sightings (vision_leading_points), in order."""
        if not (leading.balls or leading.sightings):
            return
        # A frame allocates a few hundred objects: a cyclic collection (every few frames; 0.03-1.5 ms) would
        # fall between the vision frame and its catch times in about 1 frame of 25. It is held off until
        # the balls are answered and then runs, if due, at the next allocation.
        collecting = gc.isenabled()
        gc.disable()
        try:
            self._balls(start, leading)
        finally:
            if collecting:
                gc.enable()

    def _balls(self, start: float, points: LeadingPoints) -> None:
        """A frame's balls (the ball's stream), then its camera's sightings (the chip detector's only)."""
        t_s, camera_m = points.t_s, points.camera_m
        try:
            for x, y in points.balls:
                self._ball_frame(start, t_s, x, y, camera_m)
            for x, y in points.sightings:
                self._sighting(t_s, x, y, camera_m)
        finally:
            run_sampled(self._clock_subs)  # after the outputs: not on the latency path

    def _sighting(self, t_s: float, x: float, y: float, camera_m: tuple[float, float, float]) -> None:
        """Another camera's view of an instant the ball's stream has: the chip detector's (the core judges it)."""
        try:
            self._predictor.ball_sighting(t_s, x, y, camera_m)
        except ValueError as exc:
            self._warn.warn("sighting", f"a sighting not taken: {exc}")

    def _robots_frame(self, t_s: float, rows) -> None:
        t_ns = round(t_s * 1e9)
        index = self._core_index
        moved = False
        for team, robot_id, x, y, yaw in rows.tolist():
            robot = index.get((team, robot_id))
            if robot is not None:  # else a robot this node does not serve
                moved = self._robot(robot, t_s, t_ns, x, y, yaw) or moved
        if moved and self._tracked_readers[0]:
            tracked = self._tracked_rows
            try:
                self._tracked_pub.publish(tracked_robots_cdr(
                    [tracked[i] for i in self._predictor.fresh_robots(t_s) if tracked[i] is not None]))
            except ConversionError as exc:
                self._warn.warn("tracked", f"no /robots/tracked for the frame at {t_s:.6f} s: {exc}")

    def _robot(self, robot: int, t_s: float, t_ns: int, x: float, y: float, yaw: float) -> bool:
        """One robot's pose of a frame; True when the tracker took it."""
        verdict = check_stamp(self._robot_stamps[robot], t_ns, self._warn, self._robot_topics[robot], self)
        if verdict is StampVerdict.DROP:
            return False
        tracker = self._predictor.robot_frame(robot, t_s, x, y, yaw, restart=verdict is StampVerdict.RESTART)
        if tracker is None:
            return False
        if self._tracked_readers[0]:
            team, j = self._robots[robot]
            try:
                self._tracked_rows[robot] = tracked_robot_row(team, j, t_s, (*tracker.position_m, tracker.heading_rad),
                                                              (*tracker.velocity_mps, tracker.angular_velocity_radps))
            except ConversionError as exc:
                self._tracked_rows[robot] = None
                self._warn.warn(f"tracked{robot}", f"{self._names[robot]}: not in /robots/tracked: {exc}")
        if not self._odom_readers[robot]:
            return True
        vel = tracker.velocity_mps
        var_pos, var_vel, var_yaw, var_rate = tracker.variances  # the filter's, not an exact state's zeros
        try:
            odom = odometry_cdr(
                t_s, (*tracker.position_m, tracker.heading_rad), (vel[0], vel[1], tracker.angular_velocity_radps),
                child_frame_id=self._robots[robot][0].frame(self._robots[robot][1]), position_variance_m2=var_pos,
                velocity_variance_m2ps2=var_vel, yaw_variance_rad2=var_yaw, yaw_rate_variance_rad2ps2=var_rate,
            )
        except ConversionError as exc:
            self._warn.warn(f"odom{robot}", f"{self._names[robot]}: odom not published: {exc}")
            return True
        self._odom_pubs[robot].publish(odom)
        return True

    def _ball_frame(self, start: float, t_s: float, x: float, y: float,
                    camera_m: tuple[float, float, float] | None) -> None:
        verdict = check_stamp(self._ball_stamps, round(t_s * 1e9), self._warn, "vision/ball", self)
        if verdict is StampVerdict.DROP:
            return
        self._t_vision_s = t_s
        frame = self._predictor.ball_frame(t_s, x, y, restart=verdict is StampVerdict.RESTART, camera_m=camera_m)
        if frame is None:
            return
        # Catch times go out first: they are what the robots act on, and each publish costs tens
        # of microseconds. The AI's table first (all robots in one message), then the per-robot outputs
        # (each while it has a reader); the ball topics follow.
        catch_out = None
        if frame.catch_robots and self._catches_readers[0]:
            try:
                self._catches_pub.publish(self._catch_table(frame))
                catch_out = time.perf_counter()
            except ValueError as exc:
                self._warn.warn("catches", f"no /ball/catches for the frame at {t_s:.6f} s: {exc}")
        try:
            catch_out = self._publish_catch_outputs(frame) or catch_out
        except ValueError as exc:
            self._warn.warn("catch", f"no catch times for the frame at {t_s:.6f} s: {exc}")
        if catch_out is None:  # none went out
            catch_out = time.perf_counter()
        try:
            self._publish_ball_outputs(frame)
        except ValueError as exc:
            self._warn.warn("predict", f"no ball state for the frame at {t_s:.6f} s: {exc}")
        if self._track_readers[0]:
            try:
                self._track_pub.publish(self._ball_track(frame))
            except ValueError as exc:
                self._warn.warn("track", f"no /ball/track for the frame at {t_s:.6f} s: {exc}")
        summary = self._times.add(catch_out - start, time.perf_counter() - start)
        if summary:
            self.get_logger().info(summary)
        if not self._said_compiled and self._predictor.search_compiled:
            self._said_compiled = True  # tools wait for this line: until then a frame costs ~1 ms per robot
            self.get_logger().info(COMPILED_SEARCH_LOADED)
        if self._predictor.identify(frame) is not None:  # a fit finished
            self._publish_model()

    def _publish_ball_outputs(self, frame: BallFrame) -> None:
        """The ball topics (phase, stop point, uncertain: while they have a reader); all are built (and
        checked) before the first goes out."""
        t_s, f = frame.t_s, frame.trajectory.floats
        x, y, z, vx, vy, vz = f.x_m, f.y_m, 0.0, f.vx_mps, f.vy_mps, 0.0
        xyz_cov = vxyz_cov = None
        if frame.chip is not None:  # the chip's state (the flat filter follows where the cameras see it)
            (x, y, z), (vx, vy, vz) = frame.chip.position_m.tolist(), frame.chip.velocity_mps.tolist()
            xyz_cov, vxyz_cov = chip_covariances(frame)
        state = odometry_cdr(t_s, (x, y, 0.0), (vx, vy, 0.0), child_frame_id="ball", z_m=z, vz_mps=vz,
                             position_variance_m2=frame.position_variance_m2, xyz_covariance=xyz_cov,
                             velocity_variance_m2ps2=frame.velocity_variance_m2ps2, vxyz_covariance=vxyz_cov)
        stop_point = point_cdr(t_s, frame.stop_point_m)
        v_shoot = float64_cdr(f.v_shoot_mps)
        self._phase_msg.data = frame.phase
        self._uncertain_msg.data = frame.uncertain
        phase_readers, stop_readers, uncertain_readers = self._tool_readers
        if phase_readers:  # before the state: a receiver rebuilding a chip from it reads both
            self._phase_pub.publish(self._phase_msg)
        self._state_pub.publish(state)
        if stop_readers:
            self._stop_pub.publish(stop_point)
        self._v_shoot_pub.publish(v_shoot)
        if uncertain_readers:
            self._uncertain_pub.publish(self._uncertain_msg)

    @staticmethod
    def _ball_track(frame: BallFrame) -> bytes:
        """/ball/track: what /ball/state, v_shoot, phase and uncertain carry and the observation, in one message."""
        f = frame.trajectory.floats
        if frame.chip is None:
            return ball_track_cdr(BallTrack(frame.t_s, f.x_m, f.y_m, f.vx_mps, f.vy_mps, f.v_shoot_mps, *frame.xy_m,
                                            frame.phase, frame.uncertain))
        x, y, z = frame.chip.position_m.tolist()
        vx, vy, _ = frame.chip.velocity_mps.tolist()
        return ball_track_cdr(BallTrack(frame.t_s, x, y, vx, vy, f.v_shoot_mps, *frame.xy_m, frame.phase,
                                        frame.uncertain, z))

    def _catch_table(self, frame: BallFrame) -> bytes:
        """/ball/catches: every fresh robot's pose at the frame and its catch, one message for both teams
        (an observer such as the field view takes it instead of three topics per robot)."""
        states = self._predictor.robot_states_at(frame.t_s, frame.catch_robots)
        robots = self._robots
        rows = [(robots[i][0].code, robots[i][1], *state, t, *(point if point is not None else (0.0, 0.0)))
                for i, state, t, point in zip(frame.catch_robots, states, frame.catch_times_s, frame.catch_points_m,
                                              strict=True)]
        return table_cdr(rows, contract.CATCH_TABLE_COLUMNS)

    def _publish_catch_outputs(self, frame: BallFrame) -> float | None:
        """catch_time, then catch_point, of every fresh robot (each while it has a reader).

        All values are checked before the first publish (a bad one raises ValueError and nothing
        goes out); the catch times go out before the points are even serialized. Returns when the
        last catch time went out (perf_counter; the last read one: unread ones do not go out), None
        when none went out.
        """
        ids, points = frame.catch_robots, frame.catch_points_m
        if not ids:
            return None
        seconds_to_stamp(frame.t_s)  # the points' stamp
        for point in points:
            if point is not None and not (abs(point[0]) <= MAX_ABS_VALUE and abs(point[1]) <= MAX_ABS_VALUE):
                point_cdr(frame.t_s, point)  # raises, naming the value
        time_data = [float64_cdr(t) for t in frame.catch_times_s]
        time_pubs, time_readers = self._catch_time_pubs, self._time_readers
        published = False
        for i, data in zip(ids, time_data, strict=True):
            if time_readers[i]:
                time_pubs[i].publish(data)
                published = True
        times_out = time.perf_counter() if published else None
        point_pubs, point_readers = self._catch_point_pubs, self._point_readers
        for i, point in zip(ids, points, strict=True):
            if point is not None and point_readers[i]:
                point_pubs[i].publish(point_cdr(frame.t_s, point))
        # The catch outputs' readers are often woken onto this CPU (the scheduler places a wakee
        # beside its waker) and would wait behind the rest of this frame: let them run first.
        os.sched_yield()
        return times_out

    def destroy_node(self) -> None:
        with self._lock:
            if self._predictor is not None:
                self._predictor.close()
        super().destroy_node()


def main(args: list[str] | None = None) -> int:
    return run_node(BallPredictorNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
