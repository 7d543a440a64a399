"""The plant node over DDS: closed loop in lockstep, determinism vs. the in-process runner,
stall reporting, scenarios and bad input."""

import math
import struct
import time
from pathlib import Path

import numpy as np
import pytest
from geometry_msgs.msg import PoseStamped, Twist
from nav_msgs.msg import Odometry
from rclpy.qos import QoSProfile
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState, PointCloud2
from std_msgs.msg import Float64, String

from erforce_interfaces.tools.messages import joint_state_msg
from erforce_interfaces.wire import contract
from erforce_interfaces.wire.clouds import vision_cloud_from_msg, vision_robots_from_msg
from erforce_interfaces.wire.conversions import odometry_from_msg, odometry_msg, pose2d_from_msg, stamp_to_nanoseconds
from erforce_motion.velocity_control import VelocityControlConfig
from erforce_sim.in_process.runner import InProcessRunner
from erforce_sim.plant_setup import PlantSetup

pytestmark = pytest.mark.integration

ROBOT_YAML = Path(__file__).resolve().parents[2] / "src/erforce_interfaces/config/robot.yaml"


def start_robot(graph, robot="robot_0", **vc_params):
    graph.start_node("erforce_motion", "velocity_controller", namespace=robot, params_file=ROBOT_YAML,
                     params={"use_sim_time": True, **vc_params})
    # The boards' lockstep join waits setpoint_wait_s of wall time (0.05 s by default) for the velocity
    # controller's setpoint, then answers with the previous one: on a loaded machine that changed the
    # trajectory by up to 1e-5 m. Here the wait must outlast any scheduling delay.
    graph.start_node("erforce_motion", "motor_boards", namespace=robot, params_file=ROBOT_YAML,
                     params={"use_sim_time": True, "setpoint_wait_s": 10.0})


def start_plant(graph, **params):
    defaults = {"robot_poses": [0.0, 0.0, 0.0], "ball": [2.0, 2.0, 0.0, 0.0], "real_time_factor": 0.0}
    defaults.update(params)
    return graph.start_node("erforce_sim", "plant", params_file=ROBOT_YAML, params=defaults)


def start_plant_watched(graph, **params):
    """Start the plant once this probe takes robot_0's ground truth, and return what it receives.

    The plant runs flat out: without holding its first tick until the probe reads (here: /clock,
    subscribed after the truth by ``release_first_tick``), a slow discovery let the robot drive into the
    wall unseen. It starts while the robot's nodes do.
    """
    truth = graph.subscribe("/robot_0/ground_truth/odom", Odometry)
    start_plant(graph, start_clock_subscribers=3, **params)  # velocity_controller, motor_boards, probe
    return truth


def release_first_tick(graph):
    """The probe's /clock reader, the last one the plant waits for: after the command has had 0.3 s to
    arrive (it was published once its reader had matched), so that the robot has it at tick 0."""
    graph.probe.spin_for(0.3)
    graph.subscribe("/clock", Clock, contract.QOS_CLOCK)


def send_cmd_vel(graph, vx, vy=0.0, wz=0.0, robot="robot_0"):
    pub = graph.probe.wait_for_subscribers(f"/{robot}/cmd_vel", Twist, timeout_s=20.0)
    msg = Twist()
    msg.linear.x, msg.linear.y, msg.angular.z = vx, vy, wz
    pub.publish(msg)
    return pub, msg


def test_twist_drives_the_simulated_robot_in_lockstep(ros_graph):
    """Twist -> velocity_controller -> motor_boards -> plant -> measured body velocity."""
    start_robot(ros_graph, command_timeout_s=30.0)
    truth = start_plant_watched(ros_graph)
    send_cmd_vel(ros_graph, 1.0, 0.5)
    release_first_tick(ros_graph)
    ros_graph.probe.spin_until(lambda: truth and odometry_from_msg(truth[-1])[0] > 1.0, 60.0, "1 s of sim time")
    _, pose, vel, _ = odometry_from_msg(truth[-1])
    c, s = math.cos(pose[2]), math.sin(pose[2])
    v_robot = (c * vel[0] + s * vel[1], -s * vel[0] + c * vel[1])  # cmd_vel is in base_link
    assert v_robot[0] == pytest.approx(1.0, rel=0.03) and v_robot[1] == pytest.approx(0.5, rel=0.03)
    assert abs(vel[2]) < 0.05
    stamps = [stamp_to_nanoseconds(m.header.stamp) for m in truth]
    assert stamps == sorted(stamps) and all(np.isfinite(odometry_from_msg(m)[1]).all() for m in truth)


