"""The warm standby: one spare process, every node's start done that needs no DDS, that becomes whichever dies.

``erforce-launch`` keeps one spare for all respawning nodes of ours (tools/launcher/, Runner), started as
``python -m erforce_interfaces.runtime.standby SCRIPT ...`` with ``ERFORCE_STANDBY_FD`` naming a socket: it runs the top
of each node's console script (the imports) and its ``main`` as far as ``node_support.run_node`` goes before
``rclpy.init`` (and the node's ``warm_up`` hook, if it has one), says ``ready`` on the socket and blocks. When a
node dies, the launcher writes ``go`` and that node's command line (JSON): the spare takes its arguments and
launch-prefix priority and runs its ``main`` from ``rclpy.init`` on, exactly as a fresh start would, without
the ~0.4-1.4 s of start CPU that a respawn would otherwise need first (all of which a busy machine may hand out
at a third of a core). One spare instead of one per node: the imports are mostly the same modules (numpy,
numba, rclpy), so the union costs little more than one of them.

A node run on its own (not a spare) calls ``wait_for_go`` too: it returns True at once. The socket's end of file
(the launcher gone or shutting down), SIGINT and SIGTERM end a spare quietly with exit code 0. No rclpy here:
the launcher's tests run tiny children that use it.
"""

from __future__ import annotations

import contextlib
import gc
import json
import os
import runpy
import signal
import sys
from collections.abc import Callable

STANDBY_FD_ENV = "ERFORCE_STANDBY_FD"
# What erforce-realtime leaves a standby to take on "go": the priority, with ",idle" for SCHED_IDLE where refused.
REALTIME_PRIORITY_ENV = "ERFORCE_REALTIME_PRIORITY"
READY = b"ready\n"
GO = b"go"  # then a space and the node's command line as JSON: {"argv": [...], "priority": [priority, else_idle]}
REALTIME_PREFIX = "erforce-realtime"  # tools/realtime.py's console script: a launch prefix the spare can take on
_warming = False  # in a spare, while it runs each node's main up to rclpy.init


class _End(Exception):
    pass


def is_standby() -> bool:
    """A spare still doing its imports and warm-ups (a node's module may skip costly work then)."""
    return _warming or STANDBY_FD_ENV in os.environ


def wait_for_go(warm_up: Callable[[], None] | None = None) -> bool:
    """In a spare warming up: run ``warm_up`` and return False (run_node returns before ``rclpy.init``). A node
    started on its own, or a spare that became it: True at once, nothing run."""
    if _warming and warm_up is not None:
        warm_up()
    return not _warming


