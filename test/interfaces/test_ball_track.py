"""/ball/track: the ball for observers as a sensor_msgs/PointCloud2 of one point, its bytes and its checks."""

import struct

import pytest
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import PointCloud2
from test_vision_robots import _field, cloud

from erforce_interfaces.wire import clouds
from erforce_interfaces.wire import contract as c
from erforce_interfaces.wire import conversions as conv

FIELD_NAMES = ("x", "y", "z", "vx_mps", "vy_mps", "v_shoot_mps", "seen_x_m", "seen_y_m", "phase", "uncertain")
TRACK = clouds.BallTrack(12.5, 1.5, -2.0, 3.0, -0.25, 4.5, 1.51, -2.02, "rolling", True)
# At 12.5 s, the ball rolling at (1.5, -2.0) with (3.0, -0.25) m/s, v_shoot 4.5 m/s, seen at (1.51, -2.02); rolling
# is BALL_PHASES[2]. Payload offsets: stamp 0; frame_id "field" 8; height 20; width 24; 10 fields from 28 (244 bytes:
# names of 2, 2, 2, 7, 7, 12, 9, 9, 6 and 10 bytes with their NUL); is_bigendian 276 (3 bytes padding); point_step
# 280; row_step 284; data 288 (length) and 292 (80 bytes); is_dense 372.
HAND = (b"\x00\x01\x00\x00" + struct.pack("<iI", 12, 500_000_000) + struct.pack("<I", 6) + b"field\x00" + bytes(2)
        + struct.pack("<III", 1, 1, 10)
        + b"".join(_field(name.encode(), 8 * k) for k, name in enumerate(FIELD_NAMES))
        + b"\x00" + bytes(3) + struct.pack("<III", 80, 80, 80)
        + struct.pack("<10d", 1.5, -2.0, 0.0, 3.0, -0.25, 4.5, 1.51, -2.02, 2.0, 1.0) + b"\x01")


def test_the_topic_and_its_fields_are_in_the_contract():
    assert c.BALL_TRACK.name == "/ball/track" and c.BALL_TRACK.msg_type is PointCloud2
    assert c.BALL_TRACK.qos is c.QOS_SENSOR and c.BALL_TRACK_FIELDS == FIELD_NAMES
    assert c.topic_of_name("/ball/track") is c.BALL_TRACK and c.BALL_PHASES[2] == "rolling"


def test_bytes_match_a_hand_made_layout_and_read_back():
    assert len(HAND) == 4 + 373
    assert clouds.ball_track_cdr(TRACK) == HAND
    assert clouds.ball_track_from_msg(HAND) == TRACK
    msg = deserialize_message(HAND, PointCloud2)  # rclpy reads our bytes as the cloud we meant
    assert msg == cloud(12.5, [(1.5, -2.0, 0.0, 3.0, -0.25, 4.5, 1.51, -2.02, 2.0, 1.0)], fields=FIELD_NAMES)
    assert clouds.ball_track_from_msg(msg) == TRACK
    assert clouds.ball_track_from_msg(serialize_message(msg)) == TRACK  # rclpy's padding bytes are garbage


@pytest.mark.parametrize("change", [
    dict(fields=FIELD_NAMES[:-1] + ("certain",)),  # another layout
    dict(point=(1.5, -2.0, 0.0, 3.0, -0.25, 4.5, 1.51, -2.02, 6.0, 1.0)),  # no such phase
    dict(point=(1.5, -2.0, 0.0, 3.0, -0.25, 4.5, 1.51, -2.02, 2.5, 1.0)),
    dict(point=(1.5, -2.0, 0.0, 3.0, -0.25, 4.5, 1.51, -2.02, 2.0, 0.5)),  # uncertain is 1 or 0
    dict(point=(float("nan"), -2.0, 0.0, 3.0, -0.25, 4.5, 1.51, -2.02, 2.0, 1.0)),
    dict(point=(1.5, -2.0, 0.0, 3.0, 1e4, 4.5, 1.51, -2.02, 2.0, 1.0)),
    dict(points=2),
])
def test_another_layout_or_a_bad_value_is_refused(change):
    point = change.get("point", (1.5, -2.0, 0.0, 3.0, -0.25, 4.5, 1.51, -2.02, 2.0, 1.0))
    msg = cloud(12.5, [point] * change.get("points", 1), fields=change.get("fields", FIELD_NAMES))
    for form in (msg, serialize_message(msg)):
        with pytest.raises(conv.ConversionError):
            clouds.ball_track_from_msg(form)


def test_a_bad_value_is_not_published():
    with pytest.raises(conv.ConversionError, match="phase"):
        clouds.ball_track_cdr(TRACK._replace(phase="flying"))
    with pytest.raises(conv.ConversionError, match="vx_mps"):
        clouds.ball_track_cdr(TRACK._replace(vx_mps=float("inf")))


def test_a_chip_in_the_air_carries_its_height_in_z():
    chip = TRACK._replace(phase="chip", z_m=0.42)
    data = clouds.ball_track_cdr(chip)
    assert data == HAND.replace(struct.pack("<3d", 1.5, -2.0, 0.0), struct.pack("<3d", 1.5, -2.0, 0.42)).replace(
        struct.pack("<2d", 2.0, 1.0), struct.pack("<2d", float(c.BALL_PHASES.index("chip")), 1.0))
    assert c.BALL_PHASES.index("chip") == 4  # after the flat phases: their indices stay
    assert clouds.ball_track_from_msg(data) == chip
