"""team_firmware: the main board and motor boards of many robots in one process.

The same contract as a ``velocity_controller`` plus a ``motor_boards`` per robot: per robot in
``robot_ids`` it takes ``cmd_vel`` and ``wheel_states`` and answers each tick with ``motor_duty`` (and
``motor_status`` at its rate). Inside, the main board's setpoint reaches the motor boards one tick later
without DDS, as the in-process runner steps the same cores (firmware.TeamFirmware, one call per tick),
so the lockstep graph computes the same trajectory in either deployment. ``wheel_setpoints`` only with
``publish_setpoints`` (tools).

``lockstep_topics`` ``team`` or ``field`` takes one message per tick for the team (or both teams) and
answers for this process's robots only; one time rule judges the message's stamp for all of them, and the
answer goes out before notices and status. ``team`` ``opponents`` makes it the opponents' firmware;
``team`` ``ours`` with ``opponent_ids`` runs both teams as rows of one TeamFirmware, each team answered on
its own (docs/decisions/0011): a simulation saves a process's wakes per tick, where a process per team
keeps one team's crash from the other, as on a real field.

The parameters of the two per-robot nodes are here with the prefixes ``main_board.`` and
``motor_boards.``, ``robot.*`` once for the team. ``robot_ids`` is read-only: a robot is added or removed
by starting the node with another list.
"""

from __future__ import annotations

import numpy as np
from geometry_msgs.msg import Twist
from rclpy.node import Node

from erforce_interfaces.runtime.executor import run_sampled
from erforce_interfaces.runtime.node_support import (
    SchemaNode,
    check_stamp,
    contract_publisher,
    contract_subscription,
    run_node,
    sample_clock,
)
from erforce_interfaces.runtime.param_schema import HostSchema, load_schema
from erforce_interfaces.wire import contract
from erforce_interfaces.wire.conversions import (
    ConversionError,
    field_joint_state_cdr,
    field_joint_state_from_msg,
    joint_state_cdr,
    team_joint_state_cdr,
    team_joint_state_from_msg,
    twist_from_msg,
    wheel_states_from_msg,
)
from erforce_interfaces.wire.stamps import StampFilter, StampVerdict
from erforce_interfaces.wire.tables import table_cdr
from erforce_motion import motor_boards_node, velocity_controller_node
from erforce_motion.firmware import TeamFirmware

MAIN_PREFIX, MOTOR_PREFIX = "main_board.", "motor_boards."
_CLOCK_SAMPLE_TICKS = 10  # team_firmware takes /clock (only its logs' time) once per this many team ticks
# The motor boards' DDS-side parameters (waiting for the main board's setpoint) mean nothing here.
_MOTOR_DDS_ONLY = ("lockstep_sync", "setpoint_wait_s")

SCHEMA = HostSchema(load_schema("erforce_motion", "team_firmware"), {
    MAIN_PREFIX: (velocity_controller_node.SCHEMA, ()),
    MOTOR_PREFIX: (motor_boards_node.SCHEMA, _MOTOR_DDS_ONLY),
})


def build_loops(config) -> tuple[list[tuple[contract.Team, int]], TeamFirmware]:
    """The robots (team, id) and their firmware, row r for robot r of the list (raises ValueError when invalid)."""
    own, hosted = config
    ids = [int(i) for i in own.robot_ids]
    if not ids or len(set(ids)) != len(ids):
        raise ValueError(f"robot_ids: need distinct ids, at least one, got {ids}")
    opponent_ids = [int(i) for i in own.opponent_ids]
    if len(set(opponent_ids)) != len(opponent_ids):
        raise ValueError(f"opponent_ids: need distinct ids, got {opponent_ids}")
    if opponent_ids and own.team != contract.OURS.name:
        raise ValueError("opponent_ids: only with team ours (robot_ids are then the opponents already)")
    team = contract.TEAMS[own.team]
    robots = [(team, i) for i in ids] + [(contract.OPPONENTS, i) for i in opponent_ids]
    # the per-robot nodes' builders check the parameters and say what is wrong in their words
    main = velocity_controller_node.build_loop(hosted[MAIN_PREFIX])
    motor = motor_boards_node.build_loop(hosted[MOTOR_PREFIX])
    return robots, TeamFirmware(len(robots), main.robot, main.controller.config, motor.board.config, main.loop_period_s,
                             motor.loop_period_s, main.command_timeout_s, motor.setpoint_timeout_s)


