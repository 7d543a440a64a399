"""Issue 19, the adversarial suite against the team deployment: team_firmware (the main and motor boards of
several robots in one process) and team_catcher (their catchers, as a team) in the lockstep graph with the
plant and the ball predictor, for a team of two. Each team node fulfils, for every robot in it, the
contract of the per-robot nodes it hosts (faults_support.TEAM_HOSTS): its inputs come from the contract
through them, so the suite follows the contract as topics are added.

Every input fuzzed (NaN/inf/huge values, wrong lengths, table shapes, bad stamps and frame ids), bad
/clock and stamps, parameter changes that do not describe a robot or that a node cannot apply, each team
node killed and restarted, and the launched team graph healing itself: no process dies, nothing
non-finite is published, no message ends in a callback guard (the harness fails the test on any), and
the loop closes again afterwards. Deterministic (seeded)."""

import math
import re
import signal

import numpy as np
import pytest
from faults_support import (
    TEAM_HOSTS,
    TEAM_SIM_LAUNCH,
    LaunchedDemo,
    TeamLoop,
    bad_times,
    closes_the_loop,
    fuzz_topic,
    subscribed_topics,
)
from nav_msgs.msg import Odometry
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState

from erforce_interfaces.wire import contract
from erforce_interfaces.wire.conversions import odometry_from_msg, odometry_msg, stamp_to_seconds

RESPAWN_DELAY_S = 0.1  # the launch files' default

pytestmark = pytest.mark.integration

ROBOTS = (0, 1)
TEAM_NODES = tuple(TEAM_HOSTS)
CATCHER = {"fetch_resting_ball": True, "v_max_mps": 1.0, "a_max_mps2": 2.0}
PREDICTOR = {"robot_v_max_mps": 1.0, "robot_a_max_mps2": 2.0}
# What each node publishes, for every robot where it is per robot: it must still publish afterwards.
OUTPUTS = {
    "plant": [contract.WHEEL_STATES.for_robot(i) for i in ROBOTS],
    "team_firmware": [contract.MOTOR_DUTY.for_robot(i) for i in ROBOTS],
    "ball_predictor": [contract.BALL_STATE.name, *(contract.CATCH_TIME.for_robot(i) for i in ROBOTS)],
    "team_catcher": [contract.CMD_VEL.for_robot(i) for i in ROBOTS],
}


def team_inputs() -> dict[str, contract.Topic]:
    """Every topic a team node subscribes to: its hosted nodes' inputs, for every robot of the team, and the
    team_catcher's catch table (it reads the catchers' catch times and points there)."""
    inputs = {name: topic for hosted in TEAM_HOSTS.values() for node in hosted
              for name, topic in subscribed_topics(node, ROBOTS)}
    return {**inputs, contract.BALL_CATCHES.name: contract.BALL_CATCHES}


def _loop(ros_graph, **plant) -> TeamLoop:
    loop = TeamLoop(ros_graph, robots=ROBOTS, catcher=CATCHER, predictor=PREDICTOR,
                    plant={"ball": [3.5, 0.5, 0.0, 0.0], "vision_dropout": 0.0, **plant})
    loop.start_all()
    wait_publishing(loop)
    return loop


def wait_publishing(loop, more_than: dict[str, int] | None = None) -> None:
    """Every output of every node arrives (more than ``more_than`` of them where given)."""
    seen = more_than or {}
    names = [n for outs in OUTPUTS.values() for n in outs]
    loop.spin_until(lambda: all(loop.watch.counts[n] > seen.get(n, 0) for n in names), 60.0, "every node publishing")


def assert_all_alive(loop) -> None:
    for node, proc in loop.procs.items():
        assert proc.alive(), f"{node} died:\n{proc.output()[-3000:]}"


def stalled_robots(loop) -> set[int]:
    """The robots whose newest lockstep report from the plant says stalled (not resumed since)."""
    stalled = set()
    for event in loop.events():
        for i in ROBOTS:
            if f"robot_{i} motor_boards stalled" in event:
                stalled.add(i)
            elif f"robot_{i} resumed" in event:
                stalled.discard(i)
    return stalled


