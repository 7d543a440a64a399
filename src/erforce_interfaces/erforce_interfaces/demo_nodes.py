"""A talker and a listener for trying the launcher, the topic tool and the test harness.

They use a topic of their own (``chatter``), not the stack's contract, on purpose: they
exist to show that a graph runs, not to be part of it.
"""

from __future__ import annotations

from rclpy.node import Node
from std_msgs.msg import String

from erforce_interfaces.contract import QOS_COMMAND
from erforce_interfaces.node_support import ParamSpec, declare_params, run_node

CHATTER = "chatter"

TALKER_PARAMS = (
    ParamSpec("rate_hz", 10.0, "publish rate [Hz]", min=0.1, max=1000.0),
    ParamSpec("text", "hello", "message prefix; a counter is appended"),
)


class Talker(Node):
    def __init__(self) -> None:
        super().__init__("talker")
        values = declare_params(self, TALKER_PARAMS)
        self._text = values["text"]
        self._count = 0
        self._pub = self.create_publisher(String, CHATTER, QOS_COMMAND)
        self._timer = self.create_timer(1.0 / values["rate_hz"], self._tick)

    def _tick(self) -> None:
        self._pub.publish(String(data=f"{self._text} {self._count}"))
        self._count += 1


class Listener(Node):
    def __init__(self) -> None:
        super().__init__("listener")
        self.create_subscription(String, CHATTER, self._on_msg, QOS_COMMAND)

    def _on_msg(self, msg: String) -> None:
        self.get_logger().info(f"I heard: {msg.data}")


def talker_main(args: list[str] | None = None) -> int:
    return run_node(Talker, args)


def listener_main(args: list[str] | None = None) -> int:
    return run_node(Listener, args)
