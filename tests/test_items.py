"""Generic checks over every registered task and constraint (tests/item_registry.py): the
Jacobian by finite differences, and the rows in closed loop. Promise suites stay elsewhere."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

import wbc
from item_registry import CASES, CONFIGURATIONS, Case, load
from wbc.constraints.constraint import Constraint, ConstraintData, ConstraintRows
from wbc.model.kinematics import Kinematics
from wbc.tasks.task import Task, TaskData

DT = 0.01
ROBOTS: dict[str, wbc.Robot] = {}


def robot_of(case: Case) -> wbc.Robot:
    if case.robot not in ROBOTS:
        ROBOTS[case.robot] = load(case.robot)
    return ROBOTS[case.robot]


def case_id(case: Case) -> str:
    return case.name if case.robot != "floating_puma" else f"{case.name}-floating"


def test_every_exported_item_is_registered():
    exported = {name for name in wbc.__all__ if isinstance(getattr(wbc, name), type)
                and issubclass(getattr(wbc, name), (Task, Constraint)) and name not in ("Task", "Constraint")}
    assert exported == {case.name for case in CASES}


@pytest.mark.parametrize("case", CASES, ids=case_id)
def test_a_specification_is_not_its_data(case: Case):
    """Issue 23 §2: an item is its settings; what one controller computes is a separate data
    object (``Task`` no longer inherits from ``TaskData``)."""
    robot = robot_of(case)
    item = case.make(robot, CONFIGURATIONS[case.robot][1])
    data = item.bind(robot)
    assert data is not item and not isinstance(item, (TaskData, ConstraintData))
    assert isinstance(data, TaskData if isinstance(item, Task) else ConstraintData)
    assert data.name == item.name


class _Silent(Task):
    """A task that says nothing about its rows."""


class _OldStyle(Task):
    """A task written for wbc <= 0.3 (every Task was its own data)."""

    dim = 1

    def compute(self, kin, dt, jacobian, target):
        jacobian.fill(1.0)


class _OldStyleLimit(Constraint):
    n_equalities = 1

    def compute(self, kin, dt, rows):
        rows.A[0, 3] = 1.0


class _OwnData(Task, TaskData):
    """Declared as its own data: allowed (``v[3] = 0`` softly)."""

    dim = 1

    def compute(self, kin, dt, jacobian, target):
        jacobian[0, 3], target[0] = 1.0, 0.0


@pytest.mark.parametrize("item, message", [
    (_Silent(), "_Silent computes no rows: return a TaskData subclass from its bind(), or subclass "
                "wbc.tasks.error_task.ErrorTask"),
    (_OldStyle(), "_OldStyle defines compute() but is not a TaskData: declare it `class _OldStyle(Task, TaskData)`"),
    (Constraint(), "Constraint computes no rows: return a ConstraintData subclass"),
    (_OldStyleLimit(), "_OldStyleLimit defines compute() but is not a ConstraintData"),
])
def test_an_item_that_does_not_say_how_its_rows_are_computed_is_refused_naming_the_fix(item, message):
    youbot = wbc.load_robot("youbot")
    tasks, constraints = ([item], []) if isinstance(item, Task) else ([wbc.PostureTask(1.0)], [item])
    with pytest.raises(wbc.InvalidInputError) as raised:
        wbc.Controller(youbot, tasks, constraints)
    assert message in str(raised.value)


def test_an_item_declared_as_its_own_data_serves_as_it():
    youbot = wbc.load_robot("youbot")
    own = _OwnData()
    controller = wbc.Controller(youbot, [own, wbc.PostureTask(1e-3, gain=0.01)], [wbc.JointVelocityLimits()],
                                damping=1e-12)
    assert controller.data(own) is own
    q = youbot.neutral()
    q[3:] += 0.4  # the posture asks every arm joint for -gain/dt * 0.4 = -0.4 rad/s
    v = controller.step(q)
    # joint 3 also pays cost 1 for any speed: min 1e-3 (v3 + 0.4)^2 + v3^2 -> v3 = -0.4 * 1e-3 / (1 + 1e-3)
    np.testing.assert_allclose(v[4:], -0.4, rtol=1e-6)
    np.testing.assert_allclose(v[3], -0.4e-3 / 1.001, rtol=1e-6)


def task_rows(data: TaskData, robot: wbc.Robot, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(W J, W r) of a task's data at q, computed in Python."""
    kin = Kinematics(robot)
    kin.update(q)
    WJ, Wr = np.zeros((data.dim, robot.nv)), np.zeros(data.dim)
    data.write_static(WJ)
    data.compute(kin, DT, WJ, Wr)
    return WJ, Wr


