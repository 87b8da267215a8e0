"""Joint position limits as a velocity damper."""

from __future__ import annotations

import numpy as np

from ..kinematics import Kinematics
from ..robot import Robot
from ..validation import as_gain
from .constraint import Constraint, ConstraintRows


class JointPositionLimits(Constraint):
    """Keep ``q`` inside ``[lower, upper]`` with velocity-damper bounds::

        gain * (lower - q) / dt  <=  v  <=  gain * (upper - q) / dt

    With explicit Euler integration ``q+ = q + v dt`` and ``gain`` in (0, 1], a
    configuration inside the limits stays inside: ``q+ - upper <= (1 - gain)(q - upper) <= 0``.
    The limits are approached geometrically (at most the fraction ``gain`` of the
    remaining margin per tick). Unbounded coordinates (the mobile base) are skipped.

    Args:
        gain: fraction of the remaining margin that may be consumed per tick, (0, 1].
    """

    has_bounds = True

    def __init__(self, gain: float = 0.5, name: str | None = None) -> None:
        super().__init__(name)
        self.gain = as_gain(gain)

    def bind(self, robot: Robot) -> None:
        model = robot.model
        q_index, v_index = [], []
        for joint in model.joints[1:]:
            if joint.nq == 1 and joint.nv == 1:
                i = joint.idx_q
                if np.isfinite(robot.lower[i]) or np.isfinite(robot.upper[i]):
                    q_index.append(i)
                    v_index.append(joint.idx_v)
        self._q_index = np.array(q_index, dtype=int)
        self._v_index = np.array(v_index, dtype=int)
        self._lower = robot.lower[self._q_index].copy()
        self._upper = robot.upper[self._q_index].copy()
        self._scratch = np.zeros(len(q_index))

    def compute(self, kin: Kinematics, dt: float, rows: ConstraintRows) -> None:
        q = np.take(kin.q, self._q_index, out=self._scratch)
        scale = self.gain / dt
        rows.lower[self._v_index] = (self._lower - q) * scale
        rows.upper[self._v_index] = (self._upper - q) * scale

    def __repr__(self) -> str:
        return f"JointPositionLimits(gain={self.gain})"
