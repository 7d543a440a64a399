"""One compiled pass from an SSL-Vision datagram's bytes to the bytes of its /vision/robots message.

The bridge's usual datagram (one camera frame, every detection valid) goes through the same kernels as the
general path, in one call: ssl_vision's pass over the protobuf bytes, the vision clock, the camera alignment
(camera_alignment's kernels: the frame feeds the estimate, the camera's offset comes off its balls and robots),
the tracker's ball hypotheses, its choice of the ball, the ball filter's usual update (``tracking.ball_step``: the
pass returns ``BALL_FUSED`` + its status) and its robot streams, the message's points (the camera's first, from
the bridge's camera table, ``camera_table``) and their CDR. What needs Python
stays outside: a new ball and the ball filter's unusual frames (``VisionTracker.use_ball`` with the action
returned) and anything unusual, which the pass hands back before it has changed any state (``PASS_FALLBACK``: the
bridge runs the general path on the datagram, which names the problem) or after (``PASS_GENERAL``: a robot
the points cannot carry; ``PASS_T_CAPTURE_BACK``, ``PASS_CLOCK_JUMP``, ``PASS_TIMELINE_JUMP``,
``PASS_BAD_STAMP``: the frame is refused, ``info`` says why). Every frame passes the cameras' capture order first
(vision_time.CaptureOrder, the one check that a camera's frame is after its newest, in every time source); the
stamp comes from the time source's mode (vision_time.TIME_SOURCES: the vision clock's estimate, ``t_capture`` as
it is, or the capture timeline).
The message written is byte for byte what ``clouds.vision_robots_points_cdr`` builds from the same
points. The kernels it calls from other modules (vision_time's clock and timeline, the tracker's, the camera
alignment's) are compiled into it, and numba's cache of this module goes by this file alone: a change there needs
this file touched (or its ``__pycache__`` entries removed) to take effect here.
"""

from __future__ import annotations

import math

import numpy as np

from erforce_ball_model import tracking
from erforce_ball_model.camera_alignment import CameraAlignment, alignment_frame, correct_rows
from erforce_ball_model.camera_alignment import load_kernels as load_alignment_kernels
from erforce_ball_model.vision_tracking import (
    BALL_FUSED,
    BALL_NONE,
    BALL_SIGHTING,
    BALL_UPDATE,
    COUNT_FRAMES,
    COUNT_HYPOTHESES,
    MAX_ROBOT_ID,
    SETTING_BALL_GATE,
    SETTING_BALL_SPEED,
    SETTING_HALF_LENGTH,
    SETTING_HALF_WIDTH,
    SETTING_HYPOTHESIS_TIMEOUT,
    SETTING_MAX_X,
    SETTING_MAX_Y,
    SETTING_MIN_CONFIDENCE,
    SETTING_ROBOT_GATE,
    SETTING_ROBOT_SPEED,
    VisionTracker,
    choose_ball,
    note_ball_taken,
    track_robots,
    update_hypotheses,
)
from erforce_interfaces.runtime.numba_support import compiled_for, numba
from erforce_interfaces.ssl.ssl_vision import (
    MM,
    CameraFrame,
    DecodeLimits,
    RobotSighting,
    detection_rows,
    detection_rows_size,
    encode_frame,
)
from erforce_interfaces.ssl.vision_time import (
    CAPTURE_OLD,
    CAPTURE_RESTART,
    TIME_CAPTURE,
    TIME_ESTIMATE,
    TIME_VISION,
    TIMELINE_BACK,
    CaptureOrder,
    CaptureTimeline,
    VisionClock,
    capture_step,
    clock_step,
    timeline_step,
)
from erforce_interfaces.wire import contract
from erforce_interfaces.wire.clouds import vision_robots_template
from erforce_interfaces.wire.conversions import MAX_ABS_VALUE
from erforce_interfaces.wire.robot_config import FieldConfig

__all__ = ["PASS_BAD_STAMP", "PASS_CLOCK_JUMP", "PASS_DONE", "PASS_FALLBACK", "PASS_GENERAL", "PASS_TIMELINE_JUMP",
           "PASS_T_CAPTURE_BACK", "FramePass", "camera_table", "frame_points", "robot_points"]

