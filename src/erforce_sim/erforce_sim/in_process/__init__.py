"""The worlds that run in one process, without DDS: the runner (the plant with every robot's motion
firmware), the demo's scenes, the passing game against opponents, and the motor-tuning experiment.

The same cores as the nodes (predictor, receiver, passing player, firmware) on our physics, ticked in
lockstep: tests, bench and the demo's reports import it. The physics beside this folder imports nothing
from it.
"""
