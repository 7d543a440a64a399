"""The simulator protocols and the referee message on the wire: byte fixtures written by hand from the
documented field numbers and wire types (tag = field << 3 | wire type; 0 varint, 1 fixed64,
2 length-delimited, 5 fixed32; floats little-endian IEEE 754), and hypothesis fuzz of every decoder."""

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from erforce_interfaces.ssl import ssl_sim
from erforce_interfaces.ssl.ssl_proto import (
    grsim_pb2,
    ssl_gc_referee_message_pb2,
    ssl_simulation_control_pb2,
    ssl_simulation_error_pb2,
    ssl_simulation_robot_control_pb2,
    ssl_simulation_robot_feedback_pb2,
    ssl_simulation_synchronous_pb2,
)
from erforce_interfaces.ssl.ssl_sim import RobotCommand, SimError, WireError

F1_0 = bytes.fromhex("0000803f")  # 1.0f
FM0_5 = bytes.fromhex("000000bf")  # -0.5f
F2_0 = bytes.fromhex("00000040")  # 2.0f
F4_0 = bytes.fromhex("00008040")  # 4.0f
F0 = bytes(4)
D1_5 = bytes.fromhex("000000000000f83f")  # 1.5 (double)


def length(body: bytes) -> bytes:
    assert len(body) < 128  # one varint byte
    return bytes([len(body)]) + body


# RobotControl { robot_commands: [ { id: 3, move_command { local_velocity { 1.0, -0.5, 2.0 } },
#                                    kick_speed: 4.0, kick_angle: 0, dribbler_speed: 0 } ] }
LOCAL = b"\x0d" + F1_0 + b"\x15" + FM0_5 + b"\x1d" + F2_0
MOVE = b"\x12" + length(LOCAL)
ROBOT_COMMAND = b"\x08\x03" + b"\x12" + length(MOVE) + b"\x1d" + F4_0 + b"\x25" + F0 + b"\x2d" + F0
ROBOT_CONTROL = b"\x0a" + length(ROBOT_COMMAND)


def test_robot_control_encoding_equals_the_hand_bytes():
    cmd = RobotCommand(3, forward_mps=1.0, left_mps=-0.5, angular_radps=2.0, kick_speed_mps=4.0)
    assert ssl_sim.encode_robot_control([cmd]) == ROBOT_CONTROL


# A chip: kick_speed 4.0 (the ball's speed in 3D) at kick_angle 45.0 deg (field 4, fixed32: tag 0x25; 45.0f is
# 0x42340000), no move command; as the ssl-simulation-protocol's RobotCommand numbers them.
F45_0 = bytes.fromhex("00003442")
CHIP_CONTROL = b"\x0a" + length(b"\x08\x02" + b"\x12" + length(b"\x12" + length(b"\x0d" + F0 + b"\x15" + F0
                                                                                  + b"\x1d" + F0))
                                + b"\x1d" + F4_0 + b"\x25" + F45_0 + b"\x2d" + F0)


def test_a_chip_goes_out_as_kick_speed_and_kick_angle_and_decodes_back():
    cmd = RobotCommand(2, kick_speed_mps=4.0, kick_angle_deg=45.0)
    assert ssl_sim.encode_robot_control([cmd]) == CHIP_CONTROL
    (req,) = ssl_sim.decode_robot_control(CHIP_CONTROL)
    assert (req.robot_id, req.kick_speed_mps, req.kick_angle_deg) == (2, 4.0, 45.0)
    for bad in (-1.0, 90.0, math.nan):
        with pytest.raises(ValueError, match="kick_angle_deg"):
            RobotCommand(2, kick_speed_mps=4.0, kick_angle_deg=bad)


