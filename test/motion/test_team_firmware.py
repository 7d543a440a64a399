"""Many robots' firmware over DDS: per robot (velocity_controller + motor_boards in each namespace), in one
team_firmware process on the per-robot topics and on the team-level ones (/team/wheel_states, motor_duty)
give the in-process runner's trajectory, with an opponent on the field under its own firmware (per robot
under /opponent_0/, or the opponents' team_firmware, on /opponent_team/ with team topics, or both teams in one
team_firmware on the team topics or on the field topics /field/wheel_states, motor_duty); robots come and go
by parameter; a killed firmware process stalls only its robot."""

import signal
from pathlib import Path

import numpy as np
import pytest
from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Float64MultiArray, String

from erforce_interfaces.wire import contract
from erforce_interfaces.wire.conversions import odometry_from_msg, stamp_to_nanoseconds
from erforce_motion.velocity_control import VelocityControlConfig
from erforce_sim.in_process.runner import InProcessRunner
from erforce_sim.plant_setup import PlantSetup

pytestmark = pytest.mark.integration

ROBOT_YAML = Path(__file__).resolve().parents[2] / "src/erforce_interfaces/config/robot.yaml"
POSES = ((-1.0, 0.0, 0.0), (0.0, 1.0, 0.5), (1.0, -1.0, 3.0))
TWISTS = {0: (0.8, -0.3, 1.0), 2: (-0.5, 0.6, -2.0)}  # robot_1 has no firmware: it stays put
OPPONENT_POSES = ((2.5, 1.0, 3.0),)
OPPONENT_TWIST = (0.6, 0.3, -1.5)  # opponent_0's, world index 3
# deployment -> the opponent's firmware (two_teams: our team's two processes only, no opponent; None: in our
# team_firmware, by its opponent_ids)
OPPONENT_FIRMWARE = {"per_robot": "per_robot", "team": "team", "team_topics": "team_topics", "mixed": "per_robot",
                     "one_process": None, "field": None}


# deployment -> the plant's and team_firmware's lockstep_topics
LOCKSTEP_TOPICS = {"per_robot": "per_robot", "team": "per_robot", "team_topics": "team", "two_teams": "team",
                   "mixed": "both", "one_process": "team", "field": "field"}


def _start_firmware(graph, deployment, ids, team=contract.OURS, boards=None, **params):
    """The firmware of robots ``ids``; ``boards``: more parameters of each per-robot motor_boards."""
    common = {"use_sim_time": True}
    if deployment == "two_teams":  # a team_firmware per robot on the shared team topics, each answering for its own
        return [graph.start_node("erforce_motion", "team_firmware", name=f"team_firmware_{i}",
                                 params_file=ROBOT_YAML, params={**common, "robot_ids": [i], "lockstep_topics": "team",
                                                                 "main_board.command_timeout_s": 30.0, **params})
                for i in ids]
    if deployment == "mixed":  # robot_0 per robot on its own topics, robot_2 in a team_firmware on the team topics
        first, *rest = ids
        return [*_start_firmware(graph, "per_robot", [first], boards=boards),
                *_start_firmware(graph, "team_topics", rest)]
    if deployment != "per_robot":
        return [graph.start_node("erforce_motion", "team_firmware", name=f"{team.name}_firmware",
                                 params_file=ROBOT_YAML,
                                 params={**common, "robot_ids": list(ids), "main_board.command_timeout_s": 30.0,
                                         "lockstep_topics": LOCKSTEP_TOPICS[deployment], "team": team.name,
                                         **params})]
    procs = []
    for i in ids:
        procs.append(graph.start_node("erforce_motion", "velocity_controller", namespace=team.namespace(i),
                                      params_file=ROBOT_YAML, params={**common, "command_timeout_s": 30.0}))
        procs.append(graph.start_node("erforce_motion", "motor_boards", namespace=team.namespace(i),
                                      params_file=ROBOT_YAML, params={**common, **(boards or {})}))
    return procs


def _command(graph, robot, twist, team=contract.OURS):
    pub = graph.probe.wait_for_subscribers(team.topic(contract.CMD_VEL, robot), Twist, timeout_s=30.0)
    msg = Twist()
    msg.linear.x, msg.linear.y, msg.angular.z = twist
    pub.publish(msg)


