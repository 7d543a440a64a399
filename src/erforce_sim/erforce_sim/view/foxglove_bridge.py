"""The field view for Foxglove: a Foxglove WebSocket server (the ``foxglove`` SDK) that forwards the
graph's topics and draws the page's field as a SceneUpdate.

Every topic of a standard ROS 2 type goes out as it was sent: its CDR bytes (``cdr``) with the
type's message definition (``ros2msg``, the text ``ros2 bag`` writes into MCAP; rosbags generates
it), so Foxglove decodes them itself. Its subscriptions are best effort (a publisher never waits
for the bridge) and are taken only while a Foxglove client listens. Two channels of its own come
from the field view's frames (erforce_sim.view.field_view): ``/field_view/scene`` (a foxglove
SceneUpdate in frame ``field``: field lines, robots with ids and headings, the ball, the predicted
path, stop point, catch points and the receiver's target, in the page's colours) and
``/field_view/plots`` (JSON: the ball speed against the model, the followed robot's currents
against the limit). config/foxglove_layout.json (``layout_json()``) lays them out like the page.
"""

from __future__ import annotations

import json
import math
from typing import Any

import foxglove
from foxglove import Channel, Context, Schema
from foxglove.channels import SceneUpdateChannel
from foxglove.messages import (
    ArrowPrimitive,
    Color,
    CylinderPrimitive,
    LinePrimitive,
    LinePrimitiveLineType,
    Point3,
    Pose,
    Quaternion,
    SceneEntity,
    SceneUpdate,
    SpherePrimitive,
    TextPrimitive,
    Timestamp,
    Vector3,
)

SCENE_TOPIC = "/field_view/scene"
PLOTS_TOPIC = "/field_view/plots"
FOLLOWED_ROBOT = 0  # whose motor currents the plots channel carries
FORWARD_DEPTH = 200  # messages a topic may queue between two forwards
# The page's colours (web/field_view.js).
COLORS = {
    "grass": "#2b6b34", "lines": "#f4f4f4", "ours": "#2f7de1", "opponent": "#f2d22e", "ball": "#ff8a00",
    "slide": "#ff4d4d", "roll": "#37d0ff", "stop": "#ffffff", "catch": "#ffffff", "target": "#b6ff3b",
}
BALL_DIAMETER_M = 0.043
ROBOT_HEIGHT_M = 0.15

PLOTS_SCHEMA = {
    "type": "object",
    "properties": {
        "t": {"type": "number", "description": "simulated time [s]"},
        "ball_speed_true": {"type": "number", "description": "ground truth [m/s]"},
        "ball_speed_filtered": {"type": "number", "description": "the predictor's [m/s]"},
        "ball_speed_model": {"type": "number", "description": "the two-phase model since the kick [m/s]"},
        "current_limit_a": {"type": "number"},
        "robot": {"type": "integer"},
        "avg_current_a": {"type": "array", "items": {"type": "number"}},
    },
}


def ros2msg_schema(type_name: str) -> Schema:
    """The ``ros2msg`` schema of a ROS 2 type (``pkg/msg/Name``): its definition and its dependencies'."""
    from rosbags.typesys import Stores, get_typestore

    text, _ = get_typestore(Stores.ROS2_JAZZY).generate_msgdef(type_name, ros_version=2)
    return Schema(name=type_name, encoding="ros2msg", data=text.encode())


def _color(hex_color: str, alpha: float = 1.0) -> Color:
    value = int(hex_color.lstrip("#"), 16)
    return Color(r=(value >> 16 & 255) / 255, g=(value >> 8 & 255) / 255, b=(value & 255) / 255, a=alpha)


def _pose(x: float, y: float, z: float = 0.0, yaw: float = 0.0) -> Pose:
    return Pose(position=Vector3(x=x, y=y, z=z), orientation=Quaternion(x=0.0, y=0.0, z=math.sin(yaw / 2),
                                                                          w=math.cos(yaw / 2)))


