"""The field view's core: the newest world state of the graph, and what the page draws of it.

``WorldState`` takes the graph's messages one at a time (``apply(topic, message)``, a message or, for the
types the conversions read from bytes, its CDR bytes) and keeps the newest of each: the ball (true, seen,
filtered), the robots (pose, catch time and point, motor currents, light barrier; ``/ball/catches`` and
``/ball/track`` carry most of it in two messages), the ball model in use, the simulator's events and the
passing game's choice. Opponents under ``/opponent_<id>`` are robots ``o<id>``.

``frame()`` is the page's frame as a JSON-ready dict in field coordinates [m]; ``frame_bytes()`` the same
frame in the compact binary form the live page gets (``FRAME_LAYOUT``, ``decode_frame_bytes``). The
predicted path is the ball model's own BallTrajectory with the predictor's last published parameters, off
the field's wall; the team's receiver is receiver.team_receiver of the catch times. No rclpy here: the node
(field_view_node) feeds it live, ``bag_replay.BagReplay`` from a recorded bag.
"""

from __future__ import annotations

import functools
import json
import math
import struct
from array import array
from collections import deque
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from erforce_ball_model.ball_model import BallModelParams, BallTrajectory, ball_speed
from erforce_ball_model.receiver import team_receiver
from erforce_ball_model.walls import Walls
from erforce_interfaces.wire import contract
from erforce_interfaces.wire.clouds import BallTrack, ball_track_from_msg
from erforce_interfaces.wire.conversions import ConversionError, float64_from_msg, odometry_from_msg, point_from_msg
from erforce_interfaces.wire.robot_config import FieldConfig, RobotConfig
from erforce_interfaces.wire.stamps import StampFilter, StampVerdict
from erforce_interfaces.wire.tables import check_catch_ids, field_from_msg, model_in_use_from_msg, table_from_msg

#: SSL rules: centre circle radius [m] (drawn only).
CENTRE_CIRCLE_RADIUS_M = 0.5
#: Speed above which the model's curve for the speed plot is started anew: a kick or a push [m/s].
KICK_SPEED_JUMP_MPS = 0.3
#: Marks along the predicted path, this far apart in time [s].
PATH_MARK_PERIOD_S = 0.25
#: The binary frame carries this many turns of the path off the walls (the dict frame all of them).
PATH_CORNERS = 6
#: A robot whose newest pose is this much older than the newest in the world is left out [s].
ROBOT_STALE_S = 1.0
#: Live, a stamp this much after the last one is still on the time line [s]: the view samples only the
#: newest message and runs at idle priority, so a starved view sees longer steps than a stream's reader.
STAMP_MAX_JUMP_S = 10.0
#: The team's receiver keeps its role unless another is earlier by this much (as the catchers' default).
RECEIVER_SWITCH_MARGIN_S = 0.1

# Topics the view takes, global and per robot (relative names).
# The stop point is not taken from /ball/stop_point: the view's prediction (the ball model of the
# predictor's state, v_shoot and model) has it, one topic fewer to deliver 70 times a second.
GLOBAL_TOPICS = (
    contract.GROUND_TRUTH_BALL, contract.VISION_BALL, contract.BALL_STATE, contract.BALL_PHASE,
    contract.BALL_V_SHOOT, contract.BALL_UNCERTAIN, contract.BALL_MODEL_PARAMS,
    contract.SIM_EVENTS, contract.BALL_CATCHES, contract.BALL_TRACK, contract.PASS_CHOICE, contract.VISION_FIELD,
)
ROBOT_TOPICS = (
    contract.GROUND_TRUTH_ODOM, contract.ODOM, contract.CATCH_TIME, contract.CATCH_POINT,
    contract.MOTOR_STATUS, contract.GROUND_TRUTH_MOTORS, contract.BALL_DETECTED,
)
#: What /ball/catches carries for every robot at once: a live view takes it instead of these.
CATCH_TABLE_REPLACES = (contract.ODOM, contract.CATCH_TIME, contract.CATCH_POINT)
#: What /ball/track carries at once: a live view takes it instead of these.
TRACK_REPLACES = (contract.VISION_BALL, contract.BALL_STATE, contract.BALL_PHASE, contract.BALL_V_SHOOT,
                  contract.BALL_UNCERTAIN)
#: Unstamped values: a message equal to the last one changes nothing (the node skips it undecoded).
VALUE_TOPICS = (contract.BALL_PHASE, contract.BALL_UNCERTAIN, contract.BALL_V_SHOOT, contract.CATCH_TIME,
                contract.BALL_DETECTED)
#: Types whose CDR bytes the conversions read directly (the others are deserialized first).
BYTES_TYPES = frozenset(t.type_name for t in (contract.GROUND_TRUTH_BALL, contract.VISION_BALL, contract.BALL_V_SHOOT,
                                              contract.BALL_CATCHES, contract.BALL_TRACK))
#: Topics whose messages change the frame's slowly changing part, sent as JSON in the binary frame.
META_TOPICS = (contract.BALL_PHASE, contract.BALL_UNCERTAIN, contract.BALL_MODEL_PARAMS, contract.SIM_EVENTS,
               contract.PASS_CHOICE, contract.VISION_FIELD)
