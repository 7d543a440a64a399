"""The wire contract of the stack: every topic, its message type, QoS, frame and units.

No node spells a topic string itself: it takes a ``Topic`` from here. Per-robot topics are relative
names under ``robot_<id>`` (ours) or ``opponent_<id>`` (the other team, ``Team``; each team numbers its
robots from 0 as SSL does); a node serving all robots resolves them with ``Topic.for_robot`` or
``Team.topic``.

Conventions (REP 103 / REP 105): SI units (temperatures in degrees Celsius, as sensor_msgs/Temperature);
``field`` has its origin at the centre, x towards the positive goal, z up; ``robot_<id>/base_link`` has
x towards the dribbler; wheels are ``wheel_0 ..`` in the order of RobotConfig.wheel_angles_rad. Lockstep
answers carry the stamp of the sensor tick they answer. Nothing non-finite is ever published; "never"
as a catch time is ``CATCH_TIME_NEVER``.

The lockstep JointStates exist per robot, per team (``/team/...``, ``/opponent_team/...``; joints
``robot_<id>/wheel_<k>``, each team's firmware sees only its own) and per field (``/field/...``, both
teams in one message, ours first): the values per robot are the same in all three, so they give the
same trajectory; the team and field forms save messages and wakes.

Vision reaches the graph the same way from the plant's cameras and from SSL-Vision (the bridge turns
millimetres into metres and the vision frame into ``field``, so that we always defend negative x):
one ``/vision/robots`` per camera frame, its ball first; ``/vision/ball`` and each ``vision_pose`` only
while read; geometry and the ball model transient local on ``/vision/field`` and ``/vision/ball_model``.
"""

from __future__ import annotations

import importlib
import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from geometry_msgs.msg import PointStamped, PoseStamped, Twist
from nav_msgs.msg import Odometry
from rclpy.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    QoSProfile,
    ReliabilityPolicy,
)
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState, PointCloud2
from std_msgs.msg import Bool, Float64, Float64MultiArray, String

from erforce_interfaces.wire.ament_index import find_package_share
from erforce_interfaces.wire.robot_config import BALL_CHIP_DAMPING_NAMES

FIELD_FRAME = "field"
ROBOT_NAMESPACE_PREFIX = "robot_"
OPPONENT_NAMESPACE_PREFIX = "opponent_"
BASE_LINK = "base_link"

#: Published on ``catch_time`` when no catch is possible before the ball leaves the field.
CATCH_TIME_NEVER = -1.0

#: Values of ``/ball/phase`` ("chip": a chipped ball from its detection until its first touchdown, "hopping": after
#: it until it rolls, so that a receiver rebuilding the chip from /ball/state damps its next bounce as a later one;
#: last, so that the indices /ball/track carries stay those of the flat phases).
BALL_PHASES = ("unknown", "sliding", "rolling", "stopped", "chip", "hopping")

# DDS participant settings (config/fastdds_profile.xml): announce every 0.5 s, so that a node that
# (re)starts is matched within about a second. Fast DDS 2 (Jazzy) reads the first variable, 3 the second.
DDS_PROFILE_VARIABLES = ("FASTRTPS_DEFAULT_PROFILES_FILE", "FASTDDS_DEFAULT_PROFILES_FILE")
# ROS 2's discovery settings (Jazzy): how far automatic discovery reaches, and the hosts always asked.
# The stack's default range is LOCALHOST (launch files, erforce-launch, the test harness).
DISCOVERY_RANGE = "ROS_AUTOMATIC_DISCOVERY_RANGE"
STATIC_PEERS = "ROS_STATIC_PEERS"

# Writers send from the publishing thread (Fast DDS's synchronous publication) instead of queueing each
# sample for rmw_fastrtps' default asynchronous sender thread: one thread hand-over less per message,
# which is most of what this graph pays per message (docs/decisions/0005).
DDS_PUBLICATION_MODE = {"RMW_FASTRTPS_PUBLICATION_MODE": "SYNCHRONOUS"}


def dds_profile_path(localhost: bool = False) -> Path:
    """The stack's Fast DDS profile in erforce_interfaces' share directory (as $(find-pkg-share)):
    config/fastdds_profile.xml, or with ``localhost`` config/fastdds_localhost.xml (``dds_profile_env``)."""
    name = "fastdds_localhost.xml" if localhost else "fastdds_profile.xml"
    share = find_package_share("erforce_interfaces")
    path = None if share is None else share / "config" / name
    if path is None or not path.is_file():
        raise FileNotFoundError(f"config/{name} of erforce_interfaces not found")
    return path