def test_team_inputs_cover_both_robots_and_every_hosted_contract():
    inputs = team_inputs()
    for i in ROBOTS:
        for topic in (contract.CMD_VEL, contract.WHEEL_STATES, contract.ODOM, contract.CATCH_TIME,
                      contract.CATCH_POINT, contract.BALL_DETECTED):
            assert topic.for_robot(i) in inputs
    for topic in (contract.CLOCK, contract.BALL_STATE, contract.BALL_V_SHOOT, contract.BALL_MODEL_PARAMS,
                  contract.BALL_CATCHES):
        assert topic.name in inputs
    assert contract.VISION_BALL.name not in inputs  # the predictor's, not a team node's


def test_fuzzed_inputs_and_bad_time_crash_no_team_node_and_the_loop_still_closes(ros_graph):
    rng = np.random.default_rng(20160707)
    loop = _loop(ros_graph, robot_poses=[-1.0, 0.0, 0.0, -2.5, 1.5, 0.0], ball=[1.0, 0.5, 0.0, 0.0])

    for name, topic in team_inputs().items():
        fuzz_topic(loop.probe, loop.watch, loop, name, topic, rng)

    # bad time, one message at a time (a /clock reader keeps only the newest): negative, invalid, zero,
    # far future, backwards, too far ahead; on /clock and on the stamps the team nodes check
    def send(topic, msg_type, messages, qos):
        loop.watch.paused.add(topic)
        pub = loop.probe.publisher(topic, msg_type, qos)
        for msg in messages:
            pub.publish(msg)
            loop.spin_wall(0.05)
        loop.watch.paused.discard(topic)

    send("/clock", Clock, [Clock(clock=t) for t in bad_times(loop.sim_s())], contract.QOS_CLOCK)
    wheels = [f"wheel_{k}" for k in range(4)]
    for i in ROBOTS:
        states = []
        for t in bad_times(loop.sim_s()):
            msg = JointState(name=wheels, velocity=[0.0] * 4, effort=[0.0] * 4)
            msg.header.stamp = t
            states.append(msg)
        send(contract.WHEEL_STATES.for_robot(i), JointState, states, contract.QOS_CONTROL)
        odoms = []
        for t in bad_times(loop.sim_s()):
            odom = Odometry()
            odom.header.stamp, odom.pose.pose.orientation.w = t, 1.0
            odoms.append(odom)
        send(contract.ODOM.for_robot(i), Odometry, odoms, contract.QOS_STATE)

    # inside the plant's plausibility limits, past the wheels' range: both robots of the team at once
    for i in ROBOTS:
        loop.probe.wait_for_subscribers(contract.SIM_SET_STATE.for_robot(i), Odometry).publish(
            odometry_msg(0.0, (-1.0 - 1.5 * i, 1.5 * i, 0.0), (20.0, 0.0, 100.0)))
    loop.spin_wall(0.3)

    wait_publishing(loop, {n: loop.watch.counts[n] + 5 for outs in OUTPUTS.values() for n in outs})
    t_now = loop.sim_s()
    for i in ROBOTS:
        stamp = stamp_to_seconds(loop.watch.latest[contract.ODOM.for_robot(i)].header.stamp)
        assert abs(stamp - t_now) < 0.5, f"robot_{i} odom stamped {stamp:.3f} s, plant at {t_now:.3f} s"
    assert_all_alive(loop)
    for node in TEAM_NODES:
        out = loop.procs[node].output()
        assert "rejected" in out, f"{node} logged no rejection: the fuzz did not reach it"
        assert "dropped /clock" in out, f"{node} did not drop the bad /clock:\n{out[-3000:]}"
        for i in ROBOTS:
            assert f"robot_{i}: rejected" in out or f"rejected robot_{i} " in out, (
                f"{node} logged no rejection for robot_{i}:\n{out[-3000:]}")
    loop.watch.assert_all_finite()
    closes_the_loop(loop)
    loop.watch.assert_all_finite()


