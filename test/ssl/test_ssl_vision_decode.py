"""erforce_interfaces.ssl.ssl_vision: decoding with checks (bad input named, never non-finite output),
the vision clock (offset estimate, clock jumps), and a hypothesis fuzz test of every decoder."""

from __future__ import annotations

import math
import re
import struct

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from erforce_interfaces.ssl.ssl_proto import ssl_vision_wrapper_pb2 as wrap
from erforce_interfaces.ssl.ssl_vision import (
    BallCandidate,
    BallModelFromVision,
    CameraFrame,
    CameraPose,
    ChipModelFromVision,
    FieldGeometry,
    RobotSighting,
    SslDecodeError,
    decode_wrapper,
    encode_frame,
    encode_geometry,
)
from erforce_interfaces.ssl.vision_time import ClockJump, VisionClock


def detection_packet(**frame_fields) -> wrap.SSL_WrapperPacket:
    packet = wrap.SSL_WrapperPacket()
    det = packet.detection
    det.frame_number, det.t_capture, det.t_sent, det.camera_id = 7, 100.0, 100.01, 2
    for name, value in frame_fields.items():
        setattr(det, name, value)
    return packet


def add_ball(packet, x, y, confidence=0.8):
    packet.detection.balls.add(confidence=confidence, x=x, y=y, pixel_x=0.0, pixel_y=0.0)


def add_robot(packet, team, x, y, robot_id=None, orientation=None):
    robots = packet.detection.robots_blue if team == "blue" else packet.detection.robots_yellow
    r = robots.add(confidence=1.0, x=x, y=y, pixel_x=0.0, pixel_y=0.0)
    if robot_id is not None:
        r.robot_id = robot_id
    if orientation is not None:
        r.orientation = orientation


def test_millimetres_become_metres_and_both_teams_are_kept():
    packet = detection_packet()
    add_ball(packet, 1250.0, -300.0)
    add_robot(packet, "blue", -2000.0, 1000.0, robot_id=4, orientation=1.0)
    add_robot(packet, "yellow", 500.0, 0.0, robot_id=9, orientation=7.0)  # 7 rad = 7 - 2 pi
    frame = decode_wrapper(packet.SerializeToString()).frame
    assert (frame.camera_id, frame.frame_number, frame.t_capture_s, frame.t_sent_s) == (2, 7, 100.0, 100.01)
    assert frame.balls == (BallCandidate(1.25, -0.3, pytest.approx(0.8)),)
    blue, yellow = frame.robots
    assert (blue.team, blue.robot_id, blue.x_m, blue.y_m, blue.theta_rad) == ("blue", 4, -2.0, 1.0, 1.0)
    assert (yellow.team, yellow.robot_id) == ("yellow", 9)
    assert yellow.theta_rad == pytest.approx(7.0 - 2.0 * math.pi)


@pytest.mark.parametrize(
    ("data", "message"),
    [
        (b"", "empty datagram"),
        (b"\xff\xff\xff\xff\xff", "truncated or garbage"),
        (b"\x0a\x02\x08\x01", "without required fields (detection.t_capture"),
        (b"\x18\x05", "neither detection nor geometry"),  # only an unknown field 3
    ],
)
def test_unusable_datagrams_are_named(data, message):
    with pytest.raises(SslDecodeError, match=re.escape(message)):
        decode_wrapper(data)


def test_absurd_robot_counts_bad_times_and_camera_ids_reject_the_frame():
    packet = detection_packet()
    for k in range(33):  # 32 ids per team at most
        add_robot(packet, "yellow", 0.0, 0.0, robot_id=k % 32, orientation=0.0)
    with pytest.raises(SslDecodeError, match=re.escape("absurd robot counts (0 blue, 33 yellow")) as error:
        decode_wrapper(packet.SerializeToString())
    assert error.value.kind == "counts"
    with pytest.raises(SslDecodeError, match="t_capture nan"):
        decode_wrapper(detection_packet(t_capture=math.nan).SerializeToString())
    with pytest.raises(SslDecodeError, match="camera_id 99"):
        decode_wrapper(detection_packet(camera_id=99).SerializeToString())