def _circle(x: float, y: float, radius: float, n: int = 32) -> list[tuple[float, float]]:
    return [(x + radius * math.cos(2 * math.pi * k / n), y + radius * math.sin(2 * math.pi * k / n)) for k in range(n)]


def _line(points, color: str, thickness_px: float, loop: bool = False) -> dict:
    return {"points": [(float(p[0]), float(p[1])) for p in points], "color": color, "thickness": thickness_px,
            "loop": loop}


def scene_shapes(frame: dict[str, Any]) -> dict[str, dict[str, list[dict]]]:
    """The page's drawing of ``frame`` as plain shapes per scene entity (``field``, ``robots``, ``ball``),
    in field coordinates: lines (polylines, thickness in pixels), cylinders (robot bodies), arrows
    (headings), texts, spheres (the ball). ``scene_update`` makes the foxglove messages of them."""
    f = frame["field"]
    half_l, half_w, b = f["length"] / 2, f["width"] / 2, f["boundary"]
    field_lines = [
        _line([(-half_l - b, -half_w - b), (half_l + b, -half_w - b), (half_l + b, half_w + b),
               (-half_l - b, half_w + b)], "#555c63", 3, loop=True),
        _line([(-half_l, -half_w), (half_l, -half_w), (half_l, half_w), (-half_l, half_w)], COLORS["lines"], 2,
              loop=True),
        _line([(0.0, -half_w), (0.0, half_w)], COLORS["lines"], 2),
        _line(_circle(0.0, 0.0, f["centre_circle"], 48), COLORS["lines"], 2, loop=True),
    ]
    radius = frame["robot_radius"]
    robots: dict[str, list[dict]] = {"cylinders": [], "arrows": [], "texts": [], "lines": []}
    for r in frame["robots"]:
        x, y, yaw = r["pose"]
        color = COLORS["opponent" if r["team"] == "opponent" else "ours"]
        robots["cylinders"].append({"x": x, "y": y, "radius": radius, "color": color})
        robots["arrows"].append({"x": x, "y": y, "yaw": yaw, "length": radius})
        robots["texts"].append({"x": x, "y": y, "text": str(r["id"]), "size": 14, "color": "#ffffff"})
        if r["catch_point"]:
            cx, cy = r["catch_point"]
            robots["lines"].append(_line(_circle(cx, cy, 0.06), COLORS["catch"], 2, loop=True))
            robots["texts"].append({"x": cx, "y": cy + 0.12, "text": f"{r['id']}: {r['catch_time']:.2f} s",
                                    "size": 12, "color": COLORS["catch"]})
    ball: dict[str, list[dict]] = {"spheres": [], "lines": []}
    shown = frame["ball"].get("truth") or frame["ball"].get("state")
    if shown:
        ball["spheres"].append({"x": shown[0], "y": shown[1], "diameter": BALL_DIAMETER_M, "color": COLORS["ball"]})
    path = frame["path"]
    if path:
        ball["lines"].append(_line([path["start"], path["switch"]], COLORS["slide"], 4))
        ball["lines"].append(_line([path["switch"], path["stop"]], COLORS["roll"], 4))
    if frame["stop_point"]:
        sx, sy = frame["stop_point"]
        ball["lines"].append(_line([(sx - 0.06, sy - 0.06), (sx + 0.06, sy + 0.06)], COLORS["stop"], 2))
        ball["lines"].append(_line([(sx - 0.06, sy + 0.06), (sx + 0.06, sy - 0.06)], COLORS["stop"], 2))
    if frame["receiver"]:
        tx, ty = frame["receiver"]["target"]
        ball["lines"].append(_line(_circle(tx, ty, 0.1), COLORS["target"], 4, loop=True))
    return {"field": {"lines": field_lines}, "robots": robots, "ball": ball}


