"""What every node shell of the stack shares: declared parameters, validation on change,
throttled warnings, and the standard ``main()``.

A node's parameters are described once, in its schema file (erforce_interfaces.runtime.param_schema).
``NodeParams`` declares them with descriptors and ranges and reads and checks them; the node
builds its core from the config object once it is set up itself, then ``NodeParams.on_change``
installs one on-set callback that checks every change against the schema and asks the node's
build function for the new core: if it refuses (raises ValueError), the change is rejected with
that reason and the old value stays. A parameter the node cannot apply while running is
declared read-only in the schema. ``SchemaNode`` is the Node every shell subclasses for this start.
"""

from __future__ import annotations

import array
import gc
import math
import os
import signal
import sys
import threading
import time
import traceback
import weakref
from collections.abc import Callable
from typing import Any

import rclpy
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor, SetParametersResult
from rclpy.duration import Duration
from rclpy.event_handler import PublisherEventCallbacks, SubscriptionEventCallbacks
from rclpy.exceptions import (
    InvalidParameterTypeException,
    InvalidParameterValueException,
    ParameterUninitializedException,
)
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile
from rclpy.utilities import remove_ros_args

from erforce_interfaces.runtime.executor import guard, make_executor, sample_only, set_callback_fault_handler
from erforce_interfaces.runtime.param_schema import ParamSchema, ParamSpec
from erforce_interfaces.runtime.rclpy_internals import RCLError, light_node_start, parameter_overrides
from erforce_interfaces.runtime.standby import wait_for_go
from erforce_interfaces.wire.contract import CLOCK, VISION_FIELD, Topic, dds_profile_env
from erforce_interfaces.wire.conversions import ConversionError
from erforce_interfaces.wire.robot_config import WAITING_FOR_GEOMETRY, FieldConfig, field_from_setting
from erforce_interfaces.wire.stamps import StampFilter, StampVerdict, stamp_ns
from erforce_interfaces.wire.tables import field_from_msg

_ARRAY_TYPES = {"int": Parameter.Type.INTEGER_ARRAY, "double": Parameter.Type.DOUBLE_ARRAY,
                "string": Parameter.Type.STRING_ARRAY, "bool": Parameter.Type.BOOL_ARRAY}
_INTEGER_FOR_DOUBLE = {Parameter.Type.INTEGER: Parameter.Type.DOUBLE,
                       Parameter.Type.INTEGER_ARRAY: Parameter.Type.DOUBLE_ARRAY}


def _as_declared(spec: ParamSpec | None, param: Parameter) -> Parameter:
    """An integer (array) for a double (array) parameter, as the double it means; anything else as given.

    rclpy (7.1) refuses an INTEGER for a parameter declared DOUBLE, both as a start value and as a
    change; ``ros2 launch`` writes ``real_time_factor:=0`` as the integer 0 into the parameter file."""
    if spec is None or spec.element_type != "double" or param.type_ not in _INTEGER_FOR_DOUBLE:
        return param
    return Parameter(param.name, _INTEGER_FOR_DOUBLE[param.type_], spec.coerce(param.value))


def _descriptor(spec: ParamSpec) -> ParameterDescriptor:
    d = ParameterDescriptor(description=spec.description, read_only=spec.read_only)
    constraints = spec.constraint_text()
    if constraints != "—":
        d.additional_constraints = constraints
    if spec.element_type not in ("int", "double") or (spec.lower is None and spec.upper is None):
        return d
    lo = -math.inf if spec.lower is None else spec.lower
    hi = math.inf if spec.upper is None else spec.upper
    if spec.element_type == "int":
        # rcl encodes "unbounded" integer ranges poorly; clamp to int64. Open bounds: the next integer.
        lo = lo + 1 if spec.lower_open else lo
        hi = hi - 1 if spec.upper_open else hi
        d.integer_range = [IntegerRange(from_value=int(max(lo, -(2**63))), to_value=int(min(hi, 2**63 - 1)))]
    else:  # open bounds are the schema's check; the descriptor shows the closed range
        d.floating_point_range = [FloatingPointRange(from_value=float(lo), to_value=float(hi))]
    return d


