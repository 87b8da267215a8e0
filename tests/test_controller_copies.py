"""Copies and pickles of controllers (issue 23 §8): ``copy.copy``, ``copy.deepcopy`` and
``pickle`` give a new controller built from the specification -- its own buffers, program and
solver -- that steps like the original: the same commands on the same configurations (DAQP's
working set is not carried, so there they agree to rounding; a qpsolvers backend's warm start
is, so there they are identical). ``copy.copy`` shares the robot, tasks and constraints; the
deep copy and the pickle copy them. Shipped to worker processes (multiprocessing with spawn, a
Dask worker) the commands are the same."""

from __future__ import annotations

import copy
import multiprocessing
import pickle
from collections.abc import Callable

import numpy as np
import pinocchio as pin
import pytest

import wbc
from benchmarks.scaling import chain_urdf
from conftest import require
from wbc.control.diagnostics import NoTickYetError

YOUBOT = wbc.load_robot("youbot")
DELUCA = wbc.load_robot("deluca_mm")
#: two controllers whose DAQP solves start from different working sets (a fresh one and a
#: warmed-up one; the copy of a reduced-form controller, whose solve runs outside the program and
#: whose working set is not carried) agree to rounding on the same strictly convex QP
ROUNDING = 1e-12


def _reach(robot: wbc.Robot, offset=(0.2, 0.1, -0.1), frame: str | None = None) -> wbc.FrameTask:
    frame = frame or robot.end_effector
    ee = wbc.FrameTask(frame, position_cost=1.0, orientation_cost=0.1, gain=0.5)
    pose = robot.frame_pose(robot.neutral(), frame).copy()
    pose[:3, 3] += offset
    ee.set_target(pose)
    return ee


def _flat(solver: str = "daqp", **options) -> wbc.Controller:
    return wbc.Controller(YOUBOT, [_reach(YOUBOT), wbc.PostureTask(cost=1e-3)],
                          [wbc.JointVelocityLimits(), wbc.JointPositionLimits()], solver=solver, **options)


def _levels(solver: str = "daqp") -> wbc.Controller:
    return wbc.Controller(YOUBOT, [[_reach(YOUBOT)], [wbc.PostureTask(cost=1.0)]],
                          [wbc.JointVelocityLimits(), wbc.JointPositionLimits()], solver=solver)


def _differential(reduced: bool) -> wbc.Controller:
    constraints = [wbc.JointVelocityLimits(), wbc.NonholonomicBase()]
    tasks = [_reach(DELUCA), wbc.PostureTask(cost=1e-3), wbc.SteeringTask(cost=1e-2, gain=1.0, speed_scale=0.5)]
    return wbc.Controller(DELUCA, tasks, constraints, reduced=reduced)


def _collision() -> wbc.Controller:
    ee = YOUBOT.frame_pose(YOUBOT.neutral(), "ee")[:3, 3]
    avoidance = wbc.CollisionAvoidance([wbc.Sphere(ee + (0.12, 0.0, 0.0), 0.05)], detection_distance=0.3)
    return wbc.Controller(YOUBOT, [_reach(YOUBOT, (0.15, 0.0, 0.0)), wbc.PostureTask(cost=1e-3)],
                          [wbc.JointVelocityLimits(), avoidance])


#: one controller of each mode: flat and levels, reduced and plain (with the steering preview),
#: solved in the program (DAQP) and out of it, with collision rows
MODES: dict[str, Callable[[], wbc.Controller]] = {
    "flat daqp": _flat,
    "flat quadprog": lambda: _flat("quadprog"),
    "flat osqp (warm start carried)": lambda: _flat("osqp"),
    "levels daqp": _levels,
    "levels quadprog": lambda: _levels("quadprog"),
    "differential plain, steering": lambda: _differential(False),
    "differential reduced, steering": lambda: _differential(True),
    "collision avoidance": _collision,
}

COPIES: dict[str, Callable[[wbc.Controller], wbc.Controller]] = {
    "copy": copy.copy,
    "deepcopy": copy.deepcopy,
    "pickle": lambda controller: pickle.loads(pickle.dumps(controller)),
}


def _warmed_up(controller: wbc.Controller, ticks: int = 5) -> np.ndarray:
    """``ticks`` closed-loop ticks of ``controller`` from the neutral pose; the last q."""
    q = controller.robot.neutral()
    for _ in range(ticks):
        q = controller.robot.integrate(q, controller.step(q), controller.dt)
    return q


def _sequence(robot: wbc.Robot, q: np.ndarray, count: int = 12, seed: int = 3) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    return [q + 0.05 * rng.standard_normal(robot.nq) for _ in range(count)]


