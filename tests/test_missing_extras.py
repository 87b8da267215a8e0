"""Tests whose optional extras are missing are skipped naming the extra, not failed (and fail in CI).

The missing packages are simulated: a folder first on PYTHONPATH holds packages of the same
names whose import raises ``ModuleNotFoundError`` as a missing package's does.
"""

import os
import subprocess
import sys

import pytest

from conftest import ROOT

#: files and tests that import an extra's package: at the top of the file (matplotlib), inside a
#: test (mujoco), through conftest.require (mujoco, in test_cli)
TARGETS = ["tests/test_plotting.py",
           "tests/test_youbot_model.py::test_urdf_and_mjcf_have_identical_kinematics",
           "tests/test_cli.py::test_the_summary_says_how_the_loop_was_closed"]


def _run_without(tmp_path, packages: list[str], require: bool) -> subprocess.CompletedProcess[str]:
    for name in packages:
        (tmp_path / name).mkdir()
        (tmp_path / name / "__init__.py").write_text(
            f"raise ModuleNotFoundError(\"No module named '{name}'\", name={name!r})\n")
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [str(tmp_path), os.environ.get("PYTHONPATH")])),
               WBC_REQUIRE_EXTRAS="1" if require else "0")
    command = [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-q", "-rs", "--continue-on-collection-errors"]
    return subprocess.run([*command, *TARGETS],
                          cwd=ROOT, env=env, capture_output=True, text=True, timeout=600)


@pytest.mark.slow
def test_missing_extras_skip_naming_the_extra(tmp_path):
    result = _run_without(tmp_path, ["matplotlib", "mujoco"], require=False)
    assert result.returncode == 0, result.stdout + result.stderr
    assert 'needs the [plot] extra (matplotlib is not installed): pip install "wbc[plot]"' in result.stdout
    assert result.stdout.count("needs the [sim] extra (mujoco is not installed)") == 2, result.stdout
    assert " failed" not in result.stdout and " error" not in result.stdout


@pytest.mark.slow
def test_missing_extras_fail_where_they_are_required(tmp_path):
    result = _run_without(tmp_path, ["matplotlib", "mujoco"], require=True)
    assert result.returncode in (1, 2), result.stdout + result.stderr  # failed, or a collection error
    assert "No module named 'matplotlib'" in result.stdout and "No module named 'mujoco'" in result.stdout
    assert "needs the [" not in result.stdout