class NodeParams:
    """A node's parameters, declared from its schema; ``values`` (by name) and ``config`` stay current.

    Construction declares every parameter and checks the values a launch file or parameter file gave
    (ValueError naming the first bad one: the node refuses to start). ``build(config)`` turns a
    config object into what the node runs (its core), raising ValueError for a combination it cannot
    run; ``built`` is its result for the start values. The node sets itself up from ``built`` and
    then calls ``on_change(apply)``: from then on each accepted change is built and handed to
    ``apply``, and a change that fails the schema or the build is rejected with the reason.
    """

    def __init__(self, node: Node, schema: ParamSchema, build: Callable[[Any], Any] | None = None) -> None:
        self._node = node
        self.schema = schema
        self._build = build or (lambda config: config)
        # Start values: rclpy declares from the overrides as they are, so they are converted there; changes
        # pass the pre-set callback, which rclpy calls before it checks the type.
        overrides = parameter_overrides(node)
        for name, given in list(overrides.items()):
            overrides[name] = _as_declared(schema.by_name.get(name), given)
        node.add_pre_set_parameters_callback(
            lambda params: [_as_declared(schema.by_name.get(p.name), p) for p in params])
        for s in schema.specs:
            default = _ARRAY_TYPES[s.element_type] if s.is_array and not s.default else s.default
            if s.is_array and s.default:
                default = list(default)
            try:
                node.declare_parameter(s.name, default, _descriptor(s))
            except (InvalidParameterValueException, InvalidParameterTypeException) as exc:
                # e.g. a launch file sets a value outside the declared range: one clear line
                raise ValueError(f"invalid parameter {s.name}: {exc}") from None
        self.values: dict[str, Any] = {s.name: self._read(s.name) for s in schema.specs}
        self.config = schema.parse(self.values)
        self.built = self._build(self.config)

    def _read(self, name: str) -> Any:
        try:
            value = self._node.get_parameter(name).value
        except ParameterUninitializedException:  # a typed, empty array parameter
            return []
        return list(value) if isinstance(value, list | tuple | array.array) else value

    def on_change(self, apply: Callable[[Any], None]) -> None:
        """From now on, check and build every change and hand what was built to ``apply``."""

        def _on_set(params: list[Parameter]) -> SetParametersResult:
            proposed = dict(self.values)
            for p in params:
                if p.name in self.schema.by_name:  # others (use_sim_time) are not ours to judge
                    value = p.value
                    proposed[p.name] = list(value) if isinstance(value, list | tuple | array.array) else value
            try:
                config = self.schema.parse(proposed)
                built = self._build(config)
            except (ValueError, TypeError) as exc:
                self._node.get_logger().warning(f"rejected parameter change: {exc}")
                return SetParametersResult(successful=False, reason=str(exc))
            self.values.update(proposed)
            self.config, self.built = config, built
            apply(built)
            return SetParametersResult(successful=True)

        self._node.add_on_set_parameters_callback(_on_set)


def contract_publisher(node: Node, topic: Topic, resolved_name: str | None = None,
                       readers: tuple[list[int], int] | None = None):
    """A publisher for a contract topic, with the contract's type and QoS.

    It has no default QoS-event handlers: rclpy adds each handler to every wait set, which
    made a spin of a node with 20 publishers cost 347 us instead of 92 us here. A foreign
    subscriber with an incompatible QoS still gets rclpy's warning on its own side.
    ``readers`` (a list and an index): the number of matched readers is kept there, set now and on the
    executor's thread whenever a reader comes or goes (for a publisher that skips work nobody reads).
    """
    matched = None
    if readers is not None:
        counts, index = readers

        def matched(info) -> None:
            counts[index] = info.current_count
    pub = node.create_publisher(topic.msg_type, resolved_name or topic.name, topic.qos,
                                event_callbacks=PublisherEventCallbacks(matched=matched, use_default_callbacks=False))
    if readers is not None:
        counts[index] = pub.get_subscription_count()
    return pub


def contract_subscription(node: Node, topic: Topic, callback: Callable, resolved_name: str | None = None,
                          raw: bool = False, qos: QoSProfile | None = None):
    """A subscription to a contract topic, with the contract's type and QoS.

    No default QoS-event handler either (see contract_publisher); the topic's QoS comes from
    the contract on both sides, so they cannot be incompatible within the stack. ``raw``: the
    callback gets the serialized message (bytes), for the lockstep topics' codec in conversions.
    ``qos``: a reader that may ask for less than the contract (an observer's best effort, keep last 1).
    The callback runs behind the process's callback guard (executor.guard, guard_callbacks).
    """
    sub = node.create_subscription(topic.msg_type, resolved_name or topic.name, callback, qos or topic.qos,
                                   event_callbacks=SubscriptionEventCallbacks(use_default_callbacks=False),
                                   raw=raw)
    guard(sub)
    return sub


