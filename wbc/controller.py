"""The control tick: kinematics -> tasks and constraints -> QP -> solver -> command.

The whole hot path is :meth:`Controller.step`. Every buffer is allocated once in
``__init__``; a tick writes into views of them:

    Js v ~ rs          (stacked weighted task rows, one block per task)
    H = Js^T Js + damping I,   c = -Js^T rs
    lb = max_k lower_k,  ub = min_k upper_k   (bounds of all constraints)
    G v <= h,  A v = b                         (rows of all constraints)
"""

from __future__ import annotations

import time
from collections.abc import Sequence

import numpy as np

from .constraints.constraint import Constraint, ConstraintRows
from .diagnostics import ActiveSetLabels, TickDiagnostics
from .errors import InvalidInputError, SolverError
from .kinematics import Kinematics
from .qp import QP
from .robot import Robot
from .solvers import QPSolver, make_solver
from .tasks.task import Task
from .validation import as_positive


class Controller:
    """QP whole-body velocity controller.

    Args:
        robot: the robot model.
        tasks: cost terms (at least one).
        constraints: hard limits.
        solver: a name from :func:`wbc.available_solvers` (default ``"daqp"``).
        dt: control period [s]; per-tick gains and dampers refer to it.
        damping: Tikhonov term ``damping * |v|^2`` [cost] / [unit/s]^2, keeps H positive definite.
        solver_options: settings passed to the backend (override :data:`wbc.solvers.DEFAULT_SETTINGS`).
    """

    def __init__(self, robot: Robot, tasks: Sequence[Task], constraints: Sequence[Constraint] = (),
                 solver: str = "daqp", dt: float = 0.01, damping: float = 1e-3,
                 solver_options: dict | None = None) -> None:
        if not isinstance(robot, Robot):
            raise InvalidInputError(f"robot must be a wbc.Robot, got {type(robot).__name__}")
        self.robot = robot
        self.dt = as_positive(dt, "dt")
        self.damping = float(damping)
        if not np.isfinite(self.damping) or self.damping < 0:
            raise InvalidInputError(f"damping must be finite and >= 0, got {damping}")
        self.tasks = list(tasks)
        self.constraints = list(constraints)
        if not self.tasks:
            raise InvalidInputError("a controller needs at least one task")
        for item in self.tasks:
            if not isinstance(item, Task):
                raise InvalidInputError(f"not a Task: {item!r}")
        for item in self.constraints:
            if not isinstance(item, Constraint):
                raise InvalidInputError(f"not a Constraint: {item!r}")
        self.solver: QPSolver = make_solver(solver, solver_options)
        self.kinematics = Kinematics(robot)
        self._tick = 0
        self.last: TickDiagnostics | None = None
        self._allocate()

    # ------------------------------------------------------------------ setup
    def _allocate(self) -> None:
        nv = self.robot.nv
        for task in self.tasks:
            task.bind(self.robot)
        for constraint in self.constraints:
            constraint.bind(self.robot)

        rows = sum(task.dim for task in self.tasks)
        self._Js = np.zeros((rows, nv))
        self._rs = np.zeros(rows)
        self._task_blocks = []
        start = 0
        for task in self.tasks:
            stop = start + task.dim
            self._task_blocks.append((task, self._Js[start:stop], self._rs[start:stop]))
            start = stop

        n_ineq = sum(c.n_inequalities for c in self.constraints)
        n_eq = sum(c.n_equalities for c in self.constraints)
        self.qp = QP(nv, n_ineq, n_eq)
        bounded = [c for c in self.constraints if c.has_bounds]
        self._lower = np.full((max(len(bounded), 1), nv), -np.inf)
        self._upper = np.full((max(len(bounded), 1), nv), np.inf)
        self._constraint_blocks = []
        row_labels: list[str] = []
        i_ineq = i_eq = 0
        for constraint in self.constraints:
            k = bounded.index(constraint) if constraint.has_bounds else None
            lower = self._lower[k] if k is not None else np.full(nv, -np.inf)
            upper = self._upper[k] if k is not None else np.full(nv, np.inf)
            p, e = constraint.n_inequalities, constraint.n_equalities
            block = ConstraintRows(lower, upper,
                                   self.qp.G[i_ineq:i_ineq + p], self.qp.h[i_ineq:i_ineq + p],
                                   self.qp.A[i_eq:i_eq + e], self.qp.b[i_eq:i_eq + e])
            self._constraint_blocks.append((constraint, block))
            row_labels += [f"{constraint.name}: {label}" for label in constraint.row_labels()[:p]]
            constraint.write_static(block)
            i_ineq, i_eq = i_ineq + p, i_eq + e
        for constraint in self.constraints:
            labels = constraint.row_labels()[constraint.n_inequalities:]
            row_labels += [f"{constraint.name}: {label}" for label in labels]
        names = _velocity_names(self.robot)
        bound_labels = [[f"{c.name}: {name} {side}" for side in ("upper", "lower") for name in names]
                        for c in bounded] or [[""] * (2 * nv)]
        self._labels = ActiveSetLabels(bound_labels, row_labels)
        self._diag = np.arange(nv) * (nv + 1)

    # --------------------------------------------------------------- hot path
    def step(self, q) -> np.ndarray:
        """Compute the joint velocity command ``v`` (shape (nv,)) for configuration ``q``.

        Raises InvalidInputError for a malformed ``q`` and SolverError when the QP
        backend fails (the returned command is never NaN).
        """
        start = time.perf_counter()
        q = self.robot.check_configuration(q)
        kin, dt, qp = self.kinematics, self.dt, self.qp
        kin.update(q)

        for task, jacobian, target in self._task_blocks:
            task.compute(kin, dt, jacobian, target)
        np.matmul(self._Js.T, self._Js, out=qp.H)
        qp.H.flat[self._diag] += self.damping
        np.matmul(self._Js.T, self._rs, out=qp.c)
        np.negative(qp.c, out=qp.c)

        for constraint, block in self._constraint_blocks:
            constraint.compute(kin, dt, block)
        qp.lb[:], qp.ub[:] = self._lower[0], self._upper[0]
        for lower, upper in zip(self._lower[1:], self._upper[1:]):
            np.maximum(qp.lb, lower, out=qp.lb)
            np.minimum(qp.ub, upper, out=qp.ub)
        if qp.n_eq:
            qp.sync_equalities()

        solution = self.solver.solve(qp)
        self._tick += 1
        if not solution.success:
            self.last = self._diagnostics(None, solution, start)
            raise SolverError(f"{self.solver.name} failed at tick {self._tick}: {solution.status}")
        v = solution.x
        self.last = self._diagnostics(v, solution, start)
        return v

    # ------------------------------------------------------------ diagnostics
    def _diagnostics(self, v, solution, start: float) -> TickDiagnostics:
        errors: dict[str, float] = {}
        if v is None:
            return TickDiagnostics(self._tick, self.solver.name, solution.status, False, solution.solve_time,
                                   time.perf_counter() - start, errors)
        for task in self.tasks:
            task.report(v, errors)
        qp = self.qp
        rows = None
        if qp.n_ineq or qp.n_eq:
            rows = qp.C @ v
            rows -= qp.upper[qp.n:]
        return TickDiagnostics(
            self._tick, self.solver.name, solution.status, True, solution.solve_time,
            time.perf_counter() - start, errors, v.copy(), self._lower.copy(), self._upper.copy(),
            rows, qp.n_ineq, self._labels,
        )

    def __repr__(self) -> str:
        return (f"Controller({self.robot.name!r}, tasks={self.tasks}, constraints={self.constraints}, "
                f"solver={self.solver.name!r}, dt={self.dt})")


def _velocity_names(robot: Robot) -> list[str]:
    names = []
    for joint, name in zip(robot.model.joints[1:], robot.joint_names):
        names += [name] if joint.nv == 1 else [f"{name}[{i}]" for i in range(joint.nv)]
    return names
