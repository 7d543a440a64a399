"""The wire contract and the message conversions."""

import math
import re
import struct
from pathlib import Path

import numpy as np
import pytest
from builtin_interfaces.msg import Time
from geometry_msgs.msg import PointStamped, PoseStamped, Twist
from hypothesis import given, settings
from hypothesis import strategies as st
from nav_msgs.msg import Odometry
from rclpy.serialization import deserialize_message, serialize_message
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64, Float64MultiArray, Header

from erforce_interfaces.tools import messages as msgs
from erforce_interfaces.wire import contract as c
from erforce_interfaces.wire import conversions as conv
from erforce_interfaces.wire import tables
from erforce_interfaces.wire.robot_config import FieldConfig, RobotConfig

REFERENCE = Path(__file__).resolve().parents[2] / "docs" / "reference.md"


def test_reference_generated_sections_are_current():
    from erforce_interfaces.tools import docs

    assert docs.REFERENCE == REFERENCE
    text = REFERENCE.read_text()
    for name in docs.SECTIONS:
        assert f"<!-- {name}:begin -->" in text, name
    assert docs.render(text) == text, (
        "docs/reference.md is stale: run `./run exec python -m erforce_interfaces.tools.docs`"
    )
    assert c.topic_table_markdown() in text
    assert docs.ROBOT_YAML.read_text() == docs.robot_yaml_text(), (
        "config/robot.yaml is stale: run `./run exec python -m erforce_interfaces.tools.docs`"
    )


def test_topic_names_are_valid_and_unique():
    names = [t.name for t in c.TOPICS]
    assert len(names) == len(set(names))
    for name in names:
        assert re.fullmatch(r"/?[a-z][a-z0-9_]*(/[a-z][a-z0-9_]*)*", name), name


def test_per_robot_topics_resolve_under_the_robot_namespace():
    assert c.CMD_VEL.for_robot(3) == "/robot_3/cmd_vel"
    assert c.GROUND_TRUTH_ODOM.for_robot(0) == "/robot_0/ground_truth/odom"
    with pytest.raises(ValueError):
        c.CLOCK.for_robot(0)
    with pytest.raises(ValueError):
        c.robot_namespace(-1)


def test_robot_id_of_namespace_inverts_robot_namespace():
    for i in (0, 3, 17):
        assert c.robot_id_of_namespace("/" + c.robot_namespace(i)) == i
        assert c.robot_id_of_namespace(c.robot_namespace(i)) == i
    for other in ("/", "", "/robot_", "/robot_x", "/robot_-1", "/team/robot_1", "/robot_1/x", "/robot_١"):
        assert c.robot_id_of_namespace(other) is None, other


def test_qos_vision_is_best_effort_and_commands_reliable():
    from rclpy.qos import ReliabilityPolicy

    assert c.VISION_BALL.qos.reliability == ReliabilityPolicy.BEST_EFFORT
    assert c.VISION_POSE.qos.reliability == ReliabilityPolicy.BEST_EFFORT
    for t in (c.CMD_VEL, c.KICK, c.MOTOR_DUTY, c.WHEEL_SETPOINTS, c.SIM_SET_BALL):
        assert t.qos.reliability == ReliabilityPolicy.RELIABLE, t.name


def test_type_names_use_the_ros_interface_form():
    assert c.CMD_VEL.type_name == "geometry_msgs/msg/Twist"
    assert c.CLOCK.type_name == "rosgraph_msgs/msg/Clock"


@given(st.floats(-math.pi, math.pi))
def test_yaw_quaternion_round_trip(yaw):
    assert conv.yaw_from_quaternion(conv.quaternion_from_yaw(yaw)) == pytest.approx(yaw, abs=1e-12)


def test_stamp_round_trip_is_exact_in_nanoseconds():
    stamp = conv.nanoseconds_to_stamp(12_345_678_901)
    assert (stamp.sec, stamp.nanosec) == (12, 345_678_901)
    assert conv.stamp_to_nanoseconds(stamp) == 12_345_678_901
    assert conv.stamp_to_seconds(conv.seconds_to_stamp(1.5)) == 1.5


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf, 1e9])
def test_twist_rejects_non_finite_and_huge(bad):
    msg = Twist()
    msg.linear.y = bad
    with pytest.raises(conv.ConversionError, match="linear.y"):
        conv.twist_from_msg(msg)


def test_twist_planar_values():
    msg = conv.twist_msg([1.0, -0.5, 2.0])
    assert conv.twist_from_msg(msg).tolist() == [1.0, -0.5, 2.0]
    with pytest.raises(conv.ConversionError):
        conv.twist_msg([math.nan, 0.0, 0.0])


def test_point_and_pose_reject_nan():
    msg = PointStamped()
    msg.point.x = math.nan
    with pytest.raises(conv.ConversionError, match="point.x"):
        conv.point_from_msg(msg)
    pose = PoseStamped()
    pose.pose.orientation.w = 0.0  # zero quaternion is no orientation
    with pytest.raises(conv.ConversionError, match="quaternion"):
        conv.pose2d_from_msg(pose)


def test_joint_state_length_names_and_finiteness():
    msg = msgs.joint_state_msg(5_000_000, ["wheel_0", "wheel_1", "wheel_2"], velocity=[1.0, 2.0, 3.0],
                               effort=[0.1, 0.2, 0.3])
    t_ns, speeds, currents = conv.wheel_states_from_msg(msg, 3)
    assert t_ns == 5_000_000 and speeds.tolist() == [1.0, 2.0, 3.0] and currents.tolist() == [0.1, 0.2, 0.3]
    with pytest.raises(conv.ConversionError, match="4 entries, expected 3|expected 3"):
        conv.joint_state_from_msg(JointState(velocity=[1.0, 2.0, 3.0, 4.0]), 3, "velocity")
    with pytest.raises(conv.ConversionError, match="names"):
        conv.joint_state_from_msg(JointState(name=["b", "a", "c"], velocity=[1.0, 2.0, 3.0]), 3, "velocity")
    with pytest.raises(conv.ConversionError, match=r"velocity\[1\]"):
        conv.joint_state_from_msg(JointState(velocity=[1.0, math.nan, 3.0]), 3, "velocity")
    with pytest.raises(conv.ConversionError):
        msgs.joint_state_msg(0, ["wheel_0"], velocity=[math.inf])


