"""Byte compatibility of our SSL-Vision definitions with the league's wire format.

The fixtures are written by hand from the documented field numbers and wire types (a tag is
``field_number << 3 | wire_type``; wire type 0 varint, 1 fixed64, 2 length-delimited, 5 fixed32),
not produced by our own encoder, so a wrong field number or type in a ``.proto`` file fails here.
"""

from __future__ import annotations

import struct
import subprocess
import sys

import pytest
from google.protobuf import unknown_fields
from google.protobuf.message import DecodeError

from erforce_interfaces.ssl.ssl_proto import ssl_vision_detection_pb2 as det
from erforce_interfaces.ssl.ssl_proto import ssl_vision_geometry_pb2 as geo
from erforce_interfaces.ssl.ssl_proto import ssl_vision_wrapper_pb2 as wrap


def f32(tag: int, value: float) -> bytes:
    return bytes([tag]) + struct.pack("<f", value)


def f64(tag: int, value: float) -> bytes:
    return bytes([tag]) + struct.pack("<d", value)


def sub(tag: int, payload: bytes) -> bytes:
    assert len(payload) < 128  # one-byte length varint
    return bytes([tag, len(payload)]) + payload


# SSL_DetectionBall: confidence=1 (0x0D), area=2 varint (0x10), x=3 (0x1D), y=4 (0x25), z=5 (0x2D),
# pixel_x=6 (0x35), pixel_y=7 (0x3D).
BALL = (
    f32(0x0D, 0.75)
    + b"\x10\x96\x01"  # area 150 = 0x96 0x01 as a varint
    + f32(0x1D, 1250.0)
    + f32(0x25, -300.5)
    + f32(0x2D, 21.5)
    + f32(0x35, 320.0)
    + f32(0x3D, 240.0)
)
# SSL_DetectionRobot: confidence=1, robot_id=2 varint, x=3, y=4, orientation=5, pixel_x=6, pixel_y=7,
# height=8 (0x45).
ROBOT = (
    f32(0x0D, 1.0)
    + b"\x10\x07"
    + f32(0x1D, -2000.0)
    + f32(0x25, 1000.0)
    + f32(0x2D, 1.5)
    + f32(0x35, 10.0)
    + f32(0x3D, 20.0)
    + f32(0x45, 150.0)
)
# SSL_DetectionFrame: frame_number=1 varint (0x08), t_capture=2 fixed64 (0x11), t_sent=3 (0x19),
# camera_id=4 varint (0x20), balls=5 (0x2A), robots_yellow=6 (0x32), robots_blue=7 (0x3A),
# t_capture_camera=8 fixed64 (0x41).
FRAME = (
    b"\x08\xac\x02"  # frame 300
    + f64(0x11, 1700000000.25)
    + f64(0x19, 1700000000.265)
    + b"\x20\x03"
    + sub(0x2A, BALL)
    + sub(0x3A, ROBOT)
    + f64(0x41, 12.5)
)
# SSL_WrapperPacket: detection=1 (0x0A), geometry=2 (0x12).
WRAPPER_DETECTION = sub(0x0A, FRAME)

