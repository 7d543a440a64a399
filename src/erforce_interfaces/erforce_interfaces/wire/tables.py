"""The table topics: 2-D tables as std_msgs/Float64MultiArray with labelled columns (/field, the ball and chip
models in use, /ball/catches, /robots/tracked), as messages and as serialized CDR.

Errors, limits and the stamp checks are those of ``conversions``.
"""

from __future__ import annotations

import functools
import struct
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
from std_msgs.msg import Float64MultiArray, MultiArrayDimension

from erforce_interfaces.wire.contract import (
    BALL_CHIP_MODEL_PARAM_LABELS,
    BALL_MODEL_PARAM_LABELS,
    BALL_MODEL_PARAM_ROWS,
    CATCH_TABLE_COLUMNS,
    CATCH_TIME_NEVER,
    OPPONENTS,
    OURS,
    TRACKED_ROBOT_COLUMNS,
    VISION_FIELD_COLUMNS,
    Team,
)
from erforce_interfaces.wire.conversions import (
    _CDR_LE,
    MAX_ABS_ANGULAR,
    MAX_ABS_VALUE,
    ConversionError,
    _checked_floats,
    _finite,
    _finite_array,
    _seconds_to_ns,
    _stamp_parts,
    _u32,
)
from erforce_interfaces.wire.robot_config import FieldConfig

TABLE_LIMIT = 1.0e9  # the magnitude a table's values may have (one with stamps: TRACKED_TABLE_LIMIT)
TRACKED_TABLE_LIMIT = float(2**31 - 1)  # /robots/tracked: a stamp's seconds, as builtin_interfaces/Time's int32


def table_msg(rows: np.ndarray, column_labels: Sequence[str], row_label: str = "rows",
              limit: float = TABLE_LIMIT) -> Float64MultiArray:
    """A 2-D table (rows x labelled columns) as a Float64MultiArray with a self-describing layout.

    The column dimension's label lists the column names separated by commas, so
    ``erforce-topic echo`` output can be read without this module.
    """
    table = np.atleast_2d(np.asarray(rows, dtype=float))
    if table.shape[1] != len(column_labels):
        raise ConversionError(f"table has {table.shape[1]} columns, expected {len(column_labels)}")
    _finite_array("table", table.ravel(), None, limit)
    msg = Float64MultiArray()
    n_rows, n_cols = table.shape
    msg.layout.dim = [
        MultiArrayDimension(label=row_label, size=n_rows, stride=n_rows * n_cols),
        MultiArrayDimension(label=",".join(column_labels), size=n_cols, stride=n_cols),
    ]
    msg.data = table.ravel().tolist()
    return msg


def table_cdr(rows: Sequence[Sequence[float]], column_labels: Sequence[str], row_label: str = "rows",
              limit: float = TABLE_LIMIT) -> bytes:
    """``table_msg`` serialized, with the same checks (rows: a list of equal-length rows)."""
    columns = tuple(column_labels)
    if any(len(row) != len(columns) for row in rows):
        raise ConversionError(f"table rows must have {len(columns)} columns")
    flat = _checked_floats("table", [v for row in rows for v in row], len(rows) * len(columns), limit)
    return _CDR_LE + _table_layout_cdr(row_label, len(rows), columns) + struct.pack(f"<{len(flat)}d", *flat)


@functools.lru_cache(maxsize=64)
def _table_layout_cdr(row_label: str, n_rows: int, columns: tuple[str, ...]) -> bytes:
    """Float64MultiArray up to its doubles: the two dimensions, data_offset 0 and the data count."""
    n_cols = len(columns)
    out = bytearray(_u32.pack(2))
    for label, size, stride in ((row_label, n_rows, n_rows * n_cols), (",".join(columns), n_cols, n_cols)):
        raw = label.encode() + b"\x00"
        out += bytes(-len(out) % 4) + _u32.pack(len(raw)) + raw
        out += bytes(-len(out) % 4) + _u32.pack(size) + _u32.pack(stride)
    out += bytes(-len(out) % 4) + _u32.pack(0) + _u32.pack(n_rows * n_cols)
    return bytes(out + (bytes(-len(out) % 8) if n_rows * n_cols else b""))


