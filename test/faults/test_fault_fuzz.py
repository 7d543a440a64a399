"""Issues 6 and 19, fault tests: every node's subscribed topics (contract.py) fuzzed with malformed,
non-finite, huge and empty messages, wrong array lengths and table shapes, negative, zero, far-future
and backwards stamps and foreign frame ids, while the full graph runs in lockstep. No node may crash
or stop answering, no non-finite value may appear on any topic other than the one being fuzzed at
that moment, no message may end in a node's callback guard (the harness fails the test on any), and
afterwards the graph still closes the loop. Deterministic (seeded).

The passing game's nodes (passing_game and the opponents' team_catcher with press_lanes) the same way,
in the passing game's graph as launched, during a game: a holder on the ball, the opponents pressing;
afterwards the game goes on (a pass is played and ends), under a ball model left on the latched
/ball/model_params that passes every check but leaves no pass in reach."""

import math
import time

import numpy as np
import pytest
from faults_support import (
    ClosedLoop,
    TopicWatch,
    closes_the_loop,
    fuzz_topic,
    node_topics,
    non_finite_fields,
    subscribed_topics,
    topic_names,
)
from nav_msgs.msg import Odometry
from sensor_msgs.msg import JointState
from std_msgs.msg import Bool, Float64, Float64MultiArray

from erforce_ball_model.ball_model import ChipParams
from erforce_ball_model.passing.passing_game_node import records_from_msg
from erforce_interfaces.wire import contract
from erforce_interfaces.wire.conversions import odometry_msg, stamp_to_seconds
from erforce_interfaces.wire.tables import table_msg
from erforce_sim.demo.demo import LAUNCH_FILE

pytestmark = pytest.mark.integration

NODES = ("plant", "velocity_controller", "motor_boards", "ball_predictor", "catcher")


def test_non_finite_fields_walks_nested_messages_arrays_and_sequences():
    odom = Odometry()
    assert non_finite_fields(odom) == []
    odom.pose.pose.orientation.w = math.nan
    odom.twist.covariance[7] = math.inf
    assert non_finite_fields(odom) == ["pose.pose.orientation.w", "twist.covariance[7]"]
    js = JointState(name=["a", "b"], velocity=[0.0, -math.inf], effort=[math.nan])
    assert non_finite_fields(js) == ["velocity[1]", "effort[0]"]
    table = Float64MultiArray(data=[1.0, 2.0, math.nan])
    assert non_finite_fields(table) == ["data[2]"]
    assert non_finite_fields(Float64(data=1e300)) == []  # huge but finite
    assert non_finite_fields(Bool(data=True)) == []


# What each node publishes: it must still publish after the fuzzing (it still answers).
OUTPUTS = {
    "plant": "/robot_0/wheel_states",
    "velocity_controller": "/robot_0/wheel_setpoints",
    "motor_boards": "/robot_0/motor_duty",
    "ball_predictor": "/ball/state",
    "catcher": "/robot_0/cmd_vel",
}


