"""Ziegler-Nichols tuning of the motor-board speed loop on the simulated motor + wheel, paper Sec. 4.2 / Fig. 4.

The experiment of the paper, run on the erforce_sim plant instead of a robot on the bench:

1. Put the robot on a stand (`World.set_lifted`): every wheel spins freely, no traction.
   Why lifted and not on the ground: on the ground one wheel's step drives the whole robot
   (four wheels coupled through the body) and a step large enough to measure saturates the
   traction (mu m g / 4 = 5.1 N), so the response is neither the motor + wheel nor linear.
   Lifted, the plant is exactly the motor + gear + wheel, and it is the worst case of the
   speed loop: a slipping wheel has the same small inertia (3.5x below the wheel with its
   share of the robot), so gains that are stable here stay stable when a wheel slips.
2. Excite the uncontrolled system: no PID, the paper's linear actuator duty = (R/V) i_des with
   a desired-current step (or a one-loop-period "delta impulse", the paper's wording), applied
   one loop period after t = 0 (the board computes a duty from one sample and applies it for
   the next period), and record the wheel speed at the loop rate.
3. `erforce_motion.tuning`: impulse -> step by integration, PT2 fit with dead time, inflection
   tangent (Tu, Tg), rule gains; write a ROS 2 params file for the `motor_boards` node and
   the Fig. 4-like PNG.

    tune_motor [--out DIR] [--response step|impulse] [--rule zn|chr_0|chr_20] [--structure PI|PID]

No rclpy import. The fitted times can be checked against the motor's own constants:
`motor_time_constants` gives tau_e = L/R and the mechanical tau_m = J R / (eta k_t k_e G^2)
(J at the wheel axle; = (J_wheel/G^2 + J_rotor) R / (eta k_t k_e) at the motor shaft).
"""

from __future__ import annotations

import argparse
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from erforce_interfaces.wire.robot_config import FieldConfig, RobotConfig
from erforce_motion.tuning import (
    RULES,
    TuningResult,
    plot_tuning,
    run_tuning_experiment,
    write_gains_yaml,
)
from erforce_sim.world import World
from erforce_sim.world_types import PhysicsParams, RobotSpec

MOTOR_BOARDS_NODE_KEY = "/**/motor_boards"  # matches the node in any robot namespace (robot_0, ...)


@dataclass(frozen=True)
class MotorTimeConstants:
    electrical_s: float  # L / R
    mechanical_s: float  # J_axle R / (eta k_t k_e G^2)
    gain_radps_per_a: float  # final wheel speed per desired ampere through duty = (R/V) i, no friction
    pt2_t1_s: float  # the two poles of 1 / (tau_m tau_e s^2 + tau_m s + 1)
    pt2_t2_s: float


def motor_time_constants(robot: RobotConfig) -> MotorTimeConstants:
    """Closed-form constants of the lifted motor + gear + wheel (friction neglected).

    L di/dt = V d - R i - k_e G w,  J dw/dt = eta G k_t i  with d = (R/V) i_des give
    w / i_des = (R / (k_e G)) / (tau_m tau_e s^2 + tau_m s + 1).
    """
    j_axle = robot.wheel_inertia_kgm2 + robot.gear_ratio**2 * robot.motor_rotor_inertia_kgm2
    kt = robot.motor_torque_constant_nm_per_a
    g = robot.gear_ratio
    r = robot.motor_resistance_ohm
    tau_m = j_axle * r / (robot.gear_efficiency * kt * kt * g * g)
    tau_e = robot.motor_inductance_h / r
    disc = math.sqrt(tau_m * tau_m - 4.0 * tau_m * tau_e)  # real poles while tau_m > 4 tau_e
    return MotorTimeConstants(tau_e, tau_m, r / (kt * g), 0.5 * (tau_m + disc), 0.5 * (tau_m - disc))