def _start_plant(graph, deployment, readers, opponent_poses=(), **params):
    """The plant once this probe reads every robot's ground truth; the truths by world index (ours, then the
    opponents). It starts while the firmware does, but its first tick waits for ``readers`` /clock readers and
    the probe's, which ``_release_first_tick`` subscribes once the commands are out."""
    # a reader queue for the whole run: a graph that runs flat out must not push samples out of it
    qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=500, reliability=ReliabilityPolicy.RELIABLE)
    truths = {i: graph.subscribe(f"/robot_{i}/ground_truth/odom", Odometry, qos) for i in range(len(POSES))}
    for j in range(len(opponent_poses)):
        truths[len(POSES) + j] = graph.subscribe(contract.OPPONENTS.topic(contract.GROUND_TRUTH_ODOM, j), Odometry,
                                                 qos)
    plant = graph.start_node("erforce_sim", "plant", params_file=ROBOT_YAML, params={
        "robot_poses": [v for p in POSES for v in p], "controlled": [True, False, True], "ball": [3.0, 2.0, 0.0, 0.0],
        "real_time_factor": 0.0, "wheel_states_readers": 2 if deployment in ("per_robot", "two_teams") else 1,
        "lockstep_topics": LOCKSTEP_TOPICS[deployment], "start_clock_subscribers": readers + 1,
        **({"opponent_poses": [v for p in opponent_poses for v in p]} if opponent_poses else {}), **params})
    return plant, truths


def _release_first_tick(graph):
    """The probe's /clock reader, the last one the plant waits for: after the commands have had 0.3 s to
    arrive (they were published once their readers had matched), so that every node has them at tick 0."""
    graph.probe.spin_for(0.3)
    return graph.subscribe("/clock", Clock, contract.QOS_CLOCK)


@pytest.mark.parametrize("deployment", ["per_robot", "team", "team_topics", "two_teams", "mixed", "one_process",
                                        "field"])
