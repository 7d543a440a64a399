"""The ball predictor's per-frame work (paper Sec. 5 in the loop) as one object with no ROS.

``BallPredictor`` serves a team of robots. Each vision ball frame (``ball_frame``) runs the ball
tracker (tracking.BallTracker: v_shoot, phase, ricochets) and one robotTimeToBall run for every robot
seen within ``robot_timeout_s``, after the reaction time (catch_time.catch_after_reaction); each robot
pose (``robot_frame``) feeds that robot's RobotTracker. It owns every per-frame decision: vision outside
the field refused, what a new time line resets (the caller judges stamps by
erforce_interfaces.wire.stamps.StampFilter and passes ``restart``), robot freshness and extrapolation to the
frame's stamp, "no catch" as CATCH_TIME_NEVER, and the ball model in use: the configured one, an online
fit (identification.ShotAccumulator, in a worker thread) once its errors are small, or the SSL geometry's
(``set_vision_geometry``, while ``use_vision_geometry``; no vision is answered before it arrives when the
configured field is None).

Chipped balls: given the camera of each sighting (``ball_frame``'s ``camera_m``, other cameras' sightings of
the same instant through ``ball_sighting``), a chip detector beside the ball filter (chip_tracking.ChipDetector)
judges each kick the filter sees; a chip it finds is the frame's ``chip`` (chip_model.ChipTrajectory at the
frame's stamp, with ``z_m`` and ``vz_mps``, its state's covariance ``chip_covariance``; phase "chip", "hopping"
after its first touchdown) until it rolls, when the filter takes the ball over from the chip's roll.

The ball_predictor node converts messages and publishes what this object answers; the in-process scenes
and the bench run the same object, so the catcher is tuned on the code that runs.

>>> from erforce_ball_model.predictor import BallPredictor, PredictorConfig
>>> predictor = BallPredictor(PredictorConfig(num_robots=1))
>>> predictor.robot_frame(0, 1.0, 1.0, 0.0, math.pi) is not None
True
>>> for k in range(8):  # a ball at 2 m/s towards robot_0 (taken for a fresh kick), 100 Hz vision
...     frame = predictor.ball_frame(1.0 + 0.01 * k, -2.0 + 0.02 * k, 0.0)
>>> frame.catch_robots, frame.phase
([0], 'sliding')
>>> round(frame.catch_times_s[0], 2)  # seconds from the frame's stamp, the reaction time included
1.21

No rclpy import.
"""

from __future__ import annotations

import concurrent.futures
import dataclasses
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from dataclasses import field as _default

import numpy as np

from erforce_ball_model.ball_model import BallModelParams, BallPhase, BallTrajectory, ChipParams
from erforce_ball_model.catch_time import ROBOT_REACTION_S, CatchKind, CatchSearch, RobotLimits, catch_after_reaction
from erforce_ball_model.chip_model import PHASE_CHIP, PHASE_HOPPING, ChipTrajectory
from erforce_ball_model.chip_tracking import ChipDetector, ChipDetectorConfig
from erforce_ball_model.identification import FitResult, ShotAccumulator, fit_shots
from erforce_ball_model.tracking import BallTracker, RobotTracker, TrackerConfig, UpdateStatus
from erforce_ball_model.walls import Walls
from erforce_interfaces.runtime.param_schema import schema_defaults
from erforce_interfaces.wire.robot_config import (
    BALL_CHIP_DAMPING_NAMES,
    BALL_WALL_RESTITUTION,
    FieldConfig,
    RobotConfig,
)

_DEFAULTS = schema_defaults("erforce_ball_model", "ball_predictor")

__all__ = ["CATCH_TIME_NEVER", "MODEL_ROWS", "PHASE_NAMES", "BallFrame", "BallPredictor", "FrameTimes",
           "PredictorConfig", "chip_covariances"]

CATCH_TIME_NEVER = -1.0  # the catch time that means "no catch" (erforce_interfaces.wire.contract says the same)
MODEL_ROWS = ("in_use", "fit", "std_error")  # the rows of model_rows (erforce_interfaces.wire.contract says the same)
PHASE_NAMES = {BallPhase.SLIDING: "sliding", BallPhase.ROLLING: "rolling", BallPhase.STOPPED: "stopped"}
_NEVER = int(CatchKind.NEVER)


