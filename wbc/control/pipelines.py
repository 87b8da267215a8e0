"""One pipeline per controller mode: the stages of a tick, chosen when the controller is built.

A tick (:meth:`wbc.Controller.step`) runs three stages, each an object picked once for the
controller's mode, so the tick itself has no branch on the mode:

* the **assembly** -- the Python items, then the tick program (:class:`Assembly`; with
  Python preview tasks, which need the preview the program computes, two program parts around
  them: :class:`SplitAssembly`);
* the **inputs** -- the input map of the base and what the QP's variables are
  (:class:`Holonomic`: ``v = u = x``; :class:`Nonholonomic`: ``v = x``, ``u = S^T v``;
  :class:`Reduced`: the QP over ``u``, ``v = S u``, reduced every tick);
* the **solve** -- the QP's answer: :class:`ProgramSolve` (native DAQP solved it inside the
  program; the control loop's fast path), :class:`BackendSolve` (the backend solves it now),
  :class:`LiftedSolve` (the lifted QP of :mod:`wbc.qp.lifting`, solved in the program, re-solved
  dense when not certified), :class:`CascadeSolve` (the levels of :mod:`wbc.control.hierarchy`).

A new mode is a new class of one stage.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..constraints.constraint import ConstraintData, ConstraintRows
from ..core.errors import InvalidInputError
from ..model.robot import Robot
from ..model.tick_context import TickContext
from ..qp.lifting import LiftedQP
from ..qp.problem import QP
from ..qp.reduction import InputReduction
from ..runtime import kernels
from ..runtime.kernels.ops import RUN_FOUND_NAN
from ..runtime.program import TickProgram
from ..solvers import QPSolution, QPSolver
from ..tasks.task import TaskData
from .fallback import ANSWER_TOLERANCE
from .tick_buffers import TickBuffers

if TYPE_CHECKING:  # pragma: no cover
    from .hierarchy import Hierarchy

#: a task computed in Python: (its data, its Jacobian rows, its target rows) in the task stack
PythonTask = tuple[TaskData, NDArray[np.float64], NDArray[np.float64]]
#: a constraint computed in Python: (its data, its block of rows)
PythonConstraint = tuple[ConstraintData, ConstraintRows]
PythonTasks = Sequence[PythonTask]
PythonConstraints = Sequence[PythonConstraint]

#: why a tick had no QP to solve (the fallback's status names it)
NAN_FAILURE = "QP data holds NaN (from a task or constraint)"
REDUCTION_FAILURE = "reduced form: a constraint bounded the coupled base rates x, y"

Answer = tuple[NDArray[np.float64], float]  #: (x, solve time [s]) of the fast path
Command = tuple[NDArray[np.float64], NDArray[np.float64]]  #: (v, u)


# -------------------------------------------------------------------- inputs
class Holonomic:
    """A holonomic or fixed base: the QP is over v, the inputs are v (``u is v``); nothing to
    prepare before the solve."""

    prepares = False  #: whether :meth:`prepare` must run every tick
    failure = NAN_FAILURE  #: why the latest tick's QP was unusable (read when it was)

    def prepare(self, q: NDArray[np.float64], has_nan: bool) -> bool:
        """Whatever the base needs between the assembly and the solve; whether the QP is
        unusable (then :attr:`failure` says why)."""
        return has_nan

    def command(self, x: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The command ``(v, u)`` from the QP's answer ``x``."""
        return x, x