def test_bad_detections_are_dropped_by_name_and_the_good_ones_kept():
    packet = detection_packet()
    add_ball(packet, math.nan, 0.0)
    add_ball(packet, 1e9, 0.0)  # a million metres
    add_ball(packet, 100.0, 200.0)
    add_ball(packet, 0.0, 0.0, confidence=3.0)
    add_robot(packet, "blue", 0.0, 0.0)  # no robot_id
    add_robot(packet, "yellow", math.inf, 0.0, robot_id=1)
    add_robot(packet, "yellow", 10.0, 20.0, robot_id=2, orientation=math.nan)
    out = decode_wrapper(packet.SerializeToString())
    assert out.frame.balls == (BallCandidate(0.1, 0.2, pytest.approx(0.8)),)
    (robot,) = out.frame.robots
    assert (robot.robot_id, robot.theta_rad) == (2, None)
    assert sorted(p.kind for p in out.problems) == ["bad_ball"] * 3 + ["bad_orientation", "bad_robot_id",
                                                                       "bad_robot_place"]
    assert all(p.count == 1 for p in out.problems)
    text = "\n".join(p.text for p in out.problems)
    assert "ball at (nan, 0.0) mm" in text and "blue robot without a valid id" in text
    assert "yellow robot 1 at (inf, 0.0) mm" in text and "orientation nan" in text


def test_a_frame_with_too_many_ball_candidates_keeps_the_first_32_and_its_robots():
    packet = detection_packet()
    for k in range(40):  # ball k at x = k mm: the first 32 (x 0 .. 31 mm) are kept, 8 dropped and counted
        add_ball(packet, float(k), 0.0)
    add_robot(packet, "blue", 1000.0, 0.0, robot_id=1, orientation=0.5)
    add_robot(packet, "yellow", -1000.0, 0.0, robot_id=2, orientation=-0.5)
    out = decode_wrapper(packet.SerializeToString())
    assert [b.x_m for b in out.frame.balls] == pytest.approx([k * 1e-3 for k in range(32)])
    assert out.frame.robots == (RobotSighting("blue", 1, 1.0, 0.0, 0.5, 1.0),
                                RobotSighting("yellow", 2, -1.0, 0.0, -0.5, 1.0))
    (problem,) = out.problems
    assert (problem.kind, problem.count) == ("too_many_balls", 8)
    assert problem.text == "camera 2: 40 ball candidates, 8 beyond the first 32 dropped"


def test_a_flood_of_bad_balls_leaves_room_to_name_a_bad_robot():
    packet = detection_packet()
    for _ in range(100):
        add_ball(packet, math.nan, 0.0)
    add_robot(packet, "blue", 0.0, 0.0)  # no robot_id
    add_robot(packet, "yellow", 0.0, 0.0, robot_id=3, orientation=0.0)
    out = decode_wrapper(packet.SerializeToString())
    assert out.frame.balls == () and [r.robot_id for r in out.frame.robots] == [3]
    kinds = [(p.kind, p.count) for p in out.problems]
    assert kinds.count(("bad_ball", 1)) == 32  # named one by one up to max_balls, the rest counted
    assert ("too_many_balls", 68) in kinds and ("bad_robot_id", 1) in kinds


GEOMETRY = FieldGeometry(9.0, 6.0, 0.3, 1.0, 0.18, ball_model=BallModelFromVision(-3.0, -0.26, 0.64),
                         cameras=(CameraPose(0, -2.0, 1.5, 4.0),), chip_model=ChipModelFromVision(0.5, 0.7, 0.9))


def test_geometry_round_trip_and_a_bad_ball_model_is_dropped():
    out = decode_wrapper(encode_geometry(GEOMETRY))
    assert out.frame is None and out.problems == []
    assert out.geometry == GEOMETRY
    packet = wrap.SSL_WrapperPacket.FromString(encode_geometry(GEOMETRY))
    packet.geometry.models.straight_two_phase.acc_roll = 0.5  # accelerates: not a ball model
    out = decode_wrapper(packet.SerializeToString())
    assert out.geometry.ball_model is None and out.problems[0].kind == "ball_model"
    assert "ball model dropped" in out.problems[0].text
    packet.geometry.field.field_length = 0
    out = decode_wrapper(packet.SerializeToString())
    assert out.geometry is None and out.problems[-1].kind == "geometry" and "field sizes" in out.problems[-1].text


def _varint(value: int) -> bytes:
    out = bytearray()
    while True:
        byte, value = value & 0x7F, value >> 7
        out.append(byte | (0x80 if value else 0))
        if not value:
            return bytes(out)


def _submessage(number: int, body: bytes) -> bytes:  # wire type 2: length-delimited
    return _varint(number << 3 | 2) + _varint(len(body)) + body


