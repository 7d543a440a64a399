"""team_firmware: the main board and motor boards of many robots in one process.

The same contract as one ``velocity_controller`` plus one ``motor_boards`` per robot (each in
its namespace ``robot_<id>``): per robot in ``robot_ids`` it takes ``/robot_<id>/cmd_vel`` and
``/robot_<id>/wheel_states`` and answers each tick with ``/robot_<id>/motor_duty`` and, at its
rate, ``motor_status``. Inside, the main board's setpoint reaches the motor boards without DDS,
one tick later, exactly as erforce_sim.closed_loop.runner.InProcessRunner steps the same cores
(erforce_motion.team_cores.TeamFirmware: one call per tick for all robots whose sensors arrived),
so the lockstep graph computes the same trajectory with either deployment. ``wheel_setpoints``
is published only with ``publish_setpoints`` (for tools): nobody in the graph needs it, and it
would be a message per robot per tick.

With ``lockstep_topics`` ``team`` it takes one ``/team/wheel_states`` per tick instead and answers
with one ``/team/motor_duty`` for its robots (contract: joints ``robot_<id>/wheel_<k>``); robots of the
message that are not in ``robot_ids`` belong to another process of the team and are left alone.
One time rule judges the message's stamp for all its robots (on the per-robot topics, one per robot).
The answer goes out first; notices and ``motor_status`` follow it, so the plant does not wait for them.

With ``team`` ``opponents`` it is the opponents' firmware: the same, under ``/opponent_<id>/`` and
``/opponent_team/`` (contract.Team). Each team runs its own process, as each team on a real field
runs its own robots: neither sees the other's messages, and one crashing leaves the other playing.

One executor wakes once for all robots whose ``wheel_states`` are queued, instead of two
processes per robot each waking per tick. The parameters of the two per-robot nodes are here
with the prefixes ``main_board.`` and ``motor_boards.`` (the same names, ranges and defaults),
``robot.*`` once for the team. ``robot_ids`` is read-only: a robot is added or removed by
starting the node with another list.
"""

from __future__ import annotations

import numpy as np
from geometry_msgs.msg import Twist
from rclpy.node import Node

from erforce_interfaces import contract
from erforce_interfaces.conversions import (
    ConversionError,
    joint_state_cdr,
    table_cdr,
    team_joint_state_cdr,
    team_joint_state_from_msg,
    twist_from_msg,
    wheel_states_from_msg,
)
from erforce_interfaces.executor import run_sampled
from erforce_interfaces.node_support import (
    NodeParams,
    ThrottledWarner,
    check_stamp,
    contract_publisher,
    contract_subscription,
    run_node,
    sample_clock,
)
from erforce_interfaces.param_schema import HostSchema, load_schema
from erforce_interfaces.stamps import StampFilter, StampVerdict
from erforce_motion import motor_boards_node, velocity_controller_node
from erforce_motion.team_cores import TeamFirmware

MAIN_PREFIX, MOTOR_PREFIX = "main_board.", "motor_boards."
# The motor boards' DDS-side parameters (waiting for the main board's setpoint) mean nothing here.
_MOTOR_DDS_ONLY = ("lockstep_sync", "setpoint_wait_s")

SCHEMA = HostSchema(load_schema("erforce_motion", "team_firmware"), {
    MAIN_PREFIX: (velocity_controller_node.SCHEMA, ()),
    MOTOR_PREFIX: (motor_boards_node.SCHEMA, _MOTOR_DDS_ONLY),
})


def build_loops(config) -> tuple[list[int], TeamFirmware]:
    """The robot ids and their firmware, row r for robot ids[r] (raises ValueError when invalid)."""
    own, hosted = config
    ids = [int(i) for i in own.robot_ids]
    if not ids or len(set(ids)) != len(ids):
        raise ValueError(f"robot_ids: need distinct ids, at least one, got {ids}")
    # the per-robot nodes' builders check the parameters and say what is wrong in their words
    main = velocity_controller_node.build_loop(hosted[MAIN_PREFIX])
    motor = motor_boards_node.build_loop(hosted[MOTOR_PREFIX])
    return ids, TeamFirmware(len(ids), main.robot, main.controller.config, motor.board.config, main.loop_period_s,
                             motor.loop_period_s, main.watchdog.timeout_s, motor.setpoint_timeout_s)


