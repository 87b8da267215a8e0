"""The shortcuts of the control tick compute what the plain formulas compute."""

import re
import time

import daqp
import numpy as np
import pytest

import wbc
from conftest import TASKS, random_youbot_configurations
from wbc.app.scenario import load_scenario
from wbc.qp.problem import QP
from wbc.runtime import kernels
from wbc.solvers import DaqpBackend


def random_qp(rng, qp: QP) -> None:
    """Fill ``qp`` in place with a feasible strictly convex QP (rows, equalities, bounds)."""
    n = qp.n
    M = rng.standard_normal((n, n))
    qp.H[:] = M @ M.T + 0.1 * np.eye(n)
    qp.c[:] = rng.standard_normal(n)
    qp.C[:] = rng.standard_normal(qp.C.shape)
    x0 = rng.uniform(-0.5, 0.5, n)  # strictly feasible point
    qp.ub[:], qp.lb[:] = x0 + rng.uniform(0.1, 1.0, n), x0 - rng.uniform(0.1, 1.0, n)
    qp.h[:] = qp.G @ x0 + rng.uniform(0.0, 0.5, qp.n_ineq)
    qp.b[:] = qp.A @ x0
    qp.sync_equalities()


def cold_daqp(qp: QP) -> np.ndarray:
    sense = np.zeros(qp.n + qp.n_ineq + qp.n_eq, dtype=np.int32)
    sense[qp.n + qp.n_ineq:] = 5
    x, _, exitflag, _ = daqp.solve(qp.H.copy(), qp.c.copy(), qp.C.copy(), qp.upper.copy(), qp.lower.copy(), sense)
    assert exitflag == 1
    return x


@pytest.mark.parametrize("warm_start", [True, False])
@pytest.mark.parametrize("shape", [(6, 0, 0), (6, 5, 0), (6, 4, 2)])
def test_daqp_workspace_sees_every_in_place_change_of_the_qp(rng, shape, warm_start):
    """The backend only calls update(H): c, rows and bounds must be read through its pointers."""
    backend = DaqpBackend({"warm_start": warm_start})
    qp = QP(*shape)
    for _ in range(30):
        random_qp(rng, qp)
        solution = backend.solve(qp)
        assert solution.success
        np.testing.assert_allclose(solution.x, cold_daqp(qp), rtol=0, atol=1e-9)


def test_daqp_workspace_follows_the_qp_object_it_is_given(rng):
    """Two QPs of one shape through one backend: the workspace must not keep reading the first."""
    backend = DaqpBackend()
    first, second = QP(5, 3, 1), QP(5, 3, 1)
    random_qp(rng, first)
    random_qp(rng, second)
    for qp in (first, second, first, second):
        np.testing.assert_allclose(backend.solve(qp).x, cold_daqp(qp), rtol=0, atol=1e-9)


@pytest.mark.parametrize("segment", ["H", "c", "C", "upper", "lower"])
def test_nan_screen_finds_a_nan_anywhere_and_nothing_else(segment):
    qp = QP(4, 2, 1)
    qp.H[:] = np.eye(4)
    qp.C[:] = 1e200  # huge but finite
    assert np.isinf(qp.upper).any() and not qp.has_nan()
    getattr(qp, segment).reshape(-1)[-1] = np.nan
    assert qp.has_nan()


