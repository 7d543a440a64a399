"""What every package of the stack shares, in four layers by who uses them:

- ``wire``: the contract (topic names, types, QoS), the message conversions and the robot description;
  what a robot-side node must import to speak to the others.
- ``runtime``: how a node runs (parameters from its YAML schema, the executor, stamps filters, standby);
  for every node process.
- ``ssl``: the SSL league's wire formats (vision, simulation control, log files); for the bridges to an
  outside world.
- ``tools``: developer tools (launcher, topic tool, recorder, test harness); nothing in a node imports them.
"""
