"""The catchers of a team per robot (a catcher in each namespace with team_robot_ids) and in one process
(team_catcher with robot_ids): the same inputs give the same decision, who of the team receives."""

import math

import pytest
from geometry_msgs.msg import PointStamped, Twist
from nav_msgs.msg import Odometry
from std_msgs.msg import Float64, Float64MultiArray

from erforce_interfaces.tools.messages import point_msg
from erforce_interfaces.wire import contract
from erforce_interfaces.wire.conversions import odometry_msg
from erforce_interfaces.wire.tables import table_msg, tracked_robot_row, tracked_robots_cdr

pytestmark = pytest.mark.integration

IDS = (0, 2)
POSES = {0: (-0.5, 0.3, math.pi), 2: (2.5, -1.0, math.pi)}
POINTS = {0: (-0.4, 0.0), 2: (1.0, 0.0)}


def _start(graph, deployment):
    params = {"field": "division_b"}
    if deployment in ("team", "team_tracked"):
        return [graph.start_node("erforce_ball_model", "team_catcher", params={
            **params, "robot_ids": list(IDS), "tracked_poses": deployment == "team_tracked"})]
    return [graph.start_node("erforce_ball_model", "catcher", namespace=f"robot_{i}",
                             params={**params, "team_robot_ids": list(IDS)}) for i in IDS]


@pytest.mark.parametrize("deployment", ["per_robot", "team", "team_tracked"])
def test_the_robot_with_the_earlier_catch_receives_the_other_holds(ros_graph, deployment):
    """A ball rolls along y = 0 at 2 m/s. With robot_0's catch 0.6 s and robot_2's 1.5 s away, robot_0 drives
    (to the ball's line: -y in the field, +y in its base_link as it faces -x) and robot_2 holds; with the
    times swapped, robot_2 drives and robot_0 holds. team_tracked: the team_catcher with tracked_poses, the
    robots' poses in /robots/tracked (with an opponent's row, not the team's) instead of their odom."""
    team = deployment != "per_robot"
    tracked = deployment == "team_tracked"
    procs = _start(ros_graph, deployment)
    probe = ros_graph.probe
    commands = {i: ros_graph.subscribe(f"/robot_{i}/cmd_vel", Twist, contract.CMD_VEL.qos) for i in IDS}
    pubs = {"ball": probe.wait_for_subscribers(contract.BALL_STATE.name, Odometry, timeout_s=30.0,
                                               qos=contract.BALL_STATE.qos)}
    for i in IDS:
        if not tracked:
            pubs[("odom", i)] = probe.wait_for_subscribers(contract.ODOM.for_robot(i), Odometry, timeout_s=30.0,
                                                           qos=contract.ODOM.qos)
        if not team:
            pubs[("time", i)] = probe.wait_for_subscribers(contract.CATCH_TIME.for_robot(i), Float64,
                                                           timeout_s=30.0, qos=contract.CATCH_TIME.qos)
            pubs[("point", i)] = probe.wait_for_subscribers(contract.CATCH_POINT.for_robot(i), PointStamped,
                                                            timeout_s=30.0, qos=contract.CATCH_POINT.qos)
    if tracked:
        pubs["tracked"] = probe.wait_for_subscribers(contract.ROBOTS_TRACKED.name, Float64MultiArray, timeout_s=30.0,
                                                     qos=contract.ROBOTS_TRACKED.qos)
    if team:  # the same catches as the predictor's table (with an opponent, not the team's)
        pubs["catches"] = probe.wait_for_subscribers(contract.BALL_CATCHES.name, Float64MultiArray, timeout_s=30.0,
                                                     qos=contract.BALL_CATCHES.qos)

    def feed(times, seconds):
        for k in range(round(seconds / 0.05)):
            t = 0.05 * k
            pubs["ball"].publish(odometry_msg(t, (-3.0 + 2.0 * t, 0.0, 0.0), (2.0, 0.0, 0.0)))
            if tracked:
                rows = [tracked_robot_row(contract.OURS, i, t, POSES[i], (0.0, 0.0, 0.0)) for i in IDS]
                rows.append(tracked_robot_row(contract.OPPONENTS, 0, t, (-2.0, 0.0, 0.0), (0.0, 0.0, 0.0)))
                pubs["tracked"].publish(tracked_robots_cdr(rows))
            else:
                for i in IDS:
                    pubs[("odom", i)].publish(odometry_msg(t, POSES[i], (0.0, 0.0, 0.0)))
            if team:
                rows = [[contract.OURS.code, i, *POSES[i], 0.0, 0.0, times[i], *POINTS[i]] for i in IDS]
                rows.append([contract.OPPONENTS.code, 0, -2.0, 0.0, 0.0, 0.0, 0.0, 0.1, -2.0, 0.0])
                pubs["catches"].publish(table_msg(rows, contract.CATCH_TABLE_COLUMNS))
            else:
                for i in IDS:
                    pubs[("time", i)].publish(Float64(data=times[i]))
                    pubs[("point", i)].publish(point_msg(t, POINTS[i]))
            probe.spin_for(0.05)

    def moving(i, since):
        return [m for m in commands[i][since:] if math.hypot(m.linear.x, m.linear.y) > 0.05]

    for receiver, times in ((0, {0: 0.6, 2: 1.5}), (2, {0: 1.5, 2: 0.6})):
        other = 2 if receiver == 0 else 0
        feed(times, 0.5)  # the switch (0.1 s margin, 0.25 s staleness) settles
        since = {i: len(commands[i]) for i in IDS}
        feed(times, 0.6)
        assert len(commands[receiver]) - since[receiver] >= 10 and len(commands[other]) - since[other] >= 10
        assert len(moving(receiver, since[receiver])) >= 10, f"robot_{receiver} should drive"
        assert moving(other, since[other]) == [], f"robot_{other} should hold"
    assert all(p.alive() for p in procs)


