"""The private rclpy names the stack uses (erforce_interfaces.runtime.rclpy_internals) are used nowhere else in src/,
were checked against the installed rclpy, and behave as DirectExecutor and the node helpers assume. An rclpy
update fails here, by name.
"""

import importlib.metadata
import re
import time
from pathlib import Path

import pytest
from rcl_interfaces.srv import SetParameters
from rclpy.exceptions import InvalidHandle
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.task import Future
from std_msgs.msg import Int32

from erforce_interfaces.runtime import rclpy_internals as internal
from erforce_interfaces.runtime.executor import DirectExecutor, make_executor
from erforce_interfaces.tools.testing import isolated_node

RELIABLE = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)


def _until(condition, timeout_s=10.0):
    deadline = time.monotonic() + timeout_s
    while not condition():
        assert time.monotonic() < deadline, "condition not reached before the deadline"
        time.sleep(0.005)


SRC = Path(__file__).resolve().parents[2] / "src"
# what reaching into rclpy looks like: its C extension, its logger module, the private attributes listed in
# rclpy_internals.PRIVATE_NAMES, the C handles' methods
_PRIVATE = re.compile(r"rclpy\.impl|_rclpy|rcutils_logger|\._(guard|sigint_gc|is_shutdown|callback_type|"
                      r"set_executor|parameter_overrides)\b|\.handle\.(pointer|take_|call_timer|is_timer_ready|"
                      r"service_take_request)")


def test_the_installed_rclpy_is_the_one_the_private_names_were_checked_against():
    try:
        installed = importlib.metadata.version("ros-rclpy")
    except importlib.metadata.PackageNotFoundError:
        installed = "not found (no PyPI distribution ros-rclpy)"
    assert installed == internal.RCLPY_VERSION, (
        f"rclpy {installed} is installed; erforce_interfaces.runtime.rclpy_internals was checked against rclpy "
        f"{internal.RCLPY_VERSION}. Check these private names in the new rclpy (the tests of this file), then set "
        f"RCLPY_VERSION: " + "; ".join(internal.PRIVATE_NAMES))


def test_no_module_but_rclpy_internals_reaches_into_rclpy():
    fence = SRC / "erforce_interfaces" / "erforce_interfaces" / "runtime" / "rclpy_internals.py"
    found = [f"{path.relative_to(SRC)}:{n}: {line.strip()}"
             for path in sorted(SRC.rglob("*.py")) if path != fence
             for n, line in enumerate(path.read_text().splitlines(), 1)
             if _PRIVATE.search(line.split("#")[0])]
    assert not found, "private rclpy names outside rclpy_internals:\n" + "\n".join(found)


def test_the_fence_pattern_sees_what_it_looks_for():
    assert all(_PRIVATE.search(text) for text in (
        "from rclpy.impl.implementation_singleton import rclpy_implementation",
        "executor._guard, executor._sigint_gc", "node._parameter_overrides",
        "subscription.handle.take_message(t, raw)", "future._set_executor(self)"))
    assert not _PRIVATE.search("self._guard_clock = guard_clock(node)")


def test_the_c_extension_names():
    assert isinstance(internal.WaitSet, type)
    assert issubclass(internal.RCLError, Exception)


def test_executor_base_class_state():
    with isolated_node("internals_executor") as node:
        executor = DirectExecutor(context=node.context)
        guard, sigint = internal.executor_guard_conditions(executor)
        assert isinstance(internal.handle_pointer(guard), int) and isinstance(internal.handle_pointer(sigint), int)
        assert internal.executor_context(executor) is node.context
        assert internal.executor_is_shutdown(executor) is False
        future = Future()
        internal.set_future_executor(future, executor)
        executor.shutdown()
        assert internal.executor_is_shutdown(executor) is True


