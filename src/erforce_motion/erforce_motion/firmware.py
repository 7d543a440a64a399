"""What the main board and each motor board run on every sensor tick, around the controllers.

The controllers (velocity_control, motor_board) are pure maths on one control period.
The loops here add what firmware adds: the loop rate (a loop slower than the sensor
ticks holds its last output), the command watchdog, stale-setpoint handling, and a
reset when time goes backwards (a restarted simulator).

Written once, for many robots: ``MainBoards`` and ``MotorBoards`` hold the loops of
``n_robots`` robots in rows of arrays, and the compiled ``main_board_tick`` /
``motor_board_tick`` run the tick of the robots ``rows`` on them, one call for all (a call
pays for each array it is passed, so the state lives in few arrays). ``MainBoardLoop`` and ``MotorBoardLoop``
are one robot (the per-robot nodes), ``TeamFirmware`` is both boards of a team with the
main board's setpoint reaching the motor boards one tick later, as in the lockstep
protocol (the team_firmware node and the in-process runner). So the DDS graph, per robot
or per team, and the in-process simulation compute the same numbers. No rclpy import.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from erforce_interfaces.runtime.numba_support import compiled_for, numba
from erforce_interfaces.wire.robot_config import RobotConfig
from erforce_motion.motor_board import MotorBoard, MotorBoardConfig, motor_board_reset, motor_board_step
from erforce_motion.velocity_control import VelocityControlConfig, VelocityController, velocity_reset, velocity_step

_TICK_TOLERANCE_S = 1e-6

# What a tick noticed, per robot (bit flags of main_notice / motor_notice).
NOTICE_TIME_BACKWARDS = 1
NOTICE_COMMAND_TIMEOUT = 2  # main board: no command for command_timeout_s, stopping
NOTICE_SETPOINT_TIMEOUT = 2  # motor boards: no setpoint for setpoint_timeout_s, stopping the wheels


def _robot_count(n_robots: int) -> int:
    if not isinstance(n_robots, int) or n_robots < 1:
        raise ValueError(f"n_robots: must be an int >= 1, got {n_robots!r}")
    return n_robots


def _positive(name: str, value: float) -> float:
    if not (math.isfinite(value) and value > 0.0):
        raise ValueError(f"{name} must be finite and > 0, got {value!r}")
    return float(value)


@numba.njit(cache=True, error_model="numpy")
def _due(k, ts, period, now, last_run, has_run):
    """The loop-rate gate of robot k at time ts: the dt of a run now, or 0.0 while the last output holds."""
    now[k] = ts
    if has_run[k] and ts - last_run[k] < period - _TICK_TOLERANCE_S:
        return 0.0
    dt = ts - last_run[k] if has_run[k] else period
    last_run[k] = ts
    has_run[k] = True
    return dt


@numba.njit(cache=True, error_model="numpy")
def main_board_tick(rows, t, w, args, notice):
    """MainBoardLoop's tick of each robot k in rows at time t[k] with wheel speeds w[k]: writes setpoints[k]
    of the robots whose loop runs, and notice[k]; returns whether any notice flag is set."""
    period, timeout, (command, times, flags, setpoints), vc, due = args
    now, last_run, last_feed, dt = times[0], times[1], times[2], times[3]
    has_run, feed_first, has_fed, no_hold = flags[0], flags[1], flags[2], flags[3]
    n_due = 0
    noticed = False
    for k in rows:
        ts = t[k]
        notice[k] = 0
        if ts < now[k]:
            notice[k] |= NOTICE_TIME_BACKWARDS
            has_fed[k] = False
            velocity_reset(k, vc, w[k])
            command[k, :] = 0.0
            has_run[k] = False
        if feed_first[k]:  # a command sent before the robot's first tick counts from it
            feed_first[k] = False
            has_fed[k] = True
            last_feed[k] = ts
        dt[k] = _due(k, ts, period, now, last_run, has_run)
        if dt[k] != 0.0:
            if not has_fed[k] or ts - last_feed[k] > timeout:
                if command[k, 0] != 0.0 or command[k, 1] != 0.0 or command[k, 2] != 0.0:
                    notice[k] |= NOTICE_COMMAND_TIMEOUT
                command[k, :] = 0.0
            due[n_due] = k
            n_due += 1
        noticed = noticed or notice[k] != 0
    velocity_step(due[:n_due], vc, command, w, dt, no_hold, setpoints)
    return noticed


@numba.njit(cache=True, error_model="numpy")
def motor_board_tick(rows, t, w, current, args, notice):
    """MotorBoardLoop's tick of each robot k in rows at time t[k] with sensors w[k], current[k]: writes the
    board's duty[k] of the robots whose loop runs, and notice[k]; returns whether any notice flag is set."""
    period, timeout, (setpoint, times, has_run), mb, due = args
    setpoint_time, now, last_run, dt = times[0], times[1], times[2], times[3]
    n_due = 0
    noticed = False
    for k in rows:
        ts = t[k]
        notice[k] = 0
        if ts < now[k]:
            notice[k] |= NOTICE_TIME_BACKWARDS
            motor_board_reset(k, mb)
            has_run[k] = False
            setpoint[k, :] = 0.0  # the old time line's setpoint is void
            setpoint_time[k] = -np.inf
        dt[k] = _due(k, ts, period, now, last_run, has_run)
        if dt[k] != 0.0:
            if ts - setpoint_time[k] > timeout:
                for i in range(setpoint.shape[1]):
                    if setpoint[k, i] != 0.0:
                        notice[k] |= NOTICE_SETPOINT_TIMEOUT
                setpoint[k, :] = 0.0
            due[n_due] = k
            n_due += 1
        noticed = noticed or notice[k] != 0
    motor_board_step(due[:n_due], mb, setpoint, w, current, dt)
    return noticed


