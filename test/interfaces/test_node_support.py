"""Declared parameters: descriptors, ranges, validation on change, the core's veto."""

import array
import gc
import math

import pytest
import rclpy.node
from rclpy.parameter import Parameter

from erforce_interfaces.runtime.node_support import NodeParams, ThrottledWarner, run_node, stray_arguments
from erforce_interfaces.runtime.param_schema import ParamSchema
from erforce_interfaces.tools.testing import isolated_node

SCHEMA = ParamSchema.from_yaml_text("""
param_test:
  gain: {type: double, default_value: 2.0, description: a gain, validation: {bounds<>: [0.0, 10.0]}}
  limit: {type: double, default_value: 1.0, description: a limit, validation: {gt<>: [0.0]}}
  count: {type: int, default_value: 3, description: an integer, validation: {bounds<>: [1, 8]}}
  mode: {type: string, default_value: linear, description: a mode, validation: {one_of<>: [[linear, inverse_model]]}}
  rate_hz: {type: double, default_value: 5.0, description: a rate, read_only: true}
  team: {type: int_array, default_value: [], description: robot ids, validation: {gt_eq<>: [0]}}
  gains: {type: double_array, default_value: [1.0, 2.0], description: gains, validation: {bounds<>: [0.0, 10.0]}}
""")


@pytest.fixture
def node():
    with isolated_node("param_test") as n:
        yield n


def build(config):
    if config.gain > 8.0 and config.count > 4:  # a combination the "core" refuses
        raise ValueError("gain above 8 needs count <= 4")
    return config


def test_declared_with_descriptor_ranges(node):
    params = NodeParams(node, SCHEMA, build)
    assert params.values["gain"] == 2.0 and params.built.mode == "linear" and params.config.team == ()
    desc = node.describe_parameter("gain")
    assert desc.description == "a gain"
    assert (desc.floating_point_range[0].from_value, desc.floating_point_range[0].to_value) == (0.0, 10.0)
    assert node.describe_parameter("count").integer_range[0].to_value == 8
    assert node.describe_parameter("rate_hz").read_only
    assert "linear | inverse_model" in node.describe_parameter("mode").additional_constraints


@pytest.mark.parametrize(
    ("name", "value"),
    [("gain", -1.0), ("gain", 11.0), ("gain", math.nan), ("gain", math.inf), ("count", 0), ("limit", 0.0),
     ("mode", "quadratic"), ("team", [0, -1]), ("gains", [1.0, math.inf]), ("gains", [1.0, -1.0]),
     ("rate_hz", 6.0)],
)
def test_bad_values_are_rejected_and_the_old_value_kept(node, name, value):
    seen = []
    params = NodeParams(node, SCHEMA, build)
    params.on_change(seen.append)
    before = params.values[name]
    result = node.set_parameters([Parameter(name, value=value)])[0]
    assert not result.successful and result.reason
    assert params.values[name] == before and seen == []  # nothing was applied
    if before != []:  # an unset typed array cannot be read back from rclpy
        now = node.get_parameter(name).value
        assert (list(now) if isinstance(now, array.array | list) else now) == before


def test_good_change_reaches_the_core_and_a_refused_combination_does_not(node):
    seen = []
    params = NodeParams(node, SCHEMA, build)
    params.on_change(seen.append)
    assert node.set_parameters([Parameter("gain", value=9.0)])[0].successful
    assert seen[-1].gain == 9.0 and params.config.gain == 9.0 and params.values["gain"] == 9.0
    result = node.set_parameters([Parameter("count", value=5)])[0]
    assert not result.successful and "gain above 8" in result.reason
    assert node.get_parameter("count").value == 3 and len(seen) == 1


def test_nothing_is_applied_before_the_node_asks_for_changes(node):
    """The build runs once for the start values; the callback exists only after on_change."""
    calls = []
    params = NodeParams(node, SCHEMA, lambda c: calls.append(c) or c)
    assert len(calls) == 1 and params.built is calls[0]
    assert node.set_parameters([Parameter("gain", value=4.0)])[0].successful  # no callback yet: rclpy's own
    assert len(calls) == 1