def test_one_constraint_instance_can_serve_two_controllers(youbot, rng):
    """Constraint objects cache views into the controller's buffers: sharing them between two
    controllers stepped alternately must give each the command it gets alone."""
    scenario = load_scenario(TASKS / "youbot_reach.toml")
    barrier = wbc.ManipulabilityBarrier("ee", min_value=0.05, gain=0.3)
    shared = scenario.constraints + [barrier]
    task = wbc.FrameTask("ee", 1.0, 0.5)
    task.set_target(youbot.frame_pose(youbot.neutral(), "ee"))

    def controller(constraints):
        return wbc.Controller(youbot, [task, wbc.PostureTask(1e-2)], constraints, dt=scenario.dt)

    first, second = controller(shared), controller(shared)
    configurations = random_youbot_configurations(rng, 20)
    # arm joints just outside a limit: the position dampers decide the command
    side = rng.integers(0, 2, size=(20, 5)).astype(bool)
    configurations[:, 3:] = np.where(side, youbot.upper[3:] + 0.05, youbot.lower[3:] - 0.05)
    for q1, q2 in configurations.reshape(10, 2, 8):
        v1, v2 = first.step(q1), second.step(q2)
        alone = load_scenario(TASKS / "youbot_reach.toml").constraints
        # cold vs warm-started DAQP: equal up to rounding; a stale view would be off by O(1)
        for v, q in ((v1, q1), (v2, q2)):
            fresh = controller(alone + [wbc.ManipulabilityBarrier("ee", 0.05, 0.3)]).step(q)
            np.testing.assert_allclose(v, fresh, rtol=0, atol=1e-9)


def test_heading_rows_are_the_base_frame_limits(youbot, rng):
    """Base speed rows bound the base-frame twist and wheel rows give the wheel speeds, at any heading."""
    speed, wheels = wbc.JointVelocityLimits(), wbc.MecanumWheelLimits()
    controller = wbc.Controller(youbot, [wbc.PostureTask(1.0)], [speed, wheels])
    blocks = {type(c.constraint): rows for c, rows in controller._constraint_blocks}
    for q in random_youbot_configurations(rng, 10):
        controller.step(q)
        v = rng.standard_normal(8)
        vx, vy, _ = youbot.base_twist(q, v)
        np.testing.assert_allclose(blocks[wbc.JointVelocityLimits].G @ v, [vx, -vx, vy, -vy], atol=1e-12)
        rates = youbot.wheel_speeds(q, v)
        np.testing.assert_allclose(blocks[wbc.MecanumWheelLimits].G @ v, np.concatenate([rates, -rates]),
                                   atol=1e-12)


def _loop_controller(youbot, barrier: bool = False, levels: bool = False,
                     **options) -> tuple[wbc.Controller, wbc.FrameTask]:
    """A youBot controller whose whole tick is compiled (the control loop's native path); with
    ``barrier`` a manipulability barrier too (a soft row: compiled on the youBot); with
    ``levels`` the posture strictly below the gripper (two levels: the cascade in the program)."""
    task = wbc.FrameTask("ee", 1.0, 0.5)
    task.set_target(youbot.frame_pose(youbot.neutral(), "ee"))
    limits = [wbc.JointVelocityLimits(), wbc.JointPositionLimits(), wbc.MecanumWheelLimits()]
    limits += [wbc.ManipulabilityBarrier("ee", 0.01, 0.5)] if barrier else []
    posture = wbc.PostureTask(1e-2)
    return wbc.Controller(youbot, [[task], [posture]] if levels else [task, posture], limits, **options), task


def _huge(youbot, index: int) -> np.ndarray:
    q = youbot.neutral()
    q[index] = 1e200  # finite: the program's kinematics overflow (base x: a NaN in the QP; arm: infeasible)
    return q


def _straight(youbot) -> np.ndarray:
    """The arm stretched straight (manipulability ~0): the barrier's row asks more than the
    speed limits allow -- DAQP answers infeasible, the elastic fallback answers."""
    q = youbot.neutral()
    q[3:] = 0.0
    return q


