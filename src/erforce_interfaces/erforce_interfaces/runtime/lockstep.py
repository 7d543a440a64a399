"""The lockstep protocol: the plant advances a tick only when every live motor board has answered it.

The control loop over DDS, per robot and per tick k (period T: the plant's ``control_period_s``,
default ``TICK_PERIOD_S``, 2 ms):

    plant ──wheel_states(t_k)──► motor_boards ──motor_duty(t_k)──► plant     (critical path)
          └─────────────────────► velocity_controller ──wheel_setpoints(t_k)──► motor_boards (used at k+1)

The velocity controller's answer is used one tick later, like a main board whose
setpoints reach the motor boards over a bus: the critical path is a single round trip,
and the in-process runner reproduces the same one-tick delay, so both give the same
trajectory for the same seed.

``DutyGate`` is the plant's side: it pairs answers with the open tick, lets a robot that
has no motor board (no publisher) pass, reports a peer that does not answer within a
wall-clock timeout as stalled and stops waiting for it (its motors get zero duty, as a
dead motor board leaves them), and reports it resumed when it answers again.
``SetpointJoin`` is the motor board's side: it pairs sensor tick k with the setpoint of
tick k-1. Both sides live here, next to the contract, because the protocol is part of it.
``FieldAnswerRobots`` is the plant's lookup from a field answer's robot ids to its world indices.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

# The lockstep tick over DDS: the plant's control_period_s and the robot nodes' loop_rate_hz default to
# it (their schemas' default_from). The in-process runner keeps 1 kHz (plant_setup.IN_PROCESS_TICK_PERIOD_S).
TICK_PERIOD_S = 0.002
TICK_RATE_HZ = 1.0 / TICK_PERIOD_S


@dataclass
class DutyGate:
    """Pairs motor-duty answers with the plant's open tick."""

    num_robots: int
    timeout_s: float = 1.0
    tick_ns: int = -1
    opened_at_s: float = 0.0
    duties: dict[int, np.ndarray] = field(default_factory=dict)
    stalled: dict[int, int] = field(default_factory=dict)  # robot -> tick it stalled at
    expected: set[int] = field(default_factory=set)
    names: Sequence[str] = ()  # each robot's name in the events (robot_<id> or opponent_<id>); else robot_<index>
    checked_at_s: float = math.inf  # the previous check_stall (inf: none yet)

    def open(self, tick_ns: int, now_s: float, peers_present: set[int]) -> None:
        """Start waiting for tick ``tick_ns`` from every present, non-stalled peer."""
        self.tick_ns = tick_ns
        self.opened_at_s = now_s
        self.duties = {}
        self.expected = {r for r in peers_present if r not in self.stalled}

    def offer(self, robot: int, stamp_ns: int, duty: np.ndarray) -> str | None:
        """Take an answer; returns an event text when a stalled peer comes back.

        A stalled peer is back with any answer to a tick after the one it missed: the
        plant has moved on meanwhile, so its answers are late, but it is alive; from the
        next tick on it gates the plant again.
        """
        event = None
        if robot in self.stalled and stamp_ns >= self.stalled[robot]:
            del self.stalled[robot]
            event = f"lockstep: {self._name(robot)} resumed at t={self.tick_ns * 1e-9:.3f} s"
        if stamp_ns == self.tick_ns:
            self.duties[robot] = duty
            self.expected.add(robot)
        return event

    def offer_rows(self, robots: Sequence[int], stamp_ns: int, duties: np.ndarray) -> list[str]:
        """``offer`` for several robots at once, row k of ``duties`` for ``robots[k]`` (one team or field
        answer); returns the event texts."""
        if self.stalled:
            return [event for robot, duty in zip(robots, duties, strict=True)
                    if (event := self.offer(robot, stamp_ns, duty))]
        if stamp_ns == self.tick_ns:
            self.duties.update(zip(robots, duties, strict=True))
            self.expected.update(robots)
        return []

    def ready(self) -> bool:
        return self.expected.issubset(self.duties)

    def _name(self, robot: int) -> str:
        return self.names[robot] if robot < len(self.names) else f"robot_{robot}"

    def missing(self) -> set[int]:
        return self.expected - set(self.duties)

    def check_stall(self, now_s: float) -> list[str]:
        """Stop waiting for peers silent longer than the timeout; returns event texts.

        Called at every pump of the plant. A gap longer than the timeout since the previous call means the plant
        itself did not run (stopped by SIGSTOP or a debugger, or starved of CPU): its peers' answers may be
        waiting unread, so the wait starts again from now instead of stalling every peer at once.
        """
        checked_at_s, self.checked_at_s = self.checked_at_s, now_s
        if now_s - checked_at_s > self.timeout_s:
            self.opened_at_s = max(self.opened_at_s, now_s)
            return []
        if now_s - self.opened_at_s < self.timeout_s:
            return []
        events = []
        for robot in sorted(self.missing()):
            self.stalled[robot] = self.tick_ns
            self.expected.discard(robot)
            events.append(
                f"lockstep: {self._name(robot)} motor_boards stalled: no answer to t={self.tick_ns * 1e-9:.3f} s "
                f"within {self.timeout_s:g} s; continuing with zero duty"
            )
        return events

    def duty_for(self, robot: int, num_wheels: int) -> np.ndarray:
        """The duty to apply for this tick: the answer, or zero for a silent or absent peer."""
        duty = self.duties.get(robot)
        return duty if duty is not None else np.zeros(num_wheels)