def test_a_chip_goes_to_grsim_as_the_balls_velocity_along_the_carpet_and_upwards():
    """grSim_Robot_Command: kickspeedx (field 2) and kickspeedz (field 3), the ball's horizontal and vertical speed.
    4 m/s at 30 deg: 4 cos 30 = 3.4641016 (0x405db3d7) along the carpet, 4 sin 30 = 2.0 upwards."""
    robot = (b"\x08\x05" + b"\x15" + bytes.fromhex("d7b35d40") + b"\x1d" + F2_0 + b"\x25" + F0 + b"\x2d" + F0
             + b"\x35" + F0 + b"\x38\x00" + b"\x40\x00")
    hand = b"\x0a" + length(b"\x09" + D1_5 + b"\x10\x00" + b"\x1a" + length(robot))
    cmd = RobotCommand(5, kick_speed_mps=4.0, kick_angle_deg=30.0)
    assert ssl_sim.encode_grsim_commands([cmd], "blue", timestamp_s=1.5) == hand


def test_robot_control_hand_bytes_decode_to_a_local_move():
    (req,) = ssl_sim.decode_robot_control(ROBOT_CONTROL)
    assert (req.robot_id, req.kind, req.velocity) == (3, "local", (1.0, -0.5, 2.0))
    assert (req.kick_speed_mps, req.kick_angle_deg, req.dribbler_rpm) == (4.0, 0.0, 0.0)


def test_global_and_wheel_moves_decode_from_their_oneof_numbers():
    glob = b"\x1a" + length(b"\x0d" + F1_0 + b"\x15" + F2_0 + b"\x1d" + FM0_5)  # field 3: global
    wheel = b"\x0a" + length(b"\x0d" + F1_0 + b"\x15" + F2_0 + b"\x1d" + F4_0 + b"\x25" + FM0_5)  # field 1
    data = b"".join(b"\x0a" + length(b"\x08" + bytes([i]) + b"\x12" + length(m)) for i, m in ((1, glob), (2, wheel)))
    a, b = ssl_sim.decode_robot_control(data)
    assert (a.robot_id, a.kind, a.velocity) == (1, "global", (1.0, 2.0, -0.5))
    assert (b.robot_id, b.kind, b.velocity) == (2, "wheel", (1.0, 2.0, 4.0, -0.5))  # fr, br, bl, fl


def test_dribbler_goes_out_in_rpm():
    cmd = RobotCommand(0, dribbler_radps=2 * math.pi)  # one turn per second = 60 rpm
    msg = ssl_simulation_robot_control_pb2.RobotControl.FromString(ssl_sim.encode_robot_control([cmd]))
    assert msg.robot_commands[0].dribbler_speed == pytest.approx(60.0)


def test_grsim_packet_encoding_equals_the_hand_bytes():
    robot = (b"\x08\x05" + b"\x15" + F4_0 + b"\x1d" + F0 + b"\x25" + F1_0 + b"\x2d" + FM0_5 + b"\x35" + F2_0
             + b"\x38\x01" + b"\x40\x00")
    commands = b"\x09" + D1_5 + b"\x10\x01" + b"\x1a" + length(robot)
    hand = b"\x0a" + length(commands)
    cmd = RobotCommand(5, forward_mps=1.0, left_mps=-0.5, angular_radps=2.0, kick_speed_mps=4.0, dribbler_radps=10.0)
    assert ssl_sim.encode_grsim_commands([cmd], "yellow", timestamp_s=1.5) == hand
    assert grsim_pb2.grSim_Packet.FromString(hand).commands.robot_commands[0].veltangent == 1.0


# SimulatorError {code: "X", message: "Y"}: code = 1 (tag 1 << 3 | 2 = 0x0a), message = 2 (2 << 3 | 2 = 0x12)
SIMULATOR_ERROR_X_Y = bytes.fromhex("0a0158" "120159")


