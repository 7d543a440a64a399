"""ssl_vision_bridge's compiled path from the tracker's ball and robot rows to /vision/robots points, and when it
leaves a frame to the general path (which warns and serves vision_pose readers)."""

import math

import numpy as np

from erforce_ball_model.vision_fast_path import frame_points
from erforce_ball_model.vision_fast_path import robot_points as _robot_points
from erforce_ball_model.vision_tracking import BALL_NONE, BALL_SIGHTING, BALL_UPDATE

# ssl_vision's ROBOT_COLUMNS: team (index in TEAMS: 0 blue, 1 yellow), id, x, y, theta (NaN: none), confidence
ROBOTS = np.array([
    [0.0, 2.0, 1.0, -0.5, 0.25, 1.0],
    [1.0, 7.0, -3.0, 2.0, -3.0, 0.8],
    [0.0, 9.0, 4.0, 4.0, 1.0, 1.0],  # not used by the tracker
    [1.0, 0.0, 0.5, 0.5, math.pi, 0.9],
])
USED = np.array([3, 0, 1], np.int64)
NO_BALL = (False, 0.0, 0.0)  # has_ball, ball_x, ball_y


def readers(value=0):
    """By side (0 ours, 1 the opponents) and id: -1 no vision_pose publisher yet, else its reader count."""
    return np.full((2, 32), value, np.int64)


def test_the_used_rows_become_points_with_team_codes_in_the_trackers_order():
    points = np.full((4, 6), -9.0)
    ours_blue = 0.0
    assert _robot_points(ROBOTS, USED, ours_blue, 11, readers(), points, *NO_BALL) == 3
    # (x, y, z, yaw, team code: 1 ours, 2 the opponents, id)
    assert points[:3].tolist() == [[0.5, 0.5, 0.0, math.pi, 2.0, 0.0],
                                   [1.0, -0.5, 0.0, 0.25, 1.0, 2.0],
                                   [-3.0, 2.0, 0.0, -3.0, 2.0, 7.0]]
    ours_yellow = 1.0
    assert _robot_points(ROBOTS, USED, ours_yellow, 11, readers(), points, *NO_BALL) == 3
    assert points[:3, 4].tolist() == [1.0, 2.0, 1.0]
    assert _robot_points(ROBOTS, USED[:0], ours_blue, 11, readers(), points, *NO_BALL) == 0


def test_anything_unusual_goes_to_the_general_path():
    points = np.empty((4, 6))
    for k, column, value in ((1, 4, math.nan), (1, 4, 3.5), (0, 2, math.inf), (2, 3, 1.5e3), (0, 4, -3.2)):
        robots = ROBOTS.copy()
        robots[USED[k], column] = value
        assert _robot_points(robots, USED, 0.0, 11, readers(), points, *NO_BALL) == -1, (k, column, value)
    assert _robot_points(ROBOTS, USED, 0.0, 2, readers(), points, *NO_BALL) == -1  # our id 2 beyond num_robots 2
    assert _robot_points(ROBOTS, USED, 0.0, 3, readers(), points, *NO_BALL) == 3
    for side, robot_id in ((0, 2), (1, 7), (1, 0)):
        for state in (-1, 1):  # its vision_pose publisher not created yet; one reader
            pose_readers = readers()
            pose_readers[side, robot_id] = state
            assert _robot_points(ROBOTS, USED, 0.0, 11, pose_readers, points, *NO_BALL) == -1, (side, robot_id, state)
    pose_readers = readers()
    pose_readers[0, 9] = 1  # a reader of a robot that this frame does not use
    assert _robot_points(ROBOTS, USED, 0.0, 11, pose_readers, points, *NO_BALL) == 3


def test_the_frames_ball_comes_first_as_a_point_of_team_0():
    points = np.full((5, 6), -9.0)
    assert _robot_points(ROBOTS, USED, 0.0, 11, readers(), points, True, -2.5, 1.25) == 4
    assert points[:4].tolist() == [[-2.5, 1.25, 0.0, 0.0, 0.0, 0.0],
                                   [0.5, 0.5, 0.0, math.pi, 2.0, 0.0],
                                   [1.0, -0.5, 0.0, 0.25, 1.0, 2.0],
                                   [-3.0, 2.0, 0.0, -3.0, 2.0, 7.0]]
    assert _robot_points(ROBOTS, USED[:0], 0.0, 11, readers(), points, True, 0.5, 0.0) == 1  # the ball alone
    assert points[0].tolist() == [0.5, 0.0, 0.0, 0.0, 0.0, 0.0]
    for x, y in ((math.nan, 0.0), (0.0, 1.5e3)):  # beyond the message's checks: the general path names it
        assert _robot_points(ROBOTS, USED, 0.0, 11, readers(), points, True, x, y) == -1


# Camera 3 of the Division B quadrant cameras as the bridge's camera table has it: known, x, y, z [m], its id.
CAMERA_3 = np.array([1.0, 2.275, -1.525, 4.0, 3.0])
UNKNOWN_CAMERA = np.array([0.0, 0.0, 0.0, 0.0, 3.0])


def test_the_cameras_point_comes_first_then_the_ball_or_the_cameras_sighting():
    points = np.full((6, 6), -9.0)
    assert frame_points(ROBOTS, USED, 0.0, 11, readers(), points, CAMERA_3, BALL_UPDATE, -2.5, 1.25) == 5
    assert points[:5].tolist() == [[2.275, -1.525, 4.0, 0.0, 3.0, 3.0],
                                   [-2.5, 1.25, 0.0, 0.0, 0.0, 0.0],
                                   [0.5, 0.5, 0.0, math.pi, 2.0, 0.0],
                                   [1.0, -0.5, 0.0, 0.25, 1.0, 2.0],
                                   [-3.0, 2.0, 0.0, -3.0, 2.0, 7.0]]
    # another camera's ball of an instant taken: a sighting (team 4), only after the camera's point
    assert frame_points(ROBOTS, USED[:1], 0.0, 11, readers(), points, CAMERA_3, BALL_SIGHTING, 0.5, -0.75) == 3
    assert points[:3].tolist() == [[2.275, -1.525, 4.0, 0.0, 3.0, 3.0],
                                   [0.5, -0.75, 0.0, 0.0, 4.0, 0.0],
                                   [0.5, 0.5, 0.0, math.pi, 2.0, 0.0]]
    # an unknown camera: no camera point, and a sighting is dropped (nothing can use it)
    assert frame_points(ROBOTS, USED[:1], 0.0, 11, readers(), points, UNKNOWN_CAMERA, BALL_SIGHTING, 0.5, 0.0) == 1
    assert points[0].tolist() == [0.5, 0.5, 0.0, math.pi, 2.0, 0.0]
    assert frame_points(ROBOTS, USED[:0], 0.0, 11, readers(), points, UNKNOWN_CAMERA, BALL_SIGHTING, 0.5, 0.0) == 0
    assert frame_points(ROBOTS, USED[:0], 0.0, 11, readers(), points, UNKNOWN_CAMERA, BALL_UPDATE, 0.5, 0.0) == 1
    assert points[0].tolist() == [0.5, 0.0, 0.0, 0.0, 0.0, 0.0]
    assert frame_points(ROBOTS, USED[:0], 0.0, 11, readers(), points, CAMERA_3, BALL_NONE, 0.0, 0.0) == 0
    # the general path as robot_points says
    assert frame_points(ROBOTS, USED, 0.0, 2, readers(), points, CAMERA_3, BALL_UPDATE, 0.0, 0.0) == -1