def constraint_rows(data: ConstraintData, robot: wbc.Robot, q: np.ndarray) -> ConstraintRows:
    """A constraint data's rows at q, computed in Python."""
    kin = Kinematics(robot)
    kin.update(q)
    n, m, nv = data.n_inequalities, data.n_equalities, robot.nv
    rows = ConstraintRows(np.full(nv, -np.inf), np.full(nv, np.inf), np.zeros((n, nv)), np.zeros(n),
                          np.zeros((m, nv)), np.zeros(m))
    data.write_static(rows)
    data.compute(kin, DT, rows)
    return rows


@pytest.mark.parametrize("case", [case for case in CASES if case.feedback_gain is not None], ids=case_id)
def test_the_jacobian_is_the_derivative_of_the_fed_back_error(case: Case, rng):
    """At the goal q1 (error zero, no saturation), central differences of the target column (a
    constraint's h and finite bounds) along random v equal ``-gain/dt`` times the rows' J v."""
    robot = robot_of(case)
    q = CONFIGURATIONS[case.robot][1]
    item = case.make(robot, q)
    data = item.bind(robot)
    scale = case.feedback_gain / DT
    h = 1e-6
    for _ in range(5):
        v = rng.standard_normal(robot.nv)
        plus, minus = pin.integrate(robot.model, q, h * v), pin.integrate(robot.model, q, -h * v)
        if isinstance(item, Task):
            WJ, _ = task_rows(data, robot, q)
            derivative = (task_rows(data, robot, plus)[1] - task_rows(data, robot, minus)[1]) / (2 * h)
            expected = -scale * WJ @ v
        else:
            rows, up, down = (constraint_rows(data, robot, x) for x in (q, plus, minus))
            finite, active = np.isfinite(rows.upper) & np.isfinite(rows.lower), np.isfinite(rows.h)
            derivative = np.r_[(up.h[active] - down.h[active]) / (2 * h),
                               (up.upper[finite] - down.upper[finite]) / (2 * h),
                               (up.lower[finite] - down.lower[finite]) / (2 * h)]
            expected = -scale * np.r_[rows.G[active] @ v, v[finite], v[finite]]
            assert derivative.size > 0, "the constraint has rows at q1"
        assert np.abs(expected).max() > 1e-3, "a non-trivial direction"
        np.testing.assert_allclose(derivative, expected, rtol=0, atol=1e-5 * (1 + np.abs(expected).max()))


def _error(controller: wbc.Controller, name: str) -> float:
    return sum(value for key, value in controller.last.task_errors.items() if key.startswith(name))


@pytest.mark.parametrize("case", [case for case in CASES if isinstance(case.make(robot_of(case),
                                  CONFIGURATIONS[case.robot][1]), Task) and case.name != "SteeringTask"],
                         ids=case_id)
def test_tasks_in_closed_loop(case: Case):
    """From q0, the task alone (and the speed limits) drives its error to the goal's (zero): an
    error feedback removes it; a velocity reference gets ``min |W J v - W r|^2 + damping |v|^2``
    at every tick."""
    robot = robot_of(case)
    q, goal = CONFIGURATIONS[case.robot]
    task = case.make(robot, goal)
    controller = wbc.Controller(robot, [task], [wbc.JointVelocityLimits()], dt=DT, damping=1e-3)
    reference = task.bind(robot)  # another data of the task: rows written out in Python
    first = None
    for _ in range(400):
        v = controller.step(q)
        if case.feedback_gain is None:
            WJ, Wr = task_rows(reference, robot, q)  # the limits are inactive: the damped optimum
            if reference.linear:  # min 1/2 1e-3 |v|^2 + c^T v, c = the row
                optimum = -WJ[0] / 1e-3
            else:
                optimum = np.linalg.solve(WJ.T @ WJ + 1e-3 * np.eye(robot.nv), WJ.T @ Wr)
            np.testing.assert_allclose(v, optimum, rtol=0, atol=1e-9)
        elif first is None:
            first = _error(controller, task.name)
        q = robot.integrate(q, v, DT)
    if case.feedback_gain is not None:
        assert first > 1e-3
        assert _error(controller, task.name) < 1e-6 * first