class MainBoards:
    """Fig. 2 on the main boards of ``n_robots`` robots: radio commands in, wheel-speed setpoints out."""

    def __init__(self, n_robots: int, robot: RobotConfig, config: VelocityControlConfig, loop_period_s: float,
                 command_timeout_s: float) -> None:
        self.n_robots, self.robot = _robot_count(n_robots), robot
        self.loop_period_s = _positive("loop_period_s", loop_period_s)
        self.command_timeout_s = _positive("command_timeout_s", command_timeout_s)
        self.controller = VelocityController(robot, config, n_robots)
        n = n_robots
        self.command_twist = np.zeros((n, 3))  # the radio command each robot follows
        # per robot, in two arrays (each array a kernel call is passed costs it an unpacking): the time now, of
        # the last run, of the last command, the dt of this run; whether it ran, has a command before its first
        # tick, has a command, and a twist integrator hold that is never set
        self._times, self._flags = np.zeros((4, n)), np.zeros((4, n), dtype=np.bool_)
        self.now_s, self._last_run, self._last_feed = self._times[0], self._times[1], self._times[2]
        self.now_s[:] = -math.inf
        self._has_run, self._feed_first, self._has_fed = self._flags[0], self._flags[1], self._flags[2]
        self.setpoints = np.zeros((n, robot.num_wheels))  # the last wheel speed setpoints [rad/s]
        self.args = (self.loop_period_s, self.command_timeout_s,
                     (self.command_twist, self._times, self._flags, self.setpoints), self.controller.args,
                     np.zeros(n, dtype=np.int64))  # the rows due

    def command(self, robot: int, twist) -> None:
        """A new desired twist [vx, vy, wz] (robot frame) for one robot, received at its current time."""
        self.commands(np.array([robot]), np.asarray(twist, dtype=float).reshape(1, -1))

    def commands(self, robots: np.ndarray, twists: np.ndarray) -> None:
        """``command`` for many robots at once: twists (len(robots), 3), all finite."""
        robots = np.asarray(robots, dtype=np.int64)
        twists = np.asarray(twists, dtype=float)
        if twists.shape != (robots.shape[0], 3) or not np.isfinite(twists).all():
            raise ValueError(f"twists: need ({robots.shape[0]}, 3) finite values, got {twists!r}")
        self.command_twist[robots] = twists
        now = self.now_s[robots]
        started = np.isfinite(now)
        self._has_fed[robots[started]] = True
        self._last_feed[robots[started]] = now[started]
        self._feed_first[robots[~started]] = True  # a command sent before the robot's first tick counts

    def stop(self, robot: int) -> None:
        """Drop a robot's current command (e.g. after a rejected message): decelerate to rest."""
        self.command_twist[robot] = 0.0

    def take_over(self, old: MainBoards) -> None:
        """Continue where ``old`` (same robots, new parameters) left off: same commands, timing and setpoints,
        the controllers restarted bumplessly from the measured motion."""
        if old.n_robots != self.n_robots or old.setpoints.shape != self.setpoints.shape:
            raise ValueError("take_over: the old main boards have other robots or wheels")
        self.command_twist[:] = old.command_twist
        if old.command_timeout_s == self.command_timeout_s:  # else the new watchdog waits for a command
            self._has_fed[:], self._last_feed[:] = old._has_fed, old._last_feed
        for mine, theirs in ((self.now_s, old.now_s), (self._last_run, old._last_run),
                             (self._has_run, old._has_run), (self.setpoints, old.setpoints)):
            mine[:] = theirs
        wheels = old.controller.measured_twist @ self.controller.kinematics.wheel_matrix.T
        for k in range(self.n_robots):
            velocity_reset(k, self.controller.args, np.ascontiguousarray(wheels[k]))