def _steps(controller: wbc.Controller, configurations: list[np.ndarray]) -> tuple[np.ndarray, list[str]]:
    """The commands and statuses of ``controller`` over ``configurations`` (also run in workers)."""
    commands, statuses = [], []
    for q in configurations:
        commands.append(controller.step(q).copy())
        statuses.append(controller.last.status)
    return np.array(commands), statuses


def _tolerance(controller: wbc.Controller) -> float:
    """How close a copy's commands are to the original's: identical where the warm start is
    carried (DAQP in the program, qpsolvers' initial guess) or there is none."""
    return ROUNDING if controller.solver.name == "daqp" and controller.reduced else 0.0


@pytest.mark.parametrize("make", MODES.values(), ids=MODES.keys())
@pytest.mark.parametrize("duplicate", COPIES.values(), ids=COPIES.keys())
def test_a_copy_steps_like_the_original(make, duplicate):
    original = make()
    q = _warmed_up(original)
    twin = duplicate(original)
    assert type(twin) is wbc.Controller and twin is not original
    configurations = _sequence(original.robot, q)
    # interleaved: each steps its own buffers (a shared buffer would leave one of them stale)
    expected, expected_statuses, got, got_statuses = [], [], [], []
    for q in configurations:
        expected.append(original.step(q).copy())
        errors = dict(original.last.task_errors)
        got.append(twin.step(q).copy())
        assert original.last.task_errors == errors  # the original's record still reads its own tick
        expected_statuses.append(original.last.status)
        got_statuses.append(twin.last.status)
    assert got_statuses == expected_statuses
    np.testing.assert_allclose(np.array(got), np.array(expected), rtol=0.0, atol=_tolerance(original))


@pytest.mark.parametrize("duplicate", COPIES.values(), ids=COPIES.keys())
def test_a_copy_has_its_own_buffers_program_and_solver(duplicate):
    original = _flat()
    twin = duplicate(original)
    assert twin.kinematics is not original.kinematics
    assert twin.qp is not original.qp and twin.qp.data.ctypes.data != original.qp.data.ctypes.data
    assert twin.solver is not original.solver
    assert twin._program is not original._program


def test_a_shallow_copy_has_settings_of_its_own():
    """The silent wrong result of the default ``copy.copy``: the copy's settings lived in the
    original's arrays, so ``twin.damping = ...`` changed the original's QP."""
    original, reference = _flat(), _flat()
    q = _warmed_up(reference)
    twin = copy.copy(original)
    twin.damping, twin.lm_damping, twin.dt = 10.0, 0.0, 0.05
    assert (original.damping, original.lm_damping, original.dt) == (reference.damping, reference.lm_damping,
                                                                    reference.dt)
    for q_k in _sequence(YOUBOT, q):
        np.testing.assert_allclose(original.step(q_k), reference.step(q_k), rtol=0.0, atol=ROUNDING)
    assert not np.allclose(twin.step(q), reference.step(q), atol=1e-6)  # the copy's own damping acts


def test_a_shallow_copy_shares_the_items_and_a_deep_copy_does_not():
    original = _flat()
    shallow, deep = copy.copy(original), copy.deepcopy(original)
    assert shallow.robot is original.robot
    assert all(a is b for a, b in zip(shallow.tasks + shallow.constraints, original.tasks + original.constraints,
                                      strict=True))
    assert deep.robot is not original.robot
    assert not any(a is b for a, b in zip(deep.tasks + deep.constraints, original.tasks + original.constraints,
                                          strict=True))
    q = _warmed_up(_flat())
    before = original.step(q).copy()
    shallow.tasks[0].set_target(YOUBOT.frame_pose(q, "ee"))  # the shared task's setting acts in both
    np.testing.assert_allclose(shallow.step(q), original.step(q), rtol=0.0, atol=ROUNDING)
    assert not np.allclose(original.step(q), before, atol=1e-6)
    deep.tasks[0].set_target(YOUBOT.frame_pose(YOUBOT.neutral(), "ee"))  # the deep copy's acts in it alone
    np.testing.assert_allclose(original.step(q), shallow.step(q), rtol=0.0, atol=ROUNDING)


def test_a_copy_keeps_the_specification_and_the_settings():
    original = _levels("quadprog")
    original.damping, original.lm_damping, original.dt = 2e-3, 0.5, 0.02
    for duplicate in COPIES.values():
        twin = duplicate(original)
        assert (twin.damping, twin.lm_damping, twin.dt, twin.strict, twin.reduced) == (2e-3, 0.5, 0.02, False, False)
        assert [[type(task) for task in level] for level in twin.levels] == [[wbc.FrameTask], [wbc.PostureTask]]
        assert twin.solver.name == "quadprog"
        assert duplicate(_flat(strict=True)).strict
    reduced = _differential(True)
    assert COPIES["pickle"](reduced).reduced and not COPIES["pickle"](reduced).constraints[1:]


