"""What every node shell of the stack shares: declared parameters with ranges, validation on
change, throttled warnings, and the standard ``main()``.

A node lists its parameters once as ``ParamSpec`` rows (name, default, range, description,
ros2_controllers style). ``declare_params`` turns them into ROS parameters with descriptors
and ranges, and installs one on-set callback that checks finiteness and range first, then
asks the node to build its core configuration from the proposed values: if the core refuses
(raises ValueError), the change is rejected with that reason and the old value stays.
``params_markdown`` renders the same rows as the documentation table.
"""

from __future__ import annotations

import array
import gc
import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import rclpy
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor, SetParametersResult
from rclpy.event_handler import PublisherEventCallbacks, SubscriptionEventCallbacks
from rclpy.exceptions import (
    InvalidParameterTypeException,
    InvalidParameterValueException,
    ParameterUninitializedException,
)
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.parameter import Parameter

from erforce_interfaces.contract import CLOCK, Topic
from erforce_interfaces.executor import make_executor, sample_only
from erforce_interfaces.rclpy_internals import RCLError
from erforce_interfaces.robot_config import RobotConfig

ParamValue = bool | int | float | str | list


@dataclass(frozen=True)
class ParamSpec:
    """One documented, range-checked node parameter.

    An array parameter whose default is empty names its element type in ``empty_array_of``
    (int, float, str or bool): ROS cannot type an empty list, so it is declared typed and unset, and
    reads as ``[]`` until a launch file or a parameter file gives it values.
    """

    name: str
    default: ParamValue
    description: str
    min: float | None = None
    max: float | None = None
    read_only: bool = False
    empty_array_of: type | None = None

    def __post_init__(self) -> None:
        if (self.default == []) != (self.empty_array_of is not None) or (
                self.empty_array_of is not None and self.empty_array_of not in _ARRAY_TYPES):
            raise ValueError(f"{self.name}: an empty default needs empty_array_of (int, float, str or bool), "
                             "and only an empty default takes it")

    def check(self, value: Any) -> str | None:
        """Return why ``value`` is unacceptable, or None."""
        # array parameters arrive as lists, tuples or array.array
        values = list(value) if isinstance(value, list | tuple | array.array) else [value]
        for v in values:
            if isinstance(v, float) and not math.isfinite(v):
                return f"{self.name}: must be finite, got {v!r}"
            if isinstance(v, int | float) and not isinstance(v, bool):
                if self.min is not None and v < self.min:
                    return f"{self.name}: {v!r} is below the minimum {self.min!r}"
                if self.max is not None and v > self.max:
                    return f"{self.name}: {v!r} is above the maximum {self.max!r}"
        return None

    def descriptor(self) -> ParameterDescriptor:
        d = ParameterDescriptor(description=self.description, read_only=self.read_only)
        if isinstance(self.default, bool) or (self.min is None and self.max is None):
            return d
        lo = -math.inf if self.min is None else self.min
        hi = math.inf if self.max is None else self.max
        if isinstance(self.default, int):
            # rcl encodes "unbounded" integer ranges poorly; clamp to int64.
            d.integer_range = [IntegerRange(from_value=int(max(lo, -(2**63))), to_value=int(min(hi, 2**63 - 1)))]
        elif isinstance(self.default, float):
            d.floating_point_range = [FloatingPointRange(from_value=float(lo), to_value=float(hi))]
        return d

    def range_text(self) -> str:
        if self.min is None and self.max is None:
            return "—"
        lo = "−∞" if self.min is None else f"{self.min:g}"
        hi = "∞" if self.max is None else f"{self.max:g}"
        return f"[{lo}, {hi}]"


_ARRAY_TYPES = {int: Parameter.Type.INTEGER_ARRAY, float: Parameter.Type.DOUBLE_ARRAY,
                str: Parameter.Type.STRING_ARRAY, bool: Parameter.Type.BOOL_ARRAY}