# A JointState as rmw_fastrtps serializes it (plain CDR, little endian), by hand: the 4-byte
# encapsulation header, then from payload offset 0: stamp (sec, nanosec); frame_id (length 1,
# "\0", 3 bytes padding); 4 names ("wheel_k\0": length 8, no padding); position: count 0 at 68;
# velocity: count 4 at 72, padding to 80, 4 doubles; effort: count 4 at 112, padding to 120, 4 doubles.
def _hand_serialized_wheel_state(sec, nanosec, velocity, effort) -> bytes:
    out = b"\x00\x01\x00\x00" + struct.pack("<iI", sec, nanosec) + struct.pack("<I", 1) + b"\x00" + bytes(3)
    out += struct.pack("<I", 4) + b"".join(struct.pack("<I", 8) + f"wheel_{k}".encode() + b"\x00" for k in range(4))
    out += struct.pack("<I", 0) + struct.pack("<I", 4) + bytes(4) + struct.pack("<4d", *velocity)
    return out + struct.pack("<I", 4) + bytes(4) + struct.pack("<4d", *effort)


def test_serialized_joint_state_matches_a_hand_made_layout():
    names = [f"wheel_{k}" for k in range(4)]
    velocity, effort = [1.5, -2.0, 0.0, 1e-3], [0.25, 0.5, -0.75, 1.0]
    hand = _hand_serialized_wheel_state(3, 500, velocity, effort)
    assert len(hand) == 4 + 152
    assert conv.joint_state_cdr(3_000_000_500, names, velocity=velocity, effort=effort) == hand
    t_ns, speeds, currents = conv.wheel_states_from_msg(hand, 4)
    assert t_ns == 3_000_000_500 and speeds.tolist() == velocity and currents.tolist() == effort
    # rclpy's own serializer agrees on every byte but the padding, which it leaves uninitialized
    reference = serialize_message(msgs.joint_state_msg(3_000_000_500, names, velocity=velocity, effort=effort))
    padding = {17, 18, 19, 80, 81, 82, 83, 120, 121, 122, 123}  # file offsets (payload offset + 4)
    assert len(reference) >= len(hand)
    assert [b for i, b in enumerate(reference[: len(hand)]) if i not in padding] == [
        b for i, b in enumerate(hand) if i not in padding]


_any_floats = st.lists(st.floats(width=64), max_size=6)  # NaN, inf and huge values included
# a ROS string ends at its first NUL
_ros_text = st.text(st.characters(codec="utf-8", exclude_characters="\x00"), max_size=12)


@settings(max_examples=300, deadline=None)
@given(names=st.lists(st.text(max_size=10), max_size=5), frame=st.text(max_size=9),
       position=_any_floats, velocity=_any_floats, effort=_any_floats,
       sec=st.integers(-(2**31), 2**31 - 1), nanosec=st.integers(0, 2**32 - 1), num_joints=st.integers(0, 5))
def test_serialized_and_message_forms_are_read_alike(names, frame, position, velocity, effort, sec, nanosec,
                                                      num_joints):
    """Whatever rclpy serializes, the byte reader accepts exactly what the message reader accepts,
    with the same values, or rejects it as well (a ConversionError, never another exception)."""
    msg = JointState(header=Header(stamp=Time(sec=sec, nanosec=nanosec), frame_id=frame), name=names,
                     position=position, velocity=velocity, effort=effort)
    data = serialize_message(msg)
    for field in ("position", "velocity", "effort"):
        outcomes = []
        for form in (msg, data):
            try:
                t_ns, values = conv.joint_state_from_msg(form, num_joints, field)
                outcomes.append((t_ns, values.tolist()))
            except conv.ConversionError:
                outcomes.append("rejected")
        assert outcomes[0] == outcomes[1], field


@settings(max_examples=200, deadline=None)
@given(t_ns=st.integers(-(2**31) * 10**9, 2**31 * 10**9 - 1),
       values=st.lists(st.floats(-1e3, 1e3), min_size=1, max_size=6), with_effort=st.booleans())
def test_serialized_builder_round_trips_through_rclpy(t_ns, values, with_effort):
    names = [f"wheel_{k}" for k in range(len(values))]
    effort = [v / 2 for v in values] if with_effort else None
    data = conv.joint_state_cdr(t_ns, names, velocity=values, effort=effort)
    assert deserialize_message(data, JointState) == msgs.joint_state_msg(t_ns, names, velocity=values, effort=effort)


def test_serialized_builder_refuses_what_the_message_builder_refuses():
    for bad in ([math.nan, 0.0], [math.inf, 0.0], [-math.inf, 0.0], [2e3, 0.0], [0.0, -2e3], [0.0]):
        with pytest.raises(conv.ConversionError):
            msgs.joint_state_msg(0, ["wheel_0", "wheel_1"], velocity=bad)
        with pytest.raises(conv.ConversionError):
            conv.joint_state_cdr(0, ["wheel_0", "wheel_1"], velocity=bad)
    before_1970 = conv.joint_state_cdr(-1, ["wheel_0"], effort=[0.0])  # a valid Time, as in the message form
    assert deserialize_message(before_1970, JointState) == msgs.joint_state_msg(-1, ["wheel_0"], effort=[0.0])
    for build in (msgs.joint_state_msg, conv.joint_state_cdr):  # beyond int32 seconds (year 2038)
        with pytest.raises(conv.ConversionError, match="int32"):
            build(2**31 * 10**9, ["wheel_0"], effort=[0.0])


def test_malformed_bytes_are_a_conversion_error():
    good = _hand_serialized_wheel_state(1, 2, [1.0] * 4, [0.5] * 4)
    for cut in range(len(good)):  # every truncation
        with pytest.raises(conv.ConversionError):
            conv.wheel_states_from_msg(good[:cut], 4)
    big_endian = b"\x00\x00" + good[2:]
    huge_count = good[:20] + struct.pack("<I", 2**31) + good[24:]  # the name count
    for bad in (big_endian, huge_count, b"", bytes(3)):
        with pytest.raises(conv.ConversionError):
            conv.wheel_states_from_msg(bad, 4)


@settings(max_examples=300, deadline=None)
@given(garbage=st.binary(max_size=200))
def test_random_bytes_never_raise_anything_but_a_conversion_error(garbage):
    for data in (garbage, b"\x00\x01\x00\x00" + garbage):
        try:
            conv.wheel_states_from_msg(data, 4)
        except conv.ConversionError:
            pass