def test_invalid_start_configuration_refuses_to_start(node):
    node.declare_parameter("mode", "quadratic")  # as if set from a params file
    with pytest.raises(Exception):  # noqa: B017 - rclpy raises ParameterAlreadyDeclared or ValueError
        NodeParams(node, SCHEMA, build)


def test_array_parameter_with_an_empty_default_is_typed_and_takes_values_later(node):
    seen = []
    params = NodeParams(node, SCHEMA, build)
    params.on_change(seen.append)
    assert params.values["team"] == []
    assert node.set_parameters([Parameter("team", value=[0, 2])])[0].successful
    assert seen[-1].team == (0, 2) and list(node.get_parameter("team").value) == [0, 2]
    assert not node.set_parameters([Parameter("team", value=["a"])])[0].successful  # not integers
    assert seen[-1].team == (0, 2)


def test_an_integer_start_value_for_a_double_is_taken_as_that_double():
    """rclpy 7.1 refuses an INTEGER override for a DOUBLE parameter (InvalidParameterTypeException); a
    parameter file or ``-p gain:=3`` writes 3 for 3.0. Integers stay integers where the type is int."""
    overrides = [Parameter("gain", value=3), Parameter("gains", value=[1, 4]), Parameter("count", value=5)]
    with isolated_node("param_test", parameter_overrides=overrides) as node:
        params = NodeParams(node, SCHEMA, lambda c: c)
        assert params.values["gain"] == 3.0 and isinstance(params.values["gain"], float)
        assert node.get_parameter("gain").type_ == Parameter.Type.DOUBLE
        assert params.values["gains"] == [1.0, 4.0] and all(isinstance(v, float) for v in params.values["gains"])
        assert node.get_parameter("gains").type_ == Parameter.Type.DOUBLE_ARRAY
        assert params.values["count"] == 5 and node.get_parameter("count").type_ == Parameter.Type.INTEGER
    with isolated_node("param_test", parameter_overrides=[Parameter("gain", value="3")]) as node:
        with pytest.raises(ValueError, match="invalid parameter gain"):  # a string is still no double
            NodeParams(node, SCHEMA, build)


def test_an_integer_change_for_a_double_is_taken_as_that_double(node):
    seen = []
    params = NodeParams(node, SCHEMA, build)
    params.on_change(seen.append)
    assert node.set_parameters([Parameter("gain", value=4)])[0].successful
    assert seen[-1].gain == 4.0 and node.get_parameter("gain").type_ == Parameter.Type.DOUBLE
    assert node.set_parameters([Parameter("gains", value=[0, 7])])[0].successful
    assert seen[-1].gains == (0.0, 7.0)
    result = node.set_parameters([Parameter("gain", value=11)])[0]  # converted, then judged by the range
    assert not result.successful and params.values["gain"] == 4.0
    assert not node.set_parameters([Parameter("count", value=2.0)])[0].successful  # no double for an int
    assert not node.set_parameters([Parameter("gain", value=True)])[0].successful  # a bool is no number here


def test_markdown_table_lists_every_parameter_with_what_is_valid():
    text = SCHEMA.markdown()
    assert "| `gain` | double | `2.0` | [0, 10] | a gain |" in text
    assert "| `limit` | double | `1.0` | (0, ∞) | a limit |" in text
    assert "| `mode` | string | `'linear'` | linear \\| inverse_model | a mode |" in text
    assert "| `rate_hz` | double | `5.0` | read-only | a rate |" in text


def test_throttled_warner_counts_everything_but_logs_once_per_period(node):
    warner = ThrottledWarner(node, period_s=60.0)
    for _ in range(5):
        warner.warn("nan", "NaN twist rejected")
    assert warner.counts["nan"] == 5


