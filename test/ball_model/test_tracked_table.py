"""/robots/tracked as the AI's poses: the table (tables.tracked_robots_from_msg) carries what each robot's
odom carried, and passing.player.new_poses feeds each pose once, as the odoms did."""

import math

import numpy as np
import pytest

from erforce_ball_model.passing.player import new_poses
from erforce_interfaces.wire import contract
from erforce_interfaces.wire.conversions import ConversionError, odometry_cdr, odometry_from_msg
from erforce_interfaces.wire.tables import (
    TrackedRobot,
    table_cdr,
    table_msg,
    tracked_robot_row,
    tracked_robots_cdr,
    tracked_robots_from_msg,
)

OURS, THEIRS = contract.OURS.code, contract.OPPONENTS.code
COLUMNS = contract.TRACKED_ROBOT_COLUMNS
# team, id, sec, nanosec, x, y, yaw, vx, vy, yaw rate: written by hand
TABLE = [[OURS, 2, 12, 500_000_000, -1.0, 2.0, 0.5, 0.25, -0.5, 1.5],
         [OURS, 0, 12, 0, -3.0, 0.0, 0.0, 0.0, 0.0, 0.0],
         [THEIRS, 1, 11, 750_000_000, 1.5, -0.25, -math.pi, 0.0, 2.0, -3.0]]


@pytest.mark.parametrize("as_bytes", [False, True])
def test_a_hand_built_table_reads_every_row_in_its_order(as_bytes):
    msg = table_cdr(TABLE, COLUMNS) if as_bytes else table_msg(TABLE, COLUMNS)
    assert tracked_robots_from_msg(msg) == [
        TrackedRobot(OURS, 2, 12.5, (-1.0, 2.0, 0.5), (0.25, -0.5, 1.5)),
        TrackedRobot(OURS, 0, 12.0, (-3.0, 0.0, 0.0), (0.0, 0.0, 0.0)),
        TrackedRobot(THEIRS, 1, 11.75, (1.5, -0.25, -math.pi), (0.0, 2.0, -3.0))]
    assert tracked_robots_from_msg(tracked_robots_cdr([])) == []


def test_a_row_carries_what_the_robots_odom_carries():
    """The same robot state through odometry_cdr -> odometry_from_msg and through the table: the same stamp,
    position, velocity and yaw rate; the yaw within the quaternion's rounding. A wall-clock stamp (past the
    table's 1e9 limit in seconds) survives as seconds and nanoseconds."""
    for t_s, pose, velocity in ((3.141592653, (1.25, -2.5, 2.0), (0.5, -0.75, 4.0)),
                                (1_764_236_000.123456789, (-4.0, 3.0, -0.1), (0.0, 0.0, -0.5))):
        stamp, odom_pose, odom_velocity, _ = odometry_from_msg(odometry_cdr(t_s, pose, velocity))
        (row,) = tracked_robots_from_msg(tracked_robots_cdr([tracked_robot_row(contract.OPPONENTS, 4, t_s, pose,
                                                                                 velocity)]))
        assert (row.team, row.robot_id) == (THEIRS, 4)
        assert row.stamp_s == stamp
        assert row.pose[:2] == tuple(odom_pose[:2]) and row.velocity == tuple(odom_velocity)
        assert row.pose[2] == pytest.approx(odom_pose[2], abs=1e-12)


def _with(row: int, column: str, value: float) -> list[list[float]]:
    table = [list(r) for r in TABLE]
    table[row][COLUMNS.index(column)] = value
    return table


@pytest.mark.parametrize(("table", "reason"), [
    (_with(0, "team", 3.0), "team column"),
    (_with(1, "robot_id", 0.5), "robot ids"),
    (_with(2, "stamp_sec", -1.0), "valid time"),
    (_with(2, "stamp_nanosec", 1.0e9), "valid time"),
    (_with(0, "stamp_nanosec", 0.5), "valid time"),
    (_with(0, "x_m", 1.0e4), "magnitude"),  # past what an odom may carry
    (_with(1, "vy_mps", -2.0e3), "magnitude"),
    (_with(1, "yaw_rate_radps", 1.0e6), "magnitude"),
])
def test_a_table_with_a_value_no_odom_could_carry_is_refused_whole(table, reason):
    for msg in (table_cdr(table, COLUMNS), table_msg(table, COLUMNS)):
        with pytest.raises(ConversionError, match=reason):
            tracked_robots_from_msg(msg)