class MotorBoards:
    """Fig. 3 on the motor boards of ``n_robots`` robots: setpoints and sensors in, PWM duty out."""

    def __init__(self, n_robots: int, robot: RobotConfig, config: MotorBoardConfig, loop_period_s: float,
                 setpoint_timeout_s: float) -> None:
        self.n_robots, self.robot = _robot_count(n_robots), robot
        self.loop_period_s = _positive("loop_period_s", loop_period_s)
        self.setpoint_timeout_s = _positive("setpoint_timeout_s", setpoint_timeout_s)
        self.board = MotorBoard(config, robot, n_robots=n_robots)
        self.duty = self.board.duty  # the last PWM duties
        self.setpoint = np.zeros((n_robots, robot.num_wheels))  # the setpoint each robot's boards follow
        # per robot, in one array: the time of the setpoint, now, of the last run, the dt of this run
        self._times = np.zeros((4, n_robots))
        self.setpoint_time_s, self.now_s, self._last_run = self._times[0], self._times[1], self._times[2]
        self._times[:2] = -math.inf
        self._has_run = np.zeros(n_robots, dtype=np.bool_)
        self.args = (self.loop_period_s, self.setpoint_timeout_s, (self.setpoint, self._times, self._has_run),
                     self.board.args, np.zeros(n_robots, dtype=np.int64))  # the rows due

    def take_over(self, old: MotorBoards) -> None:
        """Continue where ``old`` left off (new parameters): same setpoints, timing and duties; the controllers
        and the thermal history start afresh."""
        if old.n_robots != self.n_robots or old.duty.shape != self.duty.shape:
            raise ValueError("take_over: the old motor boards have other robots or wheels")
        for mine, theirs in ((self.duty, old.duty), (self.now_s, old.now_s), (self._last_run, old._last_run),
                             (self._has_run, old._has_run), (self.setpoint, old.setpoint),
                             (self.setpoint_time_s, old.setpoint_time_s)):
            mine[:] = theirs


class _OneRobotLoop:
    """Row 0 of a team's boards, for a per-robot node: the scratch arrays of its compiled tick, the take-over
    and the tick's notices in words."""

    def __init__(self, boards: MainBoards | MotorBoards, kernel, n_sensor_arrays: int) -> None:
        self.boards, self.robot = boards, boards.robot
        self.loop_period_s = boards.loop_period_s
        self._row, self._t_s, self._notice = np.zeros(1, dtype=np.int64), np.zeros(1), np.zeros(1, dtype=np.int64)
        sensors = (np.zeros((1, boards.robot.num_wheels)),) * n_sensor_arrays
        self._tick = compiled_for(kernel, self._row, self._t_s, *sensors, boards.args, self._notice)
        self.notice: str | None = None  # what the last tick noticed (for the node's log)

    def take_over(self, old: _OneRobotLoop) -> None:
        """Continue where ``old`` left off (new parameters), as the boards' take_over does."""
        self.boards.take_over(old.boards)

    def _say(self, before_s: float, t_s: float, reset: str, timeout_flag: int, timeout: str) -> None:
        """``notice`` for the flags the last tick raised: the boards' ``reset`` text or the ``timeout`` text."""
        notice = self._notice[0]
        if notice & NOTICE_TIME_BACKWARDS:
            self.notice = f"time went backwards ({before_s:.6f} -> {t_s:.6f} s): {reset}"
        if notice & timeout_flag:
            self.notice = timeout