def lifted_wheel_response(
    robot: RobotConfig | None = None,
    *,
    response: str = "step",
    amplitude_a: float = 2.0,
    loop_period_s: float = 0.001,
    duration_s: float = 0.15,
    wheel: int = 0,
    physics: PhysicsParams | None = None,
) -> tuple[np.ndarray, np.ndarray, float]:
    """(t [s], wheel speed [rad/s], input size) of one lifted wheel, uncontrolled.

    'step': desired current `amplitude_a` from one loop period on (input size = amplitude [A]);
    'impulse': `amplitude_a` for exactly one loop period (input size = area [A s]).
    """
    robot = robot if robot is not None else RobotConfig()
    if response not in ("step", "impulse"):
        raise ValueError(f"response: 'step' or 'impulse', got {response!r}")
    for name, v in (("amplitude_a", amplitude_a), ("loop_period_s", loop_period_s), ("duration_s", duration_s)):
        if not (math.isfinite(v) and v > 0.0):
            raise ValueError(f"{name}: must be finite and > 0, got {v!r}")
    if not 0 <= wheel < robot.num_wheels:
        raise ValueError(f"wheel: must be in [0, {robot.num_wheels - 1}], got {wheel}")
    duty_on = amplitude_a * robot.motor_resistance_ohm / robot.supply_voltage_v
    if duty_on > 1.0:
        raise ValueError(f"amplitude_a: {amplitude_a} A needs duty {duty_on:.2f} > 1")
    world = World(FieldConfig.preset("division_b"), [RobotSpec(config=robot)], None, physics=physics)
    world.set_lifted(0, True)
    n = round(duration_s / loop_period_s)
    t = np.arange(n + 1) * loop_period_s
    y = np.zeros(n + 1)
    duty = np.zeros(robot.num_wheels)
    for k in range(n):
        on = k >= 1 if response == "step" else k == 1  # one loop period of delay, as on the board
        duty[wheel] = duty_on if on else 0.0
        world.set_duty(0, duty)
        world.step(loop_period_s)
        y[k + 1] = world.wheel_speeds_radps(0)[wheel]
    size = amplitude_a if response == "step" else amplitude_a * loop_period_s
    return t, y, size


def run_on_sim(
    robot: RobotConfig | None = None, response: str = "step", amplitude_a: float | None = None,
    loop_period_s: float = 0.001, duration_s: float = 0.15,
) -> TuningResult:
    """Measure the lifted wheel on the simulator and run the paper's fit + tangent + rules."""
    if amplitude_a is None:  # an impulse needs a large, short current to move the wheel measurably
        amplitude_a = 2.0 if response == "step" else 20.0
    t, y, size = lifted_wheel_response(robot, response=response, amplitude_a=amplitude_a,
                                       loop_period_s=loop_period_s, duration_s=duration_s)
    return run_tuning_experiment(lambda dt, dur: (t, y), dt_s=loop_period_s, duration_s=duration_s,
                                 input_amplitude=size, response_kind=response, with_dead_time=True)


def motor_board_parameters(result: TuningResult, rule: str, structure: str) -> dict[str, float]:
    """motor_boards node parameters (speed loop) from a tuning result."""
    g = result.gains[rule][structure]
    params = {"speed_kp_a_per_radps": g.kp, "speed_ki_a_per_rad": g.ki, "speed_kd_as_per_rad": g.kd}
    if g.kd > 0.0:  # filter the derivative over a fraction of the delay time
        params["speed_derivative_tau_s"] = 0.2 * result.times.delay_time_tu_s
    return params


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="tune_motor", description="Ziegler-Nichols tuning of the speed loop on the simulated lifted wheel")
    parser.add_argument("--out", default="tuning_out", help="output directory (default: tuning_out)")
    parser.add_argument("--response", choices=("step", "impulse"), default="step")
    parser.add_argument("--rule", choices=RULES, default="chr_0",
                        help="zn: Ziegler-Nichols; chr_0 / chr_20: Chien-Hrones-Reswick 0 %% / 20 %% overshoot")
    parser.add_argument("--structure", choices=("PI", "PID"), default="PI")
    parser.add_argument("--duration", type=float, default=0.15, help="recorded time [s]")
    args = parser.parse_args(argv)
    out = Path(args.out)
    result = run_on_sim(response=args.response, duration_s=args.duration)
    params = motor_board_parameters(result, args.rule, args.structure)
    yaml_path = write_gains_yaml(out / f"motor_boards_{args.rule}_{args.structure.lower()}.yaml",
                                 MOTOR_BOARDS_NODE_KEY, params)
    png_path = plot_tuning(result, out / f"tuning_fig4_{args.response}.png",
                           title=f"lifted wheel, {args.response} response: PT2 fit and inflection tangent")
    tc = motor_time_constants(RobotConfig())
    tt, fit = result.times, result.fit
    print(f"PT2 fit: K={fit.gain:.3f} (rad/s)/A, T1={fit.t1_s * 1e3:.2f} ms, T2={fit.t2_s * 1e3:.3f} ms, "
          f"dead time {fit.dead_time_s * 1e3:.2f} ms, rmse {fit.rmse:.3g}")
    print(f"tangent: Tu={tt.delay_time_tu_s * 1e3:.2f} ms, Tg={tt.balance_time_tg_s * 1e3:.2f} ms "
          f"(motor: tau_m={tc.mechanical_s * 1e3:.2f} ms, tau_e={tc.electrical_s * 1e3:.3f} ms, "
          f"K={tc.gain_radps_per_a:.3f})")
    print(f"{args.rule} {args.structure}: " + ", ".join(f"{k}={v:.4g}" for k, v in params.items()))
    print(f"wrote {yaml_path} (use with --params-file) and {png_path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
