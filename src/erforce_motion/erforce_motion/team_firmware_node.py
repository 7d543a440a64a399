"""team_firmware: the main board and motor boards of many robots in one process.

The same contract as one ``velocity_controller`` plus one ``motor_boards`` per robot (each in
its namespace ``robot_<id>``): per robot in ``robot_ids`` it takes ``/robot_<id>/cmd_vel`` and
``/robot_<id>/wheel_states`` and answers each tick with ``/robot_<id>/motor_duty`` and, at its
rate, ``motor_status``. Inside, the main board's setpoint reaches the motor boards without DDS,
one tick later, exactly as erforce_sim.closed_loop.runner.InProcessRunner steps the same cores
(erforce_motion.firmware), so the lockstep graph computes the same trajectory with either
deployment. ``wheel_setpoints`` is published only with ``publish_setpoints`` (for tools):
nobody in the graph needs it, and it would be a message per robot per tick.

With ``lockstep_topics`` ``team`` it takes one ``/team/wheel_states`` per tick instead and answers
with one ``/team/motor_duty`` for its robots (contract: joints ``robot_<id>/wheel_<k>``); robots of the
message that are not in ``robot_ids`` belong to another process (the other team) and are left alone.

One executor wakes once for all robots whose ``wheel_states`` are queued, instead of two
processes per robot each waking per tick. The parameters of the two per-robot nodes are here
with the prefixes ``main_board.`` and ``motor_boards.`` (the same names, ranges and defaults),
``robot.*`` once for the team. ``robot_ids`` is read-only: a robot is added or removed by
starting the node with another list.
"""

from __future__ import annotations

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
from erforce_motion.firmware import MainBoardLoop, MotorBoardLoop

MAIN_PREFIX, MOTOR_PREFIX = "main_board.", "motor_boards."
# The motor boards' DDS-side parameters (waiting for the main board's setpoint) mean nothing here.
_MOTOR_DDS_ONLY = ("lockstep_sync", "setpoint_wait_s")

SCHEMA = HostSchema(load_schema("erforce_motion", "team_firmware"), {
    MAIN_PREFIX: (velocity_controller_node.SCHEMA, ()),
    MOTOR_PREFIX: (motor_boards_node.SCHEMA, _MOTOR_DDS_ONLY),
})


def build_loops(config) -> dict[int, tuple[MainBoardLoop, MotorBoardLoop]]:
    """One main-board and one motor-board loop per robot id (raises ValueError when invalid)."""
    own, hosted = config
    ids = list(own.robot_ids)
    if not ids or len(set(ids)) != len(ids):
        raise ValueError(f"robot_ids: need distinct ids, at least one, got {ids}")
    return {int(i): (velocity_controller_node.build_loop(hosted[MAIN_PREFIX]),
                     motor_boards_node.build_loop(hosted[MOTOR_PREFIX])) for i in ids}


class _Robot:
    """One robot's loops, publishers and the setpoint its motor boards use at the next tick."""

    def __init__(self, node: Node, robot_id: int, main: MainBoardLoop, motor: MotorBoardLoop) -> None:
        self.robot_id, self.main, self.motor = robot_id, main, motor
        self.previous_setpoint = None  # (t_s, setpoints) of the last tick
        self.last_status_ns: int | None = None
        self.stamps = StampFilter()  # the time rule for this robot's ticks
        self.duty_pub = None if node.team_topics else contract_publisher(node, contract.MOTOR_DUTY,
                                                                          contract.MOTOR_DUTY.for_robot(robot_id))
        self.status_pub = contract_publisher(node, contract.MOTOR_STATUS, contract.MOTOR_STATUS.for_robot(robot_id))
        self.setpoint_pub = contract_publisher(node, contract.WHEEL_SETPOINTS,
                                               contract.WHEEL_SETPOINTS.for_robot(robot_id))


