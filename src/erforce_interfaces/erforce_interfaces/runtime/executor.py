"""How the stack's nodes spin, and what their subscriptions do under any executor.

Every node spins on rclpy's EventsExecutor: ``make_executor`` makes the executor ``node_support.run_node``
spins on, EventsExecutor unless ERFORCE_EXECUTOR names another (``single``: SingleThreadedExecutor;
``direct``: rclpy_internals.DirectExecutor, for bench/bench_executor.py). DirectExecutor, the one executor of
our own, serves only the in-process observers that read a message's info (the test probe, the demo's
director); it and every other private rclpy name live in rclpy_internals.

Guarded subscriptions (``guard``): a subscription callback that raises would end ``spin`` and with
it the node, so one malformed message from any participant could kill a node. ``guard`` replaces a
subscription's callback, once, by an inbox that runs the node's callback inside the process's fault
handler (``set_callback_fault_handler``; ``node_support.run_node`` installs it for every node):
an exception goes to the handler instead of ending the spin, whichever executor called. Without a
handler (tests, tools) exceptions propagate. A sample rmw cannot deserialize never reaches Python:
rmw_fastrtps drops it and the take finds nothing (test/interfaces/test_executor.py shows it). Timers,
services and the rest are not guarded: they run on the node's own state, where an exception is a bug
that must stop the node.

Sampled subscriptions: a node that acts at its own rate on the newest inputs (a controller's or the
passing game's timer) or an observer that only needs every message eventually marks such subscriptions
with ``sample_only`` and calls ``run_sampled`` when it wants them, which runs their callbacks for
everything queued, oldest first (``run_newest``: only the newest of each). Under EventsExecutor a sampled
message is taken when it arrives and waits in the inbox, bounded by the subscription's history depth, so a
flood costs one append per message and one callback per ``run_newest``; DirectExecutor does not even wait
on a sampled subscription (nor serve its QoS events). A node that normally finds an input already queued
when it runs, but must wait when it is late (the motor boards' setpoint), switches it back with
``sample_only(sub, False)`` for as long as it waits. ``take_queued`` is the raw form.
"""

from __future__ import annotations

import collections
import inspect
import os
import time
import weakref
from collections.abc import Callable, Iterable

from rclpy.exceptions import InvalidHandle
from rclpy.executors import SingleThreadedExecutor
from rclpy.subscription import Subscription

from erforce_interfaces.runtime import rclpy_internals as internal  # every private rclpy name used here
from erforce_interfaces.runtime.rclpy_internals import DirectExecutor, finish_coroutine

__all__ = ["EXECUTOR_ENV", "EXECUTOR_KINDS", "DirectExecutor", "guard", "make_executor", "run_newest", "run_sampled",
           "sample_only", "set_callback_fault_handler", "take_one", "take_queued"]

EXECUTOR_ENV = "ERFORCE_EXECUTOR"  # the executor run_node spins on: one of EXECUTOR_KINDS (bench/bench_executor.py)
EXECUTOR_KINDS = ("direct", "single", "events")

_fault_handler: Callable[[Subscription, Exception], None] | None = None


def set_callback_fault_handler(handler: Callable[[Subscription, Exception], None] | None) -> None:
    """The guard every guarded subscription callback of this process runs inside (module doc); None
    removes it. The handler gets the subscription and the exception; it may re-raise."""
    global _fault_handler
    _fault_handler = handler


def make_executor(kind: str | None = None, *, context=None):
    """The executor a node spins on: ``events`` (rclpy.experimental.EventsExecutor, the default),
    ``single`` (rclpy's SingleThreadedExecutor) or ``direct`` (DirectExecutor); ``kind`` None reads the
    environment variable ERFORCE_EXECUTOR, so a bench can run the same nodes on each.

    EventsExecutor is the default for every node: public rclpy, the least CPU per message in
    bench/bench_executor.py; DirectExecutor saves the nodes that sample all their inputs a little CPU, which
    no target needs (docs/decisions/0001). The callback guard and the sampled subscriptions live on
    the subscriptions themselves (``guard``), so they hold under each."""
    kind = kind or os.environ.get(EXECUTOR_ENV) or "events"
    if kind == "direct":
        return DirectExecutor(context=context)
    if kind == "single":
        return SingleThreadedExecutor(context=context)
    if kind == "events":
        return _SpinOnceLoop(context)
    raise ValueError(f"{EXECUTOR_ENV}: one of {', '.join(EXECUTOR_KINDS)}, got {kind!r}")


class _SpinOnceLoop:
    """rclpy.experimental.EventsExecutor (a C++ object: no subclass) whose ``spin`` is a loop of ``spin_once``:
    in rclpy 7.1 its own ``spin()`` ran no timer and did not return after rclpy.shutdown
    (bench/bench_executor.py measures both)."""

    def __init__(self, context) -> None:
        from rclpy.experimental import EventsExecutor
        from rclpy.utilities import get_default_context

        self._context = context or get_default_context()
        self.executor = EventsExecutor(context=self._context)

    def __getattr__(self, name: str):
        return getattr(self.executor, name)

    def spin(self) -> None:
        while self._context.ok():
            self.executor.spin_once(timeout_sec=0.5)


