"""The simulator with the stack in the loop: everything that closes the loop between the world and the
ball model and motion packages (the physics beside this folder imports neither).

What is here: the in-process worlds (``runner``: plant and motion control; ``scenes``: the paper's scenes
in one process; ``passing_game``: the 11 v 3 game in one process), the demo over DDS and its reports
(``demo``, ``report``, ``passing_report``), the field view (``field_view`` core, ``field_view_node``,
``view_server``, ``foxglove_bridge``, ``headless_browser`` for its test and bench), the SSL log writer
(``ssl_game_log``) and the motor-tuning experiment (``tuning_experiment``).
"""