def test_a_table_of_other_columns_or_non_finite_values_is_refused():
    with pytest.raises(ConversionError, match="columns"):
        tracked_robots_from_msg(table_msg(TABLE, contract.CATCH_TABLE_COLUMNS))
    nan = table_cdr(TABLE, COLUMNS)[:-8] + np.float64(math.nan).tobytes()
    with pytest.raises(ConversionError):
        tracked_robots_from_msg(nan)
    with pytest.raises(ConversionError):
        tracked_robot_row(contract.OURS, 0, 1.0, (math.inf, 0.0, 0.0), (0.0, 0.0, 0.0))


def test_each_pose_is_fed_once_and_a_new_stamp_is_a_new_pose():
    """Three frames: the first brings all three; the second repeats robot 0's row (same stamp: fed already) and
    moves robot 2; the third carries an older stamp for robot 0 (a new time line): a new pose too. Robots not
    in the index (the other team) are skipped."""
    index = {(OURS, 0): 0, (OURS, 2): 1}
    fed = [None, None]
    frame1 = tracked_robots_from_msg(table_cdr(TABLE, COLUMNS))
    assert [(k, row.robot_id) for k, row in new_poses(frame1, index, fed)] == [(1, 2), (0, 0)]
    assert fed == [12.0, 12.5]
    table2 = _with(0, "stamp_sec", 13)
    frame2 = tracked_robots_from_msg(table_cdr(table2, COLUMNS))
    assert [(k, row.stamp_s) for k, row in new_poses(frame2, index, fed)] == [(1, 13.5)]
    table2[1][COLUMNS.index("stamp_sec")] = 2
    frame3 = tracked_robots_from_msg(table_cdr(table2, COLUMNS))
    assert [(k, row.stamp_s) for k, row in new_poses(frame3, index, fed)] == [(0, 2.0)]
    assert fed == [2.0, 13.5]


@pytest.mark.parametrize(("column", "value"), [
    ("robot_id", 1.0e6), ("robot_id", 1.0e6 + 1.0), ("robot_id", -0.0), ("robot_id", 2.5),
    ("stamp_sec", 0.0), ("stamp_sec", 2.0**31 - 1.0), ("stamp_nanosec", 999_999_999.0), ("stamp_nanosec", 1.0e9),
    ("stamp_nanosec", -1.0), ("x_m", 1.0e3), ("x_m", -1.0e3 - 1e-9), ("vy_mps", -1.0e3), ("vx_mps", 1000.5),
    ("yaw_rad", 1.0e5), ("yaw_rad", -1.0e5 - 1.0), ("yaw_rate_radps", -1.0e5), ("team", THEIRS), ("team", 0.5),
])
def test_the_one_pass_reading_accepts_exactly_what_the_checks_accept(column, value):
    """tables._tracked_plain (one pass over the rows, the path every good table takes) against the checks one
    by one (_check_tracked) on values at and just past each limit: it answers None exactly where the checks
    refuse, and otherwise the rows as written (the stamp as seconds plus nanoseconds)."""
    from erforce_interfaces.wire.tables import _check_tracked, _tracked_plain

    table = np.array(_with(1, column, value))
    try:
        _check_tracked(table)
        refused = False
    except ConversionError:
        refused = True
    fast = _tracked_plain(table.tolist())
    assert (fast is None) == refused
    if not refused:
        team, robot_id, sec, nanosec, x, y, yaw, vx, vy, wz = table[1].tolist()
        assert fast[1] == TrackedRobot(team, int(robot_id), int(sec) + int(nanosec) * 1e-9, (x, y, yaw), (vx, vy, wz))
        assert fast[0] == TrackedRobot(OURS, 2, 12.5, (-1.0, 2.0, 0.5), (0.25, -0.5, 1.5))
