"""Shared pieces of the fault tests (issues 6 and 19): a non-finite field walker, malformed messages of
every contract type, a watch over every contract topic of a graph, and the closed-loop graph started as
real node processes: per robot (plant, one robot's velocity_controller and motor_boards, optionally the
ball predictor and the catcher) or as a team (plant, team_firmware, ball predictor, team_catcher)."""

from __future__ import annotations

import contextlib
import math
import os
import re
import signal
import time
from collections.abc import Iterable
from pathlib import Path

import numpy as np
from builtin_interfaces.msg import Time
from geometry_msgs.msg import PointStamped, PoseStamped, Twist
from nav_msgs.msg import Odometry
from rclpy.qos import HistoryPolicy, QoSProfile
from rclpy.serialization import serialize_message
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState, PointCloud2, PointField
from std_msgs.msg import Bool, Float64, Float64MultiArray, Header, MultiArrayDimension, String

from erforce_interfaces.wire import contract
from erforce_interfaces.wire.conversions import odometry_from_msg, odometry_msg, stamp_to_seconds

ROBOT_YAML = Path(__file__).resolve().parents[2] / "src/erforce_interfaces/config/robot.yaml"

_FLOAT_TYPES = ("double", "float")


def non_finite_fields(msg, prefix: str = "") -> list[str]:
    """Paths of every non-finite float in ``msg``, walking nested messages, arrays and sequences."""
    bad: list[str] = []
    for name, type_name in msg.get_fields_and_field_types().items():
        value = getattr(msg, name)
        path = prefix + name
        base = type_name.split("<")[-1].split("[")[0].rstrip(">").split(",")[0]
        if type_name in _FLOAT_TYPES:
            if not math.isfinite(value):
                bad.append(path)
        elif base in _FLOAT_TYPES:  # double[36], sequence<double>, sequence<double, 3>
            arr = np.asarray(value, dtype=float)
            bad += [f"{path}[{k}]" for k in np.flatnonzero(~np.isfinite(arr))]
        elif hasattr(value, "get_fields_and_field_types"):
            bad += non_finite_fields(value, path + ".")
        elif isinstance(value, list | tuple):
            for k, item in enumerate(value):
                if hasattr(item, "get_fields_and_field_types"):
                    bad += non_finite_fields(item, f"{path}[{k}].")
    if isinstance(msg, PointCloud2) and all(f.datatype == PointField.FLOAT64 for f in msg.fields):
        values = np.frombuffer(bytes(msg.data), "<f8")  # the points' doubles (all of /vision/robots' fields)
        bad += [f"{prefix}data (double {k})" for k in np.flatnonzero(~np.isfinite(values))]
    return bad


def topic_names(robots: Iterable[int], topics=contract.TOPICS,
                opponents: Iterable[int] = ()) -> list[tuple[str, contract.Topic]]:
    """(resolved name, topic) of every contract topic for the given robots (and opponents)."""
    out = []
    for t in topics:
        if t.per_robot:
            out += [(t.for_robot(i), t) for i in robots]
            out += [(contract.OPPONENTS.topic(t, j), t) for j in opponents]
        else:
            out.append((t.name, t))
    return out


#: topics that every rclpy node may subscribe to or publish besides its contract topics
RCL_TOPICS = ("/parameter_events", "/rosout")


def node_topics(probe, node: str, namespace: str = "/", published: bool = False) -> dict[str, contract.Topic]:
    """The contract topic of every topic that the running node ``node`` subscribes to (or publishes), from the
    ROS graph, not from the contract: what it really reads. A topic outside the contract fails."""
    graph = probe.node.get_publisher_names_and_types_by_node if published else \
        probe.node.get_subscriber_names_and_types_by_node
    found = {name: contract.topic_of_name(name) for name, _ in graph(node, namespace) if name not in RCL_TOPICS}
    outside = [name for name, topic in found.items() if topic is None]
    assert not outside, f"{node} uses topics outside the contract: {outside}"
    return found


def subscribed_topics(node: str, robots: Iterable[int] = (0,)) -> list[tuple[str, contract.Topic]]:
    """The topics ``node`` subscribes to according to the contract (all use /clock: use_sim_time)."""
    return [(name, t) for name, t in topic_names(robots)
            if re.search(rf"\b{node}\b", t.subscribers) or (t is contract.CLOCK and node != "plant")]


# ------------------------------------------------------------------ malformed messages
BAD = (math.nan, math.inf, -math.inf, 1e300, -1e300, 1e12, -1.0, 0.0)
BURST = 25  # bad messages per topic


def bad_times(now_s: float) -> list[Time]:
    """Negative, no valid time, zero, the far future, backwards, ahead by more than the rule's 2 s."""
    back = max(now_s - 1.0, 0.0)
    return [Time(sec=-1, nanosec=0), Time(sec=1, nanosec=1_500_000_000), Time(sec=0, nanosec=0),
            Time(sec=2**31 - 1, nanosec=999_999_999), Time(sec=int(back), nanosec=int(back % 1 * 1e9)),
            Time(sec=int(now_s) + 30, nanosec=0)]