def test_simulator_error_hand_bytes_are_code_1_and_message_2():
    error = ssl_simulation_error_pb2.SimulatorError.FromString(SIMULATOR_ERROR_X_Y)
    assert (error.code, error.message) == ("X", "Y")
    assert ssl_simulation_error_pb2.SimulatorError(code="X", message="Y").SerializeToString() == SIMULATOR_ERROR_X_Y
    # a message without a code, as a simulator may send one
    only_message = b"\x0a" + length(b"\x12" + length(b"only text"))
    assert ssl_sim.decode_simulator_response(only_message) == ("no code: only text",)


def test_robot_control_response_hand_bytes_decode():
    error = b"\x0a" + length(b"E1") + b"\x12" + length(b"no wheels")
    feedback = [b"\x08\x04\x10\x01", b"\x08\x07\x10\x00", b"\x08\x09"]  # id 9 says nothing about contact
    data = b"\x0a" + length(error) + b"\x0a" + length(SIMULATOR_ERROR_X_Y) + b"".join(b"\x12" + length(f)
                                                                                  for f in feedback)
    fb = ssl_sim.decode_robot_control_response(data)
    assert fb.ball_contact == {4: True, 7: False}
    assert fb.errors == ("E1: no wheels", "X: Y")


def test_a_long_error_text_is_cut_for_the_log():
    message = b"m" * 1000
    error = bytes([0x12, 0xe8, 0x07]) + message  # message (2), length 1000 = varint e8 07
    (text,) = ssl_sim.decode_simulator_response(b"\x0a" + bytes([0xeb, 0x07]) + error)  # 3 + 1000 = 1003
    assert text.startswith("no code: mmm") and text.endswith("(1009 characters)")
    assert len(text) < ssl_sim.MAX_ERROR_TEXT_CHARS + 30


def test_robot_control_response_encoding_equals_the_hand_bytes():
    error = b"\x0a" + length(b"ERFORCE_UNSUPPORTED") + b"\x12" + length(b"x")
    hand = b"\x0a" + length(error) + b"\x12" + length(b"\x08\x01\x10\x01") + b"\x12" + length(b"\x08\x02\x10\x00")
    errors = [SimError(ssl_sim.ERROR_UNSUPPORTED, "x")]
    out = ssl_sim.encode_robot_control_response({2: False, 1: True}, errors)
    assert out == hand


def test_grsim_robot_status_hand_bytes_decode():
    status = [b"\x08\x03\x10\x01\x18\x00\x20\x00", b"\x08\x00\x10\x00\x18\x01\x20\x00"]
    data = b"".join(b"\x0a" + length(s) for s in status)
    assert ssl_sim.decode_grsim_robots_status(data).ball_contact == {3: True, 0: False}


def test_simulator_command_hand_bytes_decode_to_teleports():
    ball = b"\x0d" + F1_0 + b"\x15" + FM0_5 + b"\x25" + F2_0 + b"\x2d" + F0
    robot_id = b"\x08\x02\x10\x02"  # id 2, team BLUE (2)
    robot = b"\x0a" + length(robot_id) + b"\x15" + F1_0 + b"\x1d" + F2_0 + b"\x40\x01"  # x, y, present
    control = b"\x0a" + length(ball) + b"\x12" + length(robot) + b"\x1d" + F2_0  # simulation_speed 2
    req = ssl_sim.decode_simulator_command(b"\x0a" + length(control))
    assert req.ball == (1.0, -0.5, 2.0, 0.0) and req.ball_unsupported == ()
    (r,) = req.robots
    assert (r.team, r.robot_id, r.x_m, r.y_m, r.yaw_rad, r.present) == ("blue", 2, 1.0, 2.0, None, True)
    assert req.simulation_speed == 2.0 and not req.has_config


