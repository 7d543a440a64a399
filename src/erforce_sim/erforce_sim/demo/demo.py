"""``./run demo``: the main job, the passing game on the 14-robot graph (``--scenario passing``, the
default: erforce_sim.demo.passing_report), or the paper's story end to end (``--scenario scenes``,
this module).

The scenes launch launch/demo.launch.yaml (plant, ball_predictor, robot_0's velocity_controller,
motor_boards and catcher; robot_1 is the kicker), records every topic into a rosbag2/MCAP
bag, and plays a scene sequence through the plant's scenario topics:

1. the paper's Fig. 6: robot_0 at rest, the ball rolling right at 2.0 m/s, caught facing left;
2. kicks from 1 to 6.5 m/s by robot_1 (curved plate): some straight at robot_0, some passing
   it at a distance, one off the side wall.

For each scene it prints the predicted catch time against the actual one (the rising edge
of robot_0's light barrier), and whether the ball was caught. The prediction compared is
the ball predictor's newest one made at least 0.3 s before the contact (a useful lead for
a receiver); for a ball that was not caught, the one made 0.3 s after the kick. A scene counts as reachable
when the ball's true path (ground truth) passes a point robot_0 could have reached in
time under the planning limits (robotTimeToPos from its start, after a reaction delay),
independent of the predictor. At the end it writes report/<time>/: the bag, PNG plots and
summary.md (see erforce_sim.demo.report).
"""

from __future__ import annotations

import argparse
import bisect
import math
import os
import socket
import struct
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import rclpy
from geometry_msgs.msg import PointStamped
from nav_msgs.msg import Odometry
from rclpy.qos import HistoryPolicy, QoSProfile
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Bool, Float64, Float64MultiArray

from erforce_ball_model.catch_time import ROBOT_A_MAX_MPS2, ROBOT_V_MAX_MPS, RobotLimits
from erforce_interfaces.runtime.executor import DirectExecutor, run_sampled, sample_only
from erforce_interfaces.runtime.param_schema import schema_defaults
from erforce_interfaces.ssl.ssl_vision import SSL_VISION_GROUP, SslDecodeError, decode_wrapper
from erforce_interfaces.tools.processes import free_udp_port, idle_priority, spawn_in_session, stop_process
from erforce_interfaces.wire import contract
from erforce_interfaces.wire.conversions import (
    odometry_from_msg,
    odometry_msg,
    seconds_to_stamp,
    stamp_to_nanoseconds,
    stamp_to_seconds,
)
from erforce_interfaces.wire.robot_config import FIELD_PRESET, TEAM_SIZE, FieldConfig, RobotConfig
from erforce_interfaces.wire.tables import table_from_msg
from erforce_sim.demo.view_process import start_field_view
from erforce_sim.in_process.scenes import (
    KICKER,
    PREDICTION_LEAD_S,
    RECEIVER,
    TEAMMATE_POSES,
    Scene,
    compared_prediction,
    default_scenes,
    reachable,
)

_PLANT, _VIEW = schema_defaults("erforce_sim", "plant"), schema_defaults("erforce_sim", "field_view")

LAUNCH_FILE = Path(__file__).resolve().parents[2] / "launch" / "demo.launch.yaml"


@dataclass
class SceneResult:
    scene: Scene
    t_start_s: float
    t_end_s: float
    predicted_s: float | None  # absolute sim time of the predicted catch; None = "never"
    actual_s: float | None  # light barrier rising edge; None = not caught
    reachable: bool = False
    kick_fired: bool = True
    caught_by: int | None = None  # the receiver whose light barrier fired

    @property
    def caught(self) -> bool:
        return self.actual_s is not None

    @property
    def caught_text(self) -> str:
        if not self.caught:
            return "no"
        return "yes" if self.caught_by in (None, RECEIVER) else f"yes, robot_{self.caught_by}"

    @property
    def error_s(self) -> float | None:
        if self.predicted_s is None or self.actual_s is None:
            return None
        return self.predicted_s - self.actual_s


