"""The simulated world: robots (drivetrain.py), ball (ball.py), contacts (contacts.py), kicker and
light barrier (kicker.py, paper Sec. 2-3) and vision (sensors.py) behind one `World` API.

Used by the plant node (ROS shell) and by the in-process runner. Time ``t_s`` is owned by the world
and only advances in `step`. Every `step(dt_s)` is cut into ceil(dt_s * substep_hz) equal substeps
(default 20 kHz); per substep: motors + wheels + bodies, ball, then contacts. Winding temperatures
and the light barrier are updated once per step; vision frames are captured at the substep that
crosses each capture time. Deterministic for a given seed (numpy SeedSequence streams for vision,
light barrier and sensor noise). Inputs are validated: non-finite values raise ValueError, duties
out of [-1, 1] are clamped and counted, bodies placed outside the field walls raise ValueError.

Quick use::

    world = World(FieldConfig.preset("division_b"), [RobotSpec(x=-1.0)], BallState(0.0, 0.0), seed=1)
    world.set_duty(0, [0.2, 0.2, 0.2, 0.2])   # returns how many entries were clamped
    world.step(0.001)
    world.wheel_speeds_radps(0), world.motor_currents_a(0), world.poll_vision()

No rclpy import.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from erforce_interfaces.runtime.numba_support import compiled_for
from erforce_interfaces.runtime.param_schema import schema_defaults
from erforce_interfaces.wire.robot_config import FieldConfig
from erforce_sim.ball import BallBody, BallParams, BallState
from erforce_sim.contacts import (
    RobotShape,
    ball_robot,
    ball_walls,
    robot_contact_candidates,
    robot_robot,
    robot_walls,
)
from erforce_sim.drivetrain import DriveTrainCoefficients, RobotPlant, advance_robots, thermal_step
from erforce_sim.kicker import KickerPlate, beam_hits
from erforce_sim.sensors import LightBarrierParams, LightBarrierSignal, VisionFrame, VisionParams, VisionSystem
from erforce_sim.world_types import (
    EnergyBreakdown,
    KickResult,
    PhysicsParams,
    RobotSpec,
    RobotState,
    bounded,
    finite,
)

_PLANT = schema_defaults("erforce_sim", "plant")  # the plant node's defaults

MAX_BODY_SPEED_MPS = 20.0
MAX_ROBOT_YAW_RATE_RADPS = 100.0
MAX_BALL_SPIN_RADPS = 2000.0


@dataclass
class _Armed:
    speed_mps: float
    spin_ratio: float
    deadline_s: float
    angle_deg: float = 0.0


def _check_world_inputs(field_config, specs: tuple, seed) -> None:
    """World's arguments that would otherwise fail deep inside it: a clear error naming the argument."""
    if not isinstance(field_config, FieldConfig):
        raise ValueError("field_config: must be a FieldConfig")
    if not isinstance(seed, int | np.integer) or seed < 0:
        raise ValueError(f"seed: must be an int >= 0, got {seed!r}")
    for s in specs:
        if not isinstance(s, RobotSpec):
            raise ValueError(f"robots: every entry must be a RobotSpec, got {type(s).__name__}")
    ids = [(s.team, s.robot_id) for s in specs]
    if len(set(ids)) != len(ids):
        raise ValueError(f"robots: duplicate (team, robot_id) in {ids}")


