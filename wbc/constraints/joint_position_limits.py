"""Joint position limits as a velocity damper."""

from __future__ import annotations

import numpy as np

from ..core.settings import Operand
from ..core.validation import as_gain
from ..model.kinematics import Kinematics
from ..model.robot import Robot
from ..runtime import kernels
from ..runtime.program import TickProgram
from .constraint import Constraint, ConstraintData, ConstraintRows


class JointPositionLimits(Constraint):
    """Keep ``q`` inside ``[lower, upper]`` with velocity-damper bounds::

        gain * (lower - q) / dt  <=  v  <=  gain * (upper - q) / dt

    With explicit Euler integration ``q+ = q + v dt`` and ``gain`` in (0, 1], a
    configuration inside the limits stays inside: ``q+ - upper <= (1 - gain)(q - upper) <= 0``.
    The limits are approached geometrically (at most the fraction ``gain`` of the
    remaining margin per tick). Unbounded coordinates (the mobile base) are skipped.

    The constraint is *soft* with respect to the speed limits: a configuration outside
    its limits (after a collision, an encoder offset) asks for ``v`` beyond the speed
    limit; the controller then clips the bound to the speed limit, so the joint moves
    back at top speed instead of making the QP infeasible. Outside the limits both full
    margins are used (``gain = 1``): the joint lands on its limit as soon as the speed
    limit allows, instead of approaching it geometrically from outside, and the bounds
    never exclude each other, whatever the gain.

    Args:
        gain: fraction of the remaining margin that may be consumed per tick, (0, 1].
    """

    #: may be changed between ticks (validated; it lives in the compiled operand)
    gain = Operand("_gain", 0, as_gain)
    hard = False  # yields to the speed limits: from outside the limits, return at top speed

    def __init__(self, gain: float = 0.5, name: str | None = None) -> None:
        super().__init__(name)
        self._gain = np.zeros(1)  # operand of the compiled op, shared by the controllers using it
        self.gain = gain

    def bind(self, robot: Robot) -> JointPositionLimitsData:
        return JointPositionLimitsData(self, robot)

    def __repr__(self) -> str:
        return f"JointPositionLimits(gain={self.gain})"


class JointPositionLimitsData(ConstraintData):
    """:class:`JointPositionLimits` in one controller: the robot's bounded 1-DOF joints."""

    python_kernels = ("position_limit_bounds",)

    has_bounds = True
    constraint: JointPositionLimits

    def __init__(self, limits: JointPositionLimits, robot: Robot) -> None:
        super().__init__(limits)
        q_index, v_index = [], []
        for joint in robot.model.joints[1:]:
            if joint.nq == 1 and joint.nv == 1:
                i = joint.idx_q
                if np.isfinite(robot.lower[i]) or np.isfinite(robot.upper[i]):
                    q_index.append(i)
                    v_index.append(joint.idx_v)
        self._q_index = np.array(q_index, dtype=int)
        self._v_index = np.array(v_index, dtype=int)
        self._lower_limit = robot.lower[self._q_index].copy()
        self._upper_limit = robot.upper[self._q_index].copy()
        self._q = np.zeros(len(q_index))  # gathered q when the joints are not one block
        self._slices = None
        self._q_view: np.ndarray | None = None
        if len(q_index) and np.all(np.diff(self._q_index) == 1) and np.all(np.diff(self._v_index) == 1):
            self._slices = (slice(q_index[0], q_index[-1] + 1), slice(v_index[0], v_index[-1] + 1))

    def write_static(self, rows: ConstraintRows) -> None:
        if self._slices is not None:
            self._out = (rows.lower[self._slices[1]], rows.upper[self._slices[1]])
        else:
            self._out = (np.zeros(len(self._q_index)), np.zeros(len(self._q_index)))

    def add_ops(self, program: TickProgram, kin: Kinematics, rows: ConstraintRows) -> bool:
        if self._slices is None:
            return False
        q_slice, v_slice = self._slices
        program.add(kernels.POSITION_LIMITS, q=kin.q[q_slice], lower_limit=self._lower_limit,
                    upper_limit=self._upper_limit, gain=self.constraint._gain, lower=rows.lower[v_slice],
                    upper=rows.upper[v_slice], k=len(self._q_index))
        return True

    def compute(self, kin: Kinematics, dt: float, rows: ConstraintRows) -> None:
        if self._slices is not None:
            if self._q_view is None or self._q_view.base is not kin.q:
                self._q_view = kin.q[self._slices[0]]  # kin.q is updated in place every tick
            q = self._q_view
        else:
            q = np.take(kin.q, self._q_index, out=self._q)
        lower, upper = self._out
        kernels.position_limit_bounds(q, self._lower_limit, self._upper_limit, self.constraint.gain, dt, lower,
                                      upper)
        if self._slices is None:
            rows.lower[self._v_index] = lower
            rows.upper[self._v_index] = upper