END_FRAME = {"youbot": "ee", "deluca_mm": "wrist_center", "floating_puma": "ee"}


def _pushing_tasks(case: Case, robot: wbc.Robot, item: Constraint, q: np.ndarray) -> list[Task]:
    """Tasks that drive the robot into the item's rows: the end frame at full gain to a point
    out of reach (stretching the arm toward a singularity), or into the item's obstacle; the
    joints toward points past their limits for joint limits."""
    end = END_FRAME[case.robot]
    reach = wbc.PositionTask(end, gain=1.0)
    obstacles = getattr(item, "obstacles", ())
    reach.set_target(obstacles[0].center if obstacles else robot.frame_pose(q, end)[:3, 3] + [2.0, -1.5, 1.0])
    if isinstance(item, wbc.JointPositionLimits):
        return [reach, wbc.PostureTask(1.0, target=np.clip(q + 3.0, -10.0, 10.0), gain=1.0)]
    if isinstance(item, wbc.SupportPolygon):  # the platform held: the arm's reach moves the CoM over it
        still = wbc.BaseVelocityTask(100.0)
        still.set_target([0.0, 0.0, 0.0])
        return [reach, still]
    return [reach]


@pytest.mark.parametrize("case", [case for case in CASES if isinstance(case.make(robot_of(case),
                                  CONFIGURATIONS[case.robot][1]), Constraint)], ids=case_id)
def test_constraint_rows_hold_in_closed_loop(case: Case):
    """Tasks push the robot into the item's rows for 300 ticks: every command satisfies the rows
    (bounds, ``G v <= h``, ``A v = b``) written out at that tick's q -- a soft item's on the ticks
    the full QP answered -- and they bind at some tick."""
    robot = robot_of(case)
    q = CONFIGURATIONS[case.robot][0]
    item = case.make(robot, CONFIGURATIONS[case.robot][1])
    limits = [] if isinstance(item, wbc.JointVelocityLimits) else [wbc.JointVelocityLimits()]
    if case.robot == "deluca_mm" and not isinstance(item, wbc.NonholonomicBase):
        limits.append(wbc.NonholonomicBase())  # its synchro base needs the no-slip row
    controller = wbc.Controller(robot, _pushing_tasks(case, robot, item, q), [item, *limits], dt=DT)
    reference = item.bind(robot)  # another data of the item: its rows written out in Python
    if hasattr(reference, "use_context"):  # it reads the previous command (wbc.model.tick_context)
        reference.use_context(controller.context)
    binding = 0
    for _ in range(300):
        rows = constraint_rows(reference, robot, q)  # before the step, whose context holds the previous command
        v = controller.step(q)
        if not (reference.hard or controller.last.success):
            # a fallback's command keeps the hard limits; soft rows may yield (wbc.Controller)
            q = robot.integrate(q, v, DT)
            continue
        tolerance = 1e-7 * (1 + np.abs(v).max())
        assert np.all(rows.lower - tolerance <= v) and np.all(v <= rows.upper + tolerance)
        assert np.all(rows.G @ v <= rows.h + tolerance)
        np.testing.assert_allclose(rows.A @ v, rows.b, rtol=0, atol=tolerance)
        slack = np.r_[v - rows.lower, rows.upper - v, rows.h - rows.G @ v]
        binding += bool(rows.A.shape[0] or np.any(slack < 1e-6))
        q = robot.integrate(q, v, DT)
    assert binding > 0