class Nonholonomic(Holonomic):
    """A nonholonomic base in plain form: the QP is over v (the no-slip rows are constraints),
    the inputs ``u = S(q)^T v`` (``S``, the buffers' input map, written every tick)."""

    prepares = True

    def __init__(self, robot: Robot, input_map: NDArray[np.float64]) -> None:
        self._robot, self._S = robot, input_map

    def prepare(self, q: NDArray[np.float64], has_nan: bool) -> bool:
        self._robot.input_map(q, out=self._S)
        return has_nan

    def command(self, x: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        return x, self._S.T @ x


class Reduced(Nonholonomic):
    """A nonholonomic base in reduced form: the QP over v is reduced to one over the inputs u
    every tick (:class:`wbc.qp.reduction.InputReduction`), ``v = S(q) u``."""

    def __init__(self, robot: Robot, input_map: NDArray[np.float64], reduction: InputReduction, qp: QP) -> None:
        super().__init__(robot, input_map)
        self._reduction, self._qp = reduction, qp

    def prepare(self, q: NDArray[np.float64], has_nan: bool) -> bool:
        self._robot.input_map(q, out=self._S)
        self.failure = NAN_FAILURE
        if not has_nan and not self._reduction.reduce(self._qp, self._S):
            self.failure = REDUCTION_FAILURE
            return True
        return has_nan

    def command(self, x: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        return self._S @ x, x


def inputs_of(robot: Robot, input_map: NDArray[np.float64], reduction: InputReduction | None, qp: QP) -> Holonomic:
    """The inputs stage for ``robot``'s base: reduced (``reduction`` given), nonholonomic or holonomic."""
    if reduction is not None:
        return Reduced(robot, input_map, reduction, qp)
    return Nonholonomic(robot, input_map) if robot.base.is_nonholonomic else Holonomic()


# ------------------------------------------------------------------ assembly
class Assembly:
    """The tick's QP data: the Python items' rows, the tick program (one native call: compiled
    items, normal equations, bounds, NaN screen, and possibly the solve), then what the base's
    inputs need (:meth:`Holonomic.prepare`).

    ``unready``: the tasks whose :meth:`~wbc.tasks.task.TaskData.check_ready` runs before the
    first tick. ``q_screened``: no Python item reads the kinematics before the program, which
    then screens q itself; a NaN it found in q is reported here as the bad q it is.
    """

    def __init__(self, context: TickContext, robot: Robot, buffers: TickBuffers, unready: Sequence[TaskData],
                 tasks: PythonTasks, constraints: PythonConstraints, program: TickProgram, q_screened: bool,
                 q_weights: NDArray[np.float64], inputs: Holonomic | None) -> None:
        self._context, self._kinematics, self._robot, self._buffers = context, context.kinematics, robot, buffers
        # with no Python reader before the program, the kinematics are left to its first op
        self._deferred_kinematics = q_screened and context.kinematics.native
        if context.kinematics.native and not self._deferred_kinematics:
            kernels.prepare("forward_kinematics")  # kinematics.update calls it in ticks: compiled now
        self._unready = list(unready)  # checked every tick until each one is ready
        self._tasks, self._constraints, self._run = tasks, constraints, program.runner()
        _prepare_kernels(item for item, _ in constraints)
        _prepare_kernels(item for item, *_ in tasks)
        for constraint, _ in constraints:
            constraint.prepare_compute()
        self._qp = buffers.qp
        self._q_screened, self._q_weights = q_screened, q_weights  # q is finite iff q . weights is
        self._prepare = inputs.prepare if inputs is not None and inputs.prepares else None
        #: whether the program does it all (no Python item, no equality rows to sync, nothing to prepare)
        self.all_in_program = not (tasks or constraints or self._qp.n_eq or self._prepare)
        if self.all_in_program:
            self.run = self._run_program  # type: ignore[method-assign]

    def run(self, q: NDArray[np.float64], dt: float, v_measured: ArrayLike | None) -> bool:
        """Fill this tick's QP for configuration ``q`` (checked up front unless the program
        screens it) and the tick's context (``v_measured``: the measured joint velocity, or
        None); True when it cannot be solved (a NaN in its data; the inputs'
        :attr:`~Holonomic.failure` says why). Raises InvalidInputError for a bad
        ``v_measured``, or a non-finite ``q`` found by the program."""
        context, kin = self._context, self._kinematics
        context.measured = None if v_measured is None else context.measure(v_measured)
        kin.update(q, self._deferred_kinematics)
        if self._unready:
            self.check_ready()
        for task, jacobian, target in self._tasks:
            task.compute(kin, dt, jacobian, target)
        for constraint, block in self._constraints:
            constraint.compute(kin, dt, block)
        if self._qp.n_eq:
            self._qp.sync_equalities()
        has_nan = self._run(dt) == RUN_FOUND_NAN
        if has_nan and self._q_screened:
            self.screen(q)
        prepare = self._prepare
        return has_nan if prepare is None else prepare(q, has_nan)

    def _run_program(self, q: NDArray[np.float64], dt: float, v_measured: ArrayLike | None) -> bool:
        """:meth:`run` when every item is compiled, no equality rows are synced and the base
        prepares nothing: the same steps, without the empty ones (the control loop's path)."""
        context = self._context
        context.measured = None if v_measured is None else context.measure(v_measured)
        self._kinematics.update(q, self._deferred_kinematics)
        if self._unready:
            self.check_ready()
        has_nan = self._run(dt) == RUN_FOUND_NAN
        if has_nan and self._q_screened:
            self.screen(q)
        return has_nan

    def check_ready(self) -> None:
        """Raise InvalidInputError for a task that cannot be evaluated yet (e.g. no target),
        until every one of them could once."""
        for task in self._unready:
            task.check_ready()
        self._unready = []

    def ready(self) -> bool:
        """Whether every task can be evaluated now (targets set before the controller was built):
        :meth:`check_ready` without raising; once True, no tick checks them any more."""
        try:
            self.check_ready()
        except InvalidInputError:
            return False
        return True

    def screen(self, q: NDArray[np.float64]) -> None:
        """The program found a NaN: raise if it came from ``q`` (naming what is wrong with it)."""
        if not math.isfinite(q.dot(self._q_weights)):
            self._buffers.tick += 1  # this call overwrote the buffers the previous record reads lazily
            self._robot.check_configuration(q)


class SplitAssembly(Assembly):
    """An assembly with preview tasks computed in Python: they read the holonomic preview that
    the first part (an :class:`Assembly` of the items and the first program part) computes,
    and the second program part (``after``) assembles the rest."""

    def __init__(self, first: Assembly, buffers: TickBuffers, preview_tasks: PythonTasks, after: TickProgram,
                 inputs: Holonomic) -> None:
        self._first, self._kinematics, self._preview = first, first._kinematics, buffers.preview
        self._deferred_kinematics = first._deferred_kinematics
        self._preview_tasks, self._after = preview_tasks, after.runner()
        _prepare_kernels(item for item, *_ in preview_tasks)
        self._prepare = inputs.prepare if inputs.prepares else None

    def run(self, q: NDArray[np.float64], dt: float, v_measured: ArrayLike | None) -> bool:
        self._first.run(q, dt, v_measured)
        kin, preview = self._kinematics, self._preview
        for task, jacobian, target in self._preview_tasks:
            task.compute_preview(kin, dt, jacobian, target, preview)
        has_nan = self._after(dt) == RUN_FOUND_NAN
        prepare = self._prepare
        return has_nan if prepare is None else prepare(q, has_nan)


def _prepare_kernels(items: Iterable[TaskData | ConstraintData]) -> None:
    """Compile the kernels the Python ``compute`` of ``items`` may call (``python_kernels``) now,
    when the controller is built, not in its first tick."""
    kernels.prepare(*sorted({name for item in items for name in item.python_kernels}))


# --------------------------------------------------------------------- solve
def checked(solver: QPSolver, solution: QPSolution, qp: QP) -> QPSolution:
    """``solution`` of ``qp`` by ``solver``, or a failure when its answer's defect exceeds
    :data:`~wbc.control.fallback.ANSWER_TOLERANCE` (relative, :func:`wbc.runtime.kernels.qp_defect`):
    then the fallback chain answers, and the backend's warm start is dropped."""
    if solution.success:
        defect = solution.defect if solution.defect is not None else kernels.qp_defect(qp.data, solution.x)
        if defect > ANSWER_TOLERANCE:
            solver.reset()
            return QPSolution(None, False, f"answer violates the QP's constraints by {defect:.1e} (relative)",
                              solution.solve_time)
    return solution


def _no_answer(tolerance: float) -> Answer | None:
    return None


class BackendSolve:
    """The backend solves the QP ``qp`` from Python (no fast path); its answer is checked."""

    def __init__(self, solver: QPSolver, qp: QP) -> None:
        self.solver, self.qp = solver, qp  #: the backend, and the QP it sees (``controller.qp``)
        kernels.prepare("qp_defect")  # checked() calls it in ticks: compiled now
        #: the control loop's fast path, called with :data:`~wbc.control.fallback.ANSWER_TOLERANCE`:
        #: ``(x, solve time [s])`` of a solve that ran in the program and checked there (its
        #: defect at most the tolerance); None: take :meth:`checked`
        self.fast: Callable[[float], Answer | None] = _no_answer

    def checked(self) -> tuple[QPSolution, QP]:
        """The checked answer (or a failure), and the QP the fallback chain re-solves."""
        return checked(self.solver, self.solver.solve(self.qp), self.qp), self.qp

    def command(self, inputs: Holonomic) -> Callable[[NDArray[np.float64]], Command] | None:
        """The command ``(v, u)`` from the QP's answer x (:meth:`Holonomic.command`); None when
        it is ``(x, x)`` (the hot path then makes no call)."""
        return None if type(inputs) is Holonomic else inputs.command


class ProgramSolve(BackendSolve):
    """Native DAQP solved the QP inside the tick program, and checked its answer there."""

    def __init__(self, solver: QPSolver, qp: QP) -> None:
        super().__init__(solver, qp)
        self.fast = solver.collect_optimal

    def checked(self) -> tuple[QPSolution, QP]:
        return checked(self.solver, self.solver.collect(), self.qp), self.qp


class LiftedSolve(ProgramSolve):
    """The lifted QP (``x = (v, w)``, :mod:`wbc.qp.lifting`) solved in the program; a solve
    whose answer is not certified is redone on the dense QP, which the fallback then re-solves."""

    def __init__(self, solver: QPSolver, lifted: LiftedQP, buffers: TickBuffers) -> None:
        super().__init__(solver, lifted.qp)
        self._lifted, self._buffers = lifted, buffers

    def checked(self) -> tuple[QPSolution, QP]:
        solution, qp = super().checked()
        if solution.success:
            return solution, qp
        stack = self._buffers.task_stack
        dense = self._lifted.fill_dense(stack.stack_t, stack.n_plain, self._buffers.cost_scaling)
        again = checked(self.solver, self.solver.solve(dense), dense)
        return again._replace(solve_time=solution.solve_time + again.solve_time), dense

    def command(self, inputs: Holonomic) -> Callable[[NDArray[np.float64]], Command] | None:
        nv, command = self._buffers.nv, inputs.command
        return lambda x: command(x[:nv])  # x = (v, w)


class CascadeSolve(BackendSolve):
    """The levels of a strict hierarchy (:class:`~wbc.control.hierarchy.Hierarchy`), solved in
    turn from Python; ``qp`` is the last level's."""

    def __init__(self, hierarchy: Hierarchy, qp: QP) -> None:
        super().__init__(hierarchy.solver, qp)
        self._hierarchy = hierarchy

    def checked(self) -> tuple[QPSolution, QP]:
        return self._hierarchy.solve(), self.qp


class CascadeInProgram(CascadeSolve):
    """The whole cascade ran in the tick program (native DAQP)."""

    def __init__(self, hierarchy: Hierarchy, qp: QP) -> None:
        super().__init__(hierarchy, qp)
        self.fast = hierarchy.collect_optimal