_AVG_CURRENT = contract.MOTOR_STATUS_COLUMNS.index("avg_current_a")
_LIMIT_ACTIVE = contract.MOTOR_STATUS_COLUMNS.index("limit_active")
_CURRENT = contract.GROUND_TRUTH_MOTOR_COLUMNS.index("current_a")
#: The page's key of opponent ``/opponent_<id>`` (our robots are their ids).
OPPONENT_KEY_PREFIX = "o"
RobotKey = int | str


def opponent_key(opponent_id: int) -> str:
    return f"{OPPONENT_KEY_PREFIX}{int(opponent_id)}"


def _robot_order(key: RobotKey) -> tuple[int, int]:
    return (0, key) if isinstance(key, int) else (1, int(key[len(OPPONENT_KEY_PREFIX):]))


@functools.lru_cache(maxsize=4096)
def view_topic(name: str) -> tuple[contract.Topic, RobotKey | None] | None:
    """The contract topic and robot key (None: global; ``o<id>``: an opponent) of an absolute topic name
    the view takes."""
    for topic in GLOBAL_TOPICS:
        if name == topic.name:
            return topic, None
    parts = name.strip("/").split("/", 1)
    if len(parts) == 2:
        robot = contract.robot_id_of_namespace(parts[0])
        if robot is None and (opponent := contract.opponent_id_of_namespace(parts[0])) is not None:
            robot = opponent_key(opponent)
        if robot is not None:
            for topic in ROBOT_TOPICS:
                if parts[1] == topic.name:
                    return topic, robot
    return None


@dataclass(slots=True)
class RobotView:
    """One robot's newest numbers, rounded for the wire as they arrive (see ``_wire``)."""

    robot_id: RobotKey
    t_s: float = -math.inf
    pose: list[float] | None = None  # x, y, yaw [m, rad]
    speed_mps: float = 0.0
    truth: bool = False  # pose from ground truth (else the predictor's tracker, ``odom``)
    catch_time_s: float | None = None  # None: none published; CATCH_TIME_NEVER: never
    catch_point: list[float] | None = None
    avg_current_a: list[float] = field(default_factory=list)
    limit_active: list[bool] = field(default_factory=list)
    current_a: list[float] = field(default_factory=list)
    ball_detected: bool = False