def scene_update(frame: dict[str, Any], stamp_ns: int) -> SceneUpdate:
    """``scene_shapes`` of ``frame`` as a foxglove SceneUpdate in frame ``field``."""
    stamp = Timestamp(stamp_ns // 1_000_000_000, stamp_ns % 1_000_000_000)
    entities = []
    for entity_id, shapes in scene_shapes(frame).items():
        parts: dict[str, list] = {}
        parts["lines"] = [LinePrimitive(
            type=LinePrimitiveLineType.LineLoop if ln["loop"] else LinePrimitiveLineType.LineStrip,
            pose=_pose(0.0, 0.0), thickness=ln["thickness"], scale_invariant=True,
            points=[Point3(x=x, y=y, z=0.002) for x, y in ln["points"]], color=_color(ln["color"]))
            for ln in shapes.get("lines", ())]
        parts["cylinders"] = [CylinderPrimitive(
            pose=_pose(c["x"], c["y"], ROBOT_HEIGHT_M / 2),
            size=Vector3(x=2 * c["radius"], y=2 * c["radius"], z=ROBOT_HEIGHT_M), bottom_scale=1.0, top_scale=1.0,
            color=_color(c["color"])) for c in shapes.get("cylinders", ())]
        parts["arrows"] = [ArrowPrimitive(
            pose=_pose(a["x"], a["y"], ROBOT_HEIGHT_M + 0.01, a["yaw"]), shaft_length=a["length"], shaft_diameter=0.02,
            head_length=0.04, head_diameter=0.05, color=_color("#0b0d10")) for a in shapes.get("arrows", ())]
        parts["texts"] = [TextPrimitive(
            pose=_pose(t["x"], t["y"], ROBOT_HEIGHT_M + 0.05), billboard=True, font_size=t["size"],
            scale_invariant=True, color=_color(t["color"]), text=t["text"]) for t in shapes.get("texts", ())]
        parts["spheres"] = [SpherePrimitive(
            pose=_pose(b["x"], b["y"], b["diameter"] / 2), size=Vector3(x=b["diameter"], y=b["diameter"],
                                                                         z=b["diameter"]),
            color=_color(b["color"])) for b in shapes.get("spheres", ())]
        entities.append(SceneEntity(timestamp=stamp, frame_id="field", id=entity_id, **parts))
    return SceneUpdate(entities=entities)


def plots_message(frame: dict[str, Any], robot_id: int = FOLLOWED_ROBOT) -> dict[str, Any]:
    speed = frame["speed"]
    message: dict[str, Any] = {"t": frame["t"], "current_limit_a": frame["current_limit"], "robot": robot_id}
    for key in ("truth", "filtered", "model"):
        if key in speed:
            message[f"ball_speed_{'true' if key == 'truth' else key}"] = speed[key]
    robot = next((r for r in frame["robots"] if r["id"] == robot_id), None)
    if robot is not None:
        message["avg_current_a"] = robot["avg_current"]
    return message


class FoxgloveBridge:
    """The server and its channels; a node feeds it (``offer``, ``forward``, ``publish_frame``)."""

    def __init__(self, host: str, port: int) -> None:
        self.context = Context()
        self.server = foxglove.start_server(name="erforce field_view", host=host, port=port, context=self.context)
        self._scene = SceneUpdateChannel(SCENE_TOPIC, context=self.context)
        self._plots = Channel(PLOTS_TOPIC, schema=PLOTS_SCHEMA, context=self.context)
        self._forwarded: dict[str, tuple[Any, Channel]] = {}  # topic -> (subscription, channel)
        self._refused: set[str] = set()

    @property
    def port(self) -> int:
        return self.server.port()

    def offer(self, node, topic: str, type_name: str) -> bool:
        """Forward ``topic`` from now on (once); False for a type without a known definition."""
        if topic in self._forwarded or topic in self._refused:
            return topic in self._forwarded
        from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy

        from erforce_interfaces.runtime.executor import sample_only
        from erforce_interfaces.wire.contract import message_class

        try:
            schema = ros2msg_schema(type_name)
            msg_type = message_class(type_name)
        except (KeyError, ImportError, AttributeError, ValueError):
            self._refused.add(topic)
            return False
        channel = Channel(topic, schema=schema, message_encoding="cdr", context=self.context)
        qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=FORWARD_DEPTH,
                         reliability=ReliabilityPolicy.BEST_EFFORT)
        sub = sample_only(node.create_subscription(msg_type, topic, lambda _msg: None, qos, raw=True))
        self._forwarded[topic] = (sub, channel)
        return True

    def forward(self) -> int:
        """Send what arrived on the forwarded topics to the clients that subscribed to them."""
        from erforce_interfaces.runtime.executor import take_queued

        sent = 0
        for sub, channel in self._forwarded.values():
            if not channel.has_sinks():
                continue
            for data, info in take_queued(sub):
                channel.log(bytes(data), log_time=info["source_timestamp"])
                sent += 1
        return sent

    def has_clients(self) -> bool:
        return self._scene.has_sinks() or self._plots.has_sinks()

    def publish_frame(self, frame: dict[str, Any], stamp_ns: int | None = None) -> None:
        stamp = round(frame["t"] * 1e9) if stamp_ns is None else stamp_ns
        if self._scene.has_sinks():
            self._scene.log(scene_update(frame, stamp), log_time=stamp)
        if self._plots.has_sinks():
            self._plots.log(plots_message(frame), log_time=stamp)

    def stop(self) -> None:
        self.server.stop()