class MainBoardLoop(_OneRobotLoop):
    """Fig. 2 on one robot's main board (the velocity_controller node): ``MainBoards`` of one robot."""

    def __init__(self, robot: RobotConfig, config: VelocityControlConfig, loop_period_s: float,
                 command_timeout_s: float) -> None:
        super().__init__(MainBoards(1, robot, config, loop_period_s, command_timeout_s), main_board_tick, 1)
        self.controller, self.command_timeout_s = self.boards.controller, self.boards.command_timeout_s

    @property
    def setpoints(self) -> np.ndarray:
        return self.boards.setpoints[0]

    def command(self, twist: np.ndarray) -> None:
        """A new desired twist [vx, vy, wz] (robot frame), received at the current robot time."""
        self.boards.command(0, twist)

    def stop(self) -> None:
        """Drop the current command (e.g. after a rejected message): decelerate to rest."""
        self.boards.stop(0)

    def tick(self, t_s: float, wheel_speeds_radps: np.ndarray) -> np.ndarray:
        """Setpoints to send to the motor boards at sensor tick ``t_s`` (a new array)."""
        w = np.ascontiguousarray(wheel_speeds_radps, dtype=float)
        if w.shape != (self.robot.num_wheels,) or not (math.isfinite(t_s) and np.isfinite(w).all()):
            raise ValueError(f"tick: need a finite time and {self.robot.num_wheels} finite wheel speeds")
        before_s = float(self.boards.now_s[0])
        self._t_s[0] = t_s
        self.notice = None
        if self._tick(self._row, self._t_s, w.reshape(1, -1), self.boards.args, self._notice):
            self._say(before_s, t_s, "controller reset", NOTICE_COMMAND_TIMEOUT,
                      f"no command for {self.command_timeout_s:g} s: stopping")
        return self.boards.setpoints[0].copy()


class MotorBoardLoop(_OneRobotLoop):
    """Fig. 3 on one robot's motor boards (the motor_boards node): ``MotorBoards`` of one robot."""

    def __init__(self, robot: RobotConfig, config: MotorBoardConfig, loop_period_s: float,
                 setpoint_timeout_s: float) -> None:
        super().__init__(MotorBoards(1, robot, config, loop_period_s, setpoint_timeout_s), motor_board_tick, 2)
        self.board, self.setpoint_timeout_s = self.boards.board, self.boards.setpoint_timeout_s

    @property
    def duty(self) -> np.ndarray:
        return self.boards.duty[0]

    def set_setpoint(self, t_s: float, setpoint_radps: np.ndarray) -> None:
        setpoint_radps = np.asarray(setpoint_radps, dtype=float)
        if setpoint_radps.shape != (self.robot.num_wheels,) or not np.all(np.isfinite(setpoint_radps)):
            raise ValueError(f"setpoint must be {self.robot.num_wheels} finite values")
        self.boards.setpoint[0] = setpoint_radps
        self.boards.setpoint_time_s[0] = t_s

    def tick(self, t_s: float, wheel_speeds_radps: np.ndarray, currents_a: np.ndarray) -> np.ndarray:
        """PWM duties at sensor tick ``t_s`` (a new array)."""
        w = np.ascontiguousarray(wheel_speeds_radps, dtype=float)
        i = np.ascontiguousarray(currents_a, dtype=float)
        n = self.robot.num_wheels
        if w.shape != (n,) or i.shape != (n,) or not (math.isfinite(t_s) and np.isfinite(w).all()
                                                     and np.isfinite(i).all()):
            raise ValueError(f"tick: need a finite time and {n} finite wheel speeds and currents")
        before_s = float(self.boards.now_s[0])
        self._t_s[0] = t_s
        self.notice = None
        if self._tick(self._row, self._t_s, w.reshape(1, -1), i.reshape(1, -1), self.boards.args, self._notice):
            self._say(before_s, t_s, "motor boards reset", NOTICE_SETPOINT_TIMEOUT,
                      f"no setpoint for {self.setpoint_timeout_s:g} s: stopping the wheels")
        return self.boards.duty[0].copy()


@numba.njit(cache=True, error_model="numpy")
def _finite_rows(active, t, wheels, currents):
    """Whether the times t and the sensor rows of ``active`` are all finite."""
    for idx in range(t.shape[0]):
        if not math.isfinite(t[idx]):
            return False
    for k in active:
        for i in range(wheels.shape[1]):
            if not (math.isfinite(wheels[k, i]) and math.isfinite(currents[k, i])):
                return False
    return True