def test_a_hand_built_geometry_with_grsims_chip_model_decodes_by_the_leagues_field_numbers():
    """SSL_WrapperPacket.geometry (2) > SSL_GeometryData.field (1): field_length 1, field_width 2, goal_width 3,
    goal_depth 4, boundary_width 5 (int32 varints, mm); .models (3) > SSL_GeometryModels.chip_fixed_loss (2) >
    damping_xy_first_hop 1, damping_xy_other_hops 2, damping_z 3 (doubles, wire type 1): grSim's defaults 0.6, 0.96,
    0.42. No straight_two_phase: the chip model comes alone."""
    field = b"".join(_varint(n << 3) + _varint(v) for n, v in ((1, 12000), (2, 9000), (3, 1800), (4, 180), (5, 300)))
    chip = b"".join(_varint(n << 3 | 1) + struct.pack("<d", v) for n, v in ((1, 0.6), (2, 0.96), (3, 0.42)))
    datagram = _submessage(2, _submessage(1, field) + _submessage(3, _submessage(2, chip)))
    out = decode_wrapper(datagram)
    assert out.problems == [] and out.geometry.ball_model is None
    assert out.geometry.chip_model == ChipModelFromVision(damping_z=0.42, damping_xy_first_hop=0.6,
                                                          damping_xy_other_hops=0.96)
    assert (out.geometry.length_m, out.geometry.width_m, out.geometry.boundary_m) == (12.0, 9.0, 0.3)
    # our encoder writes the same fields: the same geometry back
    assert decode_wrapper(encode_geometry(out.geometry)).geometry == out.geometry


@pytest.mark.parametrize("damping_z, first_hop, other_hops", [(1.0, 0.6, 0.96), (0.42, -0.1, 0.96),
                                                              (0.42, 0.6, 1.5), (math.nan, 0.6, 0.96)])
def test_a_chip_model_that_is_none_is_dropped_by_name_and_the_rest_kept(damping_z, first_hop, other_hops):
    """A ball that keeps its whole vertical speed hops for ever (damping_z < 1); a fraction outside [0, 1] is no
    damping: the chip model is dropped and named, the field and the two-phase model stay."""
    packet = wrap.SSL_WrapperPacket.FromString(encode_geometry(GEOMETRY))
    c = packet.geometry.models.chip_fixed_loss
    c.damping_z, c.damping_xy_first_hop, c.damping_xy_other_hops = damping_z, first_hop, other_hops
    out = decode_wrapper(packet.SerializeToString())
    assert out.geometry.chip_model is None and out.geometry.ball_model == GEOMETRY.ball_model
    assert [p.kind for p in out.problems] == ["ball_model"] and "chip model dropped" in out.problems[0].text


def test_a_datagram_with_detection_and_geometry_gives_both():
    packet = wrap.SSL_WrapperPacket.FromString(encode_geometry(GEOMETRY))
    packet.MergeFrom(detection_packet())
    add_robot(packet, "yellow", 500.0, -250.0, robot_id=2, orientation=1.5)
    out = decode_wrapper(packet.SerializeToString())
    assert out.geometry == GEOMETRY and out.problems == []
    assert out.frame.robots == (RobotSighting("yellow", 2, 0.5, -0.25, 1.5, 1.0),)


def test_frame_round_trip():
    frame = CameraFrame(3, 11, 5.0, 5.02, (BallCandidate(0.5, -0.25, 0.5),),
                        (RobotSighting("yellow", 2, 1.0, -1.0, 0.5, 1.0),
                         RobotSighting("blue", 0, 0.0, 0.0, None, 1.0)))
    out = decode_wrapper(encode_frame(frame)).frame
    assert out.balls == frame.balls
    assert set(out.robots) == set(frame.robots)


# ------------------------------------------------------------------------------- vision clock
def test_the_offset_is_the_smallest_delay_seen():
    clock = VisionClock(window_s=2.0)
    offset = 1000.0  # ROS time = vision time + 1000 s
    delays = [0.004, 0.001, 0.003, 0.002, 0.005]
    for k in range(50):
        t_capture = 10.0 + k / 60.0
        t_sent = t_capture + 0.01
        stamp = clock.to_receiver(0, t_capture, t_sent, t_sent + offset + delays[k % 5])
    # after the 0.001 s sample: every stamp is the capture time + offset + 1 ms
    assert stamp == pytest.approx(t_capture + offset + 0.001, abs=1e-9)
    assert clock.offset_s(0) == pytest.approx(offset + 0.001, abs=1e-9)


