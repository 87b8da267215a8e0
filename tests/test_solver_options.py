"""solver_options are checked when the backend is built: unknown keys, bad values, budgets."""

import numpy as np
import pytest

import wbc
from wbc.core.errors import InvalidInputError, WbcError
from wbc.qp.problem import QP
from wbc.solvers import make_solver
from wbc.solvers.options import BUDGET_KEYS, InvalidSolverOptionError, valid_options

SOLVERS = wbc.available_solvers()
KNOWN = [name for name in SOLVERS if name in BUDGET_KEYS]


def small_qp() -> QP:
    qp = QP(3, 1, 0)
    qp.H[:] = np.eye(3)
    qp.c[:] = [1.0, -2.0, 0.5]
    qp.lb[:], qp.ub[:] = -1.0, 1.0
    qp.G[:], qp.h[:] = [[1.0, 1.0, 1.0]], 0.2
    return qp


def test_a_misspelt_key_is_named_with_a_suggestion():
    with pytest.raises(InvalidSolverOptionError) as raised:
        make_solver("daqp", {"time_limt": 2e-3})
    message = str(raised.value)
    assert "'time_limt'" in message and "daqp" in message and "did you mean 'time_limit'" in message
    assert "iter_limit" in message  # the valid keys are listed
    assert isinstance(raised.value, InvalidInputError) and isinstance(raised.value, WbcError)
    assert isinstance(raised.value, ValueError)


@pytest.mark.parametrize("name", KNOWN)
def test_every_backend_rejects_an_unknown_key(name):
    with pytest.raises(InvalidSolverOptionError, match=f"'no_such_option' for solver {name}"):
        make_solver(name, {"no_such_option": 1.0})


def test_the_controller_rejects_a_misspelt_key(youbot):
    with pytest.raises(wbc.InvalidInputError, match="time_limt"):
        wbc.Controller(youbot, [wbc.PostureTask(1.0)], solver_options={"time_limt": 2e-3})


@pytest.mark.parametrize("options", [{"time_limit": -1}, {"time_limit": 0.0}, {"time_limit": float("inf")},
                                     {"iter_limit": 0}, {"max_iter": float("nan")}, {"primal_tol": -1e-9},
                                     {"warm_start": 1}, {"time_limit": "2ms"}])
def test_bad_values_are_rejected(options):
    with pytest.raises(InvalidSolverOptionError, match=next(iter(options))):
        make_solver("daqp", options)


@pytest.mark.parametrize("name, options", [("osqp", {"eps_abs": -1.0}), ("osqp", {"polishing": 1}),
                                           ("highs", {"qp_iteration_limit": -5})])
def test_bad_values_of_other_backends_are_rejected(name, options):
    if name not in SOLVERS:
        pytest.skip(f"{name} not installed")
    with pytest.raises(InvalidSolverOptionError):
        make_solver(name, options)


@pytest.mark.parametrize("name", KNOWN)
def test_the_backends_own_settings_are_accepted_and_solve(name):
    """Every key wbc lists is derived from the backend: its default value is accepted and solves."""
    valid = valid_options(name)
    assert "warm_start" in valid
    default_budget = {key: 1000 if key == "max_iter" else 1.0 for key in BUDGET_KEYS[name]}
    solution = make_solver(name, default_budget).solve(small_qp())
    assert solution.success, solution.status


@pytest.mark.parametrize("name", KNOWN)
def test_generic_budgets_reach_the_backends_own_setting(name):
    budgets = BUDGET_KEYS[name]
    for generic in ("time_limit", "max_iter"):
        value = 0.5 if generic == "time_limit" else 77
        if generic in budgets:
            assert make_solver(name, {generic: value}).settings[budgets[generic]] == value
        else:
            with pytest.raises(InvalidSolverOptionError, match=f"{name} cannot honour a {generic} budget"):
                make_solver(name, {generic: value})


