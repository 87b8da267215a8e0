"""A task written outside wbc whose rows come from a compiled (numba) kernel: pull every
bounded joint toward the middle of its range, harder near the limits.

Row i: ``w_i (v_i - gain/dt (m_i - q_i))`` with ``m_i`` the middle of joint i's range and
``w_i = sqrt(cost) / (1 - s_i^2)``, ``s_i = (q_i - m_i) / half_range_i`` (clipped to 0.99):
a soft joint-limit avoidance that costs little in mid-range.

The arithmetic is one ``@njit`` kernel, declared as a :class:`wbc.runtime.compiled_op.CompiledOp`
(its operands, their shapes, the conditions on its ints) so that it runs *inside* the
controller's tick program, in the same native call as wbc's own items: the data's
``add_ops`` registers it with the task's settings and the controller's buffers (checked
against the declaration there, when the controller is built), and it writes its rows
straight into the controller's task stack. The op is compiled when this module is imported:
in every process (~1 s) when it runs as a script; imported as a module, its callback is cached
by numba (see docs/extending.md).

Run: ``python examples/custom_compiled_task.py``
"""

from __future__ import annotations

import numpy as np
from numba import njit

import wbc
from wbc.core.settings import Operand
from wbc.core.validation import as_gain, as_nonnegative
from wbc.model.kinematics import Kinematics
from wbc.runtime.compiled_op import CompiledOp
from wbc.runtime.program import TickProgram
from wbc.tasks.task import TaskData


@njit(nogil=True)
def centering_rows(q, q_index, v_index, middle, half_range, settings, error, stack_t, start, dim, nv, rows, nq, dt):
    """Rows of CenteringTask (layout in the module docstring) into the stack ``A^T``:
    column ``start + i`` holds row i, ``W J`` in entries ``:nv``, ``W r`` in entry ``nv``."""
    root, gain = np.sqrt(settings[0]), settings[1]
    for i in range(dim):
        offset = q[q_index[i]] - middle[i]
        s = min(abs(offset) / half_range[i], 0.99)
        weight = root / (1.0 - s * s)
        error[i] = -offset
        column = start + i
        for j in range(nv):
            stack_t[j, column] = 0.0
        stack_t[v_index[i], column] = weight
        stack_t[nv, column] = weight * gain / dt * error[i]


CENTERING = CompiledOp("CENTERING", centering_rows, (
    ("q", ("nq",)), ("q_index", ("dim",), "int64"), ("v_index", ("dim",), "int64"), ("middle", ("dim",)),
    ("half_range", ("dim",)), ("settings", (2,)), ("error", ("dim",)), ("stack_t", ("nv + 1", "rows")),
    ("start", None), ("dim", None), ("nv", None), ("rows", None), ("nq", None)),
    checks=("0 <= start", "start + dim <= rows"))


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

    lm_damped = False  # rows on joint coordinates: their linear model is exact (no error-scaled damping)

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

    def add_ops(self, program: TickProgram, kin: Kinematics, stack_t: np.ndarray, start: int) -> bool:
        """Run the kernel inside the controller's tick program (one native call for all items)."""
        program.add(CENTERING, q=kin.q, q_index=self._q_index, v_index=self._v_index, middle=self._middle,
                    half_range=self._half_range, settings=self.task._settings, error=self.error, stack_t=stack_t,
                    start=start, dim=self.dim, nv=stack_t.shape[0] - 1, rows=stack_t.shape[1], nq=kin.q.size)
        return True

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
