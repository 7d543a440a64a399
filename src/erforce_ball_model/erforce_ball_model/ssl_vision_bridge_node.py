"""ssl_vision_bridge: SSL-Vision multicast in, the contract's vision topics out (see contract's docstring).

A receive thread drains the socket in batches (at most ``max_batch`` per round; the kernel buffer
``receive_buffer_bytes`` absorbs bursts meanwhile); a round that finds more than ``flood_batch``
datagrams keeps each camera's newest frame and says so. Each datagram goes through
erforce_interfaces.ssl.ssl_vision (decoding, checks, capture order, vision clock), camera_alignment (each camera's
offset, learnt from what two cameras see and taken off what the camera reports; ``camera_alignment``) and
vision_tracking (the true ball, robot streams). What it drops is named by its class (ssl_vision.DROP_CLASSES): a
throttled warning per class and a counter in the periodic statistics line; the tracker's normal choices with
overlapping cameras (reflections, an older candidate) are only counted.

A camera frame goes out as one ``/vision/robots`` (what the stack reads), before ``/vision/ball``, with the
camera's position from the SSL geometry as its first point and, when the tracker took the ball of that instant
from another camera, this camera's view of it as a sighting (docs/decisions/0035); ``/vision/ball``
and each robot's ``vision_pose`` are published only while read (a DDS write is a datagram's largest
cost). The usual datagram goes from its bytes to the message's bytes in one compiled pass (vision_fast_path;
docs/decisions/0013); anything else takes the general path through the same kernels, which also warns.

Stamps (``time_source``): ``estimate`` maps t_capture onto this host's clock (a real field);
``capture`` puts the cameras' capture times on one timeline and publishes it on ``/clock`` (an outside
simulator not paced to our clock); ``vision`` takes t_capture as ROS time (our plant owns ``/clock``).
Before all three, a camera's frame not after its newest is dropped and a step back of at least
``clock_jump_s`` is passed on as a restart, taken once confirmed.
"""

from __future__ import annotations

import gc
import math
import select
import socket
import struct
import threading
import time
from collections import Counter, deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from rclpy.node import Node

from erforce_ball_model.ball_model import BallModelParams
from erforce_ball_model.camera_alignment import CameraAlignment
from erforce_ball_model.vision_fast_path import (
    I_CAMERA,
    I_CAPTURE_BACK,
    I_CAPTURE_STEP,
    I_DEVIATION,
    I_OFFSET,
    I_POINTS,
    I_SAMPLE,
    I_STAMP,
    I_T_CAPTURE,
    PASS_BAD_STAMP,
    PASS_CLOCK_JUMP,
    PASS_DONE,
    PASS_FALLBACK,
    PASS_GENERAL,
    PASS_T_CAPTURE_BACK,
    PASS_TIMELINE_JUMP,
    FramePass,
    camera_table,
    frame_points,
)
from erforce_ball_model.vision_fast_path import load_kernels as load_pass_kernels
from erforce_ball_model.vision_tracking import (
    BALL_FUSED,
    BALL_SIGHTING,
    MAX_ROBOT_ID,
    BallObservation,
    VisionTracker,
    load_kernels,
)
from erforce_interfaces.runtime.node_support import (
    NodeParams,
    ThrottledWarner,
    contract_publisher,
    run_node,
)
from erforce_interfaces.runtime.param_schema import load_schema
from erforce_interfaces.ssl.ssl_vision import (
    DROP_CLASSES,
    TEAMS,
    DecodedPacket,
    DetectionArrays,
    SslDecodeError,
    decode_wrapper,
)
from erforce_interfaces.ssl.vision_time import (
    CAPTURE_OLD,
    CAPTURE_RESTART,
    CLOCK_CAMERAS,
    TIME_CAPTURE,
    TIME_ESTIMATE,
    TIME_SOURCES,
    TIME_VISION,
    CaptureOrder,
    CaptureTimeline,
    ClockJump,
    PaceCheck,
    VisionClock,
    capture_back_text,
    capture_restart_text,
    clock_jump_text,
    timeline_jump_text,
)
from erforce_interfaces.wire import contract
from erforce_interfaces.wire.clouds import vision_robots_cdr, vision_robots_points_cdr
from erforce_interfaces.wire.conversions import ConversionError, clock_cdr, point_cdr, pose2d_cdr
from erforce_interfaces.wire.robot_config import (
    WAITING_FOR_GEOMETRY,
    FieldConfig,
    field_from_setting,
    half_turn,
    turned_half,
)
from erforce_interfaces.wire.tables import table_cdr