def _stamp(rng) -> Time:
    kind = rng.integers(5)
    if kind == 0:
        return Time(sec=0, nanosec=0)
    if kind == 1:
        return Time(sec=2**31 - 1, nanosec=999_999_999)  # the far future
    if kind == 2:
        return Time(sec=int(rng.integers(0, 100)), nanosec=4_000_000_000)  # nanosec out of range
    if kind == 3:
        return Time(sec=int(rng.integers(-(2**31), 0)), nanosec=0)  # negative: rclpy's Time.from_msg raises
    return Time(sec=int(rng.integers(0, 5)), nanosec=int(rng.integers(0, 1_000_000_000)))  # backwards or on


def _bad(rng) -> float:
    return float(BAD[rng.integers(len(BAD))])


def _quaternion(q, rng) -> None:
    kind = rng.integers(4)
    q.x, q.y, q.z, q.w = {0: (0.0, 0.0, 0.0, 0.0), 1: (0.0, 0.0, 0.0, 2.0), 2: (math.nan, 0.0, 0.0, 1.0),
                          3: (_bad(rng), _bad(rng), _bad(rng), _bad(rng))}[int(kind)]


def bad_message(msg_type, rng, columns: tuple[str, ...] = contract.BALL_MODEL_PARAM_LABELS):
    """One malformed message of ``msg_type`` with randomized bad fields (a table's: often labelled ``columns``)."""
    if msg_type is JointState:
        n = int(rng.choice([0, 1, 3, 4, 5, 8]))
        names = [f"wheel_{i}" for i in range(4)]
        msg = JointState(header=_Header(rng))
        # empty, right, swapped, too few, foreign
        msg.name = [[], names, names[::-1], names[:2], ["x"] * n][int(rng.integers(5))]
        msg.velocity = [_bad(rng) for _ in range(n)]
        msg.effort = [_bad(rng) for _ in range(int(rng.choice([0, n, 4])))]
        msg.position = [_bad(rng) for _ in range(int(rng.integers(3)))]
        return msg
    if msg_type is Twist:
        msg = Twist()
        for part in (msg.linear, msg.angular):
            part.x, part.y, part.z = (_bad(rng) if rng.random() < 0.5 else 0.0 for _ in range(3))
        return msg
    if msg_type is Odometry:
        msg = Odometry(header=_Header(rng), child_frame_id="fuzz")
        p = msg.pose.pose.position
        p.x, p.y, p.z = _bad(rng), _bad(rng), _bad(rng)
        _quaternion(msg.pose.pose.orientation, rng)
        t = msg.twist.twist
        t.linear.x, t.linear.y, t.angular.z = _bad(rng), _bad(rng), _bad(rng)
        msg.pose.covariance = [_bad(rng) for _ in range(36)]
        return msg
    if msg_type is PoseStamped:
        msg = PoseStamped(header=_Header(rng))
        msg.pose.position.x, msg.pose.position.y = _bad(rng), _bad(rng)
        _quaternion(msg.pose.orientation, rng)
        return msg
    if msg_type is PointStamped:
        msg = PointStamped(header=_Header(rng))
        msg.point.x, msg.point.y, msg.point.z = _bad(rng), _bad(rng), _bad(rng)
        return msg
    if msg_type is Float64:
        return Float64(data=_bad(rng))
    if msg_type is Bool:
        return Bool(data=bool(rng.integers(2)))
    if msg_type is String:  # /ball/phase: a phase, none, or garbage
        return String(data=str(rng.choice([*contract.BALL_PHASES, "", "HOPPING", "chip\x00", "x" * 10_000])))
    if msg_type is Clock:
        return Clock(clock=_stamp(rng))
    if msg_type is Float64MultiArray:  # a labelled table: right or wrong labels and sizes, bad values
        rows, cols = int(rng.integers(0, 4)), int(rng.integers(0, 6))  # 4 columns killed the catcher
        if columns != contract.BALL_MODEL_PARAM_LABELS and rng.random() < 0.5:
            cols = len(columns)  # the right shape, so that the values' checks are reached
        labels = [",".join(columns), "a,b", ""][int(rng.integers(3))]
        msg = Float64MultiArray()
        msg.layout.dim = [MultiArrayDimension(label=",".join(contract.BALL_MODEL_PARAM_ROWS[:max(rows, 1)]), size=rows,
                                              stride=rows * cols),
                          MultiArrayDimension(label=labels, size=cols, stride=cols)][: int(rng.integers(3))]
        # plausible values (team codes, ids) among the bad ones, so that a row can pass some checks
        fill = (lambda: -2.5) if columns == contract.BALL_MODEL_PARAM_LABELS else \
            (lambda: float(rng.choice([-2.5, 0.0, 1.0, 2.0])))
        msg.data = [_bad(rng) if rng.random() < 0.5 else fill() for _ in range(int(rng.choice([0, 3, 9, rows * cols])))]
        msg.layout.data_offset = int(rng.choice([0, 0, 1, 2**32 - 1]))
        return msg
    if msg_type is PointCloud2:  # /vision/robots: right or wrong fields and sizes, bad values, teams and ids
        n = int(rng.choice([0, 1, 2, 22]))
        names = [contract.VISION_ROBOT_FIELDS, contract.VISION_ROBOT_FIELDS[:5], ("x", "y", "z")][int(rng.integers(3))]
        msg = PointCloud2(header=_Header(rng), height=int(rng.choice([1, 1, 0, 2])), width=n)
        msg.fields = [PointField(name=name, offset=8 * k, datatype=int(rng.choice([PointField.FLOAT64] * 3 + [7])),
                                 count=1) for k, name in enumerate(names)]
        msg.point_step = int(rng.choice([8 * len(names), 48, 0]))
        msg.row_step = msg.point_step * n
        values = [[_bad(rng) if rng.random() < 0.3 else 0.5, _bad(rng) if rng.random() < 0.3 else -0.5, 0.0,
                   _bad(rng) if rng.random() < 0.3 else 1.0, float(rng.choice([1.0, 2.0, 0.0, math.nan])),
                   float(rng.choice([0.0, 1.0, 2.5, -1.0, 1e12]))] for _ in range(n)]
        msg.data = np.array(values, dtype="<f8").reshape(-1, 6)[:, :len(names)].tobytes()[:int(rng.choice(
            [10**9, 10**9, 7]))]
        return msg
    raise AssertionError(f"no fuzzer for {msg_type.__name__}")