# A team-level JointState by hand (contract: /team/wheel_states): robots 3 and 5 with two wheels each.
# Payload offsets: stamp 0..7, frame_id "" (length 1) at 8, names count at 16, four names of 16 bytes with
# their NUL ("robot_3/wheel_0") each after its length (20, 40, 60, 80), position count 0 at 100, velocity
# count at 104, padding 108..111, doubles from 112; effort count at 144, padding, doubles from 152.
def _hand_serialized_team_state(sec, nanosec, velocity, effort):
    names = b"".join(struct.pack("<I", 16) + f"robot_{r}/wheel_{k}".encode() + b"\x00" for r in (3, 5) for k in (0, 1))
    payload = (struct.pack("<iI", sec, nanosec) + struct.pack("<I", 1) + bytes(4) + struct.pack("<I", 4) + names
               + struct.pack("<I", 0) + struct.pack("<I", 4) + bytes(4) + struct.pack("<4d", *velocity)
               + struct.pack("<I", 4) + bytes(4) + struct.pack("<4d", *effort))
    assert len(payload) == 184
    return b"\x00\x01\x00\x00" + payload


def test_team_joint_names_are_robot_then_wheel():
    assert c.team_joint_names([3, 5], ("wheel_0", "wheel_1")) == (
        "robot_3/wheel_0", "robot_3/wheel_1", "robot_5/wheel_0", "robot_5/wheel_1")


def test_serialized_team_state_matches_a_hand_made_layout_and_reads_back_per_robot():
    velocity, effort = [1.5, -2.0, 0.0, 1e-3], [0.25, 0.5, -0.75, 1.0]
    hand = _hand_serialized_team_state(3, 500, velocity, effort)
    built = conv.team_joint_state_cdr(3_000_000_500, [3, 5], ("wheel_0", "wheel_1"),
                                      velocity=np.reshape(velocity, (2, 2)), effort=np.reshape(effort, (2, 2)))
    assert built == hand
    msg = deserialize_message(hand, JointState)  # rclpy reads our bytes as the joints we meant
    assert list(msg.name) == ["robot_3/wheel_0", "robot_3/wheel_1", "robot_5/wheel_0", "robot_5/wheel_1"]
    assert list(msg.velocity) == velocity and list(msg.effort) == effort
    for form in (hand, hand, msg):  # bytes twice: the second read takes the remembered names block
        t_ns, ids, (speeds, currents) = conv.team_joint_state_from_msg(form, 2, ("velocity", "effort"))
        assert t_ns == 3_000_000_500 and ids == (3, 5)
        assert speeds.tolist() == [[1.5, -2.0], [0.0, 1e-3]] and currents.tolist() == [[0.25, 0.5], [-0.75, 1.0]]


def test_a_team_state_with_a_frame_id_is_read_like_the_message():
    msg = JointState(header=Header(stamp=Time(sec=1, nanosec=2), frame_id="somewhere"),
                     name=list(c.team_joint_names([0, 7], ("wheel_0",))), effort=[0.5, -0.5])
    for form in (serialize_message(msg), msg):
        t_ns, ids, (duty,) = conv.team_joint_state_from_msg(form, 1, ("effort",))
        assert (t_ns, ids, duty.tolist()) == (1_000_000_002, (0, 7), [[0.5], [-0.5]])


@pytest.mark.parametrize("names", [
    ["robot_3/wheel_1", "robot_3/wheel_0"],  # wheel order
    ["robot_5/wheel_0", "robot_5/wheel_1", "robot_3/wheel_0", "robot_3/wheel_1"],  # robot order
    ["robot_3/wheel_0", "robot_3/wheel_1", "robot_3/wheel_0", "robot_3/wheel_1"],  # a robot twice
    ["robot_3/wheel_0"],  # half a robot
    ["opponent_3/wheel_0", "opponent_3/wheel_1"], ["robot_x/wheel_0", "robot_x/wheel_1"], ["wheel_0", "wheel_1"],
])
def test_team_state_names_must_be_robots_in_order_with_all_their_wheels(names):
    msg = JointState(name=names, effort=[0.0] * len(names))
    for form in (msg, serialize_message(msg)):
        with pytest.raises(conv.ConversionError, match="joint name"):
            conv.team_joint_state_from_msg(form, 2, ("effort",))


def test_the_opponents_team_state_names_its_robots_opponent_id_and_is_no_state_of_ours():
    """The same message for the opponents' lockstep topics: joints opponent_<id>/wheel_<k>, read back with the
    opponents' Team; each team refuses the other's names, also once a names block is remembered."""
    wheels = ("wheel_0", "wheel_1")
    data = conv.team_joint_state_cdr(2_000_000, [0, 2], wheels, effort=np.array([[0.5, -0.5], [0.25, 0.0]]),
                                     team=c.OPPONENTS)
    msg = deserialize_message(data, JointState)
    assert list(msg.name) == ["opponent_0/wheel_0", "opponent_0/wheel_1", "opponent_2/wheel_0", "opponent_2/wheel_1"]
    assert list(msg.name) == list(c.OPPONENTS.joint_names([0, 2], wheels))
    for form in (data, data, msg):
        t_ns, ids, (duty,) = conv.team_joint_state_from_msg(form, 2, ("effort",), team=c.OPPONENTS)
        assert (t_ns, ids, duty.tolist()) == (2_000_000, (0, 2), [[0.5, -0.5], [0.25, 0.0]])
        with pytest.raises(conv.ConversionError, match="is not robot_<id>/wheel_<k>"):
            conv.team_joint_state_from_msg(form, 2, ("effort",))
    ours = conv.team_joint_state_cdr(2_000_000, [0, 2], wheels, effort=np.zeros((2, 2)))
    conv.team_joint_state_from_msg(ours, 2, ("effort",))  # remembered as ours
    with pytest.raises(conv.ConversionError, match="is not opponent_<id>/wheel_<k>"):
        conv.team_joint_state_from_msg(ours, 2, ("effort",), team=c.OPPONENTS)


