"""field_view: the field drawn live in a browser, a recorded bag replayed on the same page, and a
Foxglove WebSocket server, as a ROS 2 node.

It serves http://127.0.0.1:<port>/ (view_server; the page's files ship in share/erforce_sim/web). Every
``1 / rate_hz`` of wall time, a tick in the server's thread takes the newest message of each topic the
view shows (field_view lists them), hands them to the core (field_view.WorldState) and sends the binary
frame to the pages; no message wakes the process (docs/decisions/0025). It reads the predictor's
``/ball/catches`` and ``/ball/track`` where they are on the graph (two topics at the vision rate instead of
several per robot), best effort, keep-last 1, so it never holds up a publisher, and takes nothing while no
page is open. It is an observer: its threads run under SCHED_IDLE (``observe_only``). With ``bag`` the page
can also replay that bag (bag_replay.BagReplay).

With ``foxglove_port`` > 0 it also starts a Foxglove WebSocket server (the ``foxglove`` SDK) that forwards
every topic as it is (CDR, schema encoding ``ros2msg``), plus ``/field_view/scene`` (a SceneUpdate of what
the page draws) and ``/field_view/plots``; config/foxglove_layout.json lays them out.
"""

from __future__ import annotations

import contextlib
import functools
import json
import os
import threading
from typing import Any

from rclpy.clock import Clock, ClockType
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message

from erforce_interfaces.runtime.executor import sample_only, take_one
from erforce_interfaces.runtime.node_support import SchemaNode, contract_subscription, run_node
from erforce_interfaces.runtime.param_schema import load_schema
from erforce_interfaces.wire import contract
from erforce_interfaces.wire.ament_index import find_package_share
from erforce_interfaces.wire.robot_config import FieldConfig
from erforce_sim.view.bag_replay import BagReplay
from erforce_sim.view.field_view import (
    BYTES_TYPES,
    CATCH_TABLE_REPLACES,
    TRACK_REPLACES,
    VALUE_TOPICS,
    WorldState,
    view_topic,
)
from erforce_sim.view.view_server import ViewServer

DISCOVERY_PERIOD_S = 1.0
#: Topics that change rarely: their messages come by callback (the executor wakes for them) instead of a take
#: per tick, which costs the same found empty. The model in use with its contract QoS: latched, so the view
#: has it from the start.
CALLBACK_TOPICS = (contract.BALL_MODEL_PARAMS, contract.SIM_EVENTS, contract.VISION_FIELD)
SCHEMA = load_schema("erforce_sim", "field_view")


def check_config(config):
    """The schema's config object, once the field preset is known (raises ValueError otherwise)."""
    FieldConfig.preset(config.field)
    return config


@functools.cache
def decode(type_name: str, data: bytes) -> Any:
    """What WorldState.apply takes of a message's CDR bytes: the bytes themselves for the types the
    conversions read directly, else the deserialized message."""
    if type_name in BYTES_TYPES:
        return data
    return deserialize_message(data, contract.message_class(type_name))


def web_dir():
    share = find_package_share("erforce_sim")
    path = None if share is None else share / "web"
    if path is None or not (path / "index.html").is_file():
        raise FileNotFoundError("web/index.html of erforce_sim not found (the page's files)")
    return path


def observe_only() -> None:
    """Every thread of this process under SCHED_IDLE (threads started later, such as the DDS ones, inherit
    it): among the processes of its session (Linux ranks threads by priority only inside one session's
    scheduling group, the autogroup), such as the demo's graph, the view runs only on a core none of
    them wants. Its group as a whole keeps its fair share against other sessions: a lower group weight
    (autogroup nice) starved the view's start on a loaded machine for over a minute."""
    with contextlib.suppress(AttributeError, OSError):
        for tid in os.listdir("/proc/self/task"):
            with contextlib.suppress(OSError):
                os.sched_setscheduler(int(tid), os.SCHED_IDLE, os.sched_param(0))


def _take_newest(subscription) -> list[bytes]:
    """The newest queued message of a keep-last-1 subscription (raw), or none."""
    taken = take_one(subscription)
    return [] if taken is None else [taken[0]]


