"""Linear terms in the objective (NEO's form): the youBot holds its gripper in place while a
wbc.ManipulabilityGradient climbs the arm's own manipulability (``c = -cost grad ln m`` of the
arm's five joints), then drives forward while holding it, pushed by a wbc.LinearCost ``c^T v``
that prefers forward platform motion.

A linear cost has no square: it never fades near a goal, so the held gripper gives way by about
``|c| / (w^2 gain / dt)`` (here a fraction of a millimetre).

Run: ``python examples/linear_cost.py``
"""

from __future__ import annotations

import numpy as np

import wbc

ARM = ["arm_joint_1", "arm_joint_2", "arm_joint_3", "arm_joint_4", "arm_joint_5"]


def main(ticks: int = 300) -> tuple[wbc.Robot, np.ndarray, np.ndarray, np.ndarray]:
    """Climb for ``ticks`` ticks, then drive for as many; return (robot, start q, q after the
    climb, final q)."""
    robot = wbc.load_robot("youbot")
    start = np.array([0.0, 0.0, 0.0, 0.0, 0.3, -0.4, 0.2, 0.0])  # the arm near-folded
    hold = wbc.PositionTask("ee", gain=0.5)
    hold.set_target(robot.frame_pose(start, "ee")[:3, 3])
    climb = wbc.ManipulabilityGradient("ee", cost=3e-4, rows="position", joints=ARM)
    controller = wbc.Controller(robot, [hold, climb], [wbc.JointPositionLimits(), wbc.JointVelocityLimits()])
    q = start.copy()
    for _ in range(ticks):
        q = robot.integrate(q, controller.step(q), controller.dt)
    climbed = q.copy()
    forward = wbc.LinearCost(np.r_[-1e-3, np.zeros(robot.nv - 1)])  # -c: +x, the platform forward
    hold.set_target(robot.frame_pose(q, "ee")[:3, 3] + [0.3, 0.0, 0.0])  # the gripper to go with it
    controller = wbc.Controller(robot, [hold, forward, wbc.DampingTask(1e-3)],
                                [wbc.JointPositionLimits(), wbc.JointVelocityLimits(), wbc.MecanumWheelLimits()])
    for _ in range(ticks):
        q = robot.integrate(q, controller.step(q), controller.dt)
    before, after = (wbc.manipulability(robot, x, "ee", rows="position", joints=ARM) for x in (start, climbed))
    print(f"arm manipulability {before:.2e} -> {after:.2e}; then the platform drove {q[0] - climbed[0]:.2f} m "
          "forward with the gripper")
    return robot, start, climbed, q


if __name__ == "__main__":
    main()