def test_with_press_lanes_the_opponents_wait_on_our_passing_lanes_while_we_hold_the_ball(ros_graph):
    """team_catcher for the opponents with press_lanes reads our robots' poses from /robots/tracked (its own from
    their odom): robot_0 at the origin facing +x
    holds the ball at its dribbler (d, 0), robot_1 and robot_2 stand at (3, 0) and (0, 2). The lanes' midpoints
    are ((d + 3) / 2, 0) and (d / 2, 1); opponent_1 at (0.3, 1.5) is nearest robot_2 and takes that lane,
    opponent_0 at (1, 0.3) the other (yaw 0: their base_link is the field's). Each drives towards its point."""
    from erforce_interfaces.wire.robot_config import RobotConfig

    d = RobotConfig().dribbler_offset_m
    ours = {0: (0.0, 0.0, 0.0), 1: (3.0, 0.0, math.pi), 2: (0.0, 2.0, -0.5 * math.pi)}
    theirs = {0: (1.0, 0.3, 0.0), 1: (0.3, 1.5, 0.0)}
    lanes = {0: ((d + 3.0) / 2.0, 0.0), 1: (d / 2.0, 1.0)}
    proc = ros_graph.start_node("erforce_ball_model", "team_catcher", params={
        "field": "division_a", "team": "opponents", "robot_ids": [0, 1], "press_lanes": True, "num_other_robots": 3})
    probe = ros_graph.probe
    commands = {j: ros_graph.subscribe(contract.OPPONENTS.topic(contract.CMD_VEL, j), Twist, contract.CMD_VEL.qos)
                for j in theirs}
    ball = probe.wait_for_subscribers(contract.BALL_STATE.name, Odometry, timeout_s=30.0, qos=contract.BALL_STATE.qos)
    odoms = [(pose, probe.wait_for_subscribers(contract.OPPONENTS.topic(contract.ODOM, k), Odometry, timeout_s=30.0,
                                               qos=contract.ODOM.qos)) for k, pose in theirs.items()]
    tracked = probe.wait_for_subscribers(contract.ROBOTS_TRACKED.name, Float64MultiArray, timeout_s=30.0,
                                         qos=contract.ROBOTS_TRACKED.qos)
    since = {j: len(commands[j]) for j in theirs}
    for k in range(20):
        t = 0.05 * k
        ball.publish(odometry_msg(t, (d, 0.0, 0.0), (0.0, 0.0, 0.0)))
        for pose, pub in odoms:
            pub.publish(odometry_msg(t, pose, (0.0, 0.0, 0.0)))
        tracked.publish(tracked_robots_cdr(
            [tracked_robot_row(contract.OURS, i, t, pose, (0.0, 0.0, 0.0)) for i, pose in ours.items()]))
        probe.spin_for(0.05)
    for j, pose in theirs.items():
        way = (lanes[j][0] - pose[0], lanes[j][1] - pose[1])
        late = [m for m in commands[j][since[j]:] if math.hypot(m.linear.x, m.linear.y) > 0.05]
        assert len(late) >= 5, f"opponent_{j} should drive to its lane"
        m = late[-1]
        cos = (m.linear.x * way[0] + m.linear.y * way[1]) / (math.hypot(*way) * math.hypot(m.linear.x, m.linear.y))
        assert cos == pytest.approx(1.0, abs=1e-9)
    assert proc.alive()