@dataclass
class Series:
    """Time series the report needs, gathered while the demo runs (the bag has everything too)."""

    ball_truth: list = field(default_factory=list)  # t, x, y, vx, vy
    robot_truth: list = field(default_factory=list)  # t, x, y, yaw, vx, vy, w
    motors: list = field(default_factory=list)  # t, currents(4), temps(4), speeds(4)
    motor_status: list = field(default_factory=list)  # t, avg current(4), pwm limit(4)
    ball_state: list = field(default_factory=list)  # t, x, y, vx, vy
    v_shoot: list = field(default_factory=list)  # t, v_shoot
    predictions: list = field(default_factory=list)  # robot_0's: obs t, catch time (relative)
    teammate_predictions: dict = field(default_factory=dict)  # robot id -> the same, for --receivers > 1
    teammate_truth: dict = field(default_factory=dict)  # robot id -> rows like robot_truth
    catch_points: list = field(default_factory=list)  # obs t, x, y
    model_params: list = field(default_factory=list)  # t, a_slide, a_roll, c_switch of the model in use
    vision_sent_ns: dict = field(default_factory=dict)  # vision stamp -> DDS source timestamp (plant's send)
    # Inside the graph, from DDS source timestamps: the plant sends a vision frame -> the predictor
    # sends robot_0's catch time for it (the target) / its catch point (after all catch times).
    catch_time_latency_s: list = field(default_factory=list)
    catch_point_latency_s: list = field(default_factory=list)


def _truth_row(msg: Odometry) -> tuple:
    """A robot's ground truth as Series keeps it: t, x, y, yaw, vx, vy, w."""
    t, pose, vel, _ = odometry_from_msg(msg)
    return (t, *pose, *vel)