def test_the_field_state_has_our_joints_then_the_opponents_in_a_hand_made_layout():
    """/field/wheel_states: robot_3's two wheels, then opponent_0's (string lengths 16 and 19 with the NUL), built
    by hand from the JointState fields; read back as (ours, theirs) ids with our rows first."""
    names = [b"robot_3/wheel_0", b"robot_3/wheel_1", b"opponent_0/wheel_0", b"opponent_0/wheel_1"]
    block = b""
    for name in names:  # each string at a multiple of 4 of the payload: the names start at payload offset 12
        block += bytes(-(12 + len(block)) % 4) + struct.pack("<I", len(name) + 1) + name + b"\x00"
    head = struct.pack("<iI", 2, 7) + struct.pack("<I", 1) + bytes(4) + struct.pack("<I", 4) + block
    head += bytes(-len(head) % 4) + struct.pack("<I", 0) + struct.pack("<I", 0)  # position, velocity: empty
    effort = [0.5, -0.25, 1.0, -1.0]
    head += struct.pack("<I", 4)
    hand = b"\x00\x01\x00\x00" + head + bytes(-len(head) % 8) + struct.pack("<4d", *effort)
    built = conv.field_joint_state_cdr(2_000_000_007, ([3], [0]), ("wheel_0", "wheel_1"),
                                       effort=np.reshape(effort, (2, 2)))
    assert built == hand
    assert list(deserialize_message(hand, JointState).name) == [n.decode() for n in names]
    assert c.field_joint_names(([3], [0]), ("wheel_0", "wheel_1")) == tuple(n.decode() for n in names)
    for form in (hand, hand, deserialize_message(hand, JointState)):  # bytes twice: the names block remembered
        t_ns, ids, (duty,) = conv.field_joint_state_from_msg(form, 2, ("effort",))
        assert (t_ns, ids, duty.tolist()) == (2_000_000_007, ((3,), (0,)), [[0.5, -0.25], [1.0, -1.0]])
    ours_only = conv.field_joint_state_cdr(0, ([0, 2], []), ("wheel_0",), effort=np.zeros((2, 1)))
    assert conv.field_joint_state_from_msg(ours_only, 1, ("effort",))[1] == ((0, 2), ())
    theirs_only = conv.field_joint_state_cdr(0, ([], [1]), ("wheel_0",), effort=np.zeros((1, 1)))
    assert conv.field_joint_state_from_msg(theirs_only, 1, ("effort",))[1] == ((), (1,))


@pytest.mark.parametrize("names", [
    ["opponent_0/wheel_0", "robot_3/wheel_0"],  # the opponents before ours
    ["robot_3/wheel_0", "opponent_1/wheel_0", "opponent_0/wheel_0"],  # opponents' order
    ["robot_3/wheel_0", "robot_x/wheel_0"], ["robot_3/wheel_0", "wheel_0"],
])
def test_field_state_names_must_be_ours_then_the_opponents_each_in_order(names):
    msg = JointState(name=names, effort=[0.0] * len(names))
    for form in (msg, serialize_message(msg)):
        with pytest.raises(conv.ConversionError, match="joint name"):
            conv.field_joint_state_from_msg(form, 1, ("effort",))


def test_each_team_has_its_namespaces_frames_and_lockstep_topics():
    assert (c.OURS.topic(c.ODOM, 3), c.OPPONENTS.topic(c.ODOM, 3)) == ("/robot_3/odom", "/opponent_3/odom")
    assert (c.OURS.frame(0), c.OPPONENTS.frame(0)) == ("robot_0/base_link", "opponent_0/base_link")
    assert c.OURS.lockstep_topic(c.TEAM_WHEEL_STATES) == c.TEAM_WHEEL_STATES.name == "/team/wheel_states"
    assert c.OPPONENTS.lockstep_topic(c.TEAM_MOTOR_DUTY) == "/opponent_team/motor_duty"
    assert c.topic_of_name("/opponent_team/motor_duty") is c.TEAM_MOTOR_DUTY
    assert (c.OPPONENTS.id_of_namespace("/opponent_12"), c.OPPONENTS.id_of_namespace("robot_12")) == (12, None)
    assert c.TEAMS == {"ours": c.OURS, "opponents": c.OPPONENTS} and c.OURS.code != c.OPPONENTS.code
    for bad in (lambda: c.OPPONENTS.topic(c.CLOCK, 0), lambda: c.OPPONENTS.namespace(-1),
                lambda: c.OPPONENTS.lockstep_topic(c.ODOM)):
        with pytest.raises(ValueError):
            bad()


def test_team_state_values_are_checked_both_ways():
    ok = np.zeros((2, 2))
    for bad in (math.nan, math.inf, 2e3):
        values = ok.copy()
        values[1, 0] = bad
        with pytest.raises(conv.ConversionError, match="effort"):
            conv.team_joint_state_cdr(0, [0, 1], ("wheel_0", "wheel_1"), effort=values)
        msg = JointState(name=list(c.team_joint_names([0, 1], ("wheel_0", "wheel_1"))), effort=values.ravel().tolist())
        for form in (msg, serialize_message(msg)):
            with pytest.raises(conv.ConversionError, match="effort"):
                conv.team_joint_state_from_msg(form, 2, ("effort",))
    with pytest.raises(conv.ConversionError, match="expected 4"):
        conv.team_joint_state_cdr(0, [0, 1], ("wheel_0", "wheel_1"), effort=np.zeros(3))
    with pytest.raises(conv.ConversionError, match="increasing"):
        conv.team_joint_state_cdr(0, [1, 0], ("wheel_0", "wheel_1"), effort=ok)
    saturated = conv.team_joint_state_cdr(0, [0, 1], ("wheel_0", "wheel_1"), effort=[[5e3, 0], [0, -5e3]],
                                          saturate=True)
    assert list(deserialize_message(saturated, JointState).effort) == [1e3, 0.0, 0.0, -1e3]
    short = JointState(name=list(c.team_joint_names([0, 1], ("wheel_0", "wheel_1"))), effort=[0.0] * 3)
    for form in (short, serialize_message(short)):
        with pytest.raises(conv.ConversionError, match="expected 4"):
            conv.team_joint_state_from_msg(form, 2, ("effort",))


def test_malformed_team_bytes_are_a_conversion_error():
    good = _hand_serialized_team_state(1, 2, [1.0] * 4, [0.5] * 4)
    conv.team_joint_state_from_msg(good, 2, ("velocity", "effort"))  # its names block is now remembered
    for cut in range(len(good)):  # every truncation, with the names known and (cut short) unknown
        with pytest.raises(conv.ConversionError):
            conv.team_joint_state_from_msg(good[:cut], 2, ("velocity", "effort"))
    huge_count = good[:108] + struct.pack("<I", 2**31) + good[112:]  # the velocity count
    for bad in (b"\x00\x00" + good[2:], huge_count, b"", bytes(3)):
        with pytest.raises(conv.ConversionError):
            conv.team_joint_state_from_msg(bad, 2, ("velocity", "effort"))


