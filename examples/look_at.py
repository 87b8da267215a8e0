"""Keep the gripper camera on a moving marker while reaching (wbc.LookAtTask).

The youBot carries its gripper to a point 1.5 m ahead (PositionTask; the platform has to drive)
while the camera in the gripper -- its optical axis is the gripper's z axis -- keeps looking at
a marker that slides to and fro on a wall 3 m ahead. Platform motion is priced ten times arm
motion (DampingTask, per coordinate) and the rest of the redundancy is regularised by the
kinetic energy (KineticEnergyRegularization, mass-matrix weighted).

Run: ``python examples/look_at.py``
"""

from __future__ import annotations

import numpy as np

import wbc


def marker(t: float) -> np.ndarray:
    """[m] the marker's world position at time t [s]: 0.4 m to and fro along y, period 6 s."""
    return np.array([3.0, 0.3 + 0.4 * np.sin(2 * np.pi * t / 6.0), 0.5])


def main(ticks: int = 600) -> tuple[np.ndarray, float]:
    """Run ``ticks`` ticks of 10 ms; return the final configuration and the final angle [rad]
    between the camera axis and the direction to the marker."""
    robot = wbc.load_robot("youbot")
    q = np.array([0.0, 0.0, 0.0, 0.0, 0.5, 1.0, 1.2, 0.0])
    reach = wbc.PositionTask("ee", cost=1.0, gain=0.2)
    reach.set_target([1.5, 0.3, 0.35])
    camera = wbc.LookAtTask("ee", axis=[0.0, 0.0, 1.0], cost=0.5, gain=0.3)
    damping = wbc.DampingTask([1e-2, 1e-2, 1e-2, 1e-3, 1e-3, 1e-3, 1e-3, 1e-3])  # platform (x, y, yaw), arm
    energy = wbc.KineticEnergyRegularization(1e-4)
    controller = wbc.Controller(robot, [reach, camera, damping, energy],
                                [wbc.JointPositionLimits(), wbc.JointVelocityLimits(), wbc.MecanumWheelLimits()])
    for k in range(ticks):
        camera.set_target(marker(k * controller.dt))
        q = robot.integrate(q, controller.step(q), controller.dt)
    pose = robot.frame_pose(q, "ee")
    sight = marker(ticks * controller.dt) - pose[:3, 3]
    angle = float(np.arccos(np.clip(pose[:3, 2] @ sight / np.linalg.norm(sight), -1.0, 1.0)))
    print(f"camera {angle:.1e} rad off the marker, gripper {np.linalg.norm(pose[:3, 3] - reach.target):.1e} m "
          f"from its goal, platform {np.hypot(q[0], q[1]):.2f} m from its start, status {controller.last.status}")
    return q, angle


if __name__ == "__main__":
    main()
