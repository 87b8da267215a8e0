"""Strict task priorities: ``Controller(robot, tasks=[[ee], [posture, steering]])``.

A list of lists is a priority order, highest first; a flat list is one level (the weighted QP of
:mod:`wbc.control.controller`, unchanged). Level k is the least-squares term ``|A_k v - b_k|^2`` of its
tasks, weighted among themselves as in one level: its rows ``A = [W J | W r]`` are rows of the
controller's one task stack (:class:`wbc.qp.layout.TaskStack`, tasks ordered by level). The levels
are solved in order -- a *cascade* -- each as a QP with every constraint of the controller::

    level k:  min |A_k v - b_k|^2  (+ damping |v|^2 at the last level)
              s.t. the controller's bounds and rows (hard and soft, as in one level),
                   |a v - y_a| <= eps_a  for every row a of every level above (the *band*),

``y_a = a v_j`` the task value of row a at the answer ``v_j`` of its level j.

**Why this is exact.** ``|A_k v - b_k|^2`` is strictly convex in ``y = A_k v``, so over the
convex feasible set its optimal task value ``y_k*`` is unique, and the optimal set of level k is
exactly ``{feasible v : A_k v = y_k*}``. Holding ``A_k v = y_k*`` below level k therefore costs
level k nothing: a lower level never degrades a higher one, and a level that cannot reach its
targets within the constraints (infeasible alone) takes its least-squares optimum while the
levels below still use whatever freedom remains.

**The relaxation.** Each band row is an inequality row with two sides, ``y_a - eps_a <= a v <= y_a + eps_a``,
for DAQP (one row, not two opposite ones: a lower level's QP has half the band rows to copy, check and
solve), and two rows ``+-a v <= +-y_a + eps_a`` for the backends that take ``G v <= h`` only, with
``eps_a = BAND |a| max(1, |v_j|_inf)``, ``BAND = 1e-9``, written divided by ``|a|`` (unit rows: the
solvers' tolerances and the answer check then hold a band of a task weighted 1e-12 as tightly as
one weighted 1e12; unscaled, a posture weighted 1e-12 had rows of norm 1e-6, which the 1e-6
tolerances let a level below ignore entirely). The rounding of ``y_a`` never makes a
level infeasible (its own answer is feasible for the next), and linearly dependent rows (two
tasks of one level asking for the same thing) need no rank decision. ``v_j`` is projected onto
the bounds before ``y_a`` is taken, so an answer a hair outside a bound does not move the band
off it. A backend may stop outside a band row by its own primal tolerance, like outside any row:
DAQP's in the levels (:data:`wbc.solvers.daqp.backend.LEVEL_PRIMAL_TOL`, DAQP's default 1e-6 in its scaled
rows, though a single-level controller uses 1e-9; measured up to 8e-7 relative) is then the
effective relaxation, within the answer check of every tick
(:data:`wbc.control.fallback.ANSWER_TOLERANCE`). A tighter one (``solver_options={"primal_tol": 1e-9}``)
holds the bands closer, but DAQP then called some feasible levels infeasible when a level above
saturated the limits (1.5% of the ticks of a fast reach, answered by the fallback).

**Damping.** The controller's ``damping |v|^2`` belongs to the last level only: it regularises
the command, as in one level. A level above it has a cost that is flat along its null space
(``A_k^T A_k`` is singular when the level has fewer rows than ``nv``), which leaves its v -- not
its task values -- undetermined. Backends that factorise H (DAQP, quadprog, and any backend not
in :data:`SEMIDEFINITE_SOLVERS`) get the regularisation floor of every QP there
(:data:`wbc.control.controller.DAMPING_FLOOR` = 1e-10 of the level's largest curvature,
:func:`wbc.runtime.kernels.normalise_cost`): it moves the level's task values by ``1e-10 / c``
relative along a direction of relative curvature c (< 1e-7 in the tests against the
pseudo-inverse). The others take a semidefinite H and get the level as it is: exact.

**Error-scaled damping.** The ``mu_t |v|^2`` of each task (``Controller.lm_damping``) belongs
to the level of the task: it damps the step that level asks, where its linear model cannot be
trusted (a target out of reach), and the band then holds the damped task values. It vanishes
with the level's error, so it does not change the cascade at a fixed point. The steering
preview of a hierarchy (below) leaves it out.

**Solvers.** Every backend solves the levels in turn. With native DAQP (:mod:`wbc.solvers.daqp.native`)
the whole cascade -- each level's QP, solve, answer check and band -- runs inside the tick
program, one warm-started DAQP workspace per level; otherwise (other backends, DAQP's binding,
the reduced form of a nonholonomic base) the program builds every level's QP and the levels are
solved from Python, the bands written by the same kernel.

**Fallback.** When a level's solve fails (or its answer does not check), the cascade is re-solved
from that level on by DAQP with the soft rows elastic (:meth:`wbc.control.fallback.Fallback.elastic_solve`;
the band rows, like the hard limits, stay hard): the hierarchy is kept, and where the soft rows
can hold, the elastic answer is the level's exact one. If that fails too, the command is the
answer of the deepest level solved this tick (``Outcome.LEVEL_ABOVE``: optimal for it and the
levels above, every hard limit kept -- e.g. below a level that fixes every coordinate, whose bands
DAQP can call infeasible when they touch a bound), and ``v = 0`` only when no level was solved.
The first-order and interior-point backends (OSQP, ProxQP, Clarabel, PIQP) and HiGHS report some
levels below a saturated one as infeasible or unsolved -- their feasible set is then
a thin sliver around the answer above -- and those ticks are answered by the elastic cascade (the
README has the measured rates); DAQP and quadprog, exact active-set methods, solved every level
of the tests and scenarios (DAQP did call a level infeasible under a fully determined level whose
answer sat on a velocity bound: a fuzz case, answered by the level above).

**Steering preview.** Tasks that need the holonomic preview (SteeringTask) get the cascade of the
hierarchy without constraints (:func:`wbc.runtime.kernels.hierarchy_preview`: the classical null-space
projection of the levels' ordinary rows, the damping at the last level).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from ..core.errors import InvalidInputError
from ..core.outcome import Outcome
from ..core.validation import as_items
from ..qp.layout import LevelRows
from ..qp.problem import QP
from ..qp.reduction import InputReduction
from ..runtime import kernels
from ..runtime.kernels import DAQP_CONTROL_OUTCOME, DAQP_CONTROL_TIME
from ..runtime.program import TickProgram, ops_follow_compute
from ..solvers import DaqpBackend, QPSolution, QPSolver
from ..tasks.task import Task, TaskData
from .fallback import ANSWER_TOLERANCE, Fallback
from .lm_damping import LMDamping
from .tick_buffers import TickBuffers

if TYPE_CHECKING:  # pragma: no cover
    from ..solvers.daqp.native import NativeWorkspace

#: relative half-width of the band that holds a level's task values below it (see the module docstring)
BAND = 1e-9
#: qpsolvers backends that take a positive semidefinite H: the levels above the last reach them
#: unregularised (exact). DAQP and quadprog factorise H and get the floor; with it (cond 1e10)
#: Clarabel and HiGHS stopped short of their tolerances on every tick of a tracked circle
SEMIDEFINITE_SOLVERS = frozenset({"clarabel", "highs", "osqp", "piqp", "proxqp"})

_REDUCTION_FAILURE = "reduced form: a constraint bounded the coupled base rates x, y"


def task_levels(tasks: Sequence[Task] | Sequence[Sequence[Task]]) -> tuple[list[Task], list[int] | None]:
    """The ``tasks`` argument of a controller as (its tasks in level order, the size of each
    level); sizes are None for a flat list or a single level (today's weighted QP).

    Raises InvalidInputError for a list mixing tasks and levels, an empty level, a level that is
    not a list of tasks, or a task in two levels (or twice in one).
    """
    if not isinstance(tasks, (list, tuple)) or not any(isinstance(level, (list, tuple)) for level in tasks):
        return as_items(tasks, Task, "tasks"), None
    if not all(isinstance(level, (list, tuple)) for level in tasks):
        raise InvalidInputError("tasks mixes tasks and lists: a priority order is a list of levels, highest first, "
                                "each a list of tasks (tasks=[[ee], [posture]]); a flat list of tasks is one level")
    levels = [as_items(level, Task, f"tasks, level {k}") for k, level in enumerate(tasks)]
    for k, level in enumerate(levels):
        if not level:
            raise InvalidInputError(f"tasks: level {k} is empty; give it a task or remove it")
    seen: dict[int, int] = {}
    for k, level in enumerate(levels):
        for task in level:
            if id(task) in seen:
                where = f"twice in level {k}" if seen[id(task)] == k else f"in levels {seen[id(task)]} and {k}"
                raise InvalidInputError(f"tasks: {task.name} appears {where}; a task belongs to one level "
                                        "(create another task for a second use)")
            seen[id(task)] = k
    flat = [task for level in levels for task in level]
    return flat, ([len(level) for level in levels] if len(levels) > 1 else None)


class Hierarchy:
    """The levels of one controller: their QPs, the ops that fill them, and their cascade.

    Level 0's QP is the controller's own (``buffers.qp``); level k > 0 has the same bounds
    and rows (copied by the program each tick) plus the band rows of the levels above, after the
    inequality rows. With the cascade in the program, a level below the second copies them from
    the level above it once that level holds its bands (each band computed once per tick, not once
    per level below). ``controller.qp`` is the last level's QP (the reduced one with ``reduced``).
    It reads the controller's :class:`~wbc.control.tick_buffers.TickBuffers`, never the controller.
    """

    count: int  #: number of levels
    rows: LevelRows  #: the rows of each level in the task stack

    def __init__(self, buffers: TickBuffers, sizes: Sequence[int], solver: QPSolver, fallback: Fallback) -> None:
        self._buffers = buffers
        kernels.prepare("qp_defect", "band_rows")  # called in its ticks: compiled now
        nv = buffers.nv
        level: dict[int, int] = {}
        start = 0
        for k, size in enumerate(sizes):
            level.update((id(data), k) for data in buffers.task_data[start:start + size])
            start += size
        self.count = count = len(sizes)
        upper = [block[0].name for block in buffers.task_stack.linear_blocks if level[id(block[0])] != count - 1]
        if upper:
            raise InvalidInputError(f"linear cost terms {upper} sit above the last priority level: a level's cost "
                                    "must be bounded below on its own, which only the last level's damping makes "
                                    "sure of; put them in the last level")
        self.rows = rows = LevelRows(buffers.task_stack, lambda task: level[id(task)], count, nv)
        #: each level's ordinary task blocks (for the error-scaled damping of its tasks)
        self._blocks = [[block for block in buffers.task_stack.blocks if level[id(block[0])] == k]
                        for k in range(count)]
        first = buffers.qp
        #: first band row of each level in the QPs below it (same in all of them)
        #: rows per band row: 1 for DAQP (a row with two sides), 2 for backends that take ``G v <= h`` only
        self.band_sides = 1 if isinstance(solver, DaqpBackend) else 2
        self.band_start = [first.n_ineq + self.band_sides * sum(rows.dim(j) for j in range(k)) for k in range(count)]
        self.qps = [first] + [QP(nv, self.band_start[k], first.n_eq) for k in range(1, count)]
        self._reductions: list[InputReduction] | None = None
        self.solver_qps = self.qps  #: what the backend solves, level by level
        if buffers.reduction is not None:  # reduced=True (the controller's level-0 reduction)
            self._reductions = [buffers.reduction] + [InputReduction(buffers.input_map, qp.n_ineq, qp.n_eq)
                                                     for qp in self.qps[1:]]
            self.solver_qps = [reduction.qp for reduction in self._reductions]
        self._upper_scaling = np.zeros(2)  # (damping, floor) of the levels above the last: set by add_ops
        self._settings = np.array([ANSWER_TOLERANCE, BAND])  # operand of the BAND op
        #: the backend of the levels: the controller's (DAQP: :meth:`~wbc.solvers.DaqpBackend.for_levels`)
        self.solver: QPSolver = solver
        self._workspaces: list[NativeWorkspace] | None = None
        self.in_program = False  #: the whole cascade runs in the tick program (native DAQP)
        #: each level's answer (over v) in the latest tick; None for a level not solved
        self.answers: list[NDArray[np.float64] | None] = [None] * count
        #: the same in the solver's variables (u with ``reduced``), for :meth:`CascadeFallback.last_resort`
        self.solutions: list[NDArray[np.float64] | None] = [None] * count
        self.failed = 0  #: the level whose solve failed in the latest failed tick
        self.fallback = CascadeFallback(self, fallback)

    # ----------------------------------------------------------------- program
    @property
    def upper_floor(self) -> float:
        """The regularisation floor of the levels above the last (0: a semidefinite backend's)."""
        return float(self._upper_scaling[1])

    @property
    def workspaces(self) -> list[NativeWorkspace]:
        """The levels' native DAQP workspaces (empty for other backends): their working sets are
        the cascade's warm start."""
        return list(self._workspaces or ())

    def add_ops(self, program: TickProgram, backend: QPSolver
                ) -> tuple[list[tuple[TaskData, NDArray[np.float64], NDArray[np.float64]]], TickProgram, QP, bool]:
        """Append every level's assembly -- and with native DAQP the cascade itself -- to the
        controller's tick program, after its items' ops; ``backend`` is the controller's. Returns
        what the controller keeps: (Python preview tasks, the program part after them, the QP the
        backend sees last, whether the solves run in the program)."""
        b = self._buffers
        kin, nv, stack, scaling_last = b.kinematics, b.nv, b.task_stack.stack_t, b.cost_scaling
        size = stack.shape[1]
        python_preview, rest = [], program
        if b.task_stack.preview_blocks:
            program.add(kernels.HIERARCHY_PREVIEW, stack=stack, ranges=self.rows.ranges, scaling=scaling_last,
                        preview=b.preview, nv=nv, rows=size, count=self.rows.ranges.size)
            python_preview = [(task, jacobian, target) for task, jacobian, target, start in b.task_stack.preview_blocks
                              if not (ops_follow_compute(task, "compute_preview", "add_preview_ops")
                                      and task.add_preview_ops(program, kin, stack, start, b.preview))]
            if python_preview:
                rest = TickProgram()  # runs after the Python preview tasks
        lm = LMDamping(b.lm_damping, self.count)
        for k, qp in enumerate(self.qps):
            for (first, last), reset in ((self.rows.normal[k], 1), (self.rows.preview[k], 0)):
                if last > first or reset:
                    rest.add(kernels.NORMAL_EQUATIONS, stack=stack, nv=nv, rows=size, first=first, last=last,
                             reset=reset, Hc=qp.Hc)
            if k == self.count - 1:
                b.task_stack.add_linear_op(rest, qp)
            if lm.add_task_ops(rest, stack, self._blocks[k], k):  # the error-scaled damping of the level's tasks
                lm.add_level_op(rest, k, qp.Hc, scaling_last if k == self.count - 1 else self._upper_scaling)
        solver = self.solver = backend.for_levels() if isinstance(backend, DaqpBackend) else backend
        self._upper_scaling[1] = 0.0 if solver.name in SEMIDEFINITE_SOLVERS else scaling_last[1]
        self._workspaces = workspaces = None
        if isinstance(solver, DaqpBackend) and solver.native:  # (then every workspace is one)
            # the levels below the first try their working set (the band rows) before DAQP
            self._workspaces = workspaces = [w for k, qp in enumerate(self.solver_qps)
                                             if (w := solver.workspace(qp, working_set_first=k > 0)) is not None]
        self.in_program = workspaces is not None and b.reduction is None
        first_qp = self.qps[0]
        b.bounds.add_op(rest, first_qp)
        for k, qp in enumerate(self.qps):
            if k == 1 or (k and not self.in_program):  # (in the program, levels below the second: _add_level_copy)
                self._add_level_copy(rest, first_qp, qp)
            scaling = scaling_last if k == self.count - 1 else self._upper_scaling
            rest.add(kernels.NORMALISE_LEVEL, Hc=qp.Hc, scaling=scaling, nv=nv)
            screened = qp.data if k == 0 else qp.data[:nv * nv + nv]  # below: level 0's limits, copied
            rest.add(kernels.HAS_NAN, data=screened, size=screened.size, infinite=0)
        if workspaces is not None and self.in_program:
            # level k's solve, its band into level k + 1, then level k + 1's limits -- the controller's and the
            # bands of levels 0..k -- copied into level k + 2, whose band rows of level k + 1 come next
            for k, workspace in enumerate(workspaces):
                workspace.add_op(rest)
                if k + 1 < self.count:
                    self._add_band_op(rest, k, workspace, self.qps[k + 1])
                if k + 2 < self.count:
                    self._add_level_copy(rest, self.qps[k + 1], self.qps[k + 2])
            self._native_answers: list[NDArray[np.float64] | None] = [workspace.x for workspace in workspaces]
            self._last_answer = workspaces[-1].x
            self._last_control = workspaces[-1].control
            self._upper_controls = [workspace.control for workspace in workspaces[:-1]]
        return python_preview, rest, self.solver_qps[-1], self.in_program

    @staticmethod
    def _add_level_copy(program: TickProgram, source: QP, target: QP) -> None:
        """The bounds and rows of the level QP ``source`` into those of ``target``, a level below
        it: the target's rows after them (its band rows of the levels in between) are left as they are."""
        program.add(kernels.LEVEL_CONSTRAINTS, source=source.data, target=target.data, n=source.n, p=source.n_ineq,
                    e=source.n_eq, band=target.n_ineq - source.n_ineq, source_size=source.data.size,
                    target_size=target.data.size)

    def _add_band_op(self, program: TickProgram, k: int, workspace: NativeWorkspace, target: QP) -> None:
        stack, nv = self._buffers.task_stack.stack_t, self._buffers.nv
        (first, last), (first_p, last_p) = self.rows.tasks[k], self.rows.preview[k]
        program.add(kernels.BAND, stack=stack, first=first, last=last, first_preview=first_p,
                    last_preview=last_p, x=workspace.x, lower=self.qps[0].lb, upper=self.qps[0].ub,
                    control=workspace.control, settings=self._settings, target=target.data, nv=nv,
                    rows=stack.shape[1], size=target.data.size, row=self.band_start[k],
                    target_rows=target.n_ineq + target.n_eq)

    def collect_optimal(self, tolerance: float) -> tuple[NDArray[np.float64], float] | None:
        """The pipeline's fast path with the cascade in the program: ``(x, solve time [s])`` -- a
        copy of the last level's answer, the levels' solve times summed (in the order of
        DAQP_ACCEPT_LEVEL's sum, which the controller's native tick reads) -- when the last level
        solved and its answer's defect is at most ``tolerance`` -- which the program's BAND ops
        allow only after every level above did the same, with
        :data:`wbc.control.fallback.ANSWER_TOLERANCE`; None otherwise (then :meth:`solve` says which
        level failed)."""
        exitflag, defect, elapsed = self._last_control[DAQP_CONTROL_OUTCOME].tolist()
        if not (exitflag >= 1.0 and defect <= tolerance):
            return None
        for control in self._upper_controls:
            elapsed += control.item(DAQP_CONTROL_TIME)
        self.use_native_answers()
        return self._last_answer.copy(), elapsed

    def use_native_answers(self) -> None:
        """:attr:`answers` and :attr:`solutions`: the levels' workspaces' (a cascade solved in the
        program; the controller's native tick sets them only when its diagnostics are read)."""
        self.answers = self.solutions = self._native_answers

    # -------------------------------------------------------------------- tick
    def solve(self) -> QPSolution:
        """This tick's command from the cascade (read from the program's solves, or solved now):
        the last level's answer, checked; or a failure naming the level (:attr:`failed`), for the
        controller's fallback chain (:class:`CascadeFallback`)."""
        if not self.in_program or self._workspaces is None:  # (in_program implies workspaces)
            return self.cascade(0, self._solve_level)
        elapsed = 0.0
        for k, workspace in enumerate(self._workspaces):
            exitflag, defect, spent = workspace.outcome()
            elapsed += spent
            if exitflag < 1 or not defect <= ANSWER_TOLERANCE:
                self.answers = [w.x.copy() for w in self._workspaces[:k]] + [None] * (self.count - k)
                self.solutions = list(self.answers)
                return self._failure(k, QPSolution(None, False, _native_status(exitflag, defect), elapsed))
        self.answers = self.solutions = self._native_answers
        return QPSolution(workspace.x.copy(), True, "optimal", elapsed, defect)

    def cascade(self, start: int, solve: Callable[[int], QPSolution], check: bool = True) -> QPSolution:
        """Levels ``start`` onward, each by ``solve(k)`` (the levels above hold their answers and
        bands from this tick); each answer is checked against its QP (unless ``solve`` checks
        what must hold itself: the elastic solves) and writes its band."""
        input_map = self._buffers.input_map
        self.answers = self.answers[:start] + [None] * (self.count - start)
        self.solutions = self.solutions[:start] + [None] * (self.count - start)
        elapsed = 0.0
        for k in range(start, self.count):
            if self._reductions is not None and k and not self._reductions[k].reduce(self.qps[k], input_map):
                return self._failure(k, QPSolution(None, False, _REDUCTION_FAILURE, elapsed))
            solution = solve(k)
            elapsed += solution.solve_time
            if not solution.success:
                return self._failure(k, solution._replace(solve_time=elapsed))
            x, defect = solution.x, solution.defect
            assert x is not None  # a successful solve has an answer
            if check:
                if defect is None:
                    defect = kernels.qp_defect(self.solver_qps[k].data, x)
                if defect > ANSWER_TOLERANCE:
                    status = f"answer violates the QP's constraints by {defect:.1e} (relative)"
                    return self._failure(k, QPSolution(None, False, status, elapsed))
            v = x if self._reductions is None else input_map @ x
            self.answers[k], self.solutions[k] = v, x
            for j in range(k + 1, self.count):
                self._write_band(k, v, self.qps[j])
        return QPSolution(solution.x, True, "optimal", elapsed, defect)

    def _solve_level(self, k: int) -> QPSolution:
        """Level k by the controller's backend (its own native DAQP workspace, if it has one)."""
        if self._workspaces is None:
            return self.solver.solve(self.solver_qps[k])
        workspace = self._workspaces[k]
        exitflag, defect, elapsed = workspace.solve()
        if exitflag >= 1 and np.isfinite(defect):
            return QPSolution(workspace.x.copy(), True, "optimal", elapsed, defect)
        return QPSolution(None, False, _native_status(exitflag, defect), elapsed)

    def _write_band(self, k: int, v: np.ndarray, target: QP) -> None:
        """Level k's band rows, at its answer ``v``, into the QP ``target`` of a level below."""
        (first, last), (first_p, last_p) = self.rows.tasks[k], self.rows.preview[k]
        kernels.band_rows(self._buffers.task_stack.stack_t, first, last, first_p, last_p, v, self.qps[0].lb,
                          self.qps[0].ub, BAND, target.data, self.band_start[k], target.n_ineq + target.n_eq,
                          int(self.band_sides == 1))

    def _failure(self, k: int, solution: QPSolution) -> QPSolution:
        """Level k failed: its warm start is dropped; the failure names the level."""
        self.failed = k
        if self._workspaces is not None:
            self._workspaces[k].reset()
        else:
            self.solver.reset()
        return solution._replace(status=f"level {k}: {solution.status}")


def _native_status(exitflag: int, defect: float) -> str:
    """Why a native DAQP solve's answer was not taken (the texts of :class:`wbc.solvers.DaqpBackend`)."""
    from ..solvers.daqp import abi as daqp_abi

    if exitflag < 1:
        return daqp_abi.EXIT_FLAGS.get(exitflag, f"exitflag {exitflag}")
    if not np.isfinite(defect):
        return "answer not finite"
    return f"answer violates the QP's constraints by {defect:.1e} (relative)"


class CascadeFallback(Fallback):
    """The fallback chain of a hierarchy (:class:`wbc.control.fallback.Fallback`): its elastic re-solve is
    the cascade from the level that failed on, each level by DAQP with the soft rows elastic and
    the band rows of the levels above hard."""

    def __init__(self, hierarchy: Hierarchy, plain: Fallback) -> None:
        super().__init__(plain.soft_rows, plain.budget, plain.strict)
        self._hierarchy = hierarchy

    def last_resort(self, qp: QP, reason: str, elapsed: float, has_nan: bool) -> tuple[QPSolution, Outcome, str]:
        """The answer of the deepest level solved this tick (:attr:`Hierarchy.solutions`): optimal
        for its level and those above, within every bound and row of the QP (its QP has them all,
        and it was checked) -- e.g. a level below that DAQP calls infeasible because the bands of
        a fully determined level above are thinner than its tolerance. ``v = 0`` when none was."""
        solved = [(k, x) for k, x in enumerate(self._hierarchy.solutions) if x is not None]
        if has_nan or not solved:
            return super().last_resort(qp, reason, elapsed, has_nan)
        k, x = solved[-1]
        return (QPSolution(x.copy(), False, "", elapsed), Outcome.LEVEL_ABOVE,
                f"fallback: level {k}'s answer after {reason}")

    def elastic_solve(self, qp: QP) -> QPSolution:
        """The elastic cascade from :attr:`Hierarchy.failed` (``qp``, the last level's, is solved last)."""
        hierarchy = self._hierarchy
        return hierarchy.cascade(hierarchy.failed, lambda k: Fallback.elastic_solve(self, self._factorisable(k)),
                                 check=False)

    def _factorisable(self, k: int) -> QP:
        """Level k's QP for DAQP, which factorises H: a level above the last that reached a
        semidefinite backend unregularised gets the regularisation floor the others have
        (:data:`wbc.control.controller.DAMPING_FLOOR` of its normalised H) in a copy; DAQP called such
        a level unbounded (exit flag -3) and the tick fell to the zero command."""
        hierarchy = self._hierarchy
        floor = hierarchy._buffers.cost_scaling[1]  # the controller's DAMPING_FLOOR
        qp = hierarchy.solver_qps[k]
        if k == hierarchy.count - 1 or hierarchy.upper_floor > 0.0:
            return qp
        copy = QP(qp.n, qp.n_ineq, qp.n_eq)
        copy.data[:] = qp.data
        copy.H.flat[::qp.n + 1] += floor * max(float(np.max(np.diag(qp.H))), 1.0)
        return copy
