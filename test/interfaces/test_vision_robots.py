"""/vision/robots: a sensor_msgs/PointCloud2 with a point per robot, its bytes and its checks."""

import math
import struct

import numpy as np
import pytest
from builtin_interfaces.msg import Time
from hypothesis import given, settings
from hypothesis import strategies as st
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import PointCloud2, PointField
from std_msgs.msg import Header

from erforce_interfaces.wire import clouds
from erforce_interfaces.wire import contract as c
from erforce_interfaces.wire import conversions as conv

FIELD_NAMES = ("x", "y", "z", "yaw", "team", "robot_id")


def _field(name: bytes, offset: int) -> bytes:
    """One PointField from a 4-aligned offset: name (length, characters, NUL, padding to 4), offset,
    datatype FLOAT64 (8) and 3 bytes of padding, count 1."""
    raw = name + b"\x00"
    return struct.pack("<I", len(raw)) + raw + bytes(-len(raw) % 4) + struct.pack("<IB3xI", offset, 8, 1)


# Two robots at 7.25 s: ours 3 at (1.5, -2.0) facing 0.5 rad, the opponents' 0 at (-4.0, 3.0) facing 4 rad, which
# goes on the wire as 4 - 2 pi. Payload offsets: stamp 0; frame_id "field" 8 (length 6, 2 bytes padding); height 20;
# width 24; 6 fields from 28; is_bigendian 164 (3 bytes padding); point_step 168; row_step 172; data 176 (length)
# and 180 (2 x 48 bytes); is_dense 276.
HAND = (b"\x00\x01\x00\x00" + struct.pack("<iI", 7, 250_000_000) + struct.pack("<I", 6) + b"field\x00" + bytes(2)
        + struct.pack("<III", 1, 2, 6)
        + b"".join(_field(name.encode(), 8 * k) for k, name in enumerate(FIELD_NAMES))
        + b"\x00" + bytes(3) + struct.pack("<III", 48, 96, 96)
        + struct.pack("<6d", 1.5, -2.0, 0.0, 0.5, 1.0, 3.0)
        + struct.pack("<6d", -4.0, 3.0, 0.0, 4.0 - 2.0 * math.pi, 2.0, 0.0) + b"\x01")
ROWS = [(1.0, 3.0, 1.5, -2.0, 0.5), (2.0, 0.0, -4.0, 3.0, 4.0)]  # (team, robot_id, x, y, yaw)
ROWS_READ = [[1.0, 3.0, 1.5, -2.0, 0.5], [2.0, 0.0, -4.0, 3.0, 4.0 - 2.0 * math.pi]]


def cloud(t_s, points, fields=FIELD_NAMES, frame=c.FIELD_FRAME, **overrides):
    """A PointCloud2 message built field by field (values as given: NaN and the like included)."""
    msg = PointCloud2(header=Header(frame_id=frame))
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(round(t_s * 1e9), 10**9)
    msg.height, msg.width = 1, len(points)
    msg.fields = [PointField(name=name, offset=8 * k, datatype=PointField.FLOAT64, count=1)
                  for k, name in enumerate(fields)]
    msg.point_step, msg.row_step = 8 * len(fields), 8 * len(fields) * len(points)
    msg.data = b"".join(struct.pack(f"<{len(fields)}d", *p) for p in points)
    msg.is_dense = True
    for name, value in overrides.items():
        setattr(msg, name, value)
    return msg


# The same frame with its ball at (0.25, -1.0) as the first point (team 0, yaw and robot_id 0): width 3, row_step and
# data length 144.
HAND_BALL = (HAND[:28] + struct.pack("<I", 3) + HAND[32:176] + struct.pack("<II", 144, 144)
             + struct.pack("<6d", 0.25, -1.0, 0.0, 0.0, 0.0, 0.0) + HAND[184:])


def test_the_topic_and_its_fields_are_in_the_contract():
    assert c.VISION_ROBOTS.name == "/vision/robots" and c.VISION_ROBOTS.msg_type is PointCloud2
    assert c.VISION_ROBOTS.qos is c.QOS_SENSOR and c.VISION_ROBOT_FIELDS == FIELD_NAMES
    assert c.topic_of_name("/vision/robots") is c.VISION_ROBOTS
    assert (c.OURS.code, c.OPPONENTS.code, c.VISION_BALL_CODE) == (1.0, 2.0, 0.0)


