"""Keep a light mobile manipulator from tipping: the youBot's gripper reaches 0.8 m forward
while the platform is held (a costly BaseVelocityTask) and the ground projection of the centre
of mass must stay inside a small polygon fixed to the platform (wbc.SupportPolygon) -- the
arm's reach is limited by the polygon, the base makes up the rest.

Run: ``python examples/com_support.py``
"""

from __future__ import annotations

import numpy as np

import wbc
from wbc.tasks.com_task import center_of_mass

#: [m] in the platform's frame (base_link), counter-clockwise: its front edge 6.5 cm ahead
POLYGON = [[-0.2, -0.15], [0.065, -0.15], [0.065, 0.15], [-0.2, 0.15]]


def com_in_platform(robot: wbc.Robot, q: np.ndarray) -> np.ndarray:
    """The centre of mass [m] in the platform's frame."""
    pose = robot.frame_pose(q, "base_link")
    return pose[:3, :3].T @ (center_of_mass(robot, q) - pose[:3, 3])


def main(ticks: int = 600) -> tuple[wbc.Robot, np.ndarray, float]:
    """Reach for ``ticks`` ticks of 10 ms; return (robot, final q, the largest forward offset of
    the centre of mass in the platform's frame [m])."""
    robot = wbc.load_robot("youbot")
    q = np.array([0.0, 0.0, 0.0, 0.0, 0.5, 1.0, 1.2, 0.0])
    reach = wbc.PositionTask("ee", gain=0.2)
    reach.set_target([0.8, 0.0, 0.1])
    still = wbc.BaseVelocityTask(100.0)
    still.set_target([0.0, 0.0, 0.0])
    support = wbc.SupportPolygon(POLYGON, frame="base_link", gain=0.3)
    constraints = [wbc.JointPositionLimits(), wbc.JointVelocityLimits(), wbc.MecanumWheelLimits(), support]
    controller = wbc.Controller(robot, [reach, still, wbc.PostureTask(1e-3)], constraints)
    forward = -np.inf
    for _ in range(ticks):
        q = robot.integrate(q, controller.step(q), controller.dt)
        forward = max(forward, com_in_platform(robot, q)[0])
    print(f"reach: gripper {np.linalg.norm(robot.frame_pose(q, 'ee')[:3, 3] - reach.target):.3f} m from its "
          f"target, centre of mass at most {forward * 100:.2f} cm ahead of the platform's centre (edge 6.5 cm)")
    return robot, q, forward


if __name__ == "__main__":
    main()