def test_lockstep_dds_graph_reproduces_the_in_process_trajectory(ros_graph):
    twist = (0.8, -0.3, 1.0)
    start_robot(ros_graph, command_timeout_s=30.0)
    # a stall would change the trajectory: on a loaded machine an answer may take seconds
    truth = start_plant_watched(ros_graph, seed=7, stop_after_s=0.6, lockstep_timeout_s=30.0)
    send_cmd_vel(ros_graph, *twist)
    release_first_tick(ros_graph)
    ros_graph.probe.spin_until(lambda: truth and odometry_from_msg(truth[-1])[0] >= 0.5, 60.0, "0.5 s")
    dds = {stamp_to_nanoseconds(m.header.stamp): odometry_from_msg(m) for m in truth}

    setup = PlantSetup(robot_poses=((0.0, 0.0, 0.0),), ball=(2.0, 2.0, 0.0, 0.0), seed=7, control_period_s=0.002)
    runner = InProcessRunner(setup, VelocityControlConfig(), command_timeout_s=30.0)
    runner.command(0, twist)
    compared = 0
    for _ in range(250):
        if runner.t_ns in dds:
            _, pose, vel, _ = dds[runner.t_ns]
            s = runner.world.robot_state(0)
            np.testing.assert_allclose(pose, [s.x, s.y, s.theta], rtol=0, atol=1e-9)
            np.testing.assert_allclose(vel, [s.vx, s.vy, s.w], rtol=0, atol=1e-9)
            compared += 1
        runner.tick()
    assert compared >= 40  # ground truth at 100 Hz over 0.5 s
    assert abs(runner.world.robot_state(0).vx) > 0.3  # it did move


def test_clock_is_published_and_monotonic_and_vision_sends_each_frames_ball_and_robots_in_one_message(ros_graph):
    clocks = ros_graph.subscribe("/clock", Clock, contract.QOS_CLOCK)
    q = contract
    robots = ros_graph.subscribe(q.VISION_ROBOTS.name, PointCloud2, q.VISION_ROBOTS.qos)
    poses = ros_graph.subscribe(q.OPPONENTS.topic(q.VISION_POSE, 0), PoseStamped, q.VISION_POSE.qos)
    start_plant(ros_graph, controlled=[False], pacing="realtime", real_time_factor=1.0, stop_after_s=5.0,
                robot_poses=[0.5, -1.0, 0.25], opponent_poses=[1.0, 1.0, 3.0], vision_dropout=0.0,
                startup_timeout_s=0.0)  # the opponent has motor boards: none here, and none waited for
    ros_graph.probe.spin_until(lambda: clocks and stamp_to_nanoseconds(clocks[-1].clock) >= 500_000_000, 30.0,
                               "/clock to 0.5 s")
    stamps = [stamp_to_nanoseconds(c.clock) for c in clocks]
    assert stamps == sorted(stamps)
    # vision: both teams' robots of a frame in one message (robot_0 as team 1, opponent_0 as team 2, 2 mm noise);
    # the opponent's own vision_pose, which has a reader here, carries the same pose at the same stamp
    ros_graph.probe.spin_until(lambda: len(robots) >= 10 and len(poses) >= 10, 30.0, "10 vision frames")
    frames = {t_s: rows for t_s, rows in map(vision_robots_from_msg, robots)}
    for cloud in map(vision_cloud_from_msg, robots):  # the ball at rest where the test put it, after its camera
        assert cloud.balls.tolist() == [pytest.approx([2.0, 2.0], abs=0.02)]  # 10 sigma of the 2 mm position noise
        # division B's +x +y quadrant (x, y > -0.25 m) alone sees it: its camera 4 m above the rectangle's middle
        assert (cloud.camera_id, cloud.camera_m) == (1, pytest.approx((2.275, 1.525, 4.0), abs=1e-12))
        assert not len(cloud.sightings)
    # the camera's point first, then the ball's (team at byte 32 of each 48-byte point)
    assert all(struct.unpack_from("<d40xd", bytes(msg.data), 32)
               == (contract.VISION_CAMERA_CODE, contract.VISION_BALL_CODE) for msg in robots)
    for rows in frames.values():
        assert rows[:, :2].tolist() == [[1.0, 0.0], [2.0, 0.0]]
        assert rows[:, 2:].tolist() == [pytest.approx([0.5, -1.0, 0.25], abs=0.06),  # 6 sigma of the yaw noise
                                        pytest.approx([1.0, 1.0, 3.0], abs=0.06)]
    same = [(frames[t_s], pose) for t_s, pose in map(pose2d_from_msg, poses) if t_s in frames]
    assert len(same) >= 5
    for rows, pose in same:
        assert rows[1, 2:].tolist() == pytest.approx(pose.tolist(), abs=1e-12)


