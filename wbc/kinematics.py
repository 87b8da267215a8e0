"""This tick's kinematics, computed once and shared by every task and constraint."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from .robot import Robot

_LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED


class Kinematics:
    """Forward kinematics and joint Jacobians of one configuration.

    :meth:`update` runs ``computeJointJacobians`` (which includes forward
    kinematics) once per tick; frame placements and Jacobians are then read
    without recomputing the chain. Conventions as in :mod:`wbc.robot`.
    """

    def __init__(self, robot: Robot) -> None:
        self.robot = robot
        self.model = robot.model
        self.data = robot.model.createData()
        self.q = np.zeros(robot.nq)

    def update(self, q: np.ndarray) -> None:
        """Recompute for configuration ``q`` (already validated)."""
        self.q[:] = q
        pin.computeJointJacobians(self.model, self.data, self.q)

    def frame_placement(self, frame_id: int) -> pin.SE3:
        """World placement of a frame (an SE3 owned by this object's data)."""
        return pin.updateFramePlacement(self.model, self.data, frame_id)

    def frame_jacobian(self, frame_id: int) -> np.ndarray:
        """6 x nv frame Jacobian, world-aligned at the frame origin, rows (linear; angular)."""
        return pin.getFrameJacobian(self.model, self.data, frame_id, _LWA)
