"""Every use of rclpy's internals in this stack, in one place (rclpy 7.1, ROS 2 Jazzy).

DirectExecutor (executor.py) waits and dispatches by itself, which rclpy has no public API for: it
builds its own rcl wait set, reads the executor base class's guard conditions and shutdown flag,
takes messages, requests, responses and timer calls from the entities' C handles, and hands a
client's future its executor. The node helpers catch the C extension's RCLError and read the
parameter overrides a node was started with (NodeParams takes an integer for a double). Only this module
names those internals (and light_node_start, which trims what rclpy does at a node's start);
test/interfaces/test_rclpy_internals.py checks each one against the installed
rclpy, so an rclpy update that moves one fails there, by name, instead of inside a running node.
"""

from __future__ import annotations

import importlib.util
import inspect
import sys
import types

from rclpy.impl.implementation_singleton import rclpy_implementation as _impl
from rclpy.subscription import Subscription

__all__ = [
    "RCLError",
    "WaitSet",
    "call_timer",
    "executor_context",
    "executor_guard_conditions",
    "executor_is_shutdown",
    "handle_pointer",
    "light_node_start",
    "parameter_overrides",
    "run_subscription_callback",
    "set_future_executor",
    "take_message",
    "take_request",
    "take_response",
]

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
    """Two costs of rclpy at a node's start that buy a running node nothing (idempotent):

    - rclpy's logger finds each log call's file with ``inspect.getframeinfo``, which also reads the
      source lines around it; the first call maps every loaded module to its file (``inspect.getmodule``:
      a realpath of each of ~800 modules after numba), 0.15-0.5 s of CPU in the node's first log line.
      The logger gets the caller's ``co_filename`` instead, which is what that call returns for a
      module loaded from source.
    - a message's first publisher or subscription imports its type support through the package
      ``rosidl_generator_py``, whose ``__init__`` also imports the IDL code generator (rosidl_parser,
      lark): ~0.15 s of CPU. ``rosidl_generator_py`` is registered with only ``import_type_support``;
      ``generate_py`` is imported the first time someone asks for it.
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
