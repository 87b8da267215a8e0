"""A task written outside wbc whose rows come from a compiled (numba) kernel: pull every
bounded joint toward the middle of its range, harder near the limits.

Row i: ``w_i (v_i - gain/dt (m_i - q_i))`` with ``m_i`` the middle of joint i's range and
``w_i = sqrt(cost) / (1 - s_i^2)``, ``s_i = (q_i - m_i) / half_range_i`` (clipped to 0.99):
a soft joint-limit avoidance that costs little in mid-range.

The arithmetic is one ``@njit`` kernel with an explicit signature (compiled when this module
is imported, cached on disk, never inside a tick); the data's ``compute`` calls it on the
task's settings and the controller's buffers (views, nothing allocated per tick). wbc's own
compiled items run inside the controller's single native call; a third-party kernel runs as
one extra compiled call per tick (about 0.3 us). See docs/extending.md.

Run: ``python examples/custom_compiled_task.py``
"""

from __future__ import annotations

import numpy as np
from numba import njit

import wbc
from wbc.kinematics import Kinematics
from wbc.settings import Operand
from wbc.tasks.task import TaskData
from wbc.validation import as_gain, as_nonnegative


@njit("void(float64[:], int64[:], int64[:], float64[:], float64[:], float64, float64, float64, "
      "float64[:, :], float64[:], float64[:])", cache=True, nogil=True)
def centering_rows(q, q_index, v_index, middle, half_range, cost, gain, dt, jacobian, target, error):
    """Rows of CenteringTask (layout in the module docstring)."""
    root = np.sqrt(cost)
    for i in range(len(q_index)):
        offset = q[q_index[i]] - middle[i]
        s = min(abs(offset) / half_range[i], 0.99)
        weight = root / (1.0 - s * s)
        error[i] = -offset
        jacobian[i, :] = 0.0
        jacobian[i, v_index[i]] = weight
        target[i] = weight * gain / dt * error[i]


class CenteringTask(wbc.Task):
    """Keep the bounded 1-DOF joints away from their limits; ``cost`` in [cost]/[rad]^2."""

    # settings: validated on assignment, kept in the array the kernel reads every tick
    cost = Operand("_settings", 0, as_nonnegative)
    gain = Operand("_settings", 1, as_gain)

    def __init__(self, cost: float = 1e-2, gain: float = 0.1) -> None:
        super().__init__("CenteringTask")
        self._settings = np.zeros(2)  # (cost, gain), read by the kernel every tick
        self.cost, self.gain = cost, gain

    def bind(self, robot: wbc.Robot) -> CenteringTaskData:
        return CenteringTaskData(self, robot)


class CenteringTaskData(TaskData):
    """The task in one controller: the robot's bounded joints, their ranges, the last error."""

    def __init__(self, task: CenteringTask, robot: wbc.Robot) -> None:
        super().__init__(task)
        joints = [j for j in robot.model.joints[1:] if j.nq == 1 and j.nv == 1
                  and np.isfinite(robot.lower[j.idx_q]) and np.isfinite(robot.upper[j.idx_q])]
        self._q_index = np.array([j.idx_q for j in joints], dtype=np.int64)
        self._v_index = np.array([j.idx_v for j in joints], dtype=np.int64)
        lower, upper = robot.lower[self._q_index], robot.upper[self._q_index]
        self._middle, self._half_range = 0.5 * (lower + upper), 0.5 * (upper - lower)
        self.dim = len(joints)
        self.error = np.zeros(self.dim)

    def compute(self, kin: Kinematics, dt: float, jacobian: np.ndarray, target: np.ndarray) -> None:
        cost, gain = self.task._settings
        centering_rows(kin.q, self._q_index, self._v_index, self._middle, self._half_range, cost, gain, dt,
                       jacobian, target, self.error)

    def report(self, v: np.ndarray, errors: dict[str, float]) -> None:
        errors[self.name] = float(np.max(np.abs(self.error)))


def main() -> float:
    robot = wbc.load_robot("youbot")
    q = np.array([0.0, 0.0, 0.0, 2.8, 1.4, -2.4, 1.6, 2.7])  # several arm joints near a limit
    ee = wbc.FrameTask("ee", position_cost=1.0, orientation_cost=0.0, gain=0.5)
    ee.set_target_from_configuration(robot, q)  # hold the gripper position
    centering = CenteringTask(cost=1e-2, gain=0.1)
    controller = wbc.Controller(robot, [ee, centering], [wbc.JointPositionLimits(), wbc.JointVelocityLimits()])
    controller.step(q)
    start = controller.last.task_errors["CenteringTask"]
    for _ in range(300):
        q = robot.integrate(q, controller.step(q), controller.dt)
    errors = controller.last.task_errors
    print(f"largest offset from mid-range {start:.3f} -> {errors['CenteringTask']:.3f} rad while the gripper "
          f"stays within {errors['FrameTask(ee).position'] * 1e3:.2f} mm; status {controller.last.status}")
    return errors["CenteringTask"] / start


if __name__ == "__main__":
    main()
