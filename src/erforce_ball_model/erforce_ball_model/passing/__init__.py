"""The passing game, AI side: which teammate to pass to and how hard (``decisions``), our team's AI one
tick at a time (``player``, the functional core) and the ``passing_game`` node that runs it on the graph.

No physics: it sees what the protocols carry. The in-process game and its report live with the
simulator (erforce_sim.in_process.passing_game, erforce_sim.demo.passing_report).
"""