@pytest.mark.parametrize("levels", [False, True])
@pytest.mark.parametrize("barrier", [False, True])
@pytest.mark.parametrize("options", [{}, {"solver_options": {"iter_limit": 2}}, {"strict": False, "damping": 0.0}])
def test_the_native_tick_is_the_assembly_pipeline(youbot, options, barrier, levels):
    """step(q) -- after its first tick one native call from q to the checked answer -- gives
    what the assembly pipeline (taken with v_measured, which no item here reads) gives: the same
    commands, outcomes and statuses tick by tick, on a circle with the fallback's cases mixed in
    (a NaN in the QP from the kinematics, an infeasible QP, soft rows made elastic, an iteration
    limit), slow stretches where no limit is active (the unconstrained minimiser answers,
    wbc.runtime.kernels.native_qp) between fast ones where limits are (DAQP answers); with one
    QP and with two strict levels (the cascade in the program: its level errors read the same)."""
    native, native_task = _loop_controller(youbot, barrier, levels, **options)
    pipeline, pipeline_task = _loop_controller(youbot, barrier, levels, **options)
    assert native._stepper is not None  # (the barrier is compiled on the youBot: the native tick is taken)
    assert (native._hierarchy is not None) == levels
    zero = np.zeros(youbot.nv)
    q_native, q_pipeline = youbot.neutral(), youbot.neutral()
    centre = youbot.frame_pose(youbot.neutral(), "ee")
    outcomes, statuses, by_minimiser, by_daqp = set(), set(), 0, 0
    for k in range(120):
        radius, rate = (0.02, 0.05) if k // 20 % 2 == 0 else (0.15, 0.2)  # slow, then fast, ...
        target = centre.copy()
        target[:3, 3] += radius * np.array([np.sin(rate * k), np.cos(rate * k) - 1.0, 0.0])
        native_task.set_target(target)
        pipeline_task.set_target(target)
        odd = {40: _huge(youbot, 0), 41: _huge(youbot, 3), 60: _straight(youbot), 61: _straight(youbot)}.get(k)
        v = native.step(q_native if odd is None else odd)
        w = pipeline.step(q_pipeline if odd is None else odd, v_measured=zero)
        np.testing.assert_array_equal(v, w)
        a, b = native.last, pipeline.last
        assert (a.tick, a.outcome, a.status, a.solver) == (b.tick, b.outcome, b.status, b.solver)
        np.testing.assert_array_equal(native.qp.data, pipeline.qp.data)
        if levels and odd is None:
            assert a.level_errors == b.level_errors
            np.testing.assert_array_equal(a.level_optima, b.level_optima)  # (NaN: a level not solved)
            if a.outcome is wbc.Outcome.OPTIMAL:  # the cascade's solve time: its levels' (as ``last`` is read)
                times = [w.outcome()[2] for w in native._daqp_workspaces()]
                assert a.solve_time == sum(times[:-1], times[-1]) and min(times) > 0.0
        outcomes.add(a.outcome)
        statuses.add(a.status)
        if a.outcome is wbc.Outcome.OPTIMAL:
            first = native._daqp_workspaces()[0]  # (level 0's with priorities: the one that may skip DAQP)
            iterations = first.iterations
            assert iterations == pipeline._daqp_workspaces()[0].iterations
            by_minimiser, by_daqp = by_minimiser + (iterations == 0), by_daqp + (iterations > 0)
        if odd is None:
            q_native, q_pipeline = youbot.integrate(q_native, v, 0.01), youbot.integrate(q_pipeline, w, 0.01)
    assert wbc.Outcome.ZERO in outcomes  # the odd ticks went through the fallback chain
    if barrier:  # the stretched arm: the barrier's row conflicts with the speed limits
        assert wbc.Outcome.ELASTIC in outcomes
    else:
        assert by_minimiser > 0
    if "solver_options" in options:
        assert any("iteration limit" in status for status in statuses)
    else:
        assert by_daqp > 0


def test_the_control_loop_does_not_go_through_the_assembly(youbot, monkeypatch):
    """The native tick is taken from the first tick on (the tasks checked first, in Python): a
    tick without v_measured neither calls Kinematics.update (the program copies q) nor the
    assembly; a task not ready raises at the first tick as the assembly would."""
    from wbc.model.kinematics import Kinematics

    task = wbc.FrameTask("ee", 1.0, 0.5)  # no target yet
    limits = [wbc.JointVelocityLimits(), wbc.JointPositionLimits(), wbc.MecanumWheelLimits()]
    controller = wbc.Controller(youbot, [task, wbc.PostureTask(1e-2)], limits)
    calls = []
    update = Kinematics.update
    monkeypatch.setattr(Kinematics, "update", lambda self, *args: calls.append(1) or update(self, *args))
    q = youbot.neutral()
    with pytest.raises(wbc.InvalidInputError, match="no target set"):
        controller.step(q)
    assert calls == [] and getattr(controller, "last", None) is None  # nothing ran
    task.set_target(youbot.frame_pose(q, "ee"))
    for _ in range(3):
        controller.step(q)
    assert calls == [] and controller.last.tick == 3 and controller.last.status == "optimal"
    controller.step(q, v_measured=np.zeros(youbot.nv))
    assert len(calls) == 1 and controller.context.measured is not None
    controller.step(q)  # the assembly again, once: it clears the measured velocity
    assert len(calls) == 2 and controller.context.measured is None
    controller.step(q)
    assert len(calls) == 2


