"""Declared parameters: descriptors, ranges, validation on change, the core's veto."""

import gc
import math

import pytest
import rclpy.node
from rclpy.parameter import Parameter

from erforce_interfaces.node_support import ParamSpec, ThrottledWarner, declare_params, params_markdown, run_node
from erforce_interfaces.testing import isolated_node

SPECS = (
    ParamSpec("gain", 2.0, "a gain", min=0.0, max=10.0),
    ParamSpec("limit", 1.0, "a limit", min=0.0),
    ParamSpec("count", 3, "an integer", min=1, max=8),
    ParamSpec("mode", "linear", "a mode"),
)


@pytest.fixture
def node():
    with isolated_node("param_test") as n:
        yield n


def build(values):
    if values["mode"] not in ("linear", "inverse_model"):
        raise ValueError(f"mode must be linear or inverse_model, got {values['mode']!r}")
    if values["limit"] <= 0.0:
        raise ValueError("limit must be > 0")
    return dict(values)


def test_declared_with_descriptor_ranges(node):
    seen = []
    values = declare_params(node, SPECS, build, seen.append)
    assert values["gain"] == 2.0 and seen and seen[-1]["mode"] == "linear"
    desc = node.describe_parameter("gain")
    assert desc.description == "a gain"
    assert (desc.floating_point_range[0].from_value, desc.floating_point_range[0].to_value) == (0.0, 10.0)
    assert node.describe_parameter("count").integer_range[0].to_value == 8


@pytest.mark.parametrize(
    ("name", "value"),
    [("gain", -1.0), ("gain", 11.0), ("gain", math.nan), ("gain", math.inf), ("count", 0), ("limit", 0.0),
     ("mode", "quadratic")],
)
def test_bad_values_are_rejected_and_the_old_value_kept(node, name, value):
    seen = []
    declare_params(node, SPECS, build, seen.append)
    before = node.get_parameter(name).value
    result = node.set_parameters([Parameter(name, value=value)])[0]
    assert not result.successful and result.reason
    assert node.get_parameter(name).value == before
    assert len(seen) == 1  # only the start-up configuration was applied


def test_good_change_reaches_the_core(node):
    seen = []
    declare_params(node, SPECS, build, seen.append)
    assert node.set_parameters([Parameter("gain", value=4.5)])[0].successful
    assert seen[-1]["gain"] == 4.5
    assert node.get_parameter("gain").value == 4.5


def test_invalid_start_configuration_refuses_to_start(node):
    node.declare_parameter("mode", "quadratic")  # as if set from a params file
    with pytest.raises(Exception):  # noqa: B017 - rclpy raises ParameterAlreadyDeclared or ValueError
        declare_params(node, SPECS, build)


def test_array_parameter_with_an_empty_default_is_typed_and_takes_values_later(node):
    seen = []
    specs = (ParamSpec("team", [], "robot ids", min=0, empty_array_of=int),)
    assert declare_params(node, specs, dict, seen.append)["team"] == []
    assert seen == [{"team": []}]
    assert node.set_parameters([Parameter("team", value=[0, 2])])[0].successful
    assert seen[-1] == {"team": [0, 2]} and list(node.get_parameter("team").value) == [0, 2]
    assert not node.set_parameters([Parameter("team", value=[0, -1])])[0].successful  # below min
    assert not node.set_parameters([Parameter("team", value=["a"])])[0].successful  # not integers
    assert seen[-1] == {"team": [0, 2]}


def test_empty_array_default_needs_its_element_type():
    with pytest.raises(ValueError, match="empty_array_of"):
        ParamSpec("team", [], "robot ids")
    with pytest.raises(ValueError, match="empty_array_of"):
        ParamSpec("team", [1], "robot ids", empty_array_of=int)
    with pytest.raises(ValueError, match="empty_array_of"):
        ParamSpec("team", [], "robot ids", empty_array_of=dict)


def test_markdown_table_lists_every_parameter_with_its_range():
    text = params_markdown(SPECS)
    assert "| `gain` | `2.0` | [0, 10] | a gain |" in text
    assert "| `limit` | `1.0` | [0, ∞] |" in text
    assert "| `mode` | `'linear'` | — |" in text


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


def test_array_parameters_are_checked_element_by_element(node):
    specs = (ParamSpec("gains", [1.0, 2.0], "per-axis gains", min=0.0, max=10.0),)
    declare_params(node, specs)
    import array

    for bad in ([1.0, math.inf], [1.0, -1.0], array.array("d", [math.nan])):
        assert specs[0].check(bad) is not None
        result = node.set_parameters([Parameter("gains", value=list(bad))])[0]
        assert not result.successful
    assert list(node.get_parameter("gains").value) == [1.0, 2.0]


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