def _multi_array_parts(msg: Float64MultiArray | bytes) -> tuple[list[tuple[str, int]], int, Sequence[float]]:
    """(label, size) of each dimension, data_offset and the data of a Float64MultiArray or of its CDR bytes
    (read in place: rclpy's deserialization of a 200-value table cost as much as the rest of its use)."""
    if not isinstance(msg, bytes):
        return [(d.label, d.size) for d in msg.layout.dim], msg.layout.data_offset, msg.data
    try:
        if msg[:2] != _CDR_LE[:2]:
            raise ConversionError("not a little-endian CDR Float64MultiArray")
        body = memoryview(msg)[4:]  # CDR aligns relative to the end of the encapsulation header
        (n_dims,), at = _u32.unpack_from(body, 0), 4
        if n_dims > 8:
            raise ConversionError(f"a table with {n_dims} dimensions")
        dims = []
        for _ in range(n_dims):
            (length,) = _u32.unpack_from(body, at)
            label = bytes(body[at + 4:at + 4 + length]).rstrip(b"\x00").decode()
            at += 4 + length
            at += -at % 4
            size, _stride = struct.unpack_from("<II", body, at)
            dims.append((label, size))
            at += 8
        data_offset, count = struct.unpack_from("<II", body, at)
        at += 8
        at += -at % 8 if count else 0
        if not 0 <= len(body) - (at + 8 * count) < 8:  # serializers may pad the end
            raise ConversionError(f"a table of {count} values in {len(body) - at} bytes")
        return dims, data_offset, np.frombuffer(body, dtype="<f8", count=count, offset=at)
    except (struct.error, UnicodeDecodeError, ValueError) as exc:
        if isinstance(exc, ConversionError):
            raise
        raise ConversionError(f"malformed Float64MultiArray: {exc}") from None


def table_from_msg(msg: Float64MultiArray | bytes, column_labels: Sequence[str],
                   num_rows: int | None = None, limit: float = TABLE_LIMIT) -> np.ndarray:
    """The rows x columns table of a ``table_msg`` (or its CDR bytes); its shape is checked against the
    labels (and ``num_rows`` when given), not taken from the message."""
    dims, data_offset, values = _multi_array_parts(msg)
    if len(dims) != 2 or dims[1][0] != ",".join(column_labels):
        raise ConversionError(f"expected a table with columns {','.join(column_labels)}")
    n_rows, n_cols = dims[0][1], dims[1][1]
    if n_cols != len(column_labels):
        raise ConversionError(f"table has {n_cols} columns, its labels name {len(column_labels)}")
    if num_rows is not None and n_rows != num_rows:
        raise ConversionError(f"table has {n_rows} rows, expected {num_rows}")
    if data_offset != 0:
        raise ConversionError(f"table data_offset is {data_offset}, expected 0")
    data = _finite_array("data", values, n_rows * n_cols, limit)
    return data.reshape(n_rows, n_cols)


def field_from_msg(msg: Float64MultiArray | bytes) -> FieldConfig:
    """The field of ``/vision/field`` (one row of VISION_FIELD_COLUMNS); ValueError (or ConversionError) when it
    is no field."""
    length_m, width_m, boundary_m, *_ = table_from_msg(msg, VISION_FIELD_COLUMNS, num_rows=1)[0].tolist()
    return FieldConfig(length_m, width_m, boundary_m)


def model_in_use_from_msg(msg: Float64MultiArray | bytes) -> tuple[float, float, float]:
    """(a_slide_mps2, a_roll_mps2, c_switch) of the model in use on ``/ball/model_params``: a table whose
    rows are the first one or all of ``BALL_MODEL_PARAM_ROWS`` (in_use, then a fit once there is one)."""
    table = table_from_msg(msg, BALL_MODEL_PARAM_LABELS)
    rows = _multi_array_parts(msg)[0][0][0].split(",")
    if len(rows) != len(table) or rows != list(BALL_MODEL_PARAM_ROWS[:len(rows)]):
        raise ConversionError(f"rows labelled {rows}, expected the first of {','.join(BALL_MODEL_PARAM_ROWS)}")
    a_slide, a_roll, c_switch = table[0].tolist()
    return a_slide, a_roll, c_switch