# Geometry. SSL_GeometryFieldSize: field_length..boundary_width = 1..5 varints (0x08 0x10 0x18 0x20 0x28),
# field_lines=6 (0x32), field_arcs=7 (0x3A), penalty_area_depth=8 (0x40), ball_radius=14 fixed32 (0x75).
VEC_P1 = f32(0x0D, -4500.0) + f32(0x15, 3000.0)  # Vector2f x=1, y=2
VEC_P2 = f32(0x0D, 4500.0) + f32(0x15, 3000.0)
LINE = b"\x0a\x0cTopTouchLine" + sub(0x12, VEC_P1) + sub(0x1A, VEC_P2) + f32(0x25, 10.0) + b"\x28\x02"
ARC = (
    b"\x0a\x0cCenterCircle"
    + sub(0x12, f32(0x0D, 0.0) + f32(0x15, 0.0))
    + f32(0x1D, 500.0)  # radius=3
    + f32(0x25, 0.0)  # a1=4
    + f32(0x2D, 6.25)  # a2=5
    + f32(0x35, 10.0)  # thickness=6
    + b"\x38\x01"  # type=7 CenterCircle
)
FIELD = (
    b"\x08\xa8\x46"  # 9000
    + b"\x10\xf0\x2e"  # 6000
    + b"\x18\xe8\x07"  # 1000
    + b"\x20\xb4\x01"  # 180
    + b"\x28\xac\x02"  # 300
    + sub(0x32, LINE)
    + sub(0x3A, ARC)
    + b"\x40\xe8\x07"  # penalty_area_depth 1000
    + f32(0x75, 21.5)
)
# SSL_GeometryCameraCalibration: camera_id=1 varint, focal_length=2 .. tz=12 fixed32,
# derived_camera_world_tz=15 fixed32 (0x7D), pixel_image_width=16 varint (two-byte tag 0x80 0x01).
CALIB = (
    b"\x08\x02"
    + f32(0x15, 400.0)
    + f32(0x1D, 390.0)
    + f32(0x25, 290.0)
    + f32(0x2D, 0.1)
    + f32(0x35, 0.0)
    + f32(0x3D, 1.0)
    + f32(0x45, 0.0)
    + f32(0x4D, 0.0)
    + f32(0x55, 100.0)
    + f32(0x5D, 200.0)
    + f32(0x65, 4000.0)
    + f32(0x7D, 4000.0)
    + b"\x80\x01\x80\x06"  # pixel_image_width 768
)
# SSL_BallModelStraightTwoPhase: acc_slide=1, acc_roll=2, k_switch=3, all doubles (fixed64).
TWO_PHASE = f64(0x09, -3.0) + f64(0x11, -0.26) + f64(0x19, 0.64)
# SSL_BallModelChipFixedLoss: damping_xy_first_hop=1, damping_xy_other_hops=2, damping_z=3, doubles.
CHIP = f64(0x09, 0.75) + f64(0x11, 0.95) + f64(0x19, 0.5)
MODELS = sub(0x0A, TWO_PHASE) + sub(0x12, CHIP)
GEOMETRY = sub(0x0A, FIELD) + sub(0x12, CALIB) + sub(0x1A, MODELS)
WRAPPER_GEOMETRY = bytes([0x12]) + bytes([len(GEOMETRY) & 0x7F | 0x80, len(GEOMETRY) >> 7]) + GEOMETRY


def f32_round(value: float) -> float:
    return struct.unpack("<f", struct.pack("<f", value))[0]


def test_hand_written_detection_decodes_field_by_field():
    packet = wrap.SSL_WrapperPacket.FromString(WRAPPER_DETECTION)
    assert packet.HasField("detection") and not packet.HasField("geometry")
    frame = packet.detection
    assert frame.frame_number == 300
    assert frame.t_capture == 1700000000.25
    assert frame.t_sent == 1700000000.265
    assert frame.t_capture_camera == 12.5
    assert frame.camera_id == 3
    (ball,) = frame.balls
    assert (ball.confidence, ball.area, ball.x, ball.y, ball.z) == (0.75, 150, 1250.0, -300.5, 21.5)
    assert (ball.pixel_x, ball.pixel_y) == (320.0, 240.0)
    assert len(frame.robots_yellow) == 0
    (robot,) = frame.robots_blue
    assert (robot.robot_id, robot.x, robot.y, robot.orientation, robot.height) == (7, -2000.0, 1000.0, 1.5, 150.0)


def test_hand_written_geometry_decodes_field_by_field():
    geometry = wrap.SSL_WrapperPacket.FromString(WRAPPER_GEOMETRY).geometry
    field = geometry.field
    assert (field.field_length, field.field_width, field.goal_width, field.goal_depth) == (9000, 6000, 1000, 180)
    assert field.boundary_width == 300 and field.penalty_area_depth == 1000 and field.ball_radius == 21.5
    (line,) = field.field_lines
    assert line.name == "TopTouchLine" and line.type == geo.TopTouchLine
    assert (line.p1.x, line.p1.y, line.p2.x, line.p2.y, line.thickness) == (-4500.0, 3000.0, 4500.0, 3000.0, 10.0)
    (arc,) = field.field_arcs
    assert arc.name == "CenterCircle" and arc.type == geo.CenterCircle
    assert (arc.radius, arc.a1, arc.a2, arc.thickness) == (500.0, 0.0, 6.25, 10.0)
    (calib,) = geometry.calib
    assert calib.camera_id == 2 and calib.focal_length == 400.0 and calib.distortion == f32_round(0.1)
    assert (calib.q1, calib.tx, calib.ty, calib.tz) == (1.0, 100.0, 200.0, 4000.0)
    assert calib.derived_camera_world_tz == 4000.0 and calib.pixel_image_width == 768
    two_phase = geometry.models.straight_two_phase
    assert (two_phase.acc_slide, two_phase.acc_roll, two_phase.k_switch) == (-3.0, -0.26, 0.64)
    chip = geometry.models.chip_fixed_loss
    assert (chip.damping_xy_first_hop, chip.damping_xy_other_hops, chip.damping_z) == (0.75, 0.95, 0.5)