@dataclass(frozen=True, eq=False)
class PredictorConfig:
    """Everything the predictor computes with. ``facing_fixed`` / ``facing_rad`` / ``receiving``: one value for
    all robots (shape () or (1,)) or one per robot; fixed False faces against the ball's motion; ``receiving``
    False: the robot intercepts a chip with its body rather than receive it (catch_time, ChipParams' heights)."""

    num_robots: int = 1
    model: BallModelParams = _default(default_factory=BallModelParams)
    tracker: TrackerConfig = _default(default_factory=TrackerConfig)
    # None: the world's SSL geometry (set_vision_geometry); until it arrives no frame is judged or answered
    field: FieldConfig | None = _default(default_factory=lambda: FieldConfig.preset("division_b"))
    # the catch search ends where the ball crosses the field lines extended by this
    field_margin_m: float = _DEFAULTS["field_margin_m"]
    # observations farther outside the field lines are rejected
    vision_reject_margin_m: float = _DEFAULTS["vision_reject_margin_m"]
    wall_restitution: float = BALL_WALL_RESTITUTION  # the predicted path reflects off the field's wall by this
    limits: RobotLimits = _default(default_factory=RobotLimits)
    reaction_s: float = ROBOT_REACTION_S  # a robot acts on a prediction this much later
    facing_fixed: np.ndarray = _default(default_factory=lambda: np.zeros(1, dtype=bool))
    facing_rad: np.ndarray = _default(default_factory=lambda: np.full(1, math.pi))
    receiving: np.ndarray = _default(default_factory=lambda: np.ones(1, dtype=bool))
    dribbler_offset_m: float = RobotConfig().dribbler_offset_m
    # a slower filtered ball is reported stopped and faced from the robot
    rest_speed_mps: float = _DEFAULTS["rest_speed_mps"]
    grid_step_s: float = _DEFAULTS["grid_step_s"]
    # a robot not seen for this long (vision stamps) gets no catch answer
    robot_timeout_s: float = _DEFAULTS["robot_timeout_s"]
    online_identification: bool = _DEFAULTS["online_identification"]
    ident_min_shots: int = _DEFAULTS["ident_min_shots"]
    ident_max_std: tuple[float, float, float] = (0.1, 0.02, 0.03)  # a_slide, a_roll, c_switch
    timing_log_every: int = _DEFAULTS["timing_log_every"]  # the node's timing log (not used here)
    # SSL geometry's field and ball model replace field and model
    use_vision_geometry: bool = _DEFAULTS["use_vision_geometry"]
    chip: ChipParams = _default(default_factory=ChipParams)  # a chipped ball's hops
    chip_detector: ChipDetectorConfig = _default(default_factory=ChipDetectorConfig)

    def __post_init__(self) -> None:
        n = self.num_robots
        if not (isinstance(n, int) and n >= 1):
            raise ValueError(f"num_robots: must be an int >= 1, got {n!r}")
        for name, dtype in (("facing_fixed", bool), ("facing_rad", float), ("receiving", bool)):
            values = np.array(getattr(self, name), dtype=dtype).reshape(-1)
            if values.size == 1:
                values = np.repeat(values, n)
            if values.size != n:
                raise ValueError(f"{name}: need one value or one per robot ({n}), got {values.size}")
            values.setflags(write=False)
            object.__setattr__(self, name, values)
        if not (np.isfinite(self.facing_rad).all() and (np.abs(self.facing_rad) <= 2.0 * math.pi).all()):
            raise ValueError(f"facing_rad: must be finite angles in [-2 pi, 2 pi], got {self.facing_rad.tolist()}")
        for name in ("field_margin_m", "vision_reject_margin_m", "reaction_s", "rest_speed_mps", "robot_timeout_s"):
            if not math.isfinite(getattr(self, name)):
                raise ValueError(f"{name}: must be finite, got {getattr(self, name)!r}")
        if self.reaction_s < 0.0:
            raise ValueError(f"reaction_s: must be >= 0, got {self.reaction_s!r}")
        if self.field is None and not self.use_vision_geometry:
            raise ValueError("field: from SSL geometry needs use_vision_geometry")
        if not 0.0 <= self.wall_restitution <= 1.0:
            raise ValueError(f"wall_restitution: must be in [0, 1], got {self.wall_restitution!r}")


