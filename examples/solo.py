"""Solo-12 (``example-robot-data``), a quadruped on a floating base: three feet held, the fourth
lifted 5 cm and moved 3 cm forward, the centre of mass kept 2 cm inside the triangle of the
three stance feet (``SupportPolygon``) -- a legged robot's first step.

``wbc.load_robot(urdf, base="floating")`` puts the robot on a free flyer (``q[0:7]``: position
and unit quaternion (x, y, z, w); ``v[0:6]``: the base-frame twist). The stance feet are the
top priority level, the swing foot and a posture the second (strict priorities).

Run: ``python examples/solo.py`` (needs ``pip install example-robot-data``, in ``wbc[test]``)
"""

from __future__ import annotations

import importlib.metadata
from pathlib import Path

import numpy as np

import wbc

STANCE = ["FR_FOOT", "HL_FOOT", "HR_FOOT"]
SWING = "FL_FOOT"
STANDING = [0.0, 0.8, -1.6, 0.0, 0.8, -1.6, 0.0, -0.8, 1.6, 0.0, -0.8, 1.6]  # [rad] the twelve leg joints


def solo_urdf() -> Path:
    """solo12.urdf inside the installed example-robot-data package."""
    share = importlib.metadata.distribution("example-robot-data").locate_file("cmeel.prefix/share")
    return Path(str(share)) / "example-robot-data/robots/solo_description/robots/solo12.urdf"


def main(ticks: int = 200) -> tuple[wbc.Robot, np.ndarray, np.ndarray, list[list[float]]]:
    """Run ``ticks`` ticks of 10 ms; return (robot, final q, the swing foot's target [m], the
    support triangle [m], counter-clockwise)."""
    robot = wbc.load_robot(solo_urdf(), base="floating")
    q = robot.neutral()
    q[2], q[7:] = 0.235, STANDING  # the trunk 23.5 cm up, standing on its four feet
    holds = []
    for foot in STANCE:
        hold = wbc.PositionTask(foot)
        hold.set_target(robot.frame_pose(q, foot)[:3, 3])
        holds.append(hold)
    target = robot.frame_pose(q, SWING)[:3, 3] + [0.03, 0.0, 0.05]
    swing = wbc.PositionTask(SWING, gain=0.2)
    swing.set_target(target)
    front_right, hind_left, hind_right = (robot.frame_pose(q, foot)[:2, 3].tolist() for foot in STANCE)
    triangle = [hind_right, front_right, hind_left]  # counter-clockwise
    controller = wbc.Controller(robot, [holds, [swing, wbc.PostureTask(1e-3, target=q)]],
                                [wbc.JointVelocityLimits(), wbc.SupportPolygon(triangle, margin=0.02)])
    for _ in range(ticks):
        q = robot.integrate(q, controller.step(q), controller.dt)
    reached = np.linalg.norm(robot.frame_pose(q, SWING)[:3, 3] - target)
    print(f"swing foot {reached * 1e3:.1f} mm from its target, status {controller.last.status}")
    return robot, q, target, triangle


if __name__ == "__main__":
    main()
