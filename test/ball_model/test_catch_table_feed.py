"""/ball/catches as the AI's input: the table read once per message (tables.catches_from_msg) and fed to
PassingPlayer and PressingTeam as the per-robot catch_time and catch_point topics fed them."""

import math

import numpy as np
import pytest

from erforce_ball_model.passing.player import PassingPlayer, PlayerConfig, PressingTeam
from erforce_ball_model.receiver import CatcherConfig
from erforce_interfaces.wire import contract
from erforce_interfaces.wire.conversions import (
    ConversionError,
    float64_cdr,
    float64_from_msg,
    point_cdr,
    point_from_msg,
)
from erforce_interfaces.wire.robot_config import FieldConfig, RobotConfig
from erforce_interfaces.wire.tables import Catch, catches_from_msg, table_cdr, table_msg

OURS, THEIRS = contract.OURS.code, contract.OPPONENTS.code
NEVER = contract.CATCH_TIME_NEVER
# team, id, x, y, yaw, vx, vy, catch time, catch x, catch y: as the predictor writes a frame, ours first
TABLE = [[OURS, 1, -1.0, 2.0, 0.5, 0.1, -0.2, 0.75, 1.25, -0.5],
         [OURS, 0, -3.0, 0.0, 0.0, 0.0, 0.0, NEVER, 0.0, 0.0],  # never: the point is no point
         [OURS, 3, 2.0, 2.0, 0.0, 0.0, 0.0, 0.4, 2.0, 2.5],
         [THEIRS, 0, 1.5, 0.0, math.pi, 0.0, 0.0, 0.25, 1.0, 0.125],
         [THEIRS, 2, 4.0, -1.0, math.pi, 0.0, 0.0, NEVER, 0.0, 0.0]]


@pytest.mark.parametrize("as_bytes", [False, True])
def test_a_hand_built_table_reads_each_teams_catches_in_its_order(as_bytes):
    msg = table_cdr(TABLE, contract.CATCH_TABLE_COLUMNS) if as_bytes else table_msg(TABLE, contract.CATCH_TABLE_COLUMNS)
    assert catches_from_msg(msg, contract.OURS) == [Catch(1, 0.75, (1.25, -0.5)), Catch(0, NEVER, None),
                                                    Catch(3, 0.4, (2.0, 2.5))]
    assert catches_from_msg(msg, contract.OPPONENTS) == [Catch(0, 0.25, (1.0, 0.125)), Catch(2, NEVER, None)]
    assert catches_from_msg(table_cdr([], contract.CATCH_TABLE_COLUMNS), contract.OURS) == []


def _with(row: int, column: str, value: float) -> list[list[float]]:
    table = [list(r) for r in TABLE]
    table[row][contract.CATCH_TABLE_COLUMNS.index(column)] = value
    return table


@pytest.mark.parametrize(("table", "reason"), [
    (_with(0, "team", 3.0), "team column"),
    (_with(3, "team", 0.0), "team column"),
    (_with(1, "robot_id", -1.0), "robot ids"),
    (_with(1, "robot_id", 1.5), "robot ids"),
    (_with(0, "catch_time_s", 1.0e4), "catch_time_s"),  # beyond what a catch_time may carry
    (_with(2, "catch_y_m", -2.0e3), "catch_y_m"),
])
def test_a_table_with_a_value_no_catch_topic_could_carry_is_refused_whole(table, reason):
    for msg in (table_cdr(table, contract.CATCH_TABLE_COLUMNS), table_msg(table, contract.CATCH_TABLE_COLUMNS)):
        with pytest.raises(ConversionError, match=reason):
            catches_from_msg(msg, contract.OURS)


def test_a_table_of_other_columns_or_non_finite_values_is_refused():
    with pytest.raises(ConversionError, match="columns"):
        catches_from_msg(table_msg([[1.0, 0.0]], ("team", "robot_id")), contract.OURS)
    nan = table_cdr(TABLE, contract.CATCH_TABLE_COLUMNS)[:-8] + np.float64(math.nan).tobytes()
    with pytest.raises(ConversionError):
        catches_from_msg(nan, contract.OURS)
    with pytest.raises(ConversionError):
        catches_from_msg(b"\x00\x01\x00\x00\x02", contract.OURS)


class _Calls:
    """Records the per-robot inputs a core is fed (and feeds nothing further)."""

    def __init__(self) -> None:
        self.calls: list[tuple] = []

    def on_catch(self, i, now, seconds, catch_point=None):
        self.calls.append(("time", i, now, seconds))

    on_catch_time = on_catch

    def on_catch_point(self, i, now, point):
        self.calls.append(("point", i, now, tuple(float(v) for v in point)))