@dataclass(frozen=True, eq=False, slots=True)
class BallFrame:
    """The answer to one accepted ball observation. Catch times count from ``t_s`` (the observation's
    stamp) and include the reaction time; CATCH_TIME_NEVER (and no point) when the ball leaves the
    field first. ``catch_robots`` are the robots fresh at ``t_s``, in order."""

    t_s: float
    xy_m: tuple[float, float]  # the observation
    status: UpdateStatus
    trajectory: BallTrajectory  # the ball at t_s
    phase: str  # unknown (first frame) | sliding | rolling | stopped | chip | hopping
    uncertain: bool
    # the ball filter's variance of x and of y [m^2], of vx and of vy [(m/s)^2] at t_s
    position_variance_m2: float
    velocity_variance_m2ps2: float
    catch_robots: list[int]
    catch_times_s: list[float]
    catch_points_m: list[tuple[float, float] | None]
    # a chipped ball at t_s, from its detection until it rolls (then the flat filter's trajectory is the ball)
    chip: ChipTrajectory | None = None
    # the covariance (6, 6) of the chip's (x, y, z, vx, vy, vz) at t_s (ChipDetector.state_covariance_at); None
    # without a chip or where its fit does not determine one
    chip_covariance: np.ndarray | None = None

    @property
    def z_m(self) -> float:
        """Height of the ball's centre above its resting height [m] (0 on the ground)."""
        return 0.0 if self.chip is None else float(self.chip.position_m[2])

    @property
    def vz_mps(self) -> float:
        """Vertical speed [m/s] (0 on the ground)."""
        return 0.0 if self.chip is None else float(self.chip.velocity_mps[2])

    @property
    def z_std_m(self) -> float:
        """The standard error of ``z_m`` [m] (0 on the ground; inf for a chip whose fit does not determine it)."""
        if self.chip is None:
            return 0.0
        return math.inf if self.chip_covariance is None else math.sqrt(max(float(self.chip_covariance[2, 2]), 0.0))

    @property
    def stop_point_m(self) -> tuple[float, float]:
        """Where the ball comes to rest, inside the field's wall (the trajectory reflects off it; a chip's: where
        its roll ends)."""
        x, y = (self.trajectory if self.chip is None else self.chip).stop_point.tolist()
        return x, y


# the standard error [m, m/s] a chip's state is given when its fit does not determine one: the field's size
_UNKNOWN_STD = 10.0


def chip_covariances(frame: BallFrame) -> tuple[np.ndarray, np.ndarray]:
    """What /ball/state carries of a chip's uncertainty: the covariance (3, 3) of (x, y, z) and of (vx, vy, vz) at
    the frame (its ``chip_covariance``; where the fit determines none, the filter's position variance on x and y and
    ``_UNKNOWN_STD`` squared for the rest: finite, and saying "unknown").

    >>> frame = BallFrame(0.0, (0.0, 0.0), None, None, "chip", False, 4e-6, 0.01, [], [], [], None, np.diag([1e-6] * 6))
    >>> xyz, vxyz = chip_covariances(frame)
    >>> np.diag(xyz).tolist(), float(vxyz[2, 2])
    ([1e-06, 1e-06, 1e-06], 1e-06)
    >>> np.diag(chip_covariances(dataclasses.replace(frame, chip_covariance=None))[0]).tolist()
    [4e-06, 4e-06, 100.0]
    """
    cov = frame.chip_covariance
    if cov is None or not np.isfinite(cov).all() or (np.diag(cov) < 0.0).any():
        unknown = _UNKNOWN_STD**2
        return np.diag([frame.position_variance_m2, frame.position_variance_m2, unknown]), np.eye(3) * unknown
    return cov[:3, :3].copy(), cov[3:, 3:].copy()


def _ignore(*_args) -> None:
    return None