def _Header(rng):
    return Header(stamp=_stamp(rng), frame_id=["", "field", "nonsense"][int(rng.integers(3))])


class TopicWatch:
    """Subscribes to contract topics with their QoS; checks every message as it arrives.

    ``non_finite`` collects (topic, field paths) of every message with a non-finite float;
    ``counts`` the messages per topic; ``keep`` names the topics whose messages are stored.
    """

    KEPT_DEPTH = 2000  # a kept topic's reader queue, messages

    def __init__(self, probe, robots: Iterable[int] = (0,), exclude: Iterable[str] = (),
                 keep: Iterable[str] = (), opponents: Iterable[int] = ()) -> None:
        self.counts: dict[str, int] = {}
        self.non_finite: list[tuple[str, list[str]]] = []
        self.latest: dict[str, object] = {}
        self.kept: dict[str, list] = {name: [] for name in keep}
        self.paused: set[str] = set()  # topics a test is publishing bad messages on right now
        # per paused topic: the serialized messages the test sent that the watch has not received back yet
        self.echoes_due: dict[str, list[bytes]] = {}
        excluded = set(exclude)
        self.topics = [(n, t) for n, t in topic_names(robots, opponents=opponents) if n not in excluded]
        for name, t in self.topics:
            self.counts[name] = 0
            qos = t.qos
            if name in self.kept:  # all of it: a flat-out graph sends more between two spins than the contract's depth
                qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=max(t.qos.depth, self.KEPT_DEPTH),
                                 reliability=t.qos.reliability, durability=t.qos.durability)
            probe.node.create_subscription(t.msg_type, name, lambda m, n=name: self._on(n, m), qos)

    def _on(self, name: str, msg) -> None:
        if name in self.paused:
            due = self.echoes_due.get(name)
            if due:
                with contextlib.suppress(ValueError):  # a node's message on the topic is no echo
                    due.remove(serialize_message(msg))
            return
        self.counts[name] += 1
        bad = non_finite_fields(msg)
        if bad:
            self.non_finite.append((name, bad))
        self.latest[name] = msg
        if name in self.kept:
            self.kept[name].append(msg)

    def assert_all_finite(self) -> None:
        assert not self.non_finite, f"non-finite values published: {self.non_finite[:10]}"


ECHO_WAIT_S = 0.3  # the longest a burst's echoes are waited for
#: the columns of the tables a node reads, by topic (else the model's): the fuzz gets past the label check
TABLE_COLUMNS = {contract.BALL_CATCHES.name: contract.CATCH_TABLE_COLUMNS,
                 contract.ROBOTS_TRACKED.name: contract.TRACKED_ROBOT_COLUMNS,
                 contract.BALL_CHIP_MODEL_PARAMS.name: contract.BALL_CHIP_MODEL_PARAM_LABELS}