def test_a_ball_two_cameras_see_comes_from_the_first_and_as_the_seconds_sighting(ros_graph):
    """At (0, 1) the ball lies where division B's upper quadrants overlap (|x| <= 0.25 m): camera 0, whose SSL frames
    come first, takes the ball into the frame with the robots; camera 1's view follows in a frame of its own, at
    the same stamp, as a sighting after its camera's point."""
    q = contract
    robots = ros_graph.subscribe(q.VISION_ROBOTS.name, PointCloud2, q.VISION_ROBOTS.qos)
    start_plant(ros_graph, controlled=[False], pacing="realtime", real_time_factor=1.0, stop_after_s=5.0,
                ball=[0.0, 1.0, 0.0, 0.0], vision_dropout=0.0)
    ros_graph.probe.spin_until(lambda: len(robots) >= 20, 30.0, "20 vision frames")
    clouds = [vision_cloud_from_msg(msg) for msg in robots]
    by_stamp = {}
    for cloud in clouds:
        by_stamp.setdefault(cloud.t_s, []).append(cloud)
    both = [frames for frames in by_stamp.values() if len(frames) == 2]
    assert len(both) >= 5
    for ball, other in both:
        assert (ball.camera_id, ball.camera_m) == (0, pytest.approx((-2.275, 1.525, 4.0), abs=1e-12))
        assert ball.balls.tolist() == [pytest.approx([0.0, 1.0], abs=0.02)] and not len(ball.sightings)
        assert ball.robots[:, :2].tolist() == [[1.0, 0.0]]
        assert (other.camera_id, other.camera_m) == (1, pytest.approx((2.275, 1.525, 4.0), abs=1e-12))
        assert not len(other.balls) and not len(other.robots)
        # the same world frame's ball (its 2 mm noise shared), each camera's own 0.5 mm on top: 10 sigma apart
        assert other.sightings.tolist() == [pytest.approx(ball.balls[0].tolist(), abs=0.01)]
    assert all(len(frames) <= 2 for frames in by_stamp.values())


def test_start_clock_subscribers_holds_the_first_tick_until_time_zero_can_be_seen(ros_graph):
    """With start_clock_subscribers the plant waits for that many /clock readers: the probe, which
    subscribes only after the plant is up, still receives the clock from its very first tick."""
    truth = ros_graph.subscribe(contract.GROUND_TRUTH_BALL.name, Odometry, contract.GROUND_TRUTH_BALL.qos)
    plant = start_plant(ros_graph, controlled=[False], start_clock_subscribers=1, stop_after_s=0.5)
    plant.wait_for_output(r"lockstep pacing", timeout_s=30.0)
    # Longer than the start-up grace (0.1 s): a plant free to start would have run its 0.5 s by now.
    ros_graph.probe.spin_for(2.0)
    assert plant.alive() and not truth
    # deeper than the contract's depth 1, so that the probe keeps every clock it is sent
    clocks = ros_graph.subscribe("/clock", Clock, QoSProfile(depth=100, reliability=contract.QOS_CLOCK.reliability))
    # the plant's exit comes before the probe has taken its last messages: wait for those too
    ros_graph.probe.spin_until(lambda: not plant.alive() and clocks and
                               stamp_to_nanoseconds(clocks[-1].clock) >= 490_000_000, 30.0,
                               "the plant to run its 0.5 s")
    # it ended itself quietly (node_support.end_node), once the probe had acknowledged its last /clock
    assert plant.wait_exit(5.0) == 0 and "FATAL" not in plant.output(), plant.output()
    stamps = [stamp_to_nanoseconds(c.clock) for c in clocks]
    assert stamps[-1] == 500_000_000  # tick 250 of 2 ms: the last clock was not lost with the process
    # time 0 twice: the same stamp again confirms a new time line to the readers' time rule (stamps.StampFilter)
    assert stamps[0] == stamps[1] == 0 < stamps[2]


