"""``erforce-topic``: a ``ros2 topic`` work-alike built on rclpy alone (no ros2cli, no rosidl_runtime_py).

Verbs and their output follow ``ros2 topic`` (Jazzy) so that habits and scripts carry over:

- ``list [-t] [-v] [-c]``  topic names, sorted; ``-v`` the "Published topics:" / "Subscribed topics:" view.
- ``info [-v] TOPIC``      type and endpoint counts; ``-v`` every endpoint with its QoS profile.
- ``type TOPIC``           the topic's type(s).
- ``echo TOPIC [TYPE]``    each message as YAML (the text rosidl_runtime_py's message_to_yaml gives),
  then ``---``; ``--field a.b[0]``, ``--csv``, ``--no-arr``, ``--no-str``, ``--once``, QoS options.
- ``hz TOPIC``             once a second ``average rate: R`` / ``min/max/std dev/window``.
- ``pub TOPIC TYPE YAML``  fills a message from YAML and publishes it (``-r``, ``--once``, ``-t``, ``-w``).

The tool is not part of the stack's wire contract; it is how a person (and the integration tests)
look at a running graph. Errors the user can fix (unknown type, bad YAML, unknown field, unknown
topic) end the program with one line on stderr and exit code 1; Ctrl-C ends it with exit code 0.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import rclpy
import yaml
from rclpy.clock import Clock, ClockType
from rclpy.duration import Duration
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.expand_topic_name import expand_topic_name
from rclpy.parameter import Parameter
from rclpy.qos import (
    QoSDurabilityPolicy,
    QoSHistoryPolicy,
    QoSPresetProfiles,
    QoSProfile,
    QoSReliabilityPolicy,
    qos_profile_sensor_data,
)
from rclpy.validate_full_topic_name import validate_full_topic_name

from erforce_interfaces.tools.message_text import (
    ToolError,
    dump_yaml,
    get_field,
    get_message_class,
    message_to_csv,
    message_to_yaml,
    new_message,
    parse_field_path,
    set_message_fields,
    to_plain,
)
from erforce_interfaces.wire.contract import dds_profile_env

DEFAULT_TRUNCATE_LENGTH = 128  # as ros2 topic echo
DEFAULT_HZ_WINDOW = 10000  # as ros2 topic hz
DEFAULT_SPIN_TIME_S = 0.5  # discovery wait of list / info / type, as ros2cli's direct node
# Without a ros2 daemon a topic can take one SPDP announcement period (3 s in Fast DDS) to show up
# when an initial announcement was missed; info/type wait that long for a topic they were named.
NAMED_TOPIC_WAIT_S = 3.5



# --------------------------------------------------------------------------------------------------
# Rate statistics (ros2 topic hz)
# --------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class RateStats:
    rate_hz: float
    min_interval_s: float
    max_interval_s: float
    std_dev_s: float
    window: int

    def text(self) -> str:
        """The two lines ros2 topic hz prints."""
        return (
            f"average rate: {self.rate_hz:.3f}\n\tmin: {self.min_interval_s:.3f}s "
            f"max: {self.max_interval_s:.3f}s std dev: {self.std_dev_s:.5f}s window: {self.window}"
        )


class RateWindow:
    """Intervals between the last ``window`` message arrivals (integer nanoseconds)."""

    def __init__(self, window: int = DEFAULT_HZ_WINDOW) -> None:
        if not isinstance(window, int) or window < 1:
            raise ValueError(f"window must be a positive integer, got {window!r}")
        self._intervals_ns: deque[int] = deque(maxlen=window)
        self._last_ns: int | None = None
        self.arrivals = 0

    def add(self, t_ns: int) -> None:
        """Record an arrival. A clock going backwards (sim time reset) starts the window anew."""
        if self._last_ns is not None and t_ns < self._last_ns:
            self._intervals_ns.clear()
        elif self._last_ns is not None:
            self._intervals_ns.append(t_ns - self._last_ns)
        self._last_ns = t_ns
        self.arrivals += 1

    def stats(self) -> RateStats | None:
        """Rate = 1 / mean interval; std dev is the population one; None before two arrivals."""
        if not self._intervals_ns:
            return None
        d = np.fromiter(self._intervals_ns, dtype=np.float64, count=len(self._intervals_ns)) * 1e-9
        mean = float(d.mean())
        return RateStats(
            rate_hz=1.0 / mean if mean > 0.0 else 0.0,
            min_interval_s=float(d.min()),
            max_interval_s=float(d.max()),
            std_dev_s=float(np.sqrt(np.mean((d - mean) ** 2))),
            window=len(d),
        )


# --------------------------------------------------------------------------------------------------
# QoS
# --------------------------------------------------------------------------------------------------


def _copy_qos(p: QoSProfile) -> QoSProfile:
    return QoSProfile(
        history=p.history, depth=p.depth, reliability=p.reliability, durability=p.durability,
        lifespan=p.lifespan, deadline=p.deadline, liveliness=p.liveliness,
        liveliness_lease_duration=p.liveliness_lease_duration,
        avoid_ros_namespace_conventions=p.avoid_ros_namespace_conventions,
    )


def _add_qos_args(parser: argparse.ArgumentParser, default_profile: str) -> None:
    parser.add_argument("--qos-profile", choices=QoSPresetProfiles.short_keys(), default=default_profile,
                        help=f"QoS preset to start from (default: {default_profile})")
    parser.add_argument("--qos-reliability", choices=QoSReliabilityPolicy.short_keys())
    parser.add_argument("--qos-durability", choices=QoSDurabilityPolicy.short_keys())
    parser.add_argument("--qos-history", choices=QoSHistoryPolicy.short_keys())
    parser.add_argument("--qos-depth", type=int)


def choose_qos(args: argparse.Namespace, peers: Sequence[Any]) -> QoSProfile:
    """The preset with the user's overrides; policies the user left open adapt to ``peers``.

    With peers (the publishers, for echo): reliable only if all of them are reliable (a best-effort
    publisher never talks to a reliable subscription), transient-local only if all of them are.
    """
    qos = _copy_qos(QoSPresetProfiles.get_from_short_key(args.qos_profile))
    if args.qos_history:
        qos.history = QoSHistoryPolicy.get_from_short_key(args.qos_history)
    if args.qos_depth is not None:
        qos.depth = args.qos_depth
    if args.qos_reliability:
        qos.reliability = QoSReliabilityPolicy.get_from_short_key(args.qos_reliability)
    elif peers:
        reliable = all(p.qos_profile.reliability == QoSReliabilityPolicy.RELIABLE for p in peers)
        qos.reliability = QoSReliabilityPolicy.RELIABLE if reliable else QoSReliabilityPolicy.BEST_EFFORT
    if args.qos_durability:
        qos.durability = QoSDurabilityPolicy.get_from_short_key(args.qos_durability)
    elif peers:
        latched = all(p.qos_profile.durability == QoSDurabilityPolicy.TRANSIENT_LOCAL for p in peers)
        qos.durability = QoSDurabilityPolicy.TRANSIENT_LOCAL if latched else QoSDurabilityPolicy.VOLATILE
    return qos


# --------------------------------------------------------------------------------------------------
# The rclpy side
# --------------------------------------------------------------------------------------------------


def _out(text: str = "", end: str = "\n") -> None:
    sys.stdout.write(text + end)
    sys.stdout.flush()  # piped output (grep, tests) must not wait for a full buffer


def _is_hidden(name: str) -> bool:
    return any(token.startswith("_") for token in name.split("/"))


class Session:
    """One hidden node on a SingleThreadedExecutor, with deadline-based spinning."""

    def __init__(self, ros_args: list[str], *, use_sim_time: bool = False) -> None:
        os.environ.update(dds_profile_env())  # the nodes' DDS settings: on LOCALHOST, sockets on loopback only
        rclpy.init(args=ros_args)
        overrides = [Parameter("use_sim_time", value=True)] if use_sim_time else []
        self.node = rclpy.create_node(
            f"_erforce_topic_{os.getpid()}", start_parameter_services=False, parameter_overrides=overrides
        )
        self.executor = SingleThreadedExecutor()
        self.executor.add_node(self.node)

    def close(self) -> None:
        self.executor.shutdown(timeout_sec=1.0)
        self.node.destroy_node()
        rclpy.try_shutdown()

    def spin_until(self, done: Callable[[], bool], timeout_s: float | None) -> bool:
        """Spin until ``done()`` or the timeout (None: forever); returns ``done()``."""
        deadline = None if timeout_s is None else time.monotonic() + timeout_s
        while not done():
            left = 0.1 if deadline is None else min(0.1, deadline - time.monotonic())
            if left <= 0:
                break
            self.executor.spin_once(timeout_sec=left)
        return done()

    def spin_for(self, seconds: float) -> None:
        self.spin_until(lambda: False, seconds)

    def resolve(self, topic: str) -> str:
        try:
            name = expand_topic_name(topic, self.node.get_name(), "/")
            validate_full_topic_name(name)
        except Exception as exc:  # rclpy raises its own InvalidTopicNameException types
            raise ToolError(f"invalid topic name '{topic}': {exc}") from None
        return name

    def topic_types(self, topic: str) -> list[str] | None:
        return dict(self.node.get_topic_names_and_types()).get(topic)

    def wait_for_type(self, topic: str, timeout_s: float | None) -> type:
        """The message class of ``topic``, waiting until some endpoint announces it."""
        found: list[list[str]] = []

        def known() -> bool:
            types = self.topic_types(topic)
            if types:
                found.append(types)
            return bool(types)

        if not self.spin_until(known, min(timeout_s, 1.0) if timeout_s is not None else 1.0):
            print(f"waiting for topic '{topic}' to appear ...", file=sys.stderr, flush=True)
            rest = None if timeout_s is None else max(0.0, timeout_s - 1.0)
            if not self.spin_until(known, rest):
                raise ToolError(f"could not determine the type of '{topic}': no endpoint appeared")
        types = found[-1]
        if len(types) > 1:
            raise ToolError(f"topic '{topic}' has several types ({', '.join(types)}): give the type")
        return get_message_class(types[0])


# --------------------------------------------------------------------------------------------------
# Verbs
# --------------------------------------------------------------------------------------------------


def cmd_list(s: Session, args: argparse.Namespace) -> int:
    s.spin_for(args.spin_time)
    topics = sorted(
        (n, t) for n, t in s.node.get_topic_names_and_types()
        if args.include_hidden_topics or not _is_hidden(n)
    )
    if args.count_topics:
        _out(str(len(topics)))
    elif args.verbose:
        for kind, count in (("publisher", s.node.count_publishers), ("subscriber", s.node.count_subscribers)):
            _out("\nPublished topics:" if kind == "publisher" else "\nSubscribed topics:")
            for name, types in topics:
                n = count(name)
                if n:
                    _out(f" * {name} [{', '.join(types)}] {n} {kind}{'s' if n > 1 else ''}")
    else:
        for name, types in topics:
            _out(f"{name} [{', '.join(types)}]" if args.show_types else name)
    return 0


def cmd_info(s: Session, args: argparse.Namespace) -> int:
    topic = s.resolve(args.topic)
    s.spin_for(args.spin_time)
    s.spin_until(lambda: s.topic_types(topic) is not None, NAMED_TOPIC_WAIT_S)
    types = s.topic_types(topic)
    if types is None:
        raise ToolError(f"Unknown topic '{topic}'")
    if args.verbose:  # node names arrive with a little delay after the endpoints themselves

        def named() -> bool:
            infos = s.node.get_publishers_info_by_topic(topic) + s.node.get_subscriptions_info_by_topic(topic)
            return all(i.node_name != "_NODE_NAME_UNKNOWN_" for i in infos)

        s.spin_until(named, 2.0)
    end = "\n\n" if args.verbose else "\n"
    _out(f"Type: {types[0] if len(types) == 1 else types}", end=end)
    _out(f"Publisher count: {s.node.count_publishers(topic)}", end=end)
    if args.verbose:
        for info in s.node.get_publishers_info_by_topic(topic):
            _out(str(info), end=end)
    _out(f"Subscription count: {s.node.count_subscribers(topic)}", end=end)
    if args.verbose:
        for info in s.node.get_subscriptions_info_by_topic(topic):
            _out(str(info), end=end)
    return 0


def cmd_type(s: Session, args: argparse.Namespace) -> int:
    topic = s.resolve(args.topic)
    s.spin_until(lambda: s.topic_types(topic) is not None, max(args.spin_time, NAMED_TOPIC_WAIT_S))
    types = s.topic_types(topic)
    if types is None:
        raise ToolError(f"Unknown topic '{topic}'")
    for t in types:
        _out(t)
    return 0


def _format_value(value: Any, args: argparse.Namespace) -> str:
    """What echo prints for one received message (or the selected field of it)."""
    truncate = None if args.full_length else args.truncate_length
    opts = {"truncate_length": truncate, "no_arr": args.no_arr, "no_str": args.no_str}
    if hasattr(value, "get_fields_and_field_types"):
        if args.csv:
            return message_to_csv(value, **opts) + "\n"
        return message_to_yaml(value, flow_style=args.flow_style, **opts) + "---\n"
    plain = to_plain(value, truncate=truncate, no_arr=False, no_str=args.no_str)
    if args.csv:
        return (",".join(map(str, plain)) if isinstance(plain, list) else str(plain)) + "\n"
    if isinstance(plain, list | dict):  # a selected array: YAML list, as inside a message
        return dump_yaml(plain, args.flow_style) + "---\n"
    return f"{plain}\n---\n"  # a selected scalar: printed bare, as ros2 topic echo does


def cmd_echo(s: Session, args: argparse.Namespace) -> int:
    topic = s.resolve(args.topic)
    field = parse_field_path(args.field) if args.field else None
    if args.type:
        cls = get_message_class(args.type)
        # Give publishers a moment to be discovered so that the QoS can adapt to them.
        s.spin_until(lambda: s.node.count_publishers(topic) > 0, min(args.spin_time, args.timeout or 1e9))
    else:
        cls = s.wait_for_type(topic, args.timeout)
    qos = choose_qos(args, s.node.get_publishers_info_by_topic(topic))
    received = [0]

    def on_message(msg: Any) -> None:
        if args.once and received[0]:
            return
        value = get_field(msg, field) if field else msg
        _out(_format_value(value, args), end="")
        received[0] += 1

    s.node.create_subscription(cls, topic, on_message, qos)
    s.spin_until(lambda: args.once and received[0] > 0, args.timeout)
    return 0


def cmd_hz(s: Session, args: argparse.Namespace) -> int:
    topic = s.resolve(args.topic)
    cls = s.wait_for_type(topic, args.duration)
    window = RateWindow(args.window)
    steady = Clock(clock_type=ClockType.STEADY_TIME)
    clock = s.node.get_clock() if args.use_sim_time else steady

    def on_message(_msg: Any) -> None:
        t_ns = clock.now().nanoseconds
        if t_ns != 0:  # sim time before the first /clock message
            window.add(t_ns)

    s.node.create_subscription(cls, topic, on_message, _copy_qos(qos_profile_sensor_data))
    start = time.monotonic()
    stop = None if args.duration is None else start + args.duration
    reports, last_arrivals, next_report = 0, 0, start + 1.0
    while args.count is None or reports < args.count:
        until = next_report if stop is None else min(next_report, stop)
        s.spin_until(lambda: time.monotonic() >= until, None)  # noqa: B023 (used right here)
        if stop is not None and time.monotonic() >= stop:
            break
        next_report += 1.0
        stats = window.stats()
        if stats is not None and window.arrivals != last_arrivals:
            _out(stats.text())
            reports += 1
            last_arrivals = window.arrivals
    return 0


def cmd_pub(s: Session, args: argparse.Namespace) -> int:
    if not (args.rate > 0 and math.isfinite(args.rate)):
        raise ToolError(f"rate must be a positive number, got {args.rate}")
    topic = s.resolve(args.topic)
    cls = get_message_class(args.type)
    try:
        values = yaml.safe_load(args.values)
    except yaml.YAMLError as exc:
        raise ToolError(f"invalid YAML: {' '.join(str(exc).split())}") from None
    if values is not None and not isinstance(values, dict):
        raise ToolError("The passed value needs to be a dictionary in YAML format")
    msg = new_message(cls)
    stamps = set_message_fields(msg, values)
    times = 1 if args.once else args.times

    subs = s.node.get_subscriptions_info_by_topic(topic)
    qos = choose_qos(args, [])
    if not args.qos_durability and any(
        i.qos_profile.durability == QoSDurabilityPolicy.TRANSIENT_LOCAL for i in subs
    ):
        qos.durability = QoSDurabilityPolicy.TRANSIENT_LOCAL  # offering more is compatible with all
    pub = s.node.create_publisher(cls, topic, qos)

    wait_for = args.wait_matching_subscriptions
    if wait_for is None:
        wait_for = 1 if times else 0
    if wait_for:
        deadline = None if args.max_wait_time_secs is None else time.monotonic() + args.max_wait_time_secs
        while pub.get_subscription_count() < wait_for:
            if deadline is not None and time.monotonic() >= deadline:
                raise ToolError(
                    f"Timed out waiting for subscribers: expected {wait_for}, got {pub.get_subscription_count()}"
                )
            _out(f"Waiting for at least {wait_for} matching subscription(s)...")
            step = 1.0 if deadline is None else min(1.0, deadline - time.monotonic())
            s.spin_until(lambda: pub.get_subscription_count() >= wait_for, max(step, 0.0))

    _out("publisher: beginning loop")
    period, count, next_t = 1.0 / args.rate, 0, time.monotonic()
    while True:
        if stamps:
            now = s.node.get_clock().now().to_msg()
            for set_stamp in stamps:
                set_stamp(now)
        count += 1
        if args.print and count % args.print == 0:
            _out(f"publishing #{count}: {msg!r}\n")
        pub.publish(msg)
        if times and count >= times:
            break
        next_t += period
        s.spin_until(lambda: time.monotonic() >= next_t, None)  # noqa: B023
    # Let the last message reach the wire: reliable readers acknowledge it; best effort gets a grace time.
    if qos.reliability == QoSReliabilityPolicy.RELIABLE:
        pub.wait_for_all_acked(Duration(seconds=max(args.keep_alive, 1.0)))
    s.spin_for(args.keep_alive)
    return 0


# --------------------------------------------------------------------------------------------------
# Command line
# --------------------------------------------------------------------------------------------------


def _nonneg_int(text: str) -> int:
    value = int(text)
    if value < 0:
        raise argparse.ArgumentTypeError("must be a non-negative integer")
    return value


def _pos_float(text: str) -> float:
    value = float(text)
    if not (value > 0 and math.isfinite(value)):
        raise argparse.ArgumentTypeError("must be a positive number")
    return value


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="erforce-topic", description="Inspect and use ROS 2 topics (a ros2 topic work-alike).",
        epilog="Arguments after --ros-args go to rclpy (e.g. --ros-args -p use_sim_time:=true).",
    )
    verbs = parser.add_subparsers(dest="verb", required=True, metavar="VERB")

    def verb(name: str, func: Callable, help_text: str, spin: bool = False) -> argparse.ArgumentParser:
        p = verbs.add_parser(name, help=help_text, description=help_text)
        p.set_defaults(func=func)
        if spin:
            p.add_argument("--spin-time", type=_pos_float, default=DEFAULT_SPIN_TIME_S,
                           help=f"seconds to wait for discovery (default {DEFAULT_SPIN_TIME_S})")
        return p

    p = verb("list", cmd_list, "Output a list of available topics", spin=True)
    p.add_argument("-t", "--show-types", action="store_true", help="additionally show the topic type")
    p.add_argument("-c", "--count-topics", action="store_true", help="only print the number of topics")
    p.add_argument("-v", "--verbose", action="store_true", help="list publishers and subscribers per topic")
    p.add_argument("--include-hidden-topics", action="store_true")

    p = verb("info", cmd_info, "Print information about a topic", spin=True)
    p.add_argument("topic")
    p.add_argument("-v", "--verbose", action="store_true", help="details of every endpoint, with QoS")

    p = verb("type", cmd_type, "Print a topic's type", spin=True)
    p.add_argument("topic")

    p = verb("echo", cmd_echo, "Print messages from a topic", spin=True)
    p.add_argument("topic")
    p.add_argument("type", nargs="?", help="message type (default: taken from the graph)")
    p.add_argument("--once", action="store_true", help="print the first message received and exit")
    p.add_argument("--timeout", type=_pos_float, help="give up after this many seconds")
    p.add_argument("--field", help="print only this field, e.g. pose.position or name[0]")
    p.add_argument("--csv", action="store_true", help="comma-separated values instead of YAML")
    p.add_argument("--no-arr", action="store_true", help="summarize array fields instead of printing them")
    p.add_argument("--no-str", action="store_true", help="summarize string fields")
    p.add_argument("-l", "--truncate-length", type=_nonneg_int, default=DEFAULT_TRUNCATE_LENGTH)
    p.add_argument("-f", "--full-length", action="store_true", help="never truncate")
    p.add_argument("--flow-style", action="store_true")
    _add_qos_args(p, "sensor_data")

    p = verb("hz", cmd_hz, "Print the average receiving rate")
    p.add_argument("topic")
    p.add_argument("-w", "--window", type=int, default=DEFAULT_HZ_WINDOW, help="messages in the window")
    p.add_argument("--use-sim-time", action="store_true", help="measure in ROS time (/clock), not wall time")
    p.add_argument("--duration", type=_pos_float, help="stop after this many seconds")
    p.add_argument("--count", type=_nonneg_int, help="stop after this many reports")

    p = verb("pub", cmd_pub, "Publish a message to a topic")
    p.add_argument("topic")
    p.add_argument("type", help="message type, e.g. geometry_msgs/msg/Twist")
    p.add_argument("values", nargs="?", default="{}", help='YAML, e.g. "{linear: {x: 1.0}}"')
    p.add_argument("-r", "--rate", type=float, default=1.0, help="publishing rate [Hz] (default 1)")
    p.add_argument("-p", "--print", type=_nonneg_int, default=1, help="print every N-th message (0: never)")
    once = p.add_mutually_exclusive_group()
    once.add_argument("-1", "--once", action="store_true", help="publish one message and exit")
    once.add_argument("-t", "--times", type=_nonneg_int, default=0, help="publish this many times, then exit")
    p.add_argument("-w", "--wait-matching-subscriptions", type=_nonneg_int,
                   help="wait for N matching subscriptions first (default 1 with --once/--times, else 0)")
    p.add_argument("--max-wait-time-secs", type=_pos_float, help="give up waiting for subscriptions after this")
    p.add_argument("--keep-alive", type=float, default=0.1, help="seconds to stay alive after the last message")
    _add_qos_args(p, "default")
    return parser


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    ros_args: list[str] = []
    if "--ros-args" in argv:
        cut = argv.index("--ros-args")
        argv, ros_args = argv[:cut], argv[cut:]
    args = build_parser().parse_args(argv)
    if getattr(args, "verb", None) == "hz" and args.window < 1:
        print("erforce-topic: error: --window must be at least 1", file=sys.stderr)
        return 1
    session = None
    try:
        session = Session(["erforce-topic", *ros_args], use_sim_time=getattr(args, "use_sim_time", False))
        return args.func(session, args)
    except ToolError as exc:
        print(f"erforce-topic {args.verb}: error: {exc}", file=sys.stderr)
        return 1
    except (KeyboardInterrupt, ExternalShutdownException):
        return 0
    except BrokenPipeError:  # e.g. `erforce-topic echo /x | head`
        sys.stderr.close()
        return 0
    finally:
        if session is not None:
            try:
                session.close()
            except Exception:
                pass  # already shut down by the signal handler


if __name__ == "__main__":
    sys.exit(main())