def test_fuzzed_inputs_crash_nothing_and_publish_nothing_non_finite(ros_graph):
    rng = np.random.default_rng(20160706)
    loop = ClosedLoop(
        ros_graph, with_ball_model=True,
        plant={"robot_poses": [-1.0, 0.0, 0.0], "ball": [1.0, 0.5, 0.0, 0.0], "vision_dropout": 0.0},
        catcher={"fetch_resting_ball": True, "v_max_mps": 1.0, "a_max_mps2": 2.0},
        predictor={"robot_v_max_mps": 1.0, "robot_a_max_mps2": 2.0},
    )
    loop.start_all()
    loop.spin_until(lambda: all(loop.watch.counts[t] > 0 for t in OUTPUTS.values()), 30.0, "every node publishing")

    fuzzed: dict[str, contract.Topic] = {}
    for node in NODES:
        fuzzed.update(subscribed_topics(node))
    assert len(fuzzed) >= 15
    for name, topic in fuzzed.items():
        fuzz_topic(loop.probe, loop.watch, loop, name, topic, rng)

    # Inside the plant's plausibility limits (20 m/s, 100 rad/s), but the wheels then spin past the wire's
    # range: the plant used to die publishing wheel_states; its wheel sensors saturate now (conversions).
    loop.probe.wait_for_subscribers("/robot_0/sim/set_state", Odometry).publish(
        odometry_msg(0.0, (0.0, 0.0, 0.0), (20.0, 0.0, 100.0)))
    loop.spin_wall(0.3)

    # still answering: every node publishes again, in the plant's current time line
    counts = {t: loop.watch.counts[t] for t in OUTPUTS.values()}
    loop.spin_until(lambda: all(loop.watch.counts[t] > counts[t] + 5 for t in counts), 30.0,
                    "every node publishing after the fuzzing")
    t_now = loop.sim_s()
    for topic in ("/ball/state", "/robot_0/odom"):
        stamp = stamp_to_seconds(loop.watch.latest[topic].header.stamp)
        assert abs(stamp - t_now) < 0.5, f"{topic} stamped {stamp:.3f} s, plant at {t_now:.3f} s"
    for node in NODES:
        proc = loop.procs[node]
        assert proc.alive(), f"{node} died:\n{proc.output()[-3000:]}"
        assert "rejected" in proc.output(), f"{node} logged no rejection: the fuzz did not reach it"
    loop.watch.assert_all_finite()
    closes_the_loop(loop)
    loop.watch.assert_all_finite()


# The passing game's graph (test_passing_on_the_graph.py): three of ours, one opponent pressing; no respawn,
# so that a node that dies stays dead.
GAME = {"ai": "passing", "pacing": "lockstep", "real_time_factor": "1.0", "field": "division_a",
        "robot_ids": "[0, 1, 2]", "num_robots": "3",
        "robot_poses": "[-4.5, 0.0, 0.0, -3.0, -2.5, 1.0, -3.0, 2.5, -1.0]",
        "opponent_ids": "[0]", "num_opponents": "1", "opponent_poses": "[1.5, 0.0, 3.14159265]",
        "respawn": "false", "sim_launch_prefix": ""}
GAME_NODES = ("passing_game", "opponent_interceptor")  # the team_catcher of the opponents, press_lanes on
GAME_OUTPUTS = ("/robot_0/dribbler", "/opponent_0/cmd_vel")  # each node's: published every second or more often


def node_log(output: str, node: str) -> list[str]:
    """The lines of the launcher's ``output`` that node ``node`` logged."""
    return [line for line in output.splitlines() if f"[{node}]: " in line]


