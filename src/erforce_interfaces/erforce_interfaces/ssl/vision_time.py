"""The time of SSL-Vision frames on the receiver, without ROS: the vision clock, CaptureOrder, the capture timeline.

``VisionClock`` maps a camera's ``t_capture`` (the vision host's clock) onto the receiver's
clock: per camera, the offset is the smallest ``t_receive - t_sent`` seen over a sliding window
(network and scheduling delays only ever add to it), so ``t_capture + offset`` is the capture
time on the receiver's clock. A camera whose clock jumps is noticed when its samples leave the
window's offset by more than ``jump_s`` for several packets over ``confirm_s``; then the window
restarts from the new samples (details in the class). ``CaptureOrder``, in front of every time source,
drops a camera's frame whose ``t_capture`` is not after the newest one taken (a duplicate or a stale frame);
``CaptureTimeline`` puts the cameras' capture times on one timeline (``time_source: capture``).
"""

from __future__ import annotations

import math

import numpy as np

from erforce_interfaces.runtime.numba_support import compiled_for, numba
from erforce_interfaces.ssl.ssl_vision import DecodeLimits

#: The stamps' time sources (the bridge's ``time_source``), by mode number: the vision clock's estimate of the
#: receiver's clock, ``t_capture`` as it is (already ROS time), the cameras' capture times on one timeline.
TIME_SOURCES = ("estimate", "vision", "capture")
TIME_ESTIMATE, TIME_VISION, TIME_CAPTURE = range(3)


class ClockJump(ValueError):
    """A frame refused by a time source: ``kind`` is its DROP_CLASSES class, ``clock_jump`` (the camera's clock
    seems to have jumped, not yet confirmed) or ``t_capture_back`` (an old frame the capture timeline refuses)."""

    def __init__(self, message: str, kind: str = "clock_jump") -> None:
        super().__init__(message)
        self.kind = kind


# The clock's state is arrays (one compiled step per frame, also inside the bridge's compiled pass): per camera
# a ring of window samples (t_receive, offset) with increasing offsets, whose head is the window's minimum,
# and a list of the samples of a suspected jump. A camera's ring and list hold CLOCK_CAPACITY samples (75 Hz
# over a 2 s window is 150); a sample beyond that replaces the newest one held.
CLOCK_CAMERAS = DecodeLimits().max_camera_id + 1
CLOCK_CAPACITY = 512
_CLOCK_HEAD, _CLOCK_SIZE, _CLOCK_PENDING = range(3)  # columns of the counts (per camera)
_CLOCK_WINDOW_S, _CLOCK_JUMP_S, _CLOCK_CONFIRM_PACKETS, _CLOCK_CONFIRM_S, _CLOCK_JUMPS = range(5)  # params


@numba.njit(cache=True, error_model="numpy")
def _clock_push(window, counts, camera, t_receive, offset):
    """Append a sample to the camera's monotonic window (dropping the newer samples it undercuts)."""
    cap = window.shape[1]
    head, size = counts[camera, _CLOCK_HEAD], counts[camera, _CLOCK_SIZE]
    while size > 0 and window[camera, (head + size - 1) % cap, 1] >= offset:
        size -= 1
    if size == cap:
        size -= 1
    at = (head + size) % cap
    window[camera, at, 0], window[camera, at, 1] = t_receive, offset
    counts[camera, _CLOCK_SIZE] = size + 1