def sample_clock(node: Node) -> list:
    """Take ``/clock`` only when the node runs (erforce_interfaces.runtime.executor.sample_only); returns
    the subscriptions for ``run_sampled``.

    For nodes that act on message stamps and need ROS time only for their logs: they then run no
    callback per ``/clock`` message. Not for nodes with sim-time timers, which /clock drives.
    """
    subs = [s for s in node.subscriptions if s.topic_name == CLOCK.name]
    for sub in subs:
        sample_only(sub)
    return subs


class WorldField:
    """The field a node computes with, one state from the world: the newest SSL geometry (``/vision/field``,
    latched), else what the node's ``field`` parameter names (a preset: our own plant's world), else None
    (``from_geometry``: the node waits, and says so once). ``on_change(field)`` is called whenever it changes
    (the node hands it to its core); a parameter change goes through ``set_setting``."""

    def __init__(self, node: Node, setting: str, on_change: Callable[[FieldConfig | None], None],
                 warn: ThrottledWarner) -> None:
        self._node, self._on_change, self._warn = node, on_change, warn
        self._preset = field_from_setting(setting)
        self._geometry: FieldConfig | None = None
        contract_subscription(node, VISION_FIELD, self._on_msg)
        if self._preset is None:
            node.get_logger().info(WAITING_FOR_GEOMETRY)

    @property
    def field(self) -> FieldConfig | None:
        return self._geometry or self._preset

    def set_setting(self, setting: str) -> None:
        before = self.field
        self._preset = field_from_setting(setting)
        if self.field != before:
            self._on_change(self.field)

    def _on_msg(self, msg) -> None:
        try:
            field = field_from_msg(msg)
        except (ConversionError, ValueError) as exc:
            self._warn.warn("vision_field", f"rejected {VISION_FIELD.name}: {exc}")
            return
        before, self._geometry = self.field, field
        if field != before:
            self._node.get_logger().info(f"field from SSL geometry: {field.length_m:g} x {field.width_m:g} m")
            self._on_change(field)


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

    def convert(self, msg, what: str, convert):
        """``convert(msg)``, or None with a throttled "rejected <what>" warning when it raises ConversionError."""
        try:
            return convert(msg)
        except ConversionError as exc:
            self.warn(what, f"rejected {what}: {exc}")
            return None


#: Starts the warning of the callback guard; the test harness (erforce_interfaces.tools.testing) fails a
#: test whose node logged it, unless the test declared it expects it.
CALLBACK_FAULT = "callback fault"


class SchemaNode(Node):
    """A Node whose parameters are its schema's: after ``__init__`` it has ``_params`` (NodeParams, built with
    ``build``), ``_values`` (the parameter values by name) and ``_warn`` (a ThrottledWarner). The node shells'
    common start; each sets itself up from ``self._params.built`` and then calls ``self._params.on_change``."""

    def __init__(self, node_name: str, schema: ParamSchema, build: Callable[[Any], Any] | None = None) -> None:
        super().__init__(node_name)
        self._warn = ThrottledWarner(self)
        self._params = NodeParams(self, schema, build)
        self._values = self._params.values


def guard_callbacks(node: Node) -> ThrottledWarner:
    """The one guard around every subscription callback of ``node``'s process (executor.guard): it
    guards the node's subscriptions (contract_subscription guards its own at creation, also later ones)
    and installs the handler, so it holds under any executor.

    The nodes reject bad input they know of with their own warnings ("rejected ..."); an exception
    that still escapes a callback is bad input nobody foresaw or a bug of ours. Either way the message
    is dropped and the node lives on: a throttled warning names the topic, the exception and where it
    was raised, and counts them per topic (``counts``). After shutdown (Ctrl-C under a publish) the
    exception is the shutdown itself and is dropped without a word (an executor would report it as a fault).
    """
    warner = ThrottledWarner(node)

    def on_fault(sub, exc: Exception) -> None:
        if not node.context.ok():
            return  # the shutdown under a publish, not a fault; the spin loop ends on the context
        topic = sub.topic_name
        frames = traceback.extract_tb(exc.__traceback__)
        last = frames[-1] if frames else None
        where = f" at {last.filename.rsplit('/', 1)[-1]}:{last.lineno} in {last.name}" if last else ""
        warner.warn(topic, f"{CALLBACK_FAULT} on {topic}: {type(exc).__name__}: {exc}{where}; message dropped")

    for sub in node.subscriptions:
        guard(sub)
    for timer in node.timers:
        timer.callback = quiet_after_shutdown(node, timer.callback)
    set_callback_fault_handler(on_fault)
    return warner