class Director:
    """The scenario player: places bodies, kicks, watches; its node spins on ``executor``.

    It watches without an executor wake per message: its subscriptions are sampled
    (erforce_interfaces.runtime.executor.sample_only), and ``pump()`` (called while it waits) runs their
    listeners for everything queued, in the order it was sent (DDS source timestamps). One wake
    per message made this observer the third busiest process of the demo (~20 % of a core at
    ~900 messages/s), and being a normal-priority process it preempted the simulated world and
    the predictor on each one.

    ``graph_alive`` is asked while waiting, so a dead graph fails fast with ``graph_hint``.
    Tests drive scenes with it as the demo does.
    """

    FEED_DEPTH = 1000  # messages a topic may queue between two pumps (10 s of the fastest, 100 Hz)

    def __init__(self, node, robot: RobotConfig, executor, graph_alive=lambda: True, graph_hint: str = "",
                 receivers: int = 1) -> None:
        if not 1 <= receivers <= 1 + len(TEAMMATE_POSES):
            raise ValueError(f"receivers: 1 to {1 + len(TEAMMATE_POSES)}, got {receivers!r}")
        self.node = node
        self.robot = robot
        self.executor = executor
        self._graph_alive = graph_alive
        self._graph_hint = graph_hint
        self.receivers = (RECEIVER, *list(TEAMMATE_POSES)[: receivers - 1])
        self.sim_ns = -1
        self.series = Series()
        # Rising edges of any receiver's light barrier, in simulated time: each the newest time the plant had sent
        # before it (its /clock or ground truth), and (that, the oldest it sent after) in barrier_edge_bounds_s.
        self.barrier_edges: list[float] = []
        self.barrier_edge_bounds_s: list[tuple[float, float]] = []
        self.edge_robots: list[int] = []  # whose, per edge
        self._edges_sent_ns: list[int] = []  # each edge's DDS source timestamp
        self._unsettled_edges: list[int] = []
        # per stamped plant stream: the source timestamps and simulated times [ns] of its newest messages
        self._plant_times: dict[str, tuple[list[int], list[int]]] = {}
        self._barrier = dict.fromkeys(self.receivers, False)
        self.events: list[str] = []
        self.commanded: set[int] = set()  # receivers whose catcher has sent a cmd_vel
        self.setpoints_seen = False  # robot_0's velocity controller has answered a tick
        q = contract
        self._feeds = []
        feed = self._feed
        feed(q.GROUND_TRUTH_BALL, self._on_ball_truth)
        feed(q.GROUND_TRUTH_ODOM, self._on_robot_truth, RECEIVER)
        feed(q.GROUND_TRUTH_MOTORS, self._on_motors, RECEIVER)
        feed(q.MOTOR_STATUS, self._on_status, RECEIVER)
        feed(q.BALL_STATE, self._on_ball_state)
        feed(q.BALL_V_SHOOT, self._on_v_shoot)
        feed(q.BALL_MODEL_PARAMS, self._on_params)
        feed(q.CATCH_TIME, self._on_catch_time, RECEIVER)
        feed(q.CATCH_POINT, self._on_catch_point, RECEIVER)
        self._teammate_catch_time: dict[int, float] = {}
        for r in self.receivers:
            feed(q.BALL_DETECTED, lambda m, info, r=r: self._on_barrier(r, m, info), r)
            feed(q.CMD_VEL, lambda _m, r=r: self.commanded.add(r), r)
            if r != RECEIVER:
                self.series.teammate_predictions[r] = []
                self.series.teammate_truth[r] = []
                feed(q.GROUND_TRUTH_ODOM, lambda m, r=r: self.series.teammate_truth[r].append(_truth_row(m)), r)
                feed(q.CATCH_TIME, lambda m, r=r: self._on_teammate_catch_time(r, m), r)
                feed(q.CATCH_POINT, lambda m, r=r: self._on_teammate_catch_point(r, m), r)
        # robot_0's velocity controller answers (500 Hz: dropped once seen, see pump)
        self._setpoints_feed = feed(q.WHEEL_SETPOINTS, self._on_setpoints, RECEIVER)
        feed(q.SIM_EVENTS, lambda m: self.events.append(m.data))
        feed(q.VISION_ROBOTS, self._on_vision)  # a vision frame: its ball and robots
        # /clock is taken last, so every clock sent before a message taken in the same pump is
        # there too: a message's simulated time is that of the newest clock sent before it.
        feed(q.CLOCK, self._on_clock)
        self.set_ball = node.create_publisher(Odometry, q.SIM_SET_BALL.name, q.SIM_SET_BALL.qos)
        self.set_robot = {
            i: node.create_publisher(Odometry, q.SIM_SET_STATE.for_robot(i), q.SIM_SET_STATE.qos)
            for i in (*self.receivers, KICKER)
        }
        self.kick = node.create_publisher(Float64, q.KICK.for_robot(KICKER), q.KICK.qos)
        self._last_catch_time: float | None = None
        self._catch_time_sent_ns: int | None = None
        # When vision enters the graph elsewhere (--vision ssl): the time its frame was sent, by stamp
        self.vision_sent_ns_of: Callable[[int], int | None] | None = None

    def _feed(self, topic: contract.Topic, listener: Callable, robot: int | None = None):
        """A sampled subscription to a contract topic (of ``robot``), with a deep queue."""
        deep = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=self.FEED_DEPTH, reliability=topic.qos.reliability,
                          durability=topic.qos.durability)
        name = topic.name if robot is None else topic.for_robot(robot)
        sub = sample_only(self.node.create_subscription(topic.msg_type, name, listener, deep))
        self._feeds.append(sub)
        return sub

    def pump(self) -> int:
        """Run the listeners for everything that arrived, oldest sent first; returns how many."""
        ran = run_sampled(self._feeds)
        self._settle_edges()
        if self.setpoints_seen and self._setpoints_feed is not None:
            self._feeds.remove(self._setpoints_feed)
            self.node.destroy_subscription(self._setpoints_feed)
            self._setpoints_feed = None
        return ran

    def close(self) -> None:
        for sub in self._feeds:
            self.node.destroy_subscription(sub)
        self._feeds = []

    @property
    def sim_s(self) -> float:
        return self.sim_ns * 1e-9

    def graph_ready(self) -> bool:
        """Time runs, the predictor answers, robot_0's catcher commands and its velocity controller answers.

        The plant starts once the motor boards answer and two readers take wheel_states; a recorder
        can be the second one, and a velocity controller still starting then leaves robot_0 deaf to
        the catcher (the Fig. 6 scene went uncaught that way). A catcher whose publisher exists need not
        act yet either: its timer runs on simulated time, so it commands nothing until its /clock
        subscription has matched the plant's.
        """
        return (self.sim_ns > 0 and bool(self.series.ball_state) and self.commanded == set(self.receivers)
                and self.setpoints_seen)

    # ---------------------------------------------------- light barrier edges
    # A Bool carries no stamp, and the plant sends it from the thread that sends /clock and ground truth; so an
    # edge happened after the newest of those sent before it and by the oldest sent after it (DDS source
    # timestamps: the plant's clock at each send). Delivery across topics keeps no order, and a loaded reader
    # can miss messages of a shallow writer (/clock keeps one), so the time this observer took the edge says
    # nothing: an edge settles once every stamped stream has brought a message sent after it.
    _PLANT_TIMES_KEPT = 4096

    def _note_plant_time(self, stream: str, sent_ns: int, sim_ns: int) -> None:
        sent, sim = self._plant_times.setdefault(stream, ([], []))
        sent.append(sent_ns)  # one writer's messages arrive in the order it sent them
        sim.append(sim_ns)
        if len(sent) > 2 * self._PLANT_TIMES_KEPT:
            del sent[: -self._PLANT_TIMES_KEPT], sim[: -self._PLANT_TIMES_KEPT]

    def _edge_bounds_ns(self, edge_sent_ns: int) -> tuple[int, int] | None:
        """(newest simulated time sent before the edge, oldest sent after it), or None until every stream that
        flows has sent one after it."""
        lower, upper = -1, None
        for sent, sim in self._plant_times.values():
            k = bisect.bisect_right(sent, edge_sent_ns)
            if k == len(sent):
                return None
            lower = max(lower, sim[k - 1]) if k else lower
            upper = sim[k] if upper is None else min(upper, sim[k])
        return None if upper is None else (lower, upper)

    def _settle_edges(self) -> None:
        still = []
        for k in self._unsettled_edges:
            bounds = self._edge_bounds_ns(self._edges_sent_ns[k])
            if bounds is None:
                still.append(k)
                continue
            lower_ns = bounds[0] if bounds[0] >= 0 else bounds[1]
            self.barrier_edges[k] = lower_ns * 1e-9
            self.barrier_edge_bounds_s[k] = (lower_ns * 1e-9, bounds[1] * 1e-9)
        self._unsettled_edges = still

    def edges_settled(self) -> bool:
        """Every light barrier edge has its simulated time (see ``barrier_edges``)."""
        return not self._unsettled_edges

    # ------------------------------------------------------------ listeners
    def _on_clock(self, msg: Clock, info) -> None:
        self.sim_ns = stamp_to_nanoseconds(msg.clock)
        self._note_plant_time("clock", info["source_timestamp"], self.sim_ns)

    def _on_ball_truth(self, msg: Odometry, info) -> None:
        t, pose, vel, _ = odometry_from_msg(msg)
        self.series.ball_truth.append((t, pose[0], pose[1], vel[0], vel[1]))
        self._note_plant_time("ball", info["source_timestamp"], stamp_to_nanoseconds(msg.header.stamp))

    def _on_robot_truth(self, msg: Odometry, info) -> None:
        self.series.robot_truth.append(_truth_row(msg))
        self._note_plant_time("robot", info["source_timestamp"], stamp_to_nanoseconds(msg.header.stamp))

    def _on_motors(self, msg: Float64MultiArray) -> None:
        table = table_from_msg(msg, contract.GROUND_TRUTH_MOTOR_COLUMNS)
        self.series.motors.append((self.sim_s, *table[:, 0], *table[:, 1], *table[:, 2]))

    def _on_status(self, msg: Float64MultiArray) -> None:
        table = table_from_msg(msg, contract.MOTOR_STATUS_COLUMNS)
        self.series.motor_status.append((self.sim_s, *table[:, 0], *table[:, 1]))

    def _on_ball_state(self, msg: Odometry) -> None:
        t, pose, vel, _ = odometry_from_msg(msg)
        self.series.ball_state.append((t, pose[0], pose[1], vel[0], vel[1]))

    def _on_v_shoot(self, msg: Float64) -> None:
        self.series.v_shoot.append((self.sim_s, msg.data))

    def _on_params(self, msg: Float64MultiArray) -> None:
        if len(msg.data) >= 3:
            self.series.model_params.append((self.sim_s, *msg.data[:3]))

    def _on_catch_time(self, msg: Float64, info) -> None:
        self._last_catch_time = msg.data
        self._catch_time_sent_ns = info["source_timestamp"]
        if msg.data == contract.CATCH_TIME_NEVER and self.series.ball_state:
            # no catch point comes with "never": the predictor sent this cycle's ball state first
            self.series.predictions.append((self.series.ball_state[-1][0], msg.data))

    def _on_catch_point(self, msg: PointStamped, info) -> None:
        t_obs = stamp_to_seconds(msg.header.stamp)
        if self._last_catch_time is not None:
            self.series.predictions.append((t_obs, self._last_catch_time))
        self.series.catch_points.append((t_obs, msg.point.x, msg.point.y))
        # Latency inside the graph from the DDS source timestamps (the senders' clocks): not
        # skewed by how late this observer gets to its queue. The predictor sends a frame's catch
        # time just before its catch point, which carries the frame's stamp.
        stamp_ns = stamp_to_nanoseconds(msg.header.stamp)
        sent = self.series.vision_sent_ns.pop(stamp_ns, None)
        if self.vision_sent_ns_of is not None:
            # by the frame's arrival alone: a frame's /vision/robots may go out after its catch outputs
            # (ssl_ball_predictor), so it need not have come in first
            sent = self.vision_sent_ns_of(stamp_ns)
        point_sent = info["source_timestamp"]
        if sent is not None:
            self.series.catch_point_latency_s.append((point_sent - sent) * 1e-9)
            time_sent = self._catch_time_sent_ns
            if time_sent is not None and sent < time_sent <= point_sent:
                self.series.catch_time_latency_s.append((time_sent - sent) * 1e-9)

    def _on_teammate_catch_time(self, robot: int, msg: Float64) -> None:
        self._teammate_catch_time[robot] = msg.data
        if msg.data == contract.CATCH_TIME_NEVER and self.series.ball_state:
            self.series.teammate_predictions[robot].append((self.series.ball_state[-1][0], msg.data))

    def _on_teammate_catch_point(self, robot: int, msg: PointStamped) -> None:
        t = self._teammate_catch_time.get(robot)
        if t is not None:
            self.series.teammate_predictions[robot].append((stamp_to_seconds(msg.header.stamp), t))

    def _on_vision(self, msg, info) -> None:
        stamp_ns = stamp_to_nanoseconds(msg.header.stamp)
        sent_ns = info["source_timestamp"] if self.vision_sent_ns_of is None else self.vision_sent_ns_of(stamp_ns)
        if sent_ns is None:
            return
        self.series.vision_sent_ns.setdefault(stamp_ns, sent_ns)  # the ball's frame; other cameras' follow it
        if len(self.series.vision_sent_ns) > 1000:
            self.series.vision_sent_ns.pop(next(iter(self.series.vision_sent_ns)))

    def _on_setpoints(self, _msg) -> None:
        self.setpoints_seen = True

    def _on_barrier(self, robot: int, msg: Bool, info) -> None:
        if msg.data and not self._barrier[robot]:
            self.barrier_edges.append(self.sim_s)  # until it settles
            self.barrier_edge_bounds_s.append((self.sim_s, math.inf))
            self.edge_robots.append(robot)
            self._edges_sent_ns.append(info["source_timestamp"])
            self._unsettled_edges.append(len(self.barrier_edges) - 1)
        self._barrier[robot] = bool(msg.data)

    # ------------------------------------------------------------- actions
    def place_robot(self, robot: int, pose) -> None:
        self.set_robot[robot].publish(odometry_msg(0.0, pose, (0.0, 0.0, 0.0)))

    def place_ball(self, x: float, y: float, vx: float = 0.0, vy: float = 0.0) -> None:
        self.set_ball.publish(odometry_msg(0.0, (x, y, 0.0), (vx, vy, 0.0)))

    def receiver_speed(self) -> float:
        """Speed of robot_0 from the newest ground truth [m/s] (teammates are placed at rest and hold)."""
        if not self.series.robot_truth:
            return math.inf
        _, _, _, _, vx, vy, w = self.series.robot_truth[-1]
        return math.hypot(vx, vy) + abs(w) * self.robot.robot_radius_m

    def ball_at_kicker(self, kicker_pose) -> tuple[float, float]:
        d = self.robot.dribbler_offset_m + 0.002
        return kicker_pose[0] + d * math.cos(kicker_pose[2]), kicker_pose[1] + d * math.sin(kicker_pose[2])

    # ------------------------------------------------------------- scenes
    def spin_until(self, condition, timeout_wall_s: float, what: str) -> bool:
        deadline = time.monotonic() + timeout_wall_s
        self.pump()
        while not condition():
            if time.monotonic() > deadline:
                return False
            if not self._graph_alive():
                raise RuntimeError(f"the node graph exited while waiting for {what}; {self._graph_hint}")
            self.executor.spin_once(timeout_sec=0.01)
            self.pump()
        return True

    def wait_sim(self, duration_s: float) -> None:
        end = self.sim_s + duration_s
        if not self.spin_until(lambda: self.sim_s >= end, 60.0 + 20 * duration_s, "simulated time"):
            raise RuntimeError("simulated time stopped advancing")

    def play(self, scene: Scene) -> SceneResult:
        """Set the scene up, kick (or release the rolling ball), and wait for the catch or the timeout."""
        # The kicker, the ball (at rest, also a rolling one: the catcher stays idle while we set up), then
        # the receivers, each placement taken before the next: a body put down where another is pushes
        # it, the receiver still holds the last ball, and a ball seen moving engages the catcher, which
        # then drives and heats its motors.
        self.place_robot(KICKER, scene.kicker_pose)
        self.wait_sim(0.02)
        if scene.ball is None:
            self.place_ball(*self.ball_at_kicker(scene.kicker_pose))
        else:
            self.place_ball(*scene.ball[:2])
        self.wait_sim(0.02)
        self.place_robot(RECEIVER, scene.receiver_pose)
        for r in self.receivers[1:]:
            self.place_robot(r, TEAMMATE_POSES[r])
        # Start only once the receiver stands still at its pose.
        self.wait_sim(0.7)
        for _ in range(10):
            self.place_robot(RECEIVER, scene.receiver_pose)
            self.wait_sim(0.3)
            if self.receiver_speed() < 0.02:
                break
        n_edges = len(self.barrier_edges)
        t_start = self.sim_s
        fired = True
        if scene.ball is None:
            n_events = len(self.events)
            self.kick.publish(Float64(data=scene.kick_speed_mps))
            fired = self.spin_until(lambda: any("fired" in e for e in self.events[n_events:]), 10.0, "the kick")
        else:
            self.place_ball(*scene.ball)
        end = t_start + scene.timeout_s
        self.spin_until(lambda: len(self.barrier_edges) > n_edges or self.sim_s >= end,
                        60.0 + 20 * scene.timeout_s, "the catch")
        self.spin_until(self.edges_settled, 10.0, "the plant's times around the light barrier's edge")
        actual = self.barrier_edges[n_edges] if len(self.barrier_edges) > n_edges else None
        by = self.edge_robots[n_edges] if actual is not None else None
        # This observer may lag a flat-out graph: take in the predictions up to the one compared.
        needed = (actual - PREDICTION_LEAD_S) if actual is not None else t_start + PREDICTION_LEAD_S
        truth_until = (actual if actual is not None else self.sim_s) + 0.05
        self.spin_until(lambda: self.series.predictions and self.series.predictions[-1][0] >= needed
                        and self.series.ball_truth and self.series.ball_truth[-1][0] >= truth_until
                        and self.series.robot_truth and self.series.robot_truth[-1][0] >= truth_until,
                        10.0, "the predictions and ground truth")
        return SceneResult(scene, t_start, self.sim_s, self._prediction(t_start, actual, by), actual,
                           kick_fired=fired, caught_by=by)

    def _prediction(self, t_start: float, actual: float | None, robot: int | None = None) -> float | None:
        """The catching robot's (robot_0's when none caught) prediction to compare with the contact."""
        s = self.series
        preds = s.predictions if robot in (None, RECEIVER) else s.teammate_predictions[robot]
        return compared_prediction(preds, t_start, actual)


