"""The control tick: kinematics -> tasks and constraints -> QP -> solver -> command.

The whole tick is :meth:`Controller.step`; everything it uses is allocated once, when the
controller is built, by named pieces:

* the **layout** (:mod:`wbc.qp.layout`): the task stack ``[W J | W r]`` (the tasks' rows, then
  ``sqrt(damping) I``, then the preview tasks' rows) and where each constraint writes;
* the **bound policy** (:class:`wbc.qp.bounds.BoundPolicy`): hard bounds intersected, soft
  ones clipped into them;
* the **program** (:class:`wbc.runtime.program.TickProgram`): one native call for every compiled
  item, the normal equations ``H = Js^T Js + damping I``, ``c = -Js^T rs``, the bound clip,
  the cost normalisation, the NaN screen and -- with DAQP on its native path
  (:mod:`wbc.solvers.daqp.native`) -- the solve and the check of its answer; at high DOF the QP
  is assembled in its lifted form (:mod:`wbc.qp.lifting`: the dense task rows as variables);
* the optional **holonomic preview** (tasks with ``uses_preview``, e.g. SteeringTask) and
  **input reduction** (:class:`wbc.qp.reduction.InputReduction`, ``reduced=True``);
* the **fallback chain** (:class:`wbc.control.fallback.Fallback`), driven by
  :class:`wbc.core.outcome.Outcome`;
* with strict priorities (``tasks`` a list of levels) the **cascade** of :mod:`wbc.control.hierarchy`.
"""

from __future__ import annotations

import copy
import functools
import math
import time
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Any, NamedTuple, overload

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..constraints.constraint import Constraint, ConstraintData
from ..constraints.mimic_joints import MimicJoints
from ..core.errors import InvalidInputError
from ..core.outcome import Outcome
from ..core.validation import as_flag, as_items, as_nonnegative, as_positive, finite_weights
from ..model.kinematics import NOTHING_CURRENT, Kinematics
from ..model.robot import Robot
from ..model.tick_context import TickContext
from ..qp.layout import ConstraintLayout, TaskStack
from ..qp.lifting import LiftedQP, dense_rows, worth_lifting
from ..qp.problem import QP
from ..qp.reduction import InputReduction
from ..runtime import kernels
from ..runtime.kernels.ops import RUN_ACCEPTED, RUN_BAD_INPUT, RUN_FOUND_NAN
from ..runtime.program import TickProgram, ops_follow_compute
from ..solvers import DaqpBackend, QPSolution, QPSolver, make_solver
from ..tasks.task import Task, TaskData
from .diagnostics import NoTickYetError, TickDiagnostics
from .fallback import ANSWER_TOLERANCE, Fallback
from .hierarchy import Hierarchy, task_levels
from .lm_damping import LMDamping
from .pipelines import (
    Assembly,
    BackendSolve,
    CascadeInProgram,
    CascadeSolve,
    LiftedSolve,
    ProgramSolve,
    PythonConstraint,
    PythonTask,
    SplitAssembly,
    inputs_of,
)
from .tick_buffers import TickBuffers
from .warm_up import warm_up_twin

if TYPE_CHECKING:  # pragma: no cover
    from ..solvers.daqp.native import NativeWorkspace

#: smallest damping relative to the largest curvature of the cost (:func:`wbc.runtime.kernels.normalise_cost`):
#: below it H is numerically singular (a cost 1e15 times the damping); the solvers would fail
DAMPING_FLOOR = 1e-10
#: default of ``Controller.lm_damping``: twice the smallest value that removed the full-speed
#: chatter at unreachable targets on every shipped robot (NOTES: 26 directions x 4 distances x
#: gains 0.1-1); at 1 the linear model of a one-joint reach cannot overshoot (see the class docstring)
DEFAULT_LM_DAMPING = 1.0