def dds_profile_env(environ: Mapping[str, str] = os.environ) -> dict[str, str]:
    """The variables to add to a process environment for the stack's DDS settings.

    - the publication mode, unless ``environ`` sets one;
    - unless ``environ`` names a profile of its own (the user's, or the two-host test's): for localhost-only
      discovery (DISCOVERY_RANGE LOCALHOST, the stack's default) without static peers, the range
      SYSTEM_DEFAULT and config/fastdds_localhost.xml, which keep discovery on this computer over UDP alone
      (the file says why: a restarted node is lost over Fast DDS's shared memory) with every socket on
      127.0.0.1 (its interface allowlist); for any other range, or
      none (ROS 2's default, the subnet), config/fastdds_profile.xml. Applying it twice changes nothing.
    """
    env = {name: value for name, value in DDS_PUBLICATION_MODE.items() if not environ.get(name)}
    named = next((environ[name] for name in DDS_PROFILE_VARIABLES if environ.get(name)), None)
    general, localhost = str(dds_profile_path()), str(dds_profile_path(localhost=True))
    if named not in (None, general, localhost):
        return env  # the user's own profile
    discovery_range = environ.get(DISCOVERY_RANGE, "")
    if named == localhost and discovery_range == "SYSTEM_DEFAULT":
        discovery_range = "LOCALHOST"  # set here before
    if discovery_range == "LOCALHOST" and not environ.get(STATIC_PEERS):
        if environ.get(DISCOVERY_RANGE) != "SYSTEM_DEFAULT":
            env[DISCOVERY_RANGE] = "SYSTEM_DEFAULT"
        profile = localhost
    else:
        profile = general
    env.update({name: profile for name in DDS_PROFILE_VARIABLES if environ.get(name) != profile})
    return env


def _keep_last(depth: int, reliable: bool = True, latched: bool = False) -> QoSProfile:
    """A keep-last profile: reliable or best effort, volatile or kept for late joiners (transient local)."""
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST, depth=depth,
        reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE,
    )


# QoS profiles. Vision behaves like a camera: best effort, newest wins. Commands and the
# lockstep control loop are reliable: a lost duty message would stall a tick.
QOS_SENSOR = _keep_last(5, reliable=False)
QOS_COMMAND = _keep_last(10)
QOS_CONTROL = _keep_last(50)
QOS_STATE = _keep_last(10)
# Models and geometry, state a late joiner needs at once (the ball model in use): the newest value is kept
# for it.
QOS_LATCHED = _keep_last(1, latched=True)
# /clock: reliable publisher, compatible with rclpy's best-effort clock subscription.
QOS_CLOCK = _keep_last(1)

# A log of events a late joiner needs whole (each pass as it ends): a tool started after the game did, or one
# whose discovery a loaded machine held up, still gets every entry.
QOS_LOG = _keep_last(1000, latched=True)

QOS_NAMES = {
    id(QOS_SENSOR): "sensor (best effort, keep last 5)",
    id(QOS_COMMAND): "command (reliable, keep last 10)",
    id(QOS_CONTROL): "control (reliable, keep last 50)",
    id(QOS_STATE): "state (reliable, keep last 10)",
    id(QOS_CLOCK): "clock (reliable, keep last 1)",
    id(QOS_LATCHED): "latched (reliable, transient local, keep last 1)",
    id(QOS_LOG): "log (reliable, transient local, keep last 1000)",
}


@dataclass(frozen=True)
class Topic:
    """One topic of the contract."""

    name: str  # absolute ("/clock") or relative to the robot namespace ("cmd_vel")
    msg_type: type
    qos: QoSProfile
    publisher: str
    subscribers: str
    units: str

    @property
    def per_robot(self) -> bool:
        return not self.name.startswith("/")

    def for_robot(self, robot_id: int) -> str:
        """Absolute name of a per-robot topic for robot ``robot_id``."""
        if not self.per_robot:
            raise ValueError(f"{self.name} is a global topic")
        return f"/{robot_namespace(robot_id)}/{self.name}"

    @property
    def type_name(self) -> str:
        module = self.msg_type.__module__.split(".")[0]
        return f"{module}/msg/{self.msg_type.__name__}"