def chip_model_from_msg(msg: Float64MultiArray | bytes) -> tuple[float, ...]:
    """The chip model in use on ``/ball/chip_model_params`` (one row, in_use), as the values of
    ``BALL_CHIP_MODEL_PARAM_LABELS`` in that order; whether they make a chip model is the reader's check."""
    table = table_from_msg(msg, BALL_CHIP_MODEL_PARAM_LABELS, 1)
    rows = _multi_array_parts(msg)[0][0][0]
    if rows != BALL_MODEL_PARAM_ROWS[0]:
        raise ConversionError(f"row labelled {rows!r}, expected {BALL_MODEL_PARAM_ROWS[0]!r}")
    return tuple(table[0].tolist())


# ------------------------------------------------------------ /ball/catches
_CATCH_TIME_COLUMN = CATCH_TABLE_COLUMNS.index("catch_time_s")
_CATCH_X_COLUMN = CATCH_TABLE_COLUMNS.index("catch_x_m")
_MAX_ROBOT_ID = 1.0e6


class Catch(NamedTuple):
    """One robot's row of /ball/catches as its per-robot ``catch_time`` and ``catch_point`` carry it."""

    robot_id: int
    catch_time_s: float  # CATCH_TIME_NEVER: never
    point_m: tuple[float, float] | None  # None with a catch time of never: no catch_point goes out then


def check_catch_ids(team_and_id: np.ndarray, table: str = "/ball/catches") -> None:
    """The team and robot_id columns of a /ball/catches table (or another ``table`` with those columns; finite): a
    Team's code and a whole id >= 0 in each row (ConversionError otherwise)."""
    teams, ids = team_and_id[:, 0], team_and_id[:, 1]
    if not ((ids >= 0.0) & (ids <= _MAX_ROBOT_ID) & (ids == np.floor(ids))).all():
        raise ConversionError(f"robot ids of {table} must be whole numbers >= 0")
    if not ((teams == OURS.code) | (teams == OPPONENTS.code)).all():
        raise ConversionError(f"the team column of {table} must be a contract.Team code")


def _catches_plain(rows: list, code: float) -> list[Catch] | None:
    """catches_from_msg's answer for a table's rows (lists of floats, finite) when they pass every one of its
    checks, in one pass of plain Python (numpy's calls cost more than the work on 14 rows); None when a check
    fails, for the checks one by one, which name what failed."""
    teams, limit, never = (OURS.code, OPPONENTS.code), MAX_ABS_VALUE, CATCH_TIME_NEVER
    t_col, x_col = _CATCH_TIME_COLUMN, _CATCH_X_COLUMN
    out = []
    for row in rows:
        team, robot_id = row[0], row[1]
        if not (team in teams and 0.0 <= robot_id <= _MAX_ROBOT_ID and robot_id == int(robot_id)):
            return None
        if team == code:
            t = row[t_col]
            if not -limit <= t <= limit:
                return None
            point = None
            if t != never:
                point = (row[x_col], row[x_col + 1])
                if not (-limit <= point[0] <= limit and -limit <= point[1] <= limit):
                    return None
            out.append(Catch(int(robot_id), t, point))
    return out


def catches_from_msg(msg: Float64MultiArray | bytes, team: Team) -> list[Catch]:
    """The catches of ``team``'s robots in a /ball/catches table (or its CDR bytes), in the table's order, with
    the checks of ``float64_from_msg`` and ``point_from_msg`` on each value. A table that is not one
    (columns, shape, a non-finite value, a team or robot id that is none) raises ConversionError."""
    table = table_from_msg(msg, CATCH_TABLE_COLUMNS)
    if not len(table):
        return []
    plain = _catches_plain(table.tolist(), team.code)
    if plain is not None:
        return plain
    check_catch_ids(table[:, :2])
    out = []
    t_col, x_col = _CATCH_TIME_COLUMN, _CATCH_X_COLUMN
    for row in table[table[:, 0] == team.code].tolist():
        t = _finite("catch_time_s", row[t_col])
        point = None if t == CATCH_TIME_NEVER else (_finite("catch_x_m", row[x_col]),
                                                    _finite("catch_y_m", row[x_col + 1]))
        out.append(Catch(int(row[1]), t, point))
    return out


# ------------------------------------------------------------ /robots/tracked
class TrackedRobot(NamedTuple):
    """One row of /robots/tracked: what the robot's odom carries (odometry_from_msg's stamp, pose, velocity)."""

    team: float  # Team.code
    robot_id: int
    stamp_s: float
    pose: tuple[float, float, float]  # x [m], y [m], yaw [rad] in ``field``
    velocity: tuple[float, float, float]  # vx, vy [m/s] in ``field``, yaw rate [rad/s]


