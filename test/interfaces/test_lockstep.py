"""The lockstep pairing rules, without DDS."""

import numpy as np
import pytest

from erforce_interfaces.runtime.lockstep import DutyGate, FieldAnswerRobots, SetpointJoin

MS = 1_000_000


def test_gate_waits_for_every_present_peer_and_only_for_the_open_tick():
    gate = DutyGate(num_robots=3, timeout_s=1.0)
    gate.open(5 * MS, now_s=0.0, peers_present={0, 2})
    assert not gate.ready() and gate.missing() == {0, 2}
    gate.offer(0, 4 * MS, np.ones(4))  # an answer to an old tick does not count
    assert gate.missing() == {0, 2}
    gate.offer(0, 5 * MS, np.ones(4))
    gate.offer(2, 5 * MS, np.full(4, 0.5))
    assert gate.ready()
    np.testing.assert_array_equal(gate.duty_for(1, 4), np.zeros(4))  # robot 1 has no motor board
    np.testing.assert_array_equal(gate.duty_for(2, 4), np.full(4, 0.5))


def test_gate_reports_a_stall_after_the_timeout_then_resumes():
    gate = DutyGate(num_robots=2, timeout_s=0.5)
    gate.open(1 * MS, now_s=10.0, peers_present={0, 1})
    gate.offer(0, 1 * MS, np.ones(4))
    assert gate.check_stall(now_s=10.4) == []
    events = gate.check_stall(now_s=10.6)
    assert len(events) == 1 and "robot_1" in events[0] and "stalled" in events[0]
    assert gate.ready()  # no longer waiting for robot 1
    np.testing.assert_array_equal(gate.duty_for(1, 4), np.zeros(4))
    for k in range(2, 6):  # the plant goes on without robot 1
        gate.open(k * MS, now_s=10.7, peers_present={0, 1})
        assert gate.expected == {0}  # a stalled peer does not gate the next ticks
        gate.offer(0, k * MS, np.ones(4))
        assert gate.ready()
    assert gate.offer(1, 0, np.zeros(4)) is None  # an answer from before the stall proves nothing
    event = gate.offer(1, 3 * MS, np.full(4, 0.25))  # late, but alive again
    assert event is not None and "resumed" in event
    gate.open(6 * MS, now_s=10.8, peers_present={0, 1})
    assert gate.expected == {0, 1}  # gates the plant again
    gate.offer(0, 6 * MS, np.ones(4))
    assert not gate.ready()
    gate.offer(1, 6 * MS, np.full(4, 0.25))
    assert gate.ready() and gate.duty_for(1, 4)[0] == 0.25


def test_gate_does_not_blame_its_peers_for_the_plants_own_pause():
    """The plant stopped (SIGSTOP, a debugger) or starved: its checks stopped for longer than the timeout, and
    the answers may be waiting unread. The wait starts again; a peer silent for a whole timeout after that
    still stalls."""
    gate = DutyGate(num_robots=2, timeout_s=0.5)
    gate.open(1 * MS, now_s=10.0, peers_present={0, 1})
    assert gate.check_stall(now_s=10.01) == []
    assert gate.check_stall(now_s=13.01) == []  # 3 s without a check: the plant's own pause
    gate.offer(0, 1 * MS, np.ones(4))  # robot 0's answer, read after the pause
    assert gate.check_stall(now_s=13.3) == [] and gate.missing() == {1}
    events = gate.check_stall(now_s=13.6)  # 0.59 s of waiting, checked all along: robot 1 is silent
    assert len(events) == 1 and "robot_1" in events[0] and "stalled" in events[0]


def test_join_uses_the_previous_ticks_setpoint_and_waits_for_it():
    join = SetpointJoin(wait=True)
    assert join.setpoint_for(1 * MS) == (True, None)  # first tick: nothing known, command zero
    join.done(1 * MS)
    assert join.setpoint_for(2 * MS) == (False, None)  # the answer to tick 1 has not arrived
    join.add_setpoint(1 * MS, np.array([1.0, 2.0]))
    ready, (stamp, sp) = join.setpoint_for(2 * MS)
    assert ready and stamp == 1 * MS and sp.tolist() == [1.0, 2.0]
    join.done(2 * MS)
    join.add_setpoint(2 * MS, np.array([3.0, 4.0]))
    join.add_setpoint(3 * MS, np.array([5.0, 6.0]))  # answers tick 3: must not be used at tick 3
    ready, (stamp, sp) = join.setpoint_for(3 * MS)
    assert ready and stamp == 2 * MS and sp.tolist() == [3.0, 4.0]