@numba.njit(cache=True, error_model="numpy")
def clock_step(window, pending, counts, params, camera, t_capture, t_sent, t_receive):
    """VisionClock.to_receiver on the arrays: (refused, stamp, sample, deviation, window offset); refused 1 is
    a suspected forward jump (the ClockJump), the stamp then undefined."""
    cap = window.shape[1]
    sample = t_receive - t_sent
    head, size = counts[camera, _CLOCK_HEAD], counts[camera, _CLOCK_SIZE]
    while size > 0 and window[camera, head, 0] < t_receive - params[_CLOCK_WINDOW_S]:
        head = (head + 1) % cap
        size -= 1
    counts[camera, _CLOCK_HEAD], counts[camera, _CLOCK_SIZE] = head, size
    deviation = sample - window[camera, head, 1] if size > 0 else 0.0
    jump_s = params[_CLOCK_JUMP_S]
    if abs(deviation) > jump_s:
        n = counts[camera, _CLOCK_PENDING]
        if n > 0 and abs(sample - pending[camera, n - 1, 1]) > jump_s:
            n = 0  # not one consistent jump: start counting again
        if n == pending.shape[1]:
            n -= 1
        pending[camera, n, 0], pending[camera, n, 1] = t_receive, sample
        n += 1
        counts[camera, _CLOCK_PENDING] = n
        if n >= params[_CLOCK_CONFIRM_PACKETS] and pending[camera, n - 1, 0] - pending[camera, 0, 0] >= \
                params[_CLOCK_CONFIRM_S]:
            counts[camera, _CLOCK_HEAD], counts[camera, _CLOCK_SIZE] = 0, 0
            for k in range(n):
                _clock_push(window, counts, camera, pending[camera, k, 0], pending[camera, k, 1])
            counts[camera, _CLOCK_PENDING] = 0
            params[_CLOCK_JUMPS] += 1.0
        elif deviation < 0.0:
            return 1, np.nan, sample, deviation, window[camera, head, 1]
    else:
        counts[camera, _CLOCK_PENDING] = 0
        _clock_push(window, counts, camera, t_receive, sample)
    offset = window[camera, counts[camera, _CLOCK_HEAD], 1]
    stamp = t_capture + offset
    return 0, (t_receive if t_receive < stamp else stamp), sample, deviation, offset  # never after it arrived


def clock_jump_text(camera_id: int, sample: float, deviation: float, offset: float) -> str:
    return (f"camera {camera_id}: clock offset {sample:+.3f} s is {-deviation:.3f} s below {offset:+.3f} s (the "
            "camera's clock jumped forward, or a bogus t_sent); frame refused until confirmed")


class VisionClock:
    """Per camera: vision-clock capture times -> receiver-clock stamps (see the module docstring).

    A sample more than ``jump_s`` above the window's offset is a late packet (a stall of the
    receiver or the network) or the camera's clock stepping back: the frame is stamped with the
    window's offset, right for a late packet. A sample more than ``jump_s`` below is the clock
    stepping forward or a bogus ``t_sent``: the frame is refused (``ClockJump``). Either becomes
    the new offset once ``confirm_packets`` consecutive samples agree over at least ``confirm_s``
    of receive time; a stall's backlog arrives within milliseconds and never confirms.
    Cameras 0 .. CLOCK_CAMERAS - 1 (what the decoder lets through).
    """

    def __init__(self, window_s: float = 2.0, jump_s: float = 0.25, confirm_packets: int = 5,
                 confirm_s: float = 0.2) -> None:
        if not (window_s > 0.0 and jump_s > 0.0 and confirm_packets >= 1 and confirm_s >= 0.0):
            raise ValueError("VisionClock: window_s and jump_s must be > 0, confirm_packets >= 1, confirm_s >= 0")
        self.window_s = window_s
        self.jump_s = jump_s
        self.confirm_packets = confirm_packets
        self.confirm_s = confirm_s
        self.window = np.zeros((CLOCK_CAMERAS, CLOCK_CAPACITY, 2))
        self.pending = np.zeros((CLOCK_CAMERAS, CLOCK_CAPACITY, 2))
        self.counts = np.zeros((CLOCK_CAMERAS, 3), np.int64)
        self.params = np.array([window_s, jump_s, confirm_packets, confirm_s, 0.0])

    @property
    def jumps_confirmed(self) -> int:
        return int(self.params[_CLOCK_JUMPS])

    def offset_s(self, camera_id: int) -> float | None:
        head, size, _ = self.counts[camera_id].tolist()
        return float(self.window[camera_id, head, 1]) if size else None

    def to_receiver(self, camera_id: int, t_capture_s: float, t_sent_s: float, t_receive_s: float) -> float:
        """The capture time on the receiver's clock; raises ClockJump for a frame of a suspected forward jump."""
        if not 0 <= camera_id < CLOCK_CAMERAS:
            raise ValueError(f"camera_id {camera_id} is not in 0..{CLOCK_CAMERAS - 1}")
        refused, stamp, sample, deviation, offset = clock_step(
            self.window, self.pending, self.counts, self.params, camera_id, float(t_capture_s), float(t_sent_s),
            float(t_receive_s))
        if refused:
            raise ClockJump(clock_jump_text(camera_id, sample, deviation, offset))
        return stamp


