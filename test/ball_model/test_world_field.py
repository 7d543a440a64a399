"""The field is one state from the world (node_support.WorldField): the AI's nodes (catcher, team_catcher,
passing_game) and the field view take SSL geometry's field from /vision/field; with ``field: from_geometry`` they
judge nothing before it arrives, say so once, and hand the world's field to their cores when it does.
In-process: the nodes built under rclpy, the geometry message handed to their subscription's callback."""

from __future__ import annotations

import rclpy
from std_msgs.msg import Float64MultiArray

from erforce_interfaces.wire import contract
from erforce_interfaces.wire.robot_config import FIELD_PRESETS, FieldConfig
from erforce_interfaces.wire.tables import table_msg
from erforce_sim.view.field_view import WorldState

DIVISION_A, DIVISION_B = FIELD_PRESETS["division_a"], FIELD_PRESETS["division_b"]


def field_msg(length_m: float, width_m: float, boundary_m: float = 0.3) -> Float64MultiArray:
    return table_msg([[length_m, width_m, boundary_m, 1.8, 0.18]], contract.VISION_FIELD_COLUMNS, "field")


class Recorder:
    def __init__(self) -> None:
        self.sent = []

    def publish(self, msg) -> None:
        self.sent.append(msg)


def geometry_callback(node):
    (sub,) = [s for s in node.subscriptions if s.topic_name == contract.VISION_FIELD.name]
    return sub.callback


def with_node(make, args):
    rclpy.init(args=["--ros-args", *args])
    node = None
    try:
        node = make()
        yield node
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()


def logged(node, monkeypatch) -> list[str]:
    lines: list[str] = []
    logger = node.get_logger()
    monkeypatch.setattr(type(logger), "info", lambda self, text, *a, **k: lines.append(text) or True)
    return lines


def test_a_catcher_waiting_for_the_worlds_field_stands_then_receives_inside_the_geometrys_field(monkeypatch):
    from erforce_ball_model.catcher_node import CatcherNode

    for node in with_node(CatcherNode, ["-r", "__ns:=/robot_0", "-p", "field:=from_geometry"]):
        assert node._field.field is None and node._receiver.field is None
        node._cmd_pub = Recorder()
        node._tick()
        (twist,) = node._cmd_pub.sent
        assert (twist.linear.x, twist.linear.y, twist.angular.z) == (0.0, 0.0, 0.0)
        lines = logged(node, monkeypatch)
        geometry_callback(node)(field_msg(12.0, 9.0))
        assert node._field.field == DIVISION_A and node._receiver.field == DIVISION_A
        assert lines == ["field from SSL geometry: 12 x 9 m"]
        geometry_callback(node)(field_msg(12.0, 9.0))  # the latched message again: nothing changes, no line
        assert lines == ["field from SSL geometry: 12 x 9 m"]


def test_geometry_replaces_a_catchers_preset_and_survives_a_parameter_change():
    from erforce_ball_model.catcher_node import CatcherNode

    for node in with_node(CatcherNode, ["-r", "__ns:=/robot_0", "-p", "field:=division_b"]):
        assert node._receiver.field == DIVISION_B
        geometry_callback(node)(field_msg(10.0, 7.0, 0.5))
        assert node._receiver.field == FieldConfig(10.0, 7.0, 0.5)
        node.set_parameters([rclpy.parameter.Parameter("v_max_mps", value=2.0)])
        assert node._receiver.field == FieldConfig(10.0, 7.0, 0.5)


def test_a_team_catcher_and_the_passing_game_take_the_worlds_field():
    from erforce_ball_model.passing.passing_game_node import PassingGameNode
    from erforce_ball_model.team_catcher_node import TeamCatcherNode

    for node in with_node(TeamCatcherNode, ["-p", "field:=from_geometry", "-p", "robot_ids:=[0, 1]"]):
        assert all(r.field is None for r in node._team.receivers.values())
        node._cmd_pubs = {i: Recorder() for i in node._cmd_pubs}
        node._tick()
        assert [len(p.sent) for p in node._cmd_pubs.values()] == [1, 1]  # both stand
        geometry_callback(node)(field_msg(12.0, 9.0))
        assert all(r.field == DIVISION_A for r in node._team.receivers.values())
    for node in with_node(PassingGameNode, ["-p", "field:=from_geometry", "-p", "num_robots:=2",
                                            "-p", "num_opponents:=0"]):
        assert node._player.field is None
        node._start(1.0)  # no game before the field is known, whatever the robots
        assert not node._started
        geometry_callback(node)(field_msg(12.0, 9.0))
        assert node._player.field == DIVISION_A


def test_the_field_view_draws_the_worlds_field_once_it_arrives():
    state = WorldState(DIVISION_B)
    assert state.frame()["field"]["length"] == 9.0
    assert state.apply(contract.VISION_FIELD.name, field_msg(12.0, 9.0))
    assert (state.frame()["field"]["length"], state.frame()["field"]["width"]) == (12.0, 9.0)