_KIND = contract.VISION_DETECTION_KINDS
_TEAM_CODES = (contract.OURS.code, contract.OPPONENTS.code)  # by side: 0 ours, 1 the opponents

SCHEMA = load_schema("erforce_ball_model", "ssl_vision_bridge")
_OURS_CODE, _OPPONENTS_CODE = float(_TEAM_CODES[0]), float(_TEAM_CODES[1])
_CAMERA_CODE = float(contract.VISION_CAMERA_CODE)


@dataclass(frozen=True)
class BridgeConfig:
    ours: str
    flip: bool
    field: FieldConfig | None  # None: from the world's SSL geometry (nothing is used until it arrives)
    time_source: str
    clock_window_s: float
    clock_jump_s: float
    clock_period_s: float
    publish_detections: bool
    camera_alignment: bool


def build_config(c) -> BridgeConfig:
    """The bridge configuration for a config object of the schema (raises ValueError when invalid)."""
    for name in ("group", "interface"):
        try:
            socket.inet_aton(getattr(c, name))
        except OSError:
            raise ValueError(f"{name} must be an IPv4 address, got {getattr(c, name)!r}") from None
    return BridgeConfig(
        ours=c.team_color,
        flip=turned_half(c.defend_side),
        field=field_from_setting(c.field),
        time_source=c.time_source,
        clock_window_s=c.clock_window_s,
        clock_jump_s=c.clock_jump_s,
        clock_period_s=c.clock_period_s,
        publish_detections=c.publish_detections,
        camera_alignment=c.camera_alignment,
    )


#: Linux's IP_MULTICAST_ALL (in.h), which Python's socket module does not name
IP_MULTICAST_ALL = getattr(socket, "IP_MULTICAST_ALL", 49)