def test_a_copy_continues_the_tick_counter_and_has_no_record_yet():
    original = _flat()
    q = _warmed_up(original, ticks=3)
    twin = copy.deepcopy(original)
    with pytest.raises(NoTickYetError):
        _ = twin.last
    twin.step(q)
    assert twin.last.tick == 4


def test_pickling_a_controller_whose_solver_was_replaced():
    original = _flat()
    original.solver = wbc.solvers.make_solver("daqp", {"iter_limit": 500, "warm_start": False})
    twin = pickle.loads(pickle.dumps(original))
    assert twin.solver.options == {"iter_limit": 500, "warm_start": False}
    q = _warmed_up(original)
    np.testing.assert_allclose(twin.step(q), original.step(q), rtol=0.0, atol=ROUNDING)


@pytest.mark.slow
def test_a_lifted_controller_copies(tmp_path):
    path = tmp_path / "chain32.urdf"
    path.write_text(chain_urdf(32))
    robot = wbc.load_robot(path)
    original = wbc.Controller(robot, [_reach(robot, frame="ee"), wbc.PostureTask(cost=1e-3)],
                              [wbc.JointVelocityLimits()])
    assert original._lifted is not None  # the mode under test
    q = _warmed_up(original)
    twin = pickle.loads(pickle.dumps(original))
    assert twin._lifted is not None
    expected, _ = _steps(original, _sequence(robot, q))
    got, _ = _steps(twin, _sequence(robot, q))
    np.testing.assert_allclose(got, expected, rtol=0.0, atol=0.0)


@pytest.mark.slow
@pytest.mark.parametrize("make", [_flat, _levels, lambda: _differential(True)], ids=["flat", "levels", "reduced"])
def test_a_controller_shipped_to_a_spawned_process_steps_like_the_original(make):
    original = make()
    q = _warmed_up(original)
    configurations = _sequence(original.robot, q)
    with multiprocessing.get_context("spawn").Pool(1) as pool:
        got, got_statuses = pool.apply(_steps, (original, configurations))
    expected, expected_statuses = _steps(original, configurations)
    assert got_statuses == expected_statuses
    np.testing.assert_allclose(got, expected, rtol=0.0, atol=_tolerance(original))


@pytest.mark.slow
def test_a_controller_shipped_to_a_dask_worker_steps_like_the_original():
    distributed = require("distributed")
    original = _flat()
    q = _warmed_up(original)
    configurations = _sequence(YOUBOT, q, count=4)
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster, distributed.Client(cluster) as client:
        # each a fresh unpickled copy of the warmed-up controller, one tick each
        got = client.gather([client.submit(original.step, q_k, pure=False) for q_k in configurations])
    expected = [copy.deepcopy(original).step(q_k) for q_k in configurations]
    np.testing.assert_allclose(np.array(got), np.array(expected), rtol=0.0, atol=0.0)


def test_a_robot_pickles_without_its_workspace_and_with_infinite_limits():
    """Pinocchio 3.3 cannot read back inf from its archives (`RuntimeError: input stream error` in
    the oldest-versions job, pickling the De Luca controllers): the pickled robot carries no
    per-use Data (rebuilt) and a model with finite limit vectors only, the inf entries beside it."""
    model = pin.Model(DELUCA.model)
    velocity = np.array(model.velocityLimit)
    velocity[3] = np.inf  # an unbounded joint (a URDF continuous joint without <limit>)
    model.velocityLimit = velocity
    robot = wbc.Robot("unbounded", model, base=DELUCA.base)
    state = robot.__getstate__()
    assert "_data" not in state
    for name in ("lowerPositionLimit", "upperPositionLimit", "velocityLimit", "effortLimit"):
        assert np.all(np.isfinite(getattr(state["model"], name))), name
    twin = pickle.loads(pickle.dumps(robot))
    assert twin.model.velocityLimit[3] == np.inf and twin.velocity_limit[3] == np.inf
    for name in ("lowerPositionLimit", "upperPositionLimit", "velocityLimit", "effortLimit"):
        np.testing.assert_array_equal(getattr(twin.model, name), getattr(model, name))
    q, frame = robot.neutral() + 0.1, robot.frame_names[-1]
    np.testing.assert_array_equal(twin.frame_pose(q, frame), robot.frame_pose(q, frame))