@dataclass
class WorldState:
    """The newest of everything the view shows (see the module docstring)."""

    field: FieldConfig
    current_limit_a: float = RobotConfig().continuous_current_limit_a
    robot_radius_m: float = RobotConfig().robot_radius_m
    opponent_ids: frozenset[int] = frozenset()
    team_ids: frozenset[int] = frozenset()  # the catchers' team that picks a receiver; empty: all but opponents
    t_s: float = 0.0  # newest stamp seen [s]
    ball_truth: tuple[float, float, float, float] | None = None  # x, y, vx, vy
    ball_truth_t_s: float = -math.inf
    ball_seen: tuple[float, float] | None = None
    ball_state: tuple[float, float, float, float] | None = None
    ball_state_t_s: float = -math.inf
    phase: str = "unknown"
    v_shoot_mps: float = 0.0
    uncertain: bool = False
    model: BallModelParams = field(default_factory=BallModelParams)
    robots: dict[int, RobotView] = field(default_factory=dict)
    events: deque = field(default_factory=lambda: deque(maxlen=8))
    receiver: int | None = None
    pass_choice: dict[str, Any] | None = None  # the passing game's, as the page gets it
    rejected: int = 0  # messages refused (bad numbers, mis-shaped, a stamp off the time line)
    # live: the stack's time rule (stamps.py) per stamped input; None in a replay, whose stamps are the bag's
    stamp_filters: dict[str, StampFilter] | None = None
    _speed_model: tuple[float, BallTrajectory] | None = None  # (anchor time, trajectory) for the speed plot
    _meta_serial: int = 0  # moves with every message of META_TOPICS and every refusal
    _meta_cache: tuple[int, bytes] | None = None  # (serial, the binary frame's JSON part)
    # The newest team table (rounded) and the time it came, not yet copied into the robots' views: that
    # waits for a message about one robot or a new time line (``_settle_table``), so that a frame of
    # robots known only from team tables is built from the table in one piece (``frame_bytes``).
    _pending_table: tuple[np.ndarray, float, list[int]] | None = None  # (rows, time, ids)
    _catch_layout: tuple[bytes, int] = (b"", 0)  # /ball/catches: its CDR bytes before the values, their count
    _catch_ids: _CatchIds | None = None  # the robots of the newest team table
    _robots_only_from_tables: bool = True  # no message about one robot yet

    # -------------------------------------------------------------- input
    def apply(self, topic_name: str, msg: Any) -> bool:
        """Take one message of ``topic_name``; False when the view does not take the topic or
        the message was refused (counted in ``rejected``)."""
        found = view_topic(topic_name)
        if found is None:
            return False
        topic, robot = found
        try:
            if robot is None:
                if topic in META_TOPICS:
                    self._meta_serial += 1
                self._apply_global(topic_name, topic, msg)
            else:
                self._settle_table()
                self._robots_only_from_tables = False
                self._apply_robot(topic_name, topic, self.robot(robot), msg)
        except (ConversionError, ValueError, AttributeError, IndexError, TypeError):
            self.rejected += 1
            self._meta_serial += 1
            return False
        return True

    def takes(self, topic_name: str) -> bool:
        """Whether a message of ``topic_name`` would change what the page draws now: a robot's tracked
        pose (odom) does not once its true pose arrives. The node then leaves it untaken, undecoded."""
        found = view_topic(topic_name)
        if found is None:
            return False
        topic, robot = found
        return not (topic is contract.ODOM and robot in self.robots and self.robots[robot].truth)

    def _settle_table(self) -> None:
        """Copy the pending team table into the robots' views (before anything else changes them)."""
        if self._pending_table is None:
            return
        rows, t_s, keys = self._pending_table
        self._pending_table = None
        speeds = np.round(np.hypot(rows[:, 4], rows[:, 5]), 4).tolist()
        robots, never = self.robots, contract.CATCH_TIME_NEVER
        for key, (_id, x, y, yaw, _vx, _vy, catch_s, catch_x, catch_y), speed in zip(keys, rows.tolist(), speeds,
                                                                                    strict=True):
            robot = robots[key]
            if not robot.truth:
                robot.pose, robot.t_s, robot.speed_mps = [x, y, yaw], t_s, speed
            if catch_s >= 0.0:
                robot.catch_time_s, robot.catch_point = catch_s, [catch_x, catch_y]
            else:
                robot.catch_time_s, robot.catch_point = never, None

    def robot(self, robot_id: RobotKey) -> RobotView:
        view = self.robots.get(robot_id)
        if view is None:
            view = self.robots[robot_id] = RobotView(robot_id)
        return view

    def _stamp(self, source: str, t_s: float) -> None:
        """Take ``t_s`` of ``source`` as the newest time, by the time rule when live: a stamp off the
        line raises ValueError (the message is refused); a new time line (a restarted simulator)
        forgets what is newer than it, so the old line's robots and ball neither linger nor hide."""
        if self.stamp_filters is not None:
            stamps = self.stamp_filters.setdefault(source, StampFilter(STAMP_MAX_JUMP_S))
            verdict = stamps.offer(round(t_s * 1e9))
            if verdict is StampVerdict.DROP:
                raise ValueError(f"{source}: {stamps.reason}")
            if verdict is StampVerdict.RESTART and t_s < self.t_s:
                self._settle_table()
                self._restart(t_s)
        self.t_s = max(self.t_s, t_s)

    def _restart(self, t_s: float) -> None:
        self.t_s = t_s
        for robot in self.robots.values():
            if robot.t_s > t_s:
                robot.t_s = -math.inf
        if self.ball_truth_t_s > t_s:
            self.ball_truth, self.ball_truth_t_s = None, -math.inf
        if self.ball_state_t_s > t_s:
            self.ball_state, self.ball_state_t_s, self._speed_model = None, -math.inf, None

    def _apply_global(self, name: str, topic: contract.Topic, msg: Any) -> None:
        c = contract
        if topic is c.GROUND_TRUTH_BALL:
            t, pose, vel, _ = odometry_from_msg(msg)
            self._stamp(name, t)
            self.ball_truth = _wire((pose[0], pose[1], vel[0], vel[1]))
            self.ball_truth_t_s = t
        elif topic is c.VISION_BALL:
            self.ball_seen = _wire(point_from_msg(msg)[1])
        elif topic is c.BALL_STATE:
            t, pose, vel, _ = odometry_from_msg(msg)
            self._stamp(name, t)
            self.ball_state = _wire((pose[0], pose[1], vel[0], vel[1]))
            self.ball_state_t_s = t
            self._update_speed_model(t)
        elif topic is c.BALL_PHASE:
            self.phase = msg.data if msg.data in c.BALL_PHASES else "unknown"
        elif topic is c.BALL_V_SHOOT:
            self.v_shoot_mps = float64_from_msg(msg, limit=100.0)
        elif topic is c.BALL_UNCERTAIN:
            self.uncertain = bool(msg.data)
        elif topic is c.BALL_MODEL_PARAMS:
            self.model = BallModelParams(*model_in_use_from_msg(msg))
            if self._speed_model is not None:  # the curve since the kick goes on with the model in use
                t0, before = self._speed_model
                f = before.floats
                self._speed_model = (t0, BallTrajectory.of_floats(f.x_m, f.y_m, f.vx_mps, f.vy_mps, f.v_shoot_mps,
                                                                  self.model))
        elif topic is c.SIM_EVENTS:
            self.events.append(str(msg.data)[:200])
        elif topic is c.BALL_CATCHES:
            self._apply_catch_table(self._catch_rows(msg))
        elif topic is c.BALL_TRACK:
            self._apply_track(name, ball_track_from_msg(msg))
        elif topic is c.PASS_CHOICE:
            self.pass_choice = _pass_choice(table_from_msg(msg, c.PASS_CHOICE_COLUMNS))
        elif topic is c.VISION_FIELD:  # the world's field (SSL geometry) replaces the preset drawn until then
            self.field = field_from_msg(msg)

    def _apply_track(self, name: str, track: BallTrack) -> None:
        """/ball/track: the ball state, v_shoot, phase, uncertain flag and the observation of one frame."""
        self._stamp(name, track.t_s)
        if track.phase != self.phase or track.uncertain != self.uncertain:
            self.phase, self.uncertain = track.phase, track.uncertain
            self._meta_serial += 1
        self.v_shoot_mps = track.v_shoot_mps  # before the speed model, which starts from it
        self.ball_seen = [round(track.seen_x_m, 4), round(track.seen_y_m, 4)]  # (as _wire: floats already)
        self.ball_state = [round(track.x_m, 4), round(track.y_m, 4), round(track.vx_mps, 4), round(track.vy_mps, 4)]
        self.ball_state_t_s = track.t_s
        self._update_speed_model(track.t_s)

    def _catch_rows(self, msg: Any) -> np.ndarray:
        """The /ball/catches table (tables.table_from_msg). Its CDR bytes up to the values repeat from
        frame to frame while the robots do: once read, a message that starts with the same bytes is read
        as values at the same place, with the same checks on them."""
        header, count = self._catch_layout
        if isinstance(msg, bytes) and count and msg.startswith(header) and 0 <= len(msg) - len(header) - 8 * count < 8:
            values = np.frombuffer(msg, "<f8", count, len(header))
            if np.abs(values).max() <= 1.0e9:  # False for NaN
                return values.reshape(-1, len(contract.CATCH_TABLE_COLUMNS))
        table = table_from_msg(msg, contract.CATCH_TABLE_COLUMNS)  # raises with the reason
        if isinstance(msg, bytes) and table.size:
            # the values start 8-aligned after the 4-byte encapsulation header; up to 7 bytes may pad the end
            start = next(k for k in range(len(msg) - 8 * table.size, len(msg) - 8 * table.size - 8, -1)
                         if (k - 4) % 8 == 0)
            self._catch_layout = (msg[:start], table.size)
        return table

    def _apply_catch_table(self, table: np.ndarray) -> None:
        """Both teams at one ball frame (contract.CATCH_TABLE_COLUMNS): their robots are fresh now."""
        layout = self._catch_ids
        new_layout = layout is None or table[:, :2].tobytes() != layout.ids_bytes
        if new_layout:
            layout = self._catch_ids = _CatchIds(table[:, :2], self.opponent_ids, self.team_ids)
        keys = layout.keys
        if self._pending_table is not None and self._pending_table[2] is not keys \
                and not set(self._pending_table[2]).issubset(keys):
            self._settle_table()  # the one before, for its robots this one does not list
        if new_layout:  # (a robot's view, once made, stays)
            robots = self.robots
            for key in keys:
                if key not in robots:
                    robots[key] = RobotView(key)
        self._pending_table = (np.round(table[:, 1:], 4), self.t_s, keys)

    def _apply_robot(self, name: str, topic: contract.Topic, robot: RobotView, msg: Any) -> None:
        c = contract
        if topic is c.GROUND_TRUTH_ODOM or (topic is c.ODOM and not robot.truth):
            t, pose, vel, _ = odometry_from_msg(msg)
            self._stamp(name, t)
            robot.pose, robot.t_s = _wire(pose), t
            robot.speed_mps = _wire((math.hypot(vel[0], vel[1]),))[0]
            robot.truth = topic is c.GROUND_TRUTH_ODOM
        elif topic is c.CATCH_TIME:
            value = float64_from_msg(msg, limit=1e6)
            robot.catch_time_s = round(value, 4) if value >= 0.0 else c.CATCH_TIME_NEVER
            if value < 0.0:
                robot.catch_point = None
        elif topic is c.CATCH_POINT:
            robot.catch_point = _wire(point_from_msg(msg)[1])
        elif topic is c.MOTOR_STATUS:
            table = table_from_msg(msg, c.MOTOR_STATUS_COLUMNS)
            robot.avg_current_a = _wire(table[:, _AVG_CURRENT])
            robot.limit_active = (table[:, _LIMIT_ACTIVE] != 0.0).tolist()
        elif topic is c.GROUND_TRUTH_MOTORS:
            table = table_from_msg(msg, c.GROUND_TRUTH_MOTOR_COLUMNS)
            robot.current_a = _wire(table[:, _CURRENT])
        elif topic is c.BALL_DETECTED:
            robot.ball_detected = bool(msg.data)

    def _choose_receiver(self) -> None:
        self._settle_table()
        times = {i: r.catch_time_s for i, r in self.robots.items()
                 if r.catch_time_s is not None and isinstance(i, int) and i not in self.opponent_ids
                 and (not self.team_ids or i in self.team_ids)}
        self.receiver = team_receiver(times, self.receiver, RECEIVER_SWITCH_MARGIN_S)

    def _update_speed_model(self, t: float) -> None:
        """Start the model's speed curve anew at a kick: the filtered speed jumped above the curve."""
        x, y, vx, vy = self.ball_state
        speed = math.hypot(vx, vy)
        if self._speed_model is not None:
            t0, trajectory = self._speed_model
            if t >= t0 and speed <= ball_speed(trajectory.floats, t - t0) + KICK_SPEED_JUMP_MPS:
                return
        if speed > KICK_SPEED_JUMP_MPS:
            self._speed_model = (t, BallTrajectory((x, y), (vx, vy), max(self.v_shoot_mps, speed), self.model))
        else:
            self._speed_model = None

    # ------------------------------------------------------------- output
    def prediction(self) -> BallTrajectory | None:
        if self.ball_state is None:
            return None
        x, y, vx, vy = self.ball_state
        try:
            return BallTrajectory((x, y), (vx, vy), self.v_shoot_mps, self.model, Walls.of_field(self.field))
        except ValueError:
            return None

    @staticmethod
    def _moving(trajectory: BallTrajectory | None) -> BallTrajectory | None:
        return trajectory if trajectory is not None and trajectory.floats.stop_time_s > 0.0 else None

    @staticmethod
    def _stop_point(trajectory: BallTrajectory | None) -> list[float] | None:
        """Where the ball comes to rest (the ball model's stop point; where it lies when at rest)."""
        if trajectory is None:
            return None
        return _wire(trajectory.stop_point)

    @staticmethod
    def _path_numbers(trajectory: BallTrajectory) -> tuple[list[float], list[float]]:
        """The path as the page draws it: (start, switch, wall: the first stretch's end, stop) as 8 numbers, the
        first stretch's switch time, end time, speeds at its start, switch and end, and the stop time; then the
        turns off the walls after the first stretch, as x, y pairs."""
        f = trajectory.floats
        switch, end = trajectory.switch_distance_m, f.stop_distance_m
        ends = [f.x_m, f.y_m, f.x_m + f.ux * switch, f.y_m + f.uy * switch, f.x_m + f.ux * end, f.y_m + f.uy * end,
                *trajectory.stop_point.tolist()]
        times = [trajectory.switch_time_s, f.stop_time_s, f.speed_mps, f.v_switch_mps,
                 ball_speed(f, f.stop_time_s) if len(trajectory.pieces) > 1 else 0.0,
                 trajectory.stop_time_s]
        return ends + times, trajectory.bounce_points[1:].ravel().tolist()

    def _shown_robots(self) -> list[RobotView]:
        """The robots the page draws, in id order (ours, then opponents' keys): those with a fresh pose."""
        self._settle_table()
        fresh_after = self.t_s - ROBOT_STALE_S
        shown = [r for r in self.robots.values() if r.pose is not None and r.t_s >= fresh_after]
        if any(isinstance(r.robot_id, str) for r in shown):
            shown.sort(key=lambda r: _robot_order(r.robot_id))
        else:
            shown.sort(key=lambda r: r.robot_id)
        return shown

    def _is_opponent(self, robot_id: RobotKey) -> bool:
        return isinstance(robot_id, str) or robot_id in self.opponent_ids

    def _receiver_now(self) -> tuple[int, list[float], float] | None:
        """(id, target, catch time) of the team's receiver (receiver.team_receiver), or None."""
        self._choose_receiver()
        if self.receiver is not None:
            r = self.robots[self.receiver]
            if r.catch_point is not None:
                return self.receiver, r.catch_point, r.catch_time_s
        return None

    def _speeds(self) -> tuple[float | None, float | None, float | None]:
        """The speed plot's values now: true, filtered and the model's since the kick [m/s] (None: none)."""
        truth = filtered = model = None
        if self.ball_truth is not None:
            truth = round(math.hypot(self.ball_truth[2], self.ball_truth[3]), 4)
        if self.ball_state is not None:
            filtered = round(math.hypot(self.ball_state[2], self.ball_state[3]), 4)
        if self._speed_model is not None and self.ball_state_t_s >= self._speed_model[0]:
            t0, trajectory = self._speed_model
            model = round(ball_speed(trajectory.floats, max(self.t_s - t0, 0.0)), 4)
        return truth, filtered, model

    def _meta(self) -> dict[str, Any]:
        """What changes only with META_TOPICS' messages (and the counts of refusals)."""
        p = self.model
        return {
            "field": {"length": self.field.length_m, "width": self.field.width_m, "boundary": self.field.boundary_m,
                      "centre_circle": CENTRE_CIRCLE_RADIUS_M},
            "robot_radius": self.robot_radius_m,
            "current_limit": self.current_limit_a,
            "model": {"a_slide": p.a_slide_mps2, "a_roll": p.a_roll_mps2, "c_switch": p.c_switch},
            "phase": self.phase,
            "uncertain": self.uncertain,
            "pass": self.pass_choice,
            "events": list(self.events),
            "rejected": self.rejected,
        }

    def frame(self) -> dict[str, Any]:
        """What the page draws now (field coordinates [m], times [s]; JSON-ready)."""
        meta = self._meta()
        ball: dict[str, Any] = {"phase": meta["phase"], "v_shoot": round(self.v_shoot_mps, 4),
                                "uncertain": meta["uncertain"]}
        if self.ball_truth is not None:
            ball["truth"] = self.ball_truth
            ball["truth_t"] = round(self.ball_truth_t_s, 4)
        if self.ball_seen is not None:
            ball["seen"] = self.ball_seen
        if self.ball_state is not None:
            ball["state"] = self.ball_state
        path = None
        prediction = self.prediction()
        trajectory = self._moving(prediction)
        if trajectory is not None:
            numbers, corners = self._path_numbers(trajectory)
            count = min(40, int(trajectory.stop_time_s / PATH_MARK_PERIOD_S))
            marks_t = PATH_MARK_PERIOD_S * np.arange(1, count + 1)
            points = _wire(np.vstack([np.reshape(numbers[:8], (4, 2)), np.reshape(corners, (-1, 2)),
                                      trajectory.position_at(marks_t).reshape(-1, 2)]))
            turns = len(corners) // 2
            switch_time, wall_time, speed, switch_speed, wall_speed, stop_time = (round(v, 4) for v in numbers[8:])
            path = {"start": points[0], "switch": points[1], "wall": points[2], "stop": points[3],
                    "corners": points[4:4 + turns], "marks": points[4 + turns:], "switch_time": switch_time,
                    "wall_time": wall_time, "stop_time": stop_time, "speed": speed, "switch_speed": switch_speed,
                    "wall_speed": wall_speed}
        robots = [{
            "id": r.robot_id,
            "team": "opponent" if self._is_opponent(r.robot_id) else "ours",
            "pose": r.pose,
            "speed": r.speed_mps,
            "truth": r.truth,
            "catch_time": r.catch_time_s,
            "catch_point": None if r.catch_time_s == contract.CATCH_TIME_NEVER else r.catch_point,
            "avg_current": r.avg_current_a,
            "limit_active": r.limit_active,
            "current": r.current_a,
            "ball_detected": r.ball_detected,
        } for r in self._shown_robots()]
        receiver = self._receiver_now()
        speed = {"t": round(self.t_s, 4)}
        for key, value in zip(("truth", "filtered", "model"), self._speeds(), strict=True):
            if value is not None:
                speed[key] = value
        return {
            "t": round(self.t_s, 4),
            "field": meta["field"],
            "robot_radius": meta["robot_radius"],
            "current_limit": meta["current_limit"],
            "model": meta["model"],
            "ball": ball,
            "path": path,
            "stop_point": self._stop_point(prediction),
            "robots": robots,
            "receiver": None if receiver is None else dict(zip(("id", "target", "catch_time"), receiver, strict=True)),
            "pass": meta["pass"],
            "speed": speed,
            "events": meta["events"],
            "rejected": meta["rejected"],
        }

    def frame_bytes(self) -> bytes:
        """The frame as the live page gets it (``FRAME_LAYOUT``): what ``frame()`` holds, the path as its
        ends and speeds (the page puts the marks on it) instead of a list of marks."""
        nan = math.nan
        scalars = [round(self.t_s, 4)]
        scalars += self.ball_truth or _NAN4
        scalars.append(round(self.ball_truth_t_s, 4) if self.ball_truth is not None else nan)
        scalars += self.ball_seen or _NAN2
        scalars += self.ball_state or _NAN4
        prediction = self.prediction()
        scalars += self._stop_point(prediction) or _NAN2
        scalars.append(round(self.v_shoot_mps, 4))
        trajectory = self._moving(prediction)
        if trajectory is None:
            scalars += _NAN_PATH
        else:
            numbers, corners = self._path_numbers(trajectory)
            corners = corners[:2 * PATH_CORNERS]
            scalars += numbers + corners + [math.nan] * (2 * PATH_CORNERS - len(corners))
        scalars += (nan if v is None else v for v in self._speeds())  # placed after the receiver's below
        block = self._table_block()
        if block is not None:
            receiver, cells_array, num_robots, columns = block
            speeds = scalars[-3:]
            scalars[-3:] = _NAN4 if receiver is None else (receiver[0], *receiver[1], receiver[2])
            scalars += speeds
            meta = self._meta_json()
            header = _FRAME_HEADER.pack(FRAME_MAGIC, len(meta), len(scalars), num_robots, columns)
            return b"".join((header, meta, array("d", scalars).tobytes(), cells_array.tobytes()))
        speeds = scalars[-3:]
        receiver = self._receiver_now()
        scalars[-3:] = _NAN4 if receiver is None else (receiver[0], *receiver[1], receiver[2])
        scalars += speeds
        robots = self._shown_robots()
        wheels = max((max(len(r.avg_current_a), len(r.current_a)) for r in robots), default=0)
        columns = len(ROBOT_COLUMNS) + 3 * wheels
        cells: list[float] = []
        never = contract.CATCH_TIME_NEVER
        for r in robots:
            key = r.robot_id
            kind = 2 if isinstance(key, str) else 1 if key in self.opponent_ids else 0
            number = int(key[len(OPPONENT_KEY_PREFIX):]) if kind == 2 else key
            catch_time = nan if r.catch_time_s is None else r.catch_time_s
            catch_point = r.catch_point if r.catch_point is not None and r.catch_time_s != never else _NAN2
            avg, limit, current = r.avg_current_a, r.limit_active, r.current_a
            cells += (kind, number, *r.pose, r.speed_mps, r.truth, catch_time, *catch_point, r.ball_detected,
                      len(avg), len(current))
            if wheels:
                pad = [nan] * wheels
                cells += (avg + pad)[:wheels] + (limit + pad)[:wheels] + (current + pad)[:wheels]
        meta = self._meta_json()
        header = _FRAME_HEADER.pack(FRAME_MAGIC, len(meta), len(scalars), len(robots), columns)
        return b"".join((header, meta, array("d", scalars).tobytes(), array("f", cells).tobytes()))

    def _table_block(self) -> tuple[tuple[int, list[float], float] | None, np.ndarray, int, int] | None:
        """(receiver, robot rows as float32, robots, columns) of ``frame_bytes`` straight from the pending team
        table, when every robot known came only from team tables and this one lists them all (the usual
        live case without a simulator's ground truth); else None."""
        if self._pending_table is None or not self._robots_only_from_tables:
            return None
        rows, t_s, ids = self._pending_table
        if len(ids) != len(self.robots):
            return None  # a robot of an earlier table is not in this one
        layout = self._catch_ids
        if layout.order is not None:
            rows = rows[layout.order]
        catch_s = rows[:, 6].tolist()
        self.receiver = team_receiver({layout.sorted_keys[k]: catch_s[k] for k in layout.receiver_rows},
                                      self.receiver, RECEIVER_SWITCH_MARGIN_S)
        receiver = None
        if self.receiver is not None:
            k = layout.sorted_keys.index(self.receiver)
            receiver = (self.receiver, rows[k, 7:9].tolist(), catch_s[k])
        if t_s < self.t_s - ROBOT_STALE_S:
            return receiver, np.empty(0, np.float32), 0, len(ROBOT_COLUMNS)
        # as few numpy calls as can be (each costs more than its work on 22 rows): the table's columns id ..
        # catch_y land on the cells' id .. catch_y at once, then the speed and truth columns get theirs
        cells = layout.cells.copy()  # kinds set, the rest 0
        cells[:, 1:10] = rows
        cells[:, 5] = np.round(np.hypot(rows[:, 4], rows[:, 5]), 4)
        cells[:, 6] = 0.0
        if min(catch_s) < 0.0:
            never = rows[:, 6] < 0.0
            cells[never, 7:10] = (contract.CATCH_TIME_NEVER, np.nan, np.nan)
        return receiver, cells, len(rows), len(ROBOT_COLUMNS)

    def _meta_json(self) -> bytes:
        """``_meta()`` as UTF-8 JSON padded with spaces to a multiple of 8 bytes; encoded again only when
        a message of META_TOPICS (or a refusal) came since."""
        if self._meta_cache is None or self._meta_cache[0] != self._meta_serial:
            text = json.dumps(self._meta(), separators=(",", ":"), allow_nan=False).encode()
            self._meta_cache = (self._meta_serial, text + b" " * (-len(text) % 8))
        return self._meta_cache[1]


