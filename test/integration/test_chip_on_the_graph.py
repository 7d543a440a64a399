"""A chip in our plant, seen through its cameras, in the air on /ball/state; a flat kick never.

The demo graph with vision over real UDP (vision:=ssl, the bridge in the predictor's process): the plant's four
quadrant cameras project the flying ball onto the ground and send each camera's position in the SSL geometry;
ssl_ball_predictor hands the predictor each frame with its camera's position, and the chip detector reconstructs
the flight. Or with the plant's own vision (vision:=ros): the same cameras' views on /vision/robots, each frame with
its camera's point and the other cameras' views as sightings. The chip is launched by /sim/set_ball with a vertical
speed (the plant flies it) from where the ball lay still, inside one camera's quadrant: only the curve of its
projected path tells the flight. Or it is kicked through the robot command path, as the passing game kicks
(kick_angle, then kick): the predictor takes the command as the kicker's word (kick hints) and reports the chip
sooner. The tests of each vision path share one graph (a class each; starting one takes tens of seconds): each
puts the ball where it needs it and waits for it at rest before its kick.
"""

import math
import socket

import pytest
from nav_msgs.msg import Odometry
from std_msgs.msg import Float64, String

from erforce_interfaces.runtime.param_schema import schema_defaults
from erforce_interfaces.wire import contract
from erforce_interfaces.wire.conversions import odometry_from_msg, odometry_height, odometry_msg
from erforce_interfaces.wire.robot_config import RobotConfig
from erforce_sim.demo.demo import LAUNCH_FILE, Director
from erforce_sim.in_process.scenes import KICKER, RECEIVER

pytestmark = pytest.mark.integration

START = (1.0, 1.8)  # in the +x +y camera's quadrant, away from the demo's robots
SPEED_MPS, ANGLE_DEG = 4.0, 60.0  # up at 3.46 m/s: 0.71 s in the air, apex 0.61 m, first touchdown 1.41 m on
G_MPS2 = 9.81
REST_S = 0.5
FLIGHT_S = 2.0 * SPEED_MPS * math.sin(math.radians(ANGLE_DEG)) / G_MPS2
RECEIVER_ASIDE = (-0.5, 0.3, math.pi)  # robot_0's start in demo.launch.yaml: behind every kick of this module


def free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def start_demo(ros_graph, **vision):
    """The demo graph launched and ready: (its Director, the graph, the launch, ball_topics' lists)."""
    launch = ros_graph.start_launch(LAUNCH_FILE, real_time_factor="0.0", output="screen", **vision)
    d = Director(ros_graph.probe.node, RobotConfig(), ros_graph.probe.executor,
                 graph_alive=launch.alive, graph_hint="see the launch output below")
    assert d.spin_until(d.graph_ready, 120.0, "the graph"), launch.output()[-3000:]
    return d, ros_graph, launch, ball_topics(ros_graph.probe)


def demo_for_the_class(ros_graph, **vision):
    """start_demo for the ``demo`` fixture of a class: its tests run one after another on one graph (each puts
    the ball where it needs it and waits for it at rest before its kick), which starts once."""
    demo = start_demo(ros_graph, **vision)
    yield demo
    demo[0].close()


@pytest.fixture
def director(demo):
    """The class's demo graph (its ``demo`` fixture), with the ball topics' lists emptied for this test."""
    for received in demo[3]:
        received.clear()
    return demo


def ball_topics(probe) -> tuple[list, list, list]:
    """What the probe receives on /ball/state, /ball/phase and the plant's ground truth of the ball."""
    return (probe.subscribe(contract.BALL_STATE.name, Odometry, contract.BALL_STATE.qos),
            probe.subscribe(contract.BALL_PHASE.name, String, contract.BALL_PHASE.qos),
            probe.subscribe(contract.GROUND_TRUTH_BALL.name, Odometry, contract.GROUND_TRUTH_BALL.qos))


