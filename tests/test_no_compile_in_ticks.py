"""No kernel is compiled -- nor read from numba's cache -- inside a tick or the control loop.

The kernels compile when first used (wbc.runtime.kernels._lazy): an op when a program adds it,
a kernel of a Python path when the object that calls it in ticks is built. A kernel missed
there would stall a control loop for the seconds of its compilation after an install. In a fresh
process (every dispatcher empty, the cache warm or not), every registered item's controllers --
flat with native DAQP and with a qpsolvers backend (the answer checked in Python), two priority
levels, the fallback answering -- are built, then stepped, their targets set and their commands
integrated as in the README's loop: no compiled function gains a signature in the loop. Nor in
the warm-up a build runs (wbc.control.warm_up: a twin's ticks), which would add compilation to
the first build after an install; the controllers are built without it so that it cannot
compile, at build, a kernel their own ticks would miss.
"""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from conftest import child_environment

TESTS = Path(__file__).parent

_CHILD = textwrap.dedent("""
    import sys
    import numpy as np
    import wbc
    from wbc.control.warm_up import warm_up_twin
    from item_registry import CASES, CONFIGURATIONS, _points_around_the_base, _sphere_near_the_gripper, load

    def signatures():
        found = {}
        for name, module in list(sys.modules.items()):
            if name.startswith("wbc."):
                for attribute, value in list(vars(module).items()):
                    if hasattr(value, "py_func") and hasattr(value, "overloads"):
                        found[f"{name}.{attribute}"] = len(value.overloads)
        return found

    def controllers(robot, item):
        regularisation = wbc.KineticEnergyRegularization(1e-3)
        if isinstance(item, wbc.Task):
            shapes = [([item, regularisation], []), ([[item], [regularisation]], []),
                      ([[regularisation], [item]], [])]
        else:
            shapes = [([regularisation], [item]), ([[wbc.PostureTask(1e-2)], [regularisation]], [item])]
        for tasks, constraints in shapes:
            for solver in ("daqp", "quadprog"):
                try:
                    # (no warm-up: its twin's ticks would compile at build what the ticks miss)
                    yield wbc.Controller(robot, tasks, constraints, solver=solver, dt=0.01, warm_up=False)
                except wbc.WbcError:
                    continue  # not a valid stack for this item (e.g. a linear cost above the last level)

    built = 0
    for case in CASES:
        robot = load(case.robot)
        q0, q1 = CONFIGURATIONS[case.robot]
        item = case.make(robot, q1)
        for controller in controllers(robot, item):
            built += 1
            before = signatures()
            warm_up_twin(controller._twin)  # what a build runs by default: compiles nothing the build did not
            warmed = sorted(name for name, count in signatures().items() if count != before.get(name, 0))
            assert not warmed, f"warm-up of {case.name} on {case.robot}, {controller.levels}: {warmed}"
            q = q0.copy()
            for _ in range(3):
                if isinstance(item, wbc.FrameTask):
                    item.set_target(robot.frame_pose(q1, item.frame))
                v = controller.step(q)
                q = robot.integrate(q, v, 0.01)
            after = signatures()
            new = sorted(name for name, count in after.items() if count != before.get(name, 0))
            assert not new, f"{case.name} on {case.robot}, {controller.levels} ({controller.solver.name}): {new}"
    # the collision items computed in Python (their kernels compiled at build, prepare_compute):
    # coal's pairs (a cylinder), and the rows braked under acceleration bounds; a Distances too
    import pathlib, tempfile
    from test_collision_coal_shapes import URDF
    path = pathlib.Path(tempfile.mkdtemp()) / "coal_arm.urdf"
    path.write_text(URDF)
    arm, youbot = wbc.load_robot(path), load("youbot")
    q0, q1 = CONFIGURATIONS["youbot"]
    runs = [(arm, arm.neutral(), [wbc.CollisionAvoidance([wbc.Box(np.eye(4), (0.1, 0.1, 0.1))])]),
            (youbot, q0, [_sphere_near_the_gripper(youbot, q1), wbc.AccelerationLimits(max_jerk=50.0)]),
            (youbot, q0, [_points_around_the_base(youbot, q1), wbc.AccelerationLimits(max_jerk=50.0)])]
    for robot, q, constraints in runs:
        controller = wbc.Controller(robot, [wbc.PostureTask(1.0, gain=0.3)], [wbc.JointVelocityLimits(), *constraints],
                                    dt=0.01, warm_up=False)
        python = [type(item).__name__ for item, _ in controller._python_constraints]
        assert any(name in python for name in ("CollisionAvoidanceData", "BaseFootprintAvoidanceData")), python
        before = signatures()
        for _ in range(3):
            q = robot.integrate(q, controller.step(q), 0.01)
        assert signatures() == before, [type(c).__name__ for c in constraints]
        built += 1
    distances = wbc.collision.Distances(arm, [wbc.Box(np.eye(4), (0.1, 0.1, 0.1))])
    buffers, before = distances.buffers(), signatures()
    distances.compute(arm.neutral(), buffers)
    assert signatures() == before, "Distances.compute"
    # the fallback answering (infeasible equality rows) calls its own kernel
    robot = load("youbot")
    clash = wbc.LinearConstraint([[0, 0, 0, 1, 0, 0, 0, 0], [0, 0, 0, 1, 0, 0, 0, 0]], b=[0.1, -0.1])
    controller = wbc.Controller(robot, [wbc.KineticEnergyRegularization(1e-3)], [clash], dt=0.01, warm_up=False)
    before = signatures()
    controller.step(robot.neutral())
    assert controller.last.status != "optimal"
    assert signatures() == before
    print(built)
""")