(PASS_DONE, PASS_GENERAL, PASS_FALLBACK, PASS_CLOCK_JUMP, PASS_BAD_STAMP, PASS_T_CAPTURE_BACK,
 PASS_TIMELINE_JUMP) = range(7)
# info: the frame's camera, its robots (rows from ROBOTS_AT), those used, the points written (-1: general
# path), then the clock's sample, deviation and offset (PASS_CLOCK_JUMP), the stamp (PASS_BAD_STAMP), or the
# frame's t_capture and its step [s] from the camera's newest (PASS_T_CAPTURE_BACK: how far before it, from the
# capture order or the timeline; PASS_TIMELINE_JUMP: t_capture minus the timeline's newest, a line not confirmed)
I_CAMERA, I_ROBOTS, I_USED, I_POINTS, I_SAMPLE, I_DEVIATION, I_OFFSET = range(7)
I_STAMP = I_T_CAPTURE = I_SAMPLE
I_CAPTURE_BACK = I_CAPTURE_STEP = I_DEVIATION

_OURS_CODE, _OPPONENTS_CODE = float(contract.OURS.code), float(contract.OPPONENTS.code)
_BALL_CODE = float(contract.VISION_BALL_CODE)
_CAMERA_CODE, _SIGHTING_CODE = float(contract.VISION_CAMERA_CODE), float(contract.VISION_SIGHTING_CODE)
_LIMITS = DecodeLimits()
_ball_step = tracking.compiled_ball_step()
ROBOTS_AT = 8 + 4 * _LIMITS.max_balls  # where detection_rows puts the robots' rows


@numba.njit(cache=True, error_model="numpy")
def robot_points(robots, used, ours, n_ours, pose_readers, points, has_ball, ball_x, ball_y):
    """The /vision/robots points (x, y, 0, yaw, team code, robot_id) written into ``points``: with ``has_ball``
    first the ball's (ball_x, ball_y, 0, 0, 0, 0), then those of the rows ``used`` of ``robots`` (ssl_vision's
    ROBOT_COLUMNS; the tracker checked team and id); their number, or -1 when a point needs the node's
    general path: no orientation or values beyond the message's checks, our id beyond ``n_ours``, a robot
    whose vision_pose publisher has a reader or does not exist yet (``pose_readers`` by side and id: -1, else
    the reader count)."""
    first = 0
    if has_ball:
        if not (abs(ball_x) <= MAX_ABS_VALUE and abs(ball_y) <= MAX_ABS_VALUE):  # False for NaN
            return -1
        points[0, 0], points[0, 1] = ball_x, ball_y
        points[0, 2], points[0, 3], points[0, 4], points[0, 5] = 0.0, 0.0, _BALL_CODE, 0.0
        first = 1
    for j in range(len(used)):
        k = used[j]
        team, robot_id, x, y, theta = robots[k, 0], robots[k, 1], robots[k, 2], robots[k, 3], robots[k, 4]
        if not (abs(x) <= MAX_ABS_VALUE and abs(y) <= MAX_ABS_VALUE and abs(theta) <= math.pi):  # False for NaN
            return -1
        side = 0 if team == ours else 1
        if (side == 0 and robot_id >= n_ours) or pose_readers[side, int(robot_id)] != 0:
            return -1
        p = first + j
        points[p, 0], points[p, 1], points[p, 2], points[p, 3] = x, y, 0.0, theta
        points[p, 4] = _OURS_CODE if side == 0 else _OPPONENTS_CODE
        points[p, 5] = robot_id
    return first + len(used)


def camera_table(limits: DecodeLimits = _LIMITS) -> np.ndarray:
    """The bridge's cameras as the pass reads them: a row per camera id, (known 1/0, x, y, z [m] in ``field``, id)."""
    table = np.zeros((limits.max_camera_id + 1, 5))
    table[:, 4] = np.arange(len(table))
    return table