def layout_json() -> str:
    """The Foxglove layout of config/foxglove_layout.json: the field top-down as the page draws it,
    the ball speed against the model, robot_0's motor currents against the limit."""
    import foxglove.layouts as fl

    scene = fl.ThreeDeePanel(
        title="Field (as the field view draws it)",
        config=fl.ThreeDeeConfig(
            follow_tf="field", fixed_frame="field", follow_mode="follow-none",
            camera_state=fl.ThreeDeeCameraState(perspective=False, distance=11.0, phi=0.0, theta_offset=90.0,
                                                target=(0.0, 0.0, 0.0)),
            scene=fl.BaseRendererSceneSettings(background_color="#2b6b34"),
            topics={SCENE_TOPIC: fl.BaseRendererSceneUpdateTopicSettings(visible=True)},
        ),
    )
    speed = fl.PlotPanel(title="Ball speed [m/s]: true, filtered, model", config=fl.PlotConfig(
        paths=[fl.PlotSeries(value=f"{PLOTS_TOPIC}.ball_speed_true", label="true", color="#ffffff"),
               fl.PlotSeries(value=f"{PLOTS_TOPIC}.ball_speed_filtered", label="filtered", color=COLORS["roll"]),
               fl.PlotSeries(value=f"{PLOTS_TOPIC}.ball_speed_model", label="model", color=COLORS["ball"],
                             line_style="dashed")],
        min_y_value=0.0, following_view_width=6.0, time_window_mode="sliding"))
    wheel_colors = ("#ff6b6b", "#4dd4ff", "#c6ff4d", "#ffb84d")
    currents = fl.PlotPanel(title=f"Motor currents of robot_{FOLLOWED_ROBOT} [A] (10 s average) and the limit",
                            config=fl.PlotConfig(
        paths=[fl.PlotSeries(value=f"{PLOTS_TOPIC}.avg_current_a[{k}]", label=f"wheel {k}", color=c)
               for k, c in enumerate(wheel_colors)]
        + [fl.PlotSeries(value=f"{PLOTS_TOPIC}.current_limit_a", label="limit", color="#ff5c5c", line_style="dashed")],
        min_y_value=0.0, following_view_width=30.0, time_window_mode="sliding"))
    layout = fl.Layout(content=fl.SplitContainer(direction="row", items=[
        fl.SplitItem(proportion=2, content=scene),
        fl.SplitItem(proportion=1, content=fl.SplitContainer(direction="column", items=[
            fl.SplitItem(content=speed), fl.SplitItem(content=currents),
            fl.SplitItem(content=fl.RawMessagesPanel(title="Ball state", config=fl.RawMessagesConfig(
                topic_path="/ball/state"))),
        ])),
    ]))
    return json.dumps(json.loads(layout.to_json()), indent=2) + "\n"


if __name__ == "__main__":  # regenerate the layout file: python -m erforce_sim.view.foxglove_bridge > config/...
    print(layout_json(), end="")