def test_synchronous_request_and_response_have_their_numbers():
    # SimulationSyncRequest: sim_step = 1 (fixed32, tag 0x0d) 1.0, robot_control = 3 (tag 0x1a): ROBOT_CONTROL
    request = ssl_simulation_synchronous_pb2.SimulationSyncRequest.FromString(
        b"\x0d" + F1_0 + b"\x1a" + length(ROBOT_CONTROL))
    assert request.sim_step == 1.0 and request.robot_control.robot_commands[0].id == 3
    # SimulationSyncResponse: robot_control_response = 2 (tag 0x12) {errors = 1 {SIMULATOR_ERROR_X_Y}}
    response = ssl_simulation_synchronous_pb2.SimulationSyncResponse.FromString(
        b"\x12" + length(b"\x0a" + length(SIMULATOR_ERROR_X_Y)))
    (error,) = response.robot_control_response.errors
    assert (error.code, error.message) == ("X", "Y") and len(response.detection) == 0


def test_simulator_command_reads_a_config_as_field_2():
    # SimulatorCommand.config = 2 (0x12): SimulatorConfig {vision_port = 4 (varint, tag 0x20): 10020 = a4 4e}
    config = b"\x12" + length(b"\x20\xa4\x4e")
    assert ssl_sim.decode_simulator_command(config).has_config
    assert ssl_simulation_control_pb2.SimulatorCommand.FromString(config).config.vision_port == 10020


def test_teleport_encoding_equals_the_hand_bytes():
    ball = b"\x0d" + F1_0 + b"\x15" + FM0_5 + b"\x25" + F2_0 + b"\x2d" + F0 + b"\x40\x01"  # roll = true
    robot = b"\x0a" + length(b"\x08\x01\x10\x01") + b"\x15" + F1_0 + b"\x1d" + F2_0 + b"\x25" + F0 + b"\x40\x01"
    hand = b"\x0a" + length(b"\x0a" + length(ball) + b"\x12" + length(robot))
    assert ssl_sim.encode_teleport((1.0, -0.5, 2.0, 0.0), [("yellow", 1, 1.0, 2.0, 0.0)]) == hand


def test_a_ball_placed_at_rest_is_not_asked_to_roll():
    # TeleportBall {x = 1 (0x0d), y = 2 (0x15), vx = 4 (0x25), vy = 5 (0x2d)} and no roll = 8 (0x40): grSim answers
    # every roll with GRSIM_UNSUPPORTED_ROLL_BALL, and a ball at rest has nothing to roll
    ball = b"\x0d" + F1_0 + b"\x15" + FM0_5 + b"\x25" + F0 + b"\x2d" + F0
    assert ssl_sim.encode_teleport((1.0, -0.5, 0.0, 0.0)) == b"\x0a" + length(b"\x0a" + length(ball))


def test_grsim_replacement_encoding_equals_the_hand_bytes():
    d0, dm1, d2, d90 = bytes(8), bytes.fromhex("000000000000f0bf"), bytes.fromhex("0000000000000040"), \
        bytes.fromhex("0000000000805640")  # 0.0, -1.0, 2.0, 90.0 (doubles)
    ball = b"\x09" + D1_5 + b"\x11" + dm1 + b"\x19" + d2 + b"\x21" + d0
    robot = b"\x09" + dm1 + b"\x11" + d2 + b"\x19" + d90 + b"\x20\x04" + b"\x28\x01" + b"\x30\x01"
    hand = b"\x12" + length(b"\x0a" + length(ball) + b"\x12" + length(robot))
    out = ssl_sim.encode_grsim_replacement((1.5, -1.0, 2.0, 0.0), [("yellow", 4, -1.0, 2.0, math.pi / 2)])
    assert out == hand


def test_simulator_response_round_trip_through_hand_bytes():
    hand = b"\x0a" + length(b"\x0a" + length(b"C") + b"\x12" + length(b"m"))
    assert ssl_sim.encode_simulator_response([SimError("C", "m")]) == hand
    assert ssl_sim.decode_simulator_response(hand) == ("C: m",)