@dataclass
class SetpointJoin:
    """Motor-board side of lockstep: tick k runs with the setpoint answered at tick k-1.

    ``wait`` false (real-time pacing) never holds a tick back: the newest setpoint is used.
    After one forced tick (the velocity controller was silent past a wall-clock timeout)
    the join stops waiting until a setpoint arrives again, so a dead main board costs
    one timeout, not one per tick.
    """

    wait: bool = True
    prev_sensor_ns: int | None = None
    setpoints: dict[int, np.ndarray] = field(default_factory=dict)
    source_silent: bool = False

    def add_setpoint(self, stamp_ns: int, setpoint: np.ndarray) -> None:
        if self.setpoints and stamp_ns < next(reversed(self.setpoints)):
            self.setpoints.clear()  # time went backwards (a restarted plant): the old ones mean nothing
        self.setpoints[stamp_ns] = setpoint
        self.source_silent = False
        # Stamps arrive in order, so the oldest are at the front: drop what no pending tick can ask for.
        cutoff = stamp_ns - 1_000_000_000
        while next(iter(self.setpoints)) < cutoff:
            del self.setpoints[next(iter(self.setpoints))]

    def setpoint_for(self, sensor_ns: int, force: bool = False) -> tuple[bool, tuple[int, np.ndarray] | None]:
        """(ready, (stamp_ns, setpoint) or None) for sensor tick ``sensor_ns``.

        Not ready: the setpoint answered at the previous tick has not arrived; wait.
        ``force`` (after a wall-clock timeout) takes the newest setpoint older than the
        tick instead. None means no setpoint is known yet: command zero speed.
        """
        want = self.prev_sensor_ns
        if self.wait and not self.source_silent and want is not None and want < sensor_ns:
            if want in self.setpoints:
                return True, (want, self.setpoints[want])
            if not force:
                return False, None
            self.source_silent = True
        older = [s for s in self.setpoints if s < sensor_ns]
        if not older:
            return True, None
        newest = max(older)
        return True, (newest, self.setpoints[newest])

    def done(self, sensor_ns: int) -> None:
        self.prev_sensor_ns = sensor_ns


class FieldAnswerRobots:
    """World indices of a field answer's robots (/field/motor_duty: our ids, then the opponents'), remembered per
    robot set so that the plant takes the next answer for the same set in one step.

    A set is remembered only when every robot in it is controlled, and only for the controlled set it was checked
    against: that set is part of the key, a frozenset, so a change of control is a new key and nothing learnt
    before it is found again (a mutable set cannot be a key: TypeError). At most ``max_sets`` sets are kept.
    """

    def __init__(self, ours: Mapping[int, int], theirs: Mapping[int, int], max_sets: int = 8) -> None:
        self._index = (dict(ours), dict(theirs))  # per team: robot id -> world index
        self._max_sets = max_sets
        self._robots: dict[tuple, tuple[int, ...]] = {}

    def lookup(self, ours: tuple[int, ...], theirs: tuple[int, ...],
               controlled: frozenset[int]) -> tuple[int, ...] | None:
        """The world indices of the answer's robots in its row order, or None: take it robot by robot."""
        return self._robots.get((ours, theirs, controlled))

    def learn(self, ours: tuple[int, ...], theirs: tuple[int, ...], controlled: frozenset[int]) -> None:
        """Remember the set if every robot in it is controlled (call after taking it robot by robot)."""
        key = (ours, theirs, controlled)
        robots = tuple(index.get(j) for index, ids in zip(self._index, (ours, theirs), strict=True) for j in ids)
        if all(i in controlled for i in robots):
            if len(self._robots) >= self._max_sets:
                self._robots.clear()
            self._robots[key] = robots
