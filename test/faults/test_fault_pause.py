"""Issue 36: a paused process (SIGSTOP for 3 s, then SIGCONT: a debugger, a suspended laptop, a frozen
container) rejoins the running loop by itself, the lockstep included, with no death and no respawn.

team_sim.launch.yaml for a team of two and one opponent, as test_fault_team's launched graph: each node is
paused in turn; the loop is closed again when the paused node's output is back and every other node's output
came after it (faults_support.LaunchedDemo.pause_and_heal). How fast is bench_respawn.py --pause's figure;
here the deadline only bounds a loop that does not close at all.
"""

import re

import pytest
from faults_support import TEAM_LOOP_OUTPUTS, TEAM_SIM_LAUNCH, LaunchedDemo

pytestmark = pytest.mark.integration

PAUSE_S = 3.0


def test_each_node_of_the_team_graph_paused_for_3_s_rejoins_the_loop(ros_graph):
    demo = LaunchedDemo(ros_graph, TEAM_SIM_LAUNCH, TEAM_LOOP_OUTPUTS, standby=False, robot_ids="[0, 1]",
                        num_robots="2", robot_poses="[-4.0, 0.0, 0.0, -3.0, 2.0, 0.0]", opponent_ids="[0]",
                        num_opponents="1", opponent_poses="[0.0, 1.0, 3.14159265]")
    demo.wait_running()
    pids = {node: demo.pid(node) for node in TEAM_LOOP_OUTPUTS}
    for node in TEAM_LOOP_OUTPUTS:
        heal_s = demo.pause_and_heal(node, PAUSE_S, timeout_s=60.0)
        assert heal_s > 0.0
        demo.wait_running()
    assert {node: demo.pid(node) for node in TEAM_LOOP_OUTPUTS} == pids  # nobody died, nobody was replaced
    out = demo.launch.output()
    assert not re.search(r"respawning in|process has died", out), out[-3000:]
    assert "Traceback" not in out, out[-3000:]
