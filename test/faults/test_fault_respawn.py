"""Issue 19: the launched graph heals itself. Each node type of demo.launch.yaml is killed once
(SIGKILL); erforce-launch restarts it after respawn_delay and the loop closes again with nobody
restarting anything: the restarted plant (time from 0), predictor, catcher or controller rejoins
lockstep. How fast, per node type, is a bench figure (bench/bench_respawn.py), not a timed test."""

import pytest
from faults_support import LOOP_OUTPUTS, LaunchedDemo

pytestmark = pytest.mark.integration

RESPAWN_DELAY_S = 0.5  # demo.launch.yaml's default


def test_any_single_node_killed_the_launched_graph_closes_the_loop_again_by_itself(ros_graph):
    demo = LaunchedDemo(ros_graph)
    demo.wait_running()
    heal_s = {}
    for node in ("catcher", "ball_predictor", "velocity_controller", "motor_boards", "plant"):
        heal_s[node] = demo.kill_and_heal(node, RESPAWN_DELAY_S, timeout_s=90.0)
        assert heal_s[node] > RESPAWN_DELAY_S
    out = demo.launch.output()
    for node in LOOP_OUTPUTS:
        assert out.count(f"[{node}-") and f"]: respawning in {RESPAWN_DELAY_S:g} s" in out
        assert demo.pid(node) is not None
    assert demo.launch.alive()
    assert "Traceback" not in out, out[-3000:]
