"""erforce_interfaces.runtime.executor: DirectExecutor serves every entity kind a node has, in one wait; sampled
subscriptions and undecodable samples behave alike under each executor make_executor offers.

Each test runs one node in its own context and DDS domain; publisher and subscription meet in the
same process over DDS. Waits are deadline-bound loops of ``spin_once``, never fixed sleeps.
"""

import threading
import time

import pytest
import rclpy
from builtin_interfaces.msg import Time
from rcl_interfaces.srv import SetParameters
from rclpy.event_handler import PublisherEventCallbacks, SubscriptionEventCallbacks
from rclpy.executors import ExternalShutdownException
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Int32

from erforce_interfaces.runtime.executor import (
    EXECUTOR_KINDS,
    DirectExecutor,
    make_executor,
    run_newest,
    run_sampled,
    sample_only,
)
from erforce_interfaces.runtime.node_support import NodeParams, sample_clock
from erforce_interfaces.runtime.param_schema import ParamSchema, ParamSpec
from erforce_interfaces.tools.testing import isolated_node
from erforce_interfaces.wire import contract

RELIABLE = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)


@pytest.fixture
def env():
    with isolated_node("executor_test") as node:
        executor = DirectExecutor(context=node.context)
        executor.add_node(node)
        yield node.context, node, executor
        executor.shutdown()


@pytest.fixture(params=EXECUTOR_KINDS)
def any_env(request):
    """The node on each executor a node may spin on (the kind instead of the context)."""
    with isolated_node("executor_test") as node:
        executor = make_executor(request.param, context=node.context)
        executor.add_node(node)
        yield request.param, node, executor
        executor.shutdown()


def spin_until(executor, condition, timeout_s=10.0):
    deadline = time.monotonic() + timeout_s
    while not condition():
        assert time.monotonic() < deadline, "condition not reached before the deadline"
        executor.spin_once(timeout_sec=0.05)


def connected(pub, sub):
    return lambda: pub.get_subscription_count() > 0 and sub.get_publisher_count() > 0


def test_subscriptions_receive_every_message_in_order_with_or_without_info(env):
    _, node, executor = env
    plain, with_info = [], []
    sub = node.create_subscription(Int32, "/exec/a", lambda m: plain.append(m.data), RELIABLE)
    node.create_subscription(Int32, "/exec/a", lambda m, info: with_info.append((m.data, info)), RELIABLE)
    pub = node.create_publisher(Int32, "/exec/a", RELIABLE)
    spin_until(executor, lambda: pub.get_subscription_count() == 2 and sub.get_publisher_count() == 1)
    for k in range(50):
        pub.publish(Int32(data=k))
    spin_until(executor, lambda: len(plain) == 50 and len(with_info) == 50)
    assert plain == list(range(50))
    assert [d for d, _ in with_info] == list(range(50))
    assert all(info["source_timestamp"] > 0 for _, info in with_info)


def test_timer_runs_at_its_period(env):
    _, node, executor = env
    calls = []
    node.create_timer(0.01, lambda: calls.append(time.monotonic()))
    spin_until(executor, lambda: len(calls) >= 11)
    # a 10 ms timer: the mean gap is its period (scheduling jitter averages out over 10 gaps)
    assert 0.008 <= (calls[-1] - calls[0]) / (len(calls) - 1) <= 0.03


def test_a_subscription_created_while_spinning_is_served(env):
    _, node, executor = env
    pub = node.create_publisher(Int32, "/exec/late", RELIABLE)
    executor.spin_once(timeout_sec=0.0)  # entities gathered without the subscription
    got = []
    sub = node.create_subscription(Int32, "/exec/late", lambda m: got.append(m.data), RELIABLE)
    spin_until(executor, connected(pub, sub))
    pub.publish(Int32(data=7))
    spin_until(executor, lambda: got == [7])


