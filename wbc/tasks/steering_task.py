"""Steer a nonholonomic base toward where a holonomic base would go."""

from __future__ import annotations

import math

import numpy as np

from ..core.errors import InvalidInputError
from ..core.settings import Operand
from ..core.validation import as_gain, as_positive
from ..model.kinematics import Kinematics
from ..model.robot import Robot
from ..runtime import kernels
from ..runtime.program import TickProgram
from .task import Task, TaskData


class SteeringTask(Task):
    """Turn the heading of a nonholonomic base toward the holonomic preview.

    Why: the heading rate ``omega`` of a nonholonomic base has no first-order effect on
    where the base goes. When it has no effect on the task either -- a synchro drive,
    whose chassis and arm do not turn with the wheels (the zero column of De Luca's
    ``J(q)``), or a differential drive whose task point lies on the wheel axle -- a
    one-tick velocity QP sees no reason to steer, and a target that lies sideways is
    never reached. The base is still controllable -- steering and driving generate the
    sideways motion at second order -- so the missing information is *which way the
    base ought to go*. (A differential drive carrying its arm ahead of the axle does
    not need this task: there ``omega`` swings the tool sideways and the plain QP
    steers by itself; adding the task then only fights the arm near the goal.)

    The controller provides it: before the main QP it solves the **holonomic
    relaxation** of the same task stack (all other tasks, no constraints, no
    no-slip rows), ``v_h = argmin sum ||W (J v - r)||^2 + damping ||v||^2``. Its base
    velocity ``(xdot_h, ydot_h)`` is the motion a holonomic base would make now. This
    task asks the heading to align with that direction, forward or backward
    (whichever needs less turning), with a weight that fades with the speed the
    relaxation asks of the base::

        s     = |(xdot_h, ydot_h)|
        delta = wrap_[-pi/2, pi/2)(atan2(ydot_h, xdot_h) - heading)
        row:    sqrt(cost) min(1, s / speed_scale) (omega - gain/dt * delta)

    When the relaxation needs little base motion (the arm alone reaches the target)
    the row fades out and leaves the heading to the other tasks -- important for a
    differential drive, whose heading also turns the arm. It works for any
    nonholonomic base kind and costs one small linear solve per tick.

    Args:
        cost: [cost] / [rad/s]^2.
        gain: fraction of the heading error removed per tick, (0, 1].
        speed_scale: [m/s] relaxation base speed at and above which the row has full weight.
    """

    #: settings that may be changed between ticks (validated; they live in the compiled operand)
    gain = Operand("_parameters", kernels.STEERING_GAIN, as_gain)
    speed_scale = Operand("_parameters", kernels.STEERING_SPEED_SCALE, as_positive)

    @property
    def cost(self) -> float:
        """[cost] / [rad/s]^2."""
        return self._parameters[kernels.STEERING_WEIGHT] ** 2

    @cost.setter
    def cost(self, value: float) -> None:
        self._parameters[kernels.STEERING_WEIGHT] = math.sqrt(as_positive(value, "cost"))

    def __init__(self, cost: float = 1.0, gain: float = 0.1, speed_scale: float = 0.1,
                 name: str | None = None) -> None:
        super().__init__(name)
        self._parameters = np.zeros(kernels.STEERING_SETTINGS)  # kernel operand (layout: kernels.STEERING_*)
        self.cost, self.gain, self.speed_scale = cost, gain, speed_scale

    def bind(self, robot: Robot) -> SteeringTaskData:
        if not robot.base.is_nonholonomic:
            raise InvalidInputError(f"{self.name}: robot '{robot.name}' has a {robot.base.name} base; "
                                    "steering is only needed by nonholonomic bases")
        if robot.base.no_slip_rows().matrix.tolist() != [[0.0, 1.0, 0.0]]:
            raise InvalidInputError(f"{self.name}: robot '{robot.name}' has a {robot.base.name} base, whose no-slip "
                                    "rows are not v_y = 0; SteeringTask turns a base that drives along its x axis")
        return SteeringTaskData(self, robot)

    def __repr__(self) -> str:
        return f"SteeringTask(cost={self.cost}, gain={self.gain}, speed_scale={self.speed_scale})"


class SteeringTaskData(TaskData):
    """A :class:`SteeringTask` in one controller: the base coordinates and the heading error
    of the last tick."""

    python_kernels = ("steering_row",)

    dim = 1
    uses_preview = True
    task: SteeringTask

    def __init__(self, task: SteeringTask, robot: Robot) -> None:
        super().__init__(task)
        self._x, self._y, self._heading = robot.base.indices
        self.error = np.zeros(1)  #: heading error delta [rad]

    def compute_preview(self, kin: Kinematics, dt: float, jacobian: np.ndarray, target: np.ndarray,
                        preview: np.ndarray) -> None:
        """Write the row given the holonomic relaxation's velocity ``preview`` (nv)."""
        kernels.steering_row(preview, kin.q, self._x, self._y, self._heading, self.task._parameters, dt,
                             self.error, jacobian[0], target)

    def add_preview_ops(self, program: TickProgram, kin: Kinematics, stack_t: np.ndarray, start: int,
                        preview: np.ndarray) -> bool:
        program.add(kernels.STEERING, preview=preview, q=kin.q, x=self._x, y=self._y, heading=self._heading,
                    settings=self.task._parameters, error=self.error, stack=stack_t, start=start,
                    nv=stack_t.shape[0] - 1, rows=stack_t.shape[1], nq=len(kin.q))
        return True

    def report(self, v: np.ndarray, errors: dict[str, float]) -> None:
        errors[self.name] = abs(float(self.error[0]))