def quiet_after_shutdown(node: Node, callback: Callable[[], None]) -> Callable[[], None]:
    """A timer callback that ends silently when Ctrl-C shut the context down under it (a publish then
    raises "context is invalid", which an executor would log as a fatal fault). Any other exception still
    ends the node: a timer is our own code, not input."""

    def run() -> None:
        try:
            callback()
        except Exception:
            if node.context.ok():
                raise

    return run


def guard_clock(node: Node, max_jump_s: float = 2.0) -> StampFilter | None:
    """Put the stack's time rule (stamps.StampFilter) in front of rclpy's ``/clock`` callback.

    rclpy's TimeSource raises on a negative clock and follows any other, so a single far-future or
    backwards ``/clock`` from any participant moved every sim-time node's time. Now such a clock is
    dropped with a throttled warning, and a confirmed new time line (a restarted simulator) resets
    the node's clock and calls ``node.on_clock_restart()`` when the node has one. Returns the filter
    (None without use_sim_time: no /clock subscription).
    """
    subs = [s for s in node.subscriptions if s.topic_name == CLOCK.name]
    if not subs:
        return None
    stamps = StampFilter(max_jump_s)
    warner = ThrottledWarner(node)
    for sub in subs:
        inbox = guard(sub)  # the rule goes behind the callback guard, in front of rclpy's callback
        set_time = inbox.callback

        def on_clock(msg, set_time=set_time) -> None:
            verdict = stamps.offer(stamp_ns(msg.clock.sec, msg.clock.nanosec))
            if verdict is StampVerdict.DROP:
                warner.warn("clock", f"dropped /clock: {stamps.reason}")
                return
            set_time(msg)
            if verdict is StampVerdict.RESTART:
                node.get_logger().warning(f"/clock: {stamps.reason}; resetting")
                restart = getattr(node, "on_clock_restart", None)
                if restart is not None:
                    restart()

        inbox.set_callback(on_clock)
    return stamps


def check_stamp(stamps: StampFilter, t_ns: int | None, warner: ThrottledWarner, topic: str,
                node: Node) -> StampVerdict:
    """The time rule for one input's header stamp: a dropped stamp warns (throttled, per topic), a
    restart is logged; the caller drops the message on DROP and resets its state on RESTART."""
    verdict = stamps.offer(t_ns)
    if verdict is StampVerdict.DROP:
        warner.warn(f"stamp {topic}", f"rejected {topic}: {stamps.reason}")
    elif verdict is StampVerdict.RESTART:
        node.get_logger().warning(f"{topic}: {stamps.reason}; resetting")
    return verdict


class QuietInterrupt:
    """The Python side of SIGINT while a node process runs (run_node; the recorder's own loop).

    rclpy's handler (installed by ``rclpy.init``) shuts the context down, which ends the spin, and then
    calls the Python handler. Python's default raises KeyboardInterrupt wherever the main thread is:
    when Ctrl-C in a terminal reaches a whole process group, ``ros2 launch`` forwards a second SIGINT
    to each node, which then interrupted ``destroy_node()`` in the cleanup (a traceback, exit code -2).
    This handler raises only once, and only while ``raising``: run_node leaves it on while the node
    starts (the first SIGINT ends the start) and turns it off when the spin begins, whose loop ends on
    ``received`` or the shut-down context (at most one spin_once timeout later).
    Install it before ``rclpy.init`` (rclpy calls the handler it found).
    """

    def __init__(self) -> None:
        self.received = False
        self.raising = True
        # Python handles signals in the main thread only; a node run in another thread keeps the default.
        in_main = threading.current_thread() is threading.main_thread()
        self._previous = signal.signal(signal.SIGINT, self._handle) if in_main else None

    def _handle(self, _signum, _frame) -> None:
        self.received = True
        if self.raising:
            self.raising = False
            raise KeyboardInterrupt

    def restore(self) -> None:
        """Give SIGINT back to the previous handler, unless one arrived: then the process is on its way
        out and further SIGINTs are ignored until it has exited (Python's finalization would reset a
        handler of its own to the default, which a late SIGINT kills the process by: exit code -2)."""
        if self._previous is not None:
            signal.signal(signal.SIGINT, signal.SIG_IGN if self.received else self._previous)


def stray_arguments(argv: list[str]) -> list[str]:
    """What a node's command line holds besides its program name and its ROS arguments: ``-p x:=1`` without
    ``--ros-args`` before it is silently no parameter at all, so the node names what it ignores."""
    return remove_ros_args(list(argv))[1:]


_EXIT_CODES: weakref.WeakKeyDictionary[Node, int] = weakref.WeakKeyDictionary()
FLUSH_TIMEOUT_S = 2.0  # how long a node that ends itself waits for its subscribers' acknowledgements


