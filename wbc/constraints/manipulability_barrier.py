"""Keep a frame's manipulability above a floor: a discrete-time control barrier function."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..core.errors import InvalidInputError
from ..core.settings import Operand
from ..core.validation import as_gain, as_positive
from ..model.kinematics import Kinematics
from ..model.manipulability import Manipulability, Rows, check_joint_names, row_selection
from ..model.robot import Robot
from ..runtime import kernels
from ..runtime.program import TickProgram
from .barrier import Barrier, BarrierData
from .constraint import ConstraintRows


class ManipulabilityBarrier(Barrier):
    """One inequality row that keeps ``m(q) >= m_min`` (see :mod:`wbc.model.manipulability`)::

        grad m(q) . v  >=  -gain (m(q) - m_min) / dt      written as   -grad m . v <= gain (m - m_min) / dt

    Why it works: with ``q+ = integrate(q, v dt)``, to first order
    ``m(q+) = m + dt grad m . v >= m - gain (m - m_min)``, i.e.

        m(q+) - m_min  >=  (1 - gain) (m(q) - m_min),

    so the margin shrinks at most geometrically and never changes sign: m approaches
    ``m_min`` no faster than the fraction ``gain`` of the margin per tick. ``v = 0``
    satisfies the row whenever ``m >= m_min``, so the row alone never makes a QP
    infeasible that was feasible at rest.

    Second order: the exact step adds ``dt^2 / 2 * v^T (Hess m) v + O(dt^3)``, which can
    be negative, so ``m`` may dip below ``m_min`` by at most about
    ``dt^2 |Hess m| |v|^2 / 2`` in one tick. From below the floor the row demands
    ``grad m . v >= gain (m_min - m) / dt > 0`` and the deficit shrinks by ``(1 - gain)``
    per tick, so dips do not accumulate; they stay ``O(dt^2 |v|^2 / gain)``. Choose
    ``m_min`` with that slack above the value you must never cross, and ``gain < 1``.
    Starting below ``m_min`` the row pulls ``m`` back up at the same geometric rate
    (if the velocity limits allow it).

    A :class:`~wbc.constraints.barrier.Barrier` with ``b = m - m_min``; its compiled kernel
    computes the same row in the native tick.

    Args:
        frame: frame whose Jacobian defines ``m``.
        min_value: ``m_min`` > 0, in the units of ``m`` for ``rows``.
        gain: fraction of the margin ``m - m_min`` that may be consumed per tick, (0, 1].
        rows: ``"all"``, ``"position"`` or ``"orientation"`` rows of the Jacobian.
        joints: the measure of these joints' columns only (e.g. the arm of a mobile manipulator);
            None: every joint. A chain's measure is computed in Python (not in the native tick).
    """

    #: settings that may be changed between ticks (validated; they live in the compiled operand)
    gain = Operand("_settings", kernels.BARRIER_GAIN, as_gain)
    min_value = Operand("_settings", kernels.BARRIER_MIN_VALUE, as_positive)

    def __init__(self, frame: str, min_value: float, gain: float = 0.5, rows: Rows = "all",
                 joints: Sequence[str] | None = None, name: str | None = None) -> None:
        if not isinstance(frame, str):
            raise InvalidInputError(f"frame must be a frame name, got {frame!r}")
        self.frame = frame
        row_selection(rows)
        self.rows = rows
        self.joints = None if joints is None else tuple(check_joint_names(joints))
        super().__init__(name or f"ManipulabilityBarrier({frame})")
        self._settings = np.zeros(kernels.BARRIER_SETTINGS)  # compiled operand (layout: kernels.BARRIER_*), shared
        self.gain, self.min_value = gain, min_value

    def bind(self, robot: Robot) -> ManipulabilityBarrierData:
        return ManipulabilityBarrierData(self, robot)

    def __repr__(self) -> str:
        chain = "" if self.joints is None else f", joints={list(self.joints)!r}"
        return (f"ManipulabilityBarrier(frame={self.frame!r}, min_value={self.min_value}, "
                f"gain={self.gain}, rows={self.rows!r}{chain})")


class ManipulabilityBarrierData(BarrierData):
    """:class:`ManipulabilityBarrier` in one controller: ``m`` of the robot's frame and its
    value at the last tick."""

    python_kernels = ("frame_jacobian", "manipulability_gradient")  # Manipulability.compute's

    constraint: ManipulabilityBarrier

    def __init__(self, barrier: ManipulabilityBarrier, robot: Robot) -> None:
        super().__init__(barrier, robot, 1)
        self._manipulability = Manipulability(robot, barrier.frame, barrier.rows, barrier.joints)
        self._value = np.array([np.nan])  # compiled operand: m at the last tick

    @property
    def value(self) -> float:
        """``m`` at the last tick (NaN before the first)."""
        return float(self._value[0])

    def add_ops(self, program: TickProgram, kin: Kinematics, rows: ConstraintRows) -> bool:
        if not self._manipulability.compiled:
            return False  # multi-DOF joints on the chain: the Hessian path, in Python
        selected = row_selection(self.constraint.rows)
        program.add(kernels.MANIPULABILITY_BARRIER, **self._manipulability.operands(kin), G=rows.G[0],
                    h=rows.h[0:1], settings=self.constraint._settings, value=self._value, first=selected.start,
                    last=selected.stop, nv=kin.model.nv)
        return True

    def compute_barrier(self, kin: Kinematics, values: np.ndarray, gradients: np.ndarray) -> None:
        """``b = m - m_min``, ``grad b = grad m``."""
        manipulability = self._manipulability
        self._value[0] = manipulability.compute(kin)
        values[0] = self._value[0] - self.constraint.min_value
        gradients[0] = manipulability.gradient

    def row_labels(self) -> list[str]:
        return [f"m >= {self.constraint.min_value:g}"]