def rests_at(states: list, xy, within_m: float) -> bool:
    """The predictor has had the ball lying within ``within_m`` of ``xy`` for REST_S (its stamps) on ``states``
    (/ball/state): a chip detector judges one motion at a time, so a placement must be over before a kick."""
    recent = [odometry_from_msg(m) for m in states]
    if not recent or recent[-1][0] - recent[0][0] < REST_S:
        return False
    t_end = recent[-1][0]
    return all(math.hypot(p[0] - xy[0], p[1] - xy[1]) < within_m and math.hypot(v[0], v[1]) < 0.15
               for t, p, v, _ in recent if t >= t_end - REST_S)


def spin_until_or_show(d, graph, states: list, condition, timeout_s: float, what: str) -> None:
    """graph.spin_until, failing with the last five states on /ball/state (``states``) and the newest ground truth
    of the ball and of robot_0 (the Director ``d``'s) when it times out."""
    try:
        graph.spin_until(condition, timeout_s, what)
    except TimeoutError as exc:
        last = [(round(t, 3), *p[:2].round(3), *v[:2].round(3)) for t, p, v, _ in map(odometry_from_msg, states[-5:])]
        d.pump()
        truth = [tuple(round(float(x), 3) for x in rows[-1]) if rows else None
                 for rows in (d.series.ball_truth, d.series.robot_truth)]
        raise AssertionError(f"{exc}; the last states (t, x, y, vx, vy): {last}; the newest ground truth of the ball "
                             f"(t, x, y, vx, vy) {truth[0]}, of robot_0 (t, x, y, yaw, vx, vy, w) {truth[1]}") from None


def place_ball_at_rest(d, graph, topics, xy, within_m: float) -> None:
    """Put robot_0 aside (its catcher may have chased the last ball to where this one goes, or still hold it), then
    the ball at ``xy``, sent again until the plant's ground truth shows it there (a placement published before
    the plant's subscription matched is lost: a command is not kept for a late joiner), and wait until the
    predictor has it at rest there (rests_at); ``topics`` (ball_topics') are emptied after."""
    states, _, truth = topics
    d.place_robot(RECEIVER, RECEIVER_ASIDE)
    d.wait_sim(0.02)
    truth.clear()
    d.place_ball(*xy)

    def placed() -> bool:
        if truth and math.dist(odometry_from_msg(truth[-1])[1][:2], xy) < 0.01:
            return True
        d.place_ball(*xy)
        return False

    graph.spin_until(placed, 60.0, f"the ball placed at {xy} (ground truth)")
    states.clear()
    # a wall-time deadline: on a loaded machine the lockstep graph can take a minute for the half second
    spin_until_or_show(d, graph, states, lambda: rests_at(states, xy, within_m), 120.0,
                       f"the ball at rest at {xy} on /ball/state")
    for received in topics:
        received.clear()


KICKER_POSE = (0.4, 1.6, 0.0)  # in the +x +y quadrant, kicking along +x
KICK_SPEED_MPS, KICK_ANGLE_DEG = 4.0, 45.0  # up at 2.83 m/s: 0.58 s in the air, first touchdown 1.63 m on
KICK_FLIGHT_S = 2.0 * KICK_SPEED_MPS * math.sin(math.radians(KICK_ANGLE_DEG)) / G_MPS2
# From the launch (ground truth) to the first /ball/state with phase chip and z > 0.05 m: the first third of the
# flight (the bench's chip detector with hints needs 0.11-0.18 s; the graph adds its frames' delays).
KICK_DEADLINE_S = KICK_FLIGHT_S / 3.0
# Our plant's vision (vision:=ros), stamped with each capture's time, has no wire and no bridge between the
# cameras and the predictor: from the launch, the first capture after it (one frame period at the plant's
# vision_rate_hz) and then the detection target (0.15 s after the kick).
ROS_KICK_DEADLINE_S = 0.15 + 1.0 / schema_defaults("erforce_sim", "plant")["vision_rate_hz"]
KICKS = 3


