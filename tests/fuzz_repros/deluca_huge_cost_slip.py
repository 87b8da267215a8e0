import numpy as np, wbc
robot = wbc.load_robot("deluca_mm")
q = np.array([0.0, 0.0, 0.7, 0.2, 0.8, 1.0])
for cost in [1e6, 1e8, 1e10, 1e12]:
    task = wbc.BaseVelocityTask(cost); task.set_target([0.3, 2.0, 0.5])
    c = wbc.Controller(robot, [task], [wbc.NonholonomicBase(), wbc.JointVelocityLimits()])
    v = c.step(q)
    vx, vy, w = robot.base_twist(q, v)
    print(f"{cost:.0e}", c.last.status, "v_x %.6f v_y(slip) %.2e omega %.6f" % (vx, vy, w))
