"""The nodes' build functions, without ROS: a config object of each node's schema becomes the core it
runs, and combinations no single parameter shows are refused with the reason."""

import math

import pytest

from erforce_ball_model import ball_predictor_node, catcher_node
from erforce_ball_model.receiver import CatcherConfig
from erforce_motion import motor_boards_node, velocity_controller_node
from erforce_sim import plant_node
from erforce_sim.plant_setup import build_world
from erforce_sim.ssl_cameras import BENCH_CAMERAS, CAMERA_MODELS, ERFORCE_REALISTIC
from erforce_sim.view import field_view_node


def config(module, **changes):
    values = module.SCHEMA.defaults()
    values.update(changes)
    return module.SCHEMA.parse(values)


def test_every_node_builds_from_its_defaults():
    loop = velocity_controller_node.build_loop(config(velocity_controller_node))
    assert loop.loop_period_s == pytest.approx(1.0 / 500.0)
    board = motor_boards_node.build_loop(config(motor_boards_node))
    assert board.robot.num_wheels == 4
    setup = plant_node.setup_from_params(config(plant_node))
    assert setup.num_robots == 1 and setup.control_period_s == 0.002
    predictor = ball_predictor_node.build_config(config(ball_predictor_node))
    assert predictor.num_robots == 11 and predictor.facing_fixed.shape == (11,)
    # one vision noise: the flat filter's and the chip detector's
    quieter = ball_predictor_node.build_config(config(ball_predictor_node, position_noise_m=0.0014))
    assert quieter.tracker.position_noise_m == quieter.chip_detector.noise_m == 0.0014
    # one rest speed: the catch times' and the chip detector's (a kick starts from a ball slower than it)
    slower = ball_predictor_node.build_config(config(ball_predictor_node, rest_speed_mps=0.3))
    assert slower.rest_speed_mps == slower.chip_detector.rest_speed_mps == 0.3
    catcher, dribbler_m, radius_m, field = catcher_node.build_config(config(catcher_node))
    assert catcher == CatcherConfig() and (dribbler_m, radius_m, field.length_m) == (0.0815, 0.09, 9.0)
    view = field_view_node.check_config(config(field_view_node))
    assert (view.port, view.rate_hz, view.field, view.robot.robot_radius_m) == (8090, 30.0, "division_b", 0.09)


def test_a_wheel_the_motors_cannot_drive_fast_enough_is_refused():
    # 24 V / (0.036 V s/rad * 3.6) = 185 rad/s at the wheel; at a 1 mm radius the rim makes 0.19 m/s
    with pytest.raises(ValueError, match=r"max_speed_mps 4 m/s is out of the motors' reach.*0\.185 m/s"):
        velocity_controller_node.build_loop(config(velocity_controller_node, **{"robot.wheel_radius_m": 0.001}))


def test_wheel_speeds_beyond_the_wire_are_refused():
    # 1000 V: the motors reach 7716 rad/s, 7.7 m/s at the rim; but the PID's limits (5 m/s per axis,
    # 15 rad/s) need up to (|sin a| + |cos a|) 5 / r + 15 d / r rad/s, far beyond the wire's 1000.
    cfg = config(velocity_controller_node, **{"robot.wheel_radius_m": 0.001, "robot.supply_voltage_v": 1000.0})
    worst = max(abs(math.sin(a)) + abs(math.cos(a)) for a in cfg.robot.wheel_angles_rad) * 5.0 / 0.001
    worst += 15.0 * 0.081 / 0.001
    with pytest.raises(ValueError, match=rf"wheel speeds up to {worst:.4g} rad/s .* beyond the wire's 1000"):
        velocity_controller_node.build_loop(cfg)


