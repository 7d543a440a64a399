"""Every use of rclpy's private API in this stack, in one module, checked against one rclpy version.

Everything else uses public rclpy only; every node spins on rclpy's EventsExecutor (executor.make_executor).
What needs more lives here:

- DirectExecutor: an executor that waits and dispatches by itself (its own rcl wait set, the executor
  base class's guard conditions and shutdown flag, takes from the entities' C handles, a client future's
  executor). After one wait it runs every ready timer, subscription (everything queued on it, up to 64
  messages), guard condition, service, client response and QoS event once, in that order, then waits
  again; it never waits on a sampled subscription (executor.sample_only). Callbacks run in this thread
  (a returned coroutine is driven to its end; one that suspends on a future is an error); callback
  groups are ignored. It serves the in-process observers that spin by hand and read a message's info
  (source timestamp), which EventsExecutor cannot pass in rclpy 7.1: the test probe
  (tools.testing) and the demo's director (erforce_sim.demo.demo); and ERFORCE_EXECUTOR=direct
  for the executor bench (bench/bench_executor.py).
- take_message: the raw take behind executor.take_queued / take_one (rclpy has no public take).
- RCLError (the C extension's error, e.g. "context is invalid" during Ctrl-C's shutdown) and a node's
  parameter overrides (NodeParams takes an integer for a double).
- light_node_start: trims two costs of rclpy at a node's start (its docstring).

RCLPY_VERSION is the rclpy these were checked against; test/interfaces/test_rclpy_internals.py fails, naming
PRIVATE_NAMES, when another rclpy is installed, and checks each name's behaviour, so an rclpy update that moves
one fails there instead of inside a running node.
"""

from __future__ import annotations

import importlib.util
import inspect
import sys
import types
import weakref

from rclpy.exceptions import InvalidHandle
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor, TimeoutObject
from rclpy.impl.implementation_singleton import rclpy_implementation as _impl
from rclpy.subscription import Subscription
from rclpy.utilities import timeout_sec_to_nsec

__all__ = [
    "PRIVATE_NAMES",
    "RCLPY_VERSION",
    "DirectExecutor",
    "RCLError",
    "WaitSet",
    "call_timer",
    "executor_context",
    "executor_guard_conditions",
    "executor_is_shutdown",
    "finish_coroutine",
    "handle_pointer",
    "light_node_start",
    "parameter_overrides",
    "run_subscription_callback",
    "set_future_executor",
    "set_sampled",
    "take_message",
    "take_request",
    "take_response",
]

RCLPY_VERSION = "7.1.6"  # the rclpy (PyPI distribution ros-rclpy, ROS 2 Jazzy) these names were checked against
PRIVATE_NAMES = (  # what this module reaches into, for the version check's message
    "rclpy.impl.implementation_singleton.rclpy_implementation: WaitSet, RCLError",
    "entity.handle (C handle): pointer, take_message, is_timer_ready, call_timer, service_take_request, "
    "take_response, __enter__/__exit__; Context.handle",
    "Executor._guard, Executor._sigint_gc, Executor._is_shutdown, Executor._context",
    "Subscription._callback_type, Future._set_executor, Node._parameter_overrides",
    "rclpy.impl.rcutils_logger.inspect, sys.modules['rosidl_generator_py'] (light_node_start)",
)

WaitSet = _impl.WaitSet  # rcl wait set: (subs, guards, timers, clients, services, events, context handle)
RCLError = _impl.RCLError  # e.g. "context is invalid" from a publish during Ctrl-C's shutdown


def executor_guard_conditions(executor) -> tuple:
    """The wake guard condition (``Executor.wake``) and the SIGINT guard condition of an rclpy Executor."""
    return executor._guard, executor._sigint_gc


def executor_is_shutdown(executor) -> bool:
    return executor._is_shutdown


def executor_context(executor):
    return executor._context


def handle_pointer(entity) -> int:
    """What a wait set reports a ready entity by (raises InvalidHandle once the entity is destroyed)."""
    return entity.handle.pointer


def take_message(subscription: Subscription):
    """(message, info) of the oldest queued message, or None; raw bytes for a raw subscription."""
    with subscription.handle:
        return subscription.handle.take_message(subscription.msg_type, subscription.raw)


def run_subscription_callback(subscription: Subscription, msg, info):
    """The subscription's callback, with the message info when it takes one, as rclpy's executors call it."""
    if subscription._callback_type is Subscription.CallbackType.MessageOnly:
        return subscription.callback(msg)
    return subscription.callback(msg, info)


def call_timer(timer) -> bool:
    """Mark a ready timer as called (its next period starts); False when it was not ready after all."""
    if not timer.handle.is_timer_ready():
        return False
    timer.handle.call_timer()
    return True


def take_request(service):
    """(request, header) of a waiting service request; header None when there was none."""
    return service.handle.service_take_request(service.srv_type.Request)


def take_response(client):
    """(header, response) of a waiting client response; header None when there was none."""
    return client.handle.take_response(client.srv_type.Response)