def test_a_callback_may_destroy_its_own_subscription(env):
    _, node, executor = env
    got = []

    def once(msg):
        got.append(msg.data)
        node.destroy_subscription(sub)

    sub = node.create_subscription(Int32, "/exec/once", once, RELIABLE)
    pub = node.create_publisher(Int32, "/exec/once", RELIABLE)
    spin_until(executor, connected(pub, sub))
    pub.publish(Int32(data=1))
    pub.publish(Int32(data=2))
    spin_until(executor, lambda: got)
    for _ in range(5):
        executor.spin_once(timeout_sec=0.02)
    assert got == [1]


def test_parameter_services_validate_through_the_executor(env):
    """A client (served by this executor too) sets parameters; the node's on-set check answers."""
    _, node, executor = env
    NodeParams(node, ParamSchema("executor_test", [ParamSpec("gain", "double", 2.0, "a gain", 0.0, 10.0)])).on_change(
        lambda config: None)
    client = node.create_client(SetParameters, "/executor_test/set_parameters")
    spin_until(executor, client.service_is_ready)

    def set_gain(value):
        request = SetParameters.Request(parameters=[Parameter("gain", value=value).to_parameter_msg()])
        future = client.call_async(request)
        executor.spin_until_future_complete(future, timeout_sec=10.0)
        assert future.done()
        return future.result().results[0]

    assert set_gain(4.0).successful and node.get_parameter("gain").value == 4.0
    rejected = set_gain(11.0)
    assert not rejected.successful and "out of range" in rejected.reason
    assert node.get_parameter("gain").value == 4.0


def test_guard_condition_callback_runs_when_triggered_from_another_thread(env):
    _, node, executor = env
    hits = []
    gc = node.create_guard_condition(lambda: hits.append(threading.get_ident()))
    threading.Thread(target=gc.trigger).start()
    spin_until(executor, lambda: hits)
    assert hits == [threading.get_ident()]  # the callback ran in the spinning thread


def test_qos_event_waitables_are_served(env):
    """An incompatible QoS pair raises events on both sides; their handlers are waitables."""
    _, node, executor = env
    events = []
    on_pub = PublisherEventCallbacks(incompatible_qos=lambda e: events.append("pub"))
    on_sub = SubscriptionEventCallbacks(incompatible_qos=lambda e: events.append("sub"))
    best_effort = QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT)
    node.create_publisher(Int32, "/exec/qos", best_effort, event_callbacks=on_pub)
    node.create_subscription(Int32, "/exec/qos", lambda m: None, RELIABLE, event_callbacks=on_sub)
    spin_until(executor, lambda: {"pub", "sub"} <= set(events))


def test_a_callback_that_awaits_is_refused(env):
    _, node, executor = env
    never = rclpy.task.Future()

    async def waits(msg):
        await never

    sub = node.create_subscription(Int32, "/exec/async", waits, RELIABLE)
    pub = node.create_publisher(Int32, "/exec/async", RELIABLE)
    spin_until(executor, connected(pub, sub))
    pub.publish(Int32(data=1))
    with pytest.raises(RuntimeError, match="awaited a future"):
        spin_until(executor, lambda: False, timeout_s=5.0)


def test_shutdown_ends_spin(env):
    _, _, executor = env
    threading.Timer(0.2, executor.shutdown).start()
    t0 = time.monotonic()
    executor.spin()
    assert time.monotonic() - t0 < 5.0


def test_context_shutdown_raises_external_shutdown(env):
    ctx, _, executor = env
    threading.Timer(0.2, lambda: rclpy.try_shutdown(context=ctx)).start()
    with pytest.raises(ExternalShutdownException):
        for _ in range(200):
            executor.spin_once(timeout_sec=0.05)