class _Robot:
    """One robot's row in the team firmware, its publishers and time rule."""

    def __init__(self, node: Node, team: contract.Team, robot_id: int, row: int) -> None:
        self.team, self.robot_id, self.row, self.name = team, robot_id, row, team.namespace(robot_id)
        self.stamps = StampFilter()  # the time rule for this robot's ticks on its own topics
        self.duty_pub = None if node.team_topics else contract_publisher(node, contract.MOTOR_DUTY,
                                                                          team.topic(contract.MOTOR_DUTY, robot_id))
        self.status_pub = contract_publisher(node, contract.MOTOR_STATUS, team.topic(contract.MOTOR_STATUS, robot_id))
        self.setpoint_pub = contract_publisher(node, contract.WHEEL_SETPOINTS,
                                               team.topic(contract.WHEEL_SETPOINTS, robot_id))


class _TeamLink:
    """One hosted team's lockstep topics (lockstep_topics team), or both teams' (``team`` None: lockstep_topics
    field): its time rule, its answer, the rows of its robots per robot set of the plant's message."""

    def __init__(self, node: Node, team: contract.Team | None) -> None:
        self.team = team
        self.name = team.name if team is not None else "field"
        self.robots: dict[int, _Robot] = {}  # by robot id (the field link: by (team name, robot id))
        self.stamps = StampFilter()  # one stamp for all robots of the team's message
        self.states_name = (team.lockstep_topic(contract.TEAM_WHEEL_STATES) if team is not None
                            else contract.FIELD_WHEEL_STATES.name)
        self.duty_pub = None
        self.picks: dict[tuple, tuple[np.ndarray | None, list[_Robot], np.ndarray, tuple]] = {}
        # the report has nothing to do for ticks in [quiet_from_ns, quiet_until_ns) without a notice (_report)
        self.quiet_from_ns, self.quiet_until_ns = 0, 0

    def decode(self, msg: bytes, num_wheels: int) -> tuple[int, tuple, list[np.ndarray]]:
        if self.team is None:
            return field_joint_state_from_msg(msg, num_wheels, ("velocity", "effort"))
        return team_joint_state_from_msg(msg, num_wheels, ("velocity", "effort"), team=self.team)

    def keys(self, ids: tuple) -> list:
        """The keys of ``robots`` for a message's robot ids, in the message's row order."""
        if self.team is None:
            return [(contract.OURS.name, i) for i in ids[0]] + [(contract.OPPONENTS.name, i) for i in ids[1]]
        return list(ids)

    def answer_ids(self, robots: list[_Robot]) -> tuple:
        if self.team is None:
            return (tuple(r.robot_id for r in robots if r.team is contract.OURS),
                    tuple(r.robot_id for r in robots if r.team is contract.OPPONENTS))
        return tuple(r.robot_id for r in robots)

    def encode(self, t_ns: int, ids: tuple, wheel_names: tuple[str, ...], duty: np.ndarray) -> bytes:
        if self.team is None:
            return field_joint_state_cdr(t_ns, ids, wheel_names, effort=duty)
        return team_joint_state_cdr(t_ns, ids, wheel_names, effort=duty, team=self.team)