class _CatchIds:
    """The robots of a /ball/catches table (its team and id columns), checked and laid out once for as
    long as the tables list the same robots: their keys in the table's order, and for the binary frame
    the order by key, each one's kind and the rows of the team that picks a receiver."""

    def __init__(self, team_and_id: np.ndarray, opponent_ids: frozenset[int], team_ids: frozenset[int]) -> None:
        self.ids_bytes = team_and_id.tobytes()
        check_catch_ids(team_and_id)  # finite (table_from_msg)
        teams, id_list = team_and_id[:, 0].tolist(), team_and_id[:, 1].tolist()
        ours = contract.OURS.code
        self.keys: list[RobotKey] = [int(i) if t == ours else opponent_key(int(i))
                                     for t, i in zip(teams, id_list, strict=True)]
        order = sorted(range(len(self.keys)), key=lambda k: _robot_order(self.keys[k]))
        self.order = None if order == list(range(len(order))) else order
        self.sorted_keys = [self.keys[k] for k in order]
        self.kinds = np.array([2 if isinstance(i, str) else 1 if i in opponent_ids else 0 for i in self.sorted_keys],
                              np.float32)
        self.cells = np.zeros((len(self.keys), len(ROBOT_COLUMNS)), np.float32)
        self.cells[:, 0] = self.kinds
        self.receiver_rows = [k for k, i in enumerate(self.sorted_keys) if isinstance(i, int)
                              and i not in opponent_ids and (not team_ids or i in team_ids)]
        self.receiver_ids = [self.sorted_keys[k] for k in self.receiver_rows]