def test_late_packets_keep_the_offset_and_clock_jumps_are_followed_once_confirmed():
    clock = VisionClock(window_s=2.0, jump_s=0.25, confirm_packets=5, confirm_s=0.19)  # 12 frame periods
    t_receive = 500.0
    for k in range(30):
        t_receive = 500.0 + k / 60.0
        clock.to_receiver(1, t_receive - 0.01, t_receive, t_receive)  # offset 0
    # a 0.5 s stall: its backlog of 20 frames arrives at once, each stamped with the offset it had
    stall_end = t_receive + 0.5
    for k in range(20):
        t_sent = t_receive + (k + 1) / 60.0
        assert clock.to_receiver(1, t_sent - 0.01, t_sent, stall_end) == pytest.approx(t_sent - 0.01, abs=1e-9)
    t_receive = stall_end
    assert clock.offset_s(1) == 0.0 and clock.jumps_confirmed == 0
    # the camera's clock steps back by 100 s: stamped with the old offset (too early: the tracker
    # drops them as late) until 5 frames over 0.19 s agree (the 13th); then the new offset
    stamps = []
    for _ in range(14):
        t_receive += 1 / 60.0
        stamps.append(clock.to_receiver(1, t_receive - 100.0 - 0.01, t_receive - 100.0, t_receive))
    assert stamps[0] == pytest.approx(t_receive - 13 / 60.0 - 100.01, abs=1e-9)
    assert stamps[-1] == pytest.approx(t_receive - 0.01, abs=1e-9) and clock.jumps_confirmed == 1
    # the clock steps forward again by 100 s: refused until confirmed, then followed
    refused = 0
    for _ in range(14):
        t_receive += 1 / 60.0
        try:
            stamp = clock.to_receiver(1, t_receive - 0.01, t_receive, t_receive)
        except ClockJump as exc:
            assert "camera 1: clock offset" in str(exc) and "jumped forward" in str(exc)
            refused += 1
    assert refused == 12 and stamp == pytest.approx(t_receive - 0.01, abs=1e-9)
    # a single bogus t_sent far ahead is refused and moves nothing
    with pytest.raises(ClockJump):
        clock.to_receiver(1, t_receive, t_receive + 1000.0, t_receive + 0.01)
    assert clock.offset_s(1) == pytest.approx(0.0, abs=1e-9)
    # other cameras keep their own offset
    assert clock.to_receiver(2, 1.0, 1.0, 3.0) == 3.0


def test_a_stamp_is_never_after_its_arrival():
    clock = VisionClock()
    clock.to_receiver(0, 10.0, 10.0, 10.0)
    assert clock.to_receiver(0, 10.5, 10.1, 10.1) == 10.1  # t_capture after t_sent: a broken sender


# -------------------------------------------------------------------------------------- fuzz
def _finite_out(out) -> bool:
    values = []
    if out.frame is not None:
        f = out.frame
        values += [f.t_capture_s, f.t_sent_s]
        values += [v for b in f.balls for v in (b.x_m, b.y_m, b.confidence)]
        values += [v for r in f.robots for v in (r.x_m, r.y_m, r.confidence, r.theta_rad or 0.0)]
    if out.geometry is not None:
        g = out.geometry
        values += [g.length_m, g.width_m, g.boundary_m]
        if g.ball_model is not None:
            values += [g.ball_model.a_slide_mps2, g.ball_model.a_roll_mps2, g.ball_model.c_switch]
    return all(math.isfinite(v) and abs(v) <= 1e10 for v in values)


@settings(max_examples=400, deadline=None)
@given(st.binary(max_size=300))
def test_fuzz_arbitrary_bytes(data):
    try:
        out = decode_wrapper(data)
    except SslDecodeError:
        return
    assert _finite_out(out)


floats = st.floats(allow_nan=True, allow_infinity=True, width=32)


