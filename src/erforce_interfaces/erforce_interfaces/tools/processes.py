"""Child processes of a developer tool: start one in a process group of this session, stop a group of them
(SIGINT, SIGTERM, SIGKILL), claim a DDS domain id nobody else holds, find a free UDP port.

Shared by the demo, its reports, the test harness (tools.testing) and the bench; not by nodes.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import signal
import socket
import subprocess
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

DOMAIN_ID_RANGE = range(100, 230)  # fastrtps port formula allows up to 232


class DomainLease:
    """An exclusively held DDS domain id (a flock, so a crashed holder frees it)."""

    def __init__(self, lock_dir: Path | None = None) -> None:
        lock_dir = lock_dir or Path(tempfile.gettempdir()) / "erforce-ros-domains"
        lock_dir.mkdir(parents=True, exist_ok=True)
        start = (os.getpid() * 7) % len(DOMAIN_ID_RANGE)  # spread concurrent claimants
        for k in range(len(DOMAIN_ID_RANGE)):
            domain_id = DOMAIN_ID_RANGE[(start + k) % len(DOMAIN_ID_RANGE)]
            fd = os.open(lock_dir / f"{domain_id}.lock", os.O_CREAT | os.O_RDWR, 0o666)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                os.close(fd)
                continue
            self.domain_id = domain_id
            self._fd: int | None = fd
            return
        raise RuntimeError(f"no free ROS domain id in {DOMAIN_ID_RANGE}")

    def release(self) -> None:
        if self._fd is not None:
            fcntl.flock(self._fd, fcntl.LOCK_UN)
            os.close(self._fd)
            self._fd = None


def stop_process(popen: subprocess.Popen, sigint_timeout_s: float = 5.0, sigterm_timeout_s: float = 3.0) -> None:
    """SIGINT, then SIGTERM, then SIGKILL (the process group), waiting after each."""
    stop_processes([popen], sigint_timeout_s, sigterm_timeout_s)


def stop_processes(popens: Sequence[subprocess.Popen], sigint_timeout_s: float = 5.0,
                   sigterm_timeout_s: float = 3.0) -> None:
    """``stop_process`` for several processes at once: each signal goes to every one still running before
    any is waited for, so the graph stops in the time of its slowest process, not in the sum of them all."""
    for sig, wait_s in ((signal.SIGINT, sigint_timeout_s), (signal.SIGTERM, sigterm_timeout_s)):
        running = [popen for popen in popens if popen.poll() is None]
        if not running:
            return
        for popen in running:
            with contextlib.suppress(ProcessLookupError):
                os.kill(popen.pid, sig)
        deadline = time.monotonic() + wait_s
        for popen in running:
            with contextlib.suppress(subprocess.TimeoutExpired):
                popen.wait(timeout=max(0.0, deadline - time.monotonic()))
    for popen in popens:
        if popen.poll() is not None:
            continue
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.killpg(popen.pid, signal.SIGKILL)
        with contextlib.suppress(ProcessLookupError):
            popen.kill()
        popen.wait(timeout=5.0)


def idle_priority(thread_id: int) -> None:
    """Run a thread (0: the caller) under SCHED_IDLE, where Linux has it; the demo runs anyway."""
    try:
        os.sched_setscheduler(thread_id, os.SCHED_IDLE, os.sched_param(0))
    except (AttributeError, OSError):
        pass


def spawn_in_session(cmd: list[str], log_path: Path, idle: bool = False,
                     env: dict[str, str] | None = None) -> subprocess.Popen:
    """Start a graph process in a process group of its own (stop_process signals the group) but in
    this session. Scheduling priorities rank threads only inside one autogroup, and Linux makes one
    per session (CONFIG_SCHED_AUTOGROUP, on in most distributions): in a session of its own the
    recorder's SCHED_IDLE meant nothing, and its group took an equal share of the CPUs beside the
    graph's, delaying the ball predictor by up to 13 ms in a scheduler trace.
    """
    with open(log_path, "wb") as log:  # the child keeps its own copy
        return subprocess.Popen(
            cmd, stdout=log, stderr=subprocess.STDOUT, process_group=0, env=env,
            preexec_fn=(lambda: idle_priority(0)) if idle else None,
        )


def free_udp_port() -> int:
    """A UDP port free on this machine now, below the kernel's ephemeral range: a port the kernel handed out
    (bind to port 0) may go to the next socket that binds port 0 (a simulation bridge's answer socket, a DDS
    reader) before the process meant to listen on it starts."""
    try:
        low = int(Path("/proc/sys/net/ipv4/ip_local_port_range").read_text().split()[0])
    except (OSError, ValueError, IndexError):
        low = 32768
    rng = np.random.default_rng()
    for port in rng.permutation(np.arange(20000, max(low, 20001))).tolist():
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
            try:
                probe.bind(("0.0.0.0", port))
            except OSError:
                continue
            return port
    raise RuntimeError("no free UDP port below the ephemeral range")