def test_a_frame_with_its_ball_matches_a_hand_made_layout_and_reads_back():
    assert len(HAND_BALL) == len(HAND) + 48
    assert clouds.vision_robots_cdr(7.25, ROWS, balls=[(0.25, -1.0)]) == HAND_BALL
    points = np.array([[0.25, -1.0, 0.0, 0.0, 0.0, 0.0], [1.5, -2.0, 0.0, 0.5, 1.0, 3.0],
                       [-4.0, 3.0, 0.0, 4.0 - 2.0 * math.pi, 2.0, 0.0]])
    assert clouds.vision_robots_points_cdr(7.25, points) == HAND_BALL
    for form in (HAND_BALL, deserialize_message(HAND_BALL, PointCloud2)):
        t_s, balls, rows = clouds.vision_frame_from_msg(form)
        assert t_s == 7.25 and balls.tolist() == [[0.25, -1.0]] and rows.tolist() == ROWS_READ
        assert clouds.vision_robots_from_msg(form)[1].tolist() == ROWS_READ  # a reader of robots skips the ball
    t_s, balls, rows = clouds.vision_frame_from_msg(clouds.vision_robots_cdr(1.0, [], balls=[(-3.0, 2.0)]))
    assert balls.tolist() == [[-3.0, 2.0]] and rows.shape == (0, 5)
    assert clouds.vision_frame_from_msg(HAND)[1].shape == (0, 2)
    for bad in ((math.nan, 0.0), (0.0, 2e3)):
        with pytest.raises(conv.ConversionError, match="ball: "):
            clouds.vision_robots_cdr(1.0, ROWS, balls=[bad])
        with pytest.raises(conv.ConversionError, match="ball: "):
            clouds.vision_frame_from_msg(cloud(1.0, [(*bad, 0.0, 0.0, 0.0, 0.0)]))


def test_bytes_match_a_hand_made_layout_and_read_back():
    assert len(HAND) == 4 + 277
    assert clouds.vision_robots_cdr(7.25, ROWS) == HAND
    t_s, rows = clouds.vision_robots_from_msg(HAND)
    assert t_s == 7.25 and rows.tolist() == ROWS_READ
    msg = deserialize_message(HAND, PointCloud2)  # rclpy reads our bytes as the cloud we meant
    assert msg == cloud(7.25, [(1.5, -2.0, 0.0, 0.5, 1.0, 3.0), (-4.0, 3.0, 0.0, 4.0 - 2.0 * math.pi, 2.0, 0.0)])
    # rclpy's serializer agrees on every byte but the padding, which it leaves uninitialized
    # payload offsets of the padding: after frame_id; per field after its name (none after "yaw\0") and after
    # its datatype; after is_bigendian
    padding = {4 + k for k in (18, 19, 38, 39, 45, 46, 47, 58, 59, 65, 66, 67, 78, 79, 85, 86, 87, 105, 106, 107,
                               121, 122, 123, 129, 130, 131, 149, 150, 151, 157, 158, 159, 165, 166, 167)}
    reference = serialize_message(msg)
    assert len(reference) == len(HAND)
    assert [b for i, b in enumerate(reference) if i not in padding] == [b for i, b in enumerate(HAND)
                                                                         if i not in padding]
    assert clouds.vision_robots_from_msg(reference)[1].tolist() == ROWS_READ  # garbage padding read too
    assert clouds.vision_robots_from_msg(msg)[1].tolist() == ROWS_READ


def test_points_written_by_a_producer_give_the_same_bytes():
    points = np.array([[1.5, -2.0, 0.0, 0.5, 1.0, 3.0], [-4.0, 3.0, 0.0, 4.0 - 2.0 * math.pi, 2.0, 0.0]])
    assert clouds.vision_robots_points_cdr(7.25, points) == HAND
    assert clouds.vision_robots_points_cdr(7.25, np.empty((0, 6))) == clouds.vision_robots_cdr(7.25, [])
    assert clouds.vision_robots_points_cdr(7.25, points[:1], frame_id="") == clouds.vision_robots_cdr(7.25, ROWS[:1],
                                                                                                  frame_id="")


