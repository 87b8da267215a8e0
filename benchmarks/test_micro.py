"""Micro-benchmarks of the hot path (pytest-benchmark); not part of the default test run.

    pytest benchmarks/test_micro.py --benchmark-only [--benchmark-columns=min,median,ops]
    pytest benchmarks/test_micro.py --benchmark-only -k step          # whole ticks only
    pytest benchmarks/test_micro.py --benchmark-only --benchmark-save=before   # then compare:
    pytest benchmarks/test_micro.py --benchmark-only --benchmark-compare       # after a change

``pyproject.toml`` sets ``testpaths = ["tests"]``, so a plain ``pytest`` never collects
this file. Each case cycles through configurations recorded along the scenario's own
closed loop, so the solver sees the changing active sets of a real run. Only public
pieces are timed (Controller.step, Kinematics.update, Task.compute, QPSolver.solve) so
the suite survives refactors of the controller's internals.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest

pytest.importorskip("pytest_benchmark")

import wbc  # noqa: E402
from benchmarks.common import TASKS, scenario_files  # noqa: E402
from wbc.app.scenario import load_scenario  # noqa: E402
from wbc.model.kinematics import Kinematics  # noqa: E402
from wbc.solvers import QpsolversBackend, make_solver  # noqa: E402

TRAJECTORY_TICKS = 300


class Recorded:
    """A scenario, its controller and the configurations / targets / QPs of its closed loop."""

    def __init__(self, path) -> None:
        self.scenario = sc = load_scenario(path)
        self.controller = sc.make_controller()
        self.states, self.qps = [], []
        q = sc.q0.copy()
        for k in range(min(TRAJECTORY_TICKS, sc.ticks)):
            target = tuple(np.array(x) if x is not None else None for x in sc.reference(k * sc.dt)) \
                if sc.reference is not None else None
            if target is not None:
                sc.reference_task.set_target(*target)
            v = self.controller.step(q)
            self.states.append((q.copy(), target))
            self.qps.append(self.controller.qp.copy())
            q = sc.robot.integrate(q, v, sc.dt)

    def stepper(self):
        """A zero-argument callable doing one tick on the next recorded state."""
        states = itertools.cycle(self.states)
        controller, task = self.controller, self.scenario.reference_task

        def tick():
            q, target = next(states)
            if target is not None:
                task.set_target(*target)
            return controller.step(q)

        return tick


_CACHE: dict[str, Recorded] = {}


def recorded(name: str) -> Recorded:
    if name not in _CACHE:
        _CACHE[name] = Recorded(TASKS / f"{name}.toml")
    return _CACHE[name]


SCENARIOS = [path.stem for path in scenario_files()]


# ------------------------------------------------------------------ whole ticks
@pytest.mark.parametrize("name", SCENARIOS)
def test_step(benchmark, name):
    """Controller.step of every scenario in tasks/ (kinematics + assembly + DAQP + diagnostics)."""
    benchmark.group = "step"
    tick = recorded(name).stepper()
    benchmark(tick)


# ---------------------------------------------------------------------- pieces
@pytest.fixture(scope="module")
def circle() -> Recorded:
    return recorded("youbot_circle")


def test_kinematics_update(benchmark, circle):
    """computeJointJacobians (+ forward kinematics) of one configuration."""
    benchmark.group = "pieces"
    kin = Kinematics(circle.scenario.robot)
    qs = itertools.cycle([q for q, _ in circle.states])
    benchmark(lambda: kin.update(next(qs)))


def test_check_configuration(benchmark, circle):
    """Input validation of q at the top of every tick."""
    benchmark.group = "pieces"
    q = circle.states[0][0]
    benchmark(circle.scenario.robot.check_configuration, q)


@pytest.mark.parametrize("kind", ["FrameTask", "PostureTask"])
def test_task_compute(benchmark, circle, kind):
    """One task's data writing its weighted rows through its Python path (kinematics already
    updated; in a controller the same rows come from the tick program)."""
    benchmark.group = "pieces"
    robot = circle.scenario.robot
    task = next(t for t in circle.scenario.tasks if type(t).__name__ == kind)
    data = task.bind(robot)
    kin = Kinematics(robot)
    q, target = circle.states[len(circle.states) // 2]
    kin.update(q)
    if kind == "FrameTask":
        task.set_target(*target)
    jacobian, rhs = np.zeros((data.dim, robot.nv)), np.zeros(data.dim)
    benchmark(data.compute, kin, circle.scenario.dt, jacobian, rhs)


def test_hessian_assembly(benchmark, circle):
    """H = Js^T Js (+ damping) and c = -Js^T rs for the youBot stack's 11 rows."""
    benchmark.group = "pieces"
    rng = np.random.default_rng(0)
    Js, rs = rng.normal(size=(11, 8)), rng.normal(size=11)
    H, c = np.zeros((8, 8)), np.zeros(8)

    def assemble():
        np.matmul(Js.T, Js, out=H)
        H.flat[::9] += 1e-3
        np.matmul(Js.T, rs, out=c)
        np.negative(c, out=c)

    benchmark(assemble)


@pytest.mark.parametrize("scenario", ["youbot_circle", "youbot_reach"])
@pytest.mark.parametrize("backend", ["daqp direct", "daqp via qpsolvers"])
def test_solve(benchmark, scenario, backend):
    """The QP solve alone on recorded QPs (reach has active speed and wheel limits)."""
    benchmark.group = f"solve {scenario}"
    solver = make_solver("daqp") if backend == "daqp direct" else QpsolversBackend("daqp")
    qps = itertools.cycle(recorded(scenario).qps)
    benchmark(lambda: solver.solve(next(qps)))


# ------------------------------------------------------------------------ peers
@pytest.mark.parametrize("peer", ["wbc", "Pink", "mink"])
def test_peer_step(benchmark, peer):
    """One tick of the peer stack (benchmarks.peers) in wbc, Pink and mink, same q sequence."""
    from benchmarks.peer_setups import MinkSetup, PinkSetup, WbcSetup, spec_from_scenario

    if peer != "wbc":
        pytest.importorskip("pink" if peer == "Pink" else "mink")
    benchmark.group = "peer stack"
    rec = recorded("youbot_circle")
    spec = spec_from_scenario(rec.scenario)
    setup = {"wbc": WbcSetup, "Pink": PinkSetup, "mink": MinkSetup}[peer](spec)
    states = itertools.cycle(rec.states)

    def tick():
        q, target = next(states)
        setup.set_target(target[0])
        return setup.step(q)

    benchmark(tick)


def test_available_solvers_listed():
    """Sanity: the suite runs against the installed package."""
    assert "daqp" in wbc.available_solvers()
