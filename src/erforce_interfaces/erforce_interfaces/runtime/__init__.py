"""How a node runs: its parameters from one YAML schema per node (``param_schema``), start-up, shutdown
and fault handling (``node_support``), the executor and the rclpy internals it relies on (``executor``,
``rclpy_internals``), lockstep with the simulator (``lockstep``), warm standby (``standby``), numba's
cache and fallbacks (``numba_support``) and the talker/listener demo nodes.

Every node process and the in-process worlds may import it; it imports the wire layer and nothing from
``ssl``, ``tools`` or the other packages.
"""