@pytest.mark.integration
def test_out_of_range_launch_parameter_refuses_to_start_with_one_clear_line(ros_graph):
    proc = ros_graph.start_node("erforce_motion", "velocity_controller", params={"max_accel_mps2": -3.0})
    assert proc.wait_exit(30.0) == 1
    out = proc.output()
    assert "cannot start: invalid parameter max_accel_mps2" in out
    assert "Traceback" not in out


@pytest.mark.integration
def test_the_plant_takes_an_integer_from_its_parameter_file_for_a_double(ros_graph):
    """What ``ros2 launch`` writes into the parameter file for ``real_time_factor:=0``: the integer 0. The
    plant starts with 0.0 (flat out) and takes an integer change as that double too."""
    params = ros_graph.workdir / "plant_integers.yaml"
    params.write_text("/**:\n  ros__parameters:\n    real_time_factor: 0\n    robot_poses: [0, 0, 0]\n")
    plant = ros_graph.start_node("erforce_sim", "plant", params_file=params)
    probe = ros_graph.probe
    value = probe.get_parameter("/plant", "real_time_factor", timeout_s=30.0)
    assert value == 0.0 and isinstance(value, float)
    assert list(probe.get_parameter("/plant", "robot_poses")) == [0.0, 0.0, 0.0]
    assert probe.set_parameter("/plant", "real_time_factor", 2).successful
    value = probe.get_parameter("/plant", "real_time_factor")
    assert value == 2.0 and isinstance(value, float)
    assert plant.alive(), plant.output()


def test_run_node_takes_the_start_up_objects_out_of_the_gc_before_spinning():
    """A full collection over the imports' objects stalled the predictor 0.2-0.7 s in demo runs:
    by the first callback they are frozen (gc.freeze), so the collector no longer scans them."""
    seen = []

    class FirstTick(rclpy.node.Node):
        def __init__(self):
            super().__init__("gc_probe")
            self.create_timer(0.01, self._tick)

        def _tick(self):
            seen.append(gc.get_freeze_count())
            raise SystemExit(0)

    try:
        assert run_node(FirstTick, args=[]) == 0
    finally:
        gc.unfreeze()
    assert seen and seen[0] > 10_000  # rclpy and numpy alone leave tens of thousands


def test_run_node_ends_cleanly_when_ctrl_c_shut_the_context_under_a_publishing_callback():
    """SIGINT shuts the context down at once; a callback that publishes right after got
    "publisher's context is invalid" and the node died with a traceback (a restarted motor board in
    a fault test). That is the shutdown: exit code 0. The same error with the context alive is not."""
    from rclpy.impl.implementation_singleton import rclpy_implementation
    from std_msgs.msg import Empty

    RCLError = rclpy_implementation.RCLError

    class PublishesAfterShutdown(rclpy.node.Node):
        def __init__(self, shut_down_first):
            super().__init__("shutdown_probe")
            self._pub = self.create_publisher(Empty, "shutdown_probe", 1)
            self._shut_down_first = shut_down_first
            self.create_timer(0.01, self._tick)

        def _tick(self):
            if not self._shut_down_first:
                raise RCLError("a publish failed with the context alive")  # a real fault
            self.context.shutdown()  # what rclpy's SIGINT handler does
            self._pub.publish(Empty())

    assert run_node(lambda: PublishesAfterShutdown(True), args=[]) == 0
    with pytest.raises(RCLError, match="context alive"):
        run_node(lambda: PublishesAfterShutdown(False), args=[])


def test_a_node_names_the_arguments_it_ignores():
    # `-p` before --ros-args is no parameter at all: the node says so instead of running on defaults.
    assert stray_arguments(["ssl_vision_bridge", "-p", "port:=10020"]) == ["-p", "port:=10020"]
    assert stray_arguments(["ssl_vision_bridge", "--ros-args", "-p", "port:=10020"]) == []
    assert stray_arguments(["plant", "--ros-args", "-r", "__ns:=/a", "--", "extra"]) == ["extra"]
    assert stray_arguments(["plant"]) == []