@dataclass(frozen=True)
class Team:
    """One team's names on the graph: robot ``<id>`` (0.., as SSL numbers each team) has its per-robot topics
    under ``/<prefix><id>/`` and its frame ``<prefix><id>/base_link``; the team's lockstep topics live under
    ``lockstep_namespace`` with joints ``<prefix><id>/wheel_<k>``."""

    name: str  # the value of a node's ``team`` parameter that selects it
    prefix: str
    lockstep_namespace: str
    code: float  # the team in a ``team`` column (/ball/catches, /vision/robots) and ``kind`` (/vision/detections)

    def namespace(self, robot_id: int) -> str:
        if int(robot_id) != robot_id or robot_id < 0:
            raise ValueError(f"robot id must be a non-negative integer, got {robot_id!r}")
        return f"{self.prefix}{int(robot_id)}"

    def id_of_namespace(self, namespace: str) -> int | None:
        """The robot id of one of this team's namespaces (``/robot_3`` or ``robot_3`` -> 3); None for another."""
        name = namespace.strip("/")
        digits = name[len(self.prefix):]
        if not name.startswith(self.prefix) or not digits.isascii() or not digits.isdigit():
            return None
        return int(digits)

    def topic(self, topic: Topic, robot_id: int) -> str:
        """Absolute name of a per-robot topic for this team's robot ``robot_id`` (``/opponent_3/vision_pose``)."""
        if not topic.per_robot:
            raise ValueError(f"{topic.name} is a global topic")
        return f"/{self.namespace(robot_id)}/{topic.name}"

    def lockstep_topic(self, topic: Topic) -> str:
        """This team's name of a team-level lockstep topic (``/opponent_team/motor_duty``)."""
        if topic not in (TEAM_WHEEL_STATES, TEAM_MOTOR_DUTY):
            raise ValueError(f"{topic.name} is not a team-level lockstep topic")
        return f"{self.lockstep_namespace}/{topic.name.rsplit('/', 1)[1]}"

    def frame(self, robot_id: int) -> str:
        return f"{self.namespace(robot_id)}/{BASE_LINK}"

    def joint_names(self, robot_ids, wheel_names) -> tuple[str, ...]:
        """Joint names of a team-level JointState: ``<prefix><id>/wheel_<k>`` for each robot, then each wheel."""
        return tuple(f"{self.namespace(i)}/{w}" for i in robot_ids for w in wheel_names)


OURS = Team("ours", ROBOT_NAMESPACE_PREFIX, "/team", 1.0)
OPPONENTS = Team("opponents", OPPONENT_NAMESPACE_PREFIX, "/opponent_team", 2.0)
TEAMS = {team.name: team for team in (OURS, OPPONENTS)}


def robot_namespace(robot_id: int) -> str:
    return OURS.namespace(robot_id)


def robot_id_of_namespace(namespace: str) -> int | None:
    """The robot id of a robot namespace (``/robot_3`` or ``robot_3`` -> 3); None for any other namespace."""
    return OURS.id_of_namespace(namespace)


def opponent_id_of_namespace(namespace: str) -> int | None:
    """The opponent robot id of an opponent namespace (``/opponent_3`` -> 3); None for any other namespace."""
    return OPPONENTS.id_of_namespace(namespace)


def opponent_topic(topic: Topic, robot_id: int) -> str:
    """Absolute name of a per-robot topic for the opponents' robot ``robot_id`` (``/opponent_3/vision_pose``)."""
    return OPPONENTS.topic(topic, robot_id)


def topic_of_name(name: str) -> Topic | None:
    """The contract topic an absolute name stands for (``/robot_3/odom``, ``/opponent_1/vision_pose``: ODOM,
    VISION_POSE; ``/clock``: CLOCK; ``/opponent_team/motor_duty``: TEAM_MOTOR_DUTY), or None for a topic
    outside the contract."""
    namespace, _, relative = name.strip("/").partition("/")
    per_robot = bool(relative) and any(team.id_of_namespace(namespace) is not None for team in TEAMS.values())
    for team in TEAMS.values():
        if "/" + namespace == team.lockstep_namespace and relative:
            name = f"{OURS.lockstep_namespace}/{relative}"
    for topic in TOPICS:
        if (topic.name == relative if topic.per_robot else topic.name == name) and (per_robot or not topic.per_robot):
            return topic
    return None


def message_class(type_name: str) -> type:
    """The message class of a type name (``pkg/msg/Name``, as ``Topic.type_name`` writes it)."""
    pkg, _, name = type_name.split("/")
    return getattr(importlib.import_module(f"{pkg}.msg"), name)


def field_joint_names(robot_ids, wheel_names) -> tuple[str, ...]:
    """Joint names of a field-level JointState: ``robot_ids`` is (our ids, the opponents' ids); our joints, then
    the opponents' (``Team.joint_names`` of each)."""
    ours, theirs = robot_ids
    return OURS.joint_names(ours, wheel_names) + OPPONENTS.joint_names(theirs, wheel_names)