@pytest.mark.slow  # every item's controllers in a fresh process: ~1 min (more when the kernels compile)
def test_no_kernel_compiles_in_a_tick():
    result = subprocess.run([sys.executable, "-c", _CHILD], capture_output=True, text=True, timeout=1800,
                            cwd=TESTS, env=child_environment(TESTS))
    assert result.returncode == 0, result.stderr[-3000:]
    assert int(result.stdout.split()[-1]) > 2 * 30  # the controllers were built (two per item at least)


_ENTRIES_CHILD = textwrap.dedent("""
    import sys
    import numpy as np
    import wbc.model.robot as robot_module
    import wbc.tasks.frame_task as frame_task_module
    from numba.core.dispatcher import Dispatcher
    from wbc.app.scenario import load_scenario

    scenario = load_scenario(sys.argv[1])  # the README's loop: native DAQP, the tick in one native call
    robot, task = scenario.robot, scenario.reference_task
    controller = scenario.make_controller("daqp")
    q = scenario.q0.copy()
    for _ in range(3):
        task.set_target(np.asarray(robot.frame_pose(q, task.frame)))
        q = robot.integrate(q, controller.step(q), scenario.dt)
    bound = {"set_target": frame_task_module._set_pose, "integrate": robot_module._integrate_vector_space,
             "step": controller._native_step}
    print(sorted(name for name, function in bound.items() if isinstance(function, Dispatcher)))
""")


@pytest.mark.slow  # a fresh process (the lazily compiled kernels not yet fetched): ~10 s
def test_the_control_loop_calls_compiled_entries():
    """The control loop's set_target(pose), robot.integrate and the native tick call their kernels'
    compiled entries (wbc.runtime.native_entry.unchecked_entry), not numba's dispatchers: the
    kernels, compiled lazily, are compiled when the entries are bound (else the type check stays)."""
    result = subprocess.run([sys.executable, "-c", _ENTRIES_CHILD, str(TESTS.parent / "tasks" / "youbot_circle.toml")],
                            capture_output=True, text=True, timeout=900, cwd=TESTS, env=child_environment())
    assert result.returncode == 0, result.stderr[-3000:]
    assert result.stdout.split("\n")[-2] == "[]"