class FieldViewNode(SchemaNode):
    def __init__(self) -> None:
        super().__init__("field_view", SCHEMA, check_config)
        v = self._values
        robot = self._params.config.robot
        looks = dict(current_limit_a=robot.continuous_current_limit_a, robot_radius_m=robot.robot_radius_m,
                     opponent_ids=frozenset(int(i) for i in v["opponent_robot_ids"]),
                     team_ids=frozenset(int(i) for i in v["team_robot_ids"]))
        self._state = WorldState(FieldConfig.preset(v["field"]), **looks, stamp_filters={})
        self._replay: BagReplay | None = None
        if v["bag"]:
            try:
                self._replay = BagReplay(v["bag"], decode, self._state.field, **looks)
            except Exception as exc:  # rosbags raises its own errors for a damaged bag
                raise ValueError(f"cannot replay {v['bag']}: {exc}") from None
            skipped = f", {self._replay.skipped} undecodable skipped" if self._replay.skipped else ""
            self.get_logger().info(f"replay: {v['bag']} ({len(self._replay)} messages{skipped}, "
                                   f"{self._replay.start_s:.1f} to {self._replay.end_s:.1f} s)")
        # The frames are taken, built and sent in the server's tick thread, one wake-up per frame; the graph's
        # discovery in the executor's: the lock keeps them apart.
        self._lock = threading.Lock()
        self._replay_lock = threading.Lock()
        self._subs: dict[str, Any] = {}  # topic -> raw subscription of the view
        self._types: dict[str, str] = {}
        self._rare: set[str] = set()  # CALLBACK_TOPICS' subscriptions: not taken by the tick
        self._rare_applied = False  # a message of one came since the last frame
        self._graph: list | None = None  # the graph's topics as last matched
        self._last_value: dict[str, bytes] = {}  # VALUE_TOPICS: the bytes last applied
        self._foxglove = None
        if v["foxglove_port"]:
            from erforce_sim.view.foxglove_bridge import FoxgloveBridge

            self._foxglove = FoxgloveBridge(v["host"], v["foxglove_port"])
            self.get_logger().info(f"Foxglove WebSocket server at ws://{v['host']}:{v['foxglove_port']}")
        self._discover()
        self.create_timer(DISCOVERY_PERIOD_S, self._discover, clock=Clock(clock_type=ClockType.STEADY_TIME))
        self._params.on_change(lambda _config: None)  # every parameter is read-only
        self._server = ViewServer(web_dir(), v["host"], v["port"], v["max_clients"], on_request=self._on_request,
                                  logger=None, on_tick=self._tick, tick_period_s=1.0 / v["rate_hz"])
        try:
            self._server.start()
        except (OSError, RuntimeError) as exc:  # e.g. the port is taken: one clear line (run_node)
            raise ValueError(str(exc)) from None
        self.get_logger().info(f"field view at {self._server.url}")

    def _discover(self) -> None:
        graph = self.get_topic_names_and_types()
        if graph == self._graph:
            return  # nothing to match again
        with self._lock:
            self._match(graph)
        self._graph = graph

    def _match(self, graph: list[tuple[str, list[str]]]) -> None:
        names = {topic for topic, _ in graph}
        team_table, track = contract.BALL_CATCHES.name in names, contract.BALL_TRACK.name in names
        for topic, types in graph:
            if not types:
                continue
            if self._foxglove is not None:
                self._foxglove.offer(self, topic, types[0])
            if view_topic(topic) is None:
                continue
            found = view_topic(topic)[0]
            if (team_table and found in CATCH_TABLE_REPLACES) or (track and found in TRACK_REPLACES):
                self._unsubscribe(topic)
                continue
            if topic in self._subs:
                continue
            if types[0] != found.type_name:
                self._warn.warn(f"type:{topic}", f"{topic} has type {types[0]}, not {found.type_name}: not shown")
                continue
            depth = 20 if found is contract.SIM_EVENTS else 1
            qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth, reliability=ReliabilityPolicy.BEST_EFFORT,
                             durability=DurabilityPolicy.VOLATILE)
            if found in CALLBACK_TOPICS:
                qos = found.qos if found.qos.durability == DurabilityPolicy.TRANSIENT_LOCAL else qos
                callback = functools.partial(self._on_rare_message, topic, found.type_name)
                self._subs[topic] = contract_subscription(self, found, callback, topic, raw=True, qos=qos)
                self._types[topic] = found.type_name
                self._rare.add(topic)
                continue
            sub = contract_subscription(self, found, lambda _msg: None, topic, raw=True, qos=qos)
            self._subs[topic] = sample_only(sub)
            if found in VALUE_TOPICS:
                self._last_value[topic] = b""
            self._types[topic] = found.type_name

    def _on_rare_message(self, topic: str, type_name: str, data: bytes) -> None:
        """A message of CALLBACK_TOPICS (in the executor's thread): applied now, sent with the next frame."""
        with self._lock:
            self._apply(topic, type_name, data)
            self._rare_applied = True

    def _apply(self, topic: str, type_name: str, data: bytes) -> None:
        try:
            msg = decode(type_name, data)
        except Exception as exc:
            self._warn.warn(f"decode:{topic}", f"{topic}: undecodable message ({exc})")
            return
        if not self._state.apply(topic, msg):
            self._warn.warn(f"bad:{topic}", f"{topic}: refused (bad numbers, shape or stamp)")

    def _unsubscribe(self, topic: str) -> None:
        sub = self._subs.pop(topic, None)
        if sub is not None:
            sample_only(sub, False)
            self.destroy_subscription(sub)
            self._types.pop(topic, None)
            self._rare.discard(topic)
            self._last_value.pop(topic, None)

    def _tick(self) -> None:
        """One frame (in the server's tick thread). A Ctrl-C shuts rclpy's context down from the main thread,
        maybe under this tick's takes: what that raises is the shutdown, not a fault."""
        if not self.context.ok():
            return
        with self._lock:
            try:
                self._take_and_send()
            except Exception:
                if self.context.ok():
                    raise

    def _take_and_send(self) -> None:
        if self._foxglove is not None:
            self._foxglove.forward()
        pages = self._server.client_count > 0
        foxglove = self._foxglove is not None and self._foxglove.has_clients()
        if not (pages or foxglove):
            return
        taken, self._rare_applied = int(self._rare_applied), False
        for topic, sub in self._subs.items():
            if topic in self._rare or not self._state.takes(topic):
                continue
            for data in _take_newest(sub):
                if topic in self._last_value:
                    if data == self._last_value[topic]:
                        continue  # the same value again (published with every ball frame)
                    self._last_value[topic] = data
                taken += 1
                self._apply(topic, self._types[topic], data)
        if not taken:
            return  # nothing new: the pages keep the last frame
        if pages:
            self._server.publish(self._state.frame_bytes())
        if foxglove:
            self._foxglove.publish_frame(self._state.frame())

    def _on_request(self, request: dict) -> dict:
        """A page's requests (in that page's thread of the server): ``{"info": 1}``, ``{"replay": t_s}``."""
        if "info" in request:
            replay = self._replay
            return {"info": {"replay": None if replay is None else {"start": replay.start_s, "end": replay.end_s}}}
        if "replay" in request:
            if self._replay is None:
                return {"error": "no bag to replay (parameter bag)"}
            t = request["replay"]
            if not isinstance(t, int | float) or isinstance(t, bool):
                raise ValueError(f"replay: a time in seconds, got {t!r}")
            with self._replay_lock:  # pages ask from threads of their own
                return {"frame": self._replay.frame_at(float(t))}
        raise ValueError(f"unknown request {json.dumps(request)[:80]}")

    def destroy_node(self) -> None:
        self._server.stop()
        if self._foxglove is not None:
            self._foxglove.stop()
        super().destroy_node()


def main(args: list[str] | None = None) -> int:
    observe_only()  # before rclpy starts its threads
    return run_node(FieldViewNode, args)


if __name__ == "__main__":
    raise SystemExit(main())
