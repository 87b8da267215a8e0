"""A task written outside wbc, in Python: keep a frame at a given height.

One row, ``w (J_z v - gain/dt (z* - z))``: the z row of the frame's world-aligned Jacobian
and the height error. The task is a *specification* (its settings: frame, height, cost,
gain); ``bind`` turns it into the *data* of one controller (the frame resolved against that
controller's robot, the error of the last tick). See docs/extending.md.

Run: ``python examples/custom_task.py``
"""

from __future__ import annotations

import math

import numpy as np

import wbc
from wbc.core.settings import Setting
from wbc.core.validation import as_gain, as_nonnegative, as_number
from wbc.model.kinematics import Kinematics
from wbc.tasks.task import TaskData


class HeightTask(wbc.Task):
    """Hold ``frame`` at height ``height`` [m] (world z); ``cost`` in [cost]/[m]^2."""

    # settings: validated on assignment, may change between ticks (the data reads them every tick)
    height = Setting(as_number)
    cost = Setting(as_nonnegative)
    gain = Setting(as_gain)

    def __init__(self, frame: str, height: float, cost: float = 1.0, gain: float = 0.5) -> None:
        self.frame = frame
        super().__init__(f"HeightTask({frame})")
        self.height, self.cost, self.gain = height, cost, gain

    def bind(self, robot: wbc.Robot) -> HeightTaskData:
        return HeightTaskData(self, robot)


class HeightTaskData(TaskData):
    """The task in one controller: the frame's index in that robot, the last error [m]."""

    dim = 1

    def __init__(self, task: HeightTask, robot: wbc.Robot) -> None:
        super().__init__(task)
        self._frame_id = robot.frame_id(task.frame)  # UnknownFrameError, with suggestions
        self.error = 0.0

    def compute(self, kin: Kinematics, dt: float, jacobian: np.ndarray, target: np.ndarray) -> None:
        task = self.task
        weight = math.sqrt(task.cost)
        self.error = task.height - kin.frame_placement(self._frame_id).translation[2]
        jacobian[0] = weight * kin.frame_jacobian(self._frame_id)[2]
        target[0] = weight * task.gain / dt * self.error

    def report(self, v: np.ndarray, errors: dict[str, float]) -> None:
        errors[self.name] = abs(self.error)


def main() -> float:
    robot = wbc.load_robot("youbot")
    q = np.array([0.0, 0.0, 0.0, 0.0, 0.5, 1.0, 1.2, 0.0])
    height = HeightTask("ee", height=0.35, cost=1.0)
    controller = wbc.Controller(robot, [height, wbc.PostureTask(1e-3, target=q, gain=0.05)],
                                [wbc.JointPositionLimits(), wbc.JointVelocityLimits()])
    for _ in range(300):
        q = robot.integrate(q, controller.step(q), controller.dt)
    error = controller.last.task_errors["HeightTask(ee)"]
    print(f"gripper height {robot.frame_pose(q, 'ee')[2, 3]:.4f} m (target 0.35), error {error:.2e} m, "
          f"status {controller.last.status}")
    return error


if __name__ == "__main__":
    main()