def test_referee_hand_bytes_decode_and_encode_back():
    def team(name: bytes, goalie: int) -> bytes:
        # name, score 2, red 0, yellow_cards 1, timeouts 4, timeout_time 300 s = 300000000 us, goalkeeper
        return (b"\x0a" + length(name) + b"\x10\x02\x18\x00\x28\x01\x30\x04\x38\x80\xc6\x86\x8f\x01"
                + b"\x40" + bytes([goalie]))

    hand = (b"\x08\x01" + b"\x10\x01" + b"\x18\x03" + b"\x20\x02" + b"\x28\x07" + b"\x30\x02"
            + b"\x3a" + length(team(b"Y", 1)) + b"\x42" + length(team(b"B", 0)))
    ref = ssl_gc_referee_message_pb2.Referee.FromString(hand)
    assert ref.stage == ref.NORMAL_FIRST_HALF and ref.command == ref.NORMAL_START
    assert ref.stage_time_left == -2  # sint64: zigzag 3 -> -2
    assert ref.yellow.timeout_time == 300_000_000 and ref.blue.name == "B" and ref.yellow.goalkeeper == 1
    assert ref.SerializeToString() == hand


def test_referee_stage_time_is_sint64_and_the_newer_fields_have_their_numbers():
    # stage_time_left (3) = -2**32 us: zigzag 2**33 - 1 = 33 one bits: ff ff ff ff 1f; beyond a sint32
    # TeamInfo foul_counter = 9 (tag 0x48), hull_color = 19 (tag 19 << 3 = 152: varint 98 01) LIGHT = 2;
    # Referee match_type = 19 (98 01) FRIENDLY = 3
    team = (b"\x0a" + length(b"T") + b"\x10\x00\x18\x00\x28\x00\x30\x00\x38\x00\x40\x00"
            + b"\x48\x05" + b"\x98\x01\x02")
    hand = (b"\x08\x01\x10\x01" + b"\x18\xff\xff\xff\xff\x1f" + b"\x20\x00\x28\x00\x30\x00"
            + b"\x3a" + length(team) + b"\x42" + length(team) + b"\x98\x01\x03")
    ref = ssl_gc_referee_message_pb2.Referee.FromString(hand)
    assert ref.stage_time_left == -2**32
    assert ref.yellow.foul_counter == 5 and ref.blue.hull_color == ssl_gc_referee_message_pb2.HULL_COLOR_LIGHT
    assert ref.match_type == ssl_gc_referee_message_pb2.FRIENDLY
    assert ref.SerializeToString() == hand


@pytest.mark.parametrize("data, reason", [
    (b"\x0a\x02\x10\x01", "required"),  # a RobotCommand without its id
    (b"\x0a\x05\x08", "not a valid"),  # length beyond the datagram
    (b"\xff\xff\xff", "not a valid"),
    (b"".join(b"\x0a\x02\x08" + bytes([i]) for i in range(40)), "at most"),
])
def test_bad_robot_control_is_refused_with_the_reason(data, reason):
    with pytest.raises(WireError, match=reason):
        ssl_sim.decode_robot_control(data)


def test_one_robots_bad_kick_refuses_that_kick_alone():
    """RobotCommand: id = 1 (varint), kick_speed = 3 and kick_angle = 4 (float32, little endian). Robot 1 asks a
    NaN kick speed, robot 2 a 95 deg chip, robot 3 a 100 m/s kick, robot 4 a good 4 m/s 45 deg chip: the packet
    decodes, and each bad kick is refused for its robot alone, naming the field."""
    def command(robot, speed_hex, angle_hex=None):
        body = b"\x08" + bytes([robot]) + b"\x1d" + bytes.fromhex(speed_hex)
        return b"\x0a" + length(body + (b"\x25" + bytes.fromhex(angle_hex) if angle_hex else b""))
    data = (command(1, "0000c07f") + command(2, "00008040", "0000be42") + command(3, "0000c842")
            + command(4, "00008040", "00003442"))  # NaN; 4.0, 95.0; 100.0; 4.0, 45.0
    requests = ssl_sim.decode_robot_control(data)
    assert [r.robot_id for r in requests] == [1, 2, 3, 4]
    assert requests[3].kick_speed_mps == 4.0 and requests[3].kick_angle_deg == 45.0
    actions, errors = ssl_sim.plan_robot_control(requests, [1, 2, 3, 4], {}.get)
    assert [(a.kick_speed_mps, a.kick_angle_deg) for a in actions] == [(0.0, 0.0)] * 3 + [(4.0, 45.0)]
    assert sorted(e.message.split(":")[0].split(" = ")[0] for e in errors) == [
        "robot 1 kick_speed", "robot 2", "robot 3 kick_speed"]
    assert all(e.code == ssl_sim.ERROR_INVALID and "no kick" in e.message for e in errors)