class TeamFirmwareNode(SchemaNode):
    @staticmethod
    def warm_up() -> None:
        """For a warm standby (node_support.run_node): the firmware's kernels load with the first TeamFirmware
        built (~0.3 s of CPU), so a throwaway one of the default parameters loads them before the node's own."""
        build_loops(SCHEMA.parse(SCHEMA.defaults()))

    def __init__(self) -> None:
        super().__init__("team_firmware", SCHEMA, build_loops)
        self._links: dict[str, _TeamLink] = {}  # per hosted team (ours first)
        self._field_link: _TeamLink | None = None
        self._firmware: TeamFirmware | None = None
        lockstep = self._values["lockstep_topics"]
        self.team_topics = lockstep != "per_robot"  # no per-robot lockstep topics
        self._apply(self._params.built)
        n, w = self._firmware.n_robots, self._firmware.num_wheels
        self._speeds, self._currents = np.zeros((n, w)), np.zeros((n, w))  # the sensors, row per robot
        # per row: the stamp of the last motor_status, and whether there is one on this time line
        self._status_ns, self._status_sent = np.zeros(n, dtype=np.int64), np.zeros(n, dtype=bool)
        for link in self._links.values():
            team = link.team
            for i, robot in link.robots.items():
                contract_subscription(self, contract.CMD_VEL, lambda m, r=robot: self._on_cmd_vel(r, m),
                                      team.topic(contract.CMD_VEL, i))
                if not self.team_topics:
                    contract_subscription(self, contract.WHEEL_STATES, lambda m, r=robot: self._on_wheel_states(r, m),
                                          team.topic(contract.WHEEL_STATES, i), raw=True)
            if lockstep == "team":
                link.duty_pub = contract_publisher(self, contract.TEAM_MOTOR_DUTY,
                                                   team.lockstep_topic(contract.TEAM_MOTOR_DUTY))
                contract_subscription(self, contract.TEAM_WHEEL_STATES,
                                      lambda m, link=link: self._on_team_wheel_states(link, m),
                                      link.states_name, raw=True)
        if lockstep == "field":  # both teams' robots on one pair of topics
            link = self._field_link = _TeamLink(self, None)
            link.robots = {(team_link.team.name, i): robot for team_link in self._links.values()
                           for i, robot in team_link.robots.items()}
            link.duty_pub = contract_publisher(self, contract.FIELD_MOTOR_DUTY)
            contract_subscription(self, contract.FIELD_WHEEL_STATES, lambda m: self._on_team_wheel_states(link, m),
                                  link.states_name, raw=True)
        self._clock_subs = sample_clock(self)
        self._ticks_to_clock_sample = 0
        self._first_link = self._field_link or next(iter(self._links.values()), None)
        hosted = "; ".join(f"{link.team.name}, robots {sorted(link.robots)}" for link in self._links.values())
        self.get_logger().info(f"team_firmware: {hosted}, {lockstep} lockstep topics")
        self._params.on_change(self._apply)

    def _apply(self, built: tuple[list[tuple[contract.Team, int]], TeamFirmware]) -> None:
        robots, firmware = built
        if self._firmware is not None:
            firmware.take_over(self._firmware)  # robot_ids and opponent_ids are read-only: the same rows
        self._firmware = firmware
        self._report_all_next()  # the status rate may have changed
        for row, (team, i) in enumerate(robots):
            link = self._links.get(team.name)
            if link is None:
                link = self._links[team.name] = _TeamLink(self, team)
            if i not in link.robots:
                link.robots[i] = _Robot(self, team, i, row)

    def _on_cmd_vel(self, robot: _Robot, msg: Twist) -> None:
        v = self._values
        try:
            twist = twist_from_msg(msg, v[MAIN_PREFIX + "reject_linear_above_mps"],
                                   v[MAIN_PREFIX + "reject_angular_above_radps"])
        except ConversionError as exc:
            self._firmware.stop(robot.row)
            self._warn.warn(f"cmd_vel {robot.name}", f"{robot.name}: rejected cmd_vel ({exc}); stopping")
            return
        self._firmware.command(robot.row, twist)

    def _on_wheel_states(self, robot: _Robot, msg: bytes) -> None:
        """A sensor tick of one robot (per-robot lockstep topics)."""
        run_sampled(self._clock_subs)
        firmware = self._firmware
        try:
            t_ns, speeds, currents = wheel_states_from_msg(msg, firmware.num_wheels)
        except ConversionError as exc:
            self._warn.warn(f"wheel_states {robot.name}", f"{robot.name}: rejected wheel_states: {exc}")
            return
        if self._take_sensors(robot, t_ns, speeds, currents):
            rows = np.array([robot.row])
            duty = self._tick(rows, t_ns)
            robot.duty_pub.publish(joint_state_cdr(t_ns, firmware.robot.wheel_names, effort=duty[robot.row]))
            self._report([robot], rows, t_ns)

    def _on_team_wheel_states(self, link: _TeamLink, msg: bytes) -> None:
        """One tick of every robot of the team's message that this process runs; one answer for all of them."""
        firmware = self._firmware
        try:
            t_ns, ids, (speeds, currents) = link.decode(msg, firmware.num_wheels)
        except ConversionError as exc:
            self._warn.warn(f"team_wheel_states {link.name}", f"rejected {link.states_name}: {exc}")
            return
        picks, robots, rows, ours = self._picks(link, ids)  # the message's rows of our robots; the others are not ours
        if not robots:
            return
        verdict = check_stamp(link.stamps, t_ns, self._warn, link.states_name, self)
        if verdict is StampVerdict.DROP:
            return
        if verdict is StampVerdict.RESTART:
            for robot in robots:
                self._restart(robot)
        if picks is None:  # the message's rows are all the firmware's rows, in order
            self._speeds[...] = speeds
            self._currents[...] = currents
            answer = firmware.tick(t_ns * 1e-9, self._speeds, self._currents)
        else:
            self._speeds[rows] = speeds[picks]
            self._currents[rows] = currents[picks]
            answer = self._tick(rows, t_ns)[rows]
        link.duty_pub.publish(link.encode(t_ns, ours, firmware.robot.wheel_names, answer))
        if link is self._first_link:  # /clock (the logs' time) every few ticks, after the answer the plant waits for
            self._ticks_to_clock_sample -= 1
            if self._ticks_to_clock_sample <= 0:
                self._ticks_to_clock_sample = _CLOCK_SAMPLE_TICKS
                run_sampled(self._clock_subs)
        self._report(robots, rows, t_ns, link)

    def _picks(self, link: _TeamLink, ids: tuple) -> tuple[np.ndarray | None, list[_Robot], np.ndarray, tuple]:
        """For a team (field) message's robot ids: the positions of ours among them, our robots, their rows and
        the ids of the answer; the positions are None when they are every row of the firmware, in row order."""
        picks = link.picks.get(ids)
        if picks is None:
            if len(link.picks) >= 8:  # a few robot sets: one per plant configuration
                link.picks.clear()
            link.quiet_from_ns, link.quiet_until_ns = 0, 0  # other robots: their statuses may be due
            keys = link.keys(ids)
            ks = [k for k, key in enumerate(keys) if key in link.robots]
            robots = [link.robots[keys[k]] for k in ks]
            rows = [r.row for r in robots]
            every_row = ks == list(range(len(keys))) and rows == list(range(self._firmware.n_robots))
            picks = link.picks[ids] = (None if every_row else np.array(ks, dtype=np.int64), robots,
                                       np.array(rows, dtype=np.int64), link.answer_ids(robots))
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
        self._report_all_next()

    def _report_all_next(self) -> None:
        """The next tick of every team link runs the whole report (a status may fall due otherwise)."""
        for link in (*self._links.values(), self._field_link):
            if link is not None:
                link.quiet_from_ns, link.quiet_until_ns = 0, 0

    def _tick(self, rows: np.ndarray, t_ns: int) -> np.ndarray:
        """Tick k at ``t_ns`` of the robots in ``rows`` (their sensors in those rows of _speeds/_currents), in the
        runner's order: main board (setpoint used at k+1), then the motor boards with the setpoint of tick k-1;
        one firmware call. Returns the duties, a row per robot of the firmware."""
        return self._firmware.tick(t_ns * 1e-9, self._speeds, self._currents, rows)

    def _report(self, robots: list[_Robot], rows: np.ndarray, t_ns: int, link: _TeamLink | None = None) -> None:
        """What a tick of these robots tells besides the duty (which the plant waits for, so it goes first):
        notices, setpoints (publish_setpoints) and motor_status when due. A team link's usual tick has none of
        them: no notice (the kernel's flag), no setpoints and no status due before ``link.quiet_until_ns``."""
        firmware = self._firmware
        publish_setpoints = self._values["publish_setpoints"]
        if (link is not None and not firmware.noticed and not publish_setpoints
                and link.quiet_from_ns <= t_ns < link.quiet_until_ns):
            return
        if firmware.noticed:
            for k in np.flatnonzero(firmware.main_notice[rows] | firmware.motor_notice[rows]).tolist():
                robot = robots[k]
                for notice in firmware.notices(robot.row):
                    self._warn.warn(f"notice {robot.name}", f"{robot.name}: {notice}")
        if publish_setpoints:
            names = firmware.robot.wheel_names
            for robot in robots:
                robot.setpoint_pub.publish(joint_state_cdr(t_ns, names, velocity=firmware.setpoints[robot.row]))
        period_ns = int(1e9 / self._values[MOTOR_PREFIX + "status_rate_hz"])
        last = self._status_ns[rows]
        due = ~self._status_sent[rows] | (t_ns - last >= period_ns) | (t_ns < last)
        due_rows = np.flatnonzero(due).tolist()
        if link is not None:  # after this tick's statuses: none falls due before the earliest last one + period
            last = np.where(due, t_ns, last)
            link.quiet_from_ns, link.quiet_until_ns = int(last.max()), int(last.min()) + period_ns
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
