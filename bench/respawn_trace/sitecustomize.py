"""Start-up trace of a node process, for bench_respawn.py --breakdown only (it puts this folder on
PYTHONPATH of the launched graph; nothing else imports it).

Prints one stderr line per milestone, ``respawn-trace <event> <wall s> <cpu s> <pid>``: ``site`` (the
interpreter is up), ``main`` (the node module and everything it imports are loaded: run_node is
called), ``init`` (rclpy.init done; a warm standby's after "go"), ``built`` (the node object is
constructed) and ``publish`` (its first publish on any topic).
"""

import importlib.abc
import os
import sys
import time


def _trace(event: str) -> None:
    sys.stderr.write(f"respawn-trace {event} {time.time():.4f} {time.process_time():.4f} {os.getpid()}\n")
    sys.stderr.flush()


def _patch_node_support(module) -> None:
    run_node = module.run_node

    def traced_run_node(node_factory, args=None, executor_kind=None):
        _trace("main")
        import rclpy
        from rclpy.publisher import Publisher

        init = rclpy.init

        def traced_init(*a, **k):
            result = init(*a, **k)
            _trace("init")
            return result

        rclpy.init = traced_init
        publish = Publisher.publish

        def traced_publish(self, msg):
            Publisher.publish = publish
            _trace("publish")
            return publish(self, msg)

        def factory():
            node = node_factory()
            _trace("built")
            Publisher.publish = traced_publish
            return node

        factory.warm_up = getattr(node_factory, "warm_up", None)  # a warm standby's (run_node)
        return run_node(factory, args, executor_kind)

    module.run_node = traced_run_node


class _AfterImport(importlib.abc.MetaPathFinder):
    """Patches erforce_interfaces.runtime.node_support right after it is loaded, before a node module binds run_node."""

    def find_spec(self, name, path=None, target=None):
        if name != "erforce_interfaces.runtime.node_support":
            return None
        sys.meta_path.remove(self)
        try:
            spec = importlib.util.find_spec(name)
        finally:
            sys.meta_path.insert(0, self)
        exec_module = spec.loader.exec_module

        def traced_exec(module):
            exec_module(module)
            _patch_node_support(module)

        spec.loader.exec_module = traced_exec
        return spec


import importlib.util  # noqa: E402

sys.meta_path.insert(0, _AfterImport())
_trace("site")
