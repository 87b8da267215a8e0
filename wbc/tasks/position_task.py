"""3-D position task of one frame."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core.settings import Cost, Operand
from ..core.validation import as_gain, as_speed_limit, as_vector
from ..model.kinematics import Kinematics, frame_in_joint
from ..model.robot import Robot
from ..runtime import kernels
from ..runtime.program import TickProgram
from .error_task import ErrorTask, ErrorTaskData


class PositionTask(ErrorTask):
    """Drive the origin of a frame to a target point (orientation free).

    Error ``e = p* - p`` [m] (world); rows ``W (J_lin v - r)`` with the linear rows of
    :meth:`Robot.frame_jacobian` and the desired velocity ``r = sat(gain/dt * e) + pdot*``,
    ``pdot*`` an optional feed-forward velocity [m/s] and ``sat`` scaling the feedback
    part down to at most ``max_speed`` in norm (far targets are approached at a
    bounded speed instead of demanding metres per second that only saturate the joints).
    An :class:`~wbc.tasks.error_task.ErrorTask` whose compiled kernel computes the same rows
    in the native tick.

    Args:
        frame: frame name.
        cost: [cost] / [m]^2, scalar or per axis.
        gain: fraction of the error removed per tick, in (0, 1].
        max_speed: [m/s] bound on the feedback velocity; ``None`` = unbounded.
    """

    needs_target = True

    #: settings that may be changed between ticks (validated; they live in the compiled operands)
    gain = Operand("_settings", kernels.POSITION_GAIN, as_gain)
    max_speed = Operand("_settings", kernels.POSITION_MAX_SPEED, as_speed_limit)
    cost = Cost("_weights", slice(0, 3))
    speed_limits = ((slice(0, 3), "max_speed"),)

    def __init__(self, frame: str, cost: ArrayLike = 1.0, gain: float = 1.0, max_speed: float | None = None,
                 name: str | None = None) -> None:
        self.frame = frame
        # every setting the compiled kernel reads, in one vector (layout: wbc.runtime.kernels.POSITION_*),
        # shared by the controllers using the task
        self._settings = np.zeros(kernels.POSITION_SETTINGS)
        self._weights = self._settings[kernels.POSITION_WEIGHTS]
        self._target = self._settings[kernels.POSITION_TARGET]
        self._feedforward = self._settings[kernels.POSITION_FEEDFORWARD]
        super().__init__(3, gain, name)
        self.cost = cost
        self.max_speed = max_speed
        self._has_target = False

    def default_name(self) -> str:
        return f"PositionTask({self.frame})"

    def set_target(self, position: ArrayLike, velocity: ArrayLike | None = None) -> None:
        """Set the target point [m] (world) and optionally its feed-forward velocity [m/s].

        Raises:
            InvalidInputError: ``position`` or ``velocity`` is not 3 finite numbers. The previous
                target is then kept.
        """
        target = as_vector(position, 3, "target position")
        feedforward = 0.0 if velocity is None else as_vector(velocity, 3, "target velocity")  # both checked first
        self._target[...] = target
        self._feedforward[...] = feedforward
        if not self._has_target:  # (an attribute write through Item.__setattr__ costs ~0.2 us)
            self._has_target = True

    @property
    def target(self) -> NDArray[np.float64]:
        return self._target.copy()

    def bind(self, robot: Robot) -> PositionTaskData:
        return PositionTaskData(self, robot)

    def __repr__(self) -> str:
        return (f"PositionTask(frame={self.frame!r}, cost={self.cost.tolist()}, gain={self.gain}, "
                f"max_speed={self.max_speed})")


class PositionTaskData(ErrorTaskData):
    """A :class:`PositionTask` in one controller: its frame resolved against the robot, and
    the error ``p* - p`` of the last tick."""

    task: PositionTask

    def __init__(self, task: PositionTask, robot: Robot) -> None:
        super().__init__(task, robot)
        self._frame_id = robot.frame_id(task.frame)
        self._joint_id, local, self._support = frame_in_joint(robot.model, self._frame_id)
        self._frame = np.zeros(kernels.FRAME_DATA)  # placement in the joint, then kernel scratch
        self._frame[kernels.FRAME_LOCAL] = local
        self._jacobian = np.zeros((6, robot.nv))  # kernel scratch: the full frame Jacobian

    def compute_error_and_jacobian(self, kin: Kinematics, error: np.ndarray, jacobian: np.ndarray) -> None:
        """``e = p* - p`` and the linear rows of the frame's world-aligned Jacobian (Pinocchio's)."""
        np.subtract(self.task._target, kin.frame_placement(self._frame_id).translation, out=error)
        jacobian[...] = kin.frame_jacobian(self._frame_id)[:3]

    def add_ops(self, program: TickProgram, kin: Kinematics, stack_t: np.ndarray, start: int) -> bool:
        joint_jacobians, rotation, translation = kin.joint_views(self._joint_id)
        program.add(kernels.POSITION_TASK, joint_jacobians_t=joint_jacobians.T, rotation_t=rotation.T,
                    translation=translation, support=self._support, settings=self.task._settings, frame=self._frame,
                    error=self.error, stack=stack_t, start=start, nv=stack_t.shape[0] - 1, rows=stack_t.shape[1],
                    jacobian=self._jacobian, feedforward=self.feedforward)
        return True