def set_future_executor(future, executor) -> None:
    """Let a client's future schedule its done callbacks on ``executor`` (what rclpy's executors do)."""
    future._set_executor(executor)


def parameter_overrides(node) -> dict:
    """name -> Parameter: the values the command line and parameter files gave the node, which
    ``declare_parameter`` takes; the same dict, so a replaced entry is what the declaration sees."""
    return node._parameter_overrides


# ------------------------------------------------------------------ a node process's start
def _frame_filename(frame, context: int = 1):
    """What rclpy's logger reads of ``inspect.getframeinfo(frame)``: the caller's file (and line)."""
    code = frame.f_code
    return inspect.Traceback(code.co_filename, frame.f_lineno, code.co_name, None, None)


def light_node_start() -> None:
    """Two costs of rclpy at a node's start that buy a running node nothing (idempotent; run_node calls it
    before a warm standby waits, so a take-over saves them too; figures in docs/decisions/0001):

    - rclpy's logger finds each log call's file with ``inspect.getframeinfo``, which also reads the
      source lines around it; its first call maps every loaded module to its file (``inspect.getmodule``).
      The logger gets the caller's ``co_filename`` instead, which is what that call returns for a
      module loaded from source.
    - a message's first publisher or subscription imports its type support through the package
      ``rosidl_generator_py``, whose ``__init__`` also imports the IDL code generator (rosidl_parser,
      lark). ``rosidl_generator_py`` is registered with only ``import_type_support``; ``generate_py`` is
      imported the first time someone asks for it.
    """
    from rclpy.impl import rcutils_logger

    if not isinstance(rcutils_logger.inspect, types.SimpleNamespace):
        rcutils_logger.inspect = types.SimpleNamespace(getframeinfo=_frame_filename, currentframe=inspect.currentframe)
    if "rosidl_generator_py" in sys.modules:
        return
    spec = importlib.util.find_spec("rosidl_generator_py")
    if spec is None or spec.submodule_search_locations is None:
        return
    package = importlib.util.module_from_spec(spec)  # not executed: no generator import

    def __getattr__(name: str):  # the module's own attribute lookup (PEP 562)
        if name == "generate_py":
            from rosidl_generator_py.generate_py_impl import generate_py

            return generate_py
        raise AttributeError(f"module 'rosidl_generator_py' has no attribute {name!r}")

    package.__getattr__ = __getattr__
    sys.modules["rosidl_generator_py"] = package
    from rosidl_generator_py.import_type_support_impl import import_type_support

    package.import_type_support = import_type_support
    package.__all__ = ["import_type_support", "generate_py"]


# ------------------------------------------------------------------ DirectExecutor
_KINDS = ("subscription", "timer", "guard_condition", "service", "client")
_MAX_TAKES_PER_WAKE = 64  # messages taken from one ready subscription per wait
_SAMPLED: weakref.WeakSet = weakref.WeakSet()  # subscriptions DirectExecutor leaves to their nodes (sample_only)
_sampled_changes = 0  # DirectExecutor gathers its entities again when this moves


def set_sampled(subscription: Subscription, sampled: bool) -> None:
    """executor.sample_only's part here: DirectExecutor does not wait on a sampled subscription (from its next wait)."""
    global _sampled_changes
    if sampled:
        _SAMPLED.add(subscription)
    else:
        _SAMPLED.discard(subscription)
    _sampled_changes += 1


def _ready(entities, ready_pointers):
    """The entities whose handles rcl reported ready, skipping any destroyed meanwhile."""
    if not ready_pointers:
        return
    for e in entities:
        try:
            is_ready = handle_pointer(e) in ready_pointers
        except InvalidHandle:
            continue
        if is_ready:
            yield e


def finish_coroutine(result) -> None:
    """Drive a coroutine a callback returned (e.g. a QoS event's execute) to its end: for callers that call
    callbacks themselves (DirectExecutor, executor.guard's inbox)."""
    if not inspect.iscoroutine(result):
        return
    try:
        result.send(None)
    except StopIteration:
        return
    result.close()
    raise RuntimeError("DirectExecutor: a callback awaited a future; use an rclpy executor for async callbacks")


