"""A warm standby: a node process that has done everything of its start that needs no DDS, and waits.

``erforce-launch`` keeps one standby per respawning node of ours (tools/launcher/runner.py, Runner): the same
command line, with ``ERFORCE_STANDBY_FD`` naming a socket. The process imports its node module, runs
``node_support.run_node`` up to ``rclpy.init`` (and the node's ``warm_up`` hook, if it has one), says
``ready`` on the socket and blocks. When the active process dies, the launcher writes ``go``: the
standby goes on exactly as a fresh start from ``rclpy.init`` on, without the ~0.6-1 s of start CPU that
a respawn would otherwise need first (all of which a busy machine may hand out at a third of a core).

The socket's end of file (the launcher gone or shutting down), SIGINT and SIGTERM end a standby quietly:
``wait_for_go`` returns False and the process exits with 0. No rclpy here: the launcher's tests run
tiny children that use it.
"""

from __future__ import annotations

import contextlib
import gc
import os
import signal
import sys
from collections.abc import Callable

STANDBY_FD_ENV = "ERFORCE_STANDBY_FD"
# What erforce-realtime leaves a standby to take on "go": the priority, with ",idle" for SCHED_IDLE where refused.
REALTIME_PRIORITY_ENV = "ERFORCE_REALTIME_PRIORITY"
READY = b"ready\n"
GO = b"go\n"


class _End(Exception):
    pass


def is_standby() -> bool:
    return STANDBY_FD_ENV in os.environ


def wait_for_go(warm_up: Callable[[], None] | None = None) -> bool:
    """In a standby: run ``warm_up``, say ready, wait; True on ``go``, False on the end (EOF, SIGINT,
    SIGTERM). Not a standby (no ``ERFORCE_STANDBY_FD``): True at once, nothing run.

    The variable is removed from the environment, so nothing the node starts takes itself for a standby."""
    value = os.environ.pop(STANDBY_FD_ENV, None)
    if value is None:
        return True
    fd = int(value)
    waiting = [True]

    def end(_signum, _frame) -> None:
        if waiting[0]:  # not once "go" is in: the node's own handlers take over from here
            raise _End

    previous = {s: signal.signal(s, end) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        if warm_up is not None:
            warm_up()
        # What the imports and the warm-up left lives as long as the process: out of the cyclic GC's
        # generations now, so the collection run_node does once the node is built scans only what is new.
        gc.collect()
        gc.freeze()
        with contextlib.suppress(OSError):  # the launcher may have sent "go" and closed its end already
            os.write(fd, READY)
        received = b""
        while not received.endswith(b"\n"):
            chunk = os.read(fd, 64)
            if not chunk:
                return False
            received += chunk
        waiting[0] = False
        if received == GO:
            _take_realtime_priority()
        return received == GO
    except _End:
        return False
    finally:
        waiting[0] = False
        for s, handler in previous.items():
            signal.signal(s, handler)
        os.close(fd)


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
