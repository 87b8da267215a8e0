"""Types as users and CI see them: mypy on the package (its [tool.mypy] configuration, strict),
and a user's script written like the README checked in strict mode by basedpyright (pyright)
and mypy, with no error and no partially unknown type on the names a control loop uses."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import wbc

ROOT = Path(__file__).resolve().parents[1]
USER_SCRIPT = Path(__file__).with_name("readme_user_script.py")
#: where the wbc that the tests import lives (the source tree for an editable install)
WBC_PARENT = Path(wbc.__file__).resolve().parents[1]
#: the type checkers must see the wbc the tests run, whatever the install
IMPORT_ROOT = [] if WBC_PARENT.name in ("site-packages", "dist-packages") else [str(WBC_PARENT)]


def run(command: list[str], cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(command, cwd=cwd, capture_output=True, text=True, timeout=600)


#: numpy's annotations changed in 2.3 (ndarray's type parameters got defaults, tolist() and
#: linalg results typed anew): the package is kept clean against numpy >= 2.3; numpy 2.2's stubs
#: alone would report ~180 differences (bare np.ndarray among them)
NUMPY_STUBS_CHECKED = tuple(int(part) for part in np.__version__.split(".")[:2]) >= (2, 3)


@pytest.mark.slow
@pytest.mark.skipif(not NUMPY_STUBS_CHECKED, reason=f"numpy {np.__version__}: wbc is typed against numpy >= 2.3")
def test_mypy_on_the_package_is_clean(request):
    """``mypy`` from the repository root checks wbc with the [tool.mypy] configuration (strict)."""
    cache = request.config.cache.mkdir("mypy-package")
    result = run([sys.executable, "-m", "mypy", "--cache-dir", str(cache)], ROOT)
    assert result.returncode == 0 and "Success: no issues found" in result.stdout, result.stdout + result.stderr


def _revealed(messages: list[tuple[int, str]], line_of: dict[str, int], expression: str) -> str:
    line = line_of[expression]
    return next(message for number, message in messages if number == line)


def _reveal_lines() -> dict[str, int]:
    """Line (1-based) of each ``reveal_type(expression)`` of the user script."""
    lines = USER_SCRIPT.read_text().splitlines()
    return {match[1]: number for number, text in enumerate(lines, 1)
            if (match := re.match(r"\s*reveal_type\((.*)\)\s*$", text))}


def test_user_script_passes_pyright_strict(tmp_path):
    """basedpyright (pyright) in strict mode on the README-like script: no error or warning --
    strict mode reports any partially unknown type of a name the script uses -- and the types a
    user sees: the command and poses float64 arrays, ``controller.dt`` a float and
    ``controller.last`` a TickDiagnostics (not Optional)."""
    config = tmp_path / "pyrightconfig.json"
    config.write_text(json.dumps({"typeCheckingMode": "strict", "pythonVersion": "3.10", "extraPaths": IMPORT_ROOT}))
    result = run([sys.executable, "-m", "basedpyright", "--outputjson", "--pythonpath", sys.executable,
                  "--project", str(config), str(USER_SCRIPT)], tmp_path)
    report = json.loads(result.stdout)
    diagnostics = report["generalDiagnostics"]
    problems = [d for d in diagnostics if d["severity"] != "information"]
    assert not problems, json.dumps(problems, indent=1)
    assert report["summary"]["filesAnalyzed"] == 1
    messages = [(d["range"]["start"]["line"] + 1, d["message"]) for d in diagnostics]
    line_of = _reveal_lines()
    assert len(messages) == len(line_of), messages
    for expression in line_of:
        assert "Unknown" not in _revealed(messages, line_of, expression), expression
    for callable_name in ("robot.frame_pose", "controller.step", "robot.integrate"):
        assert _revealed(messages, line_of, callable_name).endswith('dtype[float64]]"'), \
            _revealed(messages, line_of, callable_name)
    assert _revealed(messages, line_of, "ee.set_target").endswith('-> None"')
    assert _revealed(messages, line_of, "controller.dt") == 'Type of "controller.dt" is "float"'
    assert _revealed(messages, line_of, "controller.last") == 'Type of "controller.last" is "TickDiagnostics"'
    assert _revealed(messages, line_of, "controller.last.status") == 'Type of "controller.last.status" is "str"'
    for array in ("controller.step(q)", "target", "robot.wheel_speeds(q, controller.step(q))"):
        assert _revealed(messages, line_of, array).endswith('dtype[float64]]"'), _revealed(messages, line_of, array)


@pytest.mark.slow
def test_user_script_passes_mypy_strict(tmp_path, request):
    """mypy --strict on the same script, wbc read as an installed package (its own errors silent)."""
    config = tmp_path / "mypy.ini"
    path = f"mypy_path = {IMPORT_ROOT[0]}\n" if IMPORT_ROOT else ""
    config.write_text(f"[mypy]\nstrict = True\npython_version = 3.10\n{path}\n[mypy-wbc.*]\nfollow_imports = silent\n")
    cache = request.config.cache.mkdir("mypy-user-script")
    result = run([sys.executable, "-m", "mypy", "--config-file", str(config), "--cache-dir", str(cache),
                  str(USER_SCRIPT)], tmp_path)
    notes = re.findall(r":(\d+): note: Revealed type is \"(.*)\"", result.stdout)
    errors = [line for line in result.stdout.splitlines() if ": error:" in line]
    assert not errors and result.returncode == 0, result.stdout + result.stderr
    revealed = {int(line): text for line, text in notes}
    line_of = _reveal_lines()
    assert set(revealed) == set(line_of.values()), result.stdout
    assert revealed[line_of["controller.dt"]] in ("float", "builtins.float")
    assert revealed[line_of["controller.last"]] == "wbc.diagnostics.TickDiagnostics"
    for name in ("controller.step", "robot.frame_pose", "robot.integrate", "controller.step(q)", "target"):
        assert revealed[line_of[name]].endswith("numpy.dtype[numpy.float64]]"), revealed[line_of[name]]