@numba.njit(cache=True, error_model="numpy")
def _team_tick(active, t, wheels, currents, main, motor, handoff, main_notice, motor_notice):
    """One sensor tick of the robots ``active`` (times t in their order, or one time for all; sensors in their
    rows): the main boards, then the motor boards with each robot's main board setpoint of its previous tick.
    Returns 1 if any of them noticed something, 0 if not, -1 (changing nothing) for non-finite times or
    sensors. Each board's kernel runs once for all robots: robots share no state, so board by board is
    robot by robot."""
    if not _finite_rows(active, t, wheels, currents):
        return -1
    prev_sp, prev_t, has_prev, t_row = handoff
    setpoints = main[2][3]
    sp_motor, sp_time = motor[2][0], motor[2][1][0]
    for idx in range(active.shape[0]):
        t_row[active[idx]] = t[idx] if t.shape[0] == active.shape[0] else t[0]
    noticed = main_board_tick(active, t_row, wheels, main, main_notice)
    for k in active:
        if has_prev[k] and prev_t[k] < t_row[k]:
            sp_motor[k, :] = prev_sp[k]
            sp_time[k] = prev_t[k]
    noticed = motor_board_tick(active, t_row, wheels, currents, motor, motor_notice) or noticed
    for k in active:
        prev_sp[k, :] = setpoints[k]
        prev_t[k] = t_row[k]
        has_prev[k] = True
    return 1 if noticed else 0