def test_an_empty_frame_and_an_unnamed_frame_are_read():
    t_s, rows = clouds.vision_robots_from_msg(clouds.vision_robots_cdr(1.5, []))
    assert t_s == 1.5 and rows.shape == (0, 5)
    data = clouds.vision_robots_cdr(2.0, ROWS[:1], frame_id="")
    assert clouds.vision_robots_from_msg(data)[1].tolist() == ROWS_READ[:1]
    assert clouds.vision_robots_from_msg(serialize_message(deserialize_message(data, PointCloud2)))[1].tolist() == \
        ROWS_READ[:1]


_rows = st.lists(st.tuples(st.sampled_from([1.0, 2.0]), st.integers(0, 15).map(float), st.floats(-1e3, 1e3),
                           st.floats(-1e3, 1e3), st.floats(-1e6, 1e6)), max_size=22)


@settings(max_examples=150, deadline=None)
@given(t_s=st.floats(0.0, 2.0**31 - 1.0), rows=_rows)
def test_built_bytes_round_trip_through_rclpy(t_s, rows):
    data = clouds.vision_robots_cdr(t_s, rows)
    msg = deserialize_message(data, PointCloud2)
    expected = [[team, rid, x, y, math.remainder(yaw, 2.0 * math.pi)] for team, rid, x, y, yaw in rows]
    for form in (data, msg, serialize_message(msg)):
        _, read = clouds.vision_robots_from_msg(form)
        assert read.shape == (len(rows), 5)
        np.testing.assert_allclose(read, np.array(expected).reshape(-1, 5), rtol=0, atol=1e-9)
        assert (np.abs(read[:, 4]) <= math.pi).all()


_any = st.floats(width=64)


@settings(max_examples=200, deadline=None)
@given(points=st.lists(st.tuples(_any, _any, _any, _any, st.sampled_from([0.0, 1.0, 2.0, 1.5, math.nan]),
                                 st.sampled_from([0.0, 3.0, -1.0, 2.5, 1e9, math.inf])), max_size=4),
       sec=st.integers(-(2**31), 2**31 - 1), nanosec=st.integers(0, 2**32 - 1), frame=st.sampled_from(["field", "",
                                                                                                    "map"]))
def test_message_and_bytes_are_read_alike_or_refused_alike(points, sec, nanosec, frame):
    msg = cloud(0.0, points, frame=frame)
    msg.header.stamp = Time(sec=sec, nanosec=nanosec)
    outcomes = []
    for form in (msg, serialize_message(msg)):
        try:
            t_s, rows = clouds.vision_robots_from_msg(form)
            outcomes.append((t_s, rows.tolist()))
            assert np.isfinite(rows).all()
        except conv.ConversionError:
            outcomes.append("rejected")
    assert outcomes[0] == outcomes[1]


def test_the_builder_refuses_what_the_reader_refuses():
    good = (1.0, 3.0, 1.5, -2.0, 0.5)
    for k, bad in ((2, math.nan), (2, math.inf), (3, 2e3), (4, math.nan), (0, 3.0), (0, 5.0), (1, -1.0), (1, 1.5),
                   (1, math.nan)):
        row = list(good)
        row[k] = bad
        with pytest.raises(conv.ConversionError, match="robot 1: "):
            clouds.vision_robots_cdr(1.0, [good, row])
        point = [row[2], row[3], 0.0, row[4], row[0], row[1]]
        # team 3 on the ground is a camera where no camera can be
        with pytest.raises(conv.ConversionError, match="camera: z" if row[0] == 3.0 else "robot 0: "):
            clouds.vision_robots_from_msg(cloud(1.0, [point]))
    with pytest.raises(conv.ConversionError, match="robot 0: team"):  # a ball is no robot row: balls= takes it
        clouds.vision_robots_cdr(1.0, [(0.0, 0.0, 1.5, -2.0, 0.0)])
    with pytest.raises(conv.ConversionError, match="stamp"):
        clouds.vision_robots_cdr(-1.0, [good])