def test_both_deployments_reproduce_the_in_process_trajectory(ros_graph, deployment):
    """robot_0 and robot_2 have firmware (the team process by its robot_ids parameter [0, 2]), robot_1 none,
    and opponent_0 its own: every deployment (two team_firmware processes sharing the team topics too, and a
    plant serving both kinds of topics to a per-robot pair and a team_firmware) gives the in-process runner's
    trajectories of all four to 1e-9 at every ground-truth stamp, so they agree with each other."""
    one_process = OPPONENT_FIRMWARE.get(deployment, "") is None
    opponents = deployment in OPPONENT_FIRMWARE
    # a team_firmware on team or field topics skips its report in the usual tick: its statuses still go out
    status_names = [contract.MOTOR_STATUS.for_robot(i) for i in TWISTS] + (
        [contract.OPPONENTS.topic(contract.MOTOR_STATUS, 0)] if opponents else [])
    qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=100, reliability=ReliabilityPolicy.RELIABLE)
    statuses = ({name: ros_graph.subscribe(name, Float64MultiArray, qos) for name in status_names}
                if LOCKSTEP_TOPICS[deployment] in ("team", "field") else {})
    # The boards' lockstep join waits setpoint_wait_s of wall time (0.05 s by default) for the velocity
    # controller's setpoint, then answers with the previous one: on a loaded machine that changed the
    # trajectory by up to 1e-5 m. Here the wait must outlast any scheduling delay.
    boards = {"setpoint_wait_s": 10.0}
    _start_firmware(ros_graph, deployment, TWISTS, boards=boards, **({"opponent_ids": [0]} if one_process else {}))
    if opponents and OPPONENT_FIRMWARE[deployment] is not None:
        _start_firmware(ros_graph, OPPONENT_FIRMWARE[deployment], [0], contract.OPPONENTS, boards=boards)
    # use_sim_time nodes subscribe to /clock
    readers = {"per_robot": 2 * len(TWISTS), "two_teams": len(TWISTS), "mixed": 3}.get(deployment, 1)
    readers += opponents * {"per_robot": 2, None: 0}.get(OPPONENT_FIRMWARE.get(deployment), 1)
    opponent_poses = OPPONENT_POSES if opponents else ()
    # a stall would change the trajectory: on a loaded machine the first answers may take seconds
    _, truths = _start_plant(ros_graph, deployment, readers, opponent_poses, seed=7, stop_after_s=0.5,
                             lockstep_timeout_s=30.0)
    for i, twist in TWISTS.items():
        _command(ros_graph, i, twist)
    if opponents:
        _command(ros_graph, 0, OPPONENT_TWIST, contract.OPPONENTS)
    _release_first_tick(ros_graph)
    ros_graph.probe.spin_until(lambda: all(t and odometry_from_msg(t[-1])[0] >= 0.4 for t in truths.values()),
                               120.0, "0.4 s of every robot")
    dds = {i: {stamp_to_nanoseconds(m.header.stamp): odometry_from_msg(m) for m in t} for i, t in truths.items()}

    runner = InProcessRunner(PlantSetup(robot_poses=POSES, controlled=(True, False, True), ball=(3.0, 2.0, 0.0, 0.0),
                                        opponent_poses=opponent_poses, seed=7, control_period_s=0.002),
                             VelocityControlConfig(), command_timeout_s=30.0)
    for i, twist in TWISTS.items():
        runner.command(i, twist)
    if opponents:
        runner.command(len(POSES), OPPONENT_TWIST)
    compared = 0
    for _ in range(201):
        for i in truths:
            if runner.t_ns in dds[i]:
                _, pose, vel, _ = dds[i][runner.t_ns]
                s = runner.world.robot_state(i)
                np.testing.assert_allclose(pose, [s.x, s.y, s.theta], rtol=0, atol=1e-9)
                np.testing.assert_allclose(vel, [s.vx, s.vy, s.w], rtol=0, atol=1e-9)
                compared += 1
        runner.tick()
    assert compared >= len(truths) * 35  # ground truth at 100 Hz over 0.4 s, each robot
    assert abs(runner.world.robot_state(0).vx) > 0.3 and abs(runner.world.robot_state(2).w) > 1.0  # they moved
    assert runner.world.robot_state(1).vx == 0.0
    if opponents:
        assert runner.world.robot_state(3).w < -1.0  # the opponent turns as its own firmware was told
    # motor_status at 50 Hz of sim time: ticks 0, 0.02 .. 0.5 s (the plant stops after 0.5 s), one each
    ros_graph.probe.spin_until(lambda: all(len(m) >= 25 for m in statuses.values()), 30.0, "the motor statuses")
    ros_graph.probe.spin_for(0.3)
    assert all(25 <= len(m) <= 26 for m in statuses.values()), {name: len(m) for name, m in statuses.items()}


def test_a_killed_firmware_process_stalls_only_its_robot(ros_graph):
    """Per-robot deployment: robot_2's motor boards are killed; the plant reports the stall and goes on in
    lockstep with robot_0, which keeps driving its command."""
    procs = _start_firmware(ros_graph, "per_robot", TWISTS)
    events = ros_graph.subscribe("/sim/events", String)
    plant, truths = _start_plant(ros_graph, "per_robot", 2 * len(TWISTS), lockstep_timeout_s=0.5)
    for i, twist in TWISTS.items():
        _command(ros_graph, i, twist)
    clocks = _release_first_tick(ros_graph)
    ros_graph.probe.spin_until(lambda: clocks and stamp_to_nanoseconds(clocks[-1].clock) > 0.3e9, 60.0, "0.3 s")
    motor_boards_2 = procs[3]
    assert motor_boards_2.name == "motor_boards"
    motor_boards_2.signal(signal.SIGKILL)
    ros_graph.probe.spin_until(lambda: any("robot_2 motor_boards stalled" in e.data for e in events), 30.0,
                               "the stall report")
    t_stall = stamp_to_nanoseconds(clocks[-1].clock)
    ros_graph.probe.spin_until(lambda: stamp_to_nanoseconds(clocks[-1].clock) > t_stall + 1.0e9, 60.0,
                               "1 s after the stall")
    _, pose, vel, _ = odometry_from_msg(truths[0][-1])
    c, s = np.cos(pose[2]), np.sin(pose[2])
    assert c * vel[0] + s * vel[1] == pytest.approx(TWISTS[0][0], abs=0.1)  # robot_0 still drives its command
    assert vel[2] == pytest.approx(TWISTS[0][2], abs=0.1)
    assert plant.alive() and not motor_boards_2.alive()
