"""Hold the gripper in the platform's frame while the platform drives (wbc.RelativeFrameTask).

The youBot drives along an arc (BaseVelocityTask: 0.2 m/s forward, 0.3 rad/s yaw); the gripper
moves to a pose given in the platform's frame ``base_link`` and holds it there, whatever the
platform does: a tray carried at a fixed place on the robot. The task is written the new way,
its error and Jacobian only (wbc/tasks/relative_frame_task.py; docs/extending.md).

Run: ``python examples/relative_frame_task.py``
"""

from __future__ import annotations

import numpy as np

import wbc


def main() -> tuple[np.ndarray, np.ndarray]:
    """Run 3 s; return the final configuration and the gripper's target pose in the platform."""
    robot = wbc.load_robot("youbot")
    q = np.array([0.0, 0.0, 0.0, 0.2, 0.6, -0.8, 1.2, 0.3])
    # the target in the platform: the gripper's pose at other arm angles (the 5-joint arm reaches it)
    reach = q + [0.0, 0.0, 0.0, 0.3, -0.2, 0.25, 0.1, -0.3]
    tray = wbc.RelativeFrameTask("ee", "base_link", position_cost=1.0, orientation_cost=0.5, gain=0.3)
    target = np.linalg.solve(robot.frame_pose(reach, "base_link"), robot.frame_pose(reach, "ee"))
    tray.set_target(target)
    drive = wbc.BaseVelocityTask(1.0)
    drive.set_target([0.2, 0.0, 0.3])  # [m/s, m/s, rad/s] in the platform's frame
    controller = wbc.Controller(robot, [tray, drive], [wbc.JointPositionLimits(), wbc.JointVelocityLimits()])
    for _ in range(300):
        q = robot.integrate(q, controller.step(q), controller.dt)
    error = controller.last.task_errors["RelativeFrameTask(ee in base_link).position"]
    travelled = float(np.hypot(q[0], q[1]))
    print(f"gripper {error:.1e} m from its place on the platform, platform {travelled:.2f} m from its start, "
          f"status {controller.last.status}")
    return q, target


if __name__ == "__main__":
    main()