def test_the_model_in_use_outlives_a_new_clock_time_line_in_every_node_that_predicts_the_ball():
    """/ball/model_params and /ball/chip_model_params are transient local: a node gets them once. A new /clock
    time line (the simulator restarted, the predictor not) starts the node's core afresh; the models in use must go
    on, not the defaults (the chip model: none). A chip model that is none (damping_z 1: the hops never end) is
    refused and the one in use kept. In-process: the nodes' callbacks are called directly."""
    import rclpy

    from erforce_ball_model.ball_model import BallModelParams, ChipParams
    from erforce_ball_model.catcher_node import CatcherNode
    from erforce_ball_model.passing.passing_game_node import PassingGameNode
    from erforce_ball_model.team_catcher_node import TeamCatcherNode

    model = BallModelParams(-14.0, -0.7, 0.7)
    msg = table_msg([[model.a_slide_mps2, model.a_roll_mps2, model.c_switch]], contract.BALL_MODEL_PARAM_LABELS,
                    contract.BALL_MODEL_PARAM_ROWS[0])
    chip = ChipParams(damping_z=0.4, max_catch_height_m=0.3)
    labels = contract.BALL_CHIP_MODEL_PARAM_LABELS
    chip_msg = table_msg([[getattr(chip, k) for k in labels]], labels, "in_use")
    bad_chip = table_msg([[9.81, 1.0, 0.7, 1.0, 0.05, 0.15, 0.02]], labels, "in_use")
    cores = ((CatcherNode, lambda node: node._receiver), (TeamCatcherNode, lambda node: node._team),
             (PassingGameNode, lambda node: node._player))
    rclpy.init(args=["--ros-args", "-r", "__ns:=/robot_0"])  # the catcher runs in a robot's namespace
    try:
        for node_type, core in cores:
            node = node_type()
            try:
                assert core(node).model == BallModelParams() and core(node).chip_model is None
                node._on_model_params(msg)
                node._on_chip_model_params(chip_msg)
                assert core(node).model == model and core(node).chip_model == chip
                node._on_chip_model_params(bad_chip)
                assert core(node).chip_model == chip
                assert node._warn.counts.get("chip_model_params") == 1, node_type.__name__
                before = core(node)
                node.on_clock_restart()
                assert core(node) is not before and core(node).model == model, node_type.__name__
                assert core(node).chip_model == chip, node_type.__name__
            finally:
                node.destroy_node()
    finally:
        rclpy.try_shutdown()