class _Inbox:
    """What an executor calls for a guarded subscription (``guard``): the callback runs inside the fault
    handler, or, while the subscription is sampled, the message waits here for ``run_sampled``."""

    __slots__ = ("__weakref__", "callback", "queue", "sampled", "subscription", "wants_info")

    def __init__(self, subscription: Subscription, callback: Callable) -> None:
        self.subscription = weakref.proxy(subscription)  # the subscription holds its inbox
        self.set_callback(callback)
        depth = subscription.qos_profile.depth
        # Only what the subscription's own history would keep: a flood costs no memory here.
        self.queue: collections.deque = collections.deque(maxlen=depth if depth > 0 else _KEEP_ALL_BOUND)
        self.sampled = False

    def set_callback(self, callback: Callable) -> None:
        self.callback = callback
        self.wants_info = _takes_info(callback)

    def receive(self, msg, info=None) -> None:
        if self.sampled:
            if info is None:  # EventsExecutor passes no info: the time it arrived stands in for both
                now_ns = time.time_ns()
                info = {"source_timestamp": now_ns, "received_timestamp": now_ns}
            self.queue.append((msg, info))
        else:
            self.run(msg, info)

    def run(self, msg, info) -> None:
        try:
            finish_coroutine(self.callback(msg, info) if self.wants_info else self.callback(msg))
        except Exception as exc:
            if _fault_handler is None:
                raise
            _fault_handler(self.subscription, exc)


class _InboxWithInfo(_Inbox):
    __slots__ = ()

    def __call__(self, msg, info) -> None:  # rclpy then passes the message info (not EventsExecutor)
        self.receive(msg, info)


class _InboxMessageOnly(_Inbox):
    __slots__ = ()

    def __call__(self, msg) -> None:
        self.receive(msg)


_INBOXES: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
_KEEP_ALL_BOUND = 1000  # messages an inbox keeps for a keep-all subscription


def _takes_info(callback: Callable) -> bool:
    """rclpy's rule (Subscription.callback): a callback that cannot take one argument gets the message info."""
    try:
        inspect.signature(callback).bind(object())
        return False
    except TypeError:
        return True


def guard(subscription: Subscription) -> _Inbox:
    """Put the subscription's callback behind the process's fault handler, once (later calls return the
    same inbox). From then on ``subscription.callback`` is the inbox and ``inbox.callback`` the node's
    function; replace the latter with ``inbox.set_callback``."""
    inbox = _INBOXES.get(subscription)
    if inbox is None:
        original = subscription.callback
        inbox = (_InboxWithInfo if _takes_info(original) else _InboxMessageOnly)(subscription, original)
        _INBOXES[subscription] = inbox
        subscription.callback = inbox
    return inbox


def sample_only(subscription: Subscription, sampled: bool = True) -> Subscription:
    """Leave ``subscription``'s messages to its node (``run_sampled``), or with ``sampled=False`` run its
    callback per message again. DirectExecutor then does not even wait on it (from its next wait);
    under the other executors its messages wait in its inbox (``guard``)."""
    inbox = guard(subscription)
    if sampled != inbox.sampled:
        inbox.sampled = sampled
        internal.set_sampled(subscription, sampled)
        if not sampled:  # what arrived while it was sampled runs first, in order
            while inbox.queue:
                inbox.run(*inbox.queue.popleft())
    return subscription


def take_queued(subscription: Subscription) -> list:
    """Everything queued on a subscription, as (message, info) pairs: what waits in its inbox, then what
    rmw still holds."""
    inbox = _INBOXES.get(subscription)
    taken = []
    if inbox is not None:
        queue = inbox.queue
        while queue:  # one popleft at a time: an executor thread may append meanwhile (nothing is lost)
            taken.append(queue.popleft())
    while True:
        try:
            item = internal.take_message(subscription)
        except InvalidHandle:  # destroyed meanwhile
            break
        if item is None:
            break
        taken.append(item)
    return taken


def take_one(subscription: Subscription):
    """The oldest queued (message, info) of a subscription, or None: from its inbox, else from rmw. One take,
    where ``take_queued`` needs a second one to find the queue empty: for a keep-last-1 subscription, its
    newest message."""
    inbox = _INBOXES.get(subscription)
    if inbox is not None and inbox.queue:
        return inbox.queue.popleft()
    try:
        return internal.take_message(subscription)
    except InvalidHandle:  # destroyed meanwhile
        return None


def run_sampled(subscriptions: Iterable[Subscription]) -> int:
    """Run the callbacks of everything queued on ``subscriptions``, oldest first: by DDS source timestamp
    for what rmw still held (DirectExecutor), by arrival in the inbox for what an executor took (in send
    order per subscription; the executor's take order across them). Returns how many ran."""
    batch = []
    for sub in subscriptions:
        key = -1  # never decreasing per subscription: an inbox's arrival times are later than the source
        for msg, info in take_queued(sub):  # timestamps of what rmw still held behind them
            key = max(key, info["source_timestamp"])
            batch.append((key, sub, msg, info))
    batch.sort(key=lambda item: item[0])  # stable: ties keep the take order
    for _, sub, msg, info in batch:
        guard(sub).run(msg, info)
    return len(batch)


def run_newest(subscriptions: Iterable[Subscription]) -> int:
    """Like ``run_sampled``, but only the newest queued message of each subscription runs: for commands
    where the last one wins (placing a body, a kick), so that a flood costs one callback per call.
    Returns how many messages were dropped."""
    batch, dropped = [], 0
    for sub in subscriptions:
        taken = take_queued(sub)
        if taken:
            dropped += len(taken) - 1
            msg, info = taken[-1]
            batch.append((info["source_timestamp"], sub, msg, info))
    batch.sort(key=lambda item: item[0])
    for _, sub, msg, info in batch:
        guard(sub).run(msg, info)
    return dropped
