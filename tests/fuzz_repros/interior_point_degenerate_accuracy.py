import numpy as np, wbc
robot = wbc.load_robot("puma560")
q = robot.lower.copy()          # every joint exactly on its lower limit
def cmd(solver):
    t = wbc.PositionTask("ee", cost=1.0, gain=1.0)
    t.set_target([0.06752401721830886, 0.18425660712555375, -0.2850287081163513])
    c = wbc.Controller(robot, [t], [wbc.JointPositionLimits(gain=1.0), wbc.JointVelocityLimits()], solver=solver)
    v = c.step(q); return v, c.last.status
ref, _ = cmd("daqp")
for s in wbc.available_solvers():
    if s == "highs": continue
    v, st = cmd(s); print(s, st, np.max(np.abs(v - ref)))