def team_joint_names(robot_ids, wheel_names) -> tuple[str, ...]:
    """Joint names of our team's team-level JointState (``Team.joint_names``)."""
    return OURS.joint_names(robot_ids, wheel_names)


def robot_frame(robot_id: int) -> str:
    return OURS.frame(robot_id)


# ---------------------------------------------------------------- global topics
CLOCK = Topic("/clock", Clock, QOS_CLOCK, "plant; ssl_vision_bridge (time_source capture)", "every node (use_sim_time)",
              "simulation time; the plant owns time. At the plant's clock_rate_hz (100 Hz; 50 Hz in "
              "team_sim.launch.yaml): ROS time moves in steps of that period and sim-time timers tick at most "
              "that often; the lockstep and per-frame work runs on message stamps. On an outside world, the "
              "cameras' capture time (the bridge's clock_period_s)")
VISION_BALL = Topic("/vision/ball", PointStamped, QOS_SENSOR, "plant (vision), ssl_vision_bridge; while subscribed",
                    "tools", "ball centre in `field` [m], stamp = capture time; noisy, delayed, with dropouts; the "
                    "same balls as /vision/robots")
BALL_STATE = Topic("/ball/state", Odometry, QOS_STATE, "ball_predictor", "catcher, tools",
                   "filtered ball: pose [m], twist.linear [m/s] in `field`; covariance from the filter (its "
                   "variance of x, y on the pose's diagonal, of vx, vy on the twist's); a chipped "
                   "ball in the air: pose.position.z its centre's height above its resting height [m] and "
                   "twist.linear.z its vertical speed [m/s] (both 0 on the ground), and the covariances' rows and "
                   "columns 0-2 those of (x, y, z) and (vx, vy, vz) of the fitted flight (from one camera the "
                   "height is far less sure than the ground track at first; 100 on a diagonal: not determined)")
BALL_PHASE = Topic("/ball/phase", String, QOS_STATE, "ball_predictor", "catcher, team_catcher, passing_game, tools",
                   "one of " + ", ".join(BALL_PHASES) + "; each frame's before its /ball/state")
BALL_STOP_POINT = Topic("/ball/stop_point", PointStamped, QOS_STATE, "ball_predictor", "tools",
                        "where the two-phase model says the ball comes to rest [m], `field` (a chip: where it "
                        "rolls out after its hops)")
BALL_V_SHOOT = Topic("/ball/v_shoot", Float64, QOS_STATE, "ball_predictor", "catcher, tools",
                     "tracked initial shot speed v_shoot [m/s]")
BALL_UNCERTAIN = Topic("/ball/uncertain", Bool, QOS_STATE, "ball_predictor", "tools",
                       "true after a ricochet until the model fits the observations again")
BALL_MODEL_PARAMS = Topic("/ball/model_params", Float64MultiArray, QOS_LATCHED, "ball_predictor", "catcher, tools",
                          "the two-phase model in use: row in_use of [a_slide_mps2, a_roll_mps2, c_switch], then "
                          "rows fit, std_error of the last online fit once there is one (labelled in layout.dim); "
                          "at start and on every change")
BALL_CHIP_MODEL_PARAMS = Topic("/ball/chip_model_params", Float64MultiArray, QOS_LATCHED, "ball_predictor",
                               "passing_game, catcher, team_catcher, tools",
                               "the chip model in use (a chipped ball's hops): row in_use of "
                               "BALL_CHIP_MODEL_PARAM_LABELS [g_mps2, damping_z, damping_xy_first_hop, "
                               "damping_xy_other_hops, min_hop_vz_mps, max_catch_height_m, max_receive_height_m] "
                               "(labelled in layout.dim); at start and on every change")
GROUND_TRUTH_BALL = Topic("/ground_truth/ball", Odometry, QOS_STATE, "plant; while subscribed", "tests, tools only",
                          "true ball: pose [m] (position.z: height in the air), twist.linear [m/s], twist.angular = "
                          "spin [rad/s], `field`")
SIM_SET_BALL = Topic("/sim/set_ball", Odometry, QOS_COMMAND, "scenario scripts, passing_game (the referee's "
                     "placement)", "plant",
                     "place the ball: pose.position [m], twist.linear [m/s], twist.angular spin [rad/s]; "
                     "position.z > 0 or linear.z != 0: in the air without spin (a chip; our plant)")
