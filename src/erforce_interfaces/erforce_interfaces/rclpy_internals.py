"""Every use of rclpy's internals in this stack, in one place (rclpy 7.1, ROS 2 Jazzy).

DirectExecutor (executor.py) waits and dispatches by itself, which rclpy has no public API for: it
builds its own rcl wait set, reads the executor base class's guard conditions and shutdown flag,
takes messages, requests, responses and timer calls from the entities' C handles, and hands a
client's future its executor. The node helpers catch the C extension's RCLError and read the
parameter overrides a node was started with (NodeParams takes an integer for a double). Only this module
names those internals; test/interfaces/test_rclpy_internals.py checks each one against the installed
rclpy, so an rclpy update that moves one fails there, by name, instead of inside a running node.
"""

from __future__ import annotations

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