def fuzz_topic(probe, watch: TopicWatch, spinner, name: str, topic: contract.Topic, rng) -> None:
    """BURST bad messages on ``name``. The watch's own subscription receives them too (their echo), which
    is no node's output: it stays paused on ``name`` until every echo is back, or ECHO_WAIT_S at most (a
    best-effort topic may drop some). ``spinner.spin_until`` spins meanwhile (a ClosedLoop keeps commanding)."""
    watch.paused.add(name)
    due = watch.echoes_due[name] = []
    pub = probe.publisher(name, topic.msg_type, topic.qos)
    columns = TABLE_COLUMNS.get(topic.name, contract.BALL_MODEL_PARAM_LABELS)
    for _ in range(BURST):
        msg = bad_message(topic.msg_type, rng, columns)
        if name in watch.counts:  # a topic the watch reads
            due.append(serialize_message(msg))
        pub.publish(msg)
        probe.spin_for(0.002)
    end = time.monotonic() + ECHO_WAIT_S
    spinner.spin_until(lambda: not due or time.monotonic() >= end, ECHO_WAIT_S + 1.0, f"the echoes of {name}")
    watch.paused.discard(name)
    del watch.echoes_due[name]


def body_twist(odom: Odometry) -> np.ndarray:
    """[vx, vy, wz] of a field-frame odometry, rotated into the robot's base_link."""
    _, pose, vel, _ = odometry_from_msg(odom)
    c, s = math.cos(pose[2]), math.sin(pose[2])
    return np.array([c * vel[0] + s * vel[1], -s * vel[0] + c * vel[1], vel[2]])