# --------------------------------------------------------------------------------- capture order
CAPTURE_NEW, CAPTURE_OLD, CAPTURE_RESTART = range(3)  # capture_step's verdicts


@numba.njit(cache=True, error_model="numpy")
def capture_step(last_capture, camera, t_capture, restart_s, take_restart):
    """CaptureOrder.take on its array: (verdict, how far [s] t_capture lies before the camera's newest). A new
    frame is recorded, an old one not; a restart only with ``take_restart`` (a compiled pass leaves it to the
    general path, which says so)."""
    back_s = last_capture[camera] - t_capture
    if back_s < 0.0:
        last_capture[camera] = t_capture
        return CAPTURE_NEW, back_s
    if back_s < restart_s:
        return CAPTURE_OLD, back_s
    if take_restart:
        last_capture[camera] = t_capture
    return CAPTURE_RESTART, back_s


class CaptureOrder:
    """Per camera, the newest ``t_capture`` taken: the one order check in front of every time source. A frame
    that is not after it is old news (the same frame again, a frame the network reordered, a second sender with
    the same camera id) and is dropped (``t_capture_back``); one at least ``restart_s`` before it means the
    camera's clock started again (a simulator or a log restarted) and is passed on: ``vision`` stamps it as it
    is, the vision clock (``estimate``) and the capture timeline (``capture``) refuse its line as a clock jump
    until confirmed. Cameras 0 .. CLOCK_CAMERAS - 1; a compiled pass runs ``capture_step`` on ``last_s``."""

    def __init__(self, restart_s: float = 0.25) -> None:
        self.last_s = np.full(CLOCK_CAMERAS, -np.inf)
        self.restart_s = restart_s
        self._step = compiled_for(capture_step, self.last_s, 0, 0.0, 0.25, True)  # no type matching per frame

    @property
    def restart_s(self) -> float:
        return self._restart_s

    @restart_s.setter
    def restart_s(self, value: float) -> None:
        if not (math.isfinite(value) and value > 0.0):
            raise ValueError(f"CaptureOrder: restart_s must be finite and > 0, got {value!r}")
        self._restart_s = float(value)

    def take(self, camera_id: int, t_capture_s: float) -> tuple[int, float]:
        """(CAPTURE_NEW / CAPTURE_OLD (drop the frame) / CAPTURE_RESTART, how far [s] it lies before the camera's
        newest frame)."""
        if not 0 <= camera_id < CLOCK_CAMERAS:
            raise ValueError(f"camera_id {camera_id} is not in 0..{CLOCK_CAMERAS - 1}")
        return self._step(self.last_s, int(camera_id), float(t_capture_s), self._restart_s, True)


def capture_back_text(camera_id: int, t_capture_s: float, back_s: float) -> str:
    return (f"camera {camera_id}: frame with t_capture {t_capture_s:.6f} s dropped: {back_s * 1e3:.3f} ms before "
            "the camera's newest frame (the same frame again, a reordered or a stale one)")


def capture_restart_text(camera_id: int, back_s: float) -> str:
    return (f"camera {camera_id}: t_capture went back by {back_s:.3f} s: not an old frame but the camera's clock "
            "starting again (passed on to the time source)")


