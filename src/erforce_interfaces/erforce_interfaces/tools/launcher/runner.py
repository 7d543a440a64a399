"""Running the resolved processes: output relayed with each process's name, respawns (by a warm standby where
there is one), and the shutdown ladder SIGINT, SIGTERM, SIGKILL."""


from __future__ import annotations

import contextlib
import ctypes
import datetime
import functools
import json
import os
import selectors
import shlex
import signal
import socket
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TextIO

from erforce_interfaces.runtime.standby import GO, READY, STANDBY_FD_ENV, node_entry
from erforce_interfaces.tools.launcher.launch_file import ProcessSpec

#: the start of the line logged when a process's command cannot be run (tools that start a graph watch for it)
FAILED_TO_START = "process failed to start"



# ========================================================================== 3. run
_PRCTL = None


def _child_setup() -> None:  # pragma: no cover - runs in the child between fork and exec
    if _PRCTL is not None:
        _PRCTL(1, signal.SIGTERM)  # PR_SET_PDEATHSIG: die with the launcher even if it is SIGKILLed


def _standby_child_setup() -> None:  # pragma: no cover - runs in the child between fork and exec
    _child_setup()
    # Python installs no KeyboardInterrupt handler for an ignored SIGINT: a shutdown during the standby's
    # imports prints no traceback; it ends at the socket's end of file once the standby waits.
    signal.signal(signal.SIGINT, signal.SIG_IGN)


# The warm standby (erforce_interfaces.runtime.standby): one spare for every respawning node of ours.
STANDBY_FIRST_S = 3.0  # after the graph's start, so that its imports do not slow the graph's own start
STANDBY_AGAIN_S = 5.0  # after an activation or a fresh respawn, so that it does not slow the healing node
STANDBY_LABEL = "standby"  # the spare's output prefix until it becomes a node


@dataclass
class _Proc:
    spec: ProcessSpec
    popen: subprocess.Popen | None = None
    streams: dict[int, tuple[Any, TextIO | None, TextIO | None, bytearray]] = field(default_factory=dict)
    starts: int = 0
    respawn_at: float | None = None
    stage: int = 0  # shutdown ladder: 0 none, 1 SIGINT sent, 2 SIGTERM sent, 3 SIGKILL sent
    deadline: float | None = None
    sock: socket.socket | None = None  # a standby's: the launcher's end of its socket
    ready: bool = False  # a standby's: it said it is ready
    started_at: float = 0.0