def open_multicast_socket(group: str, port: int, interface: str, receive_buffer_bytes: int) -> socket.socket:
    """A non-blocking UDP socket that has joined ``group`` on ``interface`` (several listeners may share it)
    and receives the group's datagrams from that interface only."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM, socket.IPPROTO_UDP)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, receive_buffer_bytes)
    # Linux otherwise delivers the group's datagrams from every interface on which any socket of this host
    # joined it (another program's membership on the field network would let them in).
    sock.setsockopt(socket.IPPROTO_IP, IP_MULTICAST_ALL, 0)
    sock.bind((group, port))  # only this group's datagrams, not every packet to the port
    membership = struct.pack("4s4s", socket.inet_aton(group), socket.inet_aton(interface))
    sock.setsockopt(socket.IPPROTO_IP, socket.IP_ADD_MEMBERSHIP, membership)
    sock.setblocking(False)
    return sock


class SslVisionBridge(Node):
    def __init__(self, frame_sink: Callable[[bytes], None] | None = None,
                 geometry_sink: Callable[[FieldConfig, BallModelParams | None, dict[str, float] | None], None]
                 | None = None) -> None:
        """``frame_sink``: called on the receive thread with each serialized ``/vision/robots`` frame before it is
        published (a consumer in this process, erforce_ball_model.ssl_ball_predictor; the frame names its camera).
        Its CPU time is not counted in the bridge's statistics. ``geometry_sink``: called there with each new SSL
        geometry's field, ball model and chip dampings (VISION_CHIP_MODEL_LABELS: value), before the next frame goes
        to ``frame_sink`` (a topic's message could come after it)."""
        super().__init__("ssl_vision_bridge")
        self._warn = ThrottledWarner(self)
        self._frame_sink = frame_sink
        self._geometry_sink = geometry_sink
        self._sink_ns = 0  # the sink's thread CPU time in the current datagram
        self._config: BridgeConfig | None = None
        self._clock_pub = None  # /clock, created with time_source capture
        self._clock_sent_s = -math.inf  # the timeline's time last published on /clock
        self._lock = threading.Lock()  # parameter changes vs the receive thread
        self._last_geometry = None
        self._camera_poses: dict[int, tuple[float, float, float]] = {}  # by camera id, SSL-Vision's frame [m]
        self._cameras = camera_table()  # the same in the field frame, as the frames' camera points carry them
        self._params = NodeParams(self, SCHEMA, build_config)
        v = self._values = self._params.values
        self.stats: Counter[str] = Counter()
        # per drop class (per camera where the class says so): what was dropped, counted by the inputs of the class
        self.drops: Counter[str] = Counter()
        self._capture_order = CaptureOrder()
        self._apply(self._params.built)
        self.cpu_ns: deque[int] = deque(maxlen=100_000)  # per datagram, since the last statistics line
        # per datagram after the first statistics period (start-up), in whole microseconds: for the p99 of a run
        self._cpu_us_counts: Counter[int] = Counter()
        self._periods_logged = 0
        self._stats_period_s = v["stats_period_s"]
        self._stats_logged = time.monotonic()
        self._n_ours = v["num_robots"]
        q = contract
        self._ball_readers = [0]
        self._ball_pub = contract_publisher(self, q.VISION_BALL, readers=(self._ball_readers, 0))
        self._robots_pub = contract_publisher(self, q.VISION_ROBOTS)
        self._detections_pub = contract_publisher(self, q.VISION_DETECTIONS)
        self._field_pub = contract_publisher(self, q.VISION_FIELD)
        self._model_pub = contract_publisher(self, q.VISION_BALL_MODEL)
        self._chip_pub = contract_publisher(self, q.VISION_CHIP_MODEL)
        # ours (0) and the opponents (1) by robot id: the pose publisher (None: not created yet), its readers
        # (-1 until created)
        self._pose_pubs: list[list[Any]] = [[None] * (MAX_ROBOT_ID + 1) for _ in range(2)]
        self._pose_readers = np.full((2, MAX_ROBOT_ID + 1), -1, np.int64)
        self._points = np.empty((2 * (MAX_ROBOT_ID + 1) + 1, len(contract.VISION_ROBOT_FIELDS)))
        for i in range(self._n_ours):
            self._pose_publisher(0, i)
        try:
            self._sock = open_multicast_socket(v["group"], v["port"], v["interface"], v["receive_buffer_bytes"])
        except OSError as exc:  # no such interface, no multicast route, ...: one clear line at start
            raise ValueError(f"cannot join {v['group']}:{v['port']} on {v['interface']}: {exc}") from None
        self._max_batch, self._flood_batch = v["max_batch"], v["flood_batch"]
        load_kernels()  # before the first datagram
        load_pass_kernels()
        self._bind_pass()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._receive_loop, name="ssl_vision_rx", daemon=True)
        self._thread.start()
        self.get_logger().info(
            f"ssl_vision_bridge: {v['group']}:{v['port']} on {v['interface']}, we are {v['team_color']} defending "
            f"{v['defend_side']}, stamps: {v['time_source']}, field: {v['field']}"
        )
        if self._tracker.field is None:
            self.get_logger().info(WAITING_FOR_GEOMETRY)
        self._params.on_change(self._apply)
        # What start-up built lives as long as the node: out of the collector's way, so that a full
        # collection (triggered on any thread) does not walk it while datagrams wait.
        gc.freeze()

    def _apply(self, config: BridgeConfig) -> None:
        with self._lock:
            old = self._config
            self._config = config
            if old is None or (config.clock_window_s, config.clock_jump_s) != (old.clock_window_s, old.clock_jump_s):
                self._vision_clock = VisionClock(config.clock_window_s, config.clock_jump_s)
                self._pace_check = PaceCheck(config.clock_jump_s + 0.05)
            if old is None:
                self._timeline = CaptureTimeline(config.clock_jump_s)
            else:  # in place: the timeline's time (and /clock) go on
                self._timeline.set_jump_s(config.clock_jump_s)
            # a camera's t_capture back by more than a clock jump is its clock starting again, not an old frame
            self._capture_order.restart_s = config.clock_jump_s
            self._ours = float(TEAMS.index(config.ours))  # as in the decoder's team column
            if old is None:
                self._tracker = VisionTracker(config.field)
            elif config.field != old.field and self._last_geometry is None:
                self._tracker.field = config.field
            if not config.camera_alignment:
                self._alignment = None
            elif old is None or not old.camera_alignment:
                self._alignment = CameraAlignment()
            self._set_path()
            self._set_cameras()
            self._time_mode = TIME_SOURCES.index(config.time_source)
            if self._time_mode == TIME_CAPTURE and self._clock_pub is None:
                self._clock_pub = contract_publisher(self, contract.CLOCK)
            if old is not None:
                self._bind_pass()

    def _set_path(self) -> None:
        """The compiled pass takes the usual configuration (with or without the camera alignment); a flipped field,
        the detections topic and the wait for geometry take the general path."""
        cfg = self._config
        self._fast = not (cfg.flip or cfg.publish_detections or self._tracker.field is None)

    def _bind_pass(self) -> None:
        """The compiled pass on the current clock, tracker and team (at start and after parameter changes)."""
        self._frame_pass = FramePass(self._vision_clock, self._tracker, self._pose_readers, self._ours, self._n_ours,
                                     self._capture_order, timeline=self._timeline, cameras=self._cameras,
                                     alignment=self._alignment)

    def _set_cameras(self) -> None:
        """The camera table from the geometry's cameras, in the field frame (half turned with ``flip``, as the
        balls are): in place, the compiled pass reads it."""
        table = self._cameras
        table[:, :4] = 0.0
        sign = -1.0 if self._config.flip else 1.0
        for camera_id, (x, y, z) in self._camera_poses.items():
            if camera_id < len(table):
                table[camera_id, :4] = 1.0, sign * x, sign * y, z

    # ------------------------------------------------------------------ receiving
    def _receive_loop(self) -> None:
        sock = self._sock
        while not self._stop.is_set():
            try:
                ready, _, _ = select.select([sock], [], [], 0.2)
            except (OSError, ValueError):
                return  # socket closed at shutdown
            if not ready:
                continue
            batch = []
            try:
                while len(batch) < self._max_batch:
                    batch.append(sock.recv(65536))
            except BlockingIOError:
                pass
            except OSError:
                return
            try:
                self.handle_batch(batch, self.get_clock().now().nanoseconds * 1e-9)
            except Exception as exc:  # never let the thread die: log, go on with the next batch
                if not self.context.ok():
                    return  # shutting down: the context went (SIGINT) before destroy_node stopped this thread
                self._warn.warn("batch", f"ssl_vision_bridge: batch failed: {exc!r}")

    def _drop(self, kind: str, text: str, camera_id: int | None = None, n: int = 1) -> None:
        """Count ``n`` inputs of the drop class ``kind`` (a DROP_CLASSES key; per camera when ``camera_id`` is
        given) and warn, throttled per class, naming it."""
        assert kind in DROP_CLASSES, kind
        key = kind if camera_id is None else f"{kind} (camera {camera_id})"
        self.drops[key] += n
        self._warn.warn(key, f"ssl_vision_bridge: [{kind}] {text}")

    def handle_batch(self, batch: list[bytes], t_receive_s: float, t_wall_s: float | None = None) -> None:
        """Decode, track and publish a batch of datagrams received at ``t_receive_s`` (ROS clock) and ``t_wall_s``
        (time.monotonic(), the capture timeline's reference; default: now)."""
        self.stats["datagrams"] += len(batch)
        thread_time_ns = time.thread_time_ns  # a system call: two per datagram
        with self._lock:
            if self._time_mode == TIME_CAPTURE:  # the timeline's receive times: a wall clock, not its own /clock
                t_receive_s = time.monotonic() if t_wall_s is None else t_wall_s
            if len(batch) > self._flood_batch:  # decode all first: only each camera's newest frame is used
                decoded = []
                for data in batch:
                    t0 = thread_time_ns()
                    packet = self._decode(data)
                    if packet is not None:
                        decoded.append((packet, thread_time_ns() - t0))
                for packet, cpu_ns in self._newest_per_camera(decoded):
                    t0 = thread_time_ns()
                    self._use(packet, t_receive_s)
                    self.cpu_ns.append(cpu_ns + thread_time_ns() - t0 - self._take_sink_ns())
            elif self._fast:
                for data in batch:
                    t0 = thread_time_ns()
                    self._pass_datagram(data, t_receive_s)
                    self.cpu_ns.append(thread_time_ns() - t0 - self._take_sink_ns())
            else:
                for data in batch:
                    t0 = thread_time_ns()
                    packet = self._decode(data)
                    if packet is not None:
                        self._use(packet, t_receive_s)
                    self.cpu_ns.append(thread_time_ns() - t0 - self._take_sink_ns())
            if self._time_mode == TIME_CAPTURE:
                self._publish_clock()
        self._log_stats()

    def _publish_clock(self) -> None:
        """The timeline's time on /clock once it moved on by clock_period_s (never back: the timeline's time
        never goes back)."""
        newest = self._timeline.newest_s
        if newest is not None and newest - self._clock_sent_s >= max(self._config.clock_period_s, 1e-9):
            try:
                self._clock_pub.publish(clock_cdr(round(newest * 1e9)))
            except (ConversionError, OverflowError) as exc:
                self._warn.warn("clock", f"ssl_vision_bridge: /clock not published at {newest!r} s: {exc}")
                return
            self._clock_sent_s = newest

    def _publish_frame(self, data: bytes) -> None:
        """A camera frame's ``/vision/robots``: to the sink first (its answer is on the latency path), then the
        topic (tools, bags, a predictor in another process)."""
        sink = self._frame_sink
        if sink is not None:
            t0 = time.thread_time_ns()
            try:
                sink(data)
            except Exception as exc:  # the topic still gets the frame
                if not self.context.ok():
                    raise  # shutting down: the receive loop ends quietly
                self._warn.warn("sink", f"ssl_vision_bridge: the frame's consumer failed: {exc!r}")
            self._sink_ns += time.thread_time_ns() - t0
        self._robots_pub.publish(data)

    def _camera_at(self, camera_id: int) -> tuple[float, float, float, float] | None:
        """Camera ``camera_id`` as a frame's camera point takes it: (id, x, y, z) in the field frame; None: unknown."""
        row = self._cameras[camera_id].tolist() if 0 <= camera_id < len(self._cameras) else None
        return None if row is None or not row[0] else (camera_id, *row[1:4])

    def _take_sink_ns(self) -> int:
        ns, self._sink_ns = self._sink_ns, 0
        return ns

    def _pass_datagram(self, data: bytes, t_receive_s: float) -> None:
        """A datagram through the compiled pass: the usual frame is one call and one publish."""
        status, n_bytes, action, t_s, ball_x, ball_y = self._frame_pass.run(data, t_receive_s, self._time_mode)
        if status == PASS_DONE and n_bytes >= 0 and (not action or action >= BALL_FUSED):
            self.stats["frames"] += 1
            if n_bytes:
                self._publish_frame(self._frame_pass.message_view[:n_bytes].tobytes())
            if action and action != BALL_SIGHTING and self._ball_readers[0]:  # a tool's: after the predictor's
                self._ball_pub.publish(point_cdr(t_s, (ball_x, ball_y)))
            return
        if status == PASS_FALLBACK:  # nothing changed yet: the general path names the problem
            packet = self._decode(data)
            if packet is not None:
                self._use(packet, t_receive_s)
            return
        self._pass_rest(status, n_bytes, action, t_s, ball_x, ball_y)

    def _pass_rest(self, status: int, n_bytes: int, action: int, t_s: float, ball_x: float, ball_y: float) -> None:
        """What the compiled pass leaves to Python: a refused frame's warning, the ball filter, the general path."""
        fp = self._frame_pass
        info = fp.info.tolist()
        camera_id = int(info[I_CAMERA])
        if status == PASS_T_CAPTURE_BACK:
            self.stats["dropped_clock"] += 1
            self._drop("t_capture_back", capture_back_text(camera_id, info[I_T_CAPTURE], info[I_CAPTURE_BACK]),
                       camera_id)
            return
        if status == PASS_CLOCK_JUMP:
            self.stats["dropped_clock"] += 1
            self._drop("clock_jump", clock_jump_text(camera_id, info[I_SAMPLE], info[I_DEVIATION], info[I_OFFSET]),
                       camera_id)
            return
        if status == PASS_TIMELINE_JUMP:
            self.stats["dropped_clock"] += 1
            self._drop("clock_jump", timeline_jump_text(camera_id, info[I_T_CAPTURE], info[I_CAPTURE_STEP]), camera_id)
            return
        if status == PASS_BAD_STAMP:
            self.stats["dropped_clock"] += 1
            self._drop("bad_stamp", f"camera {camera_id}: no valid stamp ({info[I_STAMP]!r})")
            return
        ball = self._tracker.use_ball(action, camera_id, t_s, ball_x, ball_y) if action else None
        self.stats["frames"] += 1
        try:
            n_points = int(info[I_POINTS])
            if status == PASS_GENERAL:
                self._publish_robots(t_s, fp.robots()[fp.used()].tolist(), ball, camera_id)
            elif action and ball is None:  # the filter refused the ball written (after the camera's point, if any)
                points = fp.points[:n_points]
                at = int(n_points > 0 and points[0, 4] == _CAMERA_CODE)
                if n_points > at + 1:  # robots: the frame without its ball
                    self._publish_frame(vision_robots_points_cdr(t_s, np.delete(points, at, axis=0)))
            elif n_bytes > 0:
                self._publish_frame(fp.message_view[:n_bytes].tobytes())
            elif n_points > 0:  # a stamp the pass leaves to the checks of conversions
                self._publish_frame(vision_robots_points_cdr(t_s, fp.points[:n_points]))
            if ball is not None and not ball.sighting and self._ball_readers[0]:  # a tool's: after the predictor's
                self._ball_pub.publish(point_cdr(ball.t_s, (ball.x_m, ball.y_m)))
        except ConversionError as exc:
            self._drop("unpublishable", f"camera {camera_id}: not published: {exc}")

    def _decode(self, data: bytes) -> DecodedPacket | None:
        try:
            packet = decode_wrapper(data)
        except SslDecodeError as exc:
            self.stats["dropped_bad"] += 1
            self._drop(exc.kind, f"dropped a datagram: {exc}")
            return None
        if packet.problems:
            by_kind: dict[str, list] = {}
            for problem in packet.problems:
                by_kind.setdefault(problem.kind, []).append(problem)
            for kind, problems in by_kind.items():
                self._drop(kind, "; ".join(p.text for p in problems), n=sum(p.count for p in problems))
        return packet

    def _use(self, packet: DecodedPacket, t_receive_s: float) -> None:
        if packet.geometry is not None:
            self._on_geometry(packet.geometry)
        if packet.detection is not None:
            self._on_frame(packet.detection, t_receive_s)

    def _log_stats(self) -> None:
        now = time.monotonic()
        if now - self._stats_logged < self._stats_period_s or not self.cpu_ns:
            return
        self._stats_logged = now
        ms = sorted(self.cpu_ns)
        self.cpu_ns.clear()
        if self._periods_logged:
            self._cpu_us_counts.update(ns // 1000 for ns in ms)
        self._periods_logged += 1
        if self._time_mode == TIME_ESTIMATE:
            self._check_pace()
        s, tracker = self.stats, self._tracker
        by_class = ", ".join(f"{key} {n}" for key, n in sorted(self.drops.items())) or "none"
        self.get_logger().info(
            f"ssl_vision_bridge: {s['datagrams']} datagrams, {s['frames']} camera frames; dropped: {s['dropped_bad']} "
            f"bad, {s['dropped_clock']} clock, {s['superseded_in_flood']} superseded in floods; CPU per datagram "
            f"median {ms[len(ms) // 2] * 1e-6:.3f} ms, p99 {ms[int(0.99 * (len(ms) - 1))] * 1e-6:.3f} ms; "
            f"since the first period: {self._cpu_p99_text()}; dropped by class: {by_class}; tracker: "
            f"{tracker.late_balls} late balls, {tracker.false_candidates} false candidates, {tracker.switches} ball "
            "switches" + self._alignment_text()
        )

    def _alignment_text(self) -> str:
        if self._alignment is None:
            return ""
        parts = []
        for camera_id in sorted(self._camera_poses):
            ox, oy = self._alignment.offset_m(camera_id)
            sd = self._alignment.uncertainty_m(camera_id)
            parts.append(f"{camera_id} ({1e3 * ox:.1f}, {1e3 * oy:.1f}) +- {1e3 * sd:.1f}" if math.isfinite(sd)
                         else f"{camera_id} not paired")
        return "; camera offsets [mm]: " + (", ".join(parts) or "no cameras")

    def _check_pace(self) -> None:
        """Say when a camera's clock is not paced to ours (time_source estimate: see PaceCheck)."""
        t_receive_s = self.get_clock().now().nanoseconds * 1e-9
        for camera_id in range(CLOCK_CAMERAS):
            offset = self._vision_clock.offset_s(camera_id)
            text = None if offset is None else self._pace_check.check(camera_id, offset, t_receive_s)
            if text is not None:
                self._warn.warn(f"pace{camera_id}", "ssl_vision_bridge: " + text)

    def _cpu_p99_text(self) -> str:
        """The p99 of the CPU per datagram over every datagram after the first statistics period."""
        counts = self._cpu_us_counts
        total = sum(counts.values())
        if not total:
            return "0 datagrams"
        rank, seen = int(0.99 * (total - 1)), 0
        for us in sorted(counts):
            seen += counts[us]
            if seen > rank:
                break
        return f"{total} datagrams, p99 {us * 1e-3:.3f} ms"

    def _newest_per_camera(self, packets: list[tuple[DecodedPacket, int]]) -> list[tuple[DecodedPacket, int]]:
        newest: dict[int, tuple[DecodedPacket, int]] = {}
        kept = []
        for item in packets:
            if item[0].detection is None:
                kept.append(item)
            else:
                newest[item[0].detection.camera_id] = item
        kept += newest.values()
        superseded = len(packets) - len(kept)
        self.stats["superseded_in_flood"] += superseded
        self._drop("superseded", f"packet flood ({len(packets)} datagrams in one read): {superseded} older camera "
                                 "frames skipped", n=superseded)
        return kept

    # ----------------------------------------------------------------- geometry
    def _on_geometry(self, geometry) -> None:
        # by camera id, kept across packets: a source may send each camera's calibration in its own packet (grSim)
        self._camera_poses.update((c.camera_id, (c.x_m, c.y_m, c.z_m)) for c in geometry.cameras if c.z_m > 0.0)
        self._set_cameras()
        key = (geometry.length_m, geometry.width_m, geometry.boundary_m, geometry.ball_model, geometry.chip_model)
        if key == self._last_geometry:
            return
        self._last_geometry = key
        try:
            field = FieldConfig(geometry.length_m, geometry.width_m, geometry.boundary_m)
            self._field_pub.publish(table_cdr(
                [[geometry.length_m, geometry.width_m, geometry.boundary_m, geometry.goal_width_m,
                  geometry.goal_depth_m]], contract.VISION_FIELD_COLUMNS, "field"))
            self._tracker.field = field
            self._set_path()
            model, params = geometry.ball_model, None
            if model is not None:
                params = BallModelParams(model.a_slide_mps2, model.a_roll_mps2, model.c_switch)
                self._model_pub.publish(table_cdr([[params.a_slide_mps2, params.a_roll_mps2, params.c_switch]],
                                                  contract.BALL_MODEL_PARAM_LABELS, "model"))
                self._tracker.params = params
            chip = None if geometry.chip_model is None else {
                name: getattr(geometry.chip_model, name) for name in contract.VISION_CHIP_MODEL_LABELS}
            if chip is not None:
                self._chip_pub.publish(table_cdr([list(chip.values())], contract.VISION_CHIP_MODEL_LABELS, "model"))
            if self._geometry_sink is not None:
                self._geometry_sink(field, params, chip)
        except (ValueError, ConversionError) as exc:
            self._drop("geometry", f"geometry not used: {exc}")
            return
        self.get_logger().info(
            f"SSL geometry: field {geometry.length_m:g} x {geometry.width_m:g} m"
            + ("" if model is None else f", ball model a_slide {model.a_slide_mps2:g}, a_roll "
               f"{model.a_roll_mps2:g}, k_switch {model.c_switch:g}")
            + ("" if chip is None else ", chip model " + ", ".join(f"{k} {v:g}" for k, v in chip.items()))
        )

    # ------------------------------------------------------------------- frames
    def _on_frame(self, frame: DetectionArrays, t_receive_s: float) -> None:
        """One camera frame on the general path; ``t_receive_s``: the ROS clock, with time_source capture the
        monotonic wall clock."""
        cfg = self._config
        if self._tracker.field is None:  # nothing is judged against a field the world has not given
            self.drops["no_geometry"] += 1  # counted, not warned: the node said once that it waits
            return
        verdict, back_s = self._capture_order.take(frame.camera_id, frame.t_capture_s)
        if verdict == CAPTURE_OLD:
            self.stats["dropped_clock"] += 1
            self._drop("t_capture_back", capture_back_text(frame.camera_id, frame.t_capture_s, back_s),
                       frame.camera_id)
            return
        if verdict == CAPTURE_RESTART:
            self._warn.warn(f"t_capture_restart (camera {frame.camera_id})",
                            "ssl_vision_bridge: " + capture_restart_text(frame.camera_id, back_s))
        if self._time_mode == TIME_VISION:
            t_s = frame.t_capture_s
        else:
            try:
                if self._time_mode == TIME_CAPTURE:
                    t_s = self._timeline.stamp(frame.camera_id, frame.t_capture_s, frame.t_sent_s, t_receive_s)
                else:
                    t_s = self._vision_clock.to_receiver(frame.camera_id, frame.t_capture_s, frame.t_sent_s,
                                                         t_receive_s)
            except ClockJump as exc:  # its kind: clock_jump, or t_capture_back from the timeline
                self.stats["dropped_clock"] += 1
                self._drop(exc.kind, str(exc), frame.camera_id)
                return
        if not (math.isfinite(t_s) and t_s >= 0.0):
            self.stats["dropped_clock"] += 1
            self._drop("bad_stamp", f"camera {frame.camera_id}: no valid stamp ({t_s!r})")
            return
        balls, robots = frame.balls, frame.robots  # rows: ssl_vision's BALL_COLUMNS, ROBOT_COLUMNS
        if cfg.flip:  # into the field frame (ssl_sim_bridge turns teleports back the same way)
            balls, robots = balls.copy(), robots.copy()
            balls[:, 0], balls[:, 1] = half_turn(balls[:, 0], balls[:, 1])
            robots[:, 2], robots[:, 3], robots[:, 4] = half_turn(robots[:, 2], robots[:, 3], robots[:, 4])
        if self._alignment is not None:  # on the vision host's capture clock (one for all cameras)
            balls, robots = self._alignment.take(frame.camera_id, frame.t_capture_s, balls, robots)
        ball, used = self._tracker.frame_indices(frame.camera_id, t_s, balls, robots)
        self.stats["frames"] += 1
        try:
            if len(used) or ball is not None:  # the ball's stamp is the frame's
                if len(used) + 2 > len(self._points):
                    self._points = np.empty((len(used) + 2, self._points.shape[1]))
                action = 0 if ball is None else BALL_SIGHTING if ball.sighting else 1
                n = frame_points(robots, used, self._ours, self._n_ours, self._pose_readers, self._points,
                                 self._cameras[frame.camera_id], action, ball.x_m if action else 0.0,
                                 ball.y_m if action else 0.0)
                if n > 0:
                    self._publish_frame(vision_robots_points_cdr(t_s, self._points[:n]))
                elif n < 0:
                    self._publish_robots(t_s, robots[used].tolist(), ball, frame.camera_id)
            if ball is not None and not ball.sighting and self._ball_readers[0]:  # a tool's: after the predictor's
                self._ball_pub.publish(point_cdr(ball.t_s, (ball.x_m, ball.y_m)))
            if cfg.publish_detections:
                now_s = self._timeline.newest_s if self._time_mode == TIME_CAPTURE else t_receive_s
                self._publish_detections(cfg, frame.camera_id, now_s - t_s, balls.tolist(), robots.tolist())
        except ConversionError as exc:
            self._drop("unpublishable", f"camera {frame.camera_id}: not published: {exc}")

    def _publish_robots(self, t_s: float, rows: list[list[float]], ball: BallObservation | None,
                        camera_id: int) -> None:
        """The frame's camera, ``ball`` (or sighting) and robots in one /vision/robots, then each robot's vision_pose
        that has a reader (the general path: it creates publishers and warns)."""
        readers, n_ours = self._pose_readers, self._n_ours
        table, read = [], []
        for team, robot_id, x, y, theta, _confidence in rows:
            side, robot_id = int(team != self._ours), int(robot_id)  # side 0: ours, 1: opponents
            if math.isnan(theta):
                self._drop("no_orientation", f"{TEAMS[int(team)]} robot {robot_id} without orientation: not "
                                             "published")
                continue
            table.append((_TEAM_CODES[side], robot_id, x, y, theta))
            if side == 0 and robot_id >= n_ours:
                self._warn.warn("our_id", f"ssl_vision_bridge: our robot {robot_id} beyond num_robots "
                                          f"{n_ours}: no vision_pose")
                continue
            pub = self._pose_pubs[side][robot_id] or self._pose_publisher(side, robot_id)
            if readers[side, robot_id] > 0:
                read.append((pub, x, y, theta))
        camera = self._camera_at(camera_id)
        sightings = [] if ball is None or not ball.sighting or camera is None else [(ball.x_m, ball.y_m)]
        balls = [] if ball is None or ball.sighting else [(ball.x_m, ball.y_m)]
        if table or balls or sightings:
            self._publish_frame(vision_robots_cdr(t_s, table, balls=balls, camera=camera, sightings=sightings))
        for pub, x, y, theta in read:
            pub.publish(pose2d_cdr(t_s, (x, y, theta)))

    def _pose_publisher(self, side: int, robot_id: int):
        """Our robots' (side 0) under robot_<id>, the opponents' (side 1) under opponent_<id> (see the contract)."""
        topic = contract.VISION_POSE
        name = contract.opponent_topic(topic, robot_id) if side else topic.for_robot(robot_id)
        pub = self._pose_pubs[side][robot_id] = contract_publisher(self, topic, name,
                                                                    readers=(self._pose_readers[side], robot_id))
        return pub

    def _publish_detections(self, cfg, camera_id: int, age_s: float, balls, robots) -> None:
        rows = [[camera_id, age_s, _KIND["ball"], -1.0, b[0], b[1], 0.0, b[2]] for b in balls]
        rows += [
            [camera_id, age_s, _KIND["ours"] if r[0] == self._ours else _KIND["opponent"], r[1], r[2], r[3],
             0.0 if math.isnan(r[4]) else r[4], 1.0]
            for r in robots
        ]
        self._detections_pub.publish(table_cdr(rows, contract.VISION_DETECTION_COLUMNS, "detections"))

    def destroy_node(self) -> None:
        self._stop.set()
        self._thread.join(timeout=1.0)
        self._sock.close()
        super().destroy_node()


def main(args: list[str] | None = None) -> int:
    return run_node(SslVisionBridge, args)


if __name__ == "__main__":
    raise SystemExit(main())