class PaceCheck:
    """Whether a camera's clock runs at the pace of the receiver's, seen through VisionClock's offsets.

    The estimate maps ``t_capture`` onto the receiver's clock with a fixed offset: right for a vision host
    (clocks that differ by parts per million), wrong for a world not paced to the wall clock (grSim at
    0.62-0.98x, a simulator flat out). There the offset drifts by (1 - pace) per second, the window's
    minimum lags it and the jump rule catches up in steps of about ``jump_s``, and speeds come out scaled
    by the pace: ``time_source: capture`` is the answer. ``check`` compares a camera's offset with its
    first one; a pace off by more than 1 % plus what the estimate's lag (``lag_s``) explains gets a text.
    """

    def __init__(self, lag_s: float) -> None:
        self.lag_s = lag_s
        self._first: dict[int, tuple[float, float]] = {}

    def check(self, camera_id: int, offset_s: float, t_receive_s: float) -> str | None:
        first = self._first.setdefault(camera_id, (offset_s, t_receive_s))
        elapsed_s = t_receive_s - first[1]
        if elapsed_s <= 0.0:
            return None
        pace = 1.0 - (offset_s - first[0]) / elapsed_s
        if abs(pace - 1.0) <= 0.01 + self.lag_s / elapsed_s:
            return None
        return (f"camera {camera_id}: its clock runs at {pace:.2f}x this host's (over {elapsed_s:.0f} s): a world not "
                "paced to the wall clock; time_source estimate steps and scales its stamps, use time_source capture "
                "(and use_sim_time on the AI side)")


# ------------------------------------------------------------------------------- capture timeline
# The timeline's state is arrays, like the clock's: a row per camera (columns _TL_*), the calibration samples of
# each camera's offset, and a few numbers for the whole timeline (_TG_*).
(_TL_OFFSET, _TL_CALIBRATED, _TL_LAST_T, _TL_LAST_W, _TL_LAST_SENT, _TL_LAST_STAMP, _TL_RATE_W, _TL_RATE_SENT,
 _TL_NEXT_RATE_W, _TL_NEXT_RATE_SENT, _TL_SAMPLES, _TL_PENDING, _TL_PENDING_FIRST_T, _TL_PENDING_FIRST_W,
 _TL_PENDING_LAST_T, _TL_PENDING_LAST_W, _TL_RECEIVED_W) = range(17)
_TL_COLUMNS = 17
(_TG_NEWEST, _TG_JUMPS, _TG_JUMP_S, _TG_MAX_RATE, _TG_CONFIRM_PACKETS, _TG_CONFIRM_S, _TG_SHARE_S, _TG_REF_AGE_S,
 _TG_CALIBRATION) = range(9)
TIMELINE_OK, TIMELINE_BACK, TIMELINE_JUMP = range(3)  # timeline_step's status
_RATE_BASE_S = 0.5  # a camera's rate (its seconds per receiver second) is measured over 0.5 .. 1 s of receive time


@numba.njit(cache=True, error_model="numpy")
def _camera_rate(row):
    """The camera's clock seconds per receiver second over its last 0.5 .. 1 s (1 until 50 ms are seen)."""
    span = row[_TL_LAST_W] - row[_TL_RATE_W]
    return (row[_TL_LAST_SENT] - row[_TL_RATE_SENT]) / span if span >= 0.05 else 1.0


@numba.njit(cache=True, error_model="numpy")
def _offset_sample(cams, glob, camera, t_sent, w):
    """What the newest frame of the most recently seen calibrated camera (not ``camera``, none of whose frames
    wait as a suspected jump, seen within the reference age) says ``camera``'s offset is: its sent time on the
    timeline, carried forward at its rate to ``w``, minus ``t_sent``. NaN without such a camera."""
    best, best_w = -1, -np.inf
    for k in range(cams.shape[0]):
        row = cams[k]
        if k != camera and row[_TL_CALIBRATED] != 0.0 and row[_TL_PENDING] == 0.0 and row[_TL_LAST_W] > best_w:
            best, best_w = k, row[_TL_LAST_W]
    if best < 0 or w - best_w > glob[_TG_REF_AGE_S]:
        return np.nan
    ref = cams[best]
    return ref[_TL_LAST_SENT] + ref[_TL_OFFSET] + _camera_rate(ref) * (w - best_w) - t_sent