def test_other_clouds_and_malformed_bytes_are_refused():
    point = (1.5, -2.0, 0.0, 0.5, 1.0, 3.0)
    for msg in (cloud(1.0, [point[:5]], fields=FIELD_NAMES[:5]),  # no robot_id
                cloud(1.0, [point], fields=("x", "y", "z", "theta", "team", "robot_id")),
                cloud(1.0, [point], is_bigendian=True), cloud(1.0, [point], height=2),
                cloud(1.0, [point], row_step=96), cloud(1.0, [point], point_step=56),
                cloud(1.0, [point], frame="map")):
        for form in (msg, serialize_message(msg)):
            with pytest.raises(conv.ConversionError):
                clouds.vision_robots_from_msg(form)
    float32 = cloud(1.0, [point])
    float32.fields[5].datatype = PointField.FLOAT32
    with pytest.raises(conv.ConversionError, match="float64"):
        clouds.vision_robots_from_msg(float32)
    for cut in range(len(HAND)):  # every truncation
        with pytest.raises(conv.ConversionError):
            clouds.vision_robots_from_msg(HAND[:cut])
    for bad in (b"\x00\x00" + HAND[2:], HAND[:28] + struct.pack("<I", 10**6) + HAND[32:],  # width
                HAND[:-49] + struct.pack("<d", math.nan) + HAND[-41:]):  # x of the second robot
        with pytest.raises(conv.ConversionError):
            clouds.vision_robots_from_msg(bad)


@settings(max_examples=300, deadline=None)
@given(garbage=st.binary(max_size=300))
def test_random_bytes_never_raise_anything_but_a_conversion_error(garbage):
    for data in (garbage, b"\x00\x01\x00\x00" + garbage, HAND[:180] + garbage):
        try:
            clouds.vision_robots_from_msg(data)
        except conv.ConversionError:
            pass


def test_the_leading_ball_is_read_alone_and_a_frame_it_cannot_vouch_for_is_left_to_the_whole_decode():
    assert clouds.vision_leading_points(HAND_BALL) == (7.25, [(0.25, -1.0)], None, [])
    assert clouds.vision_leading_points(HAND) == (7.25, [], None, [])  # robots only
    two = clouds.vision_robots_cdr(3.0, ROWS, balls=[(1.0, 2.0), (-0.5, 0.75)])
    assert clouds.vision_leading_points(two) == (3.0, [(1.0, 2.0), (-0.5, 0.75)], None, [])
    # the robots are not read: the ball of a frame with a broken robot (its x NaN, after the ball) is answered;
    # the data starts at file offset 184 (payload offset 180)
    broken_robot = HAND_BALL[:184 + 48] + struct.pack("<d", math.nan) + HAND_BALL[184 + 56:]
    assert clouds.vision_leading_points(broken_robot) == (7.25, [(0.25, -1.0)], None, [])
    with pytest.raises(conv.ConversionError, match="robot 1: x is not finite"):  # the point after the ball
        clouds.vision_frame_from_msg(broken_robot)
    # a ball that fails the checks, a layout other than /vision/robots', a cut message: None
    for x, z, robot_id in ((math.nan, 0.0, 0.0), (2e3, 0.0, 0.0), (0.0, math.inf, 0.0), (0.0, 0.0, 0.5),
                           (0.0, 0.0, -1.0)):
        bad_ball = HAND_BALL[:184] + struct.pack("<6d", x, -1.0, z, 0.0, 0.0, robot_id) + HAND_BALL[232:]
        assert clouds.vision_leading_points(bad_ball) is None
        with pytest.raises(conv.ConversionError):
            clouds.vision_frame_from_msg(bad_ball)
    assert clouds.vision_leading_points(HAND_BALL[:-49]) is None
    other_fields = serialize_message(cloud(1.0, [(0.25, -1.0, 0.0, 0.0, 0.0, 0.0)], fields=("x", "y", "z", "yaw",
                                                                                             "team", "id")))
    assert clouds.vision_leading_points(other_fields) is None
    # another writer's bytes of the same cloud (rclpy's padding) are read as ours
    ours = serialize_message(deserialize_message(HAND_BALL, PointCloud2))
    assert clouds.vision_leading_points(ours) == (7.25, [(0.25, -1.0)], None, [])