class _Robot:
    """One robot's row in the team firmware, its publishers and time rule."""

    def __init__(self, node: Node, robot_id: int, row: int) -> None:
        team = node.team
        self.robot_id, self.row, self.name = robot_id, row, team.namespace(robot_id)
        self.stamps = StampFilter()  # the time rule for this robot's ticks on its own topics
        self.duty_pub = None if node.team_topics else contract_publisher(node, contract.MOTOR_DUTY,
                                                                          team.topic(contract.MOTOR_DUTY, robot_id))
        self.status_pub = contract_publisher(node, contract.MOTOR_STATUS, team.topic(contract.MOTOR_STATUS, robot_id))
        self.setpoint_pub = contract_publisher(node, contract.WHEEL_SETPOINTS,
                                               team.topic(contract.WHEEL_SETPOINTS, robot_id))


class TeamFirmwareNode(Node):
    def __init__(self) -> None:
        super().__init__("team_firmware")
        self._warn = ThrottledWarner(self)
        self._robots: dict[int, _Robot] = {}
        self._firmware: TeamFirmware | None = None
        self._params = NodeParams(self, SCHEMA, build_loops)
        self._values = self._params.values
        self.team_topics = self._values["lockstep_topics"] == "team"
        team = self.team = contract.TEAMS[self._values["team"]]
        self._apply(self._params.built)
        n, w = self._firmware.n_robots, self._firmware.num_wheels
        self._speeds, self._currents = np.zeros((n, w)), np.zeros((n, w))  # the sensors, row per robot
        # per row: the stamp of the last motor_status, and whether there is one on this time line
        self._status_ns, self._status_sent = np.zeros(n, dtype=np.int64), np.zeros(n, dtype=bool)
        self._team_stamps = StampFilter()  # the time rule for the team topic's ticks (one stamp for all robots)
        self._team_picks: dict[tuple[int, ...], tuple[np.ndarray, list[_Robot], np.ndarray, tuple[int, ...]]] = {}
        for i, robot in self._robots.items():
            contract_subscription(self, contract.CMD_VEL, lambda m, r=robot: self._on_cmd_vel(r, m),
                                  team.topic(contract.CMD_VEL, i))
            if not self.team_topics:
                contract_subscription(self, contract.WHEEL_STATES, lambda m, r=robot: self._on_wheel_states(r, m),
                                      team.topic(contract.WHEEL_STATES, i), raw=True)
        if self.team_topics:
            self._team_states_name = team.lockstep_topic(contract.TEAM_WHEEL_STATES)
            self._team_duty_pub = contract_publisher(self, contract.TEAM_MOTOR_DUTY,
                                                     team.lockstep_topic(contract.TEAM_MOTOR_DUTY))
            contract_subscription(self, contract.TEAM_WHEEL_STATES, self._on_team_wheel_states,
                                  self._team_states_name, raw=True)
        self._clock_subs = sample_clock(self)
        self.get_logger().info(f"team_firmware: {team.name}, robots {sorted(self._robots)}, "
                               f"{self._values['lockstep_topics']} lockstep topics")
        self._params.on_change(self._apply)

    def _apply(self, built: tuple[list[int], TeamFirmware]) -> None:
        ids, firmware = built
        if self._firmware is not None:
            firmware.take_over(self._firmware)  # robot_ids is read-only: the same rows
        self._firmware = firmware
        for row, i in enumerate(ids):
            if i not in self._robots:
                self._robots[i] = _Robot(self, i, row)

    def _on_cmd_vel(self, robot: _Robot, msg: Twist) -> None:
        v = self._values
        try:
            twist = twist_from_msg(msg, v[MAIN_PREFIX + "reject_linear_above_mps"],
                                   v[MAIN_PREFIX + "reject_angular_above_radps"])
        except ConversionError as exc:
            self._firmware.stop(robot.row)
            self._warn.warn(f"cmd_vel{robot.robot_id}", f"{robot.name}: rejected cmd_vel ({exc}); stopping")
            return
        self._firmware.command(robot.row, twist)

    def _on_wheel_states(self, robot: _Robot, msg: bytes) -> None:
        """A sensor tick of one robot (per-robot lockstep topics)."""
        run_sampled(self._clock_subs)
        firmware = self._firmware
        try:
            t_ns, speeds, currents = wheel_states_from_msg(msg, firmware.num_wheels)
        except ConversionError as exc:
            self._warn.warn(f"wheel_states{robot.robot_id}", f"{robot.name}: rejected wheel_states: {exc}")
            return
        if self._take_sensors(robot, t_ns, speeds, currents):
            rows = np.array([robot.row])
            duty = self._tick(rows, t_ns)
            robot.duty_pub.publish(joint_state_cdr(t_ns, firmware.robot.wheel_names, effort=duty[robot.row]))
            self._report([robot], rows, t_ns)

    def _on_team_wheel_states(self, msg: bytes) -> None:
        """One tick of every robot of ours in the message; one answer for all of them."""
        run_sampled(self._clock_subs)
        firmware = self._firmware
        try:
            t_ns, ids, (speeds, currents) = team_joint_state_from_msg(msg, firmware.num_wheels, ("velocity", "effort"),
                                                                      team=self.team)
        except ConversionError as exc:
            self._warn.warn("team_wheel_states", f"rejected {self._team_states_name}: {exc}")
            return
        picks, robots, rows, ours = self._picks(ids)  # the message's rows of our robots; the others are not ours
        if not robots:
            return
        verdict = check_stamp(self._team_stamps, t_ns, self._warn, self._team_states_name, self)
        if verdict is StampVerdict.DROP:
            return
        if verdict is StampVerdict.RESTART:
            for robot in robots:
                self._restart(robot)
        self._speeds[rows] = speeds[picks]
        self._currents[rows] = currents[picks]
        duty = self._tick(rows, t_ns)
        self._team_duty_pub.publish(team_joint_state_cdr(t_ns, ours, firmware.robot.wheel_names, effort=duty[rows],
                                                         team=self.team))
        self._report(robots, rows, t_ns)

    def _picks(self, ids: tuple[int, ...]) -> tuple[np.ndarray, list[_Robot], np.ndarray, tuple[int, ...]]:
        """For a team message's robot ids: the positions of ours among them, our robots, their rows and ids."""
        picks = self._team_picks.get(ids)
        if picks is None:
            if len(self._team_picks) >= 8:  # a few robot sets: one per plant configuration
                self._team_picks.clear()
            ks = [k for k, i in enumerate(ids) if i in self._robots]
            robots = [self._robots[ids[k]] for k in ks]
            picks = self._team_picks[ids] = (np.array(ks, dtype=np.int64), robots,
                                             np.array([r.row for r in robots], dtype=np.int64),
                                             tuple(r.robot_id for r in robots))
        return picks

    def _take_sensors(self, robot: _Robot, t_ns: int, speeds, currents) -> bool:
        """The time rule for this robot's tick; its sensors into its rows. False: the tick is dropped."""
        verdict = check_stamp(robot.stamps, t_ns, self._warn, f"{robot.name}/wheel_states", self)
        if verdict is StampVerdict.DROP:
            return False
        if verdict is StampVerdict.RESTART:
            self._restart(robot)
        self._speeds[robot.row] = speeds
        self._currents[robot.row] = currents
        return True

    def _restart(self, robot: _Robot) -> None:
        """A new time line for this robot: nothing of the old one is kept."""
        self._firmware.forget_setpoint(robot.row)
        self._status_sent[robot.row] = False

    def _tick(self, rows: np.ndarray, t_ns: int) -> np.ndarray:
        """Tick k at ``t_ns`` of the robots in ``rows`` (their sensors in those rows of _speeds/_currents), in the
        runner's order: main board (setpoint used at k+1), then the motor boards with the setpoint of tick k-1;
        one firmware call. Returns the duties, a row per robot of the firmware."""
        return self._firmware.tick(t_ns * 1e-9, self._speeds, self._currents, rows)

    def _report(self, robots: list[_Robot], rows: np.ndarray, t_ns: int) -> None:
        """What a tick of these robots tells besides the duty (which the plant waits for, so it goes first):
        notices, setpoints (publish_setpoints) and motor_status when due."""
        firmware = self._firmware
        for k in np.flatnonzero(firmware.main_notice[rows] | firmware.motor_notice[rows]).tolist():
            robot = robots[k]
            for notice in firmware.notices(robot.row):
                self._warn.warn(f"notice{robot.robot_id}", f"{robot.name}: {notice}")
        if self._values["publish_setpoints"]:
            names = firmware.robot.wheel_names
            for robot in robots:
                robot.setpoint_pub.publish(joint_state_cdr(t_ns, names, velocity=firmware.setpoints[robot.row]))
        period_ns = int(1e9 / self._values[MOTOR_PREFIX + "status_rate_hz"])
        last = self._status_ns[rows]
        due = ~self._status_sent[rows] | (t_ns - last >= period_ns) | (t_ns < last)
        due_rows = np.flatnonzero(due).tolist()
        if due_rows:
            averages, saturation = firmware.average_current_a, firmware.saturated
        for k in due_rows:
            row = int(rows[k])
            self._status_ns[row], self._status_sent[row] = t_ns, True
            limit, average, saturated = firmware.pwm_limit[row], averages[row], saturation[row]
            rows_out = [[average[j], limit[j], float(saturated[j]), float(limit[j] < 1.0)]
                        for j in range(firmware.num_wheels)]
            robots[k].status_pub.publish(table_cdr(rows_out, contract.MOTOR_STATUS_COLUMNS, "wheels"))


def main(args: list[str] | None = None) -> int:
    return run_node(TeamFirmwareNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
