"""The API reference (docs/api, Sphinx): it builds with warnings as errors -- every
cross-reference to a wbc name resolves -- and it covers every module and public name."""

from __future__ import annotations

import pkgutil
import re
import subprocess
import sys
from pathlib import Path

import pytest

import wbc
from wbc.app import closed_loop, outputs, plotting, view

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs" / "api"


def _directives(name: str) -> list[str]:
    """The targets of every ``.. name::`` directive of the reference's pages."""
    return [target for page in sorted(DOCS.glob("*.rst"))
            for target in re.findall(rf"^\.\. {name}:: (\S+)", page.read_text(), flags=re.M)]


@pytest.mark.slow
def test_api_reference_builds_without_warnings(tmp_path):
    """``sphinx-build -W --keep-going`` (nitpicky: an unresolved wbc name is a warning)."""
    result = subprocess.run([sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-b", "html", str(DOCS),
                             str(tmp_path / "html")], capture_output=True, text=True, timeout=900)
    assert result.returncode == 0, result.stderr[-20000:]
    controller_page = (tmp_path / "html" / "control.html").read_text()
    assert 'id="wbc.control.controller.Controller.step"' in controller_page
    assert "ArrayLike" in controller_page  # numpy's aliases as written, not expanded


def test_every_module_is_in_the_api_reference():
    modules = {"wbc"} | {module.name for module in pkgutil.walk_packages(wbc.__path__, "wbc.")
                         if not module.name.startswith("wbc.models")  # robot descriptions: data, no API
                         and module.name != "wbc.__main__"}  # python -m wbc: the command line
    documented = _directives("automodule")
    assert len(documented) == len(set(documented)), "a module is documented twice"
    assert set(documented) == modules


def test_the_namespace_summary_lists_every_public_name():
    index = (DOCS / "index.rst").read_text()
    tables = re.findall(r"^\.\. autosummary::\n((?:   .*\n|\n)*)", index, flags=re.M)
    summarised = [name for table in tables for name in re.findall(r"^   (\w+)$", table, flags=re.M)]
    assert sorted(summarised) == sorted(wbc.__all__)


@pytest.mark.parametrize("function", [
    wbc.Controller, wbc.Controller.step, wbc.Controller.last.fget, wbc.load_robot, wbc.model_path,
    wbc.Robot.frame_pose, wbc.Robot.frame_jacobian, wbc.Robot.integrate, wbc.Robot.check_configuration,
    wbc.FrameTask.set_target, wbc.PositionTask.set_target, wbc.PostureTask.set_target, wbc.BaseVelocityTask.set_target,
    wbc.manipulability, wbc.manipulability_gradient,
    closed_loop.run, closed_loop.RunResult.coarsened, plotting.plot_runs, view.write_html, view.LiveView.follow,
    outputs.check_output, outputs.write_atomically,
], ids=lambda function: function.__qualname__)
def test_public_api_docstrings_say_what_they_raise(function):
    """The docstrings a user reads first have a Raises section (and Returns, for the functions
    whose result is not described by their first line)."""
    assert "\n    Raises:\n" in function.__doc__ or "\n        Raises:\n" in function.__doc__, function.__qualname__
    if function in (wbc.Controller.step, wbc.load_robot, wbc.Robot.frame_pose, wbc.Robot.integrate, closed_loop.run,
                    plotting.plot_runs, view.write_html, outputs.check_output, outputs.write_atomically):
        assert "Returns:\n" in function.__doc__, function.__qualname__