def test_team_nodes_refuse_what_does_not_describe_a_robot_or_what_they_cannot_change(ros_graph):
    loop = _loop(ros_graph, robot_poses=[-3.5, 0.0, 0.0, -3.5, 2.0, 0.0])
    probe = loop.probe
    before = list(probe.get_parameter("/team_firmware", "robot.wheel_angles_rad"))
    for path in ("/team_firmware", "/team_catcher"):
        result = probe.set_parameter(path, "robot.wheel_angles_rad", [0.0, 0.0, 0.0, 0.0])
        assert not result.successful and "cannot produce every twist" in result.reason, (path, result.reason)
        assert list(probe.get_parameter(path, "robot.wheel_angles_rad")) == pytest.approx(before), path
        # the team is fixed at start: a robot is added or removed by starting the node with another list
        result = probe.set_parameter(path, "robot_ids", [0, 1, 2])
        assert not result.successful and re.search("read.only", result.reason), (path, result.reason)
        assert list(probe.get_parameter(path, "robot_ids")) == list(ROBOTS), path
    result = probe.set_parameter("/team_catcher", "as_team", False)
    assert not result.successful and probe.get_parameter("/team_catcher", "as_team") is True

    # a wheel this small: the motors reach 0.19 m/s at its rim, the main boards' speed limit is 4 m/s
    result = probe.set_parameter("/team_firmware", "robot.wheel_radius_m", 0.001)
    assert not result.successful and "out of the motors' reach" in result.reason, result.reason
    result = probe.set_parameter("/team_firmware", "robot.mass_kg", -1.0)
    assert not result.successful and "mass_kg" in result.reason
    result = probe.set_parameter("/team_firmware", "main_board.command_timeout_s", math.nan)
    assert not result.successful
    assert probe.get_parameter("/team_firmware", "robot.mass_kg") == pytest.approx(2.6)

    # changes the nodes can apply still go through, and every robot's loop keeps closing
    assert probe.set_parameter("/team_firmware", "robot.mass_kg", 2.7).successful
    assert probe.set_parameter("/team_catcher", "robot.robot_radius_m", 0.091).successful
    duty = [contract.MOTOR_DUTY.for_robot(i) for i in ROBOTS]
    counts = {n: loop.watch.counts[n] for n in duty}
    loop.spin_sim(0.5)
    for n in duty:  # one answer per tick, 100 Hz
        assert loop.watch.counts[n] > counts[n] + 40, n
    assert_all_alive(loop)
    loop.watch.assert_all_finite()
    closes_the_loop(loop)
    loop.watch.assert_all_finite()


def test_each_team_node_killed_and_restarted_the_loop_closes_again(ros_graph):
    loop = _loop(ros_graph, robot_poses=[-1.0, 0.0, 0.0, -2.5, 1.5, 0.0], ball=[1.0, 0.5, 0.0, 0.0])
    for node in TEAM_NODES:
        if node == "team_firmware":  # a robot still stalled from a slow moment would not be reported again
            loop.spin_until(lambda: not stalled_robots(loop), 30.0, "every robot answering the plant")
        n_events = len(loop.events())
        loop.kill(node, signal.SIGKILL)
        # the graph goes on without it: the plant ticks on (it reports the firmware stalled), the predictor
        # and the plant still publish
        n_clock = loop.watch.counts[contract.GROUND_TRUTH_ODOM.for_robot(0)]
        loop.spin_until(lambda n=n_clock: loop.watch.counts[contract.GROUND_TRUTH_ODOM.for_robot(0)] > n + 50, 30.0,
                        f"the plant ticking without {node}")
        if node == "team_firmware":
            # the report is on another topic than the ticks: it may come after them
            loop.spin_until(lambda n=n_events: all(any(f"robot_{i} motor_boards stalled" in e
                                                       for e in loop.events()[n:]) for i in ROBOTS), 30.0,
                            "the plant's stall report for both robots")
        counts = {n: loop.watch.counts[n] for n in OUTPUTS[node]}
        n_events = len(loop.events())
        loop.start(node)
        loop.spin_until(lambda c=counts: all(loop.watch.counts[n] > c[n] for n in c), 60.0,
                        f"every output of the restarted {node}")
        if node == "team_firmware":
            loop.spin_until(lambda n=n_events: all(any(f"robot_{i} resumed" in e for e in loop.events()[n:])
                                                   for i in ROBOTS), 30.0, "the plant's resume report")
    closes_the_loop(loop)
    assert_all_alive(loop)
    loop.watch.assert_all_finite()