def test_a_sampled_subscription_waits_for_its_node(env):
    _, node, executor = env
    sampled, ordinary = [], []
    sub = sample_only(node.create_subscription(Int32, "/exec/sampled", lambda m: sampled.append(m.data), RELIABLE))
    node.create_subscription(Int32, "/exec/ordinary", lambda m: ordinary.append(m.data), RELIABLE)
    pub = node.create_publisher(Int32, "/exec/sampled", RELIABLE)
    marker = node.create_publisher(Int32, "/exec/ordinary", RELIABLE)
    spin_until(executor, lambda: connected(pub, sub)() and marker.get_subscription_count() == 1)
    for k in range(5):
        pub.publish(Int32(data=k))
    marker.publish(Int32(data=0))  # sent after the five: once it ran, they are queued too
    spin_until(executor, lambda: ordinary == [0])
    t0 = time.monotonic()
    executor.spin_once(timeout_sec=0.3)  # five queued messages do not end the wait
    assert time.monotonic() - t0 >= 0.25
    assert sampled == []
    assert run_sampled([sub]) == 5
    assert sampled == [0, 1, 2, 3, 4]
    assert run_sampled([sub]) == 0


def _queue_behind_marker(executor, node, publish) -> None:
    """Call ``publish``, then send a marker on an ordinary subscription and spin until it ran:
    whatever ``publish`` sent is queued by then. (The marker stays: destroying it would wake
    the executor's next wait.)"""
    seen = []
    topic = f"/exec/marker{len(list(node.subscriptions))}"
    marker_sub = node.create_subscription(Int32, topic, lambda m: seen.append(m.data), RELIABLE)
    marker = node.create_publisher(Int32, topic, RELIABLE)
    spin_until(executor, connected(marker, marker_sub))
    publish()
    marker.publish(Int32(data=1))
    spin_until(executor, lambda: seen == [1])


def _wait_lasts(executor, timeout_s: float) -> float:
    t0 = time.monotonic()
    executor.spin_once(timeout_sec=timeout_s)
    return time.monotonic() - t0


def test_a_sampled_subscription_can_be_waited_on_again_and_back(env):
    _, node, executor = env
    got = []
    sub = sample_only(node.create_subscription(Int32, "/exec/toggle", lambda m: got.append(m.data), RELIABLE))
    pub = node.create_publisher(Int32, "/exec/toggle", RELIABLE)
    spin_until(executor, connected(pub, sub))
    _queue_behind_marker(executor, node, lambda: pub.publish(Int32(data=0)))
    assert _wait_lasts(executor, 0.3) >= 0.25 and got == []
    sample_only(sub, False)  # waited on again: the queued message ends the next wait
    assert _wait_lasts(executor, 5.0) < 2.0 and got == [0]
    sample_only(sub)  # and sampled once more
    _queue_behind_marker(executor, node, lambda: pub.publish(Int32(data=1)))
    assert _wait_lasts(executor, 0.3) >= 0.25 and got == [0]
    assert run_sampled([sub]) == 1 and got == [0, 1]


def test_sample_clock_takes_sim_time_when_the_node_runs_not_per_message(env):
    _, node, executor = env
    node.set_parameters([Parameter("use_sim_time", Parameter.Type.BOOL, True)])
    subs = sample_clock(node)
    assert [s.topic_name for s in subs] == ["/clock"]
    pub = node.create_publisher(Clock, "/clock", contract.QOS_CLOCK)
    spin_until(executor, connected(pub, subs[0]))
    _queue_behind_marker(executor, node, lambda: pub.publish(Clock(clock=Time(sec=42, nanosec=5))))
    assert _wait_lasts(executor, 0.3) >= 0.25
    assert node.get_clock().now().nanoseconds == 0  # sim time not taken yet
    assert run_sampled(subs) == 1
    assert node.get_clock().now().nanoseconds == 42_000_000_005


def test_run_sampled_replays_several_subscriptions_in_send_order(any_env):
    """Under DirectExecutor in send order across subscriptions (DDS source timestamps); under the others
    the executor has taken them, and they run in the order taken: in send order per subscription."""
    kind, node, executor = any_env
    seen = []
    subs = [sample_only(node.create_subscription(Int32, f"/exec/s{i}", lambda m, i=i: seen.append((i, m.data)),
                                                 RELIABLE)) for i in range(2)]
    pubs = [node.create_publisher(Int32, f"/exec/s{i}", RELIABLE) for i in range(2)]
    spin_until(executor, lambda: all(connected(p, s)() for p, s in zip(pubs, subs, strict=True)))
    expected = []
    for k in range(20):
        i = (k * 7) % 3 % 2  # an irregular interleaving of the two topics
        pubs[i].publish(Int32(data=k))
        expected.append((i, k))
    deadline = time.monotonic() + 10.0
    while len(seen) < len(expected):
        assert time.monotonic() < deadline, f"only {len(seen)} of {len(expected)} arrived"
        executor.spin_once(timeout_sec=0.02)
        run_sampled(reversed(subs))  # the take order does not decide the replay order
    if kind == "direct":
        assert seen == expected
    for i in range(2):
        assert [v for j, v in seen if j == i] == [v for j, v in expected if j == i]
    assert sorted(seen, key=lambda item: item[1]) == expected


