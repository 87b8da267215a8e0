"""Every built-in task and constraint, one ready instance each on a shipped robot (tests/test_items.py).

A new item is covered by the generic checks by adding one :class:`Case` here;
``test_every_exported_item_is_registered`` fails until it is.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

import wbc
from wbc.constraints.constraint import Constraint
from wbc.tasks.task import Task

#: per robot: the start configuration q0 and the goal q1 the targets are taken at
CONFIGURATIONS = {
    "youbot": (np.array([0.1, -0.2, 0.3, 0.2, 0.9, -0.8, 1.0, 0.4]),
               np.array([0.3, 0.1, 0.5, 0.5, 0.7, -0.5, 1.2, 0.1])),
    "deluca_mm": (np.array([0.0, 0.0, 0.0, 0.3, 0.4, 0.2]), np.array([0.4, 0.3, 0.6, 0.5, 0.2, 0.4])),
    # the PUMA 560 on a free-flyer root: (position, unit quaternion (x, y, z, w), joints)
    "floating_puma": (np.r_[0.1, -0.2, 0.3, np.array([0.1, -0.2, 0.1, 1.0]) / np.sqrt(1.06),
                            0.2, -0.5, 0.3, 0.4, 0.6, -0.2],
                      np.r_[0.2, 0.1, 0.5, np.array([-0.1, 0.1, 0.3, 1.0]) / np.sqrt(1.11),
                            0.4, -0.3, 0.5, 0.2, 0.9, 0.1]),
}


def load(name: str) -> wbc.Robot:
    """The robot of a case: a shipped one by name; ``floating_puma`` the PUMA 560 on a floating base."""
    if name == "floating_puma":
        import pinocchio as pin

        from wbc.model.mobile_base import FloatingBase
        model = pin.buildModelFromUrdf(str(wbc.model_path("puma560")), pin.JointModelFreeFlyer())
        return wbc.Robot("floating_puma", model, base=FloatingBase())
    return wbc.load_robot(name)


@dataclass(frozen=True)
class Case:
    """One item: ``make(robot, q1)`` builds it with its targets taken at ``q1``.

    ``feedback_gain``: the rows feed back an error with this gain, so by the chain rule, at
    ``q1`` (error zero, no saturation) the target column satisfies ``d(W r)/dq v = -gain/dt (W J) v``
    (a constraint's ``h`` and bounds: ``dh/dq v = -gain/dt G v``, ``d ub/dq v = -gain/dt v``);
    None when the rows feed back no error (``note`` says what covers them instead)."""

    name: str
    robot: str
    make: Callable[[wbc.Robot, np.ndarray], Task | Constraint]
    feedback_gain: float | None
    note: str = ""


def _frame_task(robot: wbc.Robot, q: np.ndarray) -> Task:
    task = wbc.FrameTask("ee", position_cost=[1.0, 2.0, 0.5], orientation_cost=0.3, gain=0.4)
    task.set_target(robot.frame_pose(q, "ee"))
    return task


def _position_task(robot: wbc.Robot, q: np.ndarray) -> Task:
    task = wbc.PositionTask("ee", cost=[1.0, 2.0, 0.5], gain=0.4)
    task.set_target(robot.frame_pose(q, "ee")[:3, 3])
    return task


def _relative_frame_task(robot: wbc.Robot, q: np.ndarray) -> Task:
    task = wbc.RelativeFrameTask("ee", "arm_link_1", position_cost=2.0, orientation_cost=0.5, gain=0.4)
    task.set_target_from_configuration(robot, q)
    return task


def _base_velocity_task(robot: wbc.Robot, q: np.ndarray) -> Task:
    task = wbc.BaseVelocityTask(1.0)
    task.set_target([0.1, -0.05, 0.2])
    return task


def _manipulability_task(robot: wbc.Robot, q: np.ndarray) -> Task:
    return wbc.ManipulabilityTask("ee", 1.0, gain=0.4, target=wbc.manipulability(robot, q, "ee"))


def _look_at_task(robot: wbc.Robot, q: np.ndarray) -> Task:
    """The gripper's x axis on a point 0.6 m along it (y, z: off the line, so the translation matters)."""
    pose = robot.frame_pose(q, "ee")
    task = wbc.LookAtTask("ee", axis=[1.0, 0.0, 0.0], cost=[1.0, 2.0, 0.5], gain=0.4)
    task.set_target(pose[:3, 3] + 0.6 * pose[:3, 0])
    return task


def _axis_align_task(robot: wbc.Robot, q: np.ndarray) -> Task:
    return wbc.AxisAlignTask("ee", axis=[0.0, 0.0, 1.0], target_axis=robot.frame_pose(q, "ee")[:3, 2], cost=2.0,
                             gain=0.4)


def _sphere_near_the_gripper(robot: wbc.Robot, q: np.ndarray) -> Constraint:
    centre = robot.frame_pose(q, "ee")[:3, 3] + [0.0, 0.0, 0.2]
    return wbc.CollisionAvoidance([wbc.Sphere(centre, 0.05)], self_collision=False, gain=0.4,
                                  detection_distance=0.4)


def _com_task(robot: wbc.Robot, q: np.ndarray) -> Task:
    task = wbc.CoMTask(cost=[1.0, 2.0, 0.5], gain=0.4)
    task.set_target_from_configuration(robot, q)
    return task


def _support_polygon(robot: wbc.Robot, q: np.ndarray) -> Constraint:
    """A rectangle on the platform whose front edge (6 cm ahead of its centre, 1 cm margin) the
    centre of mass (5.5-5.8 cm ahead at q0 and q1) meets when the arm reaches out."""
    return wbc.SupportPolygon([[-0.1, -0.1], [0.07, -0.1], [0.07, 0.1], [-0.1, 0.1]], frame="base_link",
                              margin=0.01, gain=0.4)


def _points_around_the_base(robot: wbc.Robot, q: np.ndarray) -> Constraint:
    c, s = np.cos(q[2]), np.sin(q[2])
    local = np.array([[0.55, 0.05], [-0.1, 0.45], [-0.5, -0.3], [0.2, -0.4]])  # 0.2-0.26 m from the footprint
    points = q[:2] + local @ np.array([[c, s], [-s, c]])
    return wbc.BaseFootprintAvoidance([[-0.29, -0.19], [0.29, -0.19], [0.29, 0.19], [-0.29, 0.19]], points=points,
                                      gain=0.4)


CASES = [
    Case("FrameTask", "youbot", _frame_task, 0.4),
    Case("PositionTask", "youbot", _position_task, 0.4),
    Case("RelativeFrameTask", "youbot", _relative_frame_task, 0.4),
    Case("PostureTask", "youbot", lambda robot, q: wbc.PostureTask(0.5, target=q, gain=0.4), 0.4),
    Case("ManipulabilityTask", "youbot", _manipulability_task, 0.4),
    Case("LookAtTask", "youbot", _look_at_task, 0.4),
    Case("AxisAlignTask", "youbot", _axis_align_task, 0.4),
    Case("DampingTask", "youbot", lambda robot, q: wbc.DampingTask([4.0, 4.0, 2.0, 1.0, 1.0, 0.5, 0.5, 0.5]), None,
         "no error: rows W v, target 0 (tests/test_damping_task.py)"),
    Case("KineticEnergyRegularization", "youbot", lambda robot, q: wbc.KineticEnergyRegularization(0.3), None,
         "no error: rows sqrt(cost) U v, target 0 (tests/test_kinetic_energy.py)"),
    Case("LinearTask", "youbot", lambda robot, q: wbc.LinearTask(
        [[0, 0, 0, 1, -1, 0, 0, 0], [0.5, 0, 0.2, 0, 0, 1, 0, 0]], b=[0.1, -0.2], cost=[1.0, 2.0]), None,
         "a reference, not an error: A v = b in closed loop (tests/test_linear_task.py)"),
    Case("LinearCost", "youbot", lambda robot, q: wbc.LinearCost([1e-4, -2e-4, 3e-4, 0, 1e-4, 0, -1e-4, 2e-4]), None,
         "no error: c^T v, the damped optimum -c / damping (tests/test_linear_cost.py)"),
    Case("ManipulabilityGradient", "youbot", lambda robot, q: wbc.ManipulabilityGradient("ee", 1e-5), None,
         "no error: c = -cost grad ln m (finite differences: tests/test_linear_cost.py)"),
    Case("BaseVelocityTask", "youbot", _base_velocity_task, None, "a velocity reference: J v = r in closed loop"),
    Case("SteeringTask", "deluca_mm", lambda robot, q: wbc.SteeringTask(1e-2, gain=1.0, speed_scale=0.5), None,
         "steers toward the holonomic preview: tests/test_mobile_bases.py (parking)"),
    Case("JointPositionLimits", "youbot", lambda robot, q: wbc.JointPositionLimits(gain=0.4), 0.4),
    Case("JointVelocityLimits", "youbot", lambda robot, q: wbc.JointVelocityLimits(), None, "constant limits"),
    Case("MecanumWheelLimits", "youbot", lambda robot, q: wbc.MecanumWheelLimits(), None, "wheel-speed rows"),
    Case("WheelSpeedLimits", "youbot", lambda robot, q: wbc.WheelSpeedLimits(), None, "wheel-speed rows"),
    Case("NonholonomicBase", "deluca_mm", lambda robot, q: wbc.NonholonomicBase(), None, "the no-slip row"),
    Case("ManipulabilityBarrier", "youbot",
         lambda robot, q: wbc.ManipulabilityBarrier("ee", 0.5 * wbc.manipulability(robot, q, "ee"), gain=0.4), 0.4),
    Case("CollisionAvoidance", "youbot", _sphere_near_the_gripper, 0.4),
    Case("AccelerationLimits", "youbot", lambda robot, q: wbc.AccelerationLimits(max_jerk=50.0), None,
         "bounds around the previous command: tests/test_acceleration_limits.py"),
    Case("CoMTask", "youbot", _com_task, 0.4),
    Case("SupportPolygon", "youbot", _support_polygon, 0.4),
    Case("DofFreezing", "youbot", lambda robot, q: wbc.DofFreezing(["arm_joint_2", "base_yaw"]), None,
         "constant bounds v_j = 0"),
    Case("BaseFootprintAvoidance", "youbot", _points_around_the_base, 0.4),
    Case("LinearConstraint", "youbot", lambda robot, q: wbc.LinearConstraint([[0, 0, 0, 1, -1, 0, 0, 0]]), None,
         "constant rows A v = b (tests/test_linear_cost.py)"),
    Case("MimicJoints", "youbot", lambda robot, q: wbc.MimicJoints([("arm_joint_5", "arm_joint_4", 0.5)]), None,
         "constant equality rows v_j = m v_leader (tests/test_mimic_joints.py)"),
]

#: items that read the whole velocity vector, again on a floating base (free-flyer coordinates)
CASES += [Case(case.name, "floating_puma", case.make, case.feedback_gain, case.note) for case in CASES
          if case.name in ("FrameTask", "PositionTask", "PostureTask", "LookAtTask",
                           "AxisAlignTask", "ManipulabilityTask", "JointPositionLimits", "JointVelocityLimits")]