@numba.njit(cache=True, error_model="numpy")
def _anchor(cams, samples, glob, camera, t_capture, t_sent, w, line_first_t, line_frames):
    """A camera without an offset (new, or its clock's jump confirmed): measured against another camera's
    clock (calibrated over the next frames), or, without one, its line (from ``line_first_t``, ``line_frames``
    frames) continues the timeline one frame after its newest stamp; the very first camera founds it."""
    row = cams[camera]
    d = _offset_sample(cams, glob, camera, t_sent, w)
    newest = glob[_TG_NEWEST]
    row[_TL_SAMPLES] = 0.0
    if not np.isnan(d):  # provisional until the samples of the next frames calibrate it
        row[_TL_OFFSET], row[_TL_CALIBRATED] = d, 0.0
    elif np.isnan(newest):
        row[_TL_OFFSET], row[_TL_CALIBRATED] = 0.0, 1.0
    else:
        period = (t_capture - line_first_t) / (line_frames - 1) if line_frames > 1 else 0.0
        row[_TL_OFFSET], row[_TL_CALIBRATED] = newest + max(period, 1e-6) - line_first_t, 1.0
    row[_TL_RATE_W], row[_TL_RATE_SENT] = w, t_sent
    row[_TL_NEXT_RATE_W], row[_TL_NEXT_RATE_SENT] = w, t_sent


@numba.njit(cache=True, error_model="numpy")
def _calibrate(cams, samples, glob, camera, t_sent, w):
    """One more sample of an uncalibrated camera's offset; with enough of them, their median becomes the
    offset, or the offset of a calibrated camera within share_s of it (the same clock: one host, a simulator)."""
    row = cams[camera]
    d = _offset_sample(cams, glob, camera, t_sent, w)
    if np.isnan(d):
        return
    n = int(row[_TL_SAMPLES])
    samples[camera, n] = d
    n += 1
    row[_TL_SAMPLES] = n
    if n < glob[_TG_CALIBRATION]:
        return
    offset = np.median(samples[camera, :n])
    best = glob[_TG_SHARE_S]
    for k in range(cams.shape[0]):
        other = cams[k]
        if k != camera and other[_TL_CALIBRATED] != 0.0 and abs(other[_TL_OFFSET] - offset) <= best:
            best = abs(other[_TL_OFFSET] - offset)
            offset = other[_TL_OFFSET]
    row[_TL_OFFSET], row[_TL_CALIBRATED] = offset, 1.0


