"""A recorded bag (the demo's rosbag2/MCAP) replayed as field-view frames at any log time (``BagReplay``),
for the field view node's replay request and the tests. No rclpy here.
"""

from __future__ import annotations

import bisect
import copy
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

from erforce_interfaces.wire.robot_config import FieldConfig
from erforce_sim.view.field_view import (
    WorldState,
    view_topic,
)


class BagReplay:
    """A recorded bag (the demo's rosbag2/MCAP) as frames at any time: ``frame_at(t_s)``.

    The view's topics are read once (``decode(type_name, cdr_bytes)`` gives what ``apply`` takes) and
    a snapshot of the state is kept every ``checkpoint_period_s`` of log time, so a jump anywhere
    replays at most that much; playing forward applies only what is new.
    """

    def __init__(self, path: str | Path, decode: Callable[[str, bytes], Any], field: FieldConfig,
                 checkpoint_period_s: float = 1.0, **state_kwargs) -> None:
        from rosbags.rosbag2 import Reader  # only a replay needs it

        self.path = Path(path)
        self._times: list[int] = []
        self._messages: list[tuple[str, Any]] = []
        self.skipped = 0  # records that did not decode
        with Reader(self.path) as reader:
            connections = [c for c in reader.connections if view_topic(c.topic) is not None]
            # (no connection given reads them all)
            for connection, t_ns, data in reader.messages(connections=connections) if connections else ():
                try:
                    msg = decode(connection.msgtype, bytes(data))
                except Exception:  # a damaged record: the rest plays
                    self.skipped += 1
                    continue
                self._times.append(t_ns)
                self._messages.append((connection.topic, msg))
        if not self._times:
            raise ValueError(f"{self.path}: no message of the view's topics")
        self.start_s = self._times[0] * 1e-9
        self.end_s = self._times[-1] * 1e-9
        self._blank = WorldState(field, **state_kwargs)
        self._checkpoints: list[tuple[int, WorldState]] = [(0, copy.deepcopy(self._blank))]
        state = copy.deepcopy(self._blank)
        next_checkpoint = self._times[0] + int(checkpoint_period_s * 1e9)
        for i, (topic, msg) in enumerate(self._messages):
            if self._times[i] >= next_checkpoint:
                self._checkpoints.append((i, copy.deepcopy(state)))
                next_checkpoint = self._times[i] + int(checkpoint_period_s * 1e9)
            state.apply(topic, msg)
        self._checkpoint_index = [i for i, _ in self._checkpoints]
        self._cursor = 0
        self._state = copy.deepcopy(self._blank)

    def __len__(self) -> int:
        return len(self._messages)

    def frame_at(self, t_s: float) -> dict[str, Any]:
        """The frame of the bag's state at log time ``t_s`` (clamped to the bag)."""
        if not math.isfinite(t_s):
            raise ValueError(f"replay time must be finite, got {t_s!r}")
        t_ns = round(min(max(t_s, self.start_s), self.end_s) * 1e9)
        end = bisect.bisect_right(self._times, t_ns)
        if end < self._cursor or end - self._cursor > 2 * self._checkpoint_span():
            index = bisect.bisect_right(self._checkpoint_index, end) - 1
            self._cursor, self._state = self._checkpoints[index][0], copy.deepcopy(self._checkpoints[index][1])
        for topic, msg in self._messages[self._cursor:end]:
            self._state.apply(topic, msg)
        self._cursor = end
        frame = self._state.frame()
        frame["replay"] = {"start": round(self.start_s, 4), "end": round(self.end_s, 4), "t": round(t_ns * 1e-9, 4)}
        return frame

    def _checkpoint_span(self) -> int:
        return max(1, len(self._messages) // max(1, len(self._checkpoints)))