class Controller:
    """QP whole-body velocity controller.

    Args:
        robot: the robot model.
        tasks: cost terms (at least one), weighted in one QP; or a list of lists, a priority
            order of levels, highest first (strict priorities, :mod:`wbc.control.hierarchy`).
        constraints: hard limits. A nonholonomic base needs :class:`~wbc.constraints.NonholonomicBase`
            unless ``reduced=True``.
        solver: a name from :func:`wbc.available_solvers` (default ``"daqp"``).
        dt: control period [s]; per-tick gains and dampers refer to it.
        damping: Tikhonov term ``damping * |v|^2`` [cost] / [unit/s]^2, keeps H positive definite.
        lm_damping: scale (>= 0, dimensionless) of the error-scaled damping below; 0 turns it off.
        solver_options: settings passed to the backend (override :data:`wbc.solvers.solver.DEFAULT_SETTINGS`).
        reduced: solve over the real inputs ``u`` with ``v = robot.input_map(q) u`` (the
            no-slip rows then hold by construction and are skipped). ``step`` still returns v;
            ``last.u`` holds the inputs in both forms. Holonomic and fixed bases have
            ``S = I``: both forms are the same QP there (``self.reduced`` is then False).
        strict: raise :class:`~wbc.core.errors.SolverError` when the QP cannot be solved, instead
            of the fallback below.
        warm_up: tick a throwaway copy of the controller ten times when it is built
            (:mod:`wbc.control.warm_up`), so that its first tick runs code just run (~5x a
            steady tick instead of ~12x in a fresh process), at the cost of about one more
            build (~1.6 ms on the youBot). The controller's own state and commands are the same
            either way; False skips it (copies never warm up).

    Raises:
        InvalidInputError: a bad argument (not a robot, no task, a task in two levels, a
            negative damping, ``dt <= 0``, a non-bool flag, a nonholonomic base without
            ``NonholonomicBase()`` or ``reduced=True``, ...), or a task or constraint that does
            not fit the robot (an unknown frame or joint, a base it needs and the robot lacks).
        UnknownSolverError: ``solver`` is not installed.
        InvalidSolverOptionError: a misspelt or invalid key of ``solver_options``.

    Error-scaled damping (Levenberg-Marquardt with a damping linear in the error, as in Fan and
    Yuan 2005): the damping of each level is raised to ``mu = sum_t mu_t`` of its tasks, i.e.
    ``max(damping, mu) |v|^2`` replaces ``damping |v|^2`` (a level above the last of a hierarchy,
    which has no damping, gets ``mu |v|^2``), over the tasks t with ``TaskData.lm_damped``
    (frames, positions, manipulability, custom tasks; not posture, base-velocity or steering), ::

        mu_t = lm_damping * |dt W (r_t - xi_t)| * max_j |(W J_t) e_j|      [cost] / [unit/s]^2

    -- the weighted step the task's error feedback asks this tick (``W r = W sat(gain e / dt) +
    W xi``, the feed-forward ``W xi`` left out: ``TaskData.feedforward``) times its largest
    weighted Jacobian column. Their product is the scale of the second-order term ``sum_i (W^2
    dx)_i grad^2 x_i`` that the task's linear model drops (for one revolute joint ``|d^2 p / d
    theta^2| = |d p / d theta|``, the distance to the axis). That term is what makes the linear
    model overshoot where a task cannot be met: toward a target out of reach the arm stretches
    to the boundary of its workspace, where J loses rank along the reach, and a step of ``gain
    e`` folds it past the boundary and back every tick, at full speed. With the damping at least
    the curvature along the reach the step cannot overshoot (one-joint model, ``lm_damping >=
    1``); below half of it the overshoot grows into that chatter. ``mu`` scales with the costs,
    the lengths and the gain like ``J^T W^2 J`` (``lm_damping`` is dimensionless) and vanishes
    with the error: no fixed point moves, the final approach to a reachable target is unchanged,
    and a tracked reference whose error stays small (``mu`` below ``damping``) is tracked as
    without it. It may be changed between ticks.

    Failure handling (never a NaN, never an exception in the loop unless ``strict``):

    1. *Soft bounds* (position dampers) are clipped into the *hard* ones (speed limits)
       every tick, so conflicting limits never make the QP infeasible (a joint outside its
       range returns at top speed).
    2. Every answer is checked against its QP's bounds and rows (and, for qpsolvers
       backends, for optimality). If the backend fails (infeasible rows, iteration / time
       budget, numerical trouble, an answer that does not check), the same QP is solved again
       by DAQP with the rows of soft constraints made *elastic*: hard limits hold, the
       violation shows in ``last.max_violation``; ``last.outcome`` is ``Outcome.ELASTIC``.
    3. If that fails too, or the QP data holds NaN, the command is ``v = 0`` (it satisfies
       every shipped hard limit: speed, wheel and no-slip limits); ``Outcome.ZERO``.
    """

    def __init__(self, robot: Robot, tasks: Sequence[Task] | Sequence[Sequence[Task]],
                 constraints: Sequence[Constraint] = (), solver: str = "daqp", dt: float = 0.01, damping: float = 1e-3,
                 solver_options: dict[str, Any] | None = None, reduced: bool = False, strict: bool = False,
                 lm_damping: float = DEFAULT_LM_DAMPING, warm_up: bool = True) -> None:
        if solver_options is not None and not isinstance(solver_options, Mapping):
            raise InvalidInputError(f"solver_options must be a dict of backend settings, got {solver_options!r}")
        warm = as_flag(warm_up, "warm_up")
        self._setup(robot, tasks, constraints, lambda: make_solver(solver, solver_options), dt, damping, reduced,
                    strict, lm_damping)
        if warm:
            warm_up_twin(self._twin)

    def _setup(self, robot: Robot, tasks: Sequence[Task] | Sequence[Sequence[Task]],
               constraints: Sequence[Constraint], solver: Callable[[], QPSolver], dt: float, damping: float,
               reduced: bool, strict: bool, lm_damping: float) -> None:
        """Build the controller from its specification (``solver`` makes its backend, once
        every other argument is checked); :meth:`__init__` and the copies (:meth:`__reduce__`)."""
        if not isinstance(robot, Robot):
            raise InvalidInputError(f"robot must be a wbc.Robot, got {type(robot).__name__}")
        with kernels.batch():  # a first start's kernels compile in parallel processes, done when it is built
            self.robot = robot
            self.kinematics = Kinematics(robot)
            self._context = TickContext(self.kinematics, 0.0)  # (read through the property context)
            self.dt = dt
            # (damping, floor): operand of the cost normalisation, and where the damping setting lives
            self._cost_scaling = np.array([as_nonnegative(damping, "damping"), DAMPING_FLOOR])
            self._lm_damping = np.array([as_nonnegative(lm_damping, "lm_damping")])  # operand of the LM_DAMPING ops
            self.tasks, self._level_sizes = task_levels(tasks)  # the tasks in level order; sizes (None: one level)
            self.constraints = as_items(constraints, Constraint, "constraints")
            if not self.tasks:
                raise InvalidInputError("a controller needs at least one task")
            # a holonomic or fixed base has S(q) = I: its reduced form is the plain one
            self.reduced = as_flag(reduced, "reduced") and robot.base.is_nonholonomic
            self.strict = as_flag(strict, "strict")
            self.constraints = _base_constraints(robot, self.constraints, self.reduced)
            self._solver: QPSolver = solver()
            self._q_shape = (robot.nq,)
            self._last: TickDiagnostics | None = None  # (read through the property last)
            #: the latest tick's (tick, solver, outcome, status, solve time, tick time, v, u), or v on the
            #: control loop's path (:meth:`_full_record`):
            #: what ``last`` is built from when read (a record object per tick would cost ~4 % of a tick)
            self._record: TickRecord | NativeRecord | None = None
            self._last_record: TickRecord | NativeRecord | None = None  # the record self._last was built from
            self._q_weights = finite_weights(robot.nq)  # q is finite iff q . w is (never an overflow warning)
            self._answer_tolerance = np.array([ANSWER_TOLERANCE])  # operand of the program's check of DAQP's answer
            self._allocate()

    # ----------------------------------------------------------------- copies
    def _specification(self) -> dict[str, Any]:
        """What a copy is built from: the arguments of :meth:`_setup` with today's settings."""
        return {"robot": self.robot, "tasks": self.tasks if self._level_sizes is None else self.levels,
                "constraints": self.constraints, "solver": self._solver, "dt": self.dt, "damping": self.damping,
                "reduced": self.reduced, "strict": self.strict, "lm_damping": self.lm_damping}

    def _warm_state(self) -> WarmState:
        """What the next tick starts from besides the specification: the tick counter, the
        previous command (the context's), the working sets of the DAQP workspaces that the
        program solves in (a qpsolvers backend carries its own warm start when copied) and what
        the constraints keep from tick to tick (:meth:`ConstraintData.warm_state`)."""
        previous = self._context.previous
        return WarmState(self._buffers.tick, [workspace.working_set for workspace in self._daqp_workspaces()],
                         None if previous is None else previous.copy(),
                         [data.warm_state() for data in self._constraint_data])

    def _daqp_workspaces(self) -> list[NativeWorkspace]:
        """The native DAQP workspaces the tick program solves in (the levels' or the one QP's)."""
        if self._hierarchy is not None:
            return self._hierarchy.workspaces
        bound = self._solver.bound if isinstance(self._solver, DaqpBackend) and self._solve_in_program else None
        return [bound] if bound is not None else []

    def __reduce__(self) -> tuple[Callable[..., Controller], tuple[type[Controller], dict[str, Any], WarmState]]:
        """Pickles (and, through :meth:`__copy__` / :meth:`__deepcopy__`, copies) are new
        controllers built from the specification and the warm state -- never this one's
        buffers, program or solver workspaces."""
        return _rebuilt, (type(self), self._specification(), self._warm_state())

    def __copy__(self) -> Controller:
        """A controller of the same robot and the same task and constraint objects (their
        settings act in both), with buffers, program and backend of its own."""
        specification = self._specification()
        specification["solver"] = copy.deepcopy(self._solver)
        return _rebuilt(type(self), specification, self._warm_state())

    def __deepcopy__(self, memo: dict[int, Any]) -> Controller:
        """A controller of copies of the robot, tasks and constraints (independent settings)."""
        return _rebuilt(type(self), copy.deepcopy(self._specification(), memo), self._warm_state())

    def _twin(self) -> Controller:
        """A deep copy as a plain ``Controller``, for the warm-up (:mod:`wbc.control.warm_up`):
        a subclass's own ``step`` may act on the world."""
        return _rebuilt(Controller, copy.deepcopy(self._specification()), self._warm_state())

    # --------------------------------------------------------------- settings
    _dt: float  # where dt lives
    _lifted: LiftedQP | None  # the lifted QP at high DOF (wbc.qp.lifting), None otherwise
    _answer_size: int  # the native tick's: the size of DAQP's answer, copied into a new array by the program
    _outcome: memoryview  # the native tick's: DAQP's control vector (kernels.DAQP_CONTROL_*; with _stepper)
    _packed_program: NDArray[np.int64]  # the native tick's: the program's packed operands (with _stepper)

    @property
    def last(self) -> TickDiagnostics:
        """The diagnostics record of the latest :meth:`step`.

        Raises:
            NoTickYetError: before the first :meth:`step` (a :class:`~wbc.core.errors.WbcError` and an
                ``AttributeError``: ``getattr(controller, "last", None)`` is None until then).
        """
        last, record = self._last, self._record
        if record is None:
            raise NoTickYetError("controller.last: no tick yet; call controller.step(q) first")
        if last is None or self._last_record is not record:  # built on the first read after a step
            last = self._last = TickDiagnostics(self._buffers, *self._full_record())
            self._last_record = record
        return last

    def _full_record(self) -> TickRecord:
        """The latest tick's record: the control loop's path records v only -- the rest of it is
        the same on every tick of that path: the tick is the counter's (a step that raised neither
        counted nor recorded), the solver this program's, optimal, v = u; the tick time is the
        program's own clock's and the solve time DAQP_ACCEPT's copy (with strict priorities the
        levels' sum, DAQP_ACCEPT_LEVEL's), each of the latest accepted native run (written by that
        run only: a later step that raised leaves them); with strict priorities the levels'
        answers are then the workspaces' (:meth:`~wbc.control.hierarchy.Hierarchy.use_native_answers`)."""
        record = self._record
        assert record is not None  # (read after the first step)
        if isinstance(record, np.ndarray):
            if self._hierarchy is not None:
                self._hierarchy.use_native_answers()
            return (self._buffers.tick, self._solver_name, _OPTIMAL, "optimal", self._outcome[_ACCEPTED_SOLVE_TIME],
                    self._program.accepted_run_time(), record, record)
        return record

    @property
    def dt(self) -> float:
        """Control period [s] (> 0); may be changed between ticks."""
        return self._dt

    @dt.setter
    def dt(self, value: float) -> None:
        self._dt = self._context.dt = as_positive(value, "dt")

    @property
    def context(self) -> TickContext:
        """The tick's context (:class:`~wbc.model.tick_context.TickContext`): kinematics, ``dt``,
        the previous command, the measured velocity given to :meth:`step`."""
        return self._context

    @property
    def damping(self) -> float:
        """Weight of ``|v|^2`` in the cost (>= 0); may be changed between ticks."""
        return float(self._cost_scaling[0])

    @damping.setter
    def damping(self, value: float) -> None:
        self._cost_scaling[0] = as_nonnegative(value, "damping")
        np.fill_diagonal(self._damping_rows, np.sqrt(self._cost_scaling[0]))

    @property
    def lm_damping(self) -> float:
        """Scale of the error-scaled damping of the tasks (>= 0, dimensionless; see the class
        docstring); may be changed between ticks."""
        return float(self._lm_damping[0])

    @lm_damping.setter
    def lm_damping(self, value: float) -> None:
        self._lm_damping[0] = as_nonnegative(value, "lm_damping")

    @property
    def levels(self) -> list[list[Task]]:
        """The priority levels, highest first (a flat ``tasks`` list is one level)."""
        sizes, start, levels = self._level_sizes or [len(self.tasks)], 0, []
        for size in sizes:
            levels.append(self.tasks[start:start + size])
            start += size
        return levels

    @property
    def solver(self) -> QPSolver:
        """The QP backend (:func:`wbc.solvers.make_solver`); assigning another one rebuilds
        the tick program (the solve may run inside it)."""
        return self._solver

    @solver.setter
    def solver(self, solver: QPSolver) -> None:
        if not isinstance(solver, QPSolver):
            raise InvalidInputError(f"solver must be a wbc.solvers.QPSolver (see make_solver), got "
                                    f"{type(solver).__name__}")
        self._solver = solver
        self._fallback.budget = solver.fallback_budget
        self._build_program()

    # ------------------------------------------------------------------ setup
    def _allocate(self) -> None:
        robot, nv = self.robot, self.robot.nv
        # each item's data for this controller (Model/Data: the items stay specifications)
        self._context.braking = None  # set again by the acceleration bounds of this stack, if any
        self._task_data = [self._bind(task) for task in self.tasks]
        self._constraint_data = [self._bind(constraint) for constraint in self.constraints]

        self._task_stack = stack = TaskStack(self._task_data, nv)
        self._stack_t, self._damping_rows = stack.stack_t, stack.damping_rows
        self._task_blocks, self._preview_blocks, self._n_plain = stack.blocks, stack.preview_blocks, stack.n_plain
        self._linear_blocks = stack.linear_blocks
        self.damping = self.damping  # writes sqrt(damping) I into its rows

        n_ineq = sum(c.n_inequalities for c in self._constraint_data)
        n_eq = sum(c.n_equalities for c in self._constraint_data)
        self._qp_v = qp = QP(nv, n_ineq, n_eq)
        layout = ConstraintLayout(self._constraint_data, qp, _velocity_names(robot))
        self._bound_policy = bounds = layout.bounds
        self._constraint_blocks = layout.blocks
        self._context.speed_bound[:] = layout.speed_bound  # (what the hard constraints' bound_speed declare)
        # the elastic fallback gets the main backend's budget (time; iterations if DAQP)
        self._fallback = Fallback(layout.soft_rows, self.solver.fallback_budget, self.strict)
        self._factor = np.zeros((nv, nv))  # its Cholesky factor (scratch)

        self._S = robot.input_map(robot.neutral())
        self._reduction = InputReduction(self._S, n_ineq, n_eq) if self.reduced else None
        #: the inputs stage of the tick's pipeline (wbc.control.pipelines): the base's input map
        self._inputs = inputs_of(robot, self._S, self._reduction, qp)
        # what the hierarchy, the fallback and the diagnostics read (never the controller)
        self._buffers = buffers = TickBuffers(self.kinematics, self._task_data, stack, qp, layout, self._cost_scaling,
                                              self._lm_damping, self._S, self._reduction, self._context)
        self._preview = buffers.preview  # holonomic relaxation -H^-1 c of the plain tasks
        if self._reduction is not None:
            kernels.merge_bounds(bounds.bounds.reshape(-1, nv), bounds.n_hard, qp.ub, qp.lb)  # static bounds,
            self._reduction.check_bounds(qp)  # checked once
        # strict priorities (wbc.control.hierarchy): one QP per level, their cascade and its fallback
        self._hierarchy = None
        if self._level_sizes is not None:
            self._hierarchy = buffers.cascade = Hierarchy(buffers, self._level_sizes, self.solver, self._fallback)
            self._fallback = self._hierarchy.fallback
        self._build_program()

    @overload
    def _bind(self, item: Task) -> TaskData: ...
    @overload
    def _bind(self, item: Constraint) -> ConstraintData: ...
    def _bind(self, item: Task | Constraint) -> TaskData | ConstraintData:
        """``item``'s data for this controller (:meth:`wbc.item.Item.bind`); from now on only
        the item's settings may change."""
        data = item.bind(self.robot)
        if not isinstance(item, (TaskData, ConstraintData)):  # (an item declared as its own data may define them)
            _refuse_ignored_overrides(item, data)
        use_context = getattr(data, "use_context", None)
        if callable(use_context):  # data that reads the tick's context (wbc.model.tick_context)
            use_context(self._context)
        item._in_use = True
        return data

    @overload
    def data(self, item: Task) -> TaskData: ...
    @overload
    def data(self, item: Constraint) -> ConstraintData: ...
    def data(self, item: Task | Constraint) -> TaskData | ConstraintData:
        """This controller's data of ``item`` (e.g. ``controller.data(task).error``): what
        ``item.bind(robot)`` returned when the controller was built.

        Raises:
            InvalidInputError: ``item`` is not one of this controller's tasks or constraints.
        """
        for task, task_data in zip(self.tasks, self._task_data, strict=True):
            if task is item:
                return task_data
        for constraint, constraint_data in zip(self.constraints, self._constraint_data, strict=True):
            if constraint is item:
                return constraint_data
        raise InvalidInputError(f"{item!r} is not used by this controller")

    def _build_program(self) -> None:
        """The compiled part of the tick (wbc.runtime.program): the ops of every task and constraint
        that has them, the normal equations, the holonomic preview, the bound merge, the cost
        normalisation and the NaN screen -- one native call -- and the tick's pipeline
        (:mod:`wbc.control.pipelines`) for this mode. Items without ops compute in Python
        before it; preview tasks without ops (custom ones) compute between two parts of it,
        after the preview they need."""
        kin = self.kinematics
        program = TickProgram()
        program.add(kernels.HAS_NAN, data=kin.q, size=kin.q.size, infinite=1)  # q's finiteness (see step)
        # the compiled forward kinematics (native chains), before every item; dropped again in
        # _finish_program when Python items make the kinematics be computed before the program
        row = len(program)
        self._kinematics_op = row if kin.add_op(program) else None  #: its row in the program
        self._python_tasks, self._python_constraints = self._item_ops(program)
        self._lifted = None
        solve: BackendSolve
        if self._hierarchy is not None:  # strict priorities: the levels' QPs and their cascade (wbc.control.hierarchy)
            self._python_preview, rest, qp, self._solve_in_program = self._hierarchy.add_ops(program, self.solver)
            solve = (CascadeInProgram if self._solve_in_program else CascadeSolve)(self._hierarchy, qp)
        else:
            self._python_preview, rest, solve = self._flat_ops(program)
        self._finish_program(program, rest, solve)

    def _item_ops(self, program: TickProgram) -> tuple[list[PythonTask], list[PythonConstraint]]:
        """Append the ops of the compiled items to ``program``; the items left to Python. Items
        whose subclass overrides compute keep their own rows: no inherited ops for them."""
        kin, stack = self.kinematics, self._stack_t
        tasks = [(task, jacobian, target) for task, jacobian, target, start in self._task_blocks + self._linear_blocks
                 if not (ops_follow_compute(task) and task.add_ops(program, kin, stack, start))]
        constraints = [(constraint, block) for constraint, block in self._constraint_blocks
                       if not (ops_follow_compute(constraint) and constraint.add_ops(program, kin, block))]
        return tasks, constraints

    def _flat_ops(self, program: TickProgram) -> tuple[list[PythonTask], TickProgram, BackendSolve]:
        """One level's assembly (dense, or lifted at high DOF with native DAQP) and its solve:
        (Python preview tasks, the program part after them, the solve stage)."""
        qp, nv, stack = self._qp_v, self.robot.nv, self._stack_t
        self._lifted = self._lifting()
        self._lm = LMDamping(self._lm_damping, 1)
        if self._lm.add_task_ops(program, stack, self._task_blocks, 0):  # sqrt(max(damping, mu)) I: the damping rows
            self._lm.add_rows_op(program, stack, self._n_plain - nv, self._cost_scaling)
        if self._lifted is not None:
            return [], program, self._lifted_ops(program)
        program.add(kernels.NORMAL_EQUATIONS, stack=stack, nv=nv, rows=stack.shape[1], first=0, last=self._n_plain,
                    reset=1, Hc=qp.Hc)
        self._task_stack.add_linear_op(program, qp)
        python_preview, rest = self._preview_ops(program)
        self._bound_policy.add_op(rest, qp)
        rest.add(kernels.NORMALISE_COST, Hc=qp.Hc, scaling=self._cost_scaling, nv=nv)
        rest.add(kernels.HAS_NAN, data=qp.data, size=qp.data.size, infinite=0)
        target = self._reduction.qp if self._reduction is not None else qp  # what the solver sees
        # the solve itself, when the backend can run in the program (native DAQP) and no
        # Python step (the input reduction) stands between the QP and the solver
        self._solve_in_program = not self.reduced and self.solver.bind_program(rest, target)
        return python_preview, rest, (ProgramSolve if self._solve_in_program else BackendSolve)(self.solver, target)

    def _lifting(self) -> LiftedQP | None:
        """The lifted QP (the dense task rows as variables, :mod:`wbc.qp.lifting`) when it pays:
        high DOF, native DAQP, plain form, no preview; None otherwise."""
        if self.reduced or self._preview_blocks or self._linear_blocks or not getattr(self.solver, "native", False):
            return None
        diagonal = dense_rows(self._task_stack, self.robot.nv)
        return LiftedQP(self._qp_v, diagonal) if worth_lifting(self.robot.nv, diagonal) else None

    def _lifted_ops(self, program: TickProgram) -> LiftedSolve:
        """The lifted QP's assembly, its solve and certificate, all in the program (native DAQP)."""
        assert self._lifted is not None and isinstance(self._solver, DaqpBackend)
        self._bound_policy.add_op(program, self._qp_v)
        self._lifted.add_op(program, self._stack_t, self._cost_scaling)
        self._solve_in_program = self._solver.bind_program(program, self._lifted.qp)
        assert self._solver.bound is not None  # lifting needs native DAQP, so the solve is in the program
        self._lifted.add_check_op(program, self._solver.bound)
        return LiftedSolve(self._solver, self._lifted, self._buffers)

    def _preview_ops(self, program: TickProgram) -> tuple[list[PythonTask], TickProgram]:
        """The holonomic preview -H^-1 c of the plain tasks and the rows of the tasks that need
        it (SteeringTask): (the preview tasks left to Python, the program part after them)."""
        if not self._preview_blocks:
            return [], program
        kin, stack, nv = self.kinematics, self._stack_t, self.robot.nv
        program.add(kernels.PREVIEW, Hc=self._qp_v.Hc, factor=self._factor, preview=self._preview, nv=nv)
        python_preview = [(task, jacobian, target) for task, jacobian, target, start in self._preview_blocks
                          if not (ops_follow_compute(task, "compute_preview", "add_preview_ops")
                                  and task.add_preview_ops(program, kin, stack, start, self._preview))]
        rest = TickProgram() if python_preview else program  # runs after the Python preview tasks
        rest.add(kernels.NORMAL_EQUATIONS, stack=stack, nv=nv, rows=stack.shape[1], first=self._n_plain,
                 last=self._task_stack.n_quadratic, reset=0, Hc=self._qp_v.Hc)
        return python_preview, rest

    def _finish_program(self, program: TickProgram, rest: TickProgram, solve: BackendSolve) -> None:
        """Keep the program (and its part after the Python preview tasks, if any) and the
        pipeline's assembly and solve stages."""
        if self._record is not None:  # a rebuilt program (another solver): the latest tick's record as it was
            self._record = self._full_record()
        self._program, self._program_after_preview = program, (rest if rest is not program else None)
        self._solve, self.qp = solve, solve.qp  #: qp: what the solver sees (the last level's with priorities)
        # Python items see the kinematics before the program runs: for them q is checked up front
        self._q_screened = not (self._python_tasks or self._python_constraints or self._python_preview)
        if not self._q_screened and self._kinematics_op is not None:  # Kinematics.update computes them already
            program.drop(self._kinematics_op)
        split = self._program_after_preview is not None
        # the workspace whose answer is the command when the program solves: the one QP's, or the last level's
        bound = self._solver.bound if type(solve) is ProgramSolve and isinstance(self._solver, DaqpBackend) else None
        levels_above: list[NativeWorkspace] = []  # with strict priorities: their solve times add up
        if type(solve) is CascadeInProgram and self._hierarchy is not None:
            *levels_above, bound = self._hierarchy.workspaces  # (the BAND ops stop the levels below a failed one)
        if bound is not None and not split:  # the program checks DAQP's answer itself (see step)
            bound.add_accept_op(program, self._answer_tolerance, levels_above)
        if self._kinematics_op is not None and self._q_screened:
            program.set_input(self.kinematics.q)  # q copied in by the program (the native tick's stepper)
        self._assembly = Assembly(self._context, self.robot, self._buffers, self._task_data, self._python_tasks,
                                  self._python_constraints, program, self._q_screened, self._q_weights,
                                  None if split else self._inputs)
        if split:
            self._assembly = SplitAssembly(self._assembly, self._buffers, self._python_preview, rest, self._inputs)
        # the hot path's callables (bound once: wbc.control.pipelines)
        self._assemble, self._fast, self._command = self._assembly.run, solve.fast, solve.command(self._inputs)
        # the control loop's path, when the program does the whole tick and v = x: one native call
        # from q to the checked answer (step), from the first tick on (its tasks checked first: here when
        # they are ready now, else by the first step)
        self._native_step: _NativeStep | None = None  # step's
        self._stepper: functools.partial[int] | None = None  # the program's stepper: its entry is what _native_step
        if (bound is not None and not split and self._assembly.all_in_program and self._command is None
                and self._kinematics_op is not None and self._q_screened):
            program.set_clock(*bound.clock)  # the native tick's tick time (see step)
            program.set_output(bound.x)  # the program copies DAQP's answer (the last level's) into step's array
            self._stepper = program.stepper()
            self._packed_program = self._stepper.args[0]  # (step calls the partial's entry itself: ~60 ns less)
            self._answer_size, self._outcome = bound.x.size, bound.control_view
            if self._assembly.ready():  # every target set already: the first tick is the native call too
                self._native_step = self._stepper.func
        self._solver_name = self._solver.name

    # --------------------------------------------------------------- hot path
    def step(self, q: ArrayLike, v_measured: ArrayLike | None = None) -> NDArray[np.float64]:
        """Compute the joint velocity command for configuration ``q``.

        Args:
            q: the configuration, size ``robot.nq`` (Pinocchio's; for the youBot
                ``(X_C, Y_C, theta, theta1..theta5)``).
            v_measured: the measured joint velocity [unit/s], size ``robot.nv``, if the robot
                reports one: this tick's :attr:`context` holds it for the items that read it
                (no shipped item does yet); the command does not depend on it otherwise.

        Returns:
            The command ``v``, size ``robot.nv``, never NaN and within every hard limit;
            :attr:`last` describes the tick. When the QP cannot be solved it comes from the
            fallback chain of the class docstring (``last.status`` says which link answered).

        Raises:
            InvalidInputError: ``q`` or ``v_measured`` is malformed (wrong shape, not numbers,
                NaN or inf). A
                non-finite ``q`` is caught by the program's screen, so the previous tick's lazy
                diagnostics are stale afterwards.
            SolverError: with ``strict=True``, when the QP cannot be solved.
        """
        native = self._native_step
        if native is None and v_measured is None and not self._buffers.tick and self._stepper is not None:
            self._assembly.check_ready()  # the first tick: the tasks checked here, then the one native call
            native = self._native_step = self._stepper.func
        if native is not None and v_measured is None:  # the control loop's path: the tick in one native call
            if not (type(q) is _NDARRAY and q.dtype is _FLOAT64 and q.ndim == 1):  # (what the entry does not check)
                q = self.robot.check_configuration(q)
            # q copied in (its size checked: RUN_BAD_INPUT, nothing run; its finiteness by the program's screen),
            # the program run, DAQP's answer checked (_finish_program) and, accepted, copied into v -- a new
            # array made before the call: after it, numpy's allocation runs from a cold cache (~0.1 us more)
            v = _empty(self._answer_size)
            run = native(self._packed_program, q, v, self._dt)
            self.kinematics.current = NOTHING_CURRENT  # (the program wrote q: Pinocchio's data is stale)
            if run == RUN_ACCEPTED:  # the solve and tick times are the program's (see _full_record)
                self._buffers.tick += 1
                self._context.previous = self._record = v
                return v
            if run == RUN_BAD_INPUT:
                self.robot.check_configuration(q)  # raises: q has the wrong size
            start = _clock() - self._program.run_time()  # (this tick began with the native run)
            has_nan, answer = run == RUN_FOUND_NAN, None
            if has_nan:
                self._assembly.screen(q)  # raises for a non-finite q, as the assembly does
        else:  # the pipeline of this controller's mode (wbc.control.pipelines): assembly, solve, command
            start = _clock()
            if not (type(q) is _NDARRAY and q.dtype is _FLOAT64 and q.shape == self._q_shape
                    and (self._q_screened or math.isfinite(q.dot(self._q_weights)))):  # check_configuration's fast path
                q = self.robot.check_configuration(q)
            self._native_step = None  # (a tick with v_measured: the next one clears the context's on this path)
            has_nan = self._assemble(q, self._dt, v_measured)
            answer = None if has_nan else self._fast(ANSWER_TOLERANCE)  # solved and checked in the program already
            if v_measured is None:
                self._native_step = None if self._stepper is None else self._stepper.func  # (tasks checked)
        buffers = self._buffers
        buffers.tick += 1
        if answer is not None:  # the control loop's path
            (x, solve_time), outcome, status = answer, _OPTIMAL, "optimal"
        else:
            x, solve_time, outcome, status = self._answer(has_nan)
        command = self._command  # None: v = u = x (a holonomic or fixed base, the QP over v)
        v, u = (x, x) if command is None else command(x)
        self._context.previous = v
        self._record = (buffers.tick, self._solver_name, outcome, status, solve_time, _clock() - start, v, u)
        return v

    def _answer(self, has_nan: bool) -> tuple[NDArray[np.float64], float, Outcome, str]:
        """(x, solve time [s], outcome, status) of this tick off the fast path: the solve stage's
        answer checked against the QP's bounds and rows, or the fallback chain's."""
        solution, qp = ((QPSolution(None, False, self._inputs.failure, 0.0), self.qp) if has_nan
                        else self._solve.checked())
        if solution.success:
            assert solution.x is not None  # a successful solve has an answer
            return solution.x, solution.solve_time, _OPTIMAL, "optimal"
        solution, outcome, status = self._fallback.answer(qp, solution, self._solver.name, self._buffers.tick, has_nan)
        assert solution.x is not None  # the fallback chain always answers (v = 0 at worst)
        return solution.x, solution.solve_time, outcome, status

    # ------------------------------------------------------------ diagnostics
    def constraint_violation(self, v: NDArray[np.float64]) -> float:
        """Largest violation of this tick's bounds and rows by ``v`` (0 when feasible)."""
        return self._buffers.constraint_violation(v)

    def active_constraints(self, v: NDArray[np.float64]) -> list[str]:
        """Labels of this tick's bounds and rows that ``v`` meets with equality."""
        return self._buffers.active_constraints(v)

    def __repr__(self) -> str:
        tasks = self.tasks if self._hierarchy is None else self.levels
        return (f"Controller({self.robot.name!r}, tasks={tasks}, constraints={self.constraints}, "
                f"solver={self.solver.name!r}, dt={self.dt}, reduced={self.reduced})")


