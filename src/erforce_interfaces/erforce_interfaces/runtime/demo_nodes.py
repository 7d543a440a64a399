"""A talker and a listener for trying the launcher, the topic tool and the test harness.

They use a topic of their own (``chatter``), not the stack's contract, on purpose: they
exist to show that a graph runs, not to be part of it.
"""

from __future__ import annotations

from rclpy.node import Node
from std_msgs.msg import String

from erforce_interfaces.runtime.node_support import NodeParams, run_node
from erforce_interfaces.runtime.param_schema import load_schema
from erforce_interfaces.wire.contract import QOS_COMMAND

CHATTER = "chatter"


class Talker(Node):
    def __init__(self) -> None:
        super().__init__("talker")
        config = NodeParams(self, load_schema("erforce_interfaces", "talker")).config
        self._text = config.text
        self._count = 0
        self._pub = self.create_publisher(String, CHATTER, QOS_COMMAND)
        self._timer = self.create_timer(1.0 / config.rate_hz, self._tick)

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