def test_fuzzed_inputs_crash_neither_the_passing_game_nor_the_pressing_opponents(ros_graph):
    rng = np.random.default_rng(20170706)
    probe = ros_graph.probe
    choices = ros_graph.subscribe(contract.PASS_CHOICE.name, Float64MultiArray)
    records = ros_graph.subscribe(contract.PASS_RECORDS.name, Float64MultiArray)
    launch = ros_graph.start_launch(LAUNCH_FILE.with_name("team_sim.launch.yaml"), **GAME)

    def spin_until(condition, timeout_s: float, what: str) -> None:
        probe.spin_until(lambda: condition() or not launch.alive(), timeout_s, what)
        assert launch.alive(), launch.output()[-3000:]

    # The game context: robot_0 holds the ball and has chosen a pass; the opponent presses (press_lanes).
    spin_until(lambda: any(m.layout.dim and m.layout.dim[0].size for m in choices), 120.0,
               "robot_0 holding the ball with a chosen pass")
    inputs = {node: node_topics(probe, node) for node in GAME_NODES}
    # passing_game: the ball's five topics (state, phase, v_shoot, the ball and chip models), every robot's light
    # barrier, the tracked robots' and the catch table, /clock, the world's field; the interceptor: the ball's, its
    # robot's barrier, both tables (every pose from the tracked one), /clock, the world's field
    assert len(inputs["passing_game"]) == 5 + 4 + 2 + 1 + 1, sorted(inputs["passing_game"])
    assert len(inputs["opponent_interceptor"]) == 5 + 1 + 2 + 1 + 1, sorted(inputs["opponent_interceptor"])
    assert all(contract.VISION_FIELD.name in inputs[node] for node in GAME_NODES)
    assert all({contract.BALL_CATCHES.name, contract.ROBOTS_TRACKED.name} <= set(inputs[node]) for node in GAME_NODES)
    fuzzed = {name: topic for node in GAME_NODES for name, topic in inputs[node].items()}
    # the watch reads what the two nodes publish (and the time): a watch of every topic of the graph falls behind
    outputs = {name for node in GAME_NODES for name in node_topics(probe, node, published=True)}
    assert {"/robot_0/cmd_vel", "/robot_0/dribbler", contract.PASS_RECORDS.name, "/opponent_0/cmd_vel"} <= outputs
    watched = outputs | {contract.CLOCK.name}
    watch = TopicWatch(probe, robots=(0, 1, 2), opponents=(0,),
                       exclude=[n for n, _ in topic_names((0, 1, 2), opponents=(0,)) if n not in watched])
    spin_until(lambda: all(watch.counts[t] for t in GAME_OUTPUTS), 30.0, "every game node publishing")

    for name, topic in fuzzed.items():
        fuzz_topic(probe, watch, probe, name, topic, rng)
        assert launch.alive(), launch.output()[-3000:]
    # The model is latched and published on change only: a fuzzed model that passes the checks stays in use. The
    # last one leaves no pass in reach (every kick rests within 0.29 m: a_slide -100, a_roll -50 m/s^2), which
    # stalled the game for good until the holder fell back (PassingPlayer.fallback_choice). A chip flies its hops
    # whatever the carpet, so the game plays flat passes only for this.
    assert probe.set_parameter("/passing_game", "chip_angle_deg", 0.0).successful
    probe.publisher(contract.BALL_MODEL_PARAMS.name, Float64MultiArray, contract.BALL_MODEL_PARAMS.qos).publish(
        table_msg(np.array([[-100.0, -50.0, 0.6]]), contract.BALL_MODEL_PARAM_LABELS, "in_use"))
    # likewise a fuzzed chip model that passed its checks: the predictor's (the defaults) back
    chip, labels = ChipParams(), contract.BALL_CHIP_MODEL_PARAM_LABELS
    chip_topic = contract.BALL_CHIP_MODEL_PARAMS
    probe.publisher(chip_topic.name, Float64MultiArray, chip_topic.qos).publish(
        table_msg(np.array([[getattr(chip, k) for k in labels]]), labels, "in_use"))

    last_read = [-math.inf]

    def warned() -> bool:  # the launcher's log, read at most every 0.5 s
        if time.monotonic() - last_read[0] < 0.5:
            return False
        last_read[0] = time.monotonic()
        return any("no pass in reach" in line for line in node_log(launch.output(), "passing_game"))

    spin_until(warned, 60.0, "passing_game's warning: no pass in reach")
    t_fuzzed = stamp_to_seconds(watch.latest[contract.CLOCK.name].clock)

    # still serving the good messages: a pass kicked after the warning ends (the referee puts the ball back
    # first if the fuzzed light barriers ended the game's pass or hold)
    counts = {t: watch.counts[t] for t in GAME_OUTPUTS}
    spin_until(lambda: any(r.t_kick_s > t_fuzzed for m in records for r in records_from_msg(m)), 60.0,
               "a pass after the fuzzing")
    spin_until(lambda: all(watch.counts[t] > counts[t] + 1 for t in counts), 10.0, "every game node publishing")
    out = launch.output()
    assert "process has died" not in out and "Traceback" not in out, out[-3000:]
    for node in GAME_NODES:
        log = node_log(out, node)
        assert any("rejected" in line for line in log), f"{node} logged no rejection: the fuzz did not reach it"
    watch.assert_all_finite()
