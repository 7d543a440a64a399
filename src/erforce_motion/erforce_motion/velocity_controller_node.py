"""velocity_controller: the main board of one robot (paper Fig. 2) as a ROS 2 node.

Runs in the robot's namespace. ``cmd_vel`` (Twist, robot frame) sets the desired
velocity; every ``wheel_states`` tick is answered with ``wheel_setpoints`` stamped with
that tick (see erforce_interfaces.runtime.lockstep). All maths is in erforce_motion.firmware.
"""

from __future__ import annotations

from geometry_msgs.msg import Twist

from erforce_interfaces.runtime.executor import run_sampled, sample_only
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
    MAX_ABS_VALUE,
    ConversionError,
    joint_state_cdr,
    twist_from_msg,
    wheel_states_from_msg,
)
from erforce_interfaces.wire.stamps import StampFilter, StampVerdict
from erforce_motion.firmware import MainBoardLoop
from erforce_motion.velocity_control import VelocityControlConfig

SCHEMA = load_schema("erforce_motion", "velocity_controller")


def build_loop(config) -> MainBoardLoop:
    """The main-board loop for a config object of the schema (raises ValueError when it cannot run)."""
    loop = MainBoardLoop(config.robot, VelocityControlConfig(**fields_for(VelocityControlConfig, config)),
                         1.0 / config.loop_rate_hz, config.command_timeout_s)
    bound = loop.controller.max_setpoint_radps
    if bound > MAX_ABS_VALUE:
        raise ValueError(f"the command limits ({config.command_limit_mps:g} m/s, {config.command_limit_radps:g} "
                         f"rad/s) would ask for wheel speeds up to {bound:.4g} rad/s with this robot "
                         f"(robot.wheel_radius_m {config.robot.wheel_radius_m:g} m), beyond the wire's "
                         f"{MAX_ABS_VALUE:g} rad/s")
    return loop


class VelocityControllerNode(SchemaNode):
    def __init__(self) -> None:
        super().__init__("velocity_controller", SCHEMA, build_loop)
        self._loop: MainBoardLoop = self._params.built
        self._setpoint_pub = contract_publisher(self, contract.WHEEL_SETPOINTS)
        self._stamps = StampFilter()
        # cmd_vel counts from the next tick on, so it is taken with each tick (the newest of what is queued
        # wins): a flood of cmd_vel then costs no wake per message and cannot starve the ticks.
        cmd_sub = sample_only(contract_subscription(self, contract.CMD_VEL, self._on_cmd_vel))
        contract_subscription(self, contract.WHEEL_STATES, self._on_wheel_states, raw=True)  # see motor_boards
        self._sampled = [*sample_clock(self), cmd_sub]  # runs on the ticks' stamps: no wake per /clock
        self._params.on_change(self._apply)

    def _apply(self, loop: MainBoardLoop) -> None:
        loop.take_over(self._loop)
        self._loop = loop

    def _on_cmd_vel(self, msg: Twist) -> None:
        try:
            twist = twist_from_msg(
                msg, self._values["reject_linear_above_mps"], self._values["reject_angular_above_radps"]
            )
        except ConversionError as exc:
            self._loop.stop()
            self._warn.warn("cmd_vel", f"rejected cmd_vel ({exc}); stopping")
            return
        self._loop.command(twist)

    def _on_wheel_states(self, msg: bytes) -> None:
        loop = self._loop
        try:
            t_ns, speeds, _ = wheel_states_from_msg(msg, loop.robot.num_wheels)
        except ConversionError as exc:
            self._warn.warn("wheel_states", f"rejected wheel_states: {exc}")
            return
        if check_stamp(self._stamps, t_ns, self._warn, "wheel_states", self) is StampVerdict.DROP:
            return  # before anything else: a flood of these must cost little
        run_sampled(self._sampled)
        setpoints = loop.tick(t_ns * 1e-9, speeds)
        if loop.notice:
            self._warn.warn("notice", loop.notice)
        self._setpoint_pub.publish(joint_state_cdr(t_ns, loop.robot.wheel_names, velocity=setpoints))


def main(args: list[str] | None = None) -> int:
    return run_node(VelocityControllerNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