@pytest.mark.parametrize("name", [name for name in KNOWN if "max_iter" in BUDGET_KEYS[name]])
def test_an_iteration_budget_is_a_whole_number(name):
    """A fractional iteration budget is refused when the backend is built (it was a raw TypeError
    from DAQP's constructor, or a TypeError in every tick of the others); a whole float is that int."""
    with pytest.raises(InvalidSolverOptionError, match="counts iterations: it must be a whole number, got 1.5"):
        make_solver(name, {"max_iter": 1.5})
    setting = make_solver(name, {"max_iter": 1000.0}).settings[BUDGET_KEYS[name]["max_iter"]]
    assert setting == 1000 and isinstance(setting, int)
    assert make_solver(name, {"max_iter": 1000.0}).solve(small_qp()).success


def test_a_generic_and_an_own_budget_must_agree():
    with pytest.raises(InvalidSolverOptionError, match="two different budgets"):
        make_solver("daqp", {"max_iter": 5, "iter_limit": 6})


def test_a_daqp_iteration_budget_given_by_its_generic_name_is_honoured():
    solution = make_solver("daqp", {"max_iter": 1, "warm_start": False}).solve(small_qp())
    assert not solution.success and solution.status == "iteration limit"


@pytest.mark.parametrize("name, options, expected", [
    ("daqp", {}, {}),
    ("daqp", {"time_limit": 2e-3, "iter_limit": 50}, {"time_limit": 2e-3, "iter_limit": 50}),
    ("daqp", {"max_iter": 50}, {"iter_limit": 50}),
    ("osqp", {"time_limit": 2e-3, "max_iter": 500}, {"time_limit": 2e-3}),
    ("clarabel", {"time_limit": 3e-3}, {"time_limit": 3e-3}),
    ("highs", {"time_limit": 4e-3, "qp_iteration_limit": 100}, {"time_limit": 4e-3}),
    ("proxqp", {"max_iter": 100}, {}),
    ("quadprog", {}, {}),
])
def test_fallback_budget_carries_the_main_backends_time_budget(name, options, expected):
    if name not in SOLVERS:
        pytest.skip(f"{name} not installed")
    assert make_solver(name, options).fallback_budget == expected


def test_fallback_budget_includes_a_default_time_cap():
    """OSQP's default safety cap (DEFAULT_SETTINGS) is a time budget the fallback gets too."""
    assert make_solver("osqp").fallback_budget == {"time_limit": 0.1}


def test_daqp_primal_tolerance_is_tight_alone_and_daqps_own_in_hierarchy_levels(youbot):
    """One QP: primal_tol 1e-9 (DAQP's 1e-6 stopped 1e-7 short of the optimum in the fuzz
    suite); the levels of a strict hierarchy: DAQP's 1e-6 (their band rows need the slack);
    a primal_tol the user gives holds for both."""
    from wbc.solvers import DaqpBackend

    backend = make_solver("daqp")
    assert backend.settings["primal_tol"] == 1e-9 and backend.for_levels().settings["primal_tol"] == 1e-6
    chosen = make_solver("daqp", {"primal_tol": 1e-8, "iter_limit": 500})
    levels = chosen.for_levels()
    assert isinstance(levels, DaqpBackend)
    assert levels.settings == chosen.settings == {"primal_tol": 1e-8, "iter_limit": 500}

    pose, posture = wbc.FrameTask("ee"), wbc.PostureTask(1.0)
    pose.set_target(youbot.frame_pose(youbot.neutral(), "ee"))
    single = wbc.Controller(youbot, [pose, posture], [wbc.JointVelocityLimits()])
    strict = wbc.Controller(youbot, [[pose], [posture]], [wbc.JointVelocityLimits()])
    single.step(youbot.neutral())
    strict.step(youbot.neutral())
    if single.solver.native:  # what DAQP itself reads: the settings structure of each workspace
        assert single.solver.bound.settings.primal_tol == 1e-9
        assert [w.settings.primal_tol for w in strict._hierarchy._workspaces] == [1e-6, 1e-6]
    assert strict._hierarchy.solver.settings["primal_tol"] == 1e-6 and strict.last.success
