"""erforce_sim: physics plant of the ER-Force stack (pure Python core; ROS shells live elsewhere).

Where each piece is (paper sections of the ER-Force ETDP 2016):
  world.py       World API used by the plant node and the in-process runner
  world_types.py what a World is built from (RobotSpec, PhysicsParams) and reports (RobotState, ...)
  plant_setup.py a scenario for the plant (PlantSetup) and the World it builds
  drivetrain.py  DC motors, gears, omni wheels with traction limit, robot body, winding temperature (Sec. 4)
  ball.py        ball from sliding/rolling friction; the two-phase model emerges (Sec. 5)
  contacts.py    walls, robot-robot and ball-robot collisions
  kicker.py      flat vs curved kicker plate (Sec. 2.2), light barrier beam geometry (Sec. 3)
  sensors.py     vision frames (rate, latency, noise, dropouts) and the light barrier signal (Sec. 3)
"""
