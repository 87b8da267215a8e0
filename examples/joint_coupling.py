"""Couple two joints, softly or exactly: the youBot's gripper reaches a point while its wrist
joints 3 and 4 are asked to turn at the same rate -- as a least-squares wish (wbc.LinearTask,
``A v = b`` weighted against the reach) and as a hard row (wbc.LinearConstraint, exact). Platform
motion is priced ten times arm motion (wbc.DampingTask, per coordinate).

Run: ``python examples/joint_coupling.py``
"""

from __future__ import annotations

import numpy as np

import wbc

COUPLING = [[0, 0, 0, 0, 0, 1, -1, 0]]  # v(arm_joint_3) - v(arm_joint_4) = 0


def main(ticks: int = 300) -> dict[str, tuple[float, float]]:
    """Run both couplings for ``ticks`` ticks of 10 ms; per kind, (largest |v_3 - v_4| [rad/s],
    final distance of the gripper to its target [m])."""
    robot = wbc.load_robot("youbot")
    start = np.array([0.0, 0.0, 0.0, 0.0, 0.5, 1.0, 1.2, 0.0])
    target = robot.frame_pose(start, "ee")[:3, 3] + [0.25, 0.1, -0.1]
    results = {}
    for kind in ("soft", "hard"):
        reach = wbc.PositionTask("ee", gain=0.3)
        reach.set_target(target)
        damping = wbc.DampingTask([1e-2, 1e-2, 1e-2, 1e-3, 1e-3, 1e-3, 1e-3, 1e-3])
        tasks: list[wbc.Task] = [reach, damping]
        constraints: list[wbc.Constraint] = [wbc.JointPositionLimits(), wbc.JointVelocityLimits(),
                                             wbc.MecanumWheelLimits()]
        if kind == "soft":
            tasks.append(wbc.LinearTask(COUPLING, cost=1.0))
        else:
            constraints.append(wbc.LinearConstraint(COUPLING))
        controller = wbc.Controller(robot, tasks, constraints)
        q, worst = start.copy(), 0.0
        for _ in range(ticks):
            v = controller.step(q)
            worst = max(worst, abs(v[5] - v[6]))
            q = robot.integrate(q, v, controller.dt)
        results[kind] = (worst, float(np.linalg.norm(robot.frame_pose(q, "ee")[:3, 3] - target)))
        print(f"{kind}: |v3 - v4| at most {worst:.1e} rad/s, gripper {results[kind][1]:.1e} m from its target")
    return results


if __name__ == "__main__":
    main()