class DirectExecutor(SingleThreadedExecutor):
    """SingleThreadedExecutor whose ``spin``/``spin_once`` run ready callbacks directly (see module doc)."""

    def __init__(self, *, context=None) -> None:
        super().__init__(context=context)
        self._entities = None  # (subscriptions, timers, guards, services, clients, waitables)
        self._gathered_at = -1  # _sampled_changes when the entities were gathered
        self._handles = []
        self._wait_set = None

    def wake(self) -> None:
        self._entities = None  # something changed: gather the entities again
        super().wake()

    def spin_once_until_future_complete(self, future, timeout_sec=None) -> None:
        # spin_until_future_complete comes here; the future's done callback wakes the wait.
        self.spin_once(timeout_sec.timeout if isinstance(timeout_sec, TimeoutObject) else timeout_sec)

    def spin_once(self, timeout_sec: float | None = None) -> None:
        """Wait up to ``timeout_sec`` (None: forever) and run every callback that is ready."""
        guard, sigint = executor_guard_conditions(self)
        if executor_is_shutdown(self) or guard is None or sigint is None:
            return
        context = executor_context(self)
        if self._entities is None or self._gathered_at != _sampled_changes:
            self._gather()
        subs, timers, guards, services, clients, waitables = self._entities
        # Mark every handle in use while rcl waits on it, as rclpy's executors do: an entity
        # destroyed meanwhile (another thread, shutdown) is then freed only after the wait.
        in_use = []
        try:
            try:
                for h in (*self._handles, guard.handle, sigint.handle, context.handle):
                    h.__enter__()
                    in_use.append(h)
            except InvalidHandle:  # destroyed since the entities were gathered
                self._entities = None
                return
            ws = self._wait_set
            if ws is None:
                num_events = sum(w.get_num_entities().num_events for w in waitables)
                ws = self._wait_set = WaitSet(
                    len(subs), len(guards) + 2, len(timers), len(clients), len(services), num_events,
                    context.handle)
            ws.clear_entities()
            for e in subs:
                ws.add_subscription(e.handle)
            for e in timers:
                ws.add_timer(e.handle)
            for e in guards:
                ws.add_guard_condition(e.handle)
            ws.add_guard_condition(guard.handle)
            ws.add_guard_condition(sigint.handle)
            for e in services:
                ws.add_service(e.handle)
            for e in clients:
                ws.add_client(e.handle)
            for e in waitables:
                e.add_to_wait_set(ws)
            ws.wait(timeout_sec_to_nsec(timeout_sec))
            if executor_is_shutdown(self):
                return
            if not context.ok():
                raise ExternalShutdownException()
            ready = {kind: ws.get_ready_entities(kind) for kind in _KINDS}
            ready_waitables = [w for w in waitables if w.is_ready(ws)]  # needs this wait set
            if handle_pointer(guard) in ready["guard_condition"]:
                self._entities = None  # woken: entities may have changed
        finally:
            for h in reversed(in_use):
                h.__exit__(None, None, None)
        self._dispatch(ready, subs, timers, guards, services, clients, ready_waitables)

    def _gather(self) -> None:
        self._gathered_at = _sampled_changes
        subs, timers, guards, services, clients, waitables = [], [], [], [], [], []
        for node in self.get_nodes():
            sampled = [s for s in node.subscriptions if s in _SAMPLED]
            subs.extend(s for s in node.subscriptions if s not in _SAMPLED)
            timers.extend(node.timers)
            guards.extend(node.guards)
            services.extend(node.services)
            clients.extend(node.clients)
            # A sampled subscription's QoS-event handlers stay out too: with Fast DDS they share
            # the reader's status condition, so a queued message would end every wait.
            skip = {id(h) for s in sampled for h in s.event_handlers}
            waitables.extend(w for w in node.waitables if id(w) not in skip)
        self._entities = subs, timers, guards, services, clients, waitables
        self._handles = [e.handle for e in (*subs, *timers, *guards, *services, *clients)] + waitables
        self._wait_set = None  # sized for these entities

    def _dispatch(self, ready, subs, timers, guards, services, clients, ready_waitables) -> None:
        # A callback may destroy entities: each is checked when its turn comes.
        for t in _ready(timers, ready["timer"]):
            if call_timer(t):
                finish_coroutine(t.callback())
        for s in _ready(subs, ready["subscription"]):
            self._take_and_run(s)
        for g in _ready(guards, ready["guard_condition"]):
            if g.callback is not None:
                finish_coroutine(g.callback())
        for srv in _ready(services, ready["service"]):
            request, header = take_request(srv)
            if header is not None:
                srv.send_response(srv.callback(request, srv.srv_type.Response()), header)
        for c in _ready(clients, ready["client"]):
            self._take_response(c)
        for w in ready_waitables:
            finish_coroutine(w.execute(w.take_data()))

    @staticmethod
    def _take_and_run(sub: Subscription) -> None:
        # Everything queued (up to a bound, so that the other entities are served too): under a flood
        # a wake per message cannot keep up, and a keep-last reader then drops the oldest samples,
        # the real ones among them.
        for _ in range(_MAX_TAKES_PER_WAKE):
            try:
                taken = take_message(sub)  # raises InvalidHandle once a callback destroyed it
            except InvalidHandle:
                return
            if taken is None:
                return
            finish_coroutine(run_subscription_callback(sub, *taken))

    def _take_response(self, client) -> None:
        try:
            header, response = take_response(client)
        except InvalidHandle:
            return
        if header is None:
            return
        try:
            future = client.get_pending_request(header.request_id.sequence_number)
        except KeyError:
            return  # the request was cancelled
        set_future_executor(future, self)
        future.set_result(response)