@settings(max_examples=300, deadline=None)
@given(garbage=st.binary(max_size=200))
def test_random_bytes_never_raise_anything_but_a_conversion_error_for_team_states(garbage):
    known = _hand_serialized_team_state(1, 2, [1.0] * 4, [0.5] * 4)
    for data in (garbage, b"\x00\x01\x00\x00" + garbage, known[:100] + garbage):
        try:
            conv.team_joint_state_from_msg(data, 2, ("velocity", "effort"))
        except conv.ConversionError:
            pass


# A PointStamped by hand: header stamp at payload offset 0, frame_id "field" (length 6 with its NUL)
# at 8, padding 18..23, then x, y, z from 24 (a multiple of 8); a PoseStamped continues with the
# orientation (qx, qy, qz, qw) from 48.
def test_serialized_point_and_pose_match_a_hand_made_layout():
    header = b"\x00\x01\x00\x00" + struct.pack("<iI", 7, 250_000_000) + struct.pack("<I", 6) + b"field\x00" + bytes(6)
    point = header + struct.pack("<3d", 1.25, -2.5, 0.0)
    assert conv.point_cdr(7.25, (1.25, -2.5)) == point
    assert conv.point_from_msg(point) == (7.25, (1.25, -2.5))
    half = 0.5 * 0.75
    pose = header + struct.pack("<7d", 1.25, -2.5, 0.0, 0.0, 0.0, math.sin(half), math.cos(half))
    assert conv.pose2d_cdr(7.25, (1.25, -2.5, 0.75)) == pose
    t_s, xy_yaw = conv.pose2d_from_msg(pose)
    assert t_s == 7.25 and xy_yaw.tolist() == pytest.approx([1.25, -2.5, 0.75], abs=1e-15)
    assert conv.float64_cdr(-0.5) == b"\x00\x01\x00\x00" + struct.pack("<d", -0.5)
    padding = set(range(22, 28))  # file offsets; rclpy leaves them uninitialized
    references = (msgs.point_msg(7.25, (1.25, -2.5)), msgs.pose2d_msg(7.25, (1.25, -2.5, 0.75)))
    for built, reference in zip((point, pose), references, strict=True):
        ref = serialize_message(reference)
        assert len(ref) >= len(built)
        assert [b for i, b in enumerate(ref[: len(built)]) if i not in padding] == [
            b for i, b in enumerate(built) if i not in padding]


def _read_both_ways(read, msg):
    """read(message) and read(its bytes): the values, or "rejected" (a ConversionError)."""
    outcomes = []
    for form in (msg, serialize_message(msg)):
        try:
            t, values = read(form)
            outcomes.append((t, np.asarray(values, dtype=float).tolist()))
        except conv.ConversionError:
            outcomes.append("rejected")
    return outcomes


_any_float = st.floats(width=64)
# frame ids as ROS carries them (_ros_text): rclpy serializes a str as a C string, so "a\x00b" arrives as "a"
_stamps = dict(sec=st.integers(-(2**31), 2**31 - 1), nanosec=st.integers(0, 2**32 - 1), frame=_ros_text)


@settings(max_examples=300, deadline=None)
@given(x=_any_float, y=_any_float, z=_any_float, qx=_any_float, qy=_any_float, qz=_any_float, qw=_any_float,
       value=_any_float, **_stamps)
def test_serialized_point_pose_and_float64_are_read_like_messages(x, y, z, qx, qy, qz, qw, value, sec, nanosec, frame):
    """As for JointState: every message rclpy serializes reads alike from its bytes, or both are refused."""
    header = Header(stamp=Time(sec=sec, nanosec=nanosec), frame_id=frame)
    point = PointStamped(header=header)
    point.point.x, point.point.y, point.point.z = x, y, z
    pose = PoseStamped(header=header)
    pose.pose.position.x, pose.pose.position.y, pose.pose.position.z = x, y, z
    o = pose.pose.orientation
    o.x, o.y, o.z, o.w = qx, qy, qz, qw
    for read, msg in ((conv.point_from_msg, point), (conv.pose2d_from_msg, pose),
                      (lambda m: (0.0, conv.float64_from_msg(m)), Float64(data=value))):
        outcomes = _read_both_ways(read, msg)
        assert outcomes[0] == outcomes[1], type(msg).__name__


@settings(max_examples=200, deadline=None)
@given(t_s=st.floats(0.0, 2.0**31 - 1.0), x=st.floats(-1e3, 1e3), y=st.floats(-1e3, 1e3), yaw=st.floats(-1e6, 1e6),
       frame=_ros_text)
def test_serialized_point_pose_and_float64_builders_round_trip_through_rclpy(t_s, x, y, yaw, frame):
    assert deserialize_message(conv.point_cdr(t_s, (x, y), frame), PointStamped) == msgs.point_msg(t_s, (x, y), frame)
    assert deserialize_message(conv.pose2d_cdr(t_s, (x, y, yaw), frame), PoseStamped) == msgs.pose2d_msg(
        t_s, (x, y, yaw), frame)
    assert deserialize_message(conv.float64_cdr(x), Float64) == msgs.float64_msg(x)


def test_serialized_point_pose_and_float64_builders_refuse_what_the_message_builders_refuse():
    for bad in (math.nan, math.inf, -math.inf, 2e3):
        for build in (msgs.point_msg, conv.point_cdr):
            with pytest.raises(conv.ConversionError):
                build(1.0, (bad, 0.0))
        for build in (msgs.pose2d_msg, conv.pose2d_cdr):
            with pytest.raises(conv.ConversionError):
                build(1.0, (0.0, bad, 0.0))
        for build in (msgs.float64_msg, conv.float64_cdr):
            with pytest.raises(conv.ConversionError):
                build(bad)
    for build in (msgs.point_msg, conv.point_cdr):
        for bad_stamp in (-1.0, math.nan, 5e9):
            with pytest.raises(conv.ConversionError, match="stamp"):
                build(bad_stamp, (0.0, 0.0))


def test_malformed_point_pose_and_float64_bytes_are_a_conversion_error():
    for good, read in ((conv.point_cdr(1.0, (0.5, 0.5)), conv.point_from_msg),
                       (conv.pose2d_cdr(1.0, (0.5, 0.5, 0.1)), conv.pose2d_from_msg),
                       (conv.float64_cdr(0.5), conv.float64_from_msg)):
        for cut in range(len(good)):  # every truncation
            with pytest.raises(conv.ConversionError):
                read(good[:cut])
        for bad in (b"\x00\x00" + good[2:], good[:12] + struct.pack("<I", 2**31) + good[16:]):
            if read is not conv.float64_from_msg or bad[:2] != good[:2]:
                with pytest.raises(conv.ConversionError):
                    read(bad)


