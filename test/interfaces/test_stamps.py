"""The one time rule (erforce_interfaces.wire.stamps) and the callback guard and /clock rule of every node
(node_support.guard_callbacks, guard_clock), in process."""

import time

import pytest
from builtin_interfaces.msg import Time
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Int32

from erforce_interfaces.runtime.executor import (
    EXECUTOR_KINDS,
    make_executor,
    run_sampled,
    sample_only,
    set_callback_fault_handler,
)
from erforce_interfaces.runtime.node_support import CALLBACK_FAULT, guard_callbacks, guard_clock, quiet_after_shutdown
from erforce_interfaces.tools.testing import isolated_node
from erforce_interfaces.wire import contract
from erforce_interfaces.wire.stamps import StampFilter, StampVerdict, stamp_ns

A, D, R = StampVerdict.ACCEPT, StampVerdict.DROP, StampVerdict.RESTART
S = 1_000_000_000


def verdicts(stamps_s, max_jump_s=2.0, wall_step_s=0.3):
    """Verdicts on stamps arriving ``wall_step_s`` apart (longer than the default silence_s, 0.2 s)."""
    f = StampFilter(max_jump_s)
    return [f.offer(None if t is None else round(t * S), k * wall_step_s) for k, t in enumerate(stamps_s)]


def test_stamp_ns_refuses_what_is_no_time():
    assert stamp_ns(0, 0) == 0
    assert stamp_ns(3, 5) == 3 * S + 5
    assert stamp_ns(2**31 - 1, S - 1) == (2**31 - 1) * S + S - 1
    assert stamp_ns(-1, 0) is None and stamp_ns(1, S) is None and stamp_ns(2**31, 0) is None


def test_a_running_time_line_accepts_steps_and_repeats():
    assert verdicts([0.0, 0.002, 0.002, 0.004, 2.004, 4.0]) == [A] * 6


def test_a_single_zero_far_future_or_backwards_stamp_is_dropped_and_the_line_goes_on():
    assert verdicts([10.0, 0.0, 10.002]) == [A, D, A]
    assert verdicts([10.0, 2**31 - 1.0, 10.002]) == [A, D, A]
    assert verdicts([10.0, 9.5, 10.002]) == [A, D, A]  # reordered or foreign
    assert verdicts([10.0, 12.5, 10.002]) == [A, D, A]  # more than max_jump_s ahead
    assert verdicts([10.0, None, 10.002]) == [A, D, A]


def test_a_restarted_clock_is_a_restart_at_its_second_stamp():
    assert verdicts([10.0, 0.0, 0.002, 0.004]) == [A, D, R, A]
    # re-sent (a restarted plant's first tick, until it is answered): the repeat confirms it once the old line was
    # silent for silence_s (0.2 s), not only once it is dead (dead_s, 1 s)
    assert verdicts([10.0, 0.0, 0.0, 0.0]) == [A, D, R, A]
    assert verdicts([10.0, 0.0, 0.0, 0.0], wall_step_s=0.05)[:3] == [A, D, D]  # 0.1 s of silence: not yet
    assert verdicts([10.0, 0.0], wall_step_s=1.5) == [A, R]  # a source that died and came back: at once
    assert verdicts([0.5, 0.0, 0.01]) == [A, D, R]  # also a restart shortly after the start
    assert verdicts([10.0, 100.0, 100.5]) == [A, D, R]  # a confirmed jump ahead


