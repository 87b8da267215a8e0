import numpy as np, wbc
robot = wbc.load_robot("puma560")               # or "youbot", "scorbot_er4pc": any holonomic / fixed base
c = wbc.Controller(robot, [wbc.PostureTask(1.0)], [], reduced=True)
c.step(np.zeros(6))   # UnboundLocalError: cannot access local variable 'S'