def test_a_ball_after_a_robot_is_told_from_the_team_fields_alone():
    ball = (0.25, -1.0, 0.0, 0.0, c.VISION_BALL_CODE, 0.0)
    robot = (1.5, -2.0, 0.0, 0.5, 1.0, 3.0)  # x, y, z, yaw, team, robot_id
    for points, after in (([ball, robot], False), ([robot], False), ([ball], False), ([], False),
                          ([robot, ball], True), ([ball, robot, ball], True), ([ball, ball, robot, robot], False)):
        assert clouds.vision_ball_after_robot(serialize_message(cloud(1.0, points))) is after, points
    assert clouds.vision_ball_after_robot(HAND_BALL) is False and clouds.vision_ball_after_robot(HAND) is False
    assert clouds.vision_ball_after_robot(HAND_BALL[:-49]) is False  # not the layout: left to the whole decode


# Values at and just past each limit of a point (positions 1e3 m, yaw 1e6 rad, ids 0..1024), and non-finite ones.
EDGES = (0.0, -0.0, 0.5, -1.0, 3.0, 2.0, 1e3, -1e3, math.nextafter(1e3, math.inf), 1e6, -1e6,
         math.nextafter(1e6, math.inf), 1024.0, 1025.0, math.nan, math.inf, -math.inf)


def _one_field_off(good):
    """``good`` with each of its fields in turn set to each edge value."""
    for k in range(len(good)):
        for value in EDGES:
            yield (*good[:k], value, *good[k + 1:])


def test_a_ball_point_is_refused_by_the_leading_reader_exactly_when_the_whole_decode_refuses_it():
    # the whole decode tests the array at once and each point only after that failed; the leading reader tests the
    # point alone: the two must draw the same line
    ball = (0.25, -1.0, 0.0, 0.0, c.VISION_BALL_CODE, 0.0)
    refused = 0
    for point in _one_field_off(ball):
        if point[4] != c.VISION_BALL_CODE:
            continue  # no longer a ball: the leading reader stops before it
        data = serialize_message(cloud(1.0, [point]))
        leading = clouds.vision_leading_points(data)
        try:
            _t_s, balls, _rows = clouds.vision_frame_from_msg(data)
        except conv.ConversionError:
            assert leading is None, point
            refused += 1
        else:
            assert leading == (1.0, [point[:2]], None, []) and balls.tolist() == [list(point[:2])], point
    # by hand, the values past the limits: x, y, z each 9 (beyond 1e3 or not finite); yaw 4 (beyond 1e6 or not
    # finite); the id 11 (all but 0, -0, 2, 3, 1e3 and 1024)
    assert refused == 3 * 9 + 4 + 11


def test_the_writer_refuses_a_robot_row_exactly_when_the_reader_refuses_its_point():
    for team, robot_id, x, y, yaw in _one_field_off((1.0, 3.0, 1.5, -2.0, 0.5)):
        try:
            clouds.vision_robots_cdr(1.0, [(team, robot_id, x, y, yaw)])
            written = True
        except conv.ConversionError:
            written = False
        try:
            clouds.vision_robots_from_msg(cloud(1.0, [(x, y, 0.0, yaw, team, robot_id)]))
            read = team != c.VISION_BALL_CODE  # a ball point is read as a ball; the writer takes balls apart
        except conv.ConversionError:
            read = False
        assert written == read, (team, robot_id, x, y, yaw)