class TeamFirmwareNode(Node):
    def __init__(self) -> None:
        super().__init__("team_firmware")
        self._warn = ThrottledWarner(self)
        self._robots: dict[int, _Robot] = {}
        self._params = NodeParams(self, SCHEMA, build_loops)
        self._values = self._params.values
        self.team_topics = self._values["lockstep_topics"] == "team"
        self._apply(self._params.built)
        for i, robot in self._robots.items():
            contract_subscription(self, contract.CMD_VEL, lambda m, r=robot: self._on_cmd_vel(r, m),
                                  contract.CMD_VEL.for_robot(i))
            if not self.team_topics:
                contract_subscription(self, contract.WHEEL_STATES, lambda m, r=robot: self._on_wheel_states(r, m),
                                      contract.WHEEL_STATES.for_robot(i), raw=True)
        if self.team_topics:
            self._team_duty_pub = contract_publisher(self, contract.TEAM_MOTOR_DUTY)
            contract_subscription(self, contract.TEAM_WHEEL_STATES, self._on_team_wheel_states, raw=True)
        self._clock_subs = sample_clock(self)
        self.get_logger().info(f"team_firmware: robots {sorted(self._robots)}, "
                               f"{self._values['lockstep_topics']} lockstep topics")
        self._params.on_change(self._apply)

    def _apply(self, loops: dict[int, tuple[MainBoardLoop, MotorBoardLoop]]) -> None:
        for i, (main, motor) in loops.items():
            robot = self._robots.get(i)
            if robot is None:
                self._robots[i] = _Robot(self, i, main, motor)
                continue
            main.take_over(robot.main)
            motor.take_over(robot.motor)
            robot.main, robot.motor = main, motor

    def _on_cmd_vel(self, robot: _Robot, msg: Twist) -> None:
        v = self._values
        try:
            twist = twist_from_msg(msg, v[MAIN_PREFIX + "reject_linear_above_mps"],
                                   v[MAIN_PREFIX + "reject_angular_above_radps"])
        except ConversionError as exc:
            robot.main.stop()
            self._warn.warn(f"cmd_vel{robot.robot_id}", f"robot_{robot.robot_id}: rejected cmd_vel ({exc}); stopping")
            return
        robot.main.command(twist)

    def _on_wheel_states(self, robot: _Robot, msg: bytes) -> None:
        run_sampled(self._clock_subs)
        try:
            t_ns, speeds, currents = wheel_states_from_msg(msg, robot.main.robot.num_wheels)
        except ConversionError as exc:
            self._warn.warn(f"wheel_states{robot.robot_id}", f"robot_{robot.robot_id}: rejected wheel_states: {exc}")
            return
        duty = self._tick(robot, t_ns, speeds, currents)
        if duty is not None:
            robot.duty_pub.publish(joint_state_cdr(t_ns, robot.main.robot.wheel_names, effort=duty))

    def _on_team_wheel_states(self, msg: bytes) -> None:
        """One tick of every robot of ours in the message; one answer for all of them."""
        run_sampled(self._clock_subs)
        robot_config = next(iter(self._robots.values())).main.robot
        try:
            t_ns, ids, (speeds, currents) = team_joint_state_from_msg(msg, len(robot_config.wheel_names),
                                                                      ("velocity", "effort"))
        except ConversionError as exc:
            self._warn.warn("team_wheel_states", f"rejected /team/wheel_states: {exc}")
            return
        answered, duties = [], []
        for k, i in enumerate(ids):
            robot = self._robots.get(i)
            if robot is None:  # another process's robot
                continue
            duty = self._tick(robot, t_ns, speeds[k], currents[k])
            if duty is not None:
                answered.append(i)
                duties.append(duty)
        if answered:
            self._team_duty_pub.publish(team_joint_state_cdr(t_ns, answered, robot_config.wheel_names, effort=duties))

    def _tick(self, robot: _Robot, t_ns: int, speeds, currents):
        """Tick k of one robot, in the runner's order: main board (setpoint used at k+1), then the motor
        boards with the setpoint of tick k-1. Returns the duty, or None for a tick the time rule drops."""
        main, motor = robot.main, robot.motor
        verdict = check_stamp(robot.stamps, t_ns, self._warn, f"robot_{robot.robot_id}/wheel_states", self)
        if verdict is StampVerdict.DROP:
            return None
        if verdict is StampVerdict.RESTART:
            robot.previous_setpoint = robot.last_status_ns = None  # of the old time line
        t_s = t_ns * 1e-9
        setpoint = main.tick(t_s, speeds).copy()
        if robot.previous_setpoint is not None and robot.previous_setpoint[0] < t_s:
            motor.set_setpoint(*robot.previous_setpoint)
        duty = motor.tick(t_s, speeds, currents)
        robot.previous_setpoint = (t_s, setpoint)
        for notice in (main.notice, motor.notice):
            if notice:
                self._warn.warn(f"notice{robot.robot_id}", f"robot_{robot.robot_id}: {notice}")
        if self._values["publish_setpoints"]:
            robot.setpoint_pub.publish(joint_state_cdr(t_ns, main.robot.wheel_names, velocity=setpoint))
        period_ns = int(1e9 / self._values[MOTOR_PREFIX + "status_rate_hz"])
        last = robot.last_status_ns
        if last is None or t_ns - last >= period_ns or t_ns < last:
            robot.last_status_ns = t_ns
            st = motor.board.status
            rows = [[st.average_current_a[k], st.pwm_limit[k], float(st.saturated[k]), float(st.limit_active[k])]
                    for k in range(main.robot.num_wheels)]
            robot.status_pub.publish(table_cdr(rows, contract.MOTOR_STATUS_COLUMNS, "wheels"))
        return duty


def main(args: list[str] | None = None) -> int:
    return run_node(TeamFirmwareNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
