"""A flat pass on an outside world stays a ball on the ground: the kick hint ends what came before the kick.

The scene, written from what grSim does (its robot.cpp, and the kicks measured from its vision): a pass rolls into
the passer's front 0.098 m from the robot's centre and springs back to 0.11 m (about a 0.09 m robot and a ball
radius), where the dribbler holds it; the passer turns with the ball held at its front, its yaw rate rising to
3 rad/s within 0.05 s; then it kicks flat. grSim sets a flat-kicked ball's velocity to the commanded speed along the
robot's heading with no vertical part, and the ball then follows the two-phase model its SSL geometry announces
(a_slide -14, a_roll -0.7 m/s^2, c_switch 0.7). One camera at grSim's (-3, 2.25, 4) m, 60 Hz, without noise
(grSim's vision adds none).
"""

import math

import numpy as np

from erforce_ball_model.ball_model import BallModelParams, BallTrajectory, ChipParams
from erforce_ball_model.chip_model import ChipTrajectory
from erforce_ball_model.chip_tracking import ChipDetector
from erforce_ball_model.predictor import BallPredictor, PredictorConfig
from erforce_ball_model.receiver import CatcherConfig, Receiver
from erforce_interfaces.wire.robot_config import FieldConfig

CAMERA_M = (-3.0, 2.25, 4.0)
HZ = 60.0
GRSIM_MODEL = BallModelParams(-14.0, -0.7, 0.7)
CENTRE = np.array([-1.83, 1.21])  # the passer's centre
FRONT_M = 0.11  # the held ball's centre from the passer's centre
HIT_M = 0.098  # where the ball hits the front
HEADING0_RAD = math.radians(-47.0)
YAW_RATE_RADPS, YAW_RAMP_S, TURN_S = 3.0, 0.05, 0.9
KICK_MPS = 2.76


def heading_at(s):
    """The passer's heading s seconds into its turn: the yaw rate ramps linearly to its top within YAW_RAMP_S."""
    if s < YAW_RAMP_S:
        return HEADING0_RAD + 0.5 * YAW_RATE_RADPS / YAW_RAMP_S * s * s
    return HEADING0_RAD + YAW_RATE_RADPS * (s - 0.5 * YAW_RAMP_S)


def at_front(heading_rad, distance_m=FRONT_M):
    return CENTRE + distance_m * np.array([math.cos(heading_rad), math.sin(heading_rad)])


def held_then_kicked():
    """(frames before the kick, the frames of the kick, the hint's stamp, the kick's trajectory and launch time):
    frames are (t, x, y). The hint takes the newest frame's stamp before the kick, as the predictor node does."""
    frames, t = [], 0.0
    for k in range(30, -1, -1):  # rolling in at 1.55 m/s along the passer's heading, against its front
        frames.append((t, *at_front(HEADING0_RAD, HIT_M + 1.55 * k / HZ)))
        t += 1.0 / HZ
    for k in range(int(TURN_S * HZ) + 1):
        frames.append((t, *at_front(heading_at(k / HZ))))
        t += 1.0 / HZ
    heading = heading_at(TURN_S)
    direction = np.array([math.cos(heading), math.sin(heading)])
    kick = BallTrajectory(at_front(heading), KICK_MPS * direction, KICK_MPS, GRSIM_MODEL)
    t_kick = t - 0.5 / HZ
    kicked = [(t + k / HZ, *kick.position_at(t + k / HZ - t_kick)) for k in range(40)]
    return frames, kicked, frames[-1][0], kick, t_kick


def predictor():
    return BallPredictor(PredictorConfig(num_robots=1, field=FieldConfig(12.0, 9.0, 0.3), model=GRSIM_MODEL,
                                         use_vision_geometry=False))