class Demo:
    def __init__(self, args: argparse.Namespace) -> None:
        self.args = args
        self.out = Path(args.out) / time.strftime("%Y%m%d-%H%M%S")
        self.out.mkdir(parents=True, exist_ok=True)
        self.robot = RobotConfig()
        self.field = FieldConfig.preset(args.field)
        rclpy.init()
        self.node = rclpy.create_node("demo_director")
        self.executor = DirectExecutor()
        self.executor.add_node(self.node)
        self.launch: subprocess.Popen | None = None
        self.recorder: subprocess.Popen | None = None
        self.ssl_arrivals: SslArrivals | None = None
        self.view: subprocess.Popen | None = None
        self.director = Director(
            self.node,
            self.robot,
            self.executor,
            graph_alive=lambda: self.launch is None or self.launch.poll() is None,
            graph_hint=f"see {self.out / 'graph.log'}",
            receivers=args.receivers,
        )

    def start_graph(self) -> None:
        cmd = [
            str(Path(sys.executable).with_name("erforce-launch")),
            str(LAUNCH_FILE),
            f"pacing:={self.args.pacing}",
            f"real_time_factor:={self.args.real_time_factor}",
            f"seed:={self.args.seed}",
            f"field:={self.args.field}",
            "output:=screen",
            f"robot_a_max_mps2:={float(self.args.robot_a_max)}",
            f"robot_v_max_mps:={float(self.args.robot_v_max)}",
            f"robot_side:={str(self.args.robot_side).lower()}",
            f"receivers:={self.args.receivers}",
        ]
        if self.args.vision == "ssl":  # the plant sends SSL-Vision over loopback multicast to a free port
            port = free_udp_port()
            self.ssl_arrivals = SslArrivals(port)
            self.director.vision_sent_ns_of = self.ssl_arrivals.arrival_ns
            cmd += ["vision:=ssl", f"ssl_vision_port:={port}"]
        self.launch = spawn_in_session(cmd, self.out / "graph.log")
        # The recorder is a process of its own, like `ros2 bag record -a`.
        self.recorder = spawn_in_session(
            [str(Path(sys.executable).with_name("erforce-record")), str(self.out / "bag"), "--use-sim-time"],
            self.out / "record.log", idle=True,
        )
        if self.args.view:
            self.start_view()
        # Both observers take their topics in batches and may lag and catch up; the AI nodes and
        # the control loop may not. Under SCHED_IDLE neither preempts them when its DDS threads wake.
        for tid in os.listdir("/proc/self/task"):
            idle_priority(int(tid))
        print(f"graph starting (log: {self.out / 'graph.log'}) ...", flush=True)
        if not self.director.spin_until(lambda: self.director.graph_ready() and self._recording_everything(),
                                        90.0, "the graph"):
            raise RuntimeError(f"the graph or the recorder did not come up within 90 s; see {self.out / 'graph.log'} "
                               f"and {self.out / 'record.log'}")

    def start_view(self) -> None:
        """The field view (erforce_sim.view.field_view_node) beside the graph, an observer like the recorder."""
        self.view = start_field_view(self.args, self.out, self.args.field, self.director.receivers)

    def _recording_everything(self) -> bool:
        """erforce-record has subscribed to every topic that has a publisher now (it logs each one).

        The recorder starts as slowly as any node; scenes wait for it, so the bag holds all of them.
        """
        log = (self.out / "record.log").read_text(errors="replace")
        return all(f"'{topic}'" in log for topic, _ in self.node.get_topic_names_and_types()
                   if not topic.startswith("/rosout") and "parameter_events" not in topic
                   and self.node.count_publishers(topic) > 0)

    def _reachable(self, result: SceneResult) -> bool:
        if result.caught:
            return True  # it was reached
        starts = [result.scene.receiver_pose] + [TEAMMATE_POSES[r] for r in self.director.receivers[1:]]
        return any(
            reachable(
                np.array(self.director.series.ball_truth),
                result.t_start_s,
                result.t_end_s,
                np.array(start[:2]),
                RobotLimits(self.args.robot_a_max, self.args.robot_v_max),
                self.robot.dribbler_offset_m,
                self.field,
            )
            for start in starts
        )

    def run(self) -> int:
        from erforce_sim.demo.report import write_report

        results: list[SceneResult] = []
        wall0 = sim0 = None
        try:
            self.start_graph()
            wall0, sim0 = time.monotonic(), self.director.sim_s
            scenes = default_scenes(self.field)[: self.args.scenes or None]
            print(f"{'#':>2} {'scene':<52} {'predicted':>10} {'actual':>10} {'error':>9}  caught")
            for i, scene in enumerate(scenes, 1):
                r = self.director.play(scene)
                results.append(r)
                pred = "never" if r.predicted_s is None else f"{r.predicted_s - r.t_start_s:.3f} s"
                act = "—" if r.actual_s is None else f"{r.actual_s - r.t_start_s:.3f} s"
                err = "—" if r.error_s is None else f"{r.error_s * 1e3:+.0f} ms"
                print(
                    f"{i:>2} {scene.name[:52]:<52} {pred:>10} {act:>10} {err:>9}  {r.caught_text}",
                    flush=True,
                )
        finally:
            wall = time.monotonic() - wall0 if wall0 is not None else 0.0
            sim = self.director.sim_s - sim0 if sim0 is not None else 0.0
            if self.launch is not None and self.launch.poll() is None:
                time.sleep(0.2)  # what is still in flight to the director
                self.director.pump()
            if self.launch is not None:
                stop_process(self.launch, sigint_timeout_s=10.0)
            if self.recorder is not None:
                stop_process(self.recorder, sigint_timeout_s=20.0)
            if self.view is not None:
                stop_process(self.view, sigint_timeout_s=5.0)
            self.director.close()
            if self.ssl_arrivals is not None:
                self.ssl_arrivals.close()
            self.node.destroy_node()
            rclpy.try_shutdown()
        for r in results:
            r.reachable = self._reachable(r)
        record_log = (self.out / "record.log").read_text(errors="replace").strip().splitlines()
        summary = write_report(
            self.out,
            results,
            self.director.series,
            self.robot,
            real_time_factor=sim / wall if wall > 0 else 0.0,
            recording=record_log[-1] if record_log else "no recording",
        )
        print("\n" + summary, flush=True)
        print(f"report: {self.out}")
        # The exit code says whether the demo ran; the summary says how well robot_0 caught.
        return 0 if len(results) == len(default_scenes(self.field)[: self.args.scenes or None]) else 1


