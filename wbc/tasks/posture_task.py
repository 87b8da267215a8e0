"""Joint-space posture regularisation."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from ..kinematics import Kinematics
from ..robot import Robot
from ..errors import InvalidInputError
from ..validation import as_gain, as_weights
from .task import Task, _norm


class PostureTask(Task):
    """Pull the joints toward a reference configuration.

    Error ``e = q* (-) q`` (``pinocchio.difference``, in velocity coordinates) on the
    selected coordinates; rows ``W (v_S - gain/dt * e_S)``.

    Args:
        cost: [cost] / [rad]^2 (or [m]^2 for prismatic joints), scalar or one per selected coordinate.
        target: reference configuration (size nq); ``None`` uses ``robot.neutral()``.
        gain: fraction of the error removed per tick, in (0, 1].
        joints: names of the joints to regulate; ``None`` = every joint that is not
            part of the mobile base (pulling a base toward a fixed world position is
            rarely wanted).
    """

    def __init__(self, cost, target=None, gain: float = 1.0, joints: list[str] | None = None,
                 name: str | None = None) -> None:
        super().__init__(name)
        self._cost_spec = cost
        self._target_spec = target
        self._joint_spec = joints
        self.gain = as_gain(gain)
        self.dim = 0

    def bind(self, robot: Robot) -> None:
        model = robot.model
        base = set(robot.base.indices) if robot.base.is_mobile else set()
        if self._joint_spec is None:
            indices = [i for i in range(robot.nv) if i not in base]
        else:
            indices = []
            for joint_name in self._joint_spec:
                if not model.existJointName(joint_name):
                    raise InvalidInputError(f"{self.name}: unknown joint {joint_name!r}")
                joint = model.joints[model.getJointId(joint_name)]
                indices.extend(range(joint.idx_v, joint.idx_v + joint.nv))
        self.indices = np.array(indices, dtype=int)
        self.dim = len(indices)
        self.cost = as_weights(self._cost_spec, self.dim, "cost")
        self._weights = np.sqrt(self.cost)
        self.target = robot.neutral() if self._target_spec is None else robot.check_configuration(self._target_spec)
        self._model = model
        self._weighted_selection = np.zeros((self.dim, robot.nv))
        self._weighted_selection[np.arange(self.dim), self.indices] = self._weights
        self.error = np.zeros(self.dim)

    def set_target(self, q) -> None:
        self.target = np.array(q, dtype=np.float64)

    def compute(self, kin: Kinematics, dt: float, jacobian: np.ndarray, target: np.ndarray) -> None:
        full_error = pin.difference(self._model, kin.q, self.target)
        np.take(full_error, self.indices, out=self.error)
        jacobian[...] = self._weighted_selection
        np.multiply(self.error, self.gain / dt, out=target)
        target *= self._weights

    def report(self, v: np.ndarray, errors: dict[str, float]) -> None:
        errors[self.name] = _norm(self.error)

    def __repr__(self) -> str:
        return f"PostureTask(cost={self._cost_spec!r}, gain={self.gain}, joints={self._joint_spec!r})"
