"""erforce-realtime: a command under SCHED_FIFO where allowed, else at its own priority with one line saying so."""

import json
import os
import socket
import subprocess
import sys

import pytest

from erforce_interfaces.runtime import standby
from erforce_interfaces.runtime.standby import GO, READY, STANDBY_FD_ENV
from erforce_interfaces.tools import realtime

SHOW_POLICY = [sys.executable, "-c", "import os; print(os.sched_getscheduler(0), os.sched_getparam(0).sched_priority)"]


def refusing_fifo(calls: list):
    """os.sched_setscheduler as without CAP_SYS_NICE: SCHED_FIFO refused, the rest allowed (and not done)."""
    def sched_setscheduler(pid, policy, param):
        calls.append((policy, param.sched_priority))
        if policy == os.SCHED_FIFO:
            raise PermissionError(1, "Operation not permitted")
    return sched_setscheduler


def test_the_command_runs_under_sched_fifo_at_the_priority_or_says_why_not():
    done = subprocess.run([sys.executable, "-m", "erforce_interfaces.tools.realtime", "7", *SHOW_POLICY],
                          capture_output=True, text=True, timeout=60, check=True)
    policy, priority = (int(v) for v in done.stdout.split())
    if "not allowed" in done.stderr:  # no CAP_SYS_NICE: the command still ran, at the normal policy
        assert (policy, priority) == (os.SCHED_OTHER, 0)
    else:
        assert (policy, priority) == (os.SCHED_FIFO, 7)
        assert done.stderr == ""


def test_refused_it_warns_once_and_still_runs_the_command(monkeypatch, capsys):
    ran = []
    monkeypatch.setattr(os, "sched_setscheduler", refusing_fifo([]))
    monkeypatch.setattr(os, "execvp", lambda file, args: ran.append((file, args)))
    assert realtime.main(["10", "ball_predictor", "--ros-args"]) == 0
    assert ran == [("ball_predictor", ["ball_predictor", "--ros-args"])]
    assert capsys.readouterr().err == ("erforce-realtime: SCHED_FIFO priority 10 not allowed (Operation not "
                                       "permitted); ball_predictor runs at its normal priority\n")


def test_refused_with_else_idle_the_command_runs_under_sched_idle(monkeypatch, capsys):
    calls, ran = [], []
    monkeypatch.setattr(os, "sched_setscheduler", refusing_fifo(calls))
    monkeypatch.setattr(os, "execvp", lambda file, args: ran.append((file, args)))
    assert realtime.main(["--else-idle", "5", "plant", "--ros-args"]) == 0
    assert ran == [("plant", ["plant", "--ros-args"])]
    assert calls == [(os.SCHED_FIFO, 5), (os.SCHED_IDLE, 0)]
    assert capsys.readouterr().err == ("erforce-realtime: SCHED_FIFO priority 5 not allowed (Operation not "
                                       "permitted); plant runs at SCHED_IDLE\n")


def test_without_cap_sys_nice_the_kernel_refuses_and_else_idle_runs_the_command_under_sched_idle():
    """The real refusal: the command runs without CAP_SYS_NICE (util-linux setpriv drops it from the bounding
    set, so not even root has it) and with no real-time limit (``ulimit -r`` 0); SCHED_IDLE needs no privilege."""
    no_rt = [sys.executable, "-c", "import os, resource, sys; resource.setrlimit(resource.RLIMIT_RTPRIO, (0, 0)); "
             "os.execvp(sys.argv[1], sys.argv[1:])"]
    cmd = ["setpriv", "--bounding-set", "-sys_nice", *no_rt,
           sys.executable, "-m", "erforce_interfaces.tools.realtime", "--else-idle", "5", *SHOW_POLICY]
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=60, check=True)
    assert [int(v) for v in done.stdout.split()] == [os.SCHED_IDLE, 0]
    assert done.stderr.startswith("erforce-realtime: SCHED_FIFO priority 5 not allowed")
    assert done.stderr.endswith("runs at SCHED_IDLE\n")


def test_a_standby_left_else_idle_takes_sched_idle_on_go_where_fifo_is_refused(monkeypatch, capsys):
    from erforce_interfaces.runtime import standby

    calls = []
    monkeypatch.setattr(os, "sched_setscheduler", refusing_fifo(calls))
    assert standby.node_entry(["erforce-realtime", "--else-idle", "5", "plant"]) is None  # not a script of ours
    standby.leave_realtime_priority(5, else_idle=True)  # what the spare does with the prefix on "go"
    assert calls == [] and os.environ[standby.REALTIME_PRIORITY_ENV] == "5,idle"
    standby._take_realtime_priority()
    assert calls == [(os.SCHED_FIFO, 5), (os.SCHED_IDLE, 0)]
    assert "runs at SCHED_IDLE" in capsys.readouterr().err
    assert standby.REALTIME_PRIORITY_ENV not in os.environ


@pytest.mark.parametrize("argv", [[], ["10"], ["0", "x"], ["100", "x"], ["high", "x"], ["--else-idle", "x"]])
def test_a_bad_command_line_prints_the_usage(argv, capsys):
    assert realtime.main(argv) == 2
    assert capsys.readouterr().err.startswith("usage: erforce-realtime [--else-idle] PRIORITY COMMAND")


def test_a_warm_standby_imports_at_its_normal_priority_and_takes_sched_fifo_on_go(tmp_path):
    script = tmp_path / "node"
    script.write_text(f"#!{sys.executable}\nimport os\nfrom erforce_interfaces.runtime.standby import wait_for_go\n"
                      "def main():\n"
                      "    print(os.sched_getscheduler(0), os.sched_getparam(0).sched_priority, flush=True)\n"
                      "    return 0 if wait_for_go() else 3\n")
    script.chmod(0o755)
    cmd = ["/opt/erforce-realtime", "7", str(script), "--ros-args"]
    k, priority, else_idle = standby.node_entry(cmd)
    assert (k, priority, else_idle) == (2, 7, False)
    ours, theirs = socket.socketpair()
    with ours:
        proc = subprocess.Popen([sys.executable, "-m", "erforce_interfaces.runtime.standby", str(script)],
                                env={**os.environ, STANDBY_FD_ENV: str(theirs.fileno())}, pass_fds=(theirs.fileno(),),
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        theirs.close()
        try:
            ours.settimeout(60.0)
            assert ours.recv(64) == READY
            waiting = proc.stdout.readline().split()  # its main, run as far as rclpy.init while warming
            ours.sendall(GO + b" " + json.dumps({"argv": cmd[k:], "priority": [priority, else_idle]}).encode() + b"\n")
            out, err = proc.communicate(timeout=60.0)
        finally:
            proc.kill()
    assert proc.returncode == 0, err
    assert [int(v) for v in waiting] == [os.SCHED_OTHER, 0]  # warming: the normal priority
    if "not allowed" in err:
        assert [int(v) for v in out.split()] == [os.SCHED_OTHER, 0]
    else:
        assert [int(v) for v in out.split()] == [os.SCHED_FIFO, 7]