@settings(max_examples=300, deadline=None)
@given(
    balls=st.lists(st.tuples(floats, floats, floats), max_size=40),
    robots=st.lists(st.tuples(st.sampled_from(["blue", "yellow"]), st.one_of(st.none(), st.integers(0, 2**32 - 1)),
                              floats, floats, st.one_of(st.none(), floats)), max_size=40),
    t_capture=st.floats(allow_nan=True, allow_infinity=True),
    camera_id=st.integers(0, 2**32 - 1),
    cut=st.integers(0, 10_000),
)
def test_fuzz_structured_frames_and_their_truncations(balls, robots, t_capture, camera_id, cut):
    packet = detection_packet(t_capture=t_capture, camera_id=camera_id)
    for x, y, c in balls:
        add_ball(packet, x, y, c)
    for team, rid, x, y, theta in robots:
        add_robot(packet, team, x, y, rid, theta)
    data = packet.SerializeToString()
    for chunk in (data, data[: cut % (len(data) + 1)]):
        try:
            out = decode_wrapper(chunk)
        except SslDecodeError:
            continue
        assert _finite_out(out)


@settings(max_examples=200, deadline=None)
@given(sizes=st.lists(st.integers(-2**31, 2**31 - 1), min_size=5, max_size=5),
       model=st.tuples(st.floats(), st.floats(), st.floats()), flip=st.integers(0, 10_000))
def test_fuzz_geometry(sizes, model, flip):
    packet = wrap.SSL_WrapperPacket()
    f = packet.geometry.field
    f.field_length, f.field_width, f.goal_width, f.goal_depth, f.boundary_width = sizes
    m = packet.geometry.models.straight_two_phase
    m.acc_slide, m.acc_roll, m.k_switch = model
    data = bytearray(packet.SerializeToString())
    for chunk in (bytes(data), bytes(data[: flip % len(data)]) + b"\x00" + bytes(data[flip % len(data):])):
        try:
            out = decode_wrapper(chunk)
        except SslDecodeError:
            continue
        assert _finite_out(out)
        if out.geometry is not None:
            assert out.geometry.length_m > 0 and out.geometry.width_m > 0


# Unknown fields of every wire type (field numbers the messages do not declare, and a declared number with
# another wire type, which the protobuf runtime keeps as unknown too), as bytes: key varint, then the value.
UNKNOWN_FIELDS = [
    bytes([9 << 3 | 0, 0x96, 0x01]),  # varint 150
    bytes([10 << 3 | 1]) + bytes(range(8)),  # eight bytes
    bytes([11 << 3 | 2, 3]) + b"abc",  # length-delimited
    bytes([12 << 3 | 5]) + bytes(4),  # four bytes
    bytes([13 << 3 | 3, 1 << 3 | 0, 5, 13 << 3 | 4]),  # a group holding a varint
    bytes([3 << 3 | 0, 7]),  # field 3 (x, a float) as a varint: unknown, x keeps its value
]


@settings(max_examples=200, deadline=None)
@given(
    balls=st.lists(st.tuples(st.floats(-9000, 9000, width=32), st.floats(-6000, 6000, width=32),
                             st.floats(0, 1, width=32), st.none() | st.floats(-500, 500, width=32)), max_size=4),
    robots=st.lists(st.tuples(st.sampled_from(["blue", "yellow"]), st.integers(0, 31),
                              st.floats(-9000, 9000, width=32), st.floats(-6000, 6000, width=32),
                              st.none() | st.floats(-3.0, 3.0, width=32), st.floats(0, 1, width=32)), max_size=12),
    unknown=st.lists(st.sampled_from(range(len(UNKNOWN_FIELDS))), max_size=3),
    split=st.integers(0, 16),
)
def test_the_compiled_pass_reads_what_the_protobuf_runtime_reads(balls, robots, unknown, split):
    """The detections as the runtime's message objects give them, against decode_wrapper's arrays; with
    unknown fields inside every detection and the frame, and the frame sent as two parts (merged)."""
    extra = b"".join(UNKNOWN_FIELDS[k] for k in unknown)
    det = wrap.SSL_WrapperPacket().detection
    for x, y, c, z in balls:
        b = det.balls.add()
        b.MergeFromString(_ball_bytes(x, y, c, z) + extra)
    for team, robot_id, x, y, theta, c in robots:
        r = (det.robots_blue if team == "blue" else det.robots_yellow).add()
        r.MergeFromString(_robot_bytes(robot_id, x, y, theta, c) + extra)
    first, second = detection_packet(), wrap.SSL_WrapperPacket()
    items = [(field, item) for field in ("balls", "robots_blue", "robots_yellow") for item in getattr(det, field)]
    for k, (field, item) in enumerate(items):  # the first `split` detections in the first part, the rest after
        getattr((first if k < split else second).detection, field).add().CopyFrom(item)
    data = first.SerializeToString() + extra + second.SerializePartialToString()  # the parts merge
    reference = wrap.SSL_WrapperPacket.FromString(data).detection
    out = decode_wrapper(data)
    assert out.problems == []
    arrays = out.detection
    assert (arrays.camera_id, arrays.frame_number, arrays.t_capture_s) == (2, 7, 100.0)
    assert arrays.balls.tolist() == [[b.x * 1e-3, b.y * 1e-3, b.confidence, b.z * 1e-3] for b in reference.balls]
    expected = [
        [team, r.robot_id, r.x * 1e-3, r.y * 1e-3, r.orientation if r.HasField("orientation") else math.nan,
         r.confidence]
        for team, sightings in ((0.0, reference.robots_blue), (1.0, reference.robots_yellow)) for r in sightings
    ]
    got = arrays.robots.tolist()
    assert len(got) == len(expected)
    for row, want in zip(got, expected, strict=True):
        assert row[:4] + row[5:] == want[:4] + want[5:]
        assert row[4] == want[4] or (math.isnan(row[4]) and math.isnan(want[4]))