def test_per_robot_lists_and_the_plants_robots_must_agree():
    with pytest.raises(ValueError, match=r"facing_mode: need one value or one per robot \(2\), got 3"):
        ball_predictor_node.build_config(config(ball_predictor_node, num_robots=2,
                                                facing_mode=["fixed", "fixed", "fixed"]))
    with pytest.raises(ValueError, match="robot_poses: need x, y, yaw per robot"):
        plant_node.setup_from_params(config(plant_node, robot_poses=[0.0, 0.0, 0.0, 1.0]))
    with pytest.raises(ValueError, match="opponent_poses: need x, y, yaw per robot"):
        plant_node.setup_from_params(config(plant_node, opponent_poses=[1.0, 1.0]))


def test_the_opponents_come_after_our_robots_and_face_the_ball():
    """The predictor's facing lists are per robot of ours; its core serves ours, then the opponents, who
    face towards the ball. The plant's opponents take the colour that is not ours."""
    predictor = ball_predictor_node.build_config(config(ball_predictor_node, num_robots=2, num_opponents=3,
                                                        facing_mode=["fixed", "towards_ball"], facing_rad=[0.5]))
    assert predictor.num_robots == 5
    assert predictor.facing_fixed.tolist() == [True, False, False, False, False]
    assert predictor.facing_rad.tolist() == [0.5, 0.5, math.pi, math.pi, math.pi]
    setup = plant_node.setup_from_params(config(plant_node, robot_poses=[-1.0, 0.0, 0.0, -2.0, 0.0, 0.0],
                                                opponent_poses=[1.0, 0.5, 3.0], team_color="yellow"))
    assert (setup.num_robots, setup.num_opponents, setup.our_color, setup.opponent_color) == (2, 1, "yellow", "blue")
    assert [setup.team_of(i) for i in range(3)] == [(False, 0), (False, 1), (True, 0)]
    assert setup.is_controlled(2)
    assert plant_node.setup_from_params(config(plant_node)).our_color == "blue"  # as the SSL bridge's default
    with pytest.raises(ValueError, match="realtime pacing needs real_time_factor > 0"):
        plant_node._check_pacing(config(plant_node, pacing="realtime", real_time_factor=0.0))


def test_the_plants_camera_model_reaches_its_world_and_combinations_it_cannot_apply_are_refused():
    """camera_model picks the CameraRealism of both vision outputs: erforce takes the world's frames without the
    shared noise and dropouts (each camera draws its own), so vision_noise_m and vision_dropout, the bench cameras'
    shared figures, may not claim another value; its per-camera offset only the SSL bridge's alignment takes off, so
    it needs vision_output ssl. The schema's choices are ssl_cameras.CAMERA_MODELS."""
    assert plant_node.setup_from_params(config(plant_node)).cameras is BENCH_CAMERAS
    setup = plant_node.setup_from_params(config(plant_node, camera_model="erforce", vision_output="ssl"))
    assert setup.cameras is ERFORCE_REALISTIC
    vision = build_world(setup).vision.params
    assert (vision.position_noise_m, vision.ball_dropout_prob, vision.robot_dropout_prob) == (0.0, 0.0, 0.0)
    assert vision.orientation_noise_rad == 0.01  # shared by the cameras in both models
    with pytest.raises(ValueError, match=r"camera_model 'erforce'.*vision_output 'ros' has no alignment stage"):
        plant_node.setup_from_params(config(plant_node, camera_model="erforce"))
    with pytest.raises(ValueError, match=r"camera_model 'erforce'.*vision_output 'both'"):
        plant_node.setup_from_params(config(plant_node, camera_model="erforce", vision_output="both"))
    for name, value in (("vision_noise_m", 0.001), ("vision_dropout", 0.0)):
        with pytest.raises(ValueError, match=rf"{name}: camera_model 'erforce' draws its noise and misses per camera"):
            plant_node.setup_from_params(config(plant_node, camera_model="erforce", vision_output="ssl",
                                                **{name: value}))
    assert plant_node.SCHEMA.by_name["camera_model"].one_of == tuple(sorted(CAMERA_MODELS))