def kicked_ball(d, graph, topics, kick_angle, pose, speed_mps: float, angle_deg: float, watch_s: float):
    """Kick the ball from the kicker at ``pose`` at ``angle_deg`` (sent first on ``kick_angle``, a
    kick_angle_publisher) and watch ``watch_s`` of the plant's time from its launch, or until a chip shows: (the
    launch's time, the first state's stamp with phase chip and z > 0.05 m or None, the heights on /ball/state, the
    phases); ``topics``: ball_topics'."""
    states, phases, truth = topics
    ball = d.ball_at_kicker(pose)
    d.place_robot(KICKER, pose)
    d.wait_sim(0.3)
    place_ball_at_rest(d, graph, topics, ball, 0.03)
    kick_angle.publish(Float64(data=angle_deg))
    d.kick.publish(Float64(data=speed_mps))

    def launched_s() -> float | None:  # the plant's first tick with the ball in the air or moving (ground truth)
        moving = [t for t, _p, v, _ in map(odometry_from_msg, truth) if math.hypot(v[0], v[1]) > 0.5]
        up = [odometry_from_msg(m)[0] for m in truth if odometry_height(m)[0] > 0.0]
        return min(moving + up) if moving or up else None

    graph.spin_until(lambda: launched_s() is not None, 30.0, "the kicker kicking the ball (ground truth)")
    t_launch = launched_s()

    def seen_s() -> float | None:  # the first state with the ball above 0.05 m, once a phase chip came
        up = [odometry_from_msg(m)[0] for m in states if odometry_height(m)[0] > 0.05]
        return min(up) if up and any(m.data == "chip" for m in phases) else None

    def truth_after(dt_s: float) -> bool:
        return bool(truth) and odometry_from_msg(truth[-1])[0] > t_launch + dt_s

    graph.spin_until(lambda: seen_s() is not None or truth_after(watch_s), 60.0,
                     f"a chip on /ball/state, or {watch_s} s after the launch")
    t_seen = seen_s()
    heights = [odometry_height(m)[0] for m in states if odometry_from_msg(m)[0] <= t_launch + watch_s]
    kinds = [m.data for m in phases]
    graph.spin_until(lambda: truth_after(watch_s), 60.0, "the watch over")
    return t_launch, t_seen, heights, kinds


def kick_angle_publisher(graph):
    """The probe's publisher of the kicker's kick_angle, once the plant and the predictor hear it (a command is not
    kept for a late joiner): a predictor that missed it takes the kick for a flat one, and a flat hint holds a chip
    back; a plant that missed it kicks at the angle it had."""
    return graph.probe.wait_for_subscribers(contract.KICK_ANGLE.for_robot(KICKER), Float64, count=2, timeout_s=30.0,
                                            qos=contract.KICK_ANGLE.qos)


def kicked_chip_delays(d, graph, topics) -> list[float]:
    """KICKS chips kicked by the robot as the passing game kicks; each one's delay from the launch to its first
    state in the air on /ball/state."""
    kick_angle = kick_angle_publisher(graph)
    delays = []
    for _ in range(KICKS):
        t_launch, t_seen, _, _ = kicked_ball(d, graph, topics, kick_angle, KICKER_POSE, KICK_SPEED_MPS, KICK_ANGLE_DEG,
                                             KICK_FLIGHT_S + 0.5)
        assert t_seen is not None, "the chip never showed on /ball/state in the air"
        delays.append(t_seen - t_launch)
    print(f"chip on /ball/state after the launch [s]: {[round(x, 3) for x in delays]}")
    return delays


FLAT_POSE = (0.4, 0.0, 0.0)  # kicking along y = 0, where cameras 1 and 3 overlap: two views of every capture
FLAT_WATCH_S = 1.0  # 4 m/s along +x: about 3 m rolled, short of the wall at x = 4.8 m