def test_a_silent_motor_board_is_reported_and_the_plant_goes_on(ros_graph):
    # A fake motor board that answers the first ticks, then falls silent. The plant waits
    # (up to startup_timeout_s) for a second wheel_states reader that never comes, by which
    # time it has discovered the fake, so tick 0 already waits for it.
    events = ros_graph.subscribe("/sim/events", String)
    states = ros_graph.subscribe("/robot_0/wheel_states", JointState, contract.QOS_CONTROL)
    duty_pub = ros_graph.probe.publisher("/robot_0/motor_duty", JointState, contract.QOS_CONTROL)
    plant = start_plant(ros_graph, lockstep_timeout_s=0.3, startup_timeout_s=3.0)
    answered = set()

    def answer_some():
        for m in list(states):
            t = stamp_to_nanoseconds(m.header.stamp)
            if t not in answered and t <= 20_000_000:
                answered.add(t)
                duty_pub.publish(joint_state_msg(t, [f"wheel_{i}" for i in range(4)], effort=[0.0] * 4))
        return any("stalled" in e.data for e in events)

    ros_graph.probe.spin_until(answer_some, 30.0, "a stall report")
    # after the report the plant advances without the silent board
    ros_graph.probe.spin_until(lambda: states and stamp_to_nanoseconds(states[-1].header.stamp) > 100_000_000,
                               30.0, "ticks after the stall")
    duty_pub.publish(joint_state_msg(stamp_to_nanoseconds(states[-1].header.stamp), [f"wheel_{i}" for i in range(4)],
                                     effort=[0.0] * 4))
    ros_graph.probe.spin_until(lambda: any("resumed" in e.data for e in events), 30.0, "a resume report")
    assert plant.alive()


def test_bad_duty_is_rejected_or_clamped_plant_survives(ros_graph):
    # one plant, one robot per kind of bad duty: each robot's warning is throttled on its own
    efforts = {"nan": [math.nan, 0.0, 0.0, 0.0], "short": [0.1, 0.1], "huge": [5.0, -5.0, 0.0, 0.0]}
    plant = start_plant(ros_graph, robot_poses=[0.0, 0.0, 0.0, -1.0, 0.0, 0.0, -2.0, 0.0, 0.0],
                        startup_timeout_s=0.0, pacing="realtime", real_time_factor=1.0)
    plant.wait_for_output(r"plant: 3 robot\(s\)", timeout_s=60.0)
    for i, (bad, effort) in enumerate(efforts.items()):
        duty_pub = ros_graph.probe.wait_for_subscribers(f"/robot_{i}/motor_duty", JointState,
                                                        qos=contract.QOS_CONTROL)
        warning = rf"robot_{i}: " + ("2 duty value\\(s\\) outside .* clamped" if bad == "huge"
                                     else "rejected motor_duty")
        # resent until logged: our writer has matched the plant's reader, which may not have matched it yet
        deadline = time.monotonic() + 15.0
        while True:
            duty_pub.publish(JointState(effort=effort))
            try:
                plant.wait_for_output(warning, timeout_s=0.5)
                break
            except TimeoutError:
                assert time.monotonic() < deadline, f"robot_{i}: no warning for the {bad} duty"
    truths = [ros_graph.subscribe(f"/robot_{i}/ground_truth/odom", Odometry) for i in range(len(efforts))]
    ros_graph.probe.spin_until(lambda: all(len(truth) > 5 for truth in truths), 20.0, "ground truth after bad duty")
    assert all(np.isfinite(odometry_from_msg(m)[1]).all() for truth in truths for m in truth)
    assert plant.alive()


