"""The lifted form of a high-DOF QP: the dense task rows as auxiliary variables.

The normal equations ``H = sum_r a_r a_r^T`` of the task stack are dense: forming them costs
``k nv^2`` for k dense rows (FrameTask: 6), and DAQP then factorises H from scratch every
tick (``nv^3 / 3``) -- at 64 DOF that is most of the tick. Yet H is *diagonal plus low rank*:
the posture and damping rows each touch one coordinate. Introducing ``w = U v`` for the k
dense rows ``U`` (targets ``t``) gives the same minimiser over v from::

    min 1/2 v^T D v + d^T v + 1/2 |w|^2 - t^T w   s.t.  U v - w = 0,  the controller's limits,

whose Hessian ``diag(D, I)`` DAQP inverts in O(nv) and whose k equality rows cost O(k nv)
to form (:func:`wbc.runtime.kernels.lift_qp`). The controller uses it (:data:`LIFT_MIN_DOF`,
:func:`worth_lifting`) with DAQP's native path, when no Python step needs H itself (the
input reduction, the steering preview). ``controller.qp`` is then this QP over ``(v, w)``;
the command is its first nv entries.

**Certified, else dense.** The lifted QP has the v-problem's minimiser, but DAQP solves it
through its dual, whose conditioning is not the v-problem's: with costs and damping far apart
(e.g. a posture weight 1e12 next to coordinates held only by the damping floor) DAQP was seen
to stop on the lifted QP 0.2 rad/s from the optimum, or at its iteration limit, where the dense
QP of the same tick is solved exactly. So every lifted answer is certified in the tick
program (:data:`~wbc.runtime.kernels.assembly.LIFT_CHECK`): its stationarity *in v*
(:func:`wbc.runtime.kernels.lifted_stationarity`, relative) joins its defect, both held to
:data:`wbc.control.fallback.ANSWER_TOLERANCE`. A lifted solve that fails or is not certified is
followed, in the same tick, by the dense QP (:meth:`LiftedQP.fill_dense`) solved by the same
backend -- the answer then costs a normal-equations pass and a second solve; only if that
fails too does the fallback chain answer. :attr:`LiftedQP.dense_ticks` counts those ticks.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from ..runtime import kernels
from ..runtime.program import TickProgram
from .layout import TaskStack
from .problem import QP


class SolvedWorkspace(Protocol):
    """What the certificate reads of a native DAQP solve (:class:`wbc.solvers.daqp.native.NativeWorkspace`)."""

    x: NDArray[np.float64]  #: the answer
    lam: NDArray[np.float64]  #: its multipliers (bounds, then rows)
    control: NDArray[np.float64]  #: the solve's outcome (exit flag, defect, time, iterations)


#: smallest number of velocity coordinates at which the lifted form is used: below it the
#: dense QP is as fast (measured: benchmarks/README.md, "Scaling")
LIFT_MIN_DOF = 16


def dense_rows(stack: TaskStack, nv: int) -> np.ndarray:
    """1.0 for each row of the stack's ordinary block (tasks, then damping) whose entries
    lie on one fixed coordinate (``TaskData.diagonal_rows``, the damping), else 0.0."""
    diagonal = np.zeros(stack.n_plain)
    diagonal[stack.n_plain - nv:] = 1.0  # sqrt(damping) I
    for task, _, _, start in stack.blocks:
        if task.diagonal_rows:
            diagonal[start:start + task.dim] = 1.0
    return diagonal


def worth_lifting(nv: int, diagonal: np.ndarray) -> bool:
    """Whether the lifted form is the faster one: nv >= LIFT_MIN_DOF and at most nv / 2 dense rows."""
    return nv >= LIFT_MIN_DOF and 2 * int(np.count_nonzero(diagonal == 0.0)) <= nv


class LiftedQP:
    """The lifted QP of one controller over ``x = (v, w)`` and the op that fills it."""

    def __init__(self, source: QP, diagonal: np.ndarray) -> None:
        self.source, self.diagonal = source, diagonal
        self.k = k = int(np.count_nonzero(diagonal == 0.0))  #: auxiliary variables (dense rows)
        self.qp = QP(source.n + k, source.n_ineq, source.n_eq + k)  #: what the solver sees
        self._scratch = np.zeros(2 * source.n)  # of the certificate
        self.dense_ticks = 0  #: ticks whose lifted answer was not certified: the dense QP answered
        kernels.prepare("normal_equations", "normalise_cost")  # fill_dense calls them in ticks: compiled now

    def add_check_op(self, program: TickProgram, workspace: SolvedWorkspace) -> None:
        """Append the certificate of the answer of ``workspace`` (the native DAQP solve of
        :attr:`qp`, appended before): its stationarity in v joins its defect."""
        source, qp = self.source, self.qp
        program.add(kernels.LIFT_CHECK, lifted=qp.data, x=workspace.x, lam=workspace.lam, scratch=self._scratch,
                    control=workspace.control, nv=source.n, k=self.k, p=source.n_ineq, e=source.n_eq,
                    lifted_size=qp.data.size)

    def fill_dense(self, stack_t: np.ndarray, rows: int, scaling: np.ndarray) -> QP:
        """The dense v-QP of this tick: its H and c from the stack's first ``rows`` rows,
        normalised as the controller's (its bounds and rows are this tick's already). Returns it."""
        source = self.source
        kernels.normal_equations(stack_t, 0, rows, True, source.Hc)
        kernels.normalise_cost(source.Hc, scaling[0], scaling[1])
        self.dense_ticks += 1
        return source

    def add_op(self, program: TickProgram, stack_t: np.ndarray, scaling: np.ndarray) -> None:
        """Fill :attr:`qp` from the stack and the v-QP's limits every tick (a NaN met counts
        as the NaN screen's); ``scaling`` = (damping, damping floor)."""
        source, qp = self.source, self.qp
        program.add(kernels.LIFT, stack=stack_t, diagonal=self.diagonal, source=source.data, lifted=qp.data,
                    scaling=scaling, nv=source.n, stack_rows=stack_t.shape[1], rows=self.diagonal.size, k=self.k,
                    p=source.n_ineq, e=source.n_eq, source_size=source.data.size, lifted_size=qp.data.size)