OVERLAP_START = (1.0, 0.0)  # on the line y = 0, where cameras 1 (+y) and 3 (-y) overlap (|y| <= 0.25 m)
OVERLAP_SPEED_MPS, OVERLAP_ANGLE_DEG = 3.0, 45.0  # along +x: apex 0.23 m, 0.43 s in the air; both cameras see it
OVERLAP_FLIGHT_S = 2.0 * OVERLAP_SPEED_MPS * math.sin(math.radians(OVERLAP_ANGLE_DEG)) / G_MPS2
OVERLAP_CHIPS = 3


def truth_height_at(truth: list, t_s: float) -> float:
    """The plant's true height of the ball at the ground-truth message nearest ``t_s``."""
    return odometry_height(min(truth, key=lambda m: abs(odometry_from_msg(m)[0] - t_s)))[0]


class TestOnSslVision:
    """The demo graph with SSL-Vision from the plant's cameras, the bridge in the predictor's process."""

    @pytest.fixture(scope="class")
    @classmethod
    def demo(cls, class_ros_graph):
        yield from demo_for_the_class(class_ros_graph, vision="ssl", ssl_vision_port=str(free_udp_port()),
                                      ssl_vision_process="predictor")

    def test_a_chip_in_the_plant_shows_on_ball_state_in_the_air(self, director):
        d, graph, launch, topics = director
        states, phases, truth = topics
        place_ball_at_rest(d, graph, topics, START, 0.02)  # the placement, a motion of its own, is over before the kick
        v_ground = SPEED_MPS * math.cos(math.radians(ANGLE_DEG))
        chip = odometry_msg(0.0, (*START, 0.0), (v_ground, 0.0, 0.0))
        chip.twist.twist.linear.z = SPEED_MPS * math.sin(math.radians(ANGLE_DEG))
        d.set_ball.publish(chip)

        def launched_s() -> float | None:  # the plant's first tick with the ball in the air (ground truth)
            up = [odometry_from_msg(m)[0] for m in truth if odometry_height(m)[0] > 0.0]
            return min(up) if up else None

        def in_the_air() -> bool:
            return any(odometry_height(m)[0] > 0.05 for m in states) and any(m.data == "chip" for m in phases)

        graph.spin_until(in_the_air, 60.0, "a chip with z > 0.05 m on /ball/state and phase chip")
        t_launch = launched_s()
        assert t_launch is not None, "the plant never flew the ball"
        first = next(m for m in states if odometry_height(m)[0] > 0.05)
        t_seen = odometry_from_msg(first)[0]
        assert t_seen - t_launch < FLIGHT_S, "seen in the air only after the first touchdown"
        # a height the flight can have: between the ground and its apex
        apex_m = (SPEED_MPS * math.sin(math.radians(ANGLE_DEG))) ** 2 / (2.0 * G_MPS2)
        tau = t_seen - t_launch
        z_true = SPEED_MPS * math.sin(math.radians(ANGLE_DEG)) * tau - 0.5 * G_MPS2 * tau * tau
        z_var = first.pose.covariance[14]  # the height's variance (row and column z)
        seen = f"z {odometry_height(first)[0]:.3f} m (true {z_true:.3f} m), its standard error {math.sqrt(z_var):.3f} m"
        print(f"the chip on /ball/state {tau:.3f} s after the launch: {seen}")
        assert 0.05 < odometry_height(first)[0] <= apex_m + 0.05, seen
        assert 0.0 < z_var < 1.0 and first.twist.covariance[14] > 0.0, seen  # a chip's height comes with its variance
        assert "consumer failed" not in launch.output()

    def test_a_chip_kicked_by_a_robot_shows_on_ball_state_within_the_deadline(self, director):
        d, graph, launch, topics = director
        delays = kicked_chip_delays(d, graph, topics)
        assert max(delays) < KICK_DEADLINE_S, f"delays {delays} s, deadline {KICK_DEADLINE_S:.3f} s"
        assert "consumer failed" not in launch.output()

    def test_a_chip_where_two_cameras_overlap_shows_with_its_triangulated_height(self, director):
        """Launched (/sim/set_ball) along the overlap of two cameras, the chip is seen by both at each capture;
        their disagreement is its height (two rays), which only the graph's camera points and sightings bring to
        the predictor: the first state in the air comes early in the flight with a height near the truth's."""
        d, graph, launch, topics = director
        states, phases, truth = topics
        v_ground = OVERLAP_SPEED_MPS * math.cos(math.radians(OVERLAP_ANGLE_DEG))
        vz = OVERLAP_SPEED_MPS * math.sin(math.radians(OVERLAP_ANGLE_DEG))
        seen = []
        for _ in range(OVERLAP_CHIPS):
            place_ball_at_rest(d, graph, topics, OVERLAP_START, 0.02)
            chip = odometry_msg(0.0, (*OVERLAP_START, 0.0), (v_ground, 0.0, 0.0))
            chip.twist.twist.linear.z = vz
            d.set_ball.publish(chip)

            def launched_s() -> float | None:
                up = [odometry_from_msg(m)[0] for m in truth if odometry_height(m)[0] > 0.0]
                return min(up) if up else None

            def seen_s() -> float | None:
                up = [odometry_from_msg(m)[0] for m in states if odometry_height(m)[0] > 0.05]
                return min(up) if up and any(m.data == "chip" for m in phases) else None

            def truth_after(dt_s: float) -> bool:
                t0 = launched_s()
                return t0 is not None and odometry_from_msg(truth[-1])[0] > t0 + dt_s

            graph.spin_until(lambda: seen_s() is not None or truth_after(1.0), 60.0,
                             "a chip on /ball/state, or 1 s after the launch")
            t_launch, t_seen = launched_s(), seen_s()
            assert t_seen is not None, "the chip never showed on /ball/state in the air"
            first = next(m for m in states if odometry_from_msg(m)[0] == t_seen)
            seen.append((t_seen - t_launch, odometry_height(first)[0], truth_height_at(truth, t_seen)))
            graph.spin_until(lambda: truth_after(OVERLAP_FLIGHT_S + 0.5), 60.0, "the chip landed")
        print("chip in the overlap: (delay after the launch [s], first height [m], true height then [m]):",
              [tuple(round(v, 3) for v in s) for s in seen])
        assert max(s[0] for s in seen) < OVERLAP_FLIGHT_S / 2.0
        assert all(abs(z - z_true) < 0.05 for _, z, z_true in seen)
        assert "consumer failed" not in launch.output()


