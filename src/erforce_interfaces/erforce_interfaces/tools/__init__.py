"""Developer tools: the launcher (``erforce-launch``), the topic tool (``erforce-topic``; messages as text in
``message_text``), the recorder (``erforce-record``), child processes (``processes``), the DDS test harness
(``testing``, a pytest plugin) and the generator of docs/reference.md (``docs``).

For people at a terminal, tests and the bench: the demo (erforce_sim.demo) may import them, no node or core
does, and only test/ and bench/ take the test harness (test/interfaces/test_layers.py).
"""