SO_TIMESTAMPNS = getattr(socket, "SO_TIMESTAMPNS", 35)  # Linux; Python's socket module does not name it


class SslArrivals:
    """``--vision ssl``: when each SSL-Vision frame reached this host, by its stamp in the graph.

    The kernel's receive timestamp (SO_TIMESTAMPNS, the system clock like the DDS source
    timestamps) of the first camera datagram with a ball, keyed by ``t_capture`` (the bridge's
    stamp in simulated time): the latency measured from there covers UDP, the bridge, DDS and
    the predictor.
    """

    def __init__(self, port: int) -> None:
        self._arrivals: dict[int, int] = {}
        self._sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self._sock.setsockopt(socket.SOL_SOCKET, SO_TIMESTAMPNS, 1)
        self._sock.bind((SSL_VISION_GROUP, port))
        membership = socket.inet_aton(SSL_VISION_GROUP) + socket.inet_aton("127.0.0.1")
        self._sock.setsockopt(socket.IPPROTO_IP, socket.IP_ADD_MEMBERSHIP, membership)
        self._sock.settimeout(0.2)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="ssl_arrivals", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                data, ancillary, _flags, _addr = self._sock.recvmsg(65536, 256)
            except TimeoutError:
                continue
            except OSError:
                return
            try:
                frame = decode_wrapper(data).frame
            except SslDecodeError:
                continue
            if frame is None or not frame.balls:
                continue
            for level, kind, payload in ancillary:
                if level == socket.SOL_SOCKET and kind == SO_TIMESTAMPNS:
                    sec, nsec = struct.unpack("qq", payload[:16])
                    key = stamp_to_nanoseconds(seconds_to_stamp(frame.t_capture_s))
                    self._arrivals.setdefault(key, sec * 1_000_000_000 + nsec)
                    if len(self._arrivals) > 5000:
                        self._arrivals.pop(next(iter(self._arrivals)))

    def arrival_ns(self, stamp_ns: int) -> int | None:
        return self._arrivals.get(stamp_ns)

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=1.0)
        self._sock.close()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="./run demo", description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", default="report", help="report folder (a timestamped subfolder is created)")
    parser.add_argument("--scenario", default="passing", choices=("passing", "scenes"),
                        help="passing: the passing game of a team against opponents on the 14-robot graph "
                             "(team_sim.launch.yaml ai:=passing; erforce_sim.demo.passing_report); scenes: "
                             "the paper's story (Fig. 6, then kicks) on demo.launch.yaml")
    parser.add_argument("--in-process", action="store_true",
                        help="passing: the game in one process instead, without DDS (deterministic per seed)")
    parser.add_argument("--team", type=int, default=TEAM_SIZE, help="passing: our robots (2..11)")
    parser.add_argument("--opponents", type=int, default=3, help="passing: opponents (0..6)")
    parser.add_argument("--passes", type=int, default=20, help="passing: the game ends after this many passes")
    parser.add_argument("--pacing", default=_PLANT["pacing"], choices=("lockstep", "realtime"))
    parser.add_argument(
        "--real-time-factor",
        type=float,
        default=0.0,
        help="cap on simulated seconds per wall second; 0 = as fast as lockstep goes",
    )
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--field", default=FIELD_PRESET, choices=("division_a", "division_b"),
                        help="scenes: the field (the passing game plays on division_a)")
    parser.add_argument("--scenes", type=int, default=0, help="scenes: play only the first N scenes")
    parser.add_argument(
        "--receivers",
        type=int,
        default=1,
        choices=(1, 2, 3),
        help="scenes: receiving robots: robot_0, and robot_2 and robot_3 waiting downfield; the first to the ball "
             "receives",
    )
    parser.add_argument("--robot-a-max", type=float, default=ROBOT_A_MAX_MPS2, help="catching acceleration [m/s^2]")
    parser.add_argument("--robot-v-max", type=float, default=ROBOT_V_MAX_MPS, help="catching speed [m/s]")
    parser.add_argument(
        "--robot-side",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="start robot_0's velocity_controller and motor_boards; --no-robot-side when they run "
        "on the robot, another host (see test/two_hosts)",
    )
    parser.add_argument(
        "--vision",
        default="ros",
        choices=("ros", "ssl"),
        help="ssl: vision goes as SSL-Vision packets from 4 simulated cameras through ssl_vision_bridge "
        "(loopback multicast) instead of the plant's vision topics",
    )
    parser.add_argument(
        "--world",
        default="plant",
        choices=("plant", "ssl"),
        help="passing: plant (our simulated world in the graph) or ssl (an outside world: the stand-in, "
        "ssl_world.launch.yaml, started as a program of its own, and only the AI side, team_sim.launch.yaml "
        "world:=ssl, talking to it over SSL-Vision and the simulation protocol)",
    )
    parser.add_argument("--world-ball", type=float, nargs=3, metavar=("A_SLIDE", "A_ROLL", "C_SWITCH"),
                        help="--world ssl: the stand-in's carpet as the two-phase model, e.g. -14 -0.7 0.7 (its "
                             "geometry carries it; default: the plant's own)")
    parser.add_argument("--view", action="store_true",
                        help="serve the field view in a browser while the demo runs (prints its address)")
    parser.add_argument("--view-port", type=int, default=_VIEW["port"], help="HTTP port of the field view")
    parser.add_argument("--foxglove-port", type=int, default=_VIEW["foxglove_port"],
                        help="with --view: also a Foxglove WebSocket server on this port (0: none)")
    args = parser.parse_args(argv)
    if args.scenario == "passing" and args.in_process:
        from erforce_sim.demo import passing_report  # no DDS graph: the game runs in this process

        return passing_report.run(args)
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    os.environ.update(contract.dds_profile_env())  # for the director and the recorder too
    if args.scenario == "passing":
        from erforce_sim.demo import passing_report

        return passing_report.run_on_graph(args)
    return Demo(args).run()


if __name__ == "__main__":
    sys.exit(main())