@pytest.mark.parametrize("kind", ["single", "events"])
def test_under_rclpy_executors_a_sampled_subscription_keeps_its_messages_for_its_node(kind):
    with isolated_node("sampled_elsewhere") as node:
        executor = make_executor(kind, context=node.context)
        executor.add_node(node)
        got = []
        sub = sample_only(node.create_subscription(Int32, "/exec/elsewhere", lambda m: got.append(m.data), RELIABLE))
        pub = node.create_publisher(Int32, "/exec/elsewhere", RELIABLE)
        spin_until(executor, connected(pub, sub))
        for k in range(3):
            pub.publish(Int32(data=k))
        ran = []
        spin_until(executor, lambda: ran.append(run_sampled([sub])) or got == [0, 1, 2])
        assert sum(ran) == 3
        # back to a callback per message: what waited runs first, in order
        pub.publish(Int32(data=3))
        spin_until(executor, lambda: sub.callback.queue)  # taken by the executor, waiting
        pub.publish(Int32(data=4))
        sample_only(sub, False)
        spin_until(executor, lambda: got == [0, 1, 2, 3, 4])
        executor.shutdown()


def test_an_undecodable_sample_never_reaches_a_callback_and_the_node_spins_on(any_env):
    """Bytes that are no JointState, published raw: rmw drops them in the take (no exception under
    any executor); a good message after them arrives."""
    _, node, executor = any_env
    from rclpy.serialization import serialize_message
    from sensor_msgs.msg import JointState

    got = []
    sub = node.create_subscription(JointState, "/exec/undecodable", lambda m: got.append(list(m.name)), RELIABLE)
    pub = node.create_publisher(JointState, "/exec/undecodable", RELIABLE)
    spin_until(executor, connected(pub, sub))
    good = serialize_message(JointState(name=["wheel_0"]))
    for bad in (good[:6], b"\x00\x01\x00\x00" + b"\xff" * 40):
        pub.publish(bad)  # bytes: rclpy publishes them as the serialized message
    pub.publish(good)
    spin_until(executor, lambda: got)
    assert got == [["wheel_0"]]


def test_run_newest_runs_only_the_newest_queued_message_of_each_subscription(any_env):
    """The plant's scenario commands: of what arrived since the last tick, only the newest acts."""
    _, node, executor = any_env
    got = []
    subs = [sample_only(node.create_subscription(Int32, f"/exec/newest_{k}", lambda m, k=k: got.append((k, m.data)),
                                                 RELIABLE)) for k in range(2)]
    pubs = [node.create_publisher(Int32, f"/exec/newest_{k}", RELIABLE) for k in range(2)]
    spin_until(executor, lambda: all(connected(p, s)() for p, s in zip(pubs, subs, strict=True)))
    for value in range(5):
        pubs[0].publish(Int32(data=value))
    pubs[1].publish(Int32(data=7))
    dropped = 0
    deadline = time.monotonic() + 10.0
    while not ((0, 4) in got and (1, 7) in got):
        assert time.monotonic() < deadline, got
        before = len(got)
        dropped += run_newest(subs)
        assert len(got) - before <= 2  # at most one callback per subscription and call
        executor.spin_once(timeout_sec=0.02)
    assert dropped + len(got) == 6
    firsts = [v for k, v in got if k == 0]
    assert firsts == sorted(firsts) and firsts[-1] == 4