class BallPredictor:
    """Ball and robot tracking plus robotTimeToBall for a team (module docstring).

    ``warn(key, text)`` receives what was rejected or went wrong (``key`` groups repeats, for a
    throttled log); ``info(text)`` what changed (an accepted fit). Fits run in a
    worker thread and are collected by ``identify``; ``close`` stops it.
    """

    def __init__(self, config: PredictorConfig, *, warn: Callable[[str, str], None] = _ignore,
                 info: Callable[[str], None] = _ignore, kernels: str = "now") -> None:
        self._warn, self._info = warn, info
        self._kernels = kernels  # CatchSearch's: "background" lets a node answer before numba is loaded
        self.config: PredictorConfig | None = None  # in effect: SSL geometry's field and model applied
        self._configured: PredictorConfig | None = None  # as given to configure
        self._vision_field: FieldConfig | None = None  # the newest SSL geometry, kept also while not used
        self._vision_model: BallModelParams | None = None
        self._vision_chip: dict[str, float] | None = None  # SSL geometry's chip dampings (ChipParams' names)
        self.last_fit: FitResult | None = None
        self.waiting_frames = 0  # vision dropped while the field was not known (config.field None)
        self._ball: BallTracker | None = None
        self._t_ball_s: float | None = None  # the newest ball frame's stamp the filter took (held back or not)
        self._search: CatchSearch | None = None
        self._shots: ShotAccumulator | None = None
        self._fitted_shot = None  # the newest shot a fit was started with
        self._fit_pool: concurrent.futures.ThreadPoolExecutor | None = None
        self._fit_future: concurrent.futures.Future | None = None
        n = config.num_robots
        self._robots: list[RobotTracker | None] = [None] * n
        # Each tracker's state after its last accepted pose, (t_s, x, y, vx, vy) (NaN stamp: not seen
        # yet), and the velocities as the array the catch search takes.
        self._robot_states = [(math.nan, 0.0, 0.0, 0.0, 0.0)] * n
        self._robot_vel_mps = np.zeros((n, 2))
        self.configure(config)

    # ------------------------------------------------------------------ configuration
    def configure(self, config: PredictorConfig) -> bool:
        """Apply a new configuration (the number of robots is fixed); True when the model in use changed.

        A changed model replaces the model in use, even an identified one. A changed tracker
        configuration restarts the ball filter (and the shot collection). With
        ``use_vision_geometry`` the field and models of SSL geometry, once set, take the place of
        ``config.field``, ``config.model`` and the dampings of ``config.chip``.
        """
        old = self.config
        if old is not None and config.num_robots != old.num_robots:
            raise ValueError(f"num_robots is fixed at {old.num_robots}, got {config.num_robots}")
        self._configured = config
        if config.use_vision_geometry and (self._vision_field or self._vision_model or self._vision_chip):
            config = dataclasses.replace(
                config, field=self._vision_field or config.field, model=self._vision_model or config.model,
                chip=dataclasses.replace(config.chip, **self._vision_chip) if self._vision_chip else config.chip)
        self.config = config
        model_before = None if self._ball is None else self._ball.params
        model = config.model if old is None or config.model != old.model else model_before
        self._search = None if config.field is None else CatchSearch(
            config.num_robots, config.limits, dribbler_offset_m=config.dribbler_offset_m, field=config.field,
            field_margin_m=config.field_margin_m, grid_step_s=config.grid_step_s, kernels=self._kernels)
        if self._ball is None or config.tracker != old.tracker:
            self._ball = BallTracker(model, config.tracker)  # the filter state is lost: it re-seeds
        else:
            self._ball.params = model
        if old is None or (config.chip, config.chip_detector) != (old.chip, old.chip_detector):
            self._chip = ChipDetector(config.chip_detector, config.chip, model)
        if config.online_identification and (self._shots is None or config.tracker != old.tracker):
            self._shots = ShotAccumulator(tracker_config=config.tracker)
            self._fitted_shot = None
        elif not config.online_identification:
            self._shots = None
            self._fit_future = None  # a fit still running is not used
        return old is None or model != model_before

    @property
    def chip_model(self) -> ChipParams:
        """The chip model in use (``config.chip``): the chip detector's, and what the AI must predict chips with."""
        return self.config.chip

    @property
    def model(self) -> BallModelParams:
        """The ball model in use (configured, from SSL geometry or identified). Its one state is the ball filter's
        (``BallTracker.params``): the filter's kernel, the trajectories and so the catch search all read it."""
        return self._ball.params

    def set_vision_geometry(self, field: FieldConfig | None = None, model: BallModelParams | None = None,
                            chip_dampings: Mapping[str, float] | None = None) -> bool:
        """The field, ball model and/or chip dampings (``BALL_CHIP_DAMPING_NAMES``: SSL geometry's chip_fixed_loss)
        of SSL geometry (None: that part unchanged). In effect while ``use_vision_geometry`` (also after later
        ``configure`` calls), kept for when it is turned on; True when the ball model in use changed (``chip_model``
        says the chip model in use). Dampings that make no chip model raise ValueError and change nothing."""
        if chip_dampings is not None:
            chip_dampings = dict(chip_dampings)
            if not set(chip_dampings) <= set(BALL_CHIP_DAMPING_NAMES):
                raise ValueError(f"chip_dampings: {', '.join(BALL_CHIP_DAMPING_NAMES)} only, got "
                                 f"{sorted(chip_dampings)}")
            dataclasses.replace(self._configured.chip, **chip_dampings)  # ValueError: no chip model
        field, model = field or self._vision_field, model or self._vision_model
        chip_dampings = chip_dampings or self._vision_chip
        if (field, model, chip_dampings) == (self._vision_field, self._vision_model, self._vision_chip):
            return False
        self._vision_field, self._vision_model, self._vision_chip = field, model, chip_dampings
        return self.configure(self._configured)

    def close(self) -> None:
        """Stop the fit worker (a fit in progress is dropped)."""
        if self._fit_pool is not None:
            self._fit_pool.shutdown(wait=False, cancel_futures=True)
            self._fit_pool = None
        self._fit_future = None

    # ------------------------------------------------------------------ robots
    def robot_frame(self, robot: int, t_s: float, x_m: float, y_m: float, heading_rad: float, *,
                    restart: bool = False) -> RobotTracker | None:
        """A vision pose of ``robot``: its tracker after the update, or None when the pose was rejected.
        ``restart``: the stamp starts a new time line (StampVerdict.RESTART), the robot's tracker starts over."""
        cfg, key = self.config, f"pose{robot}"
        if cfg.field is None:  # waiting for the world's field: nothing is judged against another
            self.waiting_frames += 1
            return None
        if not cfg.field.contains(x_m, y_m, cfg.vision_reject_margin_m):
            self._warn(key, f"robot_{robot}: rejected robot pose outside the field: ({x_m:.3f}, {y_m:.3f}) m")
            return None
        tracker = None if restart else self._robots[robot]
        tracker = tracker or RobotTracker()
        status = tracker.update(t_s, x_m, y_m, heading_rad)
        if status == UpdateStatus.REJECTED_TIME:
            self._warn(key, f"robot_{robot}: rejected robot pose: stamp {t_s:.6f} s is not after the previous one "
                            f"{tracker.t_s:.6f} s")
            return None
        if status == UpdateStatus.REJECTED_INVALID:
            self._warn(key, f"robot_{robot}: rejected robot pose: invalid")
            return None
        self._robots[robot] = tracker
        vel = tracker.velocity_mps
        self._robot_states[robot] = (tracker.t_s, *tracker.position_m.tolist(), *vel.tolist())
        self._robot_vel_mps[robot] = vel
        return tracker

    def robot_states_at(self, t_s: float, robots: list[int]) -> list[tuple[float, float, float, float, float]]:
        """(x, y, heading, vx, vy) [m, rad, m/s] of each of ``robots`` (seen ones) at ``t_s``: the position
        extrapolated at constant velocity, as the catch search takes it (``_robots_now``); heading 0 before
        the tracker has one."""
        out = []
        for i in robots:
            t_i, x, y, vx, vy = self._robot_states[i]
            age_s = t_s - t_i
            heading = self._robots[i].heading_rad
            out.append((x + vx * age_s, y + vy * age_s, 0.0 if heading is None else heading, vx, vy))
        return out

    def fresh_robots(self, t_s: float) -> list[int]:
        """The robots seen within robot_timeout_s of ``t_s`` (those a catch answer at ``t_s`` would serve)."""
        timeout_s = self.config.robot_timeout_s
        return [i for i, state in enumerate(self._robot_states) if abs(t_s - state[0]) <= timeout_s]

    def _robots_now(self, t_s: float) -> tuple[list[int], np.ndarray]:
        """The robots fresh at ``t_s``, and all robots' positions then (constant-velocity extrapolation).

        Stale robots stay where they were last seen, never-seen ones at the origin: the search runs
        for the whole team in one call and their answers are dropped. A loop over 22 tuples is
        cheaper here than the numpy calls for the same.
        """
        timeout_s = self.config.robot_timeout_s
        fresh, rows = [], []
        for i, (t_i, x, y, vx, vy) in enumerate(self._robot_states):
            age_s = t_s - t_i
            if abs(age_s) <= timeout_s:  # NaN (never seen) is not
                fresh.append(i)
                rows.append((x + vx * age_s, y + vy * age_s))
            else:
                rows.append((x, y))
        return fresh, np.array(rows)

    # -------------------------------------------------------------------- ball
    def ball_frame(self, t_s: float, x_m: float, y_m: float, *, restart: bool = False,
                   camera_m: tuple[float, float, float] | None = None) -> BallFrame | None:
        """A vision observation of the ball: the ball's state and every fresh robot's catch; None when
        the observation was rejected or no prediction could be made (with a warning), or when the filter
        holds it back after a gap (``TrackerConfig.max_hold_gap_s``: the next frame says what happened).
        ``restart``: the stamp starts a new time line (StampVerdict.RESTART), the ball filter and the shot
        collection start over. ``camera_m``: the position (x, y, height) [m] of the camera that saw it; with
        it the chip detector (chip_tracking) takes the sighting, and a chip it finds is the frame's ``chip``."""
        cfg = self.config
        if cfg.field is None:  # waiting for the world's field: nothing is judged against another
            self.waiting_frames += 1
            return None
        if not cfg.field.contains(x_m, y_m, cfg.vision_reject_margin_m):
            self._warn("ball_outside", f"rejected vision/ball outside the field: ({x_m:.3f}, {y_m:.3f}) m")
            return None
        if restart:
            # the robots' states belong to the old line too: none is fresh until its own stream restarts
            self._robot_states = [(math.nan, 0.0, 0.0, 0.0, 0.0)] * len(self._robot_states)
            self._ball = BallTracker(self.model, cfg.tracker)
            self._chip = ChipDetector(cfg.chip_detector, cfg.chip, self.model)
            self._t_ball_s = None
            if self._shots is not None:
                self._shots = ShotAccumulator(tracker_config=cfg.tracker)
                self._fitted_shot = None
        ball = self._ball
        last_t = ball.t_s
        held = before = None
        if camera_m is not None:  # the chip detector's: the frame held back, the motion before this frame
            held, before = ball._held, (ball.t_s, *ball.kf.state) if ball.initialized else None
        status = ball.update(t_s, x_m, y_m)
        if status == UpdateStatus.REJECTED_TIME:
            self._warn("ball_time", f"rejected vision/ball: stamp {t_s:.6f} s is not after the previous one "
                                    f"{last_t:.6f} s (time went backwards or repeated)")
            return None
        if status == UpdateStatus.REJECTED_INVALID:
            self._warn("ball_invalid", "rejected vision/ball: invalid")
            return None
        self._t_ball_s = t_s
        chip = None if camera_m is None else self._chip_sighting(t_s, x_m, y_m, camera_m, status, held,
                                                                            before)
        if chip is None and status == UpdateStatus.HELD_BACK and t_s - ball.t_s > cfg.tracker.max_hold_gap_s:
            return None  # after a gap: the old motion extrapolated is no estimate; the next frame re-seeds it
        try:
            # the path off the wall of the field in effect now (SSL geometry's once it came)
            traj = ball.trajectory().within(Walls.of_field(cfg.field, cfg.wall_restitution))
            if status == UpdateStatus.HELD_BACK:  # the filter waits for the next frame: predict to this stamp
                traj = traj.advanced(t_s - ball.t_s)
        except ValueError as exc:  # e.g. 100 m/s from two frames 1 us apart
            self._warn("predict", f"no prediction for the frame at {t_s:.6f} s: {exc}")
            return None
        # a chip in the air is taken only where it is low enough (catch_time): the catch table follows it
        robots, times, points = self._catches(t_s, traj if chip is None else chip)
        f = traj.floats
        if chip is not None:
            phase = PHASE_HOPPING if chip.bounced else PHASE_CHIP
        elif status == UpdateStatus.INITIALIZED:
            phase = "unknown"
        elif f.speed_mps <= cfg.rest_speed_mps:
            phase = "stopped"
        else:
            phase = PHASE_NAMES[traj.phase]
        covariance = None if chip is None else self._chip.state_covariance_at(t_s)
        return BallFrame(t_s, (x_m, y_m), status, traj, phase, bool(ball.uncertain), *ball.variances_at(t_s),
                         robots, times, points, chip, covariance)

    @property
    def chip_detector(self) -> ChipDetector:
        """The chip detector beside the ball filter (its kick's fit, the chip as launched: ``launch``)."""
        return self._chip

    def kick_hint(self, t_s: float, angle_deg: float, speed_mps: float | None = None) -> None:
        """A robot's kicker kicked at ``t_s`` with the elevation ``angle_deg`` (0: flat, else a chip) and the
        commanded launch speed ``speed_mps`` (None: not known): prior knowledge for the chip detector about the next
        kick it sees (ChipDetector.hint). Raises ValueError for bad values."""
        self._chip.hint(t_s, angle_deg, speed_mps)

    def ball_sighting(self, t_s: float, x_m: float, y_m: float, camera_m: tuple[float, float, float]) -> None:
        """Another camera's sighting of the ball (not the one ``ball_frame`` took, e.g. of the same instant
        from an overlapping camera): for the chip detector only, which sees a ball in the air by the
        cameras' disagreement; judged with the capture's other sightings when the next ball frame comes (a chip
        they show is that frame's, as before). Ignored unless of the ball's time line (at most ``max_gap_s`` before
        the newest ball frame, not after it) and inside the field. Raises ValueError for non-finite values."""
        cfg, t_ball_s = self.config, self._t_ball_s
        if (cfg.field is None or t_ball_s is None or not 0.0 <= t_ball_s - t_s <= cfg.tracker.max_gap_s
                or not cfg.field.contains(x_m, y_m, cfg.vision_reject_margin_m)):
            return
        self._chip.add(t_s, x_m, y_m, camera_m, judge=False)  # judged with the capture's others (judge_pending)

    def _chip_sighting(self, t_s: float, x_m: float, y_m: float, camera_m: tuple[float, float, float],
                       status: UpdateStatus, held: tuple[float, float, float] | None,
                       before: tuple[float, ...] | None) -> ChipTrajectory | None:
        """The chip detector's part of a ball frame: a new motion of the flat filter (a kick) starts a
        kick's collection unless one is under way; the chip at ``t_s``, or None. When a chip rolls, the flat
        filter takes the ball over from the chip's roll (its hand-over)."""
        detector, ball = self._chip, self._ball
        detector.judge_pending()  # the previous capture's other cameras: judged before this frame, as they came
        if status == UpdateStatus.MANEUVER and not detector.active:
            detector.start(held[0] if held is not None else t_s, before)
        detector.add(t_s, x_m, y_m, camera_m)
        roll = detector.hand_over(t_s)
        if roll is not None:
            ball.hand_over(t_s, roll)
        return detector.chip_at(t_s)

    def catches(self, t_s: float, traj) -> tuple[list[int], list[float], list]:
        """The catch table of a given ball at ``t_s`` (a BallTrajectory or, in the air, a chip_model.ChipTrajectory):
        the fresh robots, their catch times (reaction included; CATCH_TIME_NEVER: never) and robot targets."""
        return self._catches(t_s, traj)

    def _catches(self, t_s: float, traj: BallTrajectory) -> tuple[list[int], list[float], list]:
        """Catch time and robot target of every fresh robot: one robotTimeToBall run for the team."""
        cfg = self.config
        ids, pos = self._robots_now(t_s)
        if not ids:
            return [], [], []
        try:
            catch = catch_after_reaction(self._search, traj, pos, self._robot_vel_mps, cfg.reaction_s,
                                         cfg.facing_fixed, cfg.facing_rad, cfg.rest_speed_mps, cfg.receiving)
        except ValueError as exc:
            self._warn("catch", f"no catch times for the frame at {t_s:.6f} s: {exc}")
            return [], [], []
        # Per robot in plain floats (22 values; numpy calls cost more than they save here).
        kinds, times, points = catch.kind.tolist(), catch.time_s.tolist(), catch.robot_target_m.tolist()
        reaction_s = cfg.reaction_s
        out_times, out_points = [], []
        for i in ids:
            if kinds[i] == _NEVER:
                out_times.append(CATCH_TIME_NEVER)
                out_points.append(None)
            else:
                out_times.append(times[i] + reaction_s)
                out_points.append(tuple(points[i]))
        return ids, out_times, out_points

    @property
    def search_compiled(self) -> bool:
        """Whether the catch times come from the compiled search (kernels="background": once it is loaded)."""
        return self._search is not None and self._search.compiled

    def model_rows(self) -> list[list[float]]:
        """[a_slide, a_roll, c_switch] of the model in use, then of the last fit and its standard errors
        once there is one (MODEL_ROWS): what /ball/model_params carries."""
        m, fit = self.model, self.last_fit
        rows = [[m.a_slide_mps2, m.a_roll_mps2, m.c_switch]]
        if fit is not None:
            rows += [[fit.params.a_slide_mps2, fit.params.a_roll_mps2, fit.params.c_switch],
                     [fit.a_slide_std, fit.a_roll_std, fit.c_switch_std]]
        return rows

    # ---------------------------------------------------------- identification
    def identify(self, frame: BallFrame) -> FitResult | None:
        """Online identification (when configured): feed the frame's observation, collect a finished
        fit and start the next one per completed shot. Returns a fit that finished (``model`` is
        its parameters when it was accepted), else None. Off the latency path: call it after the
        frame's answers went out."""
        shots = self._shots
        if shots is None:
            return None
        if shots.tracker.params is not self.model:  # it cuts the shots with the model in use too
            shots.tracker.params = self.model
        shots.add(frame.t_s, *frame.xy_m)
        finished = None
        future = self._fit_future
        if future is not None and future.done():
            self._fit_future = None
            try:
                finished = self._fit_done(future.result())
            except Exception as exc:  # too few points, singular fit, ...: go on without it
                self._warn("fit", f"online identification: fit failed: {exc}")
        if self._fit_future is None and shots.shots and shots.shots[-1] is not self._fitted_shot:
            self._fitted_shot = shots.shots[-1]  # refit once per completed shot, one fit at a time
            if self._fit_pool is None:
                self._fit_pool = concurrent.futures.ThreadPoolExecutor(max_workers=1, thread_name_prefix="ball_fit")
            self._fit_future = self._fit_pool.submit(fit_shots, list(shots.shots), self.model)
        return finished

    def _fit_done(self, fit: FitResult) -> FitResult:
        cfg = self.config
        stds = (fit.a_slide_std, fit.a_roll_std, fit.c_switch_std)
        good = fit.num_shots >= cfg.ident_min_shots and all(
            math.isfinite(s) and s < limit for s, limit in zip(stds, cfg.ident_max_std, strict=True)
        )
        self.last_fit = fit
        if good:
            self._ball.params = fit.params
            self._info(f"online identification: now using a_slide {fit.params.a_slide_mps2:.4f}, a_roll "
                       f"{fit.params.a_roll_mps2:.4f}, c_switch {fit.params.c_switch:.4f} ({fit.num_shots} shots)")
        return fit


class FrameTimes:
    """The processing time of ``every`` frames (to the catch times out, to the end), summarized in one line."""

    def __init__(self, every: int) -> None:
        self.every = every
        self._times_s: list[tuple[float, float]] = []

    def add(self, catch_out_s: float, elapsed_s: float) -> str | None:
        """Record one frame; the summary once ``every`` frames are in (then a new window starts), else None."""
        if self.every <= 0:
            return None
        self._times_s.append((catch_out_s, elapsed_s))
        if len(self._times_s) < self.every:
            return None
        return self.flush()

    def flush(self) -> str | None:
        """The summary of the frames recorded so far (None if there are none); a new window starts."""
        if not self._times_s:
            return None
        catch_ms, ms = 1e3 * np.array(self._times_s).T
        self._times_s.clear()
        return (f"ball frame processing over {ms.size} frames: median {np.median(ms):.3f} ms, "
                f"p99 {np.percentile(ms, 99):.3f} ms, max {ms.max():.3f} ms; catch times out after: median "
                f"{np.median(catch_ms):.3f} ms, p99 {np.percentile(catch_ms, 99):.3f} ms, max {catch_ms.max():.3f} ms")