class ClosedLoop:
    """plant + robot_0's velocity_controller and motor_boards (+ ball_predictor, catcher), all watched.

    ``command`` sets a cmd_vel that the spin helpers republish every ``command_period_s`` of
    wall time, as an AI would; ``None`` stops publishing (the catcher, or nothing, drives).
    """

    NODES = ("velocity_controller", "motor_boards", "ball_predictor", "catcher", "plant")

    def __init__(self, graph, *, plant: dict | None = None, vc: dict | None = None, mb: dict | None = None,
                 predictor: dict | None = None, catcher: dict | None = None, with_ball_model: bool = False,
                 exclude: Iterable[str] = (), command_period_s: float = 0.02,
                 robot_yaml: Path = ROBOT_YAML) -> None:
        self.graph = graph
        self.robot_yaml = robot_yaml
        self.probe = graph.probe
        # The first tick waits for the /clock reader of every use_sim_time node and of the watch:
        # otherwise sim time runs ahead while a slow starter (the ball predictor loads its numba
        # kernels) comes up, and a test's sim-time budget is spent before that node takes part.
        clock_readers = 2 + 2 * with_ball_model + (contract.CLOCK.name not in set(exclude))
        self.params = {
            "plant": {"robot_poses": [0.0, 0.0, 0.0], "ball": [-2.0, 2.0, 0.0, 0.0], "real_time_factor": 1.0,
                      "lockstep_timeout_s": 0.3, "start_clock_subscribers": clock_readers, **(plant or {})},
            "velocity_controller": {"use_sim_time": True, **(vc or {})},
            "motor_boards": {"use_sim_time": True, **(mb or {})},
            "ball_predictor": {"use_sim_time": True, "num_robots": 1, **(predictor or {})},
            "catcher": {"use_sim_time": True, **(catcher or {})},
        }
        self.with_ball_model = with_ball_model
        self.watch = TopicWatch(self.probe, exclude=exclude,
                                keep=("/sim/events", "/robot_0/ground_truth/odom", "/robot_0/motor_status",
                                      "/robot_0/ground_truth/motors", "/robot_0/cmd_vel",
                                      "/robot_0/wheel_setpoints"))
        self.procs: dict[str, object] = {}
        self._twist: Twist | None = None
        self._cmd_pub = None
        self._command_period_s = command_period_s
        self._last_cmd_wall = 0.0

    # ------------------------------------------------------------ processes
    def start(self, node: str):
        namespace = "robot_0" if node in ("velocity_controller", "motor_boards", "catcher") else None
        package = {"plant": "erforce_sim", "ball_predictor": "erforce_ball_model", "catcher": "erforce_ball_model"}
        params_file = None if node == "catcher" else self.robot_yaml
        proc = self.graph.start_node(package.get(node, "erforce_motion"), node, namespace=namespace,
                                     params_file=params_file, params=self.params[node])
        self.procs[node] = proc
        return proc

    def start_all(self) -> None:
        """Robot nodes first: the plant starts ticking once both wheel_states readers are up."""
        self.start("velocity_controller")
        self.start("motor_boards")
        if self.with_ball_model:
            self.start("ball_predictor")
            self.start("catcher")
        self.start("plant")
        self.spin_until(lambda: self.sim_s() > 0.2, 60.0, "the loop running (0.2 s of sim time)")

    def kill(self, node: str, sig: int) -> int:
        proc = self.procs[node]
        proc.signal(sig)
        deadline = time.monotonic() + 15.0
        while proc.alive():  # keep spinning: the probe must not fall behind meanwhile
            if time.monotonic() > deadline:
                raise TimeoutError(f"{node} did not exit after signal {sig}")
            self.probe.spin_for(0.02)
        return proc.popen.returncode

    # ------------------------------------------------------------- spinning
    def command(self, vx: float, vy: float = 0.0, wz: float = 0.0) -> None:
        if self._cmd_pub is None:
            self._cmd_pub = self.probe.wait_for_subscribers("/robot_0/cmd_vel", Twist, timeout_s=30.0)
        msg = Twist()
        msg.linear.x, msg.linear.y, msg.angular.z = float(vx), float(vy), float(wz)
        self._twist = msg
        self._publish_command()

    def stop_commanding(self) -> None:
        self._twist = None

    def _publish_command(self) -> None:
        if self._twist is not None:
            self._cmd_pub.publish(self._twist)
            self._last_cmd_wall = time.monotonic()

    def spin_until(self, condition, timeout_s: float, what: str) -> None:
        deadline = time.monotonic() + timeout_s
        while not condition():
            if time.monotonic() > deadline:
                raise TimeoutError(f"{what} not reached within {timeout_s} s (sim time {self.sim_s():.3f} s)")
            if self._twist is not None and time.monotonic() - self._last_cmd_wall > self._command_period_s:
                self._publish_command()
            self.probe.executor.spin_once(timeout_sec=0.005)

    def drain(self, max_callbacks: int = 5000) -> None:
        """Handle everything that has arrived, so ``latest`` is as fresh as it can be (commanding on, as
        while spinning: a long backlog must not let the controller's command timeout fire)."""
        for _ in range(max_callbacks):
            if self._twist is not None and time.monotonic() - self._last_cmd_wall > self._command_period_s:
                self._publish_command()
            before = sum(self.watch.counts.values())
            self.probe.executor.spin_once(timeout_sec=0.0)
            if sum(self.watch.counts.values()) == before:
                return

    def spin_sim(self, duration_s: float, timeout_s: float = 60.0) -> float:
        """Spin until ``duration_s`` of simulated time has passed; returns the sim time reached."""
        start = self.sim_s()
        self.spin_until(lambda: self.sim_s() >= start + duration_s, timeout_s, f"{duration_s} s of sim time")
        return self.sim_s()

    def spin_wall(self, duration_s: float) -> None:
        end = time.monotonic() + duration_s
        self.spin_until(lambda: time.monotonic() >= end, duration_s + 1.0, "wall time")

    # -------------------------------------------------------------- queries
    def sim_s(self) -> float:
        """Newest ground-truth stamp (the plant's time, 100 Hz); -1 before the first."""
        truth = self.watch.latest.get("/robot_0/ground_truth/odom")
        return stamp_to_seconds(truth.header.stamp) if truth is not None else -1.0

    def events(self) -> list[str]:
        return [m.data for m in self.watch.kept["/sim/events"]]

    def velocity(self) -> np.ndarray:
        """robot_0's true body twist [vx, vy, wz] in base_link."""
        return body_twist(self.watch.latest["/robot_0/ground_truth/odom"])

    def truth(self) -> list[tuple[float, np.ndarray]]:
        """(t [s], body twist) of every ground-truth odometry received."""
        kept = self.watch.kept["/robot_0/ground_truth/odom"]
        return [(stamp_to_seconds(m.header.stamp), body_twist(m)) for m in kept]

    def assert_follows(self, twist, tol_mps: float = 0.05, settle_s: float = 1.0, timeout_s: float = 60.0) -> None:
        """Within ``settle_s`` of sim time, the true body twist comes within ``tol_mps`` of ``twist``."""
        start = self.sim_s()
        want = np.asarray(twist, dtype=float)
        self.spin_until(lambda: np.all(np.abs(self.velocity() - want) <= tol_mps) or self.sim_s() > start + settle_s,
                        timeout_s, f"following {want.tolist()}")
        assert np.all(np.abs(self.velocity() - want) <= tol_mps), (
            f"robot does not follow cmd_vel {want.tolist()}: true body twist {self.velocity().round(3).tolist()} "
            f"after {self.sim_s() - start:.2f} s of sim time")


TEAM_HOSTS = {"team_firmware": ("velocity_controller", "motor_boards"), "team_catcher": ("catcher",)}
_TEAM_PACKAGES = {"team_firmware": "erforce_motion", "ball_predictor": "erforce_ball_model",
                  "team_catcher": "erforce_ball_model", "plant": "erforce_sim"}