def _param_value(node: Node, spec: ParamSpec) -> ParamValue:
    try:
        return node.get_parameter(spec.name).value
    except ParameterUninitializedException:  # a typed, empty array parameter (ParamSpec.empty_array_of)
        return []


def declare_params(
    node: Node,
    specs: Sequence[ParamSpec],
    build: Callable[[dict[str, Any]], Any] | None = None,
    on_change: Callable[[Any], None] | None = None,
) -> dict[str, Any]:
    """Declare ``specs`` on ``node``; return the current values by name.

    ``build(values)`` turns a complete name->value dict into the node's core
    configuration and raises ValueError when the values are inconsistent. It runs
    once at start (an invalid launch configuration is fatal: the node refuses to
    start with the reason) and on every change (an invalid change is rejected and
    the old value kept). ``on_change(built)`` receives the accepted configuration.
    """
    by_name = {s.name: s for s in specs}
    for s in specs:
        try:
            default = s.default if s.empty_array_of is None else _ARRAY_TYPES[s.empty_array_of]
            node.declare_parameter(s.name, default, s.descriptor())
        except (InvalidParameterValueException, InvalidParameterTypeException) as exc:
            # e.g. a launch file sets a value outside the declared range: one clear line
            raise ValueError(f"invalid parameter {s.name}: {exc}") from None
    values = {s.name: _param_value(node, s) for s in specs}
    for s in specs:
        reason = s.check(values[s.name])
        if reason:
            raise ValueError(f"invalid parameter {reason}")
    if build is not None:
        built = build(dict(values))
        if on_change is not None:
            on_change(built)

    def _on_set(params: list[Parameter]) -> SetParametersResult:
        proposed = dict(values)
        for p in params:
            spec = by_name.get(p.name)
            if spec is None:
                continue  # e.g. use_sim_time: not ours to judge
            reason = spec.check(p.value)
            if reason:
                node.get_logger().warning(f"rejected parameter change: {reason}")
                return SetParametersResult(successful=False, reason=reason)
            proposed[p.name] = p.value
        built_new = None
        if build is not None:
            try:
                built_new = build(dict(proposed))
            except (ValueError, TypeError) as exc:
                node.get_logger().warning(f"rejected parameter change: {exc}")
                return SetParametersResult(successful=False, reason=str(exc))
        values.update(proposed)
        if on_change is not None and built_new is not None:
            on_change(built_new)
        return SetParametersResult(successful=True)

    node.add_on_set_parameters_callback(_on_set)
    return values


def contract_publisher(node: Node, topic: Topic, resolved_name: str | None = None):
    """A publisher for a contract topic, with the contract's type and QoS.

    It has no default QoS-event handlers: rclpy adds each handler to every wait set, which
    made a spin of a node with 20 publishers cost 347 us instead of 92 us here. A foreign
    subscriber with an incompatible QoS still gets rclpy's warning on its own side.
    """
    return node.create_publisher(topic.msg_type, resolved_name or topic.name, topic.qos,
                                 event_callbacks=PublisherEventCallbacks(use_default_callbacks=False))


def contract_subscription(node: Node, topic: Topic, callback: Callable, resolved_name: str | None = None,
                          raw: bool = False):
    """A subscription to a contract topic, with the contract's type and QoS.

    No default QoS-event handler either (see contract_publisher); the topic's QoS comes from
    the contract on both sides, so they cannot be incompatible within the stack. ``raw``: the
    callback gets the serialized message (bytes), for the lockstep topics' codec in conversions.
    """
    return node.create_subscription(topic.msg_type, resolved_name or topic.name, callback, topic.qos,
                                    event_callbacks=SubscriptionEventCallbacks(use_default_callbacks=False),
                                    raw=raw)


def sample_clock(node: Node) -> list:
    """Take ``/clock`` only when the node runs (erforce_interfaces.executor.sample_only); returns
    the subscriptions for ``run_sampled``.

    For nodes that act on message stamps and need ROS time only for their logs: they then do not
    wake for each ``/clock`` message. Not for nodes with sim-time timers, which /clock drives.
    """
    subs = [s for s in node.subscriptions if s.topic_name == CLOCK.name]
    for sub in subs:
        sample_only(sub)
    return subs


