"""Joint-space posture regularisation."""

from __future__ import annotations

import weakref
from collections.abc import Sequence

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike

from ..core.errors import InvalidInputError
from ..core.validation import as_gain, as_vector, as_weights
from ..model.kinematics import Kinematics
from ..model.robot import Robot
from ..runtime import kernels
from ..runtime.program import TickProgram
from .task import Task, TaskData, _norm


class PostureTask(Task):
    """Pull the joints toward a reference configuration.

    Error ``e = q* (-) q`` (``pinocchio.difference``, in velocity coordinates) on the
    selected coordinates; rows ``W (v_S - gain/dt * e_S)``.

    Args:
        cost: [cost] / [rad]^2 (or [m]^2 for prismatic joints), scalar or one per selected coordinate.
        target: reference configuration (size nq); ``None`` uses ``robot.neutral()``.
        gain: fraction of the error removed per tick, in (0, 1].
        joints: names of the joints to regulate; ``None`` = every joint that is not
            part of the base, mobile or floating (pulling a base toward a fixed world
            position is rarely wanted).
    """

    #: the data of the controllers using the task, for set_target: a copy starts without them
    _bindings = {**Task._bindings, "_data": weakref.WeakSet}

    def __init__(self, cost: ArrayLike, target: ArrayLike | None = None, gain: float = 1.0,
                 joints: Sequence[str] | None = None,
                 name: str | None = None) -> None:
        super().__init__(name)
        if joints is not None and (isinstance(joints, str) or not all(isinstance(j, str) for j in joints)):
            raise InvalidInputError(f"joints must be a list of joint names, got {joints!r}"
                                    + (f"; write joints=[{joints!r}]" if isinstance(joints, str) else ""))
        self._cost_spec = cost
        self._target_spec = target
        self._joint_spec = joints
        self._settings = np.zeros(kernels.POSTURE_SETTINGS)  # compiled operand (layout: kernels.POSTURE_*), shared
        self.gain = gain
        self._data: weakref.WeakSet[PostureTaskData] = weakref.WeakSet()  # for set_target

    @property
    def gain(self) -> float:
        """Fraction of the error removed per tick, in (0, 1]; may be changed between ticks."""
        return float(self._settings[kernels.POSTURE_GAIN])

    @gain.setter
    def gain(self, value: float) -> None:
        self._settings[kernels.POSTURE_GAIN] = as_gain(value)

    @property
    def target(self) -> ArrayLike | None:
        """The reference configuration as given (``None``: each robot's neutral configuration)."""
        return self._target_spec

    def set_target(self, q: ArrayLike) -> None:
        """New reference configuration (size nq of every robot the task is used with).

        Raises:
            InvalidInputError: ``q`` does not fit one of those robots (then no robot's reference changes).
        """
        for data in self._data:
            data.robot.check_configuration(q)  # all or nothing
        self._target_spec = q
        for data in self._data:
            data.apply_target(q)

    def bind(self, robot: Robot) -> PostureTaskData:
        data = PostureTaskData(self, robot)
        self._data.add(data)
        return data

    def __repr__(self) -> str:
        return f"PostureTask(cost={self._cost_spec!r}, gain={self.gain}, joints={self._joint_spec!r})"


class PostureTaskData(TaskData):
    """A :class:`PostureTask` in one controller: the selected coordinates of the robot, their
    weights and reference, and the error of the last tick."""

    python_kernels = ("posture_rows",)

    diagonal_rows = True  # row i is W_i e_j for the i-th selected coordinate j
    task: PostureTask
    lm_damped = False  # q moves exactly as the rows say: the linear model makes no overshoot

    def __init__(self, task: PostureTask, robot: Robot) -> None:
        super().__init__(task)
        model = robot.model
        base = set(robot.base.velocity_coordinates)
        if task._joint_spec is None:
            joints = [j for j in model.joints[1:] if j.idx_v not in base]
        else:
            joints = []
            for joint_name in task._joint_spec:
                if not model.existJointName(joint_name):
                    raise InvalidInputError(f"{self.name}: unknown joint {joint_name!r}")
                joints.append(model.joints[model.getJointId(joint_name)])
        indices = [i for j in joints for i in range(j.idx_v, j.idx_v + j.nv)]
        self.robot, self._model = robot, model
        self.indices = np.array(indices, dtype=int)
        self.dim = len(indices)
        self.cost = as_weights(task._cost_spec, self.dim, "cost")
        self._weights = np.sqrt(self.cost)
        self._weighted_selection = np.zeros((self.dim, robot.nv))
        self._weighted_selection[np.arange(self.dim), self.indices] = self._weights
        self.error = np.zeros(self.dim)
        # vector-space shortcut: 1-DOF joints (nq = nv) forming one contiguous block of q and v
        q_index = np.array([j.idx_q for j in joints], dtype=int)
        simple = all(j.nq == 1 and j.nv == 1 for j in joints) and self.dim > 0
        contiguous = simple and np.all(np.diff(q_index) == 1) and np.all(np.diff(self.indices) == 1)
        self._q_slice = slice(int(q_index[0]), int(q_index[-1]) + 1) if contiguous else None
        self._q_view: np.ndarray | None = None
        self.target = np.zeros(robot.nq)
        self._target_selected = np.zeros(self.dim)
        self.apply_target(robot.neutral() if task._target_spec is None else task._target_spec)

    def apply_target(self, q: ArrayLike) -> None:
        """Validate ``q`` against this robot and write it in place (compiled programs hold the buffers)."""
        self.target[:] = as_vector(q, self.robot.nq, "target")  # a configuration of the robot
        if self._q_slice is not None:
            self._target_selected[:] = self.target[self._q_slice]

    def add_ops(self, program: TickProgram, kin: Kinematics, stack_t: np.ndarray, start: int) -> bool:
        if self._q_slice is None:
            return False  # pin.difference over general joints: computed in Python
        nv = stack_t.shape[0] - 1
        program.add(kernels.POSTURE, q=kin.q[self._q_slice], reference=self._target_selected,
                    weights=self._weights, settings=self.task._settings, error=self.error, stack=stack_t,
                    start=start, dim=self.dim, nv=nv, rows=stack_t.shape[1])
        return True

    def write_static(self, jacobian: np.ndarray) -> None:
        jacobian[...] = self._weighted_selection

    def compute(self, kin: Kinematics, dt: float, jacobian: np.ndarray, target: np.ndarray) -> None:
        if self._q_slice is not None:
            if self._q_view is None or self._q_view.base is not kin.q:
                self._q_view = kin.q[self._q_slice]  # kin.q is updated in place every tick
            kernels.posture_rows(self._q_view, self._target_selected, self._weights, self.task._settings, dt,
                                 self.error, target)
        else:
            np.take(pin.difference(self._model, kin.q, self.target), self.indices, out=self.error)
            np.multiply(self.error, self._weights, out=target)
            target *= self.task.gain / dt

    def report(self, v: np.ndarray, errors: dict[str, float]) -> None:
        errors[self.name] = _norm(self.error)