@numba.njit(cache=True, error_model="numpy")
def frame_points(robots, used, ours, n_ours, pose_readers, points, camera, ball, ball_x, ball_y):
    """A camera frame's /vision/robots points: the camera's (its row of ``camera_table`` when known: x, y, z, 0,
    VISION_CAMERA_CODE, id), then those of ``robot_points`` with the ball's action ``ball`` (BALL_NONE: none;
    BALL_SIGHTING: a sighting's point, only after a camera's; else the ball's). Their number (0: nothing to send),
    or -1 as robot_points."""
    first = 0
    if camera[0] != 0.0:
        points[0, 0], points[0, 1], points[0, 2], points[0, 3] = camera[1], camera[2], camera[3], 0.0
        points[0, 4], points[0, 5] = _CAMERA_CODE, camera[4]
        first = 1
    sighting = ball == BALL_SIGHTING
    has_ball = ball != BALL_NONE and (first == 1 or not sighting)
    n = robot_points(robots, used, ours, n_ours, pose_readers, points[first:], has_ball, ball_x, ball_y)
    if n <= 0:
        return n
    if has_ball and sighting:
        points[first, 4] = _SIGHTING_CODE
    return first + n


@numba.njit(cache=True, error_model="numpy")
def _put_u32(buf, at, value):
    for k in range(4):
        buf[at + k] = (value >> (8 * k)) & 0xFF


