"""motor_boards: the motor boards of one robot (paper Fig. 3) as a ROS 2 node.

Runs in the robot's namespace. Each ``wheel_states`` tick (measured wheel speeds and
motor currents) is answered with ``motor_duty`` stamped with that tick, computed with
the velocity controller's setpoint of the previous tick (erforce_interfaces.runtime.lockstep).
``motor_status`` reports the average current, PWM limit and flags per wheel. All maths
is in erforce_motion.firmware / motor_board.
"""

from __future__ import annotations

import collections
import time

from rclpy.clock import Clock, ClockType

from erforce_interfaces.runtime.executor import run_sampled, sample_only
from erforce_interfaces.runtime.lockstep import SetpointJoin
from erforce_interfaces.runtime.node_support import (
    SchemaNode,
    check_stamp,
    contract_publisher,
    contract_subscription,
    run_node,
    sample_clock,
)
from erforce_interfaces.runtime.param_schema import fields_for, load_schema
from erforce_interfaces.wire import contract
from erforce_interfaces.wire.conversions import (
    ConversionError,
    joint_state_cdr,
    joint_state_from_msg,
    wheel_states_from_msg,
)
from erforce_interfaces.wire.stamps import StampFilter, StampVerdict
from erforce_interfaces.wire.tables import table_cdr
from erforce_motion.firmware import MotorBoardLoop
from erforce_motion.motor_board import MotorBoardConfig

SCHEMA = load_schema("erforce_motion", "motor_boards")


def build_loop(config) -> MotorBoardLoop:
    """The motor-board loop for a config object of the schema (raises ValueError when it cannot run)."""
    robot = config.robot
    period_s = 1.0 / config.loop_rate_hz
    board = MotorBoardConfig(**fields_for(
        MotorBoardConfig, config,
        linear_duty_per_a=config.linear_duty_per_a or None,
        loop_period_s=period_s,
        average_current_limit_a=robot.continuous_current_limit_a,
        i2t_time_constant_s=robot.winding_thermal_time_constant_s,
    ))
    return MotorBoardLoop(robot, board, period_s, config.setpoint_timeout_s)


class MotorBoardsNode(SchemaNode):
    def __init__(self) -> None:
        super().__init__("motor_boards", SCHEMA, build_loop)
        self._loop: MotorBoardLoop = self._params.built
        self._join = SetpointJoin(wait=self._values["lockstep_sync"])
        self._pending: collections.deque = collections.deque()  # (stamp_ns, speeds, currents, wall_s)
        self._last_status_ns: int | None = None
        self._tick_stamps, self._setpoint_stamps = StampFilter(), StampFilter()
        self._duty_pub = contract_publisher(self, contract.MOTOR_DUTY)
        self._status_pub = contract_publisher(self, contract.MOTOR_STATUS)
        # The lockstep topics travel serialized (conversions.joint_state_cdr): rclpy's message
        # conversion cost more than the maths. Each wake costs a few hundred microseconds of CPU
        # here: the setpoint of tick k-1 is nearly always queued when tick k arrives, so it is
        # taken then, and the executor waits on it only while a tick is held for it (_drain).
        # /clock only stamps the logs.
        contract_subscription(self, contract.WHEEL_STATES, self._on_wheel_states, raw=True)
        self._setpoint_sub = sample_only(
            contract_subscription(self, contract.WHEEL_SETPOINTS, self._on_setpoints, raw=True))
        self._sampled = [*sample_clock(self), self._setpoint_sub]  # taken with each tick
        # Wall-clock timer: a silent velocity controller must not hold a tick forever. It runs only
        # while a tick is held: with a timer in it every executor wait is a timed one, which cost
        # ~25 us more per DDS round trip on this VM.
        self._hold_timer = self.create_timer(0.05, self._drain, clock=Clock(clock_type=ClockType.STEADY_TIME))
        self._hold_timer.cancel()
        self._params.on_change(self._apply)

    def _apply(self, loop: MotorBoardLoop) -> None:
        loop.take_over(self._loop)
        self._loop = loop
        self._join.wait = self._values["lockstep_sync"]

    def _on_wheel_states(self, msg: bytes) -> None:
        try:
            t_ns, speeds, currents = wheel_states_from_msg(msg, self._loop.robot.num_wheels)
        except ConversionError as exc:
            self._warn.warn("wheel_states", f"rejected wheel_states: {exc}")
            return
        verdict = check_stamp(self._tick_stamps, t_ns, self._warn, "wheel_states", self)
        if verdict is StampVerdict.DROP:
            return  # before anything else: a flood of these must cost little
        run_sampled(self._sampled)
        if verdict is StampVerdict.RESTART:
            self._pending.clear()  # ticks of the old time line need no answer any more
        elif any(pending[0] == t_ns for pending in self._pending):
            # The plant re-sent a tick that still waits for its setpoint: it is answered once, when that comes.
            # Queued twice it would count as two ticks pending and force a stale setpoint on the tick.
            return
        self._pending.append((t_ns, speeds, currents, time.monotonic()))
        self._drain()

    def _on_setpoints(self, msg: bytes) -> None:
        try:
            t_ns, setpoints = joint_state_from_msg(msg, self._loop.robot.num_wheels, "velocity")
        except ConversionError as exc:
            self._warn.warn("wheel_setpoints", f"rejected wheel_setpoints: {exc}")
            return
        if check_stamp(self._setpoint_stamps, t_ns, self._warn, "wheel_setpoints", self) is StampVerdict.DROP:
            return
        self._join.add_setpoint(t_ns, setpoints)
        self._drain()

    def _drain(self) -> None:
        while self._pending:
            t_ns, speeds, currents, arrived_s = self._pending[0]
            late = time.monotonic() - arrived_s > self._values["setpoint_wait_s"]
            ready, entry = self._join.setpoint_for(t_ns, force=late or len(self._pending) > 1)
            if not ready:
                sample_only(self._setpoint_sub, False)  # wake for it when it comes
                if self._hold_timer.is_canceled():
                    self._hold_timer.reset()
                return
            self._pending.popleft()
            if late and entry is not None:
                self._warn.warn("late", "no setpoint from velocity_controller in time; using the newest known")
            self._answer(t_ns, speeds, currents, entry)
        sample_only(self._setpoint_sub)
        if not self._hold_timer.is_canceled():
            self._hold_timer.cancel()

    def _answer(self, t_ns: int, speeds, currents, entry) -> None:
        loop = self._loop
        if entry is not None:
            loop.set_setpoint(entry[0] * 1e-9, entry[1])
        duty = loop.tick(t_ns * 1e-9, speeds, currents)
        if loop.notice:
            self._warn.warn("notice", loop.notice)
        self._join.done(t_ns)
        self._duty_pub.publish(joint_state_cdr(t_ns, loop.robot.wheel_names, effort=duty))
        period_ns = int(1e9 / self._values["status_rate_hz"])
        if self._last_status_ns is None or t_ns - self._last_status_ns >= period_ns or t_ns < self._last_status_ns:
            self._last_status_ns = t_ns
            st = loop.board.status
            rows = [
                [st.average_current_a[i], st.pwm_limit[i], float(st.saturated[i]), float(st.limit_active[i])]
                for i in range(loop.robot.num_wheels)
            ]
            self._status_pub.publish(table_cdr(rows, contract.MOTOR_STATUS_COLUMNS, "wheels"))


def main(args: list[str] | None = None) -> int:
    return run_node(MotorBoardsNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
