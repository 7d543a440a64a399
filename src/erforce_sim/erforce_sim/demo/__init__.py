"""``./run demo`` and its reports: the demo over the node graph (``demo``), the passing game's report
(``passing_report``), the scenes' plots (``report``) and SSL game logs written from an in-process world
(``ssl_game_log``).

Entry points for a person at the terminal; nothing else in ``src/`` imports it.
"""