_FLOAT64 = np.dtype(np.float64)
_NDARRAY = np.ndarray  # (a global: one attribute lookup less per step)
_empty = np.empty
#: the tick program's compiled entry, called by step: (packed operands, q, out, dt) -> what the run returned
_NativeStep = Callable[[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64], float], int]
_OPTIMAL = Outcome.OPTIMAL
_clock = time.perf_counter  # step's tick time
_ACCEPTED_SOLVE_TIME = kernels.DAQP_CONTROL_ACCEPTED_TIME


#: what a task's or constraint's data computes (TaskData / ConstraintData)
_DATA_METHODS = ("compute", "compute_preview", "add_ops", "add_preview_ops", "report", "write_static",
                 "row_labels")


def _refuse_ignored_overrides(item: Task | Constraint, data: TaskData | ConstraintData) -> None:
    """A specification defining what its (separate) data computes would be silently ignored:
    refuse it, naming the data class to subclass instead (``Task`` and ``Constraint`` define
    none of those methods, so any found on the item is the subclass's)."""
    for name in _DATA_METHODS:
        if hasattr(item, name):
            raise InvalidInputError(
                f"{type(item).__name__} defines {name}(), but its rows are computed by {type(data).__name__}: "
                f"subclass {type(data).__name__} and return it from bind() (docs/extending.md)")