@numba.njit(cache=True, error_model="numpy")
def _message(t_s, points, n_points, head, width_at, sizes_at, message):
    """The /vision/robots bytes into ``message``: their length, or -1 for a stamp outside the usual range
    (the caller builds that message in Python, which checks it)."""
    if not 0.0 <= t_s < 2.0e9:
        return -1
    ns = np.int64(np.rint(t_s * 1e9))
    m = len(head)
    message[:m] = head
    _put_u32(message, 4, ns // 1_000_000_000)
    _put_u32(message, 8, ns % 1_000_000_000)
    _put_u32(message, width_at, n_points)
    size = 48 * n_points
    _put_u32(message, sizes_at, size)
    _put_u32(message, sizes_at + 4, size)
    message[m:m + size] = points[:n_points].ravel().view(np.uint8)
    message[m + size] = 1
    return m + size + 1


@numba.njit(cache=True, error_model="numpy")
def _frame_pass(data, t_receive, time_mode, rows, limits, last_capture, clock_window, clock_pending, clock_counts,
                clock_params, timeline_cams, timeline_samples, timeline_glob, hyps, hits, candidates, tracks, used,
                settings, ball_state, counts, ball_filter, shoot_samples, ball_model, pose_readers, ours_n_ours,
                cameras, points, head, layout, message, info, align, align_newest, align_history, align_cams,
                align_pairs, align_totals, align_settings, align_offsets, align_std):
    """The datagram ``data`` received at ``t_receive`` (the ROS clock; with TIME_CAPTURE a monotonic wall clock)
    through decoding, capture order, clock, camera alignment (``align``: the frame feeds the estimate, then the
    camera's offset is taken off its balls and robots), tracker and message (see the module docstring): (status,
    message length or -1, ball action, stamp, ball x, ball y)."""
    max_balls, max_robots = int(limits[0]), int(limits[1])
    status, n_balls, n_robots, n_rejected, geometry = detection_rows(
        data, rows, max_balls, max_robots, limits[2], limits[3], limits[4], limits[5])
    if status != 0 or n_rejected != 0 or geometry or rows[4] != n_balls:  # rows[4]: the balls in the bytes
        return PASS_FALLBACK, -1, 0, 0.0, 0.0, 0.0
    camera = int(rows[3])
    info[I_CAMERA], info[I_ROBOTS], info[I_USED], info[I_POINTS] = camera, n_robots, 0, -1
    verdict, back_s = capture_step(last_capture, camera, rows[1], limits[6], False)
    if verdict == CAPTURE_OLD:
        info[I_T_CAPTURE], info[I_CAPTURE_BACK] = rows[1], back_s
        return PASS_T_CAPTURE_BACK, -1, 0, 0.0, 0.0, 0.0
    if verdict == CAPTURE_RESTART:  # nothing changed: the general path takes it and says so
        return PASS_FALLBACK, -1, 0, 0.0, 0.0, 0.0
    if time_mode == TIME_VISION:
        t_s = rows[1]
    elif time_mode == TIME_CAPTURE:
        refused, t_s = timeline_step(timeline_cams, timeline_samples, timeline_glob, camera, rows[1], rows[2],
                                     t_receive)
        if refused:  # t_s: how far back (an old frame) or the step (a line not confirmed)
            info[I_T_CAPTURE], info[I_CAPTURE_STEP] = rows[1], t_s
            return (PASS_T_CAPTURE_BACK if refused == TIMELINE_BACK else PASS_TIMELINE_JUMP), -1, 0, 0.0, 0.0, 0.0
    else:
        refused, t_s, sample, deviation, offset = clock_step(clock_window, clock_pending, clock_counts,
                                                             clock_params, camera, rows[1], rows[2], t_receive)
        if refused:
            info[I_SAMPLE], info[I_DEVIATION], info[I_OFFSET] = sample, deviation, offset
            return PASS_CLOCK_JUMP, -1, 0, 0.0, 0.0, 0.0
    if not (np.isfinite(t_s) and t_s >= 0.0):
        info[I_STAMP] = t_s
        return PASS_BAD_STAMP, -1, 0, 0.0, 0.0, 0.0
    balls = rows[8:8 + 4 * n_balls].reshape(n_balls, 4)
    robots = rows[ROBOTS_AT:ROBOTS_AT + 6 * n_robots].reshape(n_robots, 6)
    if align:  # CameraAlignment.take, on the vision host's capture clock
        alignment_frame(align_newest, align_history, align_cams, align_pairs, align_totals, align_settings,
                        align_offsets, align_std, camera, rows[1], robots, balls)
        correct_rows(align_offsets, camera, balls, robots)
    # VisionTracker.frame_indices
    counts[COUNT_FRAMES] += 1
    p = settings
    n_hyps, n_candidates = update_hypotheses(
        hyps, hits, counts[COUNT_HYPOTHESES], t_s, balls, p[SETTING_MIN_CONFIDENCE], p[SETTING_MAX_X],
        p[SETTING_MAX_Y], p[SETTING_HALF_LENGTH], p[SETTING_HALF_WIDTH], p[SETTING_HYPOTHESIS_TIMEOUT],
        p[SETTING_BALL_GATE], p[SETTING_BALL_SPEED], candidates)
    counts[COUNT_HYPOTHESES] = n_hyps
    action, ball_x, ball_y = choose_ball(hyps, hits, t_s, candidates, n_candidates, p, ball_state, counts)
    if action == BALL_UPDATE:
        # the ball filter's usual update; a frame it holds back, refuses or that starts a maneuver leaves its
        # state as it was, and VisionTracker.use_ball does it again in Python
        status = _ball_step(ball_filter, shoot_samples, ball_model, t_s, ball_x, ball_y)
        if status == 0 or status == 1:  # UpdateStatus.INITIALIZED, ACCEPTED
            note_ball_taken(ball_state, t_s, ball_x, ball_y, ball_filter)
            action = BALL_FUSED + status
    n_used = 0
    if n_robots:
        n_used = track_robots(robots, t_s, tracks, p[SETTING_ROBOT_GATE], p[SETTING_ROBOT_SPEED], MAX_ROBOT_ID, used)
    info[I_USED] = n_used
    if n_used == 0 and action == 0:
        return PASS_DONE, 0, action, t_s, ball_x, ball_y
    n_points = frame_points(robots, used[:n_used], ours_n_ours[0], ours_n_ours[1], pose_readers, points,
                            cameras[camera], action, ball_x, ball_y)
    info[I_POINTS] = n_points
    if n_points < 0:
        return PASS_GENERAL, -1, action, t_s, ball_x, ball_y
    if n_points == 0:  # a sighting without its camera, and no robots
        return PASS_DONE, 0, action, t_s, ball_x, ball_y
    n_bytes = _message(t_s, points, n_points, head, layout[0], layout[1], message)
    return PASS_DONE, n_bytes, action, t_s, ball_x, ball_y


class FramePass:
    """``_frame_pass`` bound to a clock, a capture timeline, a tracker and the node's point and message buffers:
    ``run(data, t_receive_s, time_mode)`` returns its tuple; the decoded rows, ``info``, ``points`` and the message
    stay in the object until the next call."""

    def __init__(self, clock: VisionClock, tracker: VisionTracker, pose_readers: np.ndarray, ours: float,
                 n_ours: int, order: CaptureOrder | None = None, limits: DecodeLimits = _LIMITS,
                 timeline: CaptureTimeline | None = None, cameras: np.ndarray | None = None,
                 alignment: CameraAlignment | None = None) -> None:
        """``order``, ``timeline``: the cameras' capture order and capture timeline the node's general path shares
        (new ones when None); the order's restart_s is read here, at binding. ``cameras``: the node's
        ``camera_table``, read per frame (None: no camera known). ``alignment``: the node's camera alignment (None:
        none), fed and applied by the pass as ``CameraAlignment.take`` does."""
        if (limits.max_balls, limits.max_robots_per_team) != (_LIMITS.max_balls, _LIMITS.max_robots_per_team):
            raise ValueError("FramePass: the rows' layout is compiled for the default counts")
        self.rows = np.empty(detection_rows_size(limits.max_balls, limits.max_robots_per_team))
        self.order = order or CaptureOrder()
        self.limits = np.array([limits.max_balls, limits.max_robots_per_team, limits.max_abs_coordinate_m / MM,
                                limits.max_robot_id, limits.max_camera_id, limits.max_time_s,
                                self.order.restart_s], float)
        self.points = np.empty((2 * limits.max_robots_per_team + 1, len(contract.VISION_ROBOT_FIELDS)))
        template = vision_robots_template()
        self.head = np.frombuffer(template.head, np.uint8)
        self.layout = np.array([template.width_at, template.sizes_at], np.int64)
        self.message = np.zeros(len(template.head) + self.points.nbytes + 1, np.uint8)
        self.message_view = memoryview(self.message)
        self.info = np.zeros(7)
        if len(tracker.candidates) < limits.max_balls or len(tracker.used) < 2 * limits.max_robots_per_team:
            raise ValueError("FramePass: the tracker's buffers are smaller than a frame's detections")
        self.tracker = tracker
        timeline = timeline or CaptureTimeline()
        learning = alignment or CameraAlignment()  # arrays of the right types, not read without an alignment
        self._state = (self.rows, self.limits, self.order.last_s, clock.window, clock.pending, clock.counts,
                       clock.params, timeline.cams, timeline.samples, timeline.glob, tracker.hyps,
                       tracker.hits, tracker.candidates, tracker.robot_tracks, tracker.used, tracker.settings,
                       tracker.ball_state, tracker.counts, tracker.ball.s, tracker.ball.shoot, tracker.ball.m,
                       pose_readers, np.array([ours, n_ours], float),
                       camera_table(limits) if cameras is None else cameras, self.points, self.head, self.layout,
                       self.message, self.info, alignment is not None, *learning.state())
        # the compiled function for exactly these types: no type matching per call
        self._entry = compiled_for(_frame_pass, encode_frame(CameraFrame(0, 0, 0.0, 0.0, (), ())), 0.0,
                                   TIME_ESTIMATE, *self._state)

    def run(self, data: bytes, t_receive_s: float, time_mode: int) -> tuple:
        """``time_mode``: TIME_ESTIMATE, TIME_VISION or TIME_CAPTURE (an int: the entry is compiled for one type)."""
        return self._entry(data, t_receive_s, time_mode, *self._state)

    def robots(self) -> np.ndarray:
        """The last frame's decoded robot rows (ssl_vision's ROBOT_COLUMNS)."""
        n = int(self.info[I_ROBOTS])
        return self.rows[ROBOTS_AT:ROBOTS_AT + 6 * n].reshape(n, 6)

    def used(self) -> np.ndarray:
        return self.tracker.used[:int(self.info[I_USED])]


def load_kernels() -> None:
    """Compile (or load from numba's cache) the pass at a node's start, with and without the camera alignment."""
    tracking.load_kernels()
    load_alignment_kernels()
    for alignment in (None, CameraAlignment()):
        frame_pass = FramePass(VisionClock(), VisionTracker(FieldConfig.preset("division_b")),
                               np.zeros((2, MAX_ROBOT_ID + 1), np.int64), 0.0, 11, alignment=alignment)
        data = encode_frame(CameraFrame(0, 1, 1.0, 1.0, (), (RobotSighting("blue", 0, 0.0, 0.0, 0.0, 1.0),)))
        for mode in (TIME_ESTIMATE, TIME_CAPTURE):
            frame_pass.run(data, 1.0 + mode, mode)