class World:
    """Physics world. See the module docstring; all indices are robot list positions (0-based)."""

    def __init__(
        self,
        field_config: FieldConfig,
        robots: Sequence[RobotSpec],
        ball: BallState | None = None,
        physics: PhysicsParams | None = None,
        ball_params: BallParams | None = None,
        vision: VisionParams | None = None,
        light_barrier: LightBarrierParams | None = None,
        seed: int = _PLANT["seed"],
    ) -> None:
        self.specs: tuple[RobotSpec, ...] = tuple(robots)
        _check_world_inputs(field_config, self.specs, seed)
        self.field = field_config
        self.physics = physics or PhysicsParams()
        self.ball_params = ball_params or BallParams()
        streams = np.random.SeedSequence(int(seed)).spawn(3)
        self._sensor_rng = np.random.default_rng(streams[2])
        self.vision = VisionSystem(vision or VisionParams(), np.random.default_rng(streams[0]))
        lb_params = light_barrier or LightBarrierParams()
        lb_rng = np.random.default_rng(streams[1])
        self._half_x = field_config.wall_half_length_m
        self._half_y = field_config.wall_half_width_m
        self._t = 0.0
        self._coeff_cache: dict[float, list[tuple[float, float, float]]] = {}
        self._allocate_robot_rows()
        for s in self.specs:
            self._add_robot(s, lb_params, lb_rng)
        self._gather_robot_arrays(lb_params)
        self._rigs_changed()
        for i, s in enumerate(self.specs):
            self.place_robot(i, s.x, s.y, s.theta)
        self._ball = BallBody(self.ball_params, BallState(0.0, 0.0))
        if ball is not None:
            self.set_ball_state(ball)
        self._any_dribbler = False
        self._any_armed = False
        self._sample_light_barriers()
        self._load_kernels()

    def _allocate_robot_rows(self) -> None:
        """Every robot's state in per-robot arrays (wheels padded to the widest robot): each RobotPlant works
        on its rows, and `step` advances all contact-free robots in one compiled call."""
        self._robots: list[RobotPlant] = []
        self._shapes: list[RobotShape] = []
        self._plates: list[KickerPlate] = []
        self._coeffs: list[DriveTrainCoefficients] = []
        self._barriers: list[LightBarrierSignal] = []
        self._beam_x: list[float] = []
        self._dribbler_on: list[bool] = []
        self._kicked_out: list[bool] = []
        self._armed: list[_Armed | None] = []
        self._clamped_duties: list[int] = []
        n_robots = len(self.specs)
        width = max((s.config.num_wheels for s in self.specs), default=0)
        self._body = np.zeros((n_robots, 8))
        self._wheel_w, self._current, self._duty, self._i2, self._temp = (np.zeros((n_robots, width)) for _ in range(5))
        self.all_robots = np.arange(n_robots)  # every robot in order: set_duties' fast path knows this array
        self.all_robots.flags.writeable = False
        self._num_wheels = np.array([s.config.num_wheels for s in self.specs], dtype=np.int64)
        self._sin_a, self._cos_a = np.zeros((n_robots, width)), np.zeros((n_robots, width))
        self._rig = np.zeros(n_robots, dtype=bool)  # lifted or locked: stepped one by one (RobotPlant._advance_rig)
        self._batch_cache: dict[float, tuple[np.ndarray, np.ndarray]] = {}
        self._thermal_cache: dict[float, np.ndarray] = {}

    def _add_robot(self, s: RobotSpec, lb_params: LightBarrierParams, lb_rng: np.random.Generator) -> None:
        """The next robot's drive train, shape, kicker plate, light barrier and rows."""
        cfg = s.config
        co = DriveTrainCoefficients.from_config(
            cfg, self.physics.traction_damping_nspm, self.physics.coulomb_smoothing_radps
        )
        shape = RobotShape(cfg.robot_radius_m, cfg.dribbler_offset_m - self.ball_params.radius_m)
        if 0.5 * cfg.dribbler_width_m > shape.front_half_width_m:
            raise ValueError(
                f"robot {s.team}/{s.robot_id}: dribbler width {cfg.dribbler_width_m} m exceeds the flat front"
                f" ({2 * shape.front_half_width_m:.4f} m)"
            )
        self._coeffs.append(co)
        self._shapes.append(shape)
        self._plates.append(KickerPlate.make(s.kicker_plate, 0.5 * cfg.dribbler_width_m))
        k, n = len(self._robots), co.num_wheels
        self._sin_a[k, :n], self._cos_a[k, :n] = co.sin_a, co.cos_a
        rows = (self._body[k], self._wheel_w[k, :n], self._current[k, :n], self._duty[k, :n], self._i2[k, :n],
                self._temp[k, :n])
        self._robots.append(RobotPlant(co, 0.0, 0.0, 0.0, rows))
        self._barriers.append(LightBarrierSignal(lb_params, lb_rng))
        self._beam_x.append(shape.front_x_m + lb_params.beam_depth_m)
        self._dribbler_on.append(False)
        # The kicker's own shot leaves the running bar: the bar's grip (a held ball relaxing to the bar's velocity
        # within dribbler_time_constant_s) does not describe a ball shot past it in a few ms, and took a quarter of
        # a kick's speed and gave a chip rolling spin. Set at the kick, cleared once the ball is out of reach.
        self._kicked_out.append(False)
        self._armed.append(None)
        self._clamped_duties.append(0)

    def _gather_robot_arrays(self, lb_params: LightBarrierParams) -> None:
        """The robots' shapes, thermal constants and beams as arrays, for the compiled kernels."""
        n_robots = len(self.specs)
        self._radii = [sh.radius_m for sh in self._shapes]
        self._radii_arr = np.array(self._radii, dtype=float)
        self._front_x_arr = np.array([sh.front_x_m for sh in self._shapes], dtype=float)
        self._resistance = np.array([[c.resistance_ohm] for c in self._coeffs]).reshape(n_robots, 1)
        self._ambient = np.array([[c.ambient_c] for c in self._coeffs]).reshape(n_robots, 1)
        self._thermal_r = np.array([[c.thermal_resistance_k_per_w] for c in self._coeffs]).reshape(n_robots, 1)
        self._beam_x_arr = np.array(self._beam_x, dtype=float)
        self._beam_half_span = np.array([0.5 * s.config.dribbler_width_m for s in self.specs], dtype=float)
        self._barrier_direct = lb_params.latency_s == 0.0 and lb_params.false_flip_prob == 0.0
        self._barrier_values = np.zeros(n_robots, dtype=bool)
        # the compiled contact and beam kernels for the types they are passed (the body rows, float scalars)
        self._contacts_kernel = compiled_for(robot_contact_candidates, self._body, self._radii_arr,
                                             self._front_x_arr, *(0.0,) * 7)
        self._beam_kernel = compiled_for(beam_hits, self._body, 0.0, 0.0, 0.0, self._beam_x_arr, self._beam_half_span)

    def _load_kernels(self) -> None:
        """Load the compiled kernels now rather than in the first step, for exactly the argument types step
        passes (C-contiguous int64 rows and float64 arrays, int substep count, float times)."""
        self._advance_robots = compiled_for(
            advance_robots, np.zeros(0, dtype=np.int64), 1, 1e-4, np.zeros((0, 3)), np.zeros((0, 15)),
            self._num_wheels, self._sin_a, self._cos_a, self._duty, self._wheel_w, self._current, self._i2, self._body)
        self._thermal_step = compiled_for(thermal_step, self._temp, self._i2, self._resistance, self._ambient,
                                          self._thermal_r, np.ones((0, 1)), 1e-3)

    # ------------------------------------------------------------------ basics
    @property
    def t_s(self) -> float:
        """World time in seconds (starts at 0, advanced only by `step`)."""
        return self._t

    @property
    def num_robots(self) -> int:
        return len(self._robots)

    def _index(self, i: int) -> int:
        if not isinstance(i, int | np.integer) or isinstance(i, bool) or not 0 <= i < len(self._robots):
            raise ValueError(f"robot index must be an int in [0, {len(self._robots) - 1}], got {i!r}")
        return int(i)

    def _rigs_changed(self) -> None:
        self._free_all = np.flatnonzero(~self._rig)
        self._rig_list = np.flatnonzero(self._rig).tolist()

    def index_of(self, team: str, robot_id: int) -> int:
        """List position of the robot with this team colour and id."""
        for i, s in enumerate(self.specs):
            if s.team == team and s.robot_id == robot_id:
                return i
        raise ValueError(f"no robot {team}/{robot_id} in this world")

    # ------------------------------------------------------------------ inputs
    def set_duty(self, i: int, duty: Sequence[float] | np.ndarray) -> int:
        """Set robot i's PWM duty per wheel (held until changed).

        NaN/inf or a wrong length raise ValueError; values outside [-1, 1] are clamped. Returns the
        number of clamped entries (also accumulated in `clamped_duty_count`).
        """
        i = self._index(i)
        n = self._coeffs[i].num_wheels
        if isinstance(duty, np.ndarray) and duty.dtype == np.float64 and duty.shape == (n,):
            values = duty.tolist()
            if all(-1.0 <= v <= 1.0 for v in values):  # the usual case, in plain Python (false for NaN too)
                self._robots[i].duty[:] = values
                return 0
        try:
            arr = np.asarray(duty, dtype=float)
        except (TypeError, ValueError):
            raise ValueError(f"set_duty: robot {i}: duty must be {n} numbers, got {duty!r}") from None
        if arr.shape != (n,):
            raise ValueError(f"set_duty: robot {i}: expected {n} duties, got shape {arr.shape}")
        if not np.all(np.isfinite(arr)):
            raise ValueError(f"set_duty: robot {i}: duty must be finite, got {arr.tolist()}")
        clipped = np.clip(arr, -1.0, 1.0)
        count = int(np.count_nonzero(clipped != arr))
        self._clamped_duties[i] += count
        self._robots[i].duty[:] = clipped.tolist()
        return count

    def duty(self, i: int) -> np.ndarray:
        return np.array(self._robots[self._index(i)].duty)

    def clamped_duty_count(self, i: int) -> int:
        """Total number of duty entries clamped into [-1, 1] for robot i so far."""
        return self._clamped_duties[self._index(i)]

    def set_dribbler(self, i: int, on: bool) -> None:
        """Dribbler bar on/off: when on, a ball touching the bar is held (damped and pulled in)."""
        i = self._index(i)
        if on and not self._dribbler_on[i]:
            self._kicked_out[i] = False  # a bar started anew holds what touches it
        self._dribbler_on[i] = bool(on)
        self._any_dribbler = any(self._dribbler_on)

    def set_lifted(self, i: int, lifted: bool) -> None:
        """Test rig: robot on a stand (wheels spin freely, no traction, body held at rest)."""
        i = self._index(i)
        rb = self._robots[i]
        rb.lifted = bool(lifted)
        self._rig[i] = rb.lifted or rb.locked
        self._rigs_changed()
        if rb.lifted:
            rb.vx = rb.vy = rb.w = 0.0

    def set_wheels_locked(self, i: int, locked: bool) -> None:
        """Test rig: blocked rotors (wheel speeds held at zero)."""
        i = self._index(i)
        rb = self._robots[i]
        rb.locked = bool(locked)
        self._rig[i] = rb.lifted or rb.locked
        self._rigs_changed()
        if rb.locked:
            rb.wheel_w[:] = [0.0] * len(rb.wheel_w)

    def kick(self, i: int, speed_mps: float, spin_ratio: float | None = None, armed_for_s: float = 0.0,
             angle_deg: float = 0.0) -> KickResult:
        """Flat kick (``angle_deg`` 0) or chip with robot i at ``speed_mps`` (ball speed relative to the robot).

        Fires only when the ball touches the dribbler region (in front of the flat face, within the
        dribbler width, gap <= kick_touch_tolerance_m). Otherwise, with ``armed_for_s`` > 0, the kicker
        stays armed and fires at the first substep the ball is there, until t_s + armed_for_s.
        ``spin_ratio`` = w r / v given to the ball (None: PhysicsParams.kick_spin_ratio; <0 backspin).
        Speeds above kick_max_speed_mps are clamped (reported in the result); speed 0 disarms.
        A chip (``angle_deg`` in (0, 90): the launch's elevation, as the SSL simulation protocol's
        kick_angle) leaves the chip plate along the robot's heading, ``speed_mps`` split into
        ``cos`` along the carpet and ``sin`` upwards, without spin (the plate lifts the ball through its
        centre; the carpet spins it up at the first bounce, erforce_sim.ball).
        """
        i = self._index(i)
        speed = finite("kick: speed_mps", speed_mps)
        if speed < 0.0:
            raise ValueError(f"kick: speed_mps must be >= 0, got {speed}")
        spin = self.physics.kick_spin_ratio if spin_ratio is None else finite("kick: spin_ratio", spin_ratio)
        if not -1.0 <= spin <= 1.0:
            raise ValueError(f"kick: spin_ratio must be in [-1, 1], got {spin}")
        armed_for = finite("kick: armed_for_s", armed_for_s)
        if armed_for < 0.0:
            raise ValueError(f"kick: armed_for_s must be >= 0, got {armed_for}")
        angle = finite("kick: angle_deg", angle_deg)
        if not 0.0 <= angle < 90.0:
            raise ValueError(f"kick: angle_deg must be in [0, 90), got {angle}")
        clamped = speed > self.physics.kick_max_speed_mps
        speed = min(speed, self.physics.kick_max_speed_mps)
        if speed == 0.0:
            self._armed[i] = None
            self._any_armed = any(a is not None for a in self._armed)
            return KickResult(False, False, 0.0, clamped)
        fired = self._try_kick(i, speed, spin, angle)
        if fired is not None:
            self._armed[i] = None
            self._any_armed = any(a is not None for a in self._armed)
            return KickResult(True, False, speed, clamped, fired[0], fired[1])
        if armed_for > 0.0:
            self._armed[i] = _Armed(speed, spin, self._t + armed_for, angle)
            self._any_armed = True
            return KickResult(False, True, speed, clamped)
        return KickResult(False, False, speed, clamped)

    def _ball_in_robot_frame(self, i: int) -> tuple[float, float]:
        rb, ball = self._robots[i], self._ball
        dx, dy = ball.x - rb.x, ball.y - rb.y
        return rb.cos_th * dx + rb.sin_th * dy, -rb.sin_th * dx + rb.cos_th * dy

    def ball_in_dribbler(self, i: int) -> bool:
        """True when the ball touches robot i's dribbler region (where a kick would act)."""
        i = self._index(i)
        px, py = self._ball_in_robot_frame(i)
        return self._in_dribbler(i, px, py)

    def _in_dribbler(self, i: int, px: float, py: float) -> bool:
        fx = self._shapes[i].front_x_m
        gap = px - fx - self._ball.radius
        return (
            px > fx
            and gap <= self.physics.kick_touch_tolerance_m
            and abs(py) <= 0.5 * self.specs[i].config.dribbler_width_m
            and self._ball.z < self._ball.radius  # a ball in the air passes above the dribbler bar
        )

    def _in_kick_reach(self, i: int, px: float, py: float) -> bool:
        """The plate's stroke reaches a touching ball and every ball on the carpet the light barrier's beam crosses
        (the firmware kicks when the beam is broken): else a ball at rest between the two is seen and never kicked."""
        if self._in_dribbler(i, px, py):
            return True
        fx = self._shapes[i].front_x_m
        return (fx < px < self._beam_x[i] + self._ball.radius and abs(py) <= 0.5 * self.specs[i].config.dribbler_width_m
                and self._ball.z < self._ball.radius)

    def _try_kick(self, i: int, speed: float, spin: float, angle_deg: float = 0.0) -> tuple[float, float] | None:
        px, py = self._ball_in_robot_frame(i)
        if not self._in_kick_reach(i, px, py):
            return None
        rb, ball = self._robots[i], self._ball
        if angle_deg > 0.0:  # the chip plate: along the heading, no plunger tilt, no spin
            dev, spin = 0.0, 0.0
            vz, speed = speed * math.sin(math.radians(angle_deg)), speed * math.cos(math.radians(angle_deg))
        else:
            dev = self._plates[i].deviation_rad(py, ball.radius, self.physics.kick_tilt_compliance_rad_per_m)
            vz = 0.0
        ang = rb.theta + dev
        kx, ky = speed * math.cos(ang), speed * math.sin(ang)
        # contact point on the plate, field frame, relative to the robot centre
        fx = self._shapes[i].front_x_m
        qx = rb.cos_th * fx - rb.sin_th * py
        qy = rb.sin_th * fx + rb.cos_th * py
        nvx = rb.vx - rb.w * qy + kx
        nvy = rb.vy + rb.w * qx + ky
        jx, jy = ball.mass * (nvx - ball.vx), ball.mass * (nvy - ball.vy)  # impulse on the ball
        ball.launch(nvx, nvy, vz)
        self._kicked_out[i] = True
        ball.wx = -spin * ky / ball.radius
        ball.wy = spin * kx / ball.radius
        if not rb.lifted:  # recoil
            k = rb.k
            rb.vx -= jx / k.mass_kg
            rb.vy -= jy / k.mass_kg
            rb.w -= (qx * jy - qy * jx) / k.inertia_kgm2
        return py, dev

    def place_robot(
        self, i: int, x: float, y: float, theta: float, vx: float = 0.0, vy: float = 0.0, w: float = 0.0
    ) -> None:
        """Teleport robot i (field frame); wheels roll without slip at the given velocity, currents 0."""
        i = self._index(i)
        x, y = finite("place_robot: x", x), finite("place_robot: y", y)
        theta = math.remainder(finite("place_robot: theta", theta), 2.0 * math.pi)
        vx = bounded("place_robot: vx", vx, MAX_BODY_SPEED_MPS)
        vy = bounded("place_robot: vy", vy, MAX_BODY_SPEED_MPS)
        w = bounded("place_robot: w", w, MAX_ROBOT_YAW_RATE_RADPS)
        rad = self.specs[i].config.robot_radius_m
        lim_x, lim_y = self._half_x - rad, self._half_y - rad
        if abs(x) > lim_x or abs(y) > lim_y:
            raise ValueError(
                f"place_robot: robot {i} at ({x:.3f}, {y:.3f}) lies outside the field walls; its centre must"
                f" satisfy |x| <= {lim_x:.3f} and |y| <= {lim_y:.3f} m"
            )
        self._robots[i].set_pose_velocity(x, y, theta, vx, vy, 0.0 if self._robots[i].lifted else w)

    def place_ball(
        self, x: float, y: float, vx: float = 0.0, vy: float = 0.0, spin_ratio: float = 1.0, wz: float = 0.0
    ) -> None:
        """Teleport the ball. spin_ratio = w r / v about the rolling axis: 1 rolls, 0 slides, <0 backspin."""
        vx = bounded("place_ball: vx", vx, MAX_BODY_SPEED_MPS)
        vy = bounded("place_ball: vy", vy, MAX_BODY_SPEED_MPS)
        s = finite("place_ball: spin_ratio", spin_ratio)
        if not -1.0 <= s <= 1.0:
            raise ValueError(f"place_ball: spin_ratio must be in [-1, 1], got {s}")
        r = self.ball_params.radius_m
        self.set_ball_state(
            BallState(
                finite("place_ball: x", x),
                finite("place_ball: y", y),
                vx,
                vy,
                -s * vy / r,
                s * vx / r,
                finite("place_ball: wz", wz),
            )
        )

    def set_ball_state(self, state: BallState) -> None:
        """Teleport the ball with a full state (position, velocity, angular velocity)."""
        if not isinstance(state, BallState):
            raise ValueError("set_ball_state: expected a BallState")
        r = self.ball_params.radius_m
        lim_x, lim_y = self._half_x - r, self._half_y - r
        if abs(state.x) > lim_x or abs(state.y) > lim_y:
            raise ValueError(
                f"place_ball: ball at ({state.x:.3f}, {state.y:.3f}) lies outside the field walls; its centre"
                f" must satisfy |x| <= {lim_x:.3f} and |y| <= {lim_y:.3f} m"
            )
        bounded("ball speed", state.speed_mps, MAX_BODY_SPEED_MPS)
        for name in ("wx", "wy", "wz"):
            bounded(f"ball {name}", getattr(state, name), MAX_BALL_SPIN_RADPS)
        self._ball.set_state(state)

    # ------------------------------------------------------------------ stepping
    def _substep_coeffs(self, h: float) -> list[tuple[float, float, float]]:
        co = self._coeff_cache.get(h)
        if co is None:
            co = [c.for_substep(h) for c in self._coeffs]
            if len(self._coeff_cache) > 64:
                self._coeff_cache.clear()
            self._coeff_cache[h] = co
        return co

    def step(self, dt_s: float) -> None:
        """Advance the world by dt_s (0 < dt_s <= max_step_s) in substeps of <= 1/substep_hz.

        Bodies that cannot touch anything within dt_s (conservative distance check with bounded
        acceleration) run their substeps in one tight loop; the others are interleaved substep by
        substep with their contacts. Every body is integrated with the same substep h, and the step is
        split at vision capture times so frames see all bodies at the same instant.
        """
        dt = finite("step: dt_s", dt_s)
        if dt <= 0.0:
            raise ValueError(f"step: dt_s must be > 0 (time cannot go backwards), got {dt}")
        if dt > self.physics.max_step_s:
            raise ValueError(f"step: dt_s must be <= max_step_s = {self.physics.max_step_s}, got {dt}")
        n = max(1, math.ceil(dt * self.physics.substep_hz - 1e-9))
        h = dt / n
        coeffs = self._substep_coeffs(h)
        factors, consts = self._batch_coeffs(h, coeffs)
        t0 = self._t
        ball_wall, robot_wall, robot_pairs, ball_robots = self._contact_candidates(dt)
        if robot_wall or robot_pairs or ball_robots:
            involved = set(robot_wall) | set(ball_robots)
            for a, b in robot_pairs:
                involved.update((a, b))
            free_mask = ~self._rig
            free_mask[list(involved)] = False
            free = np.flatnonzero(free_mask)
        else:  # the common case: nobody near anything
            involved = set()
            free = self._free_all
        ball_involved = ball_wall or bool(ball_robots)
        free_rigs = [(self._robots[i], coeffs[i]) for i in self._rig_list if i not in involved]
        busy = [(i, self._robots[i], coeffs[i]) for i in sorted(involved)]
        ball = self._ball
        done = 0
        while done < n:
            # run up to the substep that crosses the next vision capture time
            j_cap = math.ceil((self.vision.next_capture_s - t0) / h - 1e-9)
            end = n if j_cap > n else max(j_cap, done + 1)
            m = end - done
            if free.size:
                self._advance_robots(free, m, h, factors, consts, self._num_wheels, self._sin_a, self._cos_a,
                                     self._duty, self._wheel_w, self._current, self._i2, self._body)
            for rb, (decay, mean_factor, c_eff) in free_rigs:
                rb.advance(m, h, decay, mean_factor, c_eff)
            if not ball_involved:
                ball.advance(m, h)
            if busy or ball_involved:
                self._substeps_with_contacts(
                    m, h, t0 + done * h, busy, ball_involved, ball_wall, robot_wall, robot_pairs, ball_robots
                )
            done = end
            if t0 + done * h >= self.vision.next_capture_s - 1e-12:
                self._capture(t0 + done * h)
        self._t = t0 + dt
        if self._any_armed:
            self._armed = [a if a is not None and a.deadline_s >= self._t else None for a in self._armed]
            self._any_armed = any(a is not None for a in self._armed)
        self._update_temperatures(dt)
        self._sample_light_barriers()

    def _batch_coeffs(self, h: float, coeffs: list[tuple[float, float, float]]) -> tuple[np.ndarray, np.ndarray]:
        """Per robot (decay, mean factor, c_eff) and RobotPlant.substep_constants for substep h, as arrays."""
        cached = self._batch_cache.get(h)
        if cached is None:
            factors = np.array(coeffs, dtype=float).reshape(len(self._robots), 3)
            consts = np.array([rb.substep_constants(h) for rb in self._robots], dtype=float).reshape(
                len(self._robots), 15)
            if len(self._batch_cache) > 64:
                self._batch_cache.clear()
            cached = self._batch_cache[h] = (factors, consts)
        return cached

    def _update_temperatures(self, dt: float) -> None:
        """RobotPlant.update_temperature for every robot at once (the same operations per wheel)."""
        decay = self._thermal_cache.get(dt)
        if decay is None:
            decay = np.array([[math.exp(-dt / c.thermal_tau_s)] for c in self._coeffs]).reshape(len(self._coeffs), 1)
            if len(self._thermal_cache) > 64:
                self._thermal_cache.clear()
            self._thermal_cache[dt] = decay
        self._thermal_step(self._temp, self._i2, self._resistance, self._ambient, self._thermal_r, decay, dt)

    def _contact_candidates(self, dt: float) -> tuple[bool, list[int], list[tuple[int, int]], list[int]]:
        """Contacts possible within dt: (ball-wall, robots near a wall, robot pairs, robots near the ball)."""
        margin = 2e-3 + self.physics.kick_touch_tolerance_m + 10.0 * dt * dt
        ball = self._ball
        bspeed = math.hypot(ball.vx, ball.vy)
        reach_b = ball.radius + bspeed * dt + margin
        ball_wall = abs(ball.x) + reach_b >= self._half_x or abs(ball.y) + reach_b >= self._half_y
        if not self._robots:
            return ball_wall, [], [], []
        wall, near, pairs, any_contact = self._contacts_kernel(
            self._body, self._radii_arr, self._front_x_arr, float(self._half_x), float(self._half_y), margin, dt,
            float(ball.x), float(ball.y), reach_b)
        if not any_contact:
            return ball_wall, [], [], []
        return (ball_wall, np.flatnonzero(wall).tolist(), [(int(a), int(b)) for a, b in pairs],
                np.flatnonzero(near).tolist())

    def _substeps_with_contacts(
        self,
        m: int,
        h: float,
        t_start: float,
        busy: list,
        ball_involved: bool,
        ball_wall: bool,
        robot_wall: list[int],
        robot_pairs: list[tuple[int, int]],
        ball_robots: list[int],
    ) -> None:
        robots, shapes, radii = self._robots, self._shapes, self._radii
        ball = self._ball
        cp = self.physics.contacts
        hx, hy = self._half_x, self._half_y
        for j in range(m):
            for _, rb, (decay, mean_factor, c_eff) in busy:
                rb.advance(1, h, decay, mean_factor, c_eff)
            if ball_involved:
                ball.advance(1, h)
            if ball_wall:
                ball_walls(ball, hx, hy, cp)
            for a in robot_wall:
                robot_walls(robots[a], radii[a], hx, hy, cp)
            for a, b in robot_pairs:
                robot_robot(robots[a], radii[a], robots[b], radii[b], cp)
            for a in ball_robots:
                ball_robot(ball, robots[a], shapes[a], cp)
            if ball_robots:
                if self._any_dribbler:
                    self._dribble(h)
                if self._any_armed:
                    self._fire_armed(t_start + (j + 1) * h)

    def _capture(self, t: float) -> None:
        self.vision.capture(
            t,
            (self._ball.x, self._ball.y),
            [(s.team, s.robot_id, rb.x, rb.y, rb.theta) for s, rb in zip(self.specs, self._robots, strict=True)],
            self._ball.z,
        )

    def _fire_armed(self, t: float) -> None:
        for i, a in enumerate(self._armed):
            if a is None:
                continue
            if t > a.deadline_s:
                self._armed[i] = None
            elif self._try_kick(i, a.speed_mps, a.spin_ratio, a.angle_deg) is not None:
                self._armed[i] = None
        self._any_armed = any(a is not None for a in self._armed)

    def _dribble(self, h: float) -> None:
        ball = self._ball
        alpha = 1.0 - math.exp(-h / self.physics.dribbler_time_constant_s)
        for i, on in enumerate(self._dribbler_on):
            if not on:
                continue
            px, py = self._ball_in_robot_frame(i)
            if not self._in_dribbler(i, px, py):
                self._kicked_out[i] = False
                continue
            if self._kicked_out[i]:
                continue
            rb = self._robots[i]
            qx = rb.cos_th * px - rb.sin_th * py
            qy = rb.sin_th * px + rb.cos_th * py
            # the bar's velocity at the ball centre, plus a pull towards the robot
            tvx = rb.vx - rb.w * qy - self.physics.dribbler_pull_mps2 * h * rb.cos_th
            tvy = rb.vy + rb.w * qx - self.physics.dribbler_pull_mps2 * h * rb.sin_th
            ball.vx += (tvx - ball.vx) * alpha
            ball.vy += (tvy - ball.vy) * alpha
            ball.wx, ball.wy = -ball.vy / ball.radius, ball.vx / ball.radius
            ball.at_rest = False
            break

    def _sample_light_barriers(self) -> None:
        if not self._robots:
            return
        ball = self._ball
        hits = self._beam_kernel(self._body, float(ball.x), float(ball.y), float(ball.radius), self._beam_x_arr,
                                 self._beam_half_span)
        if ball.z >= ball.radius:  # the beam runs at a resting ball's centre: a ball this high passes above it
            hits = np.zeros_like(hits)
        if self._barrier_direct:  # no latency, no false flips: the output is the beam itself
            self._barrier_values[:] = hits
            return
        for i, lb in enumerate(self._barriers):
            lb.sample(self._t, bool(hits[i]))
            self._barrier_values[i] = lb.value

    # ------------------------------------------------------------------ sensors
    def wheel_speeds_radps(self, i: int) -> np.ndarray:
        """Wheel speeds as the motor boards measure them (rad/s at the wheel, optional noise)."""
        rb = self._robots[self._index(i)]
        out = np.array(rb.wheel_w)
        if self.physics.wheel_speed_noise_radps > 0.0:
            out += self._sensor_rng.normal(0.0, self.physics.wheel_speed_noise_radps, out.shape)
        return out

    def motor_currents_a(self, i: int) -> np.ndarray:
        """Motor winding currents (A, instantaneous at t_s, optional noise)."""
        rb = self._robots[self._index(i)]
        out = np.array(rb.current)
        if self.physics.current_noise_a > 0.0:
            out += self._sensor_rng.normal(0.0, self.physics.current_noise_a, out.shape)
        return out

    def wheel_sensors(self, robots: Sequence[int] | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(wheel speeds, currents) of ``robots`` as rows (len(robots), wheels): what `wheel_speeds_radps` and
        `motor_currents_a` give, called robot after robot (the same noise draws in the same order)."""
        robots = np.asarray(robots, dtype=np.int64)
        speeds, currents = self._wheel_w[robots], self._current[robots]
        noise_w, noise_i = self.physics.wheel_speed_noise_radps, self.physics.current_noise_a
        if noise_w > 0.0 or noise_i > 0.0:
            for row, i in enumerate(robots):
                n = self._num_wheels[i]
                if noise_w > 0.0:
                    speeds[row, :n] += self._sensor_rng.normal(0.0, noise_w, n)
                if noise_i > 0.0:
                    currents[row, :n] += self._sensor_rng.normal(0.0, noise_i, n)
        return speeds, currents

    def set_duties(self, robots: Sequence[int] | np.ndarray, duties: np.ndarray) -> int:
        """`set_duty` for many robots: duties (len(robots), wheels); returns the number of clamped entries."""
        if (robots is self.all_robots and type(duties) is np.ndarray and duties.shape == self._duty.shape
                and np.abs(duties).max() <= 1.0):  # every robot in order, all in range (False for NaN): a copy
            self._duty[...] = duties
            return 0
        robots = np.asarray(robots, dtype=np.int64)
        arr = np.asarray(duties, dtype=float)
        if robots.ndim != 1 or arr.shape != (robots.shape[0], self._duty.shape[1]):
            raise ValueError(f"set_duties: expected duties of shape {(robots.shape[0], self._duty.shape[1])}, "
                             f"got {arr.shape}")
        if not np.isfinite(arr).all():
            raise ValueError("set_duties: duties must be finite")
        if robots.size and not 0 <= robots.min() <= robots.max() < len(self._robots):
            raise ValueError(f"set_duties: robot indices must be in [0, {len(self._robots) - 1}]")
        clipped = np.minimum(np.maximum(arr, -1.0), 1.0)
        total = 0
        if np.any(clipped != arr):
            for row, i in enumerate(robots):
                count = int(np.count_nonzero(clipped[row] != arr[row]))
                self._clamped_duties[i] += count
                total += count
        self._duty[robots] = clipped
        return total

    def winding_temperature_c(self, i: int) -> np.ndarray:
        return np.array(self._robots[self._index(i)].temp_c)

    def light_barrier(self, i: int) -> bool:
        """Robot i's light barrier output (beam interrupted by the ball), with latency and false flips."""
        return bool(self._barrier_values[self._index(i)])

    def light_barriers(self) -> np.ndarray:
        """Every robot's `light_barrier` output (a copy, bool per robot)."""
        return self._barrier_values.copy()

    def poll_vision(self) -> list[VisionFrame]:
        """Vision frames released by now (t_s), oldest first; each frame is returned once."""
        return self.vision.poll(self._t)

    # ------------------------------------------------------------------ ground truth
    def ball_state(self) -> BallState:
        return self._ball.state()

    def ball_slip_mps(self) -> float:
        """Speed of the ball's contact point on the carpet (0 while rolling)."""
        return math.hypot(*self._ball.slip_mps())

    def robot_state(self, i: int) -> RobotState:
        rb = self._robots[self._index(i)]
        return RobotState(
            rb.x, rb.y, rb.theta, rb.vx, rb.vy, rb.w, tuple(rb.wheel_w), tuple(rb.current), tuple(rb.temp_c)
        )

    def energy(self) -> EnergyBreakdown:
        """Kinetic + magnetic energy now; without inputs (duty 0, no kick/dribbler) it never increases."""
        bodies = wheels = magnetic = 0.0
        for rb in self._robots:
            k = rb.k
            bodies += 0.5 * k.mass_kg * (rb.vx**2 + rb.vy**2) + 0.5 * k.inertia_kgm2 * rb.w**2
            wheels += 0.5 * k.wheel_inertia_total_kgm2 * sum(ww * ww for ww in rb.wheel_w)
            magnetic += rb.magnetic_energy_j()
        return EnergyBreakdown(bodies, wheels, magnetic, self._ball.kinetic_energy_j())

    def all_finite(self) -> bool:
        """True when every state variable is finite (used by the property tests and the plant's every tick)."""
        b = self._ball
        if not all(math.isfinite(v) for v in (b.x, b.y, b.vx, b.vy, b.wx, b.wy, b.wz, self._t)):
            return False
        # every robot's state lives in these rows (RobotPlant works on them); padding wheels stay 0
        return all(np.isfinite(a).all() for a in (self._body, self._wheel_w, self._current, self._temp))