def test_join_forced_once_then_stops_waiting_until_setpoints_return():
    join = SetpointJoin(wait=True)
    join.add_setpoint(0, np.array([7.0]))
    join.done(1 * MS)
    assert join.setpoint_for(2 * MS) == (False, None)
    ready, (stamp, sp) = join.setpoint_for(2 * MS, force=True)
    assert ready and stamp == 0 and sp.tolist() == [7.0]
    join.done(2 * MS)
    ready, (stamp, _) = join.setpoint_for(3 * MS)  # silent source: no second wait
    assert ready and stamp == 0
    join.done(3 * MS)
    join.add_setpoint(3 * MS, np.array([8.0]))  # the main board is back
    join.done(4 * MS)
    assert join.setpoint_for(5 * MS) == (False, None)  # waits again for tick 4's answer


def test_join_in_realtime_takes_the_newest_older_setpoint():
    realtime = SetpointJoin(wait=False)
    realtime.done(1 * MS)
    realtime.add_setpoint(1 * MS, np.array([8.0]))
    realtime.add_setpoint(3 * MS, np.array([9.0]))
    ready, (stamp, sp) = realtime.setpoint_for(2 * MS)
    assert ready and stamp == 1 * MS and sp.tolist() == [8.0]


def test_join_keeps_one_second_of_setpoints_and_forgets_them_when_time_goes_back():
    join = SetpointJoin(wait=True)
    for k in range(1000):  # 2 s at 2 ms
        join.add_setpoint(k * 2 * MS, np.array([float(k)]))
    assert min(join.setpoints) == 1998 * MS - 1000 * MS and len(join.setpoints) == 501
    join.add_setpoint(4 * MS, np.array([-1.0]))  # a restarted plant starts again near 0
    assert list(join.setpoints) == [4 * MS]


def test_a_field_answers_robot_set_is_remembered_only_for_the_controlled_robots_it_was_checked_against():
    # world indices: ours 0 -> 0, 3 -> 1; the opponents' 0 -> 2, 5 -> 3
    answers = FieldAnswerRobots({0: 0, 3: 1}, {0: 2, 5: 3})
    all_four = frozenset({0, 1, 2, 3})
    assert answers.lookup((0, 3), (5,), all_four) is None  # not learnt yet
    answers.learn((0, 3), (5,), all_four)
    assert answers.lookup((0, 3), (5,), all_four) == (0, 1, 3)  # in the answer's row order
    assert answers.lookup((3, 0), (5,), all_four) is None  # another order is another set
    # a set with a robot that is not controlled, or not on the field (ours 7), is not remembered
    answers.learn((0,), (0,), frozenset({0, 1, 3}))
    answers.learn((0, 7), (), all_four)
    assert answers.lookup((0,), (0,), frozenset({0, 1, 3})) is None and answers.lookup((0, 7), (), all_four) is None
    # a change of control: what was learnt for all four is not found for the new controlled set, even where the
    # set's robots are all still controlled, until it is checked again
    without_ours_3 = frozenset({0, 2, 3})
    assert answers.lookup((0, 3), (5,), without_ours_3) is None
    answers.learn((0, 3), (5,), without_ours_3)  # ours 3 (index 1) is no longer controlled
    assert answers.lookup((0, 3), (5,), without_ours_3) is None
    answers.learn((0,), (5,), without_ours_3)
    assert answers.lookup((0,), (5,), without_ours_3) == (0, 3)
    assert answers.lookup((0, 3), (5,), frozenset({0, 1, 2, 3})) == (0, 1, 3)  # control given back: an equal set
    with pytest.raises(TypeError):  # a set that could change in place is no key
        answers.lookup((0,), (5,), {0, 2, 3})


def test_field_answer_robot_sets_are_bounded():
    answers = FieldAnswerRobots({k: k for k in range(10)}, {}, max_sets=3)
    controlled = frozenset(range(10))
    for k in range(3):
        answers.learn((k,), (), controlled)
    assert [answers.lookup((k,), (), controlled) for k in range(3)] == [(0,), (1,), (2,)]
    answers.learn((3,), (), controlled)  # a fourth: the others are forgotten
    assert [answers.lookup((k,), (), controlled) for k in range(4)] == [None, None, None, (3,)]