class TeamLoop(ClosedLoop):
    """The team deployment of the same loop: the plant with ``robots`` under control, one team_firmware
    (their main and motor boards), the ball predictor and one team_catcher (their catchers, as a team).

    ``TEAM_HOSTS`` names the per-robot nodes whose contract each team node fulfils for every robot in
    it: the fault tests derive a team node's inputs from the contract through them."""

    NODES = ("team_firmware", "ball_predictor", "team_catcher", "plant")

    def __init__(self, graph, *, robots: tuple[int, ...] = (0, 1), plant: dict | None = None,
                 firmware: dict | None = None, predictor: dict | None = None, catcher: dict | None = None,
                 exclude: Iterable[str] = (), robot_yaml: Path = ROBOT_YAML) -> None:
        self.graph = graph
        self.robot_yaml = robot_yaml
        self.probe = graph.probe
        self.robots = tuple(robots)
        poses = [c for i in self.robots for c in (-1.0 - 1.5 * i, 1.5 * i, 0.0)]
        ids = list(self.robots)
        clock_readers = 3 + (contract.CLOCK.name not in set(exclude))  # as ClosedLoop: nobody misses tick 0
        self.params = {
            "plant": {"robot_poses": poses, "controlled": [True] * len(ids), "wheel_states_readers": 1,
                      "ball": [-2.0, 2.0, 0.0, 0.0], "real_time_factor": 1.0, "lockstep_timeout_s": 0.3,
                      "start_clock_subscribers": clock_readers, **(plant or {})},
            "team_firmware": {"use_sim_time": True, "robot_ids": ids, **(firmware or {})},
            "ball_predictor": {"use_sim_time": True, "num_robots": len(ids), **(predictor or {})},
            "team_catcher": {"use_sim_time": True, "robot_ids": ids, **(catcher or {})},
        }
        self.with_ball_model = True
        per_robot = ("ground_truth/odom", "cmd_vel", "motor_status", "ground_truth/motors")
        self.watch = TopicWatch(self.probe, robots=self.robots, exclude=exclude,
                                keep=("/sim/events", *(f"/robot_{i}/{t}" for i in self.robots for t in per_robot)))
        self.procs: dict[str, object] = {}
        self._twist: Twist | None = None
        self._cmd_pub = None
        self._command_period_s = 0.02
        self._last_cmd_wall = 0.0

    def start(self, node: str):
        params_file = None if node == "team_catcher" else self.robot_yaml
        proc = self.graph.start_node(_TEAM_PACKAGES[node], node, params_file=params_file, params=self.params[node])
        self.procs[node] = proc
        return proc

    def start_all(self) -> None:
        for node in self.NODES:
            self.start(node)
        self.spin_until(lambda: self.sim_s() > 0.2, 60.0, "the loop running (0.2 s of sim time)")


# ------------------------------------------------------------------ the launched graph, respawning
DEMO_LAUNCH = Path(__file__).resolve().parents[2] / "src/erforce_sim/launch/demo.launch.yaml"
TEAM_SIM_LAUNCH = Path(__file__).resolve().parents[2] / "src/erforce_sim/launch/team_sim.launch.yaml"

# What closes the loop: each node's output that the next one acts on, per tick or frame.
LOOP_OUTPUTS = {
    "plant": (contract.CLOCK, contract.CLOCK.name),
    "velocity_controller": (contract.WHEEL_SETPOINTS, contract.WHEEL_SETPOINTS.for_robot(0)),
    "motor_boards": (contract.MOTOR_DUTY, contract.MOTOR_DUTY.for_robot(0)),
    "ball_predictor": (contract.CATCH_TIME, contract.CATCH_TIME.for_robot(0)),
    "catcher": (contract.CMD_VEL, contract.CMD_VEL.for_robot(0)),
}

# The same for team_sim.launch.yaml as shipped (both teams' firmware in one process).
TEAM_LOOP_OUTPUTS = {
    "plant": (contract.CLOCK, contract.CLOCK.name),
    "team_firmware": (contract.FIELD_MOTOR_DUTY, contract.FIELD_MOTOR_DUTY.name),
    "ball_predictor": (contract.CATCH_TIME, contract.CATCH_TIME.for_robot(0)),
    "opponent_interceptor": (contract.CMD_VEL, contract.OPPONENTS.topic(contract.CMD_VEL, 0)),
}


def standbys_ready(launch_output: str, node: str | None = None) -> bool:
    """erforce-launch (``launch_output``) has a warm standby that said it is ready and has not become a node yet:
    the one spare stands in for every node of ours (``node`` is accepted for the callers' reading)."""
    started = re.findall(r"\]: standby started with pid \[(\d+)\]", launch_output)
    ready = set(re.findall(r"\]: standby ready \[pid (\d+)\]", launch_output))
    taken = set(re.findall(r"\]: process activated from standby with pid \[(\d+)\]", launch_output))
    return bool(started) and started[-1] in ready - taken


_LOCKSTEP_EVENT = re.compile(r"lockstep: (\S+) (?:motor_boards )?(stalled|resumed)")
_STALLED = re.compile(r"lockstep: \S+ motor_boards stalled")
_RESUMED_AT = re.compile(r"\[(\d+\.\d+)\] \[plant\]: lockstep: \S+ resumed")  # the log line's wall clock