def _base_constraints(robot: Robot, constraints: list[Constraint], reduced: bool) -> list[Constraint]:
    """``constraints`` for ``robot``'s model: with :class:`MimicJoints` for its coupled joints (added
    unless given); without the rows the input map satisfies in the reduced form; with them
    (checked) for a nonholonomic base in plain form."""
    if robot.couplings and not any(type(c) is MimicJoints and c.couplings is None for c in constraints):
        constraints = [*constraints, MimicJoints()]
    if reduced:
        return [c for c in constraints if not c.satisfied_by_input_map]
    if robot.base.is_nonholonomic and not any(c.satisfied_by_input_map for c in constraints):
        raise InvalidInputError(f"robot '{robot.name}' has a {robot.base.name} base: add "
                                "NonholonomicBase() to the constraints or use reduced=True")
    return constraints


def _velocity_names(robot: Robot) -> list[str]:
    names = []
    for joint, name in zip(robot.model.joints[1:], robot.joint_names, strict=True):
        names += [name] if joint.nv == 1 else [f"{name}[{i}]" for i in range(joint.nv)]
    return names


#: what one step records for its diagnostics (:class:`TickDiagnostics`' arguments after the buffers)
TickRecord = tuple[int, str, Outcome, str, float, float, NDArray[np.float64], NDArray[np.float64]]
#: what a step on the control loop's path records: v (:meth:`Controller._full_record`)
NativeRecord = NDArray[np.float64]


