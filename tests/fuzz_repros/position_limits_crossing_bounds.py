import numpy as np, wbc
robot = wbc.load_robot("youbot")
q = np.array([0, 0, 0, 0, 0.5, 1.0, 1.2, 0.0]); q[4] = robot.upper[4] + 0.01   # 0.01 rad above the limit
for hard in (True, False):
    c = wbc.Controller(robot, [wbc.PostureTask(1.0)],
                       [wbc.JointPositionLimits(gain=0.001)] + ([wbc.JointVelocityLimits()] if hard else []))
    for _ in range(3):
        v = c.step(q); q2 = robot.integrate(q, v, c.dt)
    print(c.last.status, "v[4] =", v[4])
# hard=True: 'fallback: zero command after daqp: infeasible; ...' every tick, q never returns (deadlock)
# hard=False: 'optimal' with v[4] = midpoint of the crossed bounds, not the documented (upper - q)/dt
