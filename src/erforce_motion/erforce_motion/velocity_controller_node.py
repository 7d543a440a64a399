"""velocity_controller: the main board of one robot (paper Fig. 2) as a ROS 2 node.

Runs in the robot's namespace. ``cmd_vel`` (Twist, robot frame) sets the desired
velocity; every ``wheel_states`` tick is answered with ``wheel_setpoints`` stamped with
that tick (see erforce_interfaces.lockstep). All maths is in erforce_motion.firmware.
"""

from __future__ import annotations

from typing import Any

from geometry_msgs.msg import Twist
from rclpy.node import Node

from erforce_interfaces import contract
from erforce_interfaces.conversions import (
    ConversionError,
    joint_state_cdr,
    twist_from_msg,
    wheel_states_from_msg,
)
from erforce_interfaces.executor import run_sampled, sample_only
from erforce_interfaces.node_support import (
    ParamSpec,
    ThrottledWarner,
    check_stamp,
    contract_publisher,
    contract_subscription,
    declare_params,
    robot_config_from_params,
    robot_param_specs,
    run_node,
    sample_clock,
)
from erforce_interfaces.stamps import StampFilter, StampVerdict
from erforce_motion.firmware import MainBoardLoop
from erforce_motion.velocity_control import VelocityControlConfig

_VC = VelocityControlConfig()  # node defaults are the core's defaults

PARAMS = (
    ParamSpec(
        "loop_rate_hz",
        500.0,
        "velocity loop rate; slower than the sensor ticks holds the setpoints [Hz]",
        min=1.0,
        max=20000.0,
    ),
    ParamSpec(
        "command_timeout_s", 0.2, "stop when no cmd_vel arrived for this long (robot time) [s]", min=0.001, max=3600.0
    ),
    ParamSpec(
        "reject_linear_above_mps",
        10.0,
        "a cmd_vel faster than this is absurd: rejected, robot stops [m/s]",
        min=0.1,
        max=100.0,
    ),
    ParamSpec(
        "reject_angular_above_radps",
        60.0,
        "a cmd_vel turning faster than this is rejected [rad/s]",
        min=0.1,
        max=1000.0,
    ),
    ParamSpec(
        "feedforward_enabled", _VC.feedforward_enabled, "pass the shaped setpoint through; the PID only corrects"
    ),
    ParamSpec("max_speed_mps", _VC.max_speed_mps, "speed limit of the setpoint shaper [m/s]", min=0.01, max=20.0),
    ParamSpec(
        "max_accel_mps2", _VC.max_accel_mps2, "acceleration limit of the setpoint shaper [m/s^2]", min=0.01, max=100.0
    ),
    ParamSpec(
        "max_angular_speed_radps", _VC.max_angular_speed_radps, "angular speed limit [rad/s]", min=0.01, max=200.0
    ),
    ParamSpec(
        "max_angular_accel_radps2",
        _VC.max_angular_accel_radps2,
        "angular acceleration limit [rad/s^2]",
        min=0.01,
        max=2000.0,
    ),
    ParamSpec(
        "kp_translation", _VC.kp_translation, "PID proportional gain, vx and vy [(m/s)/(m/s)]", min=1e-6, max=1000.0
    ),
    ParamSpec("ki_translation", _VC.ki_translation, "PID integral gain, vx and vy [1/s]", min=0.0, max=10000.0),
    ParamSpec("kd_translation", _VC.kd_translation, "PID derivative gain, vx and vy [s]", min=0.0, max=100.0),
    ParamSpec("kp_rotation", _VC.kp_rotation, "PID proportional gain, wz", min=1e-6, max=1000.0),
    ParamSpec("ki_rotation", _VC.ki_rotation, "PID integral gain, wz [1/s]", min=0.0, max=10000.0),
    ParamSpec("kd_rotation", _VC.kd_rotation, "PID derivative gain, wz [s]", min=0.0, max=100.0),
    ParamSpec(
        "derivative_filter_tau_s",
        _VC.derivative_filter_tau_s,
        "low-pass time constant of the derivative [s]",
        min=0.0,
        max=1.0,
    ),
    ParamSpec("command_limit_mps", _VC.command_limit_mps, "PID output limit per linear axis [m/s]", min=0.01, max=50.0),
    ParamSpec("command_limit_radps", _VC.command_limit_radps, "PID output limit, wz [rad/s]", min=0.01, max=500.0),
    ParamSpec("anti_windup", _VC.anti_windup, "integrator anti-windup: clamp | back_calculation"),
    ParamSpec("ff_integrator_limit_mps", _VC.ff_integrator_limit_mps, "integrator bound per linear axis while "
              "feedforward is on (no wind-up while the wheels cannot follow) [m/s]", min=1e-3, max=50.0),
    ParamSpec("ff_integrator_limit_radps", _VC.ff_integrator_limit_radps, "integrator bound, wz, while "
              "feedforward is on [rad/s]", min=1e-3, max=500.0),
    ParamSpec("traction_limit_fraction", _VC.traction_limit_fraction, "the shaper keeps every wheel's traction "
              "force below this fraction of mu*N", min=0.05, max=1.0),
    ParamSpec("slip_hold_threshold_radps", _VC.slip_hold_threshold_radps, "hold the integrator while the wheel "
              "slip residual exceeds this [rad/s]", min=0.0, max=1000.0),
) + robot_param_specs()

_CONFIG_KEYS = (
    "feedforward_enabled",
    "max_speed_mps",
    "max_accel_mps2",
    "max_angular_speed_radps",
    "max_angular_accel_radps2",
    "kp_translation",
    "ki_translation",
    "kd_translation",
    "kp_rotation",
    "ki_rotation",
    "kd_rotation",
    "derivative_filter_tau_s",
    "command_limit_mps",
    "command_limit_radps",
    "anti_windup", "traction_limit_fraction", "slip_hold_threshold_radps", "ff_integrator_limit_mps",
    "ff_integrator_limit_radps",
)


def build_loop(values: dict[str, Any]) -> MainBoardLoop:
    """The main-board loop for a complete set of parameter values (raises ValueError when invalid)."""
    if values["anti_windup"] not in ("clamp", "back_calculation"):
        raise ValueError(f"anti_windup must be clamp or back_calculation, got {values['anti_windup']!r}")
    config = VelocityControlConfig(**{k: values[k] for k in _CONFIG_KEYS})
    return MainBoardLoop(
        robot_config_from_params(values), config, 1.0 / values["loop_rate_hz"], values["command_timeout_s"]
    )


class VelocityControllerNode(Node):
    def __init__(self) -> None:
        super().__init__("velocity_controller")
        self._warn = ThrottledWarner(self)
        self._loop: MainBoardLoop | None = None
        self._values = declare_params(self, PARAMS, build_loop, self._apply)
        self._setpoint_pub = contract_publisher(self, contract.WHEEL_SETPOINTS)
        self._stamps = StampFilter()
        # cmd_vel counts from the next tick on, so it is taken with each tick (the newest of what is queued
        # wins): a flood of cmd_vel then costs no wake per message and cannot starve the ticks.
        cmd_sub = sample_only(contract_subscription(self, contract.CMD_VEL, self._on_cmd_vel))
        contract_subscription(self, contract.WHEEL_STATES, self._on_wheel_states, raw=True)  # see motor_boards
        self._sampled = [*sample_clock(self), cmd_sub]  # runs on the ticks' stamps: no wake per /clock

    def _apply(self, loop: MainBoardLoop) -> None:
        if self._loop is not None:
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