def test_commands_refuse_non_finite_values():
    with pytest.raises(ValueError, match="not finite"):
        RobotCommand(0, forward_mps=math.nan)
    with pytest.raises(ValueError, match="beyond"):
        RobotCommand(0, angular_radps=1e6)


def test_global_to_local_rotates_into_the_robot_frame():
    fwd, left = ssl_sim.local_from_global(0.0, 1.0, math.pi / 2)  # heading +y, moving +y: straight ahead
    assert (fwd, left) == pytest.approx((1.0, 0.0))
    fwd, left = ssl_sim.local_from_global(1.0, 0.0, math.pi / 2)  # moving +x is to the robot's right
    assert (fwd, left) == pytest.approx((0.0, -1.0))


# ------------------------------------------------------------------------------------------ fuzz
def _planned_robot_control(data: bytes) -> list:
    """What a simulator does with a RobotControl: decoded as sent, then each robot's values checked (a value not
    finite or out of range refuses that part of that robot's command, plan_robot_control)."""
    requests = ssl_sim.decode_robot_control(data)
    actions, _errors = ssl_sim.plan_robot_control(requests, range(ssl_sim.MAX_ROBOT_ID + 1), lambda _i: 0.0,
                                                  dribbler=True)
    return actions


DECODERS = [_planned_robot_control, ssl_sim.decode_robot_control_response, ssl_sim.decode_grsim_robots_status,
            ssl_sim.decode_simulator_command, ssl_sim.decode_simulator_response]


def _all_finite(value) -> bool:
    if isinstance(value, float):
        return math.isfinite(value)
    if isinstance(value, tuple | list):
        return all(_all_finite(v) for v in value)
    if hasattr(value, "__dataclass_fields__"):
        return all(_all_finite(getattr(value, k)) for k in value.__dataclass_fields__)
    return True


@settings(max_examples=300, deadline=None)
@given(st.sampled_from(DECODERS), st.binary(max_size=200))
def test_fuzz_every_decoder_accepts_or_refuses_garbage_cleanly(decoder, data):
    try:
        out = decoder(data)
    except WireError:
        return
    assert _all_finite(out)


floats = st.floats(width=32, allow_nan=True, allow_infinity=True)


@settings(max_examples=200, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 2**32 - 1), floats, floats, floats, floats), max_size=40))
def test_fuzz_robot_control_with_any_numbers_is_finite_or_refused(rows):
    msg = ssl_simulation_robot_control_pb2.RobotControl()
    for robot_id, a, b, c, kick in rows:
        cmd = msg.robot_commands.add(id=robot_id, kick_speed=kick)
        v = cmd.move_command.global_velocity
        v.x, v.y, v.angular = a, b, c
    try:
        out = _planned_robot_control(msg.SerializeToString())
    except WireError:
        return
    assert _all_finite(out) and all(r.robot_id <= ssl_sim.MAX_ROBOT_ID for r in out)


