"""The simulator with the stack in the loop: the in-process runner (plant + motion control), the demo's
scenes played in one process, the demo over DDS and its report, and the motor-tuning experiment.

The physics beside this folder imports nothing from the ball model or motion packages; everything that
closes the loop with them lives here.
"""