def test_a_flat_kick_after_the_ball_was_carried_round_a_turning_passer_is_no_chip():
    """The kick hint (flat) ends the collection begun when the pass stopped at the passer's front: the kick starts
    its own, with the hint, and no frame of it reports a chip; the flat filter follows the kick (2.76 m/s along the
    heading, and after 0.65 s at the speed the two-phase model gives: 0.7 of the kick, less 0.7 m/s^2 rolling)."""
    pred = predictor()
    before, kicked, t_hint, kick, t_kick = held_then_kicked()
    for t, x, y in before:
        pred.ball_frame(t, x, y, camera_m=CAMERA_M)
    pred.kick_hint(t_hint, 0.0)
    frames = [pred.ball_frame(t, x, y, camera_m=CAMERA_M) for t, x, y in kicked]
    assert all(f is not None and f.chip is None and f.phase != "chip" for f in frames)
    assert pred.chip_detector.hint_angle_deg == 0.0
    last = frames[-1].trajectory
    speed = float(np.hypot(*last.velocity_mps))
    t_roll = 0.3 * KICK_MPS / 14.0
    expected = 0.7 * KICK_MPS - 0.7 * (kicked[-1][0] - t_kick - t_roll)
    assert abs(speed - expected) < 0.03
    assert float(last.velocity_mps @ kick.direction) / speed > 0.999


def test_a_receiver_ahead_of_the_flat_pass_does_not_back_away_from_it():
    """A receiver 1.5 m down the kick's line, facing the ball, fed each frame's ball state (with the height while
    the predictor reports one) stands still: its dribbler is on the line and the ball arrives on the ground."""
    pred = predictor()
    before, kicked, t_hint, kick, t_kick = held_then_kicked()
    for t, x, y in before:
        pred.ball_frame(t, x, y, camera_m=CAMERA_M)
    pred.kick_hint(t_hint, 0.0)
    heading = math.atan2(kick.direction[1], kick.direction[0])
    offset = 0.0815
    receiver = Receiver(CatcherConfig(), offset)
    receiver.on_model(GRSIM_MODEL)
    receiver.on_chip_model(ChipParams())
    stand = kick.position_m + (1.5 + offset) * kick.direction
    for t, x, y in kicked:
        frame = pred.ball_frame(t, x, y, camera_m=CAMERA_M)
        if frame.chip is None:
            receiver.on_ball(t, frame.trajectory.position_m, frame.trajectory.velocity_mps)
        else:
            receiver.on_ball(t, frame.chip.position_m, frame.chip.velocity_mps)
        receiver.on_odom(t, (*stand, heading + math.pi), (0.0, 0.0), t)
        twist = receiver.tick(t)
        assert np.array_equal(twist, np.zeros(3)), f"{t - t_kick:.3f} s after the kick the receiver moves: {twist}"


def test_a_hint_ends_a_chip_found_in_a_motion_before_it():
    """A chip seen by two cameras, then a kick hint 0.4 s after its launch (the ball is at the kicker again): the
    detector holds no chip and no kick any more (the next motion starts one); a hint at or before the motion's
    first sighting leaves it (the late news of its own kick)."""
    cameras = ((-3.0, 0.0, 4.0), (3.0, 1.0, 4.0))
    truth = ChipTrajectory((0.0, 0.0, 0.0), (2.0, 0.0, 3.0), ChipParams())

    def chip_seen():
        detector = ChipDetector(None, ChipParams())
        detector.start(1.0 / 70.0, before=(0.0, 0.0, 0.0, 0.0, 0.0))
        for k in range(1, 8):
            x, y, z = truth.position_at(k / 70.0).tolist()
            for cx, cy, cz in cameras:
                s = cz / (cz - z)
                detector.add(k / 70.0, cx + (x - cx) * s, cy + (y - cy) * s, (cx, cy, cz))
        assert detector.launch is not None
        return detector

    detector = chip_seen()
    detector.hint(0.4, 0.0)
    assert detector.launch is None and detector.chip_at(0.41) is None and not detector.active
    assert detector.t_start_s is None and detector.hint_angle_deg is None
    detector.start(0.42, before=(0.4, 0.5, 0.0, 0.0, 0.0))  # the kick's motion: the hint is its
    assert detector.hint_angle_deg == 0.0
    detector = chip_seen()
    detector.hint(1.0 / 70.0, 45.0)  # stamped with the motion's first sighting: that motion's kick
    assert detector.launch is not None and detector.t_start_s == 1.0 / 70.0
