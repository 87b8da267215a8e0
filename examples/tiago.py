"""PAL's TIAGo from ``example-robot-data``: its tool to a point 2 m to its side on its own
differential base, the head camera looking at the point all along.

TIAGo's URDF has no base joint (root ``base_footprint``, wheels as continuous joints):
``wbc.load_robot(..., "differential", wheels=[...])`` declares the base, reads the wheel radius
and track from the model and locks nothing else. The hand's fingers are frozen
(``DofFreezing``): the task is the arm's. A point to the side needs the platform to turn
and drive -- a differential base cannot slide sideways (``NonholonomicBase``: zero lateral slip).
The redundancy is damped (``DampingTask``), not pulled to a posture: a posture task would trade
a few millimetres of the tool and a few centiradians of the camera for its own error.

Run: ``python examples/tiago.py`` (needs ``pip install example-robot-data``, in ``wbc[test]``)
"""

from __future__ import annotations

import importlib.metadata
from pathlib import Path

import numpy as np

import wbc

WHEELS = ["wheel_left_joint", "wheel_right_joint"]
CAMERA = "xtion_optical_frame"  # its optical axis is z


def tiago_urdf() -> Path:
    """tiago.urdf inside the installed example-robot-data package."""
    share = importlib.metadata.distribution("example-robot-data").locate_file("cmeel.prefix/share")
    return Path(str(share)) / "example-robot-data/robots/tiago_description/robots/tiago.urdf"


def load_tiago() -> wbc.Robot:
    """TIAGo on a declared differential base (1 m/s, 1 rad/s)."""
    return wbc.load_robot(tiago_urdf(), "differential", wheels=WHEELS, max_linear_speed=1.0, max_yaw_rate=1.0)


def camera_angle(robot: wbc.Robot, q: np.ndarray, point: np.ndarray) -> float:
    """[rad] between the camera's optical axis and the line of sight to ``point``."""
    pose = robot.frame_pose(q, CAMERA)
    sight = point - pose[:3, 3]
    return float(np.arccos(np.clip(pose[:3, 2] @ sight / np.linalg.norm(sight), -1.0, 1.0)))


def main(ticks: int = 1500) -> tuple[wbc.Robot, np.ndarray, np.ndarray, float, float]:
    """Run ``ticks`` ticks of 10 ms; return (robot, final q, the target [m], the largest lateral
    slip of the platform [m/s], the largest camera angle over the last half [rad])."""
    robot = load_tiago()
    q = robot.neutral()
    target = robot.frame_pose(q, "arm_tool_link")[:3, 3] + [0.0, 2.0, 0.0]
    tool = wbc.PositionTask("arm_tool_link", gain=0.5)
    tool.set_target(target)
    head = wbc.LookAtTask(CAMERA, axis=[0.0, 0.0, 1.0], cost=0.1, gain=0.3, target=target)
    hand = [name for name in robot.joint_names if name.startswith("hand_")]
    controller = wbc.Controller(robot, [tool, head, wbc.DampingTask(1e-3)],
                                [wbc.JointPositionLimits(), wbc.JointVelocityLimits(), wbc.NonholonomicBase(),
                                 wbc.WheelSpeedLimits(), wbc.DofFreezing(hand)], dt=0.01)
    slip, late_angle = 0.0, 0.0
    for k in range(ticks):
        v = controller.step(q)
        slip = max(slip, abs(robot.base_twist(q, v)[1]))
        q = robot.integrate(q, v, controller.dt)
        if k >= ticks // 2:
            late_angle = max(late_angle, camera_angle(robot, q, target))
    reached = np.linalg.norm(robot.frame_pose(q, "arm_tool_link")[:3, 3] - target)
    print(f"tool {reached:.1e} m from its target, platform {np.hypot(q[0], q[1]):.2f} m from its start, "
          f"lateral slip {slip:.1e} m/s, camera {late_angle:.1e} rad off the target, status {controller.last.status}")
    return robot, q, target, slip, late_angle


if __name__ == "__main__":
    main()