VISION_ROBOTS = Topic("/vision/robots", PointCloud2, QOS_SENSOR, "plant (vision), ssl_vision_bridge",
                      "ball_predictor, tools",
                      "one vision frame in one message (the bridge: one camera frame; the plant: a world frame with "
                      "its ball as the camera taking it sees it, then a frame of each other camera seeing the "
                      "ball, its view as a sighting): its ball and every robot, "
                      "both teams; a point each, fields VISION_ROBOT_FIELDS (float64, little endian, height 1): "
                      "x, y [m] and z = 0 in `field`, yaw [rad] in [-pi, pi], team (Team.code: 1 ours, 2 the "
                      "opponents; VISION_BALL_CODE 0: the ball, with yaw and robot_id 0), robot_id (within "
                      "the team); first the camera that took the frame, where known (VISION_CAMERA_CODE 3: x, y, z = "
                      "its position [m] in `field`, robot_id its camera id), then the ball, then (VISION_SIGHTING_CODE "
                      "4) the ball as this camera saw it at an instant the ball already has from another camera, "
                      "then the robots; without a camera point the ball is a ground sighting; stamp = capture time; "
                      "noisy, delayed, with dropouts")
VISION_DETECTIONS = Topic("/vision/detections", Float64MultiArray, QOS_SENSOR, "ssl_vision_bridge", "tools",
                          "one message per SSL camera frame, a table with columns VISION_DETECTION_COLUMNS: every "
                          "ball candidate and robot the camera saw, in `field` [m, rad]; age_s = receipt - capture "
                          "on the ROS clock [s]")
VISION_FIELD = Topic("/vision/field", Float64MultiArray, QOS_LATCHED, "ssl_vision_bridge",
                     "ball_predictor, catcher, team_catcher, passing_game, field_view",
                     "the world's field from SSL geometry, one row of VISION_FIELD_COLUMNS [m]: replaces the nodes' "
                     "field preset; with field from_geometry they judge nothing before it")
VISION_BALL_MODEL = Topic("/vision/ball_model", Float64MultiArray, QOS_LATCHED, "ssl_vision_bridge",
                          "ball_predictor", "SSL geometry's two-phase ball model, one row [a_slide_mps2, "
                          "a_roll_mps2, c_switch]")
VISION_CHIP_MODEL = Topic("/vision/chip_model", Float64MultiArray, QOS_LATCHED, "ssl_vision_bridge",
                          "ball_predictor", "SSL geometry's fixed-loss chip model, one row of VISION_CHIP_MODEL_LABELS "
                          "[damping_z, damping_xy_first_hop, damping_xy_other_hops] (labelled in layout.dim)")
TEAM_WHEEL_STATES = Topic("/team/wheel_states", JointState, QOS_CONTROL, "plant (motor sensors; lockstep_topics "
                          "team or both)", "team_firmware",
                          "every controlled robot's wheel_states in one message per tick: joint "
                          "`robot_<id>/wheel_<k>`, velocity = wheel speed [rad/s], effort = motor current [A]; "
                          "stamp = sensor tick; the opponents' on `/opponent_team/wheel_states`, joints "
                          "`opponent_<id>/wheel_<k>`")
TEAM_MOTOR_DUTY = Topic("/team/motor_duty", JointState, QOS_CONTROL, "team_firmware (lockstep_topics team)", "plant",
                        "the motor_duty of the robots one firmware process runs, in one message per tick: joint "
                        "`robot_<id>/wheel_<k>`, effort = PWM duty in [-1, 1]; stamp = answered tick; the "
                        "opponents' on `/opponent_team/motor_duty`")
FIELD_WHEEL_STATES = Topic("/field/wheel_states", JointState, QOS_CONTROL, "plant (motor sensors; lockstep_topics "
                           "field)", "team_firmware (both teams)",
                           "both teams' controlled robots' wheel_states in one message per tick: joints "
                           "`robot_<id>/wheel_<k>`, then `opponent_<id>/wheel_<k>`, velocity = wheel speed [rad/s], "
                           "effort = motor current [A]; stamp = sensor tick")
FIELD_MOTOR_DUTY = Topic("/field/motor_duty", JointState, QOS_CONTROL, "team_firmware (lockstep_topics field)",
                         "plant", "the motor_duty of the robots of both teams one firmware process runs, in one "
                         "message per tick: joints `robot_<id>/wheel_<k>`, then `opponent_<id>/wheel_<k>`, effort = "
                         "PWM duty in [-1, 1]; stamp = answered tick")
SIM_EVENTS = Topic("/sim/events", String, QOS_STATE, "plant, ssl_sim_bridge", "tools, demo",
                   "human-readable simulator events: kicks, contacts, lockstep stalls and resumes")
