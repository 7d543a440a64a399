"""plant: the simulated world as a ROS 2 node. It owns time.

Every tick (``control_period_s``) it publishes each robot's ``wheel_states`` and ``/clock`` (at
``clock_rate_hz``) stamped with the tick's time, applies the robots' ``motor_duty`` and steps the physics;
vision frames, light barriers and ground truth (while read) go out as they fall due.

Pacing: ``lockstep`` advances a tick only once every live motor board answered it
(erforce_interfaces.runtime.lockstep), so runs are deterministic; a silent peer is reported on ``/sim/events``
after ``lockstep_timeout_s`` and driven with zero duty until it answers. ``realtime`` follows the wall
clock and applies the newest duties. ``real_time_factor`` > 0 caps the speed; a plant that fell behind
(stopped, starved, waiting out a peer) paces on from now instead of racing to catch up.

Both teams (``opponent_poses``; contract.Team) live under the same physics. ``lockstep_topics`` chooses
the lockstep messages: ``per_robot``, ``team`` (one per team and tick), ``both`` or ``field`` (one for
both teams); the gate is per robot either way.

Scenarios (``/sim/set_ball``, ``sim/set_state``, ``kick``, ``dribbler`` per robot) act at the next tick,
the newest of each; a body placed outside the field walls is refused with an error naming it.
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np
from nav_msgs.msg import Odometry
from rclpy.clock import Clock as RclClock
from rclpy.clock import ClockType
from std_msgs.msg import Bool, Float64, String

from erforce_interfaces.runtime.lockstep import DutyGate, FieldAnswerRobots
from erforce_interfaces.runtime.node_support import (
    SchemaNode,
    contract_publisher,
    contract_subscription,
    end_node,
    run_node,
)
from erforce_interfaces.runtime.param_schema import load_schema
from erforce_interfaces.ssl.ssl_sim import check_kick_angle
from erforce_interfaces.ssl.ssl_vision import BallModelFromVision
from erforce_interfaces.wire import contract
from erforce_interfaces.wire.clouds import vision_robots_cdr
from erforce_interfaces.wire.conversions import (
    ConversionError,
    clock_cdr,
    field_joint_state_cdr,
    field_joint_state_from_msg,
    float64_from_msg,
    joint_state_cdr,
    joint_state_from_msg,
    odometry_cdr,
    odometry_from_msg,
    odometry_height,
    point_cdr,
    pose2d_cdr,
    team_joint_state_cdr,
    team_joint_state_from_msg,
)
from erforce_interfaces.wire.robot_config import FieldConfig
from erforce_interfaces.wire.tables import table_cdr
from erforce_sim.ball import BallParams, BallState
from erforce_sim.camera_views import CameraViews
from erforce_sim.plant_setup import PlantSetup, build_world
from erforce_sim.sensors import VisionParams
from erforce_sim.ssl_cameras import CAMERA_MODELS, CameraRig, SslCameraSplitter, chip_model_of, open_multicast_sender
from erforce_sim.world_types import PhysicsParams

SCHEMA = load_schema("erforce_sim", "plant")
_SHARED_VISION = ("vision_noise_m", "vision_dropout")  # the bench cameras' shared noise and dropouts

_GEOMETRY_PERIOD_S = 1.0  # SSL-Vision repeats its geometry; late joiners get it within this
_MAX_TICKS_PER_PUMP = 50  # keep the executor responsive when nobody gates the ticks
_MAX_LAG_S = 0.1  # wall seconds behind real-time pacing that the plant makes up by ticking faster; beyond, it re-paces
_RETRY_S = 0.05  # re-publish an unanswered tick (lost message, late joiner, a flood that pushed it out of a
# reader's queue); duplicates are harmless
_STARTUP_GRACE_S = 0.1  # after the readers are matched (_ready_to_start); a restarted plant waits it too


def setup_from_params(config) -> PlantSetup:
    """The world's setup from a config object of the schema (all of it read-only: fixed at start)."""
    def poses(name: str) -> tuple[tuple[float, ...], ...]:
        values = getattr(config, name)
        if len(values) % 3:
            raise ValueError(f"{name}: need x, y, yaw per robot, got {len(values)} values")
        return tuple(tuple(values[i : i + 3]) for i in range(0, len(values), 3))

    cameras = CAMERA_MODELS[config.camera_model]
    if not cameras.shared_world_noise:
        for name in _SHARED_VISION:
            if getattr(config, name) != SCHEMA.default(name):
                raise ValueError(f"{name}: camera_model {cameras.name!r} draws its noise and misses per camera; "
                                 f"{name} is the shared cameras' (bench) and must keep its default "
                                 f"{SCHEMA.default(name)!r}, got {getattr(config, name)!r}")
    if cameras.object_offset_m > 0.0 and config.vision_output != "ssl":
        raise ValueError(f"camera_model {cameras.name!r}: its per-camera object offset ({cameras.object_offset_m:g} m) "
                         "is taken off only by the SSL bridge's camera_alignment; vision_output "
                         f"{config.vision_output!r} has no alignment stage: use vision_output ssl or camera_model "
                         "bench")
    return PlantSetup(
        field_preset=config.field,
        robot_poses=poses("robot_poses"),
        opponent_poses=poses("opponent_poses"),
        our_color=config.team_color,
        kicker_plates=config.kicker_plates,
        controlled=tuple(bool(c) for c in config.controlled),
        ball=config.ball,
        control_period_s=config.control_period_s,
        seed=config.seed,
        robot=config.robot,
        physics=PhysicsParams(substep_hz=config.substep_hz, kick_spin_ratio=config.kick_spin_ratio),
        ball_params=BallParams.from_model(config.ball_a_slide_mps2, config.ball_a_roll_mps2),
        vision=VisionParams(
            rate_hz=config.vision_rate_hz,
            latency_s=config.vision_latency_s,
            position_noise_m=config.vision_noise_m,
            ball_dropout_prob=config.vision_dropout,
            robot_dropout_prob=config.vision_dropout,
        ),
        cameras=cameras,
    )


