"""Parameter changes that do not describe a robot, or that a node cannot apply, are refused by every
node of a running graph, which goes on closing the loop (issue 19: "a parameter never lies")."""

import math

import numpy as np
import pytest
from faults_support import ClosedLoop

pytestmark = pytest.mark.integration

NODES = {"plant": "/plant", "velocity_controller": "/robot_0/velocity_controller",
         "motor_boards": "/robot_0/motor_boards", "ball_predictor": "/ball_predictor", "catcher": "/robot_0/catcher"}


def _moving(loop) -> bool:
    cmd = loop.watch.latest.get("/robot_0/cmd_vel")
    return cmd is not None and math.hypot(cmd.linear.x, cmd.linear.y) > 0.3 and np.hypot(*loop.velocity()[:2]) > 0.3


def test_every_node_refuses_a_robot_that_cannot_drive_and_the_plant_refuses_what_it_cannot_apply(ros_graph):
    loop = ClosedLoop(
        ros_graph, with_ball_model=True,
        plant={"robot_poses": [-3.5, 0.0, 0.0], "ball": [3.5, 0.5, 0.0, 0.0], "vision_dropout": 0.0},
        catcher={"fetch_resting_ball": True, "v_max_mps": 1.0, "a_max_mps2": 2.0},
        predictor={"robot_v_max_mps": 1.0, "robot_a_max_mps2": 2.0},
    )
    loop.start_all()
    loop.spin_until(lambda: _moving(loop), 60.0, "robot_0 driving to the ball")
    probe = loop.probe
    before = list(probe.get_parameter("/robot_0/velocity_controller", "robot.wheel_angles_rad"))

    for node, path in NODES.items():
        result = probe.set_parameter(path, "robot.wheel_angles_rad", [0.0, 0.0, 0.0, 0.0])
        assert not result.successful, node
        if node == "plant":  # the world is built from the robot once: read-only, not "accepted"
            assert "read-only" in result.reason or "read only" in result.reason, result.reason
        else:
            assert "cannot produce every twist" in result.reason, (node, result.reason)
        assert list(probe.get_parameter(path, "robot.wheel_angles_rad")) == pytest.approx(before), node

    result = probe.set_parameter("/plant", "robot.mass_kg", 1.0e6)
    assert not result.successful and probe.get_parameter("/plant", "robot.mass_kg") == 2.6

    # a wheel this small: the motors reach 0.19 m/s at its rim, the controller's speed limit is 4 m/s
    result = probe.set_parameter("/robot_0/velocity_controller", "robot.wheel_radius_m", 0.001)
    assert not result.successful and "out of the motors' reach" in result.reason, result.reason
    result = probe.set_parameter("/robot_0/velocity_controller", "robot.mass_kg", -1.0)
    assert not result.successful and "mass_kg" in result.reason

    # a change the nodes can apply still goes through, and the loop keeps closing
    assert probe.set_parameter("/robot_0/velocity_controller", "robot.mass_kg", 2.7).successful
    assert probe.set_parameter("/robot_0/catcher", "robot.robot_radius_m", 0.091).successful
    n = loop.watch.counts["/robot_0/wheel_setpoints"]
    loop.spin_sim(0.5)
    assert loop.watch.counts["/robot_0/wheel_setpoints"] > n + 100  # 500 Hz
    loop.spin_until(lambda: _moving(loop), 30.0, "robot_0 still driving")
    for node in NODES:
        assert loop.procs[node].alive(), f"{node} died:\n{loop.procs[node].output()[-3000:]}"
    loop.watch.assert_all_finite()