def tracked_robot_row(team: Team, robot_id: int, t_s: float, pose, velocity) -> tuple[float, ...]:
    """The row of TRACKED_ROBOT_COLUMNS for one robot, with odometry_cdr's checks (ConversionError)."""
    sec, nanosec = _stamp_parts(_seconds_to_ns(t_s))
    x, y, yaw = (_finite("pose.position.x", pose[0]), _finite("pose.position.y", pose[1]),
                 _finite("yaw", pose[2], MAX_ABS_ANGULAR))
    vx, vy, wz = (_finite("twist.linear.x", velocity[0]), _finite("twist.linear.y", velocity[1]),
                  _finite("twist.angular.z", velocity[2]))
    return (team.code, float(robot_id), float(sec), float(nanosec), x, y, yaw, vx, vy, wz)


def tracked_robots_cdr(rows: Sequence[Sequence[float]]) -> bytes:
    """/robots/tracked serialized from rows of ``tracked_robot_row``."""
    return table_cdr(rows, TRACKED_ROBOT_COLUMNS, limit=TRACKED_TABLE_LIMIT)


def tracked_robots_from_msg(msg: Float64MultiArray | bytes) -> list[TrackedRobot]:
    """The rows of a /robots/tracked table (or its CDR bytes), in the table's order, the stamp as
    stamp_to_seconds gives it. A table that is not one (columns, shape, a non-finite value, a team or robot id
    that is none, a stamp that is no time, a value past odometry_from_msg's limits) raises ConversionError."""
    table = table_from_msg(msg, TRACKED_ROBOT_COLUMNS, limit=TRACKED_TABLE_LIMIT)
    if not len(table):
        return []
    rows = _tracked_plain(table.tolist())
    if rows is None:
        _check_tracked(table)
        rows = [TrackedRobot(team, int(robot_id), int(sec) + int(nanosec) * 1e-9, (x, y, yaw), (vx, vy, wz))
                for team, robot_id, sec, nanosec, x, y, yaw, vx, vy, wz in table.tolist()]
    return rows


def _tracked_plain(rows: list) -> list[TrackedRobot] | None:
    """tracked_robots_from_msg's answer for a table's rows (lists of floats, finite) when they pass every check
    of ``_check_tracked``, in one pass of plain Python (numpy's calls cost more than the work on 14 rows); None
    when a check fails, for those checks, which name what failed."""
    teams, m, big = (OURS.code, OPPONENTS.code), MAX_ABS_VALUE, MAX_ABS_ANGULAR
    out = []
    for team, robot_id, sec, nanosec, x, y, yaw, vx, vy, wz in rows:
        if not (team in teams and 0.0 <= robot_id <= _MAX_ROBOT_ID and robot_id == int(robot_id)
                and sec >= 0.0 and sec == int(sec) and 0.0 <= nanosec < 1.0e9 and nanosec == int(nanosec)
                and -m <= x <= m and -m <= y <= m and -m <= vx <= m and -m <= vy <= m
                and -big <= yaw <= big and -big <= wz <= big):
            return None
        out.append(TrackedRobot(team, int(robot_id), int(sec) + int(nanosec) * 1e-9, (x, y, yaw), (vx, vy, wz)))
    return out


def _check_tracked(table: np.ndarray) -> None:
    """The checks of tracked_robots_from_msg one by one (ConversionError naming the first that fails)."""
    check_catch_ids(table[:, :2], "/robots/tracked")
    sec, nanosec = table[:, 2], table[:, 3]
    if not ((sec >= 0.0) & (sec == np.floor(sec)) & (nanosec >= 0.0) & (nanosec < 1.0e9)
            & (nanosec == np.floor(nanosec))).all():
        raise ConversionError("a stamp of /robots/tracked is not a valid time")
    if (np.abs(table[:, [4, 5, 7, 8]]) > MAX_ABS_VALUE).any() or (np.abs(table[:, [6, 9]]) > MAX_ABS_ANGULAR).any():
        raise ConversionError(f"a pose or velocity of /robots/tracked exceeds the accepted magnitude "
                              f"({MAX_ABS_VALUE:g}; {MAX_ABS_ANGULAR:.0e} for yaw and yaw rate)")
