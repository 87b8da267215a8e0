"""The extension examples (docs/extending.md) run as scripts and do what they say."""

import runpy
import subprocess
import sys

import numpy as np

from conftest import ROOT

EXAMPLES = ROOT / "examples"


def test_custom_python_task_script_runs():
    result = subprocess.run([sys.executable, str(EXAMPLES / "custom_task.py")], capture_output=True, text=True,
                            timeout=300, check=False)
    assert result.returncode == 0, result.stderr
    assert "target 0.35" in result.stdout and "status optimal" in result.stdout


def test_custom_python_task_holds_the_height():
    error = runpy.run_path(str(EXAMPLES / "custom_task.py"))["main"]()
    assert error < 1e-3  # [m]; the posture task pulls the rest


def test_custom_compiled_task_script_runs():
    result = subprocess.run([sys.executable, str(EXAMPLES / "custom_compiled_task.py")], capture_output=True,
                            text=True, timeout=300, check=False)
    assert result.returncode == 0, result.stderr
    assert "status optimal" in result.stdout


def test_custom_compiled_task_centres_the_joints():
    module = runpy.run_path(str(EXAMPLES / "custom_compiled_task.py"))
    assert module["main"]() < 0.25  # the largest offset from mid-range shrinks to a quarter
    import wbc

    robot, task = wbc.load_robot("youbot"), module["CenteringTask"](cost=1.0, gain=0.5)
    q = np.array([0.0, 0.0, 0.0, 2.8, 1.4, -2.4, 1.6, 2.7])
    controller = wbc.Controller(robot, [task])
    v = controller.step(q)
    # an isolated centering task: per joint min w^2 (v - gain/dt e)^2 + damping v^2, so
    # v = w^2 / (w^2 + damping) gain/dt e with w = 1 / (1 - s^2), e = middle - q
    middle, half = 0.5 * (robot.lower + robot.upper)[3:], 0.5 * (robot.upper - robot.lower)[3:]
    e = middle - q[3:]
    w2 = 1.0 / (1.0 - np.minimum(np.abs(e) / half, 0.99) ** 2) ** 2
    np.testing.assert_allclose(v[3:], w2 / (w2 + controller.damping) * 0.5 / controller.dt * e, rtol=1e-9)
    assert task.name in controller.last.task_errors