@settings(max_examples=300, deadline=None)
@given(garbage=st.binary(max_size=120))
def test_random_bytes_never_raise_anything_but_a_conversion_error_for_any_codec(garbage):
    for data in (garbage, b"\x00\x01\x00\x00" + garbage):
        for read in (conv.point_from_msg, conv.pose2d_from_msg, conv.float64_from_msg):
            try:
                read(data)
            except conv.ConversionError:
                pass


def test_serialized_odometry_matches_rclpy_but_for_the_padding():
    """Header "field" and child "ball": frame_id at payload 8, padding 18-19, child_frame_id at 20,
    padding 29-31, then 85 doubles from 32 (pose, its covariance, twist, its covariance)."""
    args = (3.5, (1.0, -2.0, 0.5), (0.25, -0.5, 0.0), "ball")
    kwargs = dict(spin=(1.0, 2.0, 3.0), position_variance_m2=4e-6)
    built = conv.odometry_cdr(*args, **kwargs)
    assert len(built) == 4 + 32 + 85 * 8
    assert struct.unpack_from("<85d", built, 36)[:8] == (1.0, -2.0, 0.0, 0.0, 0.0, math.sin(0.25), math.cos(0.25), 4e-6)
    reference = serialize_message(conv.odometry_msg(*args, **kwargs))
    padding = {22, 23, 33, 34, 35}  # file offsets (payload offset + 4)
    assert [b for i, b in enumerate(reference[: len(built)]) if i not in padding] == [
        b for i, b in enumerate(built) if i not in padding]
    assert deserialize_message(built, Odometry) == conv.odometry_msg(*args, **kwargs)


_small = st.floats(-1e3, 1e3)


@settings(max_examples=200, deadline=None)
@given(t_s=st.floats(0.0, 2.0**31 - 1.0), pose=st.tuples(_small, _small, st.floats(-1e6, 1e6)),
       velocity=st.tuples(_small, _small, _small), spin=st.none() | st.tuples(*[st.floats(-1e5, 1e5)] * 3),
       variance=st.none() | _small, v_variance=st.none() | _small, child=_ros_text, frame=_ros_text)
def test_serialized_odometry_round_trips_through_rclpy(t_s, pose, velocity, spin, variance, v_variance, child, frame):
    kwargs = dict(child_frame_id=child, frame_id=frame, spin=spin, position_variance_m2=variance,
                  velocity_variance_m2ps2=v_variance)
    expected = conv.odometry_msg(t_s, pose, velocity, **kwargs)
    assert deserialize_message(conv.odometry_cdr(t_s, pose, velocity, **kwargs), Odometry) == expected


def test_serialized_odometry_refuses_what_the_message_builder_refuses():
    good = dict(t_s=1.0, pose=(0.0, 0.0, 0.0), velocity=(0.0, 0.0, 0.0))
    for bad in (math.nan, math.inf, 2e3):
        for change in (dict(pose=(bad, 0.0, 0.0)), dict(velocity=(0.0, bad, 0.0)), dict(velocity=(0.0, 0.0, bad)),
                       dict(spin=(0.0, 0.0, bad * 1e3)), dict(position_variance_m2=bad),
                       dict(velocity_variance_m2ps2=bad), dict(t_s=-bad)):
            for build in (conv.odometry_msg, conv.odometry_cdr):
                with pytest.raises(conv.ConversionError):
                    build(**{**good, **change})


@settings(max_examples=200, deadline=None)
@given(rows=st.integers(1, 4).flatmap(lambda n: st.lists(st.lists(st.floats(-1e9, 1e9), min_size=n, max_size=n),
                                                         min_size=1, max_size=5).map(lambda r, n=n: (n, r))),
       row_label=_ros_text)
def test_serialized_table_round_trips_through_rclpy(rows, row_label):
    n_cols, table = rows
    labels = [f"c{k}" for k in range(n_cols)]
    built = tables.table_cdr(table, labels, row_label)
    assert deserialize_message(built, Float64MultiArray) == tables.table_msg(table, labels, row_label)


@settings(max_examples=200, deadline=None)
@given(rows=st.integers(1, 4).flatmap(lambda n: st.lists(st.lists(st.floats(-1e9, 1e9), min_size=n, max_size=n),
                                                         min_size=0, max_size=5).map(lambda r, n=n: (n, r))),
       row_label=_ros_text)
def test_a_table_reads_the_same_from_its_bytes_as_from_the_message(rows, row_label):
    n_cols, table = rows
    labels = [f"c{k}" for k in range(n_cols)]
    msg = tables.table_msg(np.array(table, dtype=float).reshape(-1, n_cols), labels, row_label)
    expected = np.array(table, dtype=float).reshape(-1, n_cols)
    for data in (serialize_message(msg), tables.table_cdr(table, labels, row_label)):  # rclpy pads with garbage
        np.testing.assert_array_equal(tables.table_from_msg(data, labels), expected)


def test_a_tables_malformed_bytes_are_refused():
    data = tables.table_cdr([[1.0, 2.0, 3.0]] * 2, ("a", "b", "c"))
    labels = ("a", "b", "c")
    np.testing.assert_array_equal(tables.table_from_msg(data, labels), [[1.0, 2.0, 3.0]] * 2)
    for bad in (data[:-1], data[:10], b"\x01" + data[1:], data + bytes(8), data[:4] + b"\xff\xff\xff\x7f" + data[8:],
                data[:-8] + struct.pack("<d", math.nan)):
        with pytest.raises(conv.ConversionError):
            tables.table_from_msg(bad, labels)


def test_serialized_table_refuses_what_the_message_builder_refuses():
    labels = ["a", "b"]
    for bad in ([[1.0, math.nan]], [[math.inf, 0.0]], [[2e9, 0.0]], [[1.0, 2.0, 3.0]], [[1.0]]):
        for build in (tables.table_msg, tables.table_cdr):
            with pytest.raises(conv.ConversionError):
                build(bad, labels)


@given(t_ns=st.integers(0, 2**31 * 10**9 - 1))
def test_serialized_clock_round_trips_through_rclpy(t_ns):
    assert deserialize_message(conv.clock_cdr(t_ns), Clock) == Clock(clock=conv.nanoseconds_to_stamp(t_ns))