def test_scenario_topics_place_and_kick_and_refuse_off_field(ros_graph):
    plant = start_plant(ros_graph, controlled=[False], pacing="realtime", real_time_factor=1.0,
                        kicker_plates=["curved"])
    events = ros_graph.subscribe("/sim/events", String)
    set_ball = ros_graph.probe.wait_for_subscribers("/sim/set_ball", Odometry)
    # ball at rest touching the robot's dribbler (robot at the origin facing +x)
    set_ball.publish(odometry_msg(0.0, (0.0815 + 0.001, 0.0, 0.0), (0.0, 0.0, 0.0)))
    ros_graph.probe.spin_until(lambda: any("ball placed" in e.data for e in events), 15.0, "ball placed")
    kick = ros_graph.probe.wait_for_subscribers("/robot_0/kick", Float64)
    kick.publish(Float64(data=3.0))
    ros_graph.probe.spin_until(lambda: any("kick 3.00 m/s" in e.data and "fired" in e.data for e in events),
                               15.0, "kick fired")
    truth = ros_graph.subscribe("/ground_truth/ball", Odometry)
    ros_graph.probe.spin_until(lambda: truth and odometry_from_msg(truth[-1])[2][0] > 1.0, 15.0, "ball moving")
    _, _, vel, _ = odometry_from_msg(truth[-1])
    assert abs(math.degrees(math.atan2(vel[1], vel[0]))) < 1.0  # curved plate: straight
    set_ball.publish(odometry_msg(0.0, (40.0, 0.0, 0.0), (0.0, 0.0, 0.0)))
    plant.wait_for_output("rejected /sim/set_ball: .*outside the field walls", timeout_s=15.0)
    set_robot = ros_graph.probe.wait_for_subscribers("/robot_0/sim/set_state", Odometry)
    set_robot.publish(odometry_msg(0.0, (0.0, -9.0, 0.0), (0.0, 0.0, 0.0)))
    plant.wait_for_output("rejected robot_0/sim/set_state: .*outside the field walls", timeout_s=15.0)
    assert plant.alive()


def test_plant_refuses_to_start_with_a_body_off_the_field(ros_graph):
    plant = start_plant(ros_graph, robot_poses=[30.0, 0.0, 0.0])
    assert plant.wait_exit(30.0) == 1
    assert "outside the field walls" in plant.output()


def test_plant_refuses_a_camera_model_its_ros_vision_cannot_apply(ros_graph):
    plant = start_plant(ros_graph, camera_model="erforce")  # vision_output ros: no camera alignment on that path
    assert plant.wait_exit(30.0) == 1
    assert "camera_model 'erforce': its per-camera object offset (0.02 m)" in plant.output()


def test_camera_model_reaches_the_cameras_of_both_outputs():
    """In-process: the node's one CameraRig errs as camera_model says, its quadrants overlap by the preset's band, the
    SSL output encodes that rig's detections and the world's frames carry no shared noise (each camera draws its own);
    by default the bench's rig feeds the ROS views."""
    import rclpy

    from erforce_interfaces.wire.robot_config import FieldConfig
    from erforce_sim.plant_node import PlantNode
    from erforce_sim.ssl_cameras import BENCH_CAMERAS, ERFORCE_REALISTIC, quadrant_cameras

    field = FieldConfig.preset(PlantSetup().field_preset)
    for params, realism in ((["-p", "camera_model:=erforce", "-p", "vision_output:=ssl"], ERFORCE_REALISTIC),
                            ([], BENCH_CAMERAS)):
        rclpy.init(args=["--ros-args", "-p", "ssl_vision_interface:=127.0.0.1", *params])
        node = None
        try:
            node = PlantNode()
            assert node._rig.realism is realism and node._rig.cameras == quadrant_cameras(field, realism.overlap_m)
            assert node.world.vision.params.position_noise_m == (0.0 if realism is ERFORCE_REALISTIC else 0.002)
            if realism is ERFORCE_REALISTIC:
                assert node._ssl.rig is node._rig and node._camera_views is None
            else:
                assert node._camera_views.rig is node._rig and node._ssl is None
        finally:
            if node is not None:
                node.destroy_node()
            rclpy.shutdown()