BALL_CATCHES = Topic("/ball/catches", Float64MultiArray, QOS_SENSOR, "ball_predictor (while subscribed)",
                     "passing_game, team_catcher, field_view, tools",
                     "both teams at one ball frame, one message for all robots: a table with columns "
                     "CATCH_TABLE_COLUMNS, a row per robot fresh at the frame, ours first, then the opponents "
                     "(its team, its id in the team, its tracked pose and velocity "
                     "at the frame's stamp [m, rad, m/s], `field`; its catch_time and catch_point as published "
                     "per robot, the point 0, 0 with a catch time of never); the AI's catch times: before the "
                     "per-robot catch_time and catch_point")
ROBOTS_TRACKED = Topic("/robots/tracked", Float64MultiArray, QOS_STATE, "ball_predictor (while subscribed)",
                       "passing_game, team_catcher (press_lanes, tracked_poses)",
                       "every robot of both teams the tracker holds (seen within robot_timeout_s), after each vision "
                       "frame that moved one: a table with columns TRACKED_ROBOT_COLUMNS, a row per robot, ours "
                       "first, then the opponents (its team, its id in the team, the stamp of its last accepted "
                       "pose as a header stamp carries it [s, ns], the tracker's pose, velocity and yaw rate then "
                       "[m, rad, m/s, rad/s], `field`: what its odom carries); a reader takes a row whose stamp "
                       "changed as a new odom, so that one message per frame replaces one odom per robot")
BALL_TRACK = Topic("/ball/track", PointCloud2, QOS_SENSOR, "ball_predictor (while subscribed)", "field_view, tools",
                   "the ball at one accepted vision frame, for observers, in one message: one point of fields "
                   "BALL_TRACK_FIELDS (float64, little endian, height 1, width 1): the filtered ball x, y, z [m] "
                   "(z as /ball/state's) and vx_mps, vy_mps [m/s] in `field` (as /ball/state), v_shoot_mps (as "
                   "/ball/v_shoot), "
                   "the observation seen_x_m, seen_y_m [m] (the vision ball answered), phase (the index "
                   "of /ball/phase's value in BALL_PHASES) and uncertain (1/0, as /ball/uncertain); stamp = "
                   "that observation's; after the per-robot outputs")
PASS_CHOICE = Topic("/pass/choice", Float64MultiArray, QOS_STATE, "passing_game (in one process: its bag)",
                    "field_view, tools",
                    "the pass the holder has chosen, one row of PASS_CHOICE_COLUMNS (robot ids of our team, "
                    "times [s] from the kick; safe 1/0 = margin_s >= safe_margin_s); no rows: no choice "
                    "(nobody holds the ball)")
PASS_RECORDS = Topic("/pass/records", Float64MultiArray, QOS_LOG, "passing_game", "demo, tools",
                     "one message per pass as it ends: one row of PASS_RECORD_COLUMNS (robot ids of each team, "
                     "times [s] from the kick, kick_speed_mps [m/s]; outcome PASS_OUTCOMES' index; caught_team "
                     "Team.code, 0 and caught_id -1 with actual_catch_s -1: nobody; first_opponent and "
                     "facing_target -1: none; opponent_predicted_s PASS_NO_OPPONENT_S: no opponent can; "
                     "kick_angle_deg 0: flat, else a chip)")

# ------------------------------------------------------------- per-robot topics
CMD_VEL = Topic("cmd_vel", Twist, QOS_COMMAND, "catcher / AI", "velocity_controller",
                "desired velocity in `base_link`: linear.x/y [m/s], angular.z [rad/s]")
WHEEL_STATES = Topic("wheel_states", JointState, QOS_CONTROL, "plant (motor sensors)",
                     "velocity_controller, motor_boards",
                     "per wheel: velocity = wheel speed [rad/s], effort = measured motor current [A]; "
                     "stamp = sensor tick")
WHEEL_SETPOINTS = Topic("wheel_setpoints", JointState, QOS_CONTROL, "velocity_controller", "motor_boards",
                        "per wheel: velocity = wheel-speed setpoint [rad/s]; stamp = answered tick")
MOTOR_DUTY = Topic("motor_duty", JointState, QOS_CONTROL, "motor_boards", "plant",
                   "per wheel: effort = PWM duty in [-1, 1]; stamp = answered tick")
MOTOR_STATUS = Topic("motor_status", Float64MultiArray, QOS_STATE, "motor_boards", "tools, demo",
                     "rows = wheels, columns = [avg_current_a, pwm_limit, saturated, limit_active]")
KICK = Topic("kick", Float64, QOS_COMMAND, "catcher / AI / scenario", "plant",
             "kick now with this ball speed [m/s] if the ball is at the kicker (in 3D: a chip at kick_angle)")
