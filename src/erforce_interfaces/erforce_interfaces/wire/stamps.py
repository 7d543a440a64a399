"""The one rule for time that every node applies to ``/clock`` and to the stamps of its inputs.

A stream of stamps from one source (the ``/clock`` topic, or the header stamps of one input topic)
moves forward in small steps. ``StampFilter`` judges each stamp against the newest one it accepted:

- ``ACCEPT``: at or after the newest accepted stamp and at most ``max_jump_s`` later (a repeat, such
  as the plant's re-sent tick, is accepted; the node's core decides what a repeat means).
- ``DROP``: not a time at all (negative, nanoseconds >= 1e9) or a jump: before the newest accepted
  stamp, or more than ``max_jump_s`` after it. A jump is dropped but remembered.
- ``RESTART``: a new time line, such as a restarted simulator that starts again at 0. A jump is taken
  as one when the old time line has been silent for ``dead_s`` of wall time (its source is gone), or
  for ``silence_s`` and the jump is confirmed by a second stamp (the same again, or after it by at most
  ``max_jump_s``, itself a jump from the old line). The same stamp again counts: a restarted plant in
  lockstep re-sends its first tick until it is answered, and nothing later comes before the answer. It
  is accepted, and the node resets what it keeps from the old time line.

So a single zero, far-future or backwards stamp from a careless or hostile participant is dropped
with a warning while the real source goes on, and so is a flood of them stamped alike (say, every
message stamped 0): it never advances. A source that died and came back restarts the line at once.
Nothing here knows ROS.
"""

from __future__ import annotations

import enum
import math
import time

_NS = 1_000_000_000
_INT32_MAX = 2**31 - 1


class StampVerdict(enum.Enum):
    ACCEPT = "accept"
    DROP = "drop"
    RESTART = "restart"


def stamp_ns(sec: int, nanosec: int) -> int | None:
    """A builtin_interfaces/Time as nanoseconds, or None when it is no valid time (rclpy's
    ``Time.from_msg`` raises on these: negative seconds, nanoseconds out of range)."""
    if not (0 <= sec <= _INT32_MAX and 0 <= nanosec < _NS):
        return None
    return sec * _NS + nanosec


class StampFilter:
    """Judges the stamps of one source (see the module docstring). ``reason`` says why the last
    stamp was dropped or restarted the time line, for the node's warning."""

    def __init__(self, max_jump_s: float = 2.0, silence_s: float = 0.2, dead_s: float = 1.0) -> None:
        if not (max_jump_s > 0.0 and 0.0 <= silence_s <= dead_s):
            raise ValueError(f"need max_jump_s > 0 and 0 <= silence_s <= dead_s, got {max_jump_s!r}, "
                             f"{silence_s!r}, {dead_s!r}")
        self.max_jump_ns = int(max_jump_s * _NS)
        self.silence_s, self.dead_s = float(silence_s), float(dead_s)
        self.newest_ns: int | None = None
        self._accepted_at_s = -math.inf  # wall time of the newest accepted stamp
        self._jump_ns: int | None = None  # the last dropped jump, which the next stamp may confirm
        self.reason = ""

    def _on_line(self, line_ns: int, t_ns: int) -> bool:
        return line_ns <= t_ns <= line_ns + self.max_jump_ns

    def offer(self, t_ns: int | None, now_s: float | None = None) -> StampVerdict:
        """The verdict on stamp ``t_ns`` [ns] (None: not a valid time) arriving at wall time ``now_s``
        [s] (default: time.monotonic())."""
        if t_ns is None or t_ns < 0:
            self.reason = "not a valid time (negative, or nanoseconds out of range)"
            return StampVerdict.DROP
        now_s = time.monotonic() if now_s is None else now_s
        newest = self.newest_ns
        if newest is None or self._on_line(newest, t_ns):
            self.newest_ns, self._jump_ns, self._accepted_at_s = t_ns, None, now_s
            return StampVerdict.ACCEPT
        jump, silent_s = self._jump_ns, now_s - self._accepted_at_s
        confirmed = jump is not None and self._on_line(jump, t_ns) and silent_s >= self.silence_s
        if confirmed or silent_s >= self.dead_s:
            self.reason = f"time line restarted: {newest / _NS:.6f} s -> {t_ns / _NS:.6f} s"
            self.newest_ns, self._jump_ns, self._accepted_at_s = t_ns, None, now_s
            return StampVerdict.RESTART
        self._jump_ns = t_ns
        direction = "before" if t_ns < newest else f"more than {self.max_jump_ns / _NS:g} s after"
        self.reason = f"stamp {t_ns / _NS:.6f} s is {direction} the newest accepted {newest / _NS:.6f} s"
        return StampVerdict.DROP

    def reset(self) -> None:
        self.newest_ns = self._jump_ns = None
        self._accepted_at_s = -math.inf