class TestOnThePlantsRosVision:
    """The demo graph with the plant's own vision topics (vision:=ros)."""

    @pytest.fixture(scope="class")
    @classmethod
    def demo(cls, class_ros_graph):
        yield from demo_for_the_class(class_ros_graph, vision="ros")

    def test_a_kicked_chip_shows_on_ball_state_within_the_deadline(self, director):
        """The plant's /vision/robots names the camera of each ball: the predictor reads the chip in flight."""
        d, graph, _, topics = director
        delays = kicked_chip_delays(d, graph, topics)
        assert max(delays) < ROS_KICK_DEADLINE_S, f"delays {delays} s, deadline {ROS_KICK_DEADLINE_S:.3f} s"

    def test_a_flat_kick_seen_by_two_cameras_is_never_in_the_air(self, director):
        """Kicked flat (kick_angle 0, what the plant and the predictor hold until told otherwise: an earlier test's
        chip angle is taken back first), along the overlap of two cameras, whose views of the rolling ball differ
        by their noise only: never phase chip, never a height on /ball/state."""
        d, graph, _, topics = director
        kick_angle = kick_angle_publisher(graph)
        for _ in range(KICKS):
            _, t_seen, heights, kinds = kicked_ball(d, graph, topics, kick_angle, FLAT_POSE, KICK_SPEED_MPS, 0.0,
                                                    FLAT_WATCH_S)
            assert t_seen is None and "chip" not in kinds and heights and max(heights) == 0.0, (t_seen, kinds)
            assert {"sliding", "rolling"} & set(kinds), kinds  # it was seen moving