KICK_ANGLE = Topic("kick_angle", Float64, QOS_COMMAND, "AI / scenario", "plant, ssl_sim_bridge",
                   "the elevation of the kicks that follow [deg], the SSL RobotCommand's kick_angle: 0 flat, in "
                   "(0, 90) a chip; sent before the kick it is for")
BALL_DETECTED = Topic("ball_detected", Bool, QOS_STATE, "plant (light barrier), ssl_sim_bridge", "catcher, tools",
                      "light barrier across the dribbler: ball present (from an external simulator: its "
                      "dribbler ball contact)")
DRIBBLER = Topic("dribbler", Float64, QOS_COMMAND, "catcher / AI", "plant, ssl_sim_bridge",
                 "dribbler speed [rad/s], 0 = off (our plant's dribbler holds a ball at any speed above 0)")
VISION_POSE = Topic("vision_pose", PoseStamped, QOS_SENSOR, "plant (vision), ssl_vision_bridge; each while subscribed",
                    "per-robot tools", "robot pose in `field` [m, rad]; stamp = capture time; noisy, delayed, with "
                    "dropouts; the same poses as /vision/robots")
ODOM = Topic("odom", Odometry, QOS_STATE, "ball_predictor (tracker)", "catcher",
             "filtered robot pose and velocity in `field`, child frame `robot_<id>/base_link`; covariances: the "
             "filter's variances of x and y, yaw / vx and vy, the yaw rate (its position-velocity terms have no "
             "place here)")
CATCH_TIME = Topic("catch_time", Float64, QOS_STATE, "ball_predictor (while subscribed)", "catcher",
                   f"seconds from the ball state's stamp until this robot can first catch the ball; "
                   f"{CATCH_TIME_NEVER:g} = never (ball leaves the field first)")
CATCH_POINT = Topic("catch_point", PointStamped, QOS_STATE, "ball_predictor (while subscribed)", "catcher",
                    "where the robot centre should be at the catch [m], `field`")
GROUND_TRUTH_ODOM = Topic("ground_truth/odom", Odometry, QOS_STATE, "plant; each while subscribed",
                          "tests, tools only",
                          "true robot pose and velocity in `field` (the simulator's state: zero covariance)")
GROUND_TRUTH_MOTORS = Topic("ground_truth/motors", Float64MultiArray, QOS_STATE, "plant; each while subscribed",
                            "tests, tools only",
                            "rows = wheels, columns = [current_a, winding_temperature_c, wheel_speed_radps]")
SIM_SET_STATE = Topic("sim/set_state", Odometry, QOS_COMMAND, "scenario scripts", "plant",
                      "place the robot: pose [m, rad] and twist [m/s, rad/s] in `field`")

TOPICS: tuple[Topic, ...] = (
    CLOCK, VISION_BALL, VISION_ROBOTS, BALL_STATE, BALL_PHASE, BALL_STOP_POINT, BALL_V_SHOOT, BALL_UNCERTAIN,
    BALL_MODEL_PARAMS, BALL_CHIP_MODEL_PARAMS, GROUND_TRUTH_BALL, VISION_DETECTIONS, VISION_FIELD, VISION_BALL_MODEL,
    VISION_CHIP_MODEL, SIM_SET_BALL, SIM_EVENTS,
    TEAM_WHEEL_STATES, TEAM_MOTOR_DUTY, FIELD_WHEEL_STATES, FIELD_MOTOR_DUTY,
    BALL_CATCHES, ROBOTS_TRACKED, BALL_TRACK, PASS_CHOICE, PASS_RECORDS,
    CMD_VEL, WHEEL_STATES, WHEEL_SETPOINTS, MOTOR_DUTY, MOTOR_STATUS, KICK, KICK_ANGLE, BALL_DETECTED, DRIBBLER,
    VISION_POSE, ODOM, CATCH_TIME, CATCH_POINT, GROUND_TRUTH_ODOM, GROUND_TRUTH_MOTORS, SIM_SET_STATE,
)

MOTOR_STATUS_COLUMNS = ("avg_current_a", "pwm_limit", "saturated", "limit_active")
GROUND_TRUTH_MOTOR_COLUMNS = ("current_a", "winding_temperature_c", "wheel_speed_radps")
BALL_MODEL_PARAM_LABELS = ("a_slide_mps2", "a_roll_mps2", "c_switch")
BALL_MODEL_PARAM_ROWS = ("in_use", "fit", "std_error")
#: the columns of /ball/chip_model_params: chip_model.ChipParams' fields, in this order (one row, in_use)
BALL_CHIP_MODEL_PARAM_LABELS = ("g_mps2", "damping_z", "damping_xy_first_hop", "damping_xy_other_hops",
                                "min_hop_vz_mps", "max_catch_height_m", "max_receive_height_m")