def test_table_round_trip_and_labels():
    rows = np.array([[1.0, 0.5, 0.0, 1.0], [2.0, 1.0, 1.0, 0.0]])
    msg = tables.table_msg(rows, c.MOTOR_STATUS_COLUMNS, "wheels")
    assert msg.layout.dim[1].label == "avg_current_a,pwm_limit,saturated,limit_active"
    np.testing.assert_array_equal(tables.table_from_msg(msg, c.MOTOR_STATUS_COLUMNS), rows)
    with pytest.raises(conv.ConversionError):
        tables.table_msg(np.array([[math.nan, 0, 0, 0]]), c.MOTOR_STATUS_COLUMNS)


def test_odometry_round_trip_with_spin():
    msg = conv.odometry_msg(2.0, [1.0, -2.0, 0.5], [0.3, 0.4, 0.0], spin=[10.0, -5.0, 1.0])
    t, pose, vel, ang = conv.odometry_from_msg(msg)
    assert t == 2.0
    np.testing.assert_allclose(pose, [1.0, -2.0, 0.5])
    np.testing.assert_allclose(vel[:2], [0.3, 0.4])
    np.testing.assert_allclose(ang, [10.0, -5.0, 1.0])


def test_refilled_messages_equal_new_ones():
    """Publishers refill their messages every tick: a refill leaves nothing of the previous one."""
    odom = conv.odometry_msg(1.0, [1.0, 2.0, 0.5], [3.0, 4.0, 0.0], "ball", spin=[1.0, 2.0, 3.0],
                             position_variance_m2=0.25)
    refilled = conv.odometry_msg(2.5, [-1.0, 0.5, -1.0], [0.1, 0.2, 0.3], "robot_0", out=odom)
    assert refilled is odom
    assert odom == conv.odometry_msg(2.5, [-1.0, 0.5, -1.0], [0.1, 0.2, 0.3], "robot_0")
    point = msgs.point_msg(1.0, (1.0, 2.0), frame_id="other")
    assert msgs.point_msg(3.0, (4.0, 5.0), out=point) == msgs.point_msg(3.0, (4.0, 5.0))
    assert conv.point_from_msg(point) == (3.0, (4.0, 5.0))
    assert all(type(v) is float for v in conv.point_from_msg(point)[1])


def test_robot_config_validation_and_yaml(tmp_path):
    cfg = RobotConfig.from_yaml(Path(__file__).resolve().parents[2] / "src/erforce_interfaces/config/robot.yaml")
    assert cfg == RobotConfig()  # the generated file reads back as the defaults it was written from
    assert cfg.num_wheels == 4 and cfg.wheel_names[-1] == "wheel_3"
    assert math.degrees(cfg.wheel_angles_rad[0]) == pytest.approx(60.0)
    with pytest.raises(ValueError, match="at least 3"):
        RobotConfig(wheel_angles_rad=(0.0, 1.0))
    with pytest.raises(ValueError, match="wheel_radius_m"):
        RobotConfig(wheel_radius_m=0.0)
    with pytest.raises(ValueError, match="mass_kg"):
        RobotConfig(mass_kg=math.nan)
    with pytest.raises(ValueError, match="unknown robot config keys: colour"):
        RobotConfig.from_dict({"colour": "blue"})


def test_field_presets():
    a, b = FieldConfig.preset("division_a"), FieldConfig.preset("division_b")
    assert (a.length_m, a.width_m, b.length_m, b.width_m) == (12.0, 9.0, 9.0, 6.0)
    assert a.contains(5.9, 4.4) and not a.contains(6.1, 0.0)
    with pytest.raises(ValueError, match="unknown field preset"):
        FieldConfig.preset("division_c")