#: The binary frame (little-endian): a header, the JSON of what changes slowly (``WorldState._meta``),
#: then SCALARS as float64 and a row of float32 per robot (ROBOT_COLUMNS, then per wheel the average
#: current [A], the limit flag and the current [A] as three blocks of ``wheels`` each). NaN: none.
FRAME_LAYOUT = "header (magic, JSON bytes, scalars, robots, robot columns: 5 x uint32), JSON, scalars, robots"
FRAME_MAGIC = b"EFV1"
_FRAME_HEADER = struct.Struct("<4sIIII4x")  # 24 bytes: the float64 block starts 8-aligned after the padded JSON
SCALARS = ("t", "truth_x", "truth_y", "truth_vx", "truth_vy", "truth_t", "seen_x", "seen_y", "state_x", "state_y",
           "state_vx", "state_vy", "stop_x", "stop_y", "v_shoot", "path_x", "path_y", "switch_x", "switch_y",
           "wall_x", "wall_y", "end_x", "end_y", "switch_time", "wall_time", "path_speed", "switch_speed",
           "wall_speed", "stop_time", *(f"corner{k}_{a}" for k in range(PATH_CORNERS) for a in "xy"), "receiver",
           "target_x", "target_y", "receiver_catch_time", "speed_truth", "speed_filtered", "speed_model")