@numba.njit(cache=True, error_model="numpy")
def timeline_step(cams, samples, glob, camera, t_capture, t_sent, w):
    """CaptureTimeline.stamp on the arrays: (status, value). TIMELINE_OK: the stamp; TIMELINE_BACK (an old
    frame: drop class t_capture_back): how far [s] t_capture lies before the camera's newest on its line;
    TIMELINE_JUMP (a line not yet confirmed: clock_jump): t_capture minus the newest accepted one [s]."""
    row = cams[camera]
    jump_s, max_rate = glob[_TG_JUMP_S], glob[_TG_MAX_RATE]
    # the capture time a frame may move on by: jump_s, and at max_rate over the receive time the camera was
    # silent (since any frame of it: refused frames do not make a jump plausible)
    silent_s = max(w - row[_TL_RECEIVED_W], 0.0)
    row[_TL_RECEIVED_W] = w
    if np.isnan(row[_TL_OFFSET]):
        _anchor(cams, samples, glob, camera, t_capture, t_sent, w, t_capture, 1)
    else:
        dt = t_capture - row[_TL_LAST_T]
        if 0.0 < dt <= jump_s + max_rate * silent_s:
            row[_TL_PENDING] = 0.0
            if row[_TL_CALIBRATED] == 0.0:
                _calibrate(cams, samples, glob, camera, t_sent, w)
        elif -jump_s < dt <= 0.0:  # an old frame (CaptureOrder in front drops most): until the clock passes
            return TIMELINE_BACK, -dt
        else:  # the camera's clock stepped back or too far forward: a new line once confirmed
            n = int(row[_TL_PENDING])
            if n > 0:
                step = t_capture - row[_TL_PENDING_LAST_T]
                if -jump_s < step <= 0.0:  # a late frame of the new line
                    return TIMELINE_BACK, -step
                if not 0.0 < step <= jump_s + max_rate * max(w - row[_TL_PENDING_LAST_W], 0.0):
                    n = 0  # not one line: count again
            if n == 0:
                row[_TL_PENDING_FIRST_T], row[_TL_PENDING_FIRST_W] = t_capture, w
            n += 1
            row[_TL_PENDING], row[_TL_PENDING_LAST_T], row[_TL_PENDING_LAST_W] = n, t_capture, w
            if n < glob[_TG_CONFIRM_PACKETS] or w - row[_TL_PENDING_FIRST_W] < glob[_TG_CONFIRM_S]:
                return TIMELINE_JUMP, dt
            glob[_TG_JUMPS] += 1.0
            row[_TL_PENDING] = 0.0
            _anchor(cams, samples, glob, camera, t_capture, t_sent, w, row[_TL_PENDING_FIRST_T], n)
    stamp = t_capture + row[_TL_OFFSET]
    if not stamp > row[_TL_LAST_STAMP]:  # after a correction of the offset: the camera's stamps still increase
        stamp = row[_TL_LAST_STAMP] + 1e-6
    row[_TL_LAST_T], row[_TL_LAST_W], row[_TL_LAST_SENT], row[_TL_LAST_STAMP] = t_capture, w, t_sent, stamp
    if w - row[_TL_NEXT_RATE_W] >= _RATE_BASE_S:
        row[_TL_RATE_W], row[_TL_RATE_SENT] = row[_TL_NEXT_RATE_W], row[_TL_NEXT_RATE_SENT]
        row[_TL_NEXT_RATE_W], row[_TL_NEXT_RATE_SENT] = w, t_sent
    # the timeline's now moves with calibrated cameras only: a camera still being measured is a few
    # milliseconds off (its reference's rate unknown at first) and must not carry /clock ahead
    if row[_TL_CALIBRATED] != 0.0 and (np.isnan(glob[_TG_NEWEST]) or stamp > glob[_TG_NEWEST]):
        glob[_TG_NEWEST] = stamp
    return TIMELINE_OK, stamp


def timeline_jump_text(camera_id: int, t_capture_s: float, step_s: float) -> str:
    what = f"goes back {-step_s:.3f} s" if step_s <= 0.0 else f"jumps {step_s:.3f} s ahead"
    return (f"camera {camera_id}: t_capture {t_capture_s:.6f} s {what} from its newest on the capture timeline (the "
            "camera's clock stepped); frame refused until its new time line is confirmed")


def timeline_refusal(camera_id: int, status: int, t_capture_s: float, value: float) -> ClockJump:
    """A refused frame's ClockJump, its class and text from timeline_step's (status, value)."""
    if status == TIMELINE_BACK:
        return ClockJump(capture_back_text(camera_id, t_capture_s, value), "t_capture_back")
    return ClockJump(timeline_jump_text(camera_id, t_capture_s, value))


