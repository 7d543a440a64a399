"""erforce-launch's warm standby (launcher.Runner, erforce_interfaces.runtime.standby) with tiny Python children,
no ROS.

Each test runs a Runner in a process of its own (it installs signal handlers) on ProcessSpecs whose command
is CHILD, a console script of this interpreter as a node's: its ``main`` returns at once in the spare while
it warms up, else says "running <name> <pid>" and runs until a signal. The launcher's delays are shortened
for the test (STANDBY_FIRST_S, STANDBY_AGAIN_S).
"""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

CHILD = r"""
import os, signal, sys, time
from erforce_interfaces.runtime.standby import is_standby, wait_for_go
if is_standby():
    time.sleep(float(os.environ["CHILD_IMPORT_S"]))  # a real node's imports


def main():
    if not wait_for_go():
        return 0
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(0))
    signal.signal(signal.SIGINT, lambda *_: sys.exit(0))
    print(f"running {sys.argv[1]} {os.getpid()}", flush=True)
    while True:
        time.sleep(0.05)


if __name__ == "__main__":
    sys.exit(main())
"""

RUNNER = r"""
import json, os, sys
from erforce_interfaces.tools.launcher import runner
cfg = json.loads(sys.argv[1])
runner.STANDBY_FIRST_S, runner.STANDBY_AGAIN_S = cfg["first_s"], cfg["again_s"]  # the Runner reads them there
env = {**os.environ, "CHILD_IMPORT_S": str(cfg["import_s"])}
specs = [runner.ProcessSpec(label=f"{name}-{k + 1}", cmd=[cfg["script"], name], env=env, output="screen",
                            respawn=True, respawn_delay_s=cfg["delay_s"], respawn_max_retries=cfg["retries"],
                            standby=True) for k, name in enumerate(cfg["names"])]
sys.exit(runner.Runner(specs, 2.0, 2.0, standby=cfg["standby"]).run())
"""

FIRST_S, AGAIN_S, DELAY_S = 0.3, 1.0, 0.4