def test_the_native_tick_records_every_diagnostic(youbot):
    """On the control loop's path step records v only, the program times its run and DAQP's
    accept op keeps the accepted solve time; ``last`` reads every field as the pipeline's full
    record does: tick, solver, outcome, status, v and u (the returned array itself), the solve
    time DAQP's op wrote, a tick time between it and the time around the call, the lazy
    fields. A step that raises keeps the latest tick's diagnostics, its tick time too (also
    when the program ran: a NaN q); a new solver (a rebuilt program) neither renames the
    latest tick's nor loses its tick time."""
    native, native_task = _loop_controller(youbot)
    pipeline, pipeline_task = _loop_controller(youbot)
    zero, q = np.zeros(youbot.nv), youbot.neutral()
    centre = youbot.frame_pose(q, "ee")
    for k in range(6):
        target = centre.copy()
        target[:3, 3] += 0.02 * np.array([np.sin(0.1 * k), np.cos(0.1 * k) - 1.0, 0.0])
        native_task.set_target(target)
        pipeline_task.set_target(target)
        start = time.perf_counter()
        v = native.step(q)
        elapsed = time.perf_counter() - start
        solve_time = float(native.solver.bound.control[kernels.DAQP_CONTROL_TIME])
        w = pipeline.step(q, v_measured=zero)
        assert native._record is v if k else len(native._record) == 8  # the first tick is the assembly's
        a, b = native.last, pipeline.last
        assert a is native.last  # built once per tick
        expected = (k + 1, "daqp", wbc.Outcome.OPTIMAL, "optimal", True)
        assert (a.tick, a.solver, a.outcome, a.status, a.success) == expected
        assert (b.tick, b.solver, b.outcome, b.status, b.success) == (a.tick, a.solver, a.outcome, a.status, a.success)
        assert a.v is v and a.u is v and native.context.previous is v
        np.testing.assert_array_equal(a.v, w)
        assert a.solve_time == solve_time and 0.0 < a.solve_time <= a.tick_time <= elapsed
        assert a.task_errors == b.task_errors and a.active_constraints == b.active_constraints
        assert a.max_violation == b.max_violation
        q = youbot.integrate(q, v, 0.01)
    tick_time = a.tick_time
    with pytest.raises(wbc.InvalidInputError):
        native.step(q[:-1])
    assert native.last is a and native.last.tick == 6
    with pytest.raises(wbc.InvalidInputError):
        native.step(np.full_like(q, np.nan))  # the program runs (its NaN screen), not accepted
    assert native._program.run_time() > 0.0 and native._record is a.v
    assert (native.last.tick, native.last.tick_time, native.last.v) == (6, tick_time, a.v)
    v = native.step(q)  # (last not read before the solver changes)
    tick_time = native._program.accepted_run_time()
    native.solver = wbc.solvers.make_solver("quadprog")
    # (the NaN step counted a tick: it overwrote the buffers the lazy fields read)
    assert (native.last.tick, native.last.solver, native.last.tick_time) == (8, "daqp", tick_time)
    assert native.last.v is v and tick_time > 0.0
    native.step(q)
    assert (native.last.tick, native.last.solver) == (9, "quadprog")