def end_node(node: Node, code: int = 0) -> None:
    """End ``run_node``'s loop after the current callback, with exit ``code``: a node that ends itself (the
    plant's stop_after_s). Raising SystemExit in a callback would end it too, but the executor logs that as
    a fatal fault, and the last messages could die with the process before a subscriber took them."""
    _EXIT_CODES[node] = int(code)


def flush_publishers(node: Node, timeout_s: float = FLUSH_TIMEOUT_S) -> bool:
    """Wait until every reliable subscriber acknowledged what ``node`` published, at most ``timeout_s`` in
    all; False when one did not (a subscriber that is gone or stuck must not hold a node's exit)."""
    deadline = time.monotonic() + timeout_s
    acked = True
    for publisher in node.publishers:
        left_ns = max(0, int((deadline - time.monotonic()) * 1e9))
        acked = publisher.wait_for_all_acked(Duration(nanoseconds=left_ns)) and acked
    return acked


def run_node(node_factory: Callable[[], Node | tuple[Node, ...]], args: list[str] | None = None,
             executor_kind: str | None = None) -> int:
    """Standard node main: init, spin on EventsExecutor (erforce_interfaces.runtime.executor.make_executor;
    ``executor_kind`` picks another, as there), clean shutdown. A factory may return several nodes: one process
    and one executor for all (as a component container), destroyed in the order given.

    Every node gets the callback guard (guard_callbacks) and the time rule on /clock (guard_clock).

    In erforce-launch's warm standby (erforce_interfaces.runtime.standby) warming up, it returns 0 before
    ``rclpy.init``, after the node's optional ``warm_up`` (a static method of the node class: an expensive first
    step that needs no node, e.g. loading numba kernels); the spare calls the node's main again when it becomes
    the node.
    A main does nothing else before run_node that it would not want done in the spare.

    A node ends itself with ``end_node`` (its code is the exit code).

    Returns the process exit code: 0 after Ctrl-C (one SIGINT or several, to the process alone or to
    its process group; see QuietInterrupt) or external shutdown, 1 when the node refused to start
    (for example an invalid parameter file).
    """
    interrupt = QuietInterrupt()
    node = None
    nodes: tuple[Node, ...] = ()
    code = 0
    light_node_start()  # a respawned node is back sooner (rclpy_internals)
    try:
        if not wait_for_go(getattr(node_factory, "warm_up", None)):
            return 0
        # The stack's DDS settings also under `ros2 run` or a launcher of the user's: Fast DDS reads them
        # when rclpy.init creates the participant; a profile or mode the user set stays.
        os.environ.update(dds_profile_env())
        rclpy.init(args=args)
        try:
            made = node_factory()
        except ValueError as exc:
            # Invalid configuration at start-up: one clear line, no traceback.
            rclpy.logging.get_logger("erforce").fatal(f"cannot start: {exc}")
            return 1
        nodes = made if isinstance(made, tuple) else (made,)
        node = nodes[0]
        stray = stray_arguments(sys.argv if args is None else args)
        if stray:
            node.get_logger().warning(
                f"ignoring arguments {' '.join(stray)}: a node takes ROS arguments only, after --ros-args "
                "(e.g. --ros-args -p port:=10020)")
        executor = make_executor(executor_kind)  # EventsExecutor unless told or ERFORCE_EXECUTOR says otherwise
        for each in nodes:
            guard_callbacks(each)
            guard_clock(each)
            executor.add_node(each)
        # The imports (numpy, numba, rclpy) leave ~130k objects that the cyclic GC would scan in every
        # full collection: ~50 ms each back to back, while the node's loop waits. They live as long
        # as the process, so they leave the GC's generations once, here.
        gc.collect()
        gc.freeze()
        # From here a SIGINT only ends the loop: raised inside a callback, KeyboardInterrupt would be reported
        # by the executor as that callback's fault. rclpy's handler shuts the context down; the loop sees it.
        interrupt.raising = False
        while node.context.ok() and not interrupt.received and not any(n in _EXIT_CODES for n in nodes):
            executor.spin_once(timeout_sec=0.5)
        ended = [_EXIT_CODES[n] for n in nodes if n in _EXIT_CODES]
        if ended:  # end_node: what the node sent last reaches its subscribers before it goes
            code = ended[0]
            for each in nodes:
                flush_publishers(each)
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
        interrupt.raising = False  # a further SIGINT must not break the cleanup
        set_callback_fault_handler(None)
        for each in nodes:
            each.destroy_node()
        rclpy.try_shutdown()
        interrupt.restore()
    return code