def _check_pacing(config):
    """The parameters that change at run time, as a whole (pacing, real_time_factor)."""
    if config.pacing == "realtime" and config.real_time_factor <= 0.0:
        raise ValueError("realtime pacing needs real_time_factor > 0")
    return config


class PlantNode(SchemaNode):
    @staticmethod
    def warm_up() -> None:
        """For a warm standby (node_support.run_node): the world's kernels load with the first world built
        (~0.4 s of CPU), so a throwaway world loads them before the node's own is needed."""
        build_world(PlantSetup())

    def __init__(self) -> None:
        super().__init__("plant", SCHEMA, _check_pacing)
        self._pump_timer = None
        self.setup = setup_from_params(self._params.config)
        self.world = build_world(self.setup)  # refuses bodies off the field with a clear error
        setup = self.setup
        self._n = setup.num_robots + setup.num_opponents  # world indices: ours, then the opponents
        self._kick_angles: dict[int, float] = {}  # robot -> the elevation of its next kicks [deg] (kick_angle)
        self._index_robots()
        self._gate = DutyGate(self._n, self._values["lockstep_timeout_s"], names=self._names)
        self._latest_duty = {i: None for i in range(self._n)}
        self._tick = 0
        self._period_ns = self.setup.period_ns
        self._started = False
        self._ended = False  # end_node was called: no further tick
        self._start_wall = time.monotonic()
        self._peers_seen_at: float | None = None
        self._pace_origin: tuple[float, int] | None = None
        self._last_publish_wall = 0.0
        self._last_clock_ns = -(10**18)
        self._schedule_ground_truth()
        self._barrier_state = np.full(self._n, -1, dtype=np.int8)  # as last published (-1: not yet)
        self._all_robots = self.world.all_robots  # np.arange(n), the one World.set_duties recognises
        self._duties = np.zeros((self._n, len(self._wheels)))  # the duties a tick applies, row per robot
        topics = self._values["lockstep_topics"]
        self._per_robot_lockstep = topics in ("per_robot", "both")
        self._team_lockstep = topics in ("team", "both")
        self._field_lockstep = topics == "field"
        self._index_lockstep_teams()
        self._create_world_topics()
        self._create_robot_topics()
        self._create_lockstep_topics()
        self._setup_vision()
        self._apply_params(self._params.config)
        self._params.on_change(self._apply_params)
        # Who answers is a graph query (slow): refreshed 5 times a second, not every tick.
        self.create_timer(0.2, self._refresh_peers, clock=RclClock(clock_type=ClockType.STEADY_TIME))
        self.get_logger().info(
            f"plant: {setup.num_robots} robot(s) and {setup.num_opponents} opponent(s), {setup.field_preset}, "
            f"tick {setup.control_period_s * 1e3:g} ms, "
            f"{self._values['pacing']} pacing, {topics} lockstep topics"
        )

    def _index_robots(self) -> None:
        """Each world index as the graph knows it: its team and its id in the team, its namespace, its
        colour in vision, whether it is controlled."""
        setup, n = self.setup, self._n
        self._robots = [(contract.OPPONENTS if opp else contract.OURS, j) for opp, j in map(setup.team_of, range(n))]
        self._names = [team.namespace(j) for team, j in self._robots]
        self._index = {(team.name, j): i for i, (team, j) in enumerate(self._robots)}
        self._vision_index = {(setup.opponent_color if team is contract.OPPONENTS else setup.our_color, j): i
                              for i, (team, j) in enumerate(self._robots)}
        self._wheels = setup.robot.wheel_names
        # immutable: a change of control is a new set, and so a new key of the field answers' robot sets
        self._controlled = frozenset(i for i in range(n) if setup.is_controlled(i))

    def _schedule_ground_truth(self) -> None:
        """Ground truth: the ball's and each robot's, each at ground_truth_rate_hz, the robots taking turns over
        the ticks of one period (a tick publishes a few of them, not all at once): index n is the ball."""
        n = self._n
        truth_period_ns = 1e9 / self._values["ground_truth_rate_hz"]
        slots = max(1, int(truth_period_ns // self._period_ns))
        self._last_truth_ns = np.array([((i + 1) * slots // (n + 1)) * self._period_ns - truth_period_ns
                                        for i in range(n)] + [-truth_period_ns], dtype=float)

    def _index_lockstep_teams(self) -> None:
        """Per team with robots on the field: its controlled world indices (ours come first in
        _controlled_ids), their rows among the sensed ones and their ids in the team."""
        self._controlled_ids = tuple(sorted(self._controlled))
        self._team_ids = {team: [i for i in self._controlled_ids if self._robots[i][0] is team]
                          for team in (contract.OURS, contract.OPPONENTS)
                          if team is contract.OURS or self.setup.num_opponents}
        self._team_rows = {team: np.array([self._controlled_ids.index(i) for i in ids], dtype=np.int64)
                           for team, ids in self._team_ids.items()}
        self._team_robot_ids = {team: tuple(self._robots[i][1] for i in ids) for team, ids in self._team_ids.items()}
        self._team_named: set[int] = set()  # robots some team or field motor_duty answer was for
        # a field answer's robot ids (ours, theirs) -> their world indices, once all of them were taken robot by
        # robot (all controlled: _team_named has them)
        self._field_answer_robots = FieldAnswerRobots(
            *({j: i for i, (team, j) in enumerate(self._robots) if team is side}
              for side in (contract.OURS, contract.OPPONENTS)))
        # the field message's robot ids: (ours, the opponents')
        self._field_robot_ids = (self._team_robot_ids[contract.OURS], self._team_robot_ids.get(contract.OPPONENTS, ()))

    def _create_world_topics(self) -> None:
        """The publishers of the world as a whole (clock, events, vision, the ball's truth) and the scenario
        commands' inbox."""
        q, pub = contract, contract_publisher
        self._clock_pub = pub(self, q.CLOCK)
        self._events_pub = pub(self, q.SIM_EVENTS)
        self._vision_ball_readers = [0]  # /vision/ball goes out only while it has readers (tools)
        self._vision_ball_pub = pub(self, q.VISION_BALL, readers=(self._vision_ball_readers, 0))
        self._vision_robots_pub = pub(self, q.VISION_ROBOTS)
        self._vision_pose_readers = [0] * self._n  # a robot's vision_pose goes out only while it has readers
        self._truth_ball_pub = pub(self, q.GROUND_TRUTH_BALL)
        # Scenario commands act at the next tick, the newest of each: a callback only keeps the message, so
        # a flood costs a take per message, not a placement or kick (with its event) each, and a tick costs
        # nothing for the many scenario topics nobody publishes on.
        self._scenario_pending: dict[str, Any] = {}
        self._scenario_overtaken = 0

    def _scenario(self, key: str, apply):
        """A scenario command's callback: it keeps the newest message under ``key`` for the next tick."""
        def keep(msg):
            self._scenario_overtaken += key in self._scenario_pending
            self._scenario_pending.pop(key, None)  # the newest goes last: commands act in arrival order
            self._scenario_pending[key] = lambda: apply(msg)
        return keep

    def _create_robot_topics(self) -> None:
        """Per robot its sensors' publishers, its motor_duty (per-robot lockstep) and its scenario commands;
        then the ball's placement and the list of ground-truth publishers."""
        q, pub, sub, scenario = contract, contract_publisher, contract_subscription, self._scenario
        self._pubs: list[dict[str, Any]] = []
        for i, (team, j) in enumerate(self._robots):
            self._pubs.append(
                {
                    "states": pub(self, q.WHEEL_STATES, team.topic(q.WHEEL_STATES, j)) if self._per_robot_lockstep
                    else None,
                    "vision": pub(self, q.VISION_POSE, team.topic(q.VISION_POSE, j),
                                  readers=(self._vision_pose_readers, i)),
                    "barrier": pub(self, q.BALL_DETECTED, team.topic(q.BALL_DETECTED, j)),
                    "truth": pub(self, q.GROUND_TRUTH_ODOM, team.topic(q.GROUND_TRUTH_ODOM, j)),
                    "motors": pub(self, q.GROUND_TRUTH_MOTORS, team.topic(q.GROUND_TRUTH_MOTORS, j)),
                }
            )
            if self._per_robot_lockstep:
                sub(self, q.MOTOR_DUTY, lambda m, i=i: self._on_duty(i, m), team.topic(q.MOTOR_DUTY, j), raw=True)
            sub(self, q.KICK, scenario(f"kick{i}", lambda m, i=i: self._on_kick(i, m)), team.topic(q.KICK, j))
            sub(self, q.KICK_ANGLE, scenario(f"kick_angle{i}", lambda m, i=i: self._on_kick_angle(i, m)),
                team.topic(q.KICK_ANGLE, j))
            sub(self, q.DRIBBLER, scenario(f"dribbler{i}", lambda m, i=i: self._on_dribbler(i, m)),
                team.topic(q.DRIBBLER, j))
            sub(self, q.SIM_SET_STATE, scenario(f"set{i}", lambda m, i=i: self._on_set_robot(i, m)),
                team.topic(q.SIM_SET_STATE, j))
        sub(self, q.SIM_SET_BALL, scenario("ball", self._on_set_ball))
        # Ground truth goes out only while it has readers (tools, recorders, tests), counted with the peers (a
        # reader event per publisher would cost every wait of the executor): per robot its odometry and motors,
        # then the ball's.
        self._truth_pubs = [p[key] for p in self._pubs for key in ("truth", "motors")] + [self._truth_ball_pub]
        self._truth_readers = [0] * len(self._truth_pubs)
        self._peers: set[int] = set()

    def _create_lockstep_topics(self) -> None:
        """The team-level and field-level lockstep topics, as lockstep_topics asks."""
        q, pub, sub = contract, contract_publisher, contract_subscription
        if self._team_lockstep:
            self._team_states_pubs = {}
            for team in self._team_ids:
                self._team_states_pubs[team] = pub(self, q.TEAM_WHEEL_STATES, team.lockstep_topic(q.TEAM_WHEEL_STATES))
                sub(self, q.TEAM_MOTOR_DUTY, lambda m, team=team: self._on_team_duty(team, m),
                    team.lockstep_topic(q.TEAM_MOTOR_DUTY), raw=True)
        if self._field_lockstep:
            self._field_states_pub = pub(self, q.FIELD_WHEEL_STATES)
            sub(self, q.FIELD_MOTOR_DUTY, self._on_field_duty, raw=True)

    def _apply_params(self, config) -> None:
        """Pacing, real-time factor and stall timeout take effect at once (the rest is read-only)."""
        self._gate.timeout_s = config.lockstep_timeout_s
        self._pace_origin = (time.monotonic(), self._tick) if self._started else None
        if self._pump_timer is not None:
            self.destroy_timer(self._pump_timer)
        # Every wake of an rclpy executor costs ~0.4 ms of CPU here. Lockstep ticks are driven by
        # the duty answers; the timer only paces (real time, capped lockstep) and checks for stalls.
        paced = config.pacing == "realtime" or config.real_time_factor > 0.0
        self._pump_timer = self.create_timer(self.setup.control_period_s if paced else 0.02, self._pump,
                                             clock=RclClock(clock_type=ClockType.STEADY_TIME))

    # ---------------------------------------------------------------- inputs
    def _event(self, text: str, warn: bool = False) -> None:
        if warn:  # rclpy ties a severity to each call site: two call sites
            self.get_logger().warning(text)
        else:
            self.get_logger().info(text)
        self._events_pub.publish(String(data=f"t={self.world.t_s:.3f} {text}"))

    def _on_duty(self, robot: int, msg: bytes) -> None:
        try:
            t_ns, duty = joint_state_from_msg(msg, len(self._wheels), "effort")
        except ConversionError as exc:
            # A broken answer still answers the tick, with the motors off: lockstep goes on.
            self._warn.warn(f"duty{robot}", f"{self._names[robot]}: rejected motor_duty ({exc}); motors off")
            t_ns = self._tick * self._period_ns
            duty = None
        self._take_duty(robot, t_ns, duty)
        if t_ns == self._gate.tick_ns:  # only an answer to the open tick can let it advance (a flood of others
            self._pump()                # costs no pump each; the pacing timer still runs)

    def _on_team_duty(self, team: contract.Team, msg: bytes) -> None:
        topic = team.lockstep_topic(contract.TEAM_MOTOR_DUTY)
        try:
            t_ns, ids, (duties,) = team_joint_state_from_msg(msg, len(self._wheels), ("effort",), team=team)
        except ConversionError as exc:  # no robot to answer for: the robots stall, and are reported, if it lasts
            self._warn.warn(f"team_duty_{team.name}", f"rejected {topic} ({exc})")
            return
        self._take_team_duties(topic, t_ns, team, ids, duties)
        if t_ns == self._gate.tick_ns:
            self._pump()

    def _on_field_duty(self, msg: bytes) -> None:
        topic = contract.FIELD_MOTOR_DUTY.name
        try:
            t_ns, (ours, theirs), (duties,) = field_joint_state_from_msg(msg, len(self._wheels), ("effort",))
        except ConversionError as exc:  # as a team answer: the robots stall, and are reported, if it lasts
            self._warn.warn("field_duty", f"rejected {topic} ({exc})")
            return
        robots = self._field_answer_robots.lookup(ours, theirs, self._controlled)
        if robots is None:  # a robot set not seen before: robot by robot, with a warning for any not ours
            self._take_team_duties(topic, t_ns, contract.OURS, ours, duties)
            self._take_team_duties(topic, t_ns, contract.OPPONENTS, theirs, duties[len(ours):])
            self._field_answer_robots.learn(ours, theirs, self._controlled)  # the usual answer: next time at once
        else:
            self._latest_duty.update(zip(robots, duties, strict=True))
            for event in self._gate.offer_rows(robots, t_ns, duties):
                self._event(event)
        if t_ns == self._gate.tick_ns:
            self._pump()

    def _take_team_duties(self, topic: str, t_ns: int, team: contract.Team, ids: tuple[int, ...],
                          duties: np.ndarray) -> None:
        """The answers of a team or field message for ``team``'s robots ``ids`` (duty row k for ids[k])."""
        for k, robot_id in enumerate(ids):
            robot = self._index.get((team.name, robot_id))
            if robot not in self._controlled:
                self._warn.warn(f"team_duty_{team.name}{robot_id}", f"{topic} for {team.namespace(robot_id)}, which is "
                                f"not a controlled robot of this plant; ignored")
                continue
            self._team_named.add(robot)
            self._take_duty(robot, t_ns, duties[k])

    def _take_duty(self, robot: int, t_ns: int, duty: np.ndarray | None) -> None:
        if duty is not None:
            self._latest_duty[robot] = duty
        event = self._gate.offer(robot, t_ns, duty if duty is not None else np.zeros(len(self._wheels)))
        if event:
            self._event(event)

    def _on_kick(self, robot: int, msg: Float64) -> None:
        angle = self._kick_angles.get(robot, 0.0)
        try:
            speed = float64_from_msg(msg, limit=100.0)
            result = self.world.kick(robot, speed, armed_for_s=0.1, angle_deg=angle)
        except (ConversionError, ValueError) as exc:
            self._warn.warn(f"kick{robot}", f"{self._names[robot]}: rejected kick: {exc}")
            return
        state = "fired" if result.fired else ("armed" if result.armed else "no ball at the kicker")
        clamped = " (clamped)" if result.clamped else ""
        chip = f" chip {angle:g} deg" if angle > 0.0 else ""
        self._event(f"{self._names[robot]} kick {result.speed_mps:.2f} m/s{chip}{clamped}: {state}")

    def _on_kick_angle(self, robot: int, msg: Float64) -> None:
        """The elevation of this robot's next kicks (0 flat, else a chip); a bad one leaves the last in force."""
        try:
            self._kick_angles[robot] = check_kick_angle("kick_angle", float64_from_msg(msg, limit=90.0))
        except (ConversionError, ValueError) as exc:
            self._warn.warn(f"kick_angle{robot}", f"{self._names[robot]}: rejected kick_angle: {exc}")

    def _on_dribbler(self, robot: int, msg: Float64) -> None:
        try:
            on = float64_from_msg(msg, limit=1.0e5) > 0.0
        except ConversionError as exc:
            self._warn.warn(f"dribbler{robot}", f"{self._names[robot]}: rejected dribbler: {exc}")
            return
        self.world.set_dribbler(robot, on)

    def _on_set_ball(self, msg: Odometry) -> None:
        """A ball with a height or a vertical speed (pose.position.z, twist.linear.z) is put in the air without spin:
        a chip as a scenario launches it; else it is placed on the ground, rolling."""
        try:
            _, pose, velocity, _ = odometry_from_msg(msg)
            z_m, vz_mps = odometry_height(msg)
            if z_m == 0.0 and vz_mps == 0.0:
                self.world.place_ball(pose[0], pose[1], velocity[0], velocity[1])
            else:
                self.world.set_ball_state(BallState(pose[0], pose[1], velocity[0], velocity[1], z=z_m, vz=vz_mps))
        except (ConversionError, ValueError) as exc:
            self._warn.warn("set_ball", f"rejected /sim/set_ball: {exc}")
            return
        air = "" if z_m == 0.0 and vz_mps == 0.0 else f" in the air (z {z_m:.3f} m, vz {vz_mps:.2f} m/s)"
        self._event(f"ball placed at ({pose[0]:.3f}, {pose[1]:.3f}) with ({velocity[0]:.2f}, {velocity[1]:.2f}) m/s"
                    + air)

    def _on_set_robot(self, robot: int, msg: Odometry) -> None:
        try:
            _, pose, velocity, _ = odometry_from_msg(msg)
            self.world.place_robot(robot, pose[0], pose[1], pose[2], velocity[0], velocity[1], velocity[2])
        except (ConversionError, ValueError) as exc:
            self._warn.warn(f"set_robot{robot}", f"rejected {self._names[robot]}/sim/set_state: {exc}")
            return
        self._event(f"{self._names[robot]} placed at ({pose[0]:.3f}, {pose[1]:.3f}, {pose[2]:.3f})")

    # ---------------------------------------------------------------- ticking
    def _refresh_peers(self) -> None:
        q = contract
        self._truth_readers = [p.get_subscription_count() for p in self._truth_pubs]
        peers = set()
        if self._per_robot_lockstep:
            peers = {i for i in self._controlled if self.count_publishers(self._topic(q.MOTOR_DUTY, i)) > 0}
        # A team answer names its robots; until the first one, every controlled robot of the team is taken as
        # served (one that is not stalls once, after lockstep_timeout_s, and is reported).
        if self._team_lockstep:
            for team, ids in self._team_ids.items():
                if self.count_publishers(team.lockstep_topic(q.TEAM_MOTOR_DUTY)) > 0:
                    peers |= (self._team_named & set(ids)) or set(ids)
        if self._field_lockstep and self.count_publishers(q.FIELD_MOTOR_DUTY.name) > 0:
            peers |= (self._team_named & self._controlled) or self._controlled
        self._peers = peers

    def _topic(self, topic: contract.Topic, i: int) -> str:
        """The name of a per-robot topic for world index ``i``."""
        team, j = self._robots[i]
        return team.topic(topic, j)

    def _ready_to_start(self) -> bool:
        q = contract
        waited = time.monotonic() - self._start_wall
        readers = self._values["wheel_states_readers"]
        # every controlled robot served: on its own topics, or its team's (each team may use either). The
        # readers are counted as the tick's writers have matched them (get_subscription_count), not as the
        # graph lists them: tick 0 is then sent to each of them.
        team_served = {team for team in self._team_ids if self._team_lockstep
                       and self.count_publishers(team.lockstep_topic(q.TEAM_MOTOR_DUTY)) > 0
                       and self._team_states_pubs[team].get_subscription_count() >= readers}
        field_served = (self._field_lockstep and self.count_publishers(q.FIELD_MOTOR_DUTY.name) > 0
                        and self._field_states_pub.get_subscription_count() >= readers)
        robots_ok = field_served or all(
            self._robots[i][0] in team_served
            or (self._per_robot_lockstep and self.count_publishers(self._topic(q.MOTOR_DUTY, i)) > 0
                and self._pubs[i]["states"].get_subscription_count() >= readers)
            for i in self._controlled
        )
        clock_ok = self._clock_pub.get_subscription_count() >= self._values["start_clock_subscribers"]
        ok = robots_ok and clock_ok
        if not ok and waited > self._values["startup_timeout_s"]:
            self._event(f"starting without all controlled robots or /clock subscribers after {waited:.1f} s", warn=True)
            return True
        # Matching is not symmetric: a reader this writer has matched may not have matched the writer yet
        # (the two learn of each other from each other's announcements, within milliseconds here).
        # Start once the peers have been matched for a moment, so tick 0 reaches everyone.
        if not ok:
            self._peers_seen_at = None
            return False
        if self._peers_seen_at is None:
            self._peers_seen_at = time.monotonic()
        return time.monotonic() - self._peers_seen_at >= _STARTUP_GRACE_S

    def _pump(self) -> None:
        if self._ended:  # stop_after_s or a broken state: run_node ends the process after this callback
            return
        now = time.monotonic()
        if not self._started:
            if not self._ready_to_start():
                return
            self._started = True
            self._refresh_peers()
            self._pace_origin = (now, 0)
            self._publish_tick()
            self._confirm_time_line()
            return
        lockstep = self._values["pacing"] == "lockstep"
        for _ in range(_MAX_TICKS_PER_PUMP):
            if lockstep:
                for event in self._gate.check_stall(now):
                    self._event(event, warn=True)
                if not self._gate.ready():
                    if now - self._last_publish_wall > _RETRY_S:
                        self._publish_tick(retry=True)
                    return
            if not self._pace_allows(now):
                return
            self._advance(lockstep)
            if self._finished():
                return
            now = time.monotonic()

    def _pace_allows(self, now: float) -> bool:
        rtf = self._values["real_time_factor"]
        if rtf <= 0.0:
            return True
        wall0, tick0 = self._pace_origin
        sim_elapsed = (self._tick + 1 - tick0) * self._period_ns * 1e-9
        if now - wall0 - sim_elapsed / rtf > _MAX_LAG_S:
            # Behind by more than a moment (the plant was stopped or starved, or waited out a stalled peer): pace
            # from now on. Making it up would run the world flat out, every tick gated by the peers' answers,
            # and make their clocks jump.
            self._pace_origin = (now, self._tick)
            return False
        return sim_elapsed <= rtf * (now - wall0)

    def _advance(self, lockstep: bool) -> None:
        if self._scenario_pending:
            pending, self._scenario_pending = self._scenario_pending, {}
            for apply in pending.values():
                apply()
        if self._scenario_overtaken:
            self._warn.warn("scenario_flood", f"{self._scenario_overtaken} scenario command(s) overtaken by newer "
                            "ones in one tick")
            self._scenario_overtaken = 0
        duties = self._duties
        duties.fill(0.0)  # a silent or absent peer's motors get zero duty
        answers = self._gate.duties if lockstep else self._latest_duty
        for i, duty in answers.items():
            if duty is not None:
                duties[i] = duty
        if self.world.set_duties(self._all_robots, duties):
            for i in np.flatnonzero((np.abs(duties) > 1.0).any(axis=1)).tolist():
                clamped = int(np.count_nonzero(np.abs(duties[i]) > 1.0))
                self._warn.warn(f"clamp{i}", f"{self._names[i]}: {clamped} duty value(s) outside [-1, 1] clamped")
        self.world.step(self.setup.control_period_s)
        self._tick += 1
        if not self.world.all_finite():  # never publish a broken state; stop loudly instead
            self._event("physics produced a non-finite state; stopping", warn=True)
            self._ended = True
            end_node(self, 1)
            return
        self._publish_tick()

    def _finished(self) -> bool:
        stop = self._values["stop_after_s"]
        if stop > 0.0 and self._tick * self._period_ns * 1e-9 >= stop - 1e-12:
            self._event(f"stop_after_s reached at t={self.world.t_s:.3f} s")
            self._ended = True
            end_node(self, 0)
        return self._ended

    def _confirm_time_line(self) -> None:
        """Send tick 0's sensors and /clock once more at once. After a restart the peers' time rule
        (stamps.StampFilter) takes the new line only when a second stamp confirms it; the same stamp again
        counts, and sent now it does not wait for the retry (``_RETRY_S``) or the next /clock period."""
        self._publish_tick(retry=True)
        if self._last_clock_ns == 0:
            self._clock_pub.publish(clock_cdr(0))

    def _publish_tick(self, retry: bool = False) -> None:
        t_ns = self._tick * self._period_ns
        now = time.monotonic()
        self._last_publish_wall = now
        world = self.world
        # The tick's sensor values first: they start the motor boards' answer, which the next
        # tick waits for; everything else is published while the motor boards compute.
        ids = self._controlled_ids
        speeds, currents = world.wheel_sensors(ids)  # rows in ids order
        if self._per_robot_lockstep:
            for row, i in enumerate(ids):
                self._pubs[i]["states"].publish(  # serialized, as motor_boards explains
                    joint_state_cdr(  # the sensors saturate (conversions explains the choice)
                        t_ns, self._wheels, velocity=speeds[row], effort=currents[row], saturate=True,
                    )
                )
        if self._team_lockstep and ids:
            for team, rows in self._team_rows.items():  # each team's rows of the sensors
                if rows.size:
                    self._team_states_pubs[team].publish(team_joint_state_cdr(
                        t_ns, self._team_robot_ids[team], self._wheels, velocity=speeds[rows],
                        effort=currents[rows], saturate=True, team=team,
                    ))
        if self._field_lockstep and ids:  # both teams in one message: the sensors' rows are ours, then theirs
            self._field_states_pub.publish(field_joint_state_cdr(
                t_ns, self._field_robot_ids, self._wheels, velocity=speeds, effort=currents, saturate=True,
            ))
        if retry:
            return
        if t_ns - self._last_clock_ns >= 1e9 / self._values["clock_rate_hz"] - 1:
            self._last_clock_ns = t_ns
            self._clock_pub.publish(clock_cdr(t_ns))
        self._gate.open(t_ns, now, self._peers)
        for frame in world.poll_vision():
            detections = self._rig.detect(frame)  # one draw of the cameras for both outputs
            if self._camera_views is not None:
                self._publish_vision(frame, detections)
            if self._ssl is not None:
                self._ssl_queue.extend(self._ssl.packets(frame, detections))
        if self._ssl is not None:
            self._publish_ssl_vision()
        detected = world.light_barriers()
        changed = self._all_robots if t_ns % 100_000_000 == 0 else np.flatnonzero(detected != self._barrier_state)
        for i in changed.tolist():
            self._barrier_state[i] = detected[i]
            self._pubs[i]["barrier"].publish(Bool(data=bool(detected[i])))
        due = np.flatnonzero(t_ns - self._last_truth_ns >= 1e9 / self._values["ground_truth_rate_hz"] - 1)
        if due.size:
            self._last_truth_ns[due] = t_ns
            self._publish_truth(t_ns * 1e-9, due.tolist())

    def _setup_vision(self) -> None:
        """The cameras of both vision outputs, one CameraRig (camera_model): the ROS frames' camera views, the
        SSL-Vision packets."""
        v = self._values
        field = FieldConfig.preset(self.setup.field_preset)
        # The geometry's two-phase model is the plant's own ball physics in the paper's terms (ball.py):
        # decelerations mu g, and c_switch from the kick's backspin.
        ball = self.world.ball_params
        model = BallModelFromVision(-ball.a_slide_mps2, -ball.a_roll_mps2,
                                    ball.switch_ratio(self.setup.physics.kick_spin_ratio))
        self._rig = CameraRig.quadrants(field, self.setup.cameras, seed=self.setup.seed, ball_model=model,
                                        chip_model=chip_model_of(ball))
        self._camera_views = CameraViews(self._rig) if v["vision_output"] in ("ros", "both") else None
        self._ssl = None
        if v["vision_output"] == "ros":
            return
        self._ssl = SslCameraSplitter.on_rig(self._rig, self.setup.vision.latency_s)
        self._ssl_sock = open_multicast_sender(v["ssl_vision_interface"])
        self._ssl_address = (v["ssl_vision_group"], v["ssl_vision_port"])
        self._ssl_queue: list[tuple[float, bytes]] = []
        self._ssl_geometry_t = -math.inf

    def _send_ssl(self, data: bytes) -> None:
        try:
            self._ssl_sock.sendto(data, self._ssl_address)
        except OSError as exc:  # a full socket buffer or no route: this frame is lost, as on a network
            self._warn.warn("ssl_send", f"SSL-Vision packet not sent: {exc}")

    def _publish_ssl_vision(self) -> None:
        """The geometry when due and the queued camera packets whose release time has come."""
        t = self.world.t_s
        if t - self._ssl_geometry_t >= _GEOMETRY_PERIOD_S:
            self._ssl_geometry_t = t
            self._send_ssl(self._ssl.geometry_packet())
        due = [p for p in self._ssl_queue if p[0] <= t + 1e-9]
        if due:
            self._ssl_queue = [p for p in self._ssl_queue if p[0] > t + 1e-9]
            for _release, data in sorted(due, key=lambda p: p[0]):
                self._send_ssl(data)

    def _publish_vision(self, frame, detections) -> None:
        """A world frame on /vision/robots (serialized, as the ball predictor takes it): the ball as the camera that
        takes it sees it, after that camera's point, with every robot; then each other camera that sees the ball
        its own frame with its point and its view as a sighting (camera_views; docs/decisions/0035)."""
        t = frame.t_capture_s
        seen = self._camera_views.frame_views(frame, detections)
        views = seen.balls
        balls = [(view.x_m, view.y_m) for view in views[:1]]
        if self._vision_ball_readers[0]:
            for xy in balls:
                self._vision_ball_pub.publish(point_cdr(t, xy))
        if not (seen.robots or balls):
            return
        rows, read = [], []
        for det in seen.robots:
            i = self._vision_index[det.team, det.robot_id]
            team, j = self._robots[i]
            rows.append((team.code, j, det.x, det.y, det.theta))
            if self._vision_pose_readers[i]:
                read.append((i, det))
        self._vision_robots_pub.publish(vision_robots_cdr(t, rows, balls=balls,
                                                          camera=views[0].camera if views else None))
        for view in views[1:]:
            self._vision_robots_pub.publish(vision_robots_cdr(t, (), camera=view.camera,
                                                              sightings=[(view.x_m, view.y_m)]))
        for i, det in read:
            self._pubs[i]["vision"].publish(pose2d_cdr(t, (det.x, det.y, det.theta)))

    def _publish_truth(self, t_s: float, due: list[int]) -> None:
        """The ground truth of the robots in ``due`` (world indices; the index after the last robot: the ball)."""
        world, n, readers = self.world, self._n, self._truth_readers
        if due[-1] == n:
            due = due[:-1]
            if readers[2 * n]:  # serialized, as vision: building these messages was an eighth of the plant's time
                b = world.ball_state()
                self._truth_ball_pub.publish(
                    odometry_cdr(t_s, (b.x, b.y, 0.0), (b.vx, b.vy, 0.0), "ball", spin=(b.wx, b.wy, b.wz), z_m=b.z,
                                 vz_mps=b.vz)
                )
        for i in due:
            if not (readers[2 * i] or readers[2 * i + 1]):
                continue
            team, j = self._robots[i]
            r = world.robot_state(i)
            if readers[2 * i]:
                self._pubs[i]["truth"].publish(
                    odometry_cdr(t_s, (r.x, r.y, r.theta), (r.vx, r.vy, r.w), team.frame(j))
                )
            if not readers[2 * i + 1]:
                continue
            rows = [
                [r.currents_a[k], r.winding_temperatures_c[k], r.wheel_speeds_radps[k]]
                for k in range(len(self._wheels))
            ]
            self._pubs[i]["motors"].publish(table_cdr(rows, contract.GROUND_TRUTH_MOTOR_COLUMNS, "wheels"))


def main(args: list[str] | None = None) -> int:
    return run_node(PlantNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