#: kind: 0 ours, 1 an opponent among ``opponent_ids``, 2 an opponent ``/opponent_<id>`` (key ``o<id>``).
ROBOT_COLUMNS = ("kind", "id", "x", "y", "yaw", "speed", "truth", "catch_time", "catch_x", "catch_y",
                 "ball_detected", "avg_current_count", "current_count")
_NAN2, _NAN4 = (math.nan,) * 2, (math.nan,) * 4
_NAN_PATH = (math.nan,) * (SCALARS.index("receiver") - SCALARS.index("path_x"))


def decode_frame_bytes(data: bytes) -> dict[str, Any]:
    """A binary frame (``WorldState.frame_bytes``) as the dict the page builds of it (web/field_view.js
    decodeFrame does the same): ``frame()``'s keys, the path without its marks. Raises ValueError."""
    if len(data) < _FRAME_HEADER.size or data[:4] != FRAME_MAGIC:
        raise ValueError("not a field view frame")
    _, meta_len, num_scalars, num_robots, columns = _FRAME_HEADER.unpack_from(data)
    start = _FRAME_HEADER.size
    scalars_at = start + meta_len
    robots_at = scalars_at + 8 * num_scalars
    if num_scalars != len(SCALARS) or len(data) != robots_at + 4 * num_robots * columns:
        raise ValueError("a field view frame of the wrong size")
    frame = json.loads(data[start:scalars_at])
    s = dict(zip(SCALARS, np.frombuffer(data, "<f8", num_scalars, scalars_at).tolist(), strict=True))

    def pair(a: str, b: str) -> list[float] | None:
        return None if math.isnan(s[a]) else [s[a], s[b]]

    frame["t"] = s["t"]
    ball = {"phase": frame.pop("phase"), "uncertain": frame.pop("uncertain"), "v_shoot": s["v_shoot"]}
    if not math.isnan(s["truth_x"]):
        ball["truth"] = [s["truth_x"], s["truth_y"], s["truth_vx"], s["truth_vy"]]
        ball["truth_t"] = s["truth_t"]
    if not math.isnan(s["seen_x"]):
        ball["seen"] = pair("seen_x", "seen_y")
    if not math.isnan(s["state_x"]):
        ball["state"] = [s["state_x"], s["state_y"], s["state_vx"], s["state_vy"]]
    frame["ball"] = ball
    frame["stop_point"] = pair("stop_x", "stop_y")
    corners = [pair(f"corner{k}_x", f"corner{k}_y") for k in range(PATH_CORNERS)]
    frame["path"] = None if math.isnan(s["path_x"]) else {
        "start": pair("path_x", "path_y"), "switch": pair("switch_x", "switch_y"), "wall": pair("wall_x", "wall_y"),
        "stop": pair("end_x", "end_y"), "corners": [c for c in corners if c is not None],
        **{k: s[k] for k in ("switch_time", "wall_time", "stop_time", "switch_speed", "wall_speed")},
        "speed": s["path_speed"]}
    frame["receiver"] = None if math.isnan(s["receiver"]) else {
        "id": int(s["receiver"]), "target": pair("target_x", "target_y"), "catch_time": s["receiver_catch_time"]}
    frame["speed"] = {"t": s["t"], **{k: s[f"speed_{k}"] for k in ("truth", "filtered", "model")
                                      if not math.isnan(s[f"speed_{k}"])}}
    rows = np.frombuffer(data, "<f4", num_robots * columns, robots_at).reshape(num_robots, columns).tolist()
    wheels = (columns - len(ROBOT_COLUMNS)) // 3
    robots = []
    for row in rows:
        r = dict(zip(ROBOT_COLUMNS, row, strict=False))
        kind, number = int(r["kind"]), int(r["id"])
        extra = row[len(ROBOT_COLUMNS):]
        avg_n, cur_n = int(r["avg_current_count"]), int(r["current_count"])
        robots.append({
            "id": opponent_key(number) if kind == 2 else number,
            "team": "ours" if kind == 0 else "opponent",
            "pose": [r["x"], r["y"], r["yaw"]],
            "speed": r["speed"],
            "truth": bool(r["truth"]),
            "catch_time": None if math.isnan(r["catch_time"]) else r["catch_time"],
            "catch_point": None if math.isnan(r["catch_x"]) else [r["catch_x"], r["catch_y"]],
            "avg_current": extra[:avg_n],
            "limit_active": [bool(v) for v in extra[wheels:wheels + avg_n]],
            "current": extra[2 * wheels:2 * wheels + cur_n],
            "ball_detected": bool(r["ball_detected"]),
        })
    frame["robots"] = robots
    return frame