class Runner:
    """Starts the processes, relays their output, respawns, and tears everything down.

    A respawn of a node of ours (ProcessSpec.standby) is carried out by the warm standby where it is ready: one
    spare for all of them (``spare``), to which the launcher writes "go" and the node's command line once the
    respawn delay has passed; the spare becomes the process (its pid, output, respawn count and shutdown). The
    next spare starts ``STANDBY_AGAIN_S`` later; a spare that died on its own is logged, the next respawn is a
    fresh start, and a new spare follows that.
    """

    def __init__(self, specs: list[ProcessSpec], sigterm_timeout_s: float = 5.0, sigkill_timeout_s: float = 5.0,
                 shutdown_on_exit: bool = False, out: TextIO | None = None, err: TextIO | None = None,
                 standby: bool = True) -> None:
        self.procs = [_Proc(s) for s in specs]
        self.use_standby = standby
        self.spare: _Proc | None = None  # the warm standby, waiting for "go"
        self.spare_at: float | None = None  # when the next spare may start (None: none planned)
        self._retired: list[_Proc] = []  # standbys on their way out (end of file, signals), reaped as children
        self.sigterm_timeout_s = sigterm_timeout_s
        self.sigkill_timeout_s = sigkill_timeout_s
        self.shutdown_on_exit = shutdown_on_exit
        self.out, self.err = out or sys.stdout, err or sys.stderr
        self.failed = False
        self.shutting_down = False
        self._signals: list[int] = []
        self._sel = selectors.DefaultSelector()
        self._log_dir: Path | None = None
        global _PRCTL
        if _PRCTL is None and sys.platform.startswith("linux"):
            with contextlib.suppress(OSError, AttributeError):
                _PRCTL = ctypes.CDLL(None, use_errno=True).prctl

    def info(self, who: str, text: str, level: str = "INFO") -> None:
        self._write(self.out, f"[{level}] [{who}]: {text}\n")

    @staticmethod
    def _write(stream: TextIO, text: str) -> None:
        with contextlib.suppress(OSError, ValueError):  # a closed pager must not take the graph down
            stream.write(text)
            stream.flush()

    def run(self) -> int:
        wake_r, wake_w = os.pipe()
        os.set_blocking(wake_r, False)
        os.set_blocking(wake_w, False)
        self._sel.register(wake_r, selectors.EVENT_READ, None)
        old = {s: signal.signal(s, self._on_signal) for s in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)}
        old[signal.SIGCHLD] = signal.signal(signal.SIGCHLD, lambda *_: None)  # only to wake select()
        old_wakeup = signal.set_wakeup_fd(wake_w, warn_on_full_buffer=False)
        try:
            if any(p.spec.output != "screen" for p in self.procs):
                self.info("launch", f"All log files can be found below {self._logs()}")
            for p in self.procs:
                self._start(p)
            self.spare_at = time.monotonic() + STANDBY_FIRST_S
            while self._retired or self.spare is not None or any(p.popen is not None or p.respawn_at is not None
                                                                 for p in self.procs):
                self._step()
        finally:
            for p in [*self.procs, *self._standbys(), *self._retired]:  # after an internal error: nothing may
                if p.popen is not None:                                    # outlive us
                    self._kill(p, signal.SIGKILL)
                    p.popen.wait()
                    self._drain(p)
                if p.sock is not None:
                    p.sock.close()
            signal.set_wakeup_fd(old_wakeup)
            for s, handler in old.items():
                signal.signal(s, handler)
            self._sel.close()
            os.close(wake_r)
            os.close(wake_w)
        return 1 if self.failed else 0

    def _on_signal(self, signum: int, frame: Any) -> None:
        self._signals.append(signum)

    def _logs(self) -> Path:
        if self._log_dir is None:
            base = os.environ.get("ROS_LOG_DIR") or os.path.join(
                os.environ.get("ROS_HOME") or os.path.expanduser("~/.ros"), "log")
            stamp = datetime.datetime.now().strftime("%Y-%m-%d-%H-%M-%S-%f")
            self._log_dir = Path(base) / f"{stamp}-{socket.gethostname()}-{os.getpid()}"
            self._log_dir.mkdir(parents=True, exist_ok=True)
        return self._log_dir

    def _start(self, p: _Proc) -> None:
        s = p.spec
        p.respawn_at, p.stage, p.deadline = None, 0, None
        env = dict(s.env)
        env.setdefault("PYTHONUNBUFFERED", "1")  # line-by-line output from Python nodes, as ros2 launch
        try:
            popen = subprocess.Popen(s.cmd, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                     env=env, cwd=s.cwd, process_group=0, preexec_fn=_child_setup)
        except OSError as exc:
            self.info(s.label, f"{FAILED_TO_START}: {exc}", "ERROR")
            self.failed = True
            return
        p.popen, p.starts = popen, p.starts + 1
        self._relay(p, popen)
        self.info(s.label, f"process started with pid [{popen.pid}]")

    def _relay(self, p: _Proc, popen: subprocess.Popen) -> None:
        for pipe, name in ((popen.stdout, "stdout"), (popen.stderr, "stderr")):
            fd = pipe.fileno()
            os.set_blocking(fd, False)
            p.streams[fd] = (pipe, *self._targets(p.spec, name), bytearray())
            self._sel.register(fd, selectors.EVENT_READ, p)

    def _targets(self, s: ProcessSpec, name: str) -> tuple[TextIO | None, TextIO | None]:
        """Where ``s``'s stream ``name`` goes: the screen's stream (or None) and its log file (or None)."""
        log = open(self._logs() / f"{s.label.replace('/', '_')}-{name}.log", "a") if s.output != "screen" else None
        return (self.out if name == "stdout" else self.err) if s.output != "log" else None, log

    # ------------------------------------------------------------------ the warm standby
    def _served(self, p: _Proc) -> bool:
        """The spare can become ``p`` at its next respawn (respawn_max_retries counts activations): a node of ours
        whose command it can run (standby.node_entry) in the environment of the first such node."""
        retries = p.spec.respawn_max_retries
        return (self.use_standby and p.spec.standby and p.spec.respawn and not self.shutting_down
                and (retries < 0 or p.starts <= retries) and p in self._spare_group)

    @functools.cached_property
    def _spare_group(self) -> list[_Proc]:
        group = [p for p in self.procs if p.spec.standby and p.spec.respawn and node_entry(p.spec.cmd) is not None]
        return [p for p in group if (p.spec.env, p.spec.cwd) == (group[0].spec.env, group[0].spec.cwd)]

    def _standbys(self) -> list[_Proc]:
        return [self.spare] if self.spare is not None else []

    def _start_standby(self, now: float) -> None:
        group = self._spare_group
        first = group[0].spec
        scripts = list(dict.fromkeys(p.spec.cmd[node_entry(p.spec.cmd)[0]] for p in group))
        s = ProcessSpec(label=STANDBY_LABEL, cmd=[sys.executable, "-m", "erforce_interfaces.runtime.standby", *scripts],
                        env=first.env, cwd=first.cwd, output=first.output)
        self.spare_at = None
        ours, theirs = socket.socketpair()
        env = dict(s.env)
        env.setdefault("PYTHONUNBUFFERED", "1")
        env[STANDBY_FD_ENV] = str(theirs.fileno())
        try:
            popen = subprocess.Popen(s.cmd, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                     env=env, cwd=s.cwd, process_group=0, preexec_fn=_standby_child_setup,
                                     pass_fds=(theirs.fileno(),))
        except OSError as exc:
            self.info(s.label, f"standby failed to start: {exc}; respawns are fresh starts", "ERROR")
            ours.close()
            return
        finally:
            theirs.close()
        sb = _Proc(s, popen=popen, sock=ours, started_at=now)
        self._relay(sb, popen)
        ours.setblocking(False)
        self._sel.register(ours.fileno(), selectors.EVENT_READ, ("standby", sb))
        self.spare = sb
        self.info(s.label, f"standby started with pid [{popen.pid}]")

    def _standby_says(self, sb: _Proc) -> None:
        if sb is not self.spare or sb.sock is None:
            return
        try:
            data = sb.sock.recv(64)
        except BlockingIOError:
            return
        except OSError:
            data = b""
        if not data:  # it is gone or going: the exit is seen by poll()
            self._sel.unregister(sb.sock.fileno())
            sb.sock.close()
            sb.sock = None
        elif READY in data and not sb.ready:
            sb.ready = True
            self.info(sb.spec.label, f"standby ready [pid {sb.popen.pid}]")

    def _activate(self, p: _Proc) -> bool:
        """Turn the spare into ``p``'s process; False if there is none that can take over."""
        sb = self.spare
        if sb is None or not sb.ready or not self._served(p):
            return False
        self.spare = None
        k, priority, else_idle = node_entry(p.spec.cmd)
        order = GO + b" " + json.dumps({"argv": p.spec.cmd[k:], "priority": None if priority is None else
                                        [priority, else_idle]}).encode() + b"\n"
        sent = False
        if sb.sock is not None:
            with contextlib.suppress(OSError):
                sent = sb.sock.send(order) == len(order)
            self._sel.unregister(sb.sock.fileno())
            sb.sock.close()
            sb.sock = None
        if not sent or sb.popen.poll() is not None:
            self.info(p.spec.label, f"standby [pid {sb.popen.pid}] could not take over; starting afresh", "WARNING")
            self._retire(sb)
            return False
        p.popen, p.starts, p.respawn_at, p.stage, p.deadline = sb.popen, p.starts + 1, None, 0, None
        for fd, (pipe, _, log, buf) in sb.streams.items():  # its output is the node's from here on
            if log is not None:
                log.close()
            p.streams[fd] = (pipe, *self._targets(p.spec, "stdout" if fd == sb.popen.stdout.fileno() else "stderr"),
                             buf)
            self._sel.modify(fd, selectors.EVENT_READ, p)
        self.info(p.spec.label, f"process activated from standby with pid [{sb.popen.pid}]")
        return True

    def _retire(self, sb: _Proc) -> None:
        """Let a standby go: end of file on its socket ends it; it is reaped like any child (and at shutdown
        gets the ladder's signals)."""
        if sb.sock is not None:
            self._sel.unregister(sb.sock.fileno())
            sb.sock.close()
            sb.sock = None
        self._retired.append(sb)

    def _standby_exited(self, sb: _Proc, on_its_own: bool) -> None:
        assert sb.popen is not None
        popen, code = sb.popen, sb.popen.returncode
        self._drain(sb)
        sb.popen = None
        if sb.sock is not None:
            self._sel.unregister(sb.sock.fileno())
            sb.sock.close()
            sb.sock = None
        if on_its_own:
            self.info(sb.spec.label, f"standby died on its own [pid {popen.pid}, exit code {code}]; the next "
                      "respawn is a fresh start", "ERROR")
        elif code == 0:
            self.info(sb.spec.label, f"standby has finished cleanly [pid {popen.pid}]")
        else:
            self.info(sb.spec.label, f"standby has died [pid {popen.pid}, exit code {code}]", "ERROR")

    def _step(self) -> None:
        now = time.monotonic()
        children = [*self.procs, *self._standbys(), *self._retired]
        deadlines = [t for p in children for t in (p.respawn_at, p.deadline) if t is not None]
        if self.spare_at is not None:
            deadlines.append(self.spare_at)
        timeout = max(0.0, min([now + 0.5, *deadlines]) - now)
        for key, _ in self._sel.select(timeout):
            if key.data is None:
                with contextlib.suppress(BlockingIOError):
                    os.read(key.fd, 512)
            elif isinstance(key.data, tuple):
                self._standby_says(key.data[1])
            else:
                self._read(key.data, key.fd)
        while self._signals:
            signum = self._signals.pop(0)
            self._shutdown(f"user interrupted with ctrl-c ({signal.Signals(signum).name})"
                           if signum == signal.SIGINT else f"received {signal.Signals(signum).name}")
        if self.spare is not None and self.spare.popen.poll() is not None:
            sb, self.spare = self.spare, None
            self._standby_exited(sb, on_its_own=True)
            self.spare_at = None  # the next respawn starts afresh and plans the next spare
        for p in self.procs:
            if p.popen is not None and p.popen.poll() is not None:
                self._exited(p)
        for sb in list(self._retired):
            if sb.popen.poll() is not None:
                self._retired.remove(sb)
                self._standby_exited(sb, on_its_own=False)
        now = time.monotonic()
        for p in self.procs:
            if p.respawn_at is not None and now >= p.respawn_at and not self.shutting_down:
                if not self._activate(p):
                    self._start(p)
                if self.spare is None:
                    self.spare_at = now + STANDBY_AGAIN_S
        wanted = [p for p in self.procs if self._served(p) and (p.popen is not None or p.respawn_at is not None)]
        if self.spare is not None and not wanted:  # no respawn left to stand in for
            sb, self.spare = self.spare, None
            self._retire(sb)
        if self.spare is None and self.spare_at is not None and now >= self.spare_at and wanted:
            self._start_standby(now)
        for p in [*self.procs, *self._standbys(), *self._retired]:
            if p.popen is not None and p.deadline is not None and now >= p.deadline:
                self._escalate(p, now)

    def _read(self, p: _Proc, fd: int) -> int:
        """Relay complete lines readable now; bytes read, 0 at end of file (stream closed), -1 if none."""
        try:
            data = os.read(fd, 65536)
        except BlockingIOError:
            return -1
        if not data:
            self._end_stream(p, fd)
            return 0
        buf = p.streams[fd][3]
        buf.extend(data)
        cut = buf.rfind(b"\n") + 1
        if cut:
            self._emit(p, fd, bytes(buf[:cut - 1]))
            del buf[:cut]
        return len(data)

    def _emit(self, p: _Proc, fd: int, chunk: bytes) -> None:
        _, screen, log, _ = p.streams[fd]
        lines = [raw.decode("utf-8", "replace").rstrip("\r") for raw in chunk.split(b"\n")]
        if screen is not None:
            self._write(screen, "".join(f"[{p.spec.label}] {line}\n" for line in lines))
        if log is not None:
            log.write("".join(line + "\n" for line in lines))
            log.flush()

    def _end_stream(self, p: _Proc, fd: int) -> None:
        pipe, _, log, buf = p.streams[fd]
        if buf:
            self._emit(p, fd, bytes(buf))
        self._sel.unregister(fd)
        del p.streams[fd]
        pipe.close()
        if log is not None:
            log.close()

    def _drain(self, p: _Proc) -> None:
        """After the exit: relay what is left; a pipe a grandchild still holds is let go."""
        for fd in list(p.streams):
            while (n := self._read(p, fd)) > 0:
                pass
            if n < 0:
                self._end_stream(p, fd)

    def _exited(self, p: _Proc) -> None:
        assert p.popen is not None
        popen, code = p.popen, p.popen.returncode
        self._drain(p)
        p.popen, p.stage, p.deadline = None, 0, None
        if code == 0:
            self.info(p.spec.label, f"process has finished cleanly [pid {popen.pid}]")
        else:
            self.info(p.spec.label, f"process has died [pid {popen.pid}, exit code {code}, "
                      f"cmd '{shlex.join(p.spec.cmd)}'].", "ERROR")
        if self.shutting_down:
            return
        retries = p.spec.respawn_max_retries
        if p.spec.respawn and (retries < 0 or p.starts <= retries):
            p.respawn_at = time.monotonic() + p.spec.respawn_delay_s
            self.info(p.spec.label, f"respawning in {p.spec.respawn_delay_s:g} s")
            return
        if code != 0:
            self.failed = True
        if self.shutdown_on_exit:
            self._shutdown(f"process[{p.spec.label}] exited and --shutdown-on-exit is set")

    def _shutdown(self, reason: str) -> None:
        now = time.monotonic()
        if self.shutting_down:  # again: stop waiting, go to the next rung at once
            self.info("launch", f"{reason} again, escalating", "WARNING")
            for p in [*self.procs, *self._retired]:
                if p.popen is not None and p.stage < 3:
                    p.deadline = now
            return
        self.shutting_down = True
        self.info("launch", reason, "WARNING")
        for p in self.procs:
            p.respawn_at = None
        self.spare_at = None
        if self.spare is not None:
            sb, self.spare = self.spare, None
            self._retire(sb)
        for p in [*self.procs, *self._retired]:
            if p.popen is not None:
                self._kill(p, signal.SIGINT)
                p.stage, p.deadline = 1, now + self._timeout(p.spec.sigterm_timeout_s, self.sigterm_timeout_s)

    def _escalate(self, p: _Proc, now: float) -> None:
        if p.stage == 1:
            waited = self._timeout(p.spec.sigterm_timeout_s, self.sigterm_timeout_s)
            self.info(p.spec.label, f"process[{p.spec.label}] failed to terminate '{waited:g}' seconds after "
                      "receiving 'SIGINT', escalating to 'SIGTERM'", "ERROR")
            self._kill(p, signal.SIGTERM)
            p.stage, p.deadline = 2, now + self._timeout(p.spec.sigkill_timeout_s, self.sigkill_timeout_s)
        elif p.stage == 2:
            waited = self._timeout(p.spec.sigkill_timeout_s, self.sigkill_timeout_s)
            self.info(p.spec.label, f"process[{p.spec.label}] failed to terminate '{waited:g}' seconds after "
                      "receiving 'SIGTERM', escalating to 'SIGKILL'", "ERROR")
            self._kill(p, signal.SIGKILL)
            p.stage, p.deadline = 3, None

    @staticmethod
    def _timeout(own: float | None, default: float) -> float:
        return default if own is None else own

    @staticmethod
    def _kill(p: _Proc, sig: int) -> None:
        if p.popen is not None and p.popen.returncode is None:  # not reaped, so the group id is still ours
            with contextlib.suppress(ProcessLookupError, PermissionError):
                os.killpg(p.popen.pid, sig)