def lockstep_stalled(plant_output: str) -> set[str]:
    """The robots the plant's lockstep gate goes on without, from its events in ``plant_output`` (in order:
    "lockstep: robot_0 motor_boards stalled: ..." until "lockstep: robot_0 resumed at ...")."""
    stalled: set[str] = set()
    for name, what in _LOCKSTEP_EVENT.findall(plant_output):
        (stalled.add if what == "stalled" else stalled.discard)(name)
    return stalled


class LaunchedDemo:
    """demo.launch.yaml (or ``launch_file``) under erforce-launch (respawn on by default), with the arrival
    times (wall clock) of every node's loop output (``loop_outputs``: node name -> (topic, resolved name))."""

    def __init__(self, graph, launch_file: Path = DEMO_LAUNCH, loop_outputs=None, standby: bool = True,
                 **launch_args) -> None:
        self.graph = graph
        self.probe = graph.probe
        self._label_nodes: dict[str, set[str]] = {}  # label -> the __node:= names its processes were started with
        loop_outputs = LOOP_OUTPUTS if loop_outputs is None else loop_outputs
        self.arrivals: dict[str, list[float]] = {node: [] for node in loop_outputs}
        for node, (topic, name) in loop_outputs.items():
            self.probe.node.create_subscription(topic.msg_type, name,
                                                lambda _m, n=node: self.arrivals[n].append(time.monotonic()),
                                                topic.qos)
        # the plant's events (lockstep stalls and resumes), as they arrive: all of them
        self.events: list[tuple[float, str]] = []
        events_qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1000,
                                reliability=contract.SIM_EVENTS.qos.reliability)
        self.probe.node.create_subscription(contract.SIM_EVENTS.msg_type, contract.SIM_EVENTS.name,
                                            lambda m: self.events.append((time.monotonic(), m.data)), events_qos)
        args = {"output": "screen", "sim_launch_prefix": "", **launch_args}
        self.launch = graph.start_launch(launch_file, standby=standby, **args)

    def pid(self, node: str) -> int | None:
        """The newest live process the launcher started or activated from a warm standby as node ``node`` (its
        ``__node:=`` name: two team_firmware processes share a label), else the newest labelled ``node`` (None
        before the first). A standby counts from its activation, when it became the node's process: it has a
        command line of its own, so it is known by its label (one seen with that node's name only)."""
        started = [(label, int(pid)) for label, pid in re.findall(r"\[(\S+)-\d+\]: process (?:started|activated "
                                                                 r"from standby) with pid \[(\d+)\]",
                                                                 self.launch.output())]
        for label, pid in reversed(started):
            try:
                argv = Path(f"/proc/{pid}/cmdline").read_bytes().split(b"\0")
            except OSError:
                continue
            names = [a.removeprefix(b"__node:=").decode() for a in argv if a.startswith(b"__node:=")]
            if names:
                self._label_nodes.setdefault(label, set()).update(names)
            elif self._label_nodes.get(label) == {node}:  # the spare keeps its own command line
                return pid
            if node in names:
                return pid
        found = [pid for label, pid in started if label == node]
        return found[-1] if found else None

    def wait_standbys_ready(self, node: str | None = None, timeout_s: float = 120.0) -> None:
        """Until the launcher's warm standby (one for every node of ours) is ready."""
        self.graph.spin_until(lambda: standbys_ready(self.launch.output(), node), timeout_s,
                              f"a ready warm standby for {node or 'every process'}")

    def log_size(self) -> int:
        return self.launch.log_path.stat().st_size

    def gate_closed_at(self, t_s: float, log_offset: int) -> float | None:
        """None while the plant's lockstep gate goes on without a robot it reported stalled since ``t_s``
        (monotonic; byte ``log_offset`` of the launch's output); else when it waited for every robot again (its
        last "resumed", by the log line's wall-clock stamp), or -inf when it stalled on none. The log has every
        event but writes them late; /sim/events has them as the outputs came, but may drop some of a burst:
        the gate counts as closed only once the log has at least as many stalls as /sim/events brought."""
        on_topic = sum(1 for t, text in self.events if t > t_s and _STALLED.search(text))
        with open(self.launch.log_path, "rb") as log:
            log.seek(log_offset)
            since = log.read().decode(errors="replace")
        if len(_STALLED.findall(since)) < on_topic or lockstep_stalled(since):
            return None
        resumed = [float(t) for t in _RESUMED_AT.findall(since)]
        return max(resumed) + time.monotonic() - time.time() if resumed else -math.inf

    def all_flowing_since(self, t_s: float) -> bool:
        return all(times and times[-1] > t_s for times in self.arrivals.values())

    def wait_running(self, timeout_s: float = 120.0) -> None:
        start = time.monotonic()
        self.graph.spin_until(lambda: self.all_flowing_since(max(start, time.monotonic() - 0.5)), timeout_s,
                              "every node's loop output flowing")

    def kill_and_heal(self, node: str, respawn_delay_s: float, timeout_s: float = 60.0) -> float:
        """SIGKILL ``node``; wall seconds until the loop is closed again without help: the respawned node's
        output is back, after it every other node's output came again (the lockstep loop went round), and the
        plant's lockstep gate waits for every robot again (it resumed each one it reported stalled, /sim/events)."""
        old = self.pid(node)
        t_kill, log0 = time.monotonic(), self.log_size()
        os.kill(old, signal.SIGKILL)
        # Nothing that arrives before the respawn delay, or before the launcher has started the new process or
        # activated a standby, can be the new process's (on a loaded machine the old one's last messages can
        # arrive that late).
        t_back = [t_kill + respawn_delay_s, None]

        def healed() -> bool:
            if t_back[1] is None:
                if self.pid(node) in (None, old):
                    return False
                t_back[1] = max(t_back[0], time.monotonic())
            mine = [t for t in self.arrivals[node] if t > t_back[1]]
            return bool(mine) and self.all_flowing_since(mine[0]) and self.gate_closed_at(t_kill, log0) is not None

        self.graph.spin_until(healed, timeout_s, f"the loop closed again after {node} was killed")
        assert self.pid(node) != old, f"{node}: the loop closed, but not by a respawned process"
        first_back = next(t for t in self.arrivals[node] if t > t_back[1])
        flowing = max(next(t for t in times if t > first_back) for times in self.arrivals.values())
        return max(flowing, self.gate_closed_at(t_kill, log0)) - t_kill

    def pause_and_heal(self, node: str, pause_s: float, timeout_s: float = 60.0) -> float:
        """SIGSTOP ``node`` for ``pause_s`` of wall time (a debugger, a suspended laptop, a frozen container), then
        SIGCONT; wall seconds from SIGCONT until the loop is closed again by the same process: its output is back
        and after it every other node's output came again (as ``kill_and_heal``)."""
        pid = self.pid(node)
        t_stop, log0 = time.monotonic(), self.log_size()
        os.kill(pid, signal.SIGSTOP)
        try:
            resume_at = time.monotonic() + pause_s
            self.graph.spin_until(lambda: time.monotonic() >= resume_at, pause_s + 5.0, f"{node} paused")
        finally:
            os.kill(pid, signal.SIGCONT)
        t_cont = time.monotonic()

        def healed() -> bool:
            mine = [t for t in self.arrivals[node] if t > t_cont]
            return bool(mine) and self.all_flowing_since(mine[0]) and self.gate_closed_at(t_stop, log0) is not None

        self.graph.spin_until(healed, timeout_s, f"the loop closed again after {node} was paused")
        assert self.pid(node) == pid, f"{node}: the loop closed, but by a new process"
        first_back = next(t for t in self.arrivals[node] if t > t_cont)
        flowing = max(next(t for t in times if t > first_back) for times in self.arrivals.values())
        return max(flowing, self.gate_closed_at(t_stop, log0)) - t_cont


