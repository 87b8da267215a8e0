import numpy as np, wbc
youbot, puma = wbc.load_robot("youbot"), wbc.load_robot("puma560")
qy = np.array([0, 0, 0, 0, 0.5, 1.0, 1.2, 0.0])
def make(i):
    ee = wbc.PositionTask("ee", 1.0, gain=0.5); ee.set_target([0.3, 0.1, 0.4])
    return [[ee], [wbc.PostureTask(1e-2, gain=0.5)], [wbc.JointPositionLimits(0.5)], [wbc.JointVelocityLimits()]][i]
base = lambda i: [[wbc.PostureTask(1e-3)], []] if i >= 2 else [[], []]
for i, name in enumerate(["PositionTask", "PostureTask", "JointPositionLimits", "JointVelocityLimits"]):
    obj = make(i)
    def ctl(robot, objs):
        t, c = base(i); (t if i < 2 else c).extend(objs); return wbc.Controller(robot, t, c)
    a = ctl(youbot, obj); ctl(puma, obj); ref = ctl(youbot, make(i))
    print(name, np.max(np.abs(a.step(qy) - ref.step(qy))))