ROBOT_PREFIX = "robot."


def robot_param_specs() -> tuple[ParamSpec, ...]:
    """``robot.*`` parameters of every node that needs the robot description (config/robot.yaml)."""
    defaults = RobotConfig().to_dict()
    docs = RobotConfig.field_docs()
    specs = []
    for name, default in defaults.items():
        lower = None if name == "ambient_temperature_c" or name == "wheel_angles_rad" else 0.0
        upper = 1.0 if name == "gear_efficiency" else None
        specs.append(ParamSpec(ROBOT_PREFIX + name, default, docs[name], min=lower, max=upper))
    return tuple(specs)


def robot_config_from_params(values: dict[str, Any]) -> RobotConfig:
    """The RobotConfig of a node's ``robot.*`` parameter values (raises ValueError when invalid)."""
    return RobotConfig.from_dict({k[len(ROBOT_PREFIX):]: v for k, v in values.items() if k.startswith(ROBOT_PREFIX)})


def params_markdown(specs: Iterable[ParamSpec], skip_robot: bool = True) -> str:
    """The documentation table of a node's parameters (``robot.*`` is documented once, separately)."""
    rows = ["| parameter | default | range | description |", "|---|---|---|---|"]
    for s in specs:
        if skip_robot and s.name.startswith(ROBOT_PREFIX):
            continue

        rows.append(f"| `{s.name}` | `{s.default!r}` | {s.range_text()} | {s.description} |")
    return "\n".join(rows)


class ThrottledWarner:
    """At most one warning per key per ``period_s`` of wall time; counts what it swallowed."""

    def __init__(self, node: Node, period_s: float = 2.0) -> None:
        self._logger = node.get_logger()
        self._clock = rclpy.clock.Clock(clock_type=rclpy.clock.ClockType.STEADY_TIME)
        self._period_ns = int(period_s * 1e9)
        self._last_ns: dict[str, int] = {}
        self.counts: dict[str, int] = {}

    def warn(self, key: str, text: str) -> None:
        self.counts[key] = self.counts.get(key, 0) + 1
        now = self._clock.now().nanoseconds
        last = self._last_ns.get(key)
        if last is None or now - last >= self._period_ns:
            self._last_ns[key] = now
            n = self.counts[key]
            self._logger.warning(f"{text} ({n} so far)" if n > 1 else text)


def run_node(node_factory: Callable[[], Node], args: list[str] | None = None) -> int:
    """Standard node main: init, spin on EventsExecutor (erforce_interfaces.executor.make_executor), clean shutdown.

    Returns the process exit code: 0 after Ctrl-C or external shutdown, 1 when the
    node refused to start (for example an invalid parameter file).
    """
    rclpy.init(args=args)
    node = None
    code = 0
    try:
        try:
            node = node_factory()
        except ValueError as exc:
            # Invalid configuration at start-up: one clear line, no traceback.
            rclpy.logging.get_logger("erforce").fatal(f"cannot start: {exc}")
            return 1
        executor = make_executor()  # EventsExecutor unless ERFORCE_EXECUTOR says otherwise
        executor.add_node(node)
        # The imports (numpy, numba, rclpy) leave ~130k objects that the cyclic GC would scan in every
        # full collection: ~50 ms each back to back, while the node's loop waits. They live as long
        # as the process, so they leave the GC's generations once, here.
        gc.collect()
        gc.freeze()
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except SystemExit as exc:  # a node may end itself (e.g. the plant's stop_after_s)
        code = exc.code if isinstance(exc.code, int) else 0
    except RCLError:
        # Ctrl-C shuts the context down at once, also under a callback that is about to publish;
        # its "context is invalid" is the shutdown, not a fault.
        if node is None or node.context.ok():
            raise
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return code