def test_our_encoding_equals_the_hand_bytes():
    # protobuf writes fields in field-number order; the hand fixtures list t_capture_camera (8) last
    # and the ball's fields in order, so build the same frame and compare byte for byte.
    frame = det.SSL_DetectionFrame(frame_number=300, t_capture=1700000000.25, t_sent=1700000000.265, camera_id=3)
    frame.balls.add(confidence=0.75, area=150, x=1250.0, y=-300.5, z=21.5, pixel_x=320.0, pixel_y=240.0)
    frame.robots_blue.add(
        confidence=1.0, robot_id=7, x=-2000.0, y=1000.0, orientation=1.5, pixel_x=10.0, pixel_y=20.0, height=150.0
    )
    frame.t_capture_camera = 12.5
    assert wrap.SSL_WrapperPacket(detection=frame).SerializeToString() == WRAPPER_DETECTION

    models = geo.SSL_GeometryModels()
    models.straight_two_phase.acc_slide = -3.0
    models.straight_two_phase.acc_roll = -0.26
    models.straight_two_phase.k_switch = 0.64
    models.chip_fixed_loss.damping_xy_first_hop = 0.75
    models.chip_fixed_loss.damping_xy_other_hops = 0.95
    models.chip_fixed_loss.damping_z = 0.5
    assert models.SerializeToString() == MODELS


def test_the_newer_geometry_and_wrapper_fields_have_their_numbers():
    # SSL_GeometryFieldSize boundary_width_goal_line = 16 (varint, tag 16 << 3 = 128: 80 01) 250 (fa 01),
    # goal_substitution_area_width = 17 (tag 136: 88 01) 1200 (b0 09); SSL_WrapperPacket source = 3 (varint,
    # tag 0x18) SSL_SOURCE_GRSIM = 4
    field = FIELD + b"\x80\x01\xfa\x01" + b"\x88\x01\xb0\x09"
    assert 128 <= len(field) < 256 and len(field) + 3 < 256  # two-byte length varints: low 7 bits | 0x80, 1
    geometry = bytes([0x0A, len(field) - 128 | 0x80, 1]) + field
    data = bytes([0x12, len(geometry) - 128 | 0x80, 1]) + geometry + b"\x18\x04"
    packet = wrap.SSL_WrapperPacket.FromString(data)
    assert packet.geometry.field.boundary_width_goal_line == 250
    assert packet.geometry.field.goal_substitution_area_width == 1200
    assert packet.source == wrap.SSL_SOURCE_GRSIM
    assert len(unknown_fields.UnknownFieldSet(packet)) == 0
    assert len(unknown_fields.UnknownFieldSet(packet.geometry.field)) == 0


def test_the_same_frame_from_yellow_uses_field_six():
    frame = det.SSL_DetectionFrame(frame_number=1, t_capture=0.0, t_sent=0.0, camera_id=0)
    frame.robots_yellow.add(confidence=1.0, x=0.0, y=0.0, pixel_x=0.0, pixel_y=0.0)
    encoded = frame.SerializeToString()
    robot = f32(0x0D, 1.0) + f32(0x1D, 0.0) + f32(0x25, 0.0) + f32(0x35, 0.0) + f32(0x3D, 0.0)
    assert encoded == b"\x08\x01" + f64(0x11, 0.0) + f64(0x19, 0.0) + b"\x20\x00" + sub(0x32, robot)


def test_a_frame_without_its_required_fields_is_reported_and_a_truncated_one_rejected():
    packet = wrap.SSL_WrapperPacket.FromString(sub(0x0A, b"\x08\x01"))  # only frame_number
    assert not packet.IsInitialized()
    assert packet.FindInitializationErrors() == ["detection.t_capture", "detection.t_sent", "detection.camera_id"]
    with pytest.raises(DecodeError):
        wrap.SSL_WrapperPacket.FromString(WRAPPER_DETECTION[:-3])


def test_generated_modules_are_current():
    result = subprocess.run(
        [sys.executable, "-m", "erforce_interfaces.ssl.ssl_proto.generate", "--check"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 0, result.stderr