#: the columns of /vision/chip_model: the part of the chip model SSL geometry's chip_fixed_loss gives
VISION_CHIP_MODEL_LABELS = BALL_CHIP_DAMPING_NAMES
#: the PointField names of /vision/robots, in this order, each one FLOAT64 (at offsets 0, 8, ..). A PointCloud2
#: rather than a Float64MultiArray table: its header carries the capture stamp and the frame, and viewers
#: (rviz, Foxglove) draw it as it is.
VISION_ROBOT_FIELDS = ("x", "y", "z", "yaw", "team", "robot_id")
#: the PointField names of /ball/track's one point, in this order, each one FLOAT64 (x, y, z first: viewers draw
#: the point where the filtered ball is).
BALL_TRACK_FIELDS = ("x", "y", "z", "vx_mps", "vy_mps", "v_shoot_mps", "seen_x_m", "seen_y_m", "phase", "uncertain")
VISION_DETECTION_COLUMNS = ("camera_id", "age_s", "kind", "robot_id", "x_m", "y_m", "theta_rad", "confidence")
#: ``team`` of the ball's point in /vision/robots (a frame carries its ball with its robots: one message per frame)
VISION_BALL_CODE = 0.0
#: ``team`` of the camera's point in /vision/robots: x, y, z its position in ``field`` [m] (SSL geometry's
#: calibration), yaw 0, robot_id the camera id; at most one, before the ball. A chip detector reads a ball in the
#: air from where each camera saw it (docs/decisions/0035).
VISION_CAMERA_CODE = 3.0
#: ``team`` of a sighting in /vision/robots: the ball as the frame's camera saw it at an instant whose ball came
#: from another camera (an overlap) or earlier, for the chip detector only (the ball's own stream stays one point
#: per instant); only in a frame with a camera point, after the ball's place, yaw and robot_id 0
VISION_SIGHTING_CODE = 4.0
#: ``kind`` values of /vision/detections (theta_rad is 0 for balls and robots without orientation)
VISION_DETECTION_KINDS = {"ball": VISION_BALL_CODE, "ours": OURS.code, "opponent": OPPONENTS.code}
#: ``team`` is Team.code (1 ours, 2 the opponents); ``robot_id`` counts within the team
CATCH_TABLE_COLUMNS = ("team", "robot_id", "x_m", "y_m", "yaw_rad", "vx_mps", "vy_mps", "catch_time_s", "catch_x_m",
                       "catch_y_m")
#: ``team`` and ``robot_id`` as in CATCH_TABLE_COLUMNS; the stamp in two whole-number columns, as
#: builtin_interfaces/Time has it (so the table's values may reach 2**31 - 1, where other tables' stop at 1e9)
TRACKED_ROBOT_COLUMNS = ("team", "robot_id", "stamp_sec", "stamp_nanosec", "x_m", "y_m", "yaw_rad", "vx_mps",
                         "vy_mps", "yaw_rate_radps")
#: first_opponent counts the opponents 0.. (``/opponent_<id>``), -1: none can catch the pass; then
#: opponent_catch_s and margin_s are PASS_NO_OPPONENT_S (a table holds finite numbers only).
PASS_NO_OPPONENT_S = 1.0e6
PASS_CHOICE_COLUMNS = ("passer_id", "receiver_id", "kick_speed_mps", "direction_rad", "receiver_catch_s",
                       "opponent_catch_s", "first_opponent", "margin_s", "safe_margin_s", "safe")
PASS_RECORD_COLUMNS = ("index", "t_kick_s", "passer_id", "receiver_id", "kick_speed_mps", "predicted_catch_s",
                       "opponent_predicted_s", "first_opponent", "rated_safe", "outcome", "caught_team", "caught_id",
                       "actual_catch_s", "facing_target", "kick_angle_deg")
PASS_OUTCOMES = ("completed", "intercepted", "lost")
VISION_FIELD_COLUMNS = ("length_m", "width_m", "boundary_m", "goal_width_m", "goal_depth_m")


def topic_table_markdown() -> str:
    """The topic table of docs/reference.md, generated from TOPICS (a test keeps the file in sync)."""
    rows = [
        "| topic | type | QoS | publisher → subscribers | units, frame, meaning |",
        "|---|---|---|---|---|",
    ]
    for t in TOPICS:
        name = t.name if not t.per_robot else f"/robot_<id>/{t.name}"
        rows.append(
            f"| `{name}` | `{t.type_name}` | {QOS_NAMES[id(t.qos)]} | {t.publisher} → {t.subscribers} "
            f"| {t.units} |"
        )
    return "\n".join(rows)