def test_pacing_changes_take_effect_at_runtime(ros_graph):
    plant = start_plant(ros_graph, controlled=[False], real_time_factor=0.0)
    clocks = ros_graph.subscribe("/clock", Clock, contract.QOS_CLOCK)
    ros_graph.probe.spin_until(lambda: len(clocks) > 5, 30.0, "clock")
    # realtime pacing with real_time_factor 0 is refused (as tested below), so the factor goes first
    assert not ros_graph.probe.set_parameter("/plant", "pacing", "realtime").successful
    assert ros_graph.probe.set_parameter("/plant", "real_time_factor", 0.5).successful
    assert ros_graph.probe.set_parameter("/plant", "pacing", "realtime").successful
    ros_graph.probe.spin_for(0.5)
    t0_sim, t0_wall = stamp_to_nanoseconds(clocks[-1].clock) * 1e-9, time.monotonic()
    ros_graph.probe.spin_for(2.0)
    rate = (stamp_to_nanoseconds(clocks[-1].clock) * 1e-9 - t0_sim) / (time.monotonic() - t0_wall)
    assert 0.35 < rate < 0.65  # half real time, within scheduling jitter on a loaded machine
    assert not ros_graph.probe.set_parameter("/plant", "pacing", "warp").successful
    assert not ros_graph.probe.set_parameter("/plant", "real_time_factor", -1.0).successful
    assert plant.alive()


def test_team_topics_gate_the_ticks_apply_the_duties_and_refuse_what_is_not_a_team_answer(ros_graph):
    """lockstep_topics team: one /team/wheel_states per tick with the controlled robot_0 only (robot_1 has no
    motion control); a fake team_firmware answers on /team/motor_duty, and no tick comes before the previous
    one is answered; the duty reaches the wheels; malformed answers and answers for robots the plant does not
    control are refused with a warning, and the plant goes on."""
    states = ros_graph.subscribe(contract.TEAM_WHEEL_STATES.name, JointState, contract.QOS_CONTROL)
    duty_pub = ros_graph.probe.publisher(contract.TEAM_MOTOR_DUTY.name, JointState, contract.QOS_CONTROL)
    plant = start_plant(ros_graph, robot_poses=[0.0, 0.0, 0.0, 1.0, 1.0, 0.0], controlled=[True, False],
                        lockstep_topics="team", wheel_states_readers=1, lockstep_timeout_s=30.0)
    wheels = [f"wheel_{k}" for k in range(4)]
    robot_0 = contract.team_joint_names([0], wheels)
    answered: list[int] = []

    def answer(t_ns, names=robot_0):
        duty_pub.publish(joint_state_msg(t_ns, names, effort=[0.5] * 4))

    def answer_new_ticks(until_ns):
        for m in list(states):
            t = stamp_to_nanoseconds(m.header.stamp)
            if t not in answered:
                assert not answered or t == answered[-1] + 2_000_000, "a tick before the previous one was answered"
                answered.append(t)
                answer(t)
        return answered and answered[-1] >= until_ns

    ros_graph.probe.spin_until(lambda: answer_new_ticks(100_000_000), 60.0, "100 ms of answered ticks")
    first, last = states[0], states[-1]
    assert list(first.name) == list(contract.team_joint_names([0], wheels))
    assert list(first.velocity) == [0.0] * 4 and all(v > 1.0 for v in last.velocity)  # the duty drove the wheels
    answer(answered[-1], names=["robot_0/wheel_1", "robot_0/wheel_0", "robot_0/wheel_2", "robot_0/wheel_3"])
    plant.wait_for_output("rejected /team/motor_duty", timeout_s=15.0)
    answer(answered[-1], names=contract.team_joint_names([1], wheels))
    plant.wait_for_output("/team/motor_duty for robot_1, which is not a controlled robot", timeout_s=15.0)
    goal_ns = answered[-1] + 20_000_000
    ros_graph.probe.spin_until(lambda: answer_new_ticks(goal_ns), 60.0, "ticks after the refusals")
    assert plant.alive()