def test_dds_profile_env_points_at_the_stacks_profile_unless_one_is_named():
    general, localhost = c.dds_profile_path(), c.dds_profile_path(localhost=True)
    assert general.name == "fastdds_profile.xml" and "<leaseAnnouncement>" in general.read_text()
    sync = {"RMW_FASTRTPS_PUBLICATION_MODE": "SYNCHRONOUS"}
    both = dict.fromkeys(c.DDS_PROFILE_VARIABLES, str(general))
    udp_local = dict.fromkeys(c.DDS_PROFILE_VARIABLES, str(localhost))
    udp_local["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "SYSTEM_DEFAULT"
    # Localhost-only discovery: the UDP-only localhost profile under SYSTEM_DEFAULT, so that rmw_fastrtps
    # does not put its own shared-memory transport in.
    assert c.dds_profile_env({"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}) == udp_local | sync
    assert c.dds_profile_env({"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST", **both}) == udp_local | sync
    # Applied twice, nothing changes.
    local = {"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}
    once = local | c.dds_profile_env(local)
    assert c.dds_profile_env(once) == {}
    # ROS 2's default range (the subnet), a range beyond this computer, or static peers (rmw ignores those
    # under SYSTEM_DEFAULT): the general profile.
    for environ in ({}, {"ROS_AUTOMATIC_DISCOVERY_RANGE": "SUBNET"}, {"ROS_AUTOMATIC_DISCOVERY_RANGE": "OFF"},
                    {"ROS_AUTOMATIC_DISCOVERY_RANGE": "SYSTEM_DEFAULT"},
                    {"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST", "ROS_STATIC_PEERS": "10.0.0.2"}):
        assert c.dds_profile_env(environ) == both | sync, environ
    # The localhost profile is taken back when the range widens.
    assert c.dds_profile_env({**udp_local, "ROS_AUTOMATIC_DISCOVERY_RANGE": "SUBNET"}) == both | sync
    # The user's own profile: untouched, whatever the range.
    assert c.dds_profile_env({"FASTRTPS_DEFAULT_PROFILES_FILE": "/mine.xml"}) == sync
    assert c.dds_profile_env({"FASTDDS_DEFAULT_PROFILES_FILE": "/mine.xml"}) == sync
    assert c.dds_profile_env({"FASTRTPS_DEFAULT_PROFILES_FILE": ""}) != sync  # empty is unset
    # The user's publication mode stays.
    mine = {"FASTRTPS_DEFAULT_PROFILES_FILE": "/mine.xml", "RMW_FASTRTPS_PUBLICATION_MODE": "ASYNCHRONOUS"}
    assert c.dds_profile_env(mine) == {}


def test_the_localhost_profile_uses_udp_alone_and_asks_only_this_computer():
    xml = c.dds_profile_path(localhost=True).read_text()
    assert "<useBuiltinTransports>false</useBuiltinTransports>" in xml and "<type>UDPv4</type>" in xml
    assert "SHM" not in xml.split("-->", 1)[1]
    peers = xml.split("<initialPeersList>")[1].split("</initialPeersList>")[0]
    assert peers.count("<address>") == 1 and "<address>127.0.0.1</address>" in peers
    assert "<metatrafficMulticastLocatorList>" not in xml and "<leaseAnnouncement>" in xml


def test_a_table_whose_shape_disagrees_with_its_labels_is_refused():
    """The catcher died on a /ball/model_params table with 4 columns under the right label."""
    good = tables.table_msg([[-2.5, -0.3, 0.6]] * 3, c.BALL_MODEL_PARAM_LABELS)
    assert tables.table_from_msg(good, c.BALL_MODEL_PARAM_LABELS, 3).shape == (3, 3)
    four = tables.table_msg([[-2.5, -0.3, 0.6]] * 3, c.BALL_MODEL_PARAM_LABELS)
    four.layout.dim[1].size, four.data = 4, [-2.5, -0.3, 0.6, 1.0] * 3
    with pytest.raises(conv.ConversionError, match="4 columns"):
        tables.table_from_msg(four, c.BALL_MODEL_PARAM_LABELS)
    with pytest.raises(conv.ConversionError, match="1 rows, expected 3"):
        tables.table_from_msg(tables.table_msg([[-2.5, -0.3, 0.6]], c.BALL_MODEL_PARAM_LABELS),
                            c.BALL_MODEL_PARAM_LABELS, 3)
    good.layout.data_offset = 2
    with pytest.raises(conv.ConversionError, match="data_offset"):
        tables.table_from_msg(good, c.BALL_MODEL_PARAM_LABELS)


def test_world_frame_inputs_must_be_in_field_or_unnamed_and_stamps_must_be_times():
    for frame in ("field", ""):
        point = PointStamped(header=Header(frame_id=frame, stamp=Time(sec=2, nanosec=5)))
        assert conv.point_from_msg(point)[0] == conv.point_from_msg(serialize_message(point))[0] == 2.000000005
    for frame in ("map", "robot_0/base_link", "x" * 300):
        for read in (conv.point_from_msg, conv.pose2d_from_msg):
            msg = (PointStamped if read is conv.point_from_msg else PoseStamped)(header=Header(frame_id=frame))
            msg_q = getattr(msg, "pose", None)
            if msg_q is not None:
                msg_q.orientation.w = 1.0
            for form in (msg, serialize_message(msg)):
                with pytest.raises(conv.ConversionError, match="frame_id"):
                    read(form)
        with pytest.raises(conv.ConversionError, match="frame_id"):
            conv.odometry_from_msg(Odometry(header=Header(frame_id=frame)))
    for sec, nanosec in ((-1, 0), (3, 1_000_000_000), (-(2**31), 999)):
        stamp = Time(sec=sec, nanosec=nanosec)
        js = JointState(header=Header(stamp=stamp), velocity=[0.0], effort=[0.0])
        for form in (js, serialize_message(js)):
            with pytest.raises(conv.ConversionError, match="not a valid time"):
                conv.joint_state_from_msg(form, 1, "velocity")
        with pytest.raises(conv.ConversionError, match="not a valid time"):
            conv.point_from_msg(serialize_message(PointStamped(header=Header(stamp=stamp))))


def test_a_saturating_sensor_clips_finite_values_and_still_refuses_non_finite_ones():
    """The plant's wheel sensors (conversions' docstring): a robot placed at 20 m/s while turning at
    100 rad/s spins its wheels past the wire's range; the reading saturates instead of failing."""
    names = ("wheel_0", "wheel_1")
    with pytest.raises(conv.ConversionError):
        conv.joint_state_cdr(0, names, velocity=[1022.0, 0.0])
    data = conv.joint_state_cdr(7, names, velocity=[1022.0, -5e6], effort=[125.0, -1.0], saturate=True)
    t_ns, speeds, currents = conv.wheel_states_from_msg(data, 2)
    assert t_ns == 7 and speeds.tolist() == [conv.MAX_ABS_VALUE, -conv.MAX_ABS_VALUE]
    assert currents.tolist() == [125.0, -1.0]
    with pytest.raises(conv.ConversionError, match="not finite"):
        conv.joint_state_cdr(0, names, velocity=[math.nan, 0.0], saturate=True)


def test_model_in_use_is_the_first_row_of_the_model_table():
    in_use, fit, std = [-2.5, -0.3, 0.6], [-2.4, -0.31, 0.61], [0.01, 0.002, 0.003]
    labels = c.BALL_MODEL_PARAM_LABELS
    assert tables.model_in_use_from_msg(tables.table_msg([in_use], labels, "in_use")) == (-2.5, -0.3, 0.6)
    three = tables.table_msg([in_use, fit, std], labels, "in_use,fit,std_error")
    assert tables.model_in_use_from_msg(three) == (-2.5, -0.3, 0.6)
    assert tables.model_in_use_from_msg(serialize_message(three)) == (-2.5, -0.3, 0.6)  # its bytes
    for rows, label in (([fit, std, in_use], "fit,std_error,in_use"), ([in_use, fit], "in_use,fit,std_error")):
        for msg in (tables.table_msg(rows, labels, label), tables.table_cdr(rows, labels, label)):
            with pytest.raises(conv.ConversionError):
                tables.model_in_use_from_msg(msg)
    four_columns = tables.table_msg([[*in_use, 1.0]], (*labels, "extra"), "in_use")
    with pytest.raises(conv.ConversionError, match="columns"):
        tables.model_in_use_from_msg(four_columns)


@pytest.mark.parametrize(("name", "topic"), [
    ("/clock", c.CLOCK), ("/ball/state", c.BALL_STATE), ("/robot_3/odom", c.ODOM),
    ("/robot_0/ground_truth/odom", c.GROUND_TRUTH_ODOM), ("/opponent_1/vision_pose", c.VISION_POSE),
    ("/odom", None), ("/robot_x/odom", None), ("/team/odom", None), ("/robot_0/ball/state", None), ("/chatter", None)])
def test_topic_of_name_finds_the_contract_topic_of_an_absolute_name(name, topic):
    assert c.topic_of_name(name) is topic