class Launched:
    """The Runner's process and everything it printed (stdout and stderr, one reader thread each)."""

    def __init__(self, script: Path, *, retries: int = -1, import_s: float = 0.0, standby: bool = True,
                 names: tuple[str, ...] = ("child",)) -> None:
        cfg = {"first_s": FIRST_S, "again_s": AGAIN_S, "delay_s": DELAY_S, "retries": retries, "import_s": import_s,
               "standby": standby, "script": str(script), "names": list(names)}
        self.popen = subprocess.Popen([sys.executable, "-c", RUNNER, json.dumps(cfg)], stdout=subprocess.PIPE,
                                      stderr=subprocess.STDOUT, text=True)
        self.lines: list[tuple[float, str]] = []
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        for line in self.popen.stdout:
            self.lines.append((time.monotonic(), line.rstrip("\n")))

    def text(self) -> str:
        return "\n".join(line for _, line in self.lines)

    def wait_for(self, pattern: str, timeout_s: float = 20.0, after: float = 0.0) -> tuple[float, re.Match]:
        """The first line after ``after`` (monotonic) that matches, and when it was read."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            for t, line in list(self.lines):
                m = re.search(pattern, line)
                if m and t >= after:
                    return t, m
            if self.popen.poll() is not None and not self._reader.is_alive():
                break
            time.sleep(0.01)
        raise AssertionError(f"no line matching {pattern!r}; output:\n{self.text()}")

    def pid_of(self, pattern: str, **kw) -> int:
        return int(self.wait_for(pattern, **kw)[1].group(1))

    def stop(self) -> int:
        if self.popen.poll() is None:
            self.popen.send_signal(signal.SIGINT)
        code = self.popen.wait(20.0)
        self._reader.join(5.0)
        return code


@pytest.fixture
def launched(tmp_path):
    made: list[Launched] = []
    script = tmp_path / "child"
    script.write_text(f"#!{sys.executable}\n{CHILD}")
    script.chmod(0o755)

    def make(**kw) -> Launched:
        made.append(Launched(script, **kw))
        return made[-1]

    yield make
    for runner in made:
        if runner.popen.poll() is None:
            runner.popen.kill()
            runner.popen.wait()


def gone(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    return False


def test_a_standby_takes_over_after_the_respawn_delay_and_a_new_one_follows_later(launched):
    run = launched()
    active = run.pid_of(r"\[child-1\]: process started with pid \[(\d+)\]")
    standby = run.pid_of(r"\[standby\]: standby ready \[pid (\d+)\]")
    assert standby != active and f"running child {standby}" not in run.text()  # it waits: no "running" yet
    t_kill = time.monotonic()
    os.kill(active, signal.SIGKILL)
    t_on, m = run.wait_for(r"\[child-1\]: process activated from standby with pid \[(\d+)\]")
    assert int(m.group(1)) == standby
    assert t_on - t_kill >= DELAY_S  # the line is read after it was written, the kill was before the death
    run.wait_for(rf"\[child-1\] running child {standby}$")  # its output is relayed as the process's
    t_next, m = run.wait_for(r"\[standby\]: standby started with pid \[(\d+)\]", after=t_on)
    assert int(m.group(1)) not in (active, standby)
    assert t_next - t_kill >= DELAY_S + AGAIN_S
    assert "process started with pid" not in run.text().split("process activated", 1)[1]  # no fresh start
    assert run.stop() == 0


def test_one_spare_stands_in_for_every_node_and_becomes_the_one_that_died(launched):
    run = launched(names=("first", "second"))
    run.pid_of(r"\[first-1\]: process started with pid \[(\d+)\]")
    second = run.pid_of(r"\[second-2\]: process started with pid \[(\d+)\]")
    spare = run.pid_of(r"\[standby\]: standby ready \[pid (\d+)\]")
    assert run.text().count("standby started") == 1  # one for both
    os.kill(second, signal.SIGKILL)
    assert run.pid_of(r"\[second-2\]: process activated from standby with pid \[(\d+)\]") == spare
    run.wait_for(rf"\[second-2\] running second {spare}$")  # the dead node's arguments, its output label
    assert "running first" not in run.text().split("process activated", 1)[1]
    assert run.stop() == 0


def test_respawn_max_retries_counts_activations_as_starts(launched):
    run = launched(retries=1)
    active = run.pid_of(r"process started with pid \[(\d+)\]")
    standby = run.pid_of(r"standby ready \[pid (\d+)\]")
    os.kill(active, signal.SIGKILL)
    assert run.pid_of(r"process activated from standby with pid \[(\d+)\]") == standby
    time.sleep(AGAIN_S + 0.5)  # when a next standby would have started: none, no respawn is left
    os.kill(standby, signal.SIGKILL)
    assert run.popen.wait(20.0) == 1  # the last start died (SIGKILL): no respawn left, a failure
    run.stop()
    out = run.text()
    assert out.count("standby started") == 1 and out.count("respawning in") == 1, out


def test_sigint_reaps_the_process_and_its_standby_quietly(launched):
    run = launched()
    active = run.pid_of(r"process started with pid \[(\d+)\]")
    standby = run.pid_of(r"standby ready \[pid (\d+)\]")
    assert run.stop() == 0
    out = run.text()
    assert f"standby has finished cleanly [pid {standby}]" in out
    assert f"process has finished cleanly [pid {active}]" in out
    assert gone(active) and gone(standby)


def test_a_standby_still_importing_ends_quietly_at_shutdown(launched):
    run = launched(import_s=1.5)
    run.pid_of(r"process started with pid \[(\d+)\]", timeout_s=20.0)
    standby = run.pid_of(r"standby started with pid \[(\d+)\]")
    assert run.stop() == 0  # SIGINT while it imports: ignored there, the socket's end of file ends it
    out = run.text()
    assert f"standby has finished cleanly [pid {standby}]" in out and "Traceback" not in out, out
    assert "standby ready" not in out


def test_a_standby_that_died_is_replaced_by_a_fresh_start_then_a_new_standby(launched):
    run = launched()
    active = run.pid_of(r"process started with pid \[(\d+)\]")
    standby = run.pid_of(r"standby ready \[pid (\d+)\]")
    os.kill(standby, signal.SIGKILL)
    run.wait_for(rf"standby died on its own \[pid {standby}, exit code -9\]; the next respawn is a fresh start")
    t_kill = time.monotonic()
    os.kill(active, signal.SIGKILL)
    t_new, m = run.wait_for(r"process started with pid \[(\d+)\]", after=t_kill)
    assert int(m.group(1)) not in (active, standby)
    assert run.pid_of(r"standby started with pid \[(\d+)\]", after=t_new) != standby
    assert "activated" not in run.text()
    assert run.stop() == 0


def test_no_standby_respawns_by_fresh_starts_only(launched):
    run = launched(standby=False)
    active = run.pid_of(r"process started with pid \[(\d+)\]")
    time.sleep(FIRST_S + 0.5)
    os.kill(active, signal.SIGKILL)
    _, m = run.wait_for(r"process started with pid \[(\d+)\]", after=time.monotonic())
    assert int(m.group(1)) != active
    assert run.stop() == 0
    assert "standby started" not in run.text() and "activated" not in run.text()


def test_only_nodes_of_ours_get_a_standby_and_the_switch_is_on_the_command_line(tmp_path):
    from erforce_interfaces.tools.launcher import Resolver
    from erforce_interfaces.tools.launcher.cli import _parse_cli

    launch = tmp_path / "mixed.launch.yaml"
    launch.write_text("launch:\n"
                      "  - node: {pkg: erforce_motion, exec: velocity_controller, respawn: 'true'}\n"
                      "  - executable: {cmd: sleep 10, respawn: 'true'}\n")
    specs = Resolver({}, tmp_path).resolve(launch, launch.name)
    # ours start through node_support.run_node (their schema says so); anything else would run as a second copy
    assert [(s.label, s.standby) for s in specs] == [("velocity_controller-1", True), ("sleep-2", False)]
    assert _parse_cli([str(launch)])[0].standby is True
    assert _parse_cli(["--no-standby", str(launch)])[0].standby is False


def test_the_spare_becomes_the_named_node_at_the_priority_it_had_before_the_warm_ups(tmp_path):
    """Each main runs while the spare warms up; one that lowers the process's scheduling (field_view: SCHED_IDLE)
    before run_node must not leave it to the node the spare becomes."""
    import socket

    from erforce_interfaces.runtime.standby import GO, READY, STANDBY_FD_ENV

    scripts = {}
    for name, before in (("idle", "os.sched_setscheduler(0, os.SCHED_IDLE, os.sched_param(0))"), ("plain", "")):
        scripts[name] = tmp_path / name
        scripts[name].write_text(
            f"#!{sys.executable}\nimport os, sys\nfrom erforce_interfaces.runtime.standby import wait_for_go\n"
            f"def main():\n    {before or 'pass'}\n    if not wait_for_go():\n        return 0\n"
            "    print(sys.argv[1:], os.sched_getscheduler(0), flush=True)\n    return 5\n")
    ours, theirs = socket.socketpair()
    with ours:
        cmd = [sys.executable, "-m", "erforce_interfaces.runtime.standby", *map(str, scripts.values())]
        proc = subprocess.Popen(cmd,
                                env={**os.environ, STANDBY_FD_ENV: str(theirs.fileno())}, pass_fds=(theirs.fileno(),),
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        theirs.close()
        try:
            ours.settimeout(60.0)
            assert ours.recv(64) == READY
            ours.sendall(GO + b" " + json.dumps({"argv": [str(scripts["plain"]), "--ros-args"]}).encode() + b"\n")
            out, err = proc.communicate(timeout=60.0)
        finally:
            proc.kill()
    assert proc.returncode == 5, err  # the named node's main ran, with its arguments, and its exit code is the spare's
    assert out.split() == ["['--ros-args']", str(os.sched_getscheduler(0))]
