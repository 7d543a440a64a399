"""ssl_ball_predictor: ssl_vision_bridge and ball_predictor in one process and one executor.

The two nodes as they are (each with its own name, parameters and schema: ``params/ssl_vision_bridge.yaml``,
``params/ball_predictor.yaml``), hosted together as a component container hosts nodes. The bridge's receive
thread hands each camera frame's serialized ``/vision/robots`` to the predictor (``answer_vision``) before it
publishes it: the predictor answers the frame on that thread, so a datagram's catch times go out one UDP wake
after it arrived, with no DDS write, reader wake or executor round in between. ``/vision/robots``,
``/vision/ball`` and the rest are still published afterwards, for tools and bags. The predictor takes no
``/vision/robots`` from DDS here (it would see its own frames twice); its other subscriptions, parameters and
geometry callbacks run on the executor, one at a time with the frames (the predictor's lock). Frames are answered
in datagram order, each whole (its ball, then its robots) before the next datagram is handled. SSL geometry reaches
the predictor the same way (``take_geometry``), before the frames after it: with ``field: from_geometry`` neither
node judges a frame before the world's field is known.

Parameters: a launch file's inline parameters reach both nodes (their key is ``/**``) and each declares its own;
``field`` and ``num_robots``, in both schemas, mean the same in both. A parameter file may address one node by
name (``/ssl_vision_bridge:`` or ``/ball_predictor:``). Do not rename the node (``name:``/``__node``): the remap
would give both nodes one name.
"""

from __future__ import annotations

from erforce_ball_model.ball_predictor_node import BallPredictorNode
from erforce_ball_model.ssl_vision_bridge_node import SslVisionBridge
from erforce_interfaces.runtime.node_support import run_node


def make_nodes() -> tuple[SslVisionBridge, BallPredictorNode]:
    """The bridge (destroyed first: its receive thread stops before the predictor goes) and the predictor."""
    predictor = BallPredictorNode(vision_topic=False)
    try:
        bridge = SslVisionBridge(frame_sink=predictor.answer_vision, geometry_sink=predictor.take_geometry)
    except BaseException:
        predictor.destroy_node()
        raise
    return bridge, predictor


make_nodes.warm_up = BallPredictorNode.warm_up


def main(args: list[str] | None = None) -> int:
    return run_node(make_nodes, args)


if __name__ == "__main__":
    raise SystemExit(main())