def _ball_bytes(x, y, c, z) -> bytes:
    ball = wrap.SSL_WrapperPacket().detection.balls.add(confidence=c, x=x, y=y, pixel_x=0.0, pixel_y=0.0)
    if z is not None:
        ball.z = z
    return ball.SerializePartialToString()


def _robot_bytes(robot_id, x, y, theta, c) -> bytes:
    robot = wrap.SSL_WrapperPacket().detection.robots_blue.add(confidence=c, robot_id=robot_id, x=x, y=y,
                                                                 pixel_x=0.0, pixel_y=0.0)
    if theta is not None:
        robot.orientation = theta
    return robot.SerializePartialToString()


@settings(max_examples=500, deadline=None)
@given(edits=st.lists(st.tuples(st.integers(0, 10_000), st.integers(0, 255), st.sampled_from(["set", "insert", "cut"])),
                      min_size=1, max_size=4),
       tail=st.sampled_from([b""] + UNKNOWN_FIELDS + [bytes([0 << 3 | 0, 1]), bytes([13 << 3 | 3, 14 << 3 | 4]),
                                                      bytes([2 << 3 | 2, 0])]))
def test_what_the_compiled_pass_accepts_the_protobuf_runtime_accepts(edits, tail):
    """Byte edits of a valid frame (and a tail: unknown fields, field number 0, a group ended by another
    number, an empty geometry): a datagram the pass takes without the runtime is one the runtime
    parses completely, with a detection and without geometry; the pass reads the same frame from it."""
    from erforce_interfaces.ssl import ssl_vision

    packet = detection_packet()
    add_ball(packet, 100.0, 200.0)
    add_robot(packet, "blue", 300.0, -400.0, robot_id=3, orientation=0.5)
    add_robot(packet, "yellow", -300.0, 400.0, robot_id=5)
    data = bytearray(packet.SerializeToString() + tail)
    for at, value, how in edits:
        at %= len(data) + 1
        if how == "set" and at < len(data):
            data[at] = value
        elif how == "insert":
            data.insert(at, value)
        elif how == "cut":
            del data[at:]
        if not data:
            return
    data = bytes(data)
    limits = ssl_vision.DecodeLimits()
    out = np.empty(ssl_vision.detection_rows_size(limits.max_balls, limits.max_robots_per_team))
    status, *_, geometry = ssl_vision.detection_rows(
        data, out, limits.max_balls, limits.max_robots_per_team, limits.max_abs_coordinate_m / ssl_vision.MM,
        limits.max_robot_id, limits.max_camera_id, limits.max_time_s)
    if status == ssl_vision._DECLINED or geometry:
        return
    runtime = wrap.SSL_WrapperPacket()
    runtime.ParseFromString(data)  # raises DecodeError if the pass took what the runtime refuses
    assert runtime.IsInitialized() and runtime.HasField("detection") and not runtime.HasField("geometry")
    det = runtime.detection
    if status != 0:  # a frame the checks refuse (a NaN stamp, a camera id): named by _frame_error
        return
    assert out[:4].tolist() == [det.frame_number, det.t_capture, det.t_sent, det.camera_id]
    assert out[4:7].tolist() == [len(det.balls), len(det.robots_blue), len(det.robots_yellow)]