def _pass_choice(table: np.ndarray) -> dict[str, Any] | None:
    """A /pass/choice table (contract.PASS_CHOICE_COLUMNS) as the page draws it; no row: no choice."""
    if len(table) == 0:
        return None
    if len(table) != 1:
        raise ValueError(f"/pass/choice has {len(table)} rows, expected one or none")
    row = dict(zip(contract.PASS_CHOICE_COLUMNS, _wire(table[0]), strict=True))
    ids = (row["passer_id"], row["receiver_id"])
    if any(i < 0 or i != int(i) for i in ids) or row["first_opponent"] != int(row["first_opponent"]):
        raise ValueError("/pass/choice: robot ids must be whole numbers, ours >= 0")
    nobody = row["first_opponent"] < 0  # no opponent can catch the pass
    return {
        "passer": int(row["passer_id"]),
        "receiver": int(row["receiver_id"]),
        "kick_speed": row["kick_speed_mps"],
        "direction": row["direction_rad"],
        "receiver_catch": row["receiver_catch_s"],
        "first_opponent": None if nobody else opponent_key(int(row["first_opponent"])),
        "opponent_catch": None if nobody else row["opponent_catch_s"],
        "margin": None if nobody else row["margin_s"],
        "safe_margin": row["safe_margin_s"],
        "safe": row["safe"] != 0.0,
    }


def _wire(values) -> list:
    """Numbers as the page gets them: plain floats rounded to 0.1 mm / 0.1 ms (JSON has no NaN, and the
    conversions let none in). Many values in one numpy call: round() per value cost more than the
    rest of a frame; a few in Python, where numpy's call overhead is the larger."""
    if isinstance(values, np.ndarray) and (values.ndim > 1 or values.size > 8):
        return np.round(values.astype(float), 4).tolist()
    return [round(float(v), 4) for v in values]