class WarmState(NamedTuple):
    """A controller's state beyond its specification (:meth:`Controller._warm_state`)."""

    tick: int  #: the tick counter
    working_sets: list[NDArray[np.intc]]  #: DAQP's constraint states, one per workspace of the program
    previous: NDArray[np.float64] | None  #: the previous command (``TickContext.previous``)
    constraints: list[Any]  #: each constraint data's :meth:`~wbc.constraints.constraint.ConstraintData.warm_state`


def _rebuilt(cls: type[Controller], specification: dict[str, Any], warm: WarmState) -> Controller:
    """A controller of class ``cls`` built from ``specification`` (:meth:`Controller._specification`;
    its solver an object) and ``warm``: what copies and pickles of one are."""
    solver = specification.pop("solver")
    controller = cls.__new__(cls)
    controller._setup(solver=lambda: solver, **specification)
    controller._buffers.tick, controller._context.previous = warm.tick, warm.previous
    workspaces = controller._daqp_workspaces()
    if len(workspaces) == len(warm.working_sets):  # (the same modes: always, unless DAQP's C API went missing)
        for workspace, states in zip(workspaces, warm.working_sets, strict=True):
            workspace.working_set = states
    for data, state in zip(controller._constraint_data, warm.constraints, strict=True):
        if state is not None:
            data.resume(state)
    return controller