def test_a_strict_step_that_raises_leaves_the_native_record_of_the_latest_tick(youbot):
    """The native tick records v only: its solve and tick times are read when ``last`` is. A
    strict controller's next native run solves, is not accepted (an infeasible QP) and raises:
    DAQP's control vector and the program's latest run time then hold that run's -- ``last``
    still reads the latest accepted tick's (DAQP_ACCEPT's copy, the program's accepted run)."""
    controller, _ = _loop_controller(youbot, strict=True)
    control, q = controller.solver.bound.control, youbot.neutral()
    for _ in range(3):
        v = controller.step(q)  # (last not read: built lazily below)
    solve_time, tick_time = float(control[kernels.DAQP_CONTROL_TIME]), controller._program.run_time()
    control[kernels.DAQP_CONTROL_TIME] = -1.0  # a mark: the failing run's solve overwrites it
    with pytest.raises(wbc.SolverError):
        controller.step(_huge(youbot, 3))
    assert control[kernels.DAQP_CONTROL_TIME] >= 0.0 and controller._program.run_time() > 0.0
    last = controller.last
    assert last.v is v and (last.solve_time, last.tick_time) == (solve_time, tick_time)
    assert last.tick == 4  # (the raising step counted its tick before the fallback chain raised, as ever)
    assert 0.0 < solve_time <= tick_time


def test_a_task_without_target_is_refused_before_the_native_tick(youbot):
    controller = wbc.Controller(youbot, [wbc.FrameTask("ee"), wbc.PostureTask(1e-2)], [wbc.JointVelocityLimits()])
    for _ in range(2):  # refused again: a refused first tick does not open the native path
        with pytest.raises(wbc.InvalidInputError, match="target"):
            controller.step(youbot.neutral())


def _bad_configurations(youbot) -> dict[str, object]:
    q = youbot.neutral()
    nan, inf = q.copy(), q.copy()
    nan[2], inf[5] = np.nan, -np.inf
    return {"nan": nan, "inf": inf, "short": q[:-1], "long": np.r_[q, 0.0], "matrix": q[None, :],
            "text": ["a"] * youbot.nq, "none": None}


def _unusual_configurations(youbot, rng) -> dict[str, object]:
    q = youbot.neutral() + 0.1 * rng.standard_normal(youbot.nq)
    read_only, wide = q.copy(), np.zeros(2 * youbot.nq)
    read_only.flags.writeable = False
    wide[::2] = q
    return {"list": q.tolist(), "read-only": read_only, "strided": wide[::2], "big-endian": q.astype(">f8"),
            "float32": q.astype(np.float32), "int": np.round(q).astype(int)}


@pytest.mark.parametrize("case", ["nan", "inf", "short", "long", "matrix", "text", "none"])
def test_a_bad_q_on_the_native_tick_is_refused_as_by_the_assembly(youbot, case):
    """The same exception and message as a fresh controller's first tick (the assembly's),
    and the next good tick answers as before."""
    bad = _bad_configurations(youbot)[case]
    fresh, _ = _loop_controller(youbot)
    with pytest.raises(wbc.InvalidInputError) as expected:
        fresh.step(bad)
    warm, _ = _loop_controller(youbot)
    q = youbot.neutral()
    before = warm.step(q)
    warm.step(q)
    with pytest.raises(type(expected.value), match="^" + re.escape(str(expected.value)) + "$"):
        warm.step(bad)
    np.testing.assert_array_equal(warm.step(q), before)
    assert warm.last.outcome is wbc.Outcome.OPTIMAL


def test_unusual_but_valid_qs_on_the_native_tick(youbot, rng):
    """Lists, read-only, strided, big-endian, float32 and integer arrays: the command the
    assembly gives for the same q (converted by check_configuration)."""
    for case, q in _unusual_configurations(youbot, rng).items():
        warm, _ = _loop_controller(youbot)
        warm.step(youbot.neutral())
        warm.step(youbot.neutral())
        pipeline, _ = _loop_controller(youbot)
        np.testing.assert_array_equal(warm.step(q), pipeline.step(q, v_measured=np.zeros(youbot.nv)), err_msg=case)