def closes_the_loop(loop, timeout_s: float = 60.0) -> None:
    """Ball at rest 1.5 m from robot_0: the catcher (fetch_resting_ball) drives the robot to it, through
    vision, the ball predictor, the catcher, the velocity controller, the motor boards and the plant."""
    probe = loop.probe
    n_events = len(loop.events())
    probe.wait_for_subscribers("/robot_0/sim/set_state", Odometry).publish(
        odometry_msg(0.0, (-1.0, 0.0, 0.0), (0.0, 0.0, 0.0)))
    probe.wait_for_subscribers("/sim/set_ball", Odometry).publish(odometry_msg(0.0, (0.5, 0.3, 0.0), (0.0, 0.0, 0.0)))

    def placed_at_s() -> float | None:
        """The sim time of the plant's report that it placed robot_0 ("t=<s> robot_0 placed at ...")."""
        for event in loop.events()[n_events:]:
            if "robot_0 placed at (-1.000, 0.000" in event:
                return float(event.split()[0].removeprefix("t="))
        return None

    def distance_to_ball_m() -> float:
        """From the ground truth of robot_0 and the ball, both stamped after the placement, else infinite."""
        odom = loop.watch.latest.get("/robot_0/ground_truth/odom")
        ball = loop.watch.latest.get("/ground_truth/ball")
        t_placed = placed_at_s()
        if odom is None or ball is None or t_placed is None or min(
                stamp_to_seconds(odom.header.stamp), stamp_to_seconds(ball.header.stamp)) <= t_placed:
            return math.inf
        r, b = odom.pose.pose.position, ball.pose.pose.position
        return math.hypot(r.x - b.x, r.y - b.y)

    # The plant's report, not the ground truth: the catcher drives the robot off at once, and a probe that lags
    # (it reads every topic) keeps only the newest ground truth, which may all come after the robot left.
    loop.spin_until(lambda: placed_at_s() is not None, 10.0, "robot_0 placed")
    loop.spin_until(lambda: distance_to_ball_m() < 0.25, timeout_s, "robot_0 at the ball")
