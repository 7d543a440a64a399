"""Every node executable of the packages exits quietly with code 0 on SIGINT: sent to the process alone,
and to its process group followed by more SIGINTs to the process while it stops (the group's SIGINT alone
is that case's first signal). The last is what a terminal's Ctrl-C under ``ros2 launch`` delivers (the
terminal signals the whole group, then launch forwards SIGINT to each child); before
node_support.QuietInterrupt the second one raised KeyboardInterrupt in run_node's cleanup (a traceback,
exit code -2).

The executables are the console scripts the packages register (their setup.py, as installed); each is
either a node here or a tool listed in TOOLS, so a new one cannot slip past this test.
"""

import importlib.metadata
import os
import signal
import socket
import time

import pytest
from std_msgs.msg import String

PACKAGES = ("erforce_interfaces", "erforce_ball_model", "erforce_motion", "erforce_sim")

# Console scripts that are command line tools, not nodes: they end by themselves or have their own
# SIGINT rules (the launcher's are in test_launcher.py, the topic tool's in test_topic_tool.py; erforce-realtime
# becomes the command it prefixes, test_realtime.py).
TOOLS = {"erforce-launch", "erforce-topic", "ssl_log_replay", "ball_figures", "ball_fit", "tune_motor",
         "ssl_game_log", "erforce-realtime"}


def free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def node_params(executable: str) -> dict:
    """What a node needs to start on its own without taking a port another test or a running stack uses."""
    if executable == "ssl_vision_bridge":
        return {"interface": "127.0.0.1", "port": free_udp_port()}
    if executable == "ssl_sim_server":
        return {"control_port": free_udp_port(), "robot_control_port": free_udp_port()}
    if executable == "ssl_sim_bridge":
        return {"command_port": free_udp_port()}
    if executable == "field_view":
        return {"port": 0}
    return {}


def console_scripts() -> list[str]:
    return sorted(ep.name for pkg in PACKAGES for ep in importlib.metadata.distribution(pkg).entry_points
                  if ep.group == "console_scripts")


NODES = [name for name in console_scripts() if name not in TOOLS]


def test_every_console_script_is_a_node_or_a_listed_tool():
    assert set(TOOLS) <= set(console_scripts())
    assert {"talker", "plant", "motor_boards", "ball_predictor", "erforce-record"} <= set(NODES)


def interrupt_alone(procs) -> None:
    for proc in procs:
        os.kill(proc.pid, signal.SIGINT)


def interrupt_group_then_forwarded(procs, deadline_s: float = 20.0) -> None:
    """Each one's group's SIGINT, then one to each process every 5 ms until it has exited: some land in its
    cleanup. Every process at once: one after the other, their shutdowns would add up."""
    for proc in procs:
        os.killpg(proc.pid, signal.SIGINT)
    deadline = time.monotonic() + deadline_s
    while any(proc.alive() for proc in procs) and time.monotonic() < deadline:
        time.sleep(0.005)
        for proc in procs:
            proc.signal(signal.SIGINT)


@pytest.mark.integration
@pytest.mark.parametrize("interrupt", [interrupt_alone, interrupt_group_then_forwarded],
                         ids=["alone", "group-then-forwarded"])
def test_every_node_exits_quietly_with_0_on_sigint(ros_graph, tmp_path, interrupt):
    # All at once: each start costs seconds of CPU (imports), the test would take minutes one by one.
    procs = {}
    for exe in NODES:
        if exe == "erforce-record":
            procs[exe] = ros_graph.start([ros_graph.probe_executable(exe), str(tmp_path / "bag")], name=exe)
        else:
            procs[exe] = ros_graph.start_node("", exe, name=f"sigint_{exe}", params=node_params(exe))
    # Up: a node answers on its parameter service only once its executor spins; the recorder, which has
    # no services, logs each topic it subscribes to from inside its loop.
    probe = ros_graph.probe
    chatter = probe.publisher("/sigint_probe", String)
    chatter.publish(String(data="up?"))
    for exe, proc in procs.items():
        if exe == "erforce-record":
            proc.wait_for_output("Subscribed to topic '/sigint_probe'", timeout_s=120.0)
        else:
            assert probe.get_parameter(f"/sigint_{exe}", "use_sim_time", timeout_s=120.0) is False, exe
    interrupt(list(procs.values()))
    failures = []
    for exe, proc in procs.items():
        code = proc.wait_exit(30.0)
        out = proc.output()
        if code != 0 or "Traceback" in out or "KeyboardInterrupt" in out:
            failures.append(f"{exe}: exit code {code}\n{out[-1500:]}")
    assert not failures, "\n".join(failures)


@pytest.mark.integration
def test_a_warm_standby_ends_quietly_with_0_on_sigint_sigterm_or_the_launchers_end(ros_graph):
    """The spare erforce-launch keeps (erforce_interfaces.runtime.standby, given the scripts of real nodes with a
    warm-up: plant, ball_predictor, and two without) waits after their imports and warm-ups with no DDS node,
    prints nothing, and ends with 0 on SIGINT (alone or to its group), SIGTERM, or the end of file of its socket
    (the launcher gone)."""
    import subprocess
    import sys

    from erforce_interfaces.runtime.standby import READY, STANDBY_FD_ENV

    def end_by_eof(proc, sock) -> None:
        sock.close()

    endings = {"SIGINT": lambda proc, sock: proc.send_signal(signal.SIGINT),
               "SIGINT to the group": lambda proc, sock: os.killpg(proc.pid, signal.SIGINT),
               "SIGTERM": lambda proc, sock: proc.send_signal(signal.SIGTERM),
               "end of file": end_by_eof}
    scripts = [ros_graph.probe_executable(exe) for exe in ("velocity_controller", "plant", "ball_predictor", "catcher")]
    started = {}
    try:
        for how in endings:  # all at once: each spare's imports and warm-ups cost a second or two of CPU
            ours, theirs = socket.socketpair()
            env = {**ros_graph.env, STANDBY_FD_ENV: str(theirs.fileno())}
            proc = subprocess.Popen([sys.executable, "-m", "erforce_interfaces.runtime.standby", *scripts],
                                    env=env, pass_fds=(theirs.fileno(),), stdout=subprocess.PIPE,
                                    stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL, start_new_session=True)
            theirs.close()
            ours.settimeout(180.0)
            started[how] = (proc, ours)
        for how, (_proc, sock) in started.items():
            assert sock.recv(64) == READY, how
        names = {name for name, _ in ros_graph.probe.node.get_node_names_and_namespaces()}
        assert not names & {"velocity_controller", "plant", "ball_predictor", "catcher"}, names  # no node yet
        failures = []
        for how, (proc, sock) in started.items():
            endings[how](proc, sock)
            code = proc.wait(30.0)
            out = proc.stdout.read().decode(errors="replace")
            if code != 0 or out:
                failures.append(f"{how}: exit code {code}, output:\n{out[-1500:]}")
        assert not failures, "\n".join(failures)
    finally:
        for proc, sock in started.values():
            sock.close()
            if proc.poll() is None:
                proc.kill()
                proc.wait()