def test_a_flood_off_the_time_line_cannot_take_over_while_the_real_source_goes_on():
    """Say every message of a flood is stamped 0: while the real ticks keep coming (2 ms apart here),
    the old line is never silent for silence_s, so the flood confirms nothing."""
    stamps = [10.0]
    for k in range(1, 200):
        stamps += [0.0, 0.0, 10.0 + 0.002 * k]
    got = verdicts(stamps, wall_step_s=0.0007)
    assert got[3::3] == [A] * 199 and set(got[1::3] + got[2::3]) == {D}
    # the real source stops (a dead simulator) and a new one starts: restart once the old line was silent
    f = StampFilter(silence_s=0.2)
    assert [f.offer(t, w) for t, w in ((10 * S, 0.0), (0, 0.05), (0, 0.1), (0, 0.25), (S // 100, 0.3),
                                       (S // 50, 0.31))] == [A, D, D, R, A, A]


def test_two_unrelated_bad_stamps_confirm_nothing():
    assert verdicts([10.0, 0.0, 50.0, 10.002]) == [A, D, D, A]
    assert verdicts([10.0, 0.0, 5.0, 10.002]) == [A, D, D, A]  # 5 s after the jump: beyond max_jump_s


def test_the_filter_refuses_a_useless_jump_limit_and_resets():
    with pytest.raises(ValueError):
        StampFilter(0.0)
    with pytest.raises(ValueError):
        StampFilter(silence_s=-1.0)
    with pytest.raises(ValueError):
        StampFilter(silence_s=2.0, dead_s=1.0)
    f = StampFilter()
    f.offer(10 * S)
    f.reset()
    assert f.offer(0) is A


# ------------------------------------------------------------------ in process, over DDS
RELIABLE = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)


@pytest.fixture(params=EXECUTOR_KINDS)
def env(request):
    """A node on each executor a node may spin on: the guard lives on the callbacks, not in the executor."""
    with isolated_node("guard_test") as node:
        executor = make_executor(request.param, context=node.context)
        executor.add_node(node)
        yield node, executor
        set_callback_fault_handler(None)
        executor.shutdown()


def spin_until(executor, condition, timeout_s=10.0):
    deadline = time.monotonic() + timeout_s
    while not condition():
        assert time.monotonic() < deadline, "condition not reached"
        executor.spin_once(timeout_sec=0.02)


class Logged:
    """Captures a node's warnings."""

    def __init__(self, node):
        self.lines = []
        logger = node.get_logger()
        logger.warning = lambda text, **_: self.lines.append(text)
        node.get_logger = lambda: logger


def test_the_guard_turns_a_raising_callback_into_a_counted_warning_and_spins_on(env):
    node, executor = env
    logged = Logged(node)
    taken = []

    def picky(msg):
        if msg.data < 0:
            raise TypeError(f"negative {msg.data}")
        taken.append(msg.data)

    node.create_subscription(Int32, "/guarded", picky, RELIABLE)
    sampled = sample_only(node.create_subscription(Int32, "/guarded_sampled", picky, RELIABLE))
    warner = guard_callbacks(node)
    pub = node.create_publisher(Int32, "/guarded", RELIABLE)
    pub_sampled = node.create_publisher(Int32, "/guarded_sampled", RELIABLE)
    spin_until(executor, lambda: pub.get_subscription_count() and pub_sampled.get_subscription_count())
    for v in (1, -2, -3, 4):
        pub.publish(Int32(data=v))
        pub_sampled.publish(Int32(data=10 * v))
    spin_until(executor, lambda: len(taken) >= 2)
    spin_until(executor, lambda: run_sampled([sampled]) > 0 or len(taken) >= 4)
    run_sampled([sampled])
    assert sorted(taken) == [1, 4, 10, 40]
    assert warner.counts == {"/guarded": 2, "/guarded_sampled": 2}
    # throttled: one line per topic, naming the topic, the exception and where it was raised
    assert len(logged.lines) == 2
    assert all(CALLBACK_FAULT in line and "TypeError: negative" in line and "in picky" in line
               for line in logged.lines)


def test_without_a_guard_a_raising_callback_ends_the_spin(env):
    node, executor = env
    node.create_subscription(Int32, "/unguarded", lambda m: 1 / 0, RELIABLE)
    pub = node.create_publisher(Int32, "/unguarded", RELIABLE)
    spin_until(executor, lambda: pub.get_subscription_count())
    pub.publish(Int32(data=1))
    with pytest.raises(ZeroDivisionError):
        spin_until(executor, lambda: False, timeout_s=5.0)


def test_a_timer_fault_ends_the_node_unless_the_context_was_shut_down_under_it(env):
    node, _executor = env

    def publish_after_ctrl_c():
        raise RuntimeError("Failed to publish: publisher's context is invalid")

    timer = node.create_timer(10.0, publish_after_ctrl_c)
    guard_callbacks(node)
    # A timer is our own code: with the context up its exception still ends the node.
    with pytest.raises(RuntimeError, match="context is invalid"):
        timer.callback()

    class ShutDown:
        context = type("Context", (), {"ok": staticmethod(lambda: False)})()

    # After Ctrl-C the same exception is the shutdown itself: silent.
    assert quiet_after_shutdown(ShutDown(), publish_after_ctrl_c)() is None


def test_the_clock_rule_drops_garbage_and_resets_on_a_restart(env):
    node, executor = env
    from rclpy.parameter import Parameter

    node.set_parameters([Parameter("use_sim_time", value=True)])
    logged = Logged(node)
    restarts = []
    node.on_clock_restart = lambda: restarts.append(node.get_clock().now().nanoseconds)
    guard_callbacks(node)
    stamps = guard_clock(node)
    pub = node.create_publisher(Clock, contract.CLOCK.name, contract.CLOCK.qos)
    spin_until(executor, lambda: pub.get_subscription_count())

    def send(sec, nanosec, seen):
        """Publish until ``seen()``: rclpy's /clock reader is best effort, keep last 1."""
        deadline = time.monotonic() + 10.0
        while not seen():
            assert time.monotonic() < deadline, f"clock {sec} s {nanosec} ns not seen"
            pub.publish(Clock(clock=Time(sec=sec, nanosec=nanosec)))
            executor.spin_once(timeout_sec=0.02)

    def now_is(ns):
        return lambda: node.get_clock().now().nanoseconds == ns

    def judged():
        return stamps.reason != ""

    send(10, 0, now_is(10 * S))
    for sec, nanosec in ((-1, 0), (1, S), (0, 0), (2**31 - 1, 0), (5, 0), (12, 5000)):
        stamps.reason = ""
        send(sec, nanosec, judged)  # dropped: rclpy's Time.from_msg raises on the first two
        send(10, 1000, now_is(10 * S + 1000))
    assert sum("dropped /clock" in line for line in logged.lines) == 1, logged.lines  # throttled
    assert not any(CALLBACK_FAULT in line for line in logged.lines)
    assert restarts == []
    stamps.reason = ""
    send(0, 0, judged)  # the simulator restarted: its second clock confirms it
    assert restarts == [] and node.get_clock().now().nanoseconds == 10 * S + 1000
    send(0, 2_000_000, now_is(2_000_000))
    assert restarts == [2_000_000]
