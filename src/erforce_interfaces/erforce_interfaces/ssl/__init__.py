"""The SSL league's protocols as the league defines them: SSL-Vision datagrams (``ssl_vision``) and the time
of their frames on the receiver (``vision_time``), the
simulation control and robot protocols of ER-Force's simulator and grSim (``ssl_sim``), log files and
their replay (``ssl_log``, ``ssl_log_replay``) and our own ``.proto`` definitions (``ssl_proto``).

For the bridges between an outside world and the graph (the vision bridge, the simulator bridge and
server, the simulated cameras). It imports the wire and runtime layers, never ``tools``.
"""