class CaptureTimeline:
    """The cameras' capture times on one timeline: the stamps and /clock of ``time_source: capture``.

    The time of an outside world is its cameras' ``t_capture``: a simulator's simulated time, a vision
    host's clock. The timeline follows it, whatever its pace against the receiver's clock (a simulator at
    0.6x or 3x): a camera's stamp is ``t_capture + offset``, with the camera's offset fixed, so consecutive
    frames of a camera are as far apart on the timeline as they were captured, gaps included.

    - The first camera founds the timeline (offset 0: the stamps are its capture times). A later camera
      is measured against the most recently seen calibrated camera: that camera's newest sent time,
      carried forward at its measured rate to the receive time, minus the new camera's ``t_sent`` (equal
      network delays). The median of ``calibration_frames`` such samples becomes its offset, or the offset
      of a calibrated camera within ``share_s`` of it (one clock: SSL-Vision's host, a simulator).
    - A camera's ``t_capture`` that is not after its previous one refuses the frame (TIMELINE_BACK, drop
      class t_capture_back): a late or repeated frame, or a step back by less than ``jump_s``, which passes
      once the clock passes its previous time (CaptureOrder in front drops these first; the timeline sees one
      only while its newest and the order's differ, around a line not yet confirmed). One more than ``jump_s``
      back (which CaptureOrder passes on as a restart), or later by more than ``jump_s`` plus ``max_rate``
      times the receive time the camera was silent (a world at most that much faster than the receiver),
      starts a suspected new line (TIMELINE_JUMP, drop class clock_jump): once ``confirm_packets`` frames on
      it span ``confirm_s`` of receive time, the camera's clock has jumped (a restarted simulator) and it is
      measured again as a new camera; without another camera to measure it against, its new line continues
      the timeline one frame period after its newest stamp. A stalled receiver's backlog is consecutive
      frames and passes.
    - A camera's stamps strictly increase; ``newest_s`` (what /clock says), the newest stamp of a
      calibrated camera, never goes back. Vision that stops holds it; when vision resumes, it moves on by
      the capture time that passed.

    Receive times ``t_wall_s`` are a monotonic wall clock (the timeline's own /clock must not be its
    reference). Cameras 0 .. CLOCK_CAMERAS - 1.
    """

    def __init__(self, jump_s: float = 0.25, max_rate: float = 10.0, confirm_packets: int = 5,
                 confirm_s: float = 0.2, share_s: float = 0.02, reference_age_s: float = 0.5,
                 calibration_frames: int = 30) -> None:
        if not (jump_s > 0.0 and max_rate > 0.0 and confirm_packets >= 1 and confirm_s >= 0.0 and share_s >= 0.0
                and reference_age_s > 0.0 and 1 <= calibration_frames <= CLOCK_CAPACITY):
            raise ValueError("CaptureTimeline: jump_s, max_rate and reference_age_s must be > 0, confirm_packets "
                             f">= 1, confirm_s and share_s >= 0, calibration_frames in 1..{CLOCK_CAPACITY}")
        self.cams = np.full((CLOCK_CAMERAS, _TL_COLUMNS), 0.0)
        self.cams[:, [_TL_OFFSET, _TL_LAST_STAMP]] = np.nan, -np.inf
        self.samples = np.zeros((CLOCK_CAMERAS, calibration_frames))
        self.glob = np.array([np.nan, 0.0, jump_s, max_rate, confirm_packets, confirm_s, share_s, reference_age_s,
                              calibration_frames])

    def set_jump_s(self, jump_s: float) -> None:
        """A new jump_s from now on (the timeline's time and offsets stay)."""
        if not jump_s > 0.0:
            raise ValueError(f"CaptureTimeline: jump_s must be > 0, got {jump_s!r}")
        self.glob[_TG_JUMP_S] = jump_s

    @property
    def newest_s(self) -> float | None:
        """The newest stamp given (the timeline's now), None before the first frame."""
        newest = float(self.glob[_TG_NEWEST])
        return None if math.isnan(newest) else newest

    @property
    def jumps_confirmed(self) -> int:
        return int(self.glob[_TG_JUMPS])

    def offset_s(self, camera_id: int) -> float | None:
        offset = float(self.cams[camera_id, _TL_OFFSET])
        return None if math.isnan(offset) else offset

    def calibrated(self, camera_id: int) -> bool:
        return bool(self.cams[camera_id, _TL_CALIBRATED])

    def last_capture_s(self, camera_id: int) -> float:
        return float(self.cams[camera_id, _TL_LAST_T])

    def stamp(self, camera_id: int, t_capture_s: float, t_sent_s: float, t_wall_s: float) -> float:
        """The frame's stamp on the timeline; raises ClockJump (its kind the drop class) for a refused frame."""
        if not 0 <= camera_id < CLOCK_CAMERAS:
            raise ValueError(f"camera_id {camera_id} is not in 0..{CLOCK_CAMERAS - 1}")
        status, value = timeline_step(self.cams, self.samples, self.glob, camera_id, float(t_capture_s),
                                      float(t_sent_s), float(t_wall_s))
        if status != TIMELINE_OK:
            raise timeline_refusal(camera_id, status, t_capture_s, value)
        return value