def _wait_for_line(fd: int) -> bytes | None:
    """Say ready on ``fd`` and wait for the launcher's line; None on the end (EOF, SIGINT, SIGTERM)."""
    waiting = [True]

    def end(_signum, _frame) -> None:
        if waiting[0]:  # not once the line is in: the node's own handlers take over from here
            raise _End

    previous = {s: signal.signal(s, end) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        with contextlib.suppress(OSError):  # the launcher may have closed its end already
            os.write(fd, READY)
        received = b""
        while not received.endswith(b"\n"):
            chunk = os.read(fd, 65536)
            if not chunk:
                return None
            received += chunk
        return received
    except _End:
        return None
    finally:
        waiting[0] = False
        for s, handler in previous.items():
            signal.signal(s, handler)


def node_entry(cmd: list[str]) -> tuple[int, int | None, bool] | None:
    """Where a spare can become the process of ``cmd``: (index of the console script in ``cmd``, the SCHED_FIFO
    priority of an ``erforce-realtime`` prefix or None, its ``--else-idle``); None where it cannot (another
    prefix, or a script that is not a Python script of this interpreter): that node respawns by a fresh start."""
    k, priority, else_idle = 0, None, False
    if cmd and os.path.basename(cmd[0]) == REALTIME_PREFIX:
        else_idle = len(cmd) > 1 and cmd[1] == "--else-idle"
        k = 1 + else_idle
        if len(cmd) <= k + 1 or not cmd[k].isdigit():
            return None
        priority, k = int(cmd[k]), k + 1
    try:
        with open(cmd[k], "rb") as script:
            first = script.readline().strip()
    except (OSError, IndexError):
        return None
    return (k, priority, else_idle) if first == b"#!" + os.fsencode(sys.executable) else None


def spare_main(scripts: list[str]) -> int:
    """A spare for the nodes of ``scripts`` (console scripts): imports and warm-ups of each, then wait; on "go" run
    the named node's ``main`` with its arguments and return its exit code (0 on the end)."""
    global _warming
    fd = int(os.environ.pop(STANDBY_FD_ENV))
    mains: dict[str, Callable[[], int]] = {}
    policy = os.sched_getscheduler(0), os.sched_getparam(0)
    _warming = True
    try:
        for script in scripts:
            sys.argv = [script]
            found = runpy.run_path(script, run_name="erforce_standby")  # the script's imports, not its main
            mains[script] = found["main"]
            mains[script]()  # run_node up to rclpy.init: light_node_start, warm_up
    finally:
        _warming = False
    # A main may set its own scheduling before run_node (field_view: SCHED_IDLE); the node it becomes sets it again
    for tid in os.listdir("/proc/self/task"):
        with contextlib.suppress(OSError):
            os.sched_setscheduler(int(tid), *policy)
    # What the imports and warm-ups left lives as long as the process: out of the cyclic GC's generations now,
    # so the collection run_node does once the node is built scans only what is new.
    gc.collect()
    gc.freeze()
    line = _wait_for_line(fd)
    os.close(fd)
    if line is None or not line.startswith(GO + b" "):
        return 0
    order = json.loads(line[len(GO) + 1:])
    sys.argv = list(order["argv"])
    if order.get("priority") is not None:
        leave_realtime_priority(*order["priority"])
        _take_realtime_priority()
    return mains[sys.argv[0]]()


def leave_realtime_priority(priority: int, else_idle: bool) -> None:
    """erforce-realtime's request, for the standby to take on "go" (``_take_realtime_priority``)."""
    os.environ[REALTIME_PRIORITY_ENV] = f"{priority},idle" if else_idle else str(priority)


def _take_realtime_priority() -> None:
    """The priority erforce-realtime left for the node (tools/realtime.py), now that the standby becomes it."""
    value = os.environ.pop(REALTIME_PRIORITY_ENV, None)
    if value is not None:
        priority, _, fallback = value.partition(",")
        refused = set_fifo_priority(int(priority), os.path.basename(sys.argv[0]), else_idle=fallback == "idle")
        if refused is not None:
            print(refused, file=sys.stderr, flush=True)


def set_fifo_priority(priority: int, command: str, else_idle: bool = False) -> str | None:
    """This thread (and the threads it starts from now on) under SCHED_FIFO at ``priority``; the line to print
    when that is not allowed (None: done). Refused, ``else_idle`` puts it under SCHED_IDLE instead (allowed to
    everyone): the CPU goes to every other process first. For erforce-realtime (tools/realtime.py) and a standby
    on "go"."""
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
    except OSError as exc:  # EPERM without CAP_SYS_NICE; EINVAL where the kernel has no real-time class
        runs_at = "its normal priority"
        if else_idle:
            try:
                os.sched_setscheduler(0, os.SCHED_IDLE, os.sched_param(0))
                runs_at = "SCHED_IDLE"
            except OSError:
                pass
        return (f"erforce-realtime: SCHED_FIFO priority {priority} not allowed ({exc.strerror}); {command} runs at "
                f"{runs_at}")
    return None


if __name__ == "__main__":
    # through the package's module (not this __main__ copy): node_support reads the same ``_warming``
    from erforce_interfaces.runtime.standby import spare_main as _spare_main

    sys.exit(_spare_main(sys.argv[1:]))
