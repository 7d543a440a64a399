"""``erforce-realtime [--else-idle] PRIORITY COMMAND [ARG ...]``: run a command under SCHED_FIFO at PRIORITY (1-99),
where allowed.

A launch prefix for the node on a latency path (the ball predictor: vision in, catch times out). On a 2-core
machine that runs a whole team, a normal-priority predictor waits behind the other processes' time slices
whenever it wakes; under SCHED_FIFO it runs the moment its frame arrives, and every thread it starts inherits
the policy. Raising a priority needs CAP_SYS_NICE (root, or ``ulimit -r``): without it the command runs at its
own priority (with ``--else-idle``: under SCHED_IDLE, for a process that must not take the CPU from a
latency path it could not outrank, the simulated world) and one line on stderr says so, so a launch file can
name this prefix by default and still start for every user. Linux's real-time throttling
(``/proc/sys/kernel/sched_rt_runtime_us``, 95 % by default) keeps a runaway from taking a whole machine.

erforce-launch's warm standby (erforce_interfaces.runtime.standby) does its imports at the normal priority and takes the
priority of this prefix on "go", when it becomes the node (standby.node_entry reads the prefix off the command).

    launch-prefix: $(find-pkg-prefix erforce_interfaces)/lib/erforce_interfaces/erforce-realtime 10
"""

from __future__ import annotations

import os
import sys

from erforce_interfaces.runtime.standby import set_fifo_priority


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else list(argv)
    usage = ("usage: erforce-realtime [--else-idle] PRIORITY COMMAND [ARG ...]  (PRIORITY: SCHED_FIFO priority, "
             "1-99; --else-idle: SCHED_IDLE where that is not allowed)")
    else_idle = bool(args) and args[0] == "--else-idle"
    args = args[else_idle:]
    if len(args) < 2 or not args[0].isdigit() or not 1 <= int(args[0]) <= 99:
        print(usage, file=sys.stderr)
        return 2
    priority, command = int(args[0]), args[1:]
    if (refused := set_fifo_priority(priority, command[0], else_idle)) is not None:
        print(refused, file=sys.stderr, flush=True)
    try:
        os.execvp(command[0], command)
    except OSError as exc:
        print(f"erforce-realtime: cannot run {command[0]}: {exc.strerror}", file=sys.stderr)
        return 127
    return 0  # not reached: exec replaced this process


if __name__ == "__main__":
    raise SystemExit(main())