def test_the_launched_team_graph_closes_the_loop_again_by_itself_after_any_single_kill(ros_graph):
    """team_sim.launch.yaml for a team of two and one opponent: the opponent is a team of its own on the graph
    (its id 0 under /opponent_0/), both teams' firmware in one process on the field lockstep topics; each node
    SIGKILLed once, erforce-launch
    restarts it after respawn_delay and both teams' loops close again with nobody restarting anything; then
    the opponents' interceptor drives opponent_0 to a ball rolling past it, from the predictor's catch times."""
    opponent = contract.OPPONENTS
    outputs = {"plant": (contract.CLOCK, contract.CLOCK.name),
               "team_firmware": (contract.FIELD_MOTOR_DUTY, contract.FIELD_MOTOR_DUTY.name),  # both teams
               "ball_predictor": (contract.CATCH_TIME, opponent.topic(contract.CATCH_TIME, 0)),
               "opponent_interceptor": (contract.CMD_VEL, opponent.topic(contract.CMD_VEL, 0))}
    truth = ros_graph.subscribe(opponent.topic(contract.GROUND_TRUTH_ODOM, 0), Odometry)
    demo = LaunchedDemo(ros_graph, TEAM_SIM_LAUNCH, outputs, robot_ids="[0, 1]", num_robots="2",
                        robot_poses="[-4.0, 0.0, 0.0, -3.0, 2.0, 0.0]", opponent_ids="[0]", num_opponents="1",
                        opponent_poses="[0.0, 1.0, 3.14159265]")
    demo.wait_running()
    topics = {name for name, _ in ros_graph.probe.node.get_topic_names_and_types()}
    for name in (opponent.topic(contract.VISION_POSE, 0), opponent.topic(contract.ODOM, 0),
                 contract.FIELD_WHEEL_STATES.name, opponent.topic(contract.MOTOR_STATUS, 0)):
        assert name in topics, name
    assert not any(name.startswith(("/robot_2/", "/opponent_1/")) for name in topics), sorted(topics)
    for node in ("plant", "ball_predictor", "team_firmware"):  # as the launcher starts their warm standbys
        demo.wait_standbys_ready(node)
        assert demo.kill_and_heal(node, RESPAWN_DELAY_S, timeout_s=90.0) > RESPAWN_DELAY_S
    out = demo.launch.output()
    for node in ("plant", "team_firmware", "ball_predictor"):
        assert re.search(rf"\[{node}-\d+\]: respawning in {RESPAWN_DELAY_S:g} s", out), node
        assert re.search(rf"\[{node}-\d+\]: process activated from standby with pid", out), node  # as shipped
    assert demo.launch.alive()
    assert "Traceback" not in out, out[-3000:]

    # a ball rolling up the line x = -1, 1 m from opponent_0 (it passes y = 1 at about 1.5 m/s)
    start = odometry_from_msg(truth[-1])[1][:2]
    ros_graph.probe.wait_for_subscribers(contract.SIM_SET_BALL.name, Odometry).publish(
        odometry_msg(0.0, (-1.0, -2.0, 0.0), (0.0, 2.5, 0.0)))
    ros_graph.spin_until(lambda: "opponent_0 light barrier: ball received" in demo.launch.output(), 30.0,
                         "opponent_0 receiving the ball")
    assert np.hypot(*(odometry_from_msg(truth[-1])[1][:2] - start)) > 0.5  # it went to the ball