@settings(max_examples=200, deadline=None)
@given(floats, floats, floats, st.integers(0, 2**32 - 1), st.sampled_from([0, 1, 2]))
def test_fuzz_simulator_command_with_any_numbers_is_finite_or_refused(x, y, yaw, robot_id, team):
    msg = ssl_simulation_control_pb2.SimulatorCommand()
    msg.control.teleport_ball.x, msg.control.teleport_ball.y = x, y
    r = msg.control.teleport_robot.add(x=x, y=y, orientation=yaw)
    r.id.id, r.id.team = robot_id, team
    try:
        out = ssl_sim.decode_simulator_command(msg.SerializeToString())
    except WireError:
        return
    assert _all_finite(out)


@settings(max_examples=100, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 2**32 - 1), st.booleans()), max_size=40))
def test_fuzz_feedback_ids_are_bounded_or_refused(rows):
    msg = ssl_simulation_robot_feedback_pb2.RobotControlResponse()
    for robot_id, contact in rows:
        msg.feedback.add(id=robot_id, dribbler_ball_contact=contact)
    try:
        out = ssl_sim.decode_robot_control_response(msg.SerializeToString())
    except WireError:
        return
    assert all(0 <= k <= ssl_sim.MAX_ROBOT_ID for k in out.ball_contact)


# A teleport given in the field frame (x towards the opponents' goal): the ball at (1, 2) m rolling at (3, 0) m/s,
# our robot 5 at (1, 2) m facing +y (pi/2 rad). Defending the simulator's positive x, the simulator's frame is the
# field frame turned by half a turn: (-1, -2) m, (-3, 0) m/s, facing -y (-pi/2 rad, grSim: -90 degrees).
TELEPORT_CASES = [
    (team, side, (1.0, 2.0, 3.0, 0.0) if side == "negative_x" else (-1.0, -2.0, -3.0, 0.0),
     (1.0, 2.0, math.pi / 2) if side == "negative_x" else (-1.0, -2.0, -math.pi / 2))
    for team in ("blue", "yellow") for side in ("negative_x", "positive_x")
]


@pytest.mark.parametrize(("team", "side", "ball", "robot"), TELEPORT_CASES)
def test_teleports_in_the_field_frame_reach_the_simulator_in_its_frame(team, side, ball, robot):
    data = ssl_sim.teleport_packet("ssl", side, (1.0, 2.0, 3.0, 0.0), [(team, 5, 1.0, 2.0, math.pi / 2)])
    control = ssl_simulation_control_pb2.SimulatorCommand.FromString(data).control
    b, (r,) = control.teleport_ball, control.teleport_robot
    assert (b.x, b.y, b.vx, b.vy) == ball  # metres, m/s (floats: these are exact)
    assert (r.id.id, r.id.team) == (5, 2 if team == "blue" else 1)  # gc Team: YELLOW 1, BLUE 2
    assert (r.x, r.y) == robot[:2] and r.orientation == pytest.approx(robot[2], abs=1e-6)  # radians

    data = ssl_sim.teleport_packet("grsim", side, (1.0, 2.0, 3.0, 0.0), [(team, 5, 1.0, 2.0, math.pi / 2)])
    replacement = grsim_pb2.grSim_Packet.FromString(data).replacement
    b, (r,) = replacement.ball, replacement.robots
    assert (b.x, b.y, b.vx, b.vy) == ball  # grSim: metres, m/s
    assert (r.id, r.yellowteam, r.x, r.y) == (5, team == "yellow", *robot[:2])
    assert r.dir == pytest.approx(math.degrees(robot[2]), abs=1e-9)  # grSim: degrees


def test_a_half_turn_is_its_own_inverse_and_keeps_a_missing_heading():
    from erforce_interfaces.wire.robot_config import half_turn
    x, y, theta = half_turn(0.5, -4.0, 3.0)
    assert (x, y) == (-0.5, 4.0) and theta == pytest.approx(3.0 - math.pi)
    assert half_turn(x, y, theta)[2] == pytest.approx(3.0)
    assert math.isnan(half_turn(1.0, 1.0, math.nan)[2])