class SpyPlayer(_Calls, PassingPlayer):
    def __init__(self, n_team: int, n_opponents: int) -> None:
        _Calls.__init__(self)
        robot = RobotConfig()
        PassingPlayer.__init__(self, PlayerConfig(), n_team, n_opponents, FieldConfig.preset("division_a"),
                               robot.dribbler_offset_m, robot.robot_radius_m)


class SpyTeam(_Calls, PressingTeam):
    def __init__(self, ids) -> None:
        _Calls.__init__(self)
        robot = RobotConfig()
        PressingTeam.__init__(self, CatcherConfig(), robot.dribbler_offset_m, robot.robot_radius_m,
                              FieldConfig.preset("division_a"), ids)


def per_robot_feed(core, now: float, team_code: float, mine) -> None:
    """What the per-robot topics fed: the predictor sends every read catch_time, then every read catch_point
    (none for never); each one through its own message."""
    rows = [r for r in TABLE if r[0] == team_code and r[1] in mine]
    for r in rows:
        core.on_catch_time(int(r[1]), now, float64_from_msg(float64_cdr(r[7])))
    for r in rows:
        if r[7] != NEVER:
            core.on_catch_point(int(r[1]), now, point_from_msg(point_cdr(1.0, (r[8], r[9])))[1])


def test_the_table_feeds_the_passing_player_what_its_robots_topics_did():
    """Three of ours (0 .. 2) and three opponents: our rows 1 and 0 (robot 3 is none of ours), times first."""
    player = SpyPlayer(3, 3)
    player.on_catches(2.5, catches_from_msg(table_cdr(TABLE, contract.CATCH_TABLE_COLUMNS), contract.OURS))
    assert player.calls == [("time", 1, 2.5, 0.75), ("time", 0, 2.5, NEVER), ("point", 1, 2.5, (1.25, -0.5))]
    per_robot = SpyPlayer(3, 3)
    per_robot_feed(per_robot, 2.5, OURS, range(3))
    assert per_robot.calls == player.calls


def test_the_table_feeds_the_opponents_team_catcher_what_its_robots_topics_did():
    """The opponents' catcher drives opponents 0 and 1: row opponent_0 only (opponent_2 is not its robot)."""
    team = SpyTeam((0, 1))
    team.on_catches(4.0, catches_from_msg(table_cdr(TABLE, contract.CATCH_TABLE_COLUMNS), contract.OPPONENTS))
    assert team.calls == [("time", 0, 4.0, 0.25), ("point", 0, 4.0, (1.0, 0.125))]
    per_robot = SpyTeam((0, 1))
    per_robot_feed(per_robot, 4.0, THEIRS, (0, 1))
    assert per_robot.calls == team.calls
    both = SpyTeam((0, 2))
    both.on_catches(4.0, catches_from_msg(table_msg(TABLE, contract.CATCH_TABLE_COLUMNS), contract.OPPONENTS))
    assert both.calls == [("time", 0, 4.0, 0.25), ("time", 2, 4.0, NEVER), ("point", 0, 4.0, (1.0, 0.125))]


@pytest.mark.parametrize(("row", "column", "value"), [
    (0, "catch_time_s", 1.0e3), (0, "catch_time_s", -1.0e3 - 1e-6), (2, "catch_x_m", -1.0e3), (2, "catch_y_m", 1001.0),
    (1, "catch_x_m", 5.0e3),  # a point of a never catch is no point: not checked
    (3, "catch_time_s", 2.0e3),  # the other team's row: not this team's catch
    (1, "robot_id", 1.0e6), (1, "robot_id", 1.0e6 + 1.0), (1, "robot_id", 0.25), (4, "team", 7.0),
])
def test_the_one_pass_reading_accepts_exactly_what_the_checks_accept(row, column, value):
    """tables._catches_plain (one pass over the rows, the path every good table takes) against the checks
    one by one on values at and just past each limit, for our team: None exactly where the checks refuse the
    table, else the same catches."""
    from erforce_interfaces.wire.tables import _catches_plain, check_catch_ids

    table = _with(row, column, value)
    try:
        check_catch_ids(np.array(table)[:, :2])
        expected = []
        for r in table:
            if r[0] == OURS:
                t = r[7]
                if abs(t) > 1.0e3 or (t != NEVER and max(abs(r[8]), abs(r[9])) > 1.0e3):
                    raise ConversionError("beyond a catch topic's magnitude")
                expected.append(Catch(int(r[1]), t, None if t == NEVER else (r[8], r[9])))
    except ConversionError:
        expected = None
    assert _catches_plain(table, OURS) == expected
    msg = table_cdr(table, contract.CATCH_TABLE_COLUMNS)
    if expected is None:
        with pytest.raises(ConversionError):
            catches_from_msg(msg, contract.OURS)
    else:
        assert catches_from_msg(msg, contract.OURS) == expected