def test_messages_are_taken_from_a_subscription_and_its_callback_run_with_or_without_info():
    with isolated_node("internals_take") as node:
        plain, with_info = [], []
        sub = node.create_subscription(Int32, "/internals/a", plain.append, RELIABLE)
        sub_info = node.create_subscription(Int32, "/internals/a", lambda m, i: with_info.append((m, i)), RELIABLE)
        pub = node.create_publisher(Int32, "/internals/a", RELIABLE)
        _until(lambda: pub.get_subscription_count() == 2)
        assert internal.take_message(sub) is None  # nothing queued yet
        pub.publish(Int32(data=7))
        taken = []
        _until(lambda: taken.append(internal.take_message(sub)) or taken[-1] is not None)
        msg, info = taken[-1]
        assert msg.data == 7 and "source_timestamp" in info
        internal.run_subscription_callback(sub, msg, info)
        assert [m.data for m in plain] == [7]
        internal.run_subscription_callback(sub_info, msg, info)
        assert with_info[0][0].data == 7 and with_info[0][1] is info
        assert isinstance(internal.handle_pointer(sub), int)
        node.destroy_subscription(sub)
        with pytest.raises(InvalidHandle):
            internal.take_message(sub)


def test_timer_call_and_service_and_client_takes():
    with isolated_node("internals_services") as node:
        timer = node.create_timer(0.001, lambda: None)
        _until(lambda: internal.call_timer(timer))
        service = node.create_service(SetParameters, "/internals/set", lambda req, resp: resp)
        client = node.create_client(SetParameters, "/internals/set")
        _request, header = internal.take_request(service)
        assert header is None  # nothing waiting
        header, _response = internal.take_response(client)
        assert header is None


def test_make_executor_names_the_three_executors():
    from rclpy.executors import SingleThreadedExecutor

    with isolated_node("internals_kinds") as node:
        assert type(make_executor("direct", context=node.context)) is DirectExecutor
        assert type(make_executor("single", context=node.context)) is SingleThreadedExecutor
        events = make_executor(context=node.context)  # the default (docs/decisions/0001)
        assert type(events.executor).__name__ == "EventsExecutor"
        events.add_node(node)
        assert node in events.get_nodes()
        with pytest.raises(ValueError, match="ERFORCE_EXECUTOR"):
            make_executor("multi", context=node.context)


def test_parameter_overrides_are_what_declare_parameter_takes():
    from rclpy.parameter import Parameter

    with isolated_node("internals_overrides", parameter_overrides=[Parameter("x", value=3)]) as node:
        overrides = internal.parameter_overrides(node)
        assert overrides["x"].value == 3
        overrides["x"] = Parameter("x", value=4.5)
        assert node.declare_parameter("x", 1.0).value == 4.5


_LIGHT_START = """
import sys
from erforce_interfaces.runtime.rclpy_internals import light_node_start
light_node_start()
light_node_start()  # idempotent
from rclpy.impl.rcutils_logger import CallerId
from std_msgs.msg import Int32
from erforce_interfaces.tools.testing import isolated_node

def caller():
    return CallerId()

with isolated_node("light_start") as node:
    node.create_publisher(Int32, "light_start", 10).publish(Int32(data=1))  # its type support is loaded
    node.get_logger().info("logged", throttle_duration_sec=1.0)  # the throttle filter keys on the caller
    here = caller()
    print(here.function_name, here.file_path == __file__, here.line_number)
    generator = ("lark", "rosidl_parser.parser", "rosidl_generator_py.generate_py_impl")
    print(sorted(m for m in generator if m in sys.modules))
    import rosidl_generator_py
    print(callable(rosidl_generator_py.generate_py))
"""


def test_light_node_start_loads_type_support_without_the_generator_and_logs_the_caller(tmp_path):
    """light_node_start in a fresh interpreter (it changes process-wide state): a publisher still works,
    the IDL generator is not imported until asked for, and the logger's caller is the calling frame."""
    import subprocess
    import sys

    script = tmp_path / "light_start.py"
    script.write_text(_LIGHT_START)
    out = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    line = next(n for n, text in enumerate(_LIGHT_START.splitlines(), 1) if "return CallerId()" in text)
    assert out.stdout.splitlines() == ["caller True " + str(line), "[]", "True"]