class TeamFirmware:
    """Main board + motor boards of ``n_robots`` robots (rows 0 .. n_robots - 1), ticked together.

    Per robot, ``tick`` does what the lockstep graph does with one MainBoardLoop and one MotorBoardLoop:
    the main board's setpoint of this tick is used by the motor boards at the robot's next tick.
    ``command`` / ``commands`` / ``stop`` are the radio side; ``tick`` takes the robots whose sensors arrived.
    All robots share one RobotConfig and one configuration of each board, as a team deployment does.
    """

    def __init__(self, n_robots: int, robot: RobotConfig, velocity_config: VelocityControlConfig,
                 motor_config: MotorBoardConfig, main_period_s: float, motor_period_s: float,
                 command_timeout_s: float, setpoint_timeout_s: float) -> None:
        self.main = MainBoards(n_robots, robot, velocity_config, main_period_s, command_timeout_s)
        self.motor = MotorBoards(n_robots, robot, motor_config, motor_period_s, setpoint_timeout_s)
        self.n_robots, self.robot, self.num_wheels = n_robots, robot, robot.num_wheels
        self.velocity_config, self.motor_config = velocity_config, motor_config
        self.command_timeout_s, self.setpoint_timeout_s = self.main.command_timeout_s, self.motor.setpoint_timeout_s
        vc, board = self.main.controller, self.motor.board
        self.kinematics, self.max_setpoint_radps = vc.kinematics, vc.max_setpoint_radps
        # the state the team node and the runner read, per robot (rows) and wheel
        self.command_twist, self.setpoints, self.duty = self.main.command_twist, self.main.setpoints, board.duty
        self.measured_twist, self.shaped_twist = vc.measured_twist, vc.shaped_twist
        self.twist_command, self.integrator_held = vc.command_twist, vc.integrator_held
        self.desired_current_a, self.current_command_a = board.desired_current_a, board.current_command_a
        self.pwm_limit, self.over_limit = board.thermal.pwm_limits, board.thermal.over_limits
        self.window_samples = board.thermal.window_samples
        # the setpoints on their way to the motor boards (setpoint, time, whether there is one), each robot's time
        self._handoff = (np.zeros((n_robots, self.num_wheels)), np.zeros(n_robots), np.zeros(n_robots, dtype=np.bool_),
                         np.zeros(n_robots))
        self.main_notice = np.zeros(n_robots, dtype=np.int64)
        self.motor_notice = np.zeros(n_robots, dtype=np.int64)
        self.noticed = False  # some robot of the last tick has a notice flag set
        self._all = np.arange(n_robots, dtype=np.int64)
        self._one_time = np.zeros(1)  # a tick's time when it is one for all robots
        # Load the compiled kernel now (numba's disk cache; a compile after a code change), not at the first
        # sensor tick: a node answers its first lockstep tick in time. tick passes exactly these types
        # (C-contiguous int64 rows, float64 times and sensors) to the compiled function.
        self._args = (self.main.args, self.motor.args, self._handoff, self.main_notice, self.motor_notice)
        self._kernel = compiled_for(_team_tick, np.zeros(0, dtype=np.int64), np.zeros(0), self.duty, self.duty,
                                    *self._args)

    # ------------------------------------------------------------------ radio side
    def command(self, robot: int, twist) -> None:
        """A new desired twist [vx, vy, wz] (robot frame) for one robot, received at its current time."""
        self.main.command(robot, twist)

    def commands(self, robots: np.ndarray, twists: np.ndarray) -> None:
        """``command`` for many robots at once: twists (len(robots), 3), all finite."""
        self.main.commands(robots, twists)

    def stop(self, robot: int) -> None:
        """Drop a robot's current command (e.g. after a rejected message): decelerate to rest."""
        self.main.stop(robot)

    def forget_setpoint(self, robot: int) -> None:
        """A new time line for this robot: the setpoint of the old one does not reach its motor boards."""
        self._handoff[2][robot] = False

    # ------------------------------------------------------------------ sensor ticks
    def tick(self, t_s: float | np.ndarray, wheel_speeds_radps: np.ndarray, currents_a: np.ndarray,
             robots: Sequence[int] | np.ndarray | None = None) -> np.ndarray:
        """A sensor tick of ``robots`` (None: all) at times ``t_s`` (one for all, or one per robot).

        wheel_speeds_radps, currents_a: (n_robots, wheels); only the rows of ``robots`` are read.
        Returns ``duty`` (n_robots, wheels), updated in the rows of ``robots`` (the array is reused:
        copy what you keep). ``setpoints``, ``main_notice`` and ``motor_notice`` are updated likewise, and
        ``noticed`` says whether any of these robots' notice flags is set.
        Raises ValueError (changing nothing) for non-finite sensors or times.
        """
        if robots is None:
            active = self._all
        else:
            active = np.asarray(robots, dtype=np.int64)
            if active.ndim != 1 or (active.size and not 0 <= active.min() <= active.max() < self.n_robots):
                raise ValueError(f"robots: need row indices in [0, {self.n_robots - 1}], got {robots!r}")
            active = np.ascontiguousarray(active)
        if isinstance(t_s, float | int):
            t = self._one_time
            t[0] = t_s
        else:
            t = np.ascontiguousarray(np.broadcast_to(np.asarray(t_s, dtype=float), active.shape))
        w = np.ascontiguousarray(wheel_speeds_radps, dtype=float)
        cur = np.ascontiguousarray(currents_a, dtype=float)
        shape = (self.n_robots, self.num_wheels)
        if w.shape != shape or cur.shape != shape:
            raise ValueError(f"sensors: need {shape} arrays, got {w.shape} and {cur.shape}")
        noticed = self._kernel(active, t, w, cur, *self._args)
        if noticed < 0:
            raise ValueError("tick: times, wheel speeds and currents must be finite")
        self.noticed = noticed > 0
        return self.duty

    # ------------------------------------------------------------------ status
    @property
    def average_current_a(self) -> np.ndarray:
        """Per robot and wheel: the thermal limiter's average current (boxcar mean, or sqrt of i^2 in 'i2t')."""
        return self.motor.board.thermal.average_currents_a()

    @property
    def saturated(self) -> np.ndarray:
        """Per robot and wheel: speed loop at +-peak current, or duty at the PWM limit (MotorBoard.saturated)."""
        return self.motor.board.saturated_rows()

    def notices(self, robot: int) -> list[str]:
        """What the last tick of this robot noticed, in the words of the per-robot loops."""
        out = []
        m, b = int(self.main_notice[robot]), int(self.motor_notice[robot])
        if m & NOTICE_TIME_BACKWARDS:
            out.append("time went backwards: controller reset")
        if m & NOTICE_COMMAND_TIMEOUT:
            out.append(f"no command for {self.command_timeout_s:g} s: stopping")
        if b & NOTICE_TIME_BACKWARDS:
            out.append("time went backwards: motor boards reset")
        if b & NOTICE_SETPOINT_TIMEOUT:
            out.append(f"no setpoint for {self.setpoint_timeout_s:g} s: stopping the wheels")
        return out

    def take_over(self, old: TeamFirmware) -> None:
        """Continue where ``old`` (same robots, other parameters) left off, as MainBoardLoop.take_over and
        MotorBoardLoop.take_over do, with the setpoints on their way to the motor boards."""
        self.main.take_over(old.main)
        self.motor.take_over(old.motor)
        for mine, theirs in zip(self._handoff[:3], old._handoff[:3], strict=True):
            mine[:] = theirs
