"""Developer tools: the launcher (``erforce-launch``), the topic tool (``erforce-topic``), the recorder
(``erforce-record``), the DDS test harness (a pytest plugin) and the README generator.

Nothing outside this folder imports it: a robot-side node needs only the contract, the conversions and
the node helpers.
"""