# The frame of HAND_BALL as camera 3 of the league's Division B quadrant cameras took it: its first point the camera
# at (2.275, -1.525, 4.0) m (SSL geometry's derived_camera_world_tx/ty/tz 2275, -1525, 4000 mm), team 3, robot_id
# its id 3; then the ball; then the same camera's sighting at (0.5, -0.75), team 4. Width 5, 240 bytes of data.
CAMERA_POINT = struct.pack("<6d", 2.275, -1.525, 4.0, 0.0, 3.0, 3.0)
SIGHTING_POINT = struct.pack("<6d", 0.5, -0.75, 0.0, 0.0, 4.0, 0.0)
HAND_CAMERA = (HAND[:28] + struct.pack("<I", 5) + HAND[32:176] + struct.pack("<II", 240, 240) + CAMERA_POINT
               + struct.pack("<6d", 0.25, -1.0, 0.0, 0.0, 0.0, 0.0) + SIGHTING_POINT + HAND[184:])


def test_the_camera_and_its_sighting_go_out_and_come_in_as_written_by_hand():
    assert (c.VISION_CAMERA_CODE, c.VISION_SIGHTING_CODE) == (3.0, 4.0)
    written = clouds.vision_robots_cdr(7.25, ROWS, balls=[(0.25, -1.0)], camera=(3, 2.275, -1.525, 4.0),
                                       sightings=[(0.5, -0.75)])
    assert written == HAND_CAMERA
    assert clouds.vision_leading_points(HAND_CAMERA) == (7.25, [(0.25, -1.0)], (2.275, -1.525, 4.0), [(0.5, -0.75)])
    cloud_read = clouds.vision_cloud_from_msg(HAND_CAMERA)
    assert (cloud_read.t_s, cloud_read.camera_id, cloud_read.camera_m) == (7.25, 3, (2.275, -1.525, 4.0))
    assert cloud_read.balls.tolist() == [[0.25, -1.0]] and cloud_read.sightings.tolist() == [[0.5, -0.75]]
    assert cloud_read.robots.tolist() == ROWS_READ  # the camera is no robot
    t_s, balls, rows = clouds.vision_frame_from_msg(deserialize_message(HAND_CAMERA, PointCloud2))
    assert (t_s, balls.tolist(), rows.tolist()) == (7.25, [[0.25, -1.0]], ROWS_READ)
    assert clouds.vision_robots_from_msg(HAND_CAMERA)[1].tolist() == ROWS_READ
    assert clouds.vision_ball_after_robot(HAND_CAMERA) is False
    # a frame without a camera is as before: no camera, no sightings
    plain = clouds.vision_cloud_from_msg(HAND_BALL)
    assert (plain.camera_id, plain.camera_m, plain.sightings.shape) == (None, None, (0, 2))


def test_a_camera_not_above_the_field_two_cameras_or_a_sighting_without_one_are_refused():
    ball = (0.25, -1.0, 0.0, 0.0, c.VISION_BALL_CODE, 0.0)
    camera = (2.275, -1.525, 4.0, 0.0, c.VISION_CAMERA_CODE, 3.0)
    sighting = (0.5, -0.75, 0.0, 0.0, c.VISION_SIGHTING_CODE, 0.0)
    for points, what in (([(2.275, -1.525, 0.0, 0.0, 3.0, 3.0), ball], "above the field"),
                         ([(2.275, -1.525, -4.0, 0.0, 3.0, 3.0), ball], "above the field"),
                         ([camera, camera, ball], "2 camera points"), ([ball, sighting], "without the camera")):
        data = serialize_message(cloud(1.0, points))
        with pytest.raises(conv.ConversionError, match=what):
            clouds.vision_cloud_from_msg(data)
        assert clouds.vision_leading_points(data) is None
    with pytest.raises(conv.ConversionError, match="without the camera"):
        clouds.vision_robots_cdr(1.0, [], balls=[(0.0, 0.0)], sightings=[(0.1, 0.0)])
    with pytest.raises(conv.ConversionError, match="above the field"):
        clouds.vision_robots_cdr(1.0, [], balls=[(0.0, 0.0)], camera=(0, 1.0, 1.0, 0.0))
    # a camera or a sighting after a robot: another writer's order, which the reader takes whole
    for points in ([(1.5, -2.0, 0.0, 0.5, 1.0, 3.0), camera, ball], [camera, ball, (1.5, -2.0, 0.0, 0.5, 1.0, 3.0),
                                                                     sighting]):
        assert clouds.vision_ball_after_robot(serialize_message(cloud(1.0, points))) is True
