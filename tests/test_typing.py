"""Types as users and CI see them: mypy on the package (its [tool.mypy] configuration, strict),
and a user's script made of the documentation's own code -- the README's first snippet and the
control loop of docs/control-loop.md, taken from the pages -- checked in strict mode by
basedpyright (pyright) and mypy: no error, no partially unknown type on the names a control
loop uses, and the types a user reads for them."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import wbc
from test_docs import blocks

ROOT = Path(__file__).resolve().parents[1]
#: where the wbc that the tests import lives (the source tree for an editable install)
WBC_PARENT = Path(wbc.__file__).resolve().parents[1]
#: the type checkers must see the wbc the tests run, whatever the install
IMPORT_ROOT = [] if WBC_PARENT.name in ("site-packages", "dist-packages") else [str(WBC_PARENT)]



def _mypy_cache(request: pytest.FixtureRequest, tmp_path: Path, name: str) -> Path:
    """mypy's cache folder: in pytest's cache (kept between runs) when the cache plugin is on,
    else a fresh one (``-p no:cacheprovider``: a cold, slower run)."""
    cache = getattr(request.config, "cache", None)
    return Path(cache.mkdir(name)) if cache is not None else tmp_path / name

def run(command: list[str], cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(command, cwd=cwd, capture_output=True, text=True, timeout=600)


#: the user's driver, typed as a user would type it (the loop leaves these names to the driver)
DRIVER = '''
import numpy as np
from numpy.typing import NDArray


def running() -> bool: raise NotImplementedError
def read_joint_positions() -> NDArray[np.float64]: raise NotImplementedError
def target_pose() -> NDArray[np.float64]: raise NotImplementedError
def log(message: str) -> None: raise NotImplementedError
def send_wheel_speeds(speeds: NDArray[np.float64]) -> None: raise NotImplementedError
def send_arm_velocities(velocities: NDArray[np.float64]) -> None: raise NotImplementedError
'''

#: what the user's checker must see after each snippet (names the snippet defines)
REVEALED = {
    "readme": ("robot.frame_pose", "ee.set_target", "controller.step", "robot.integrate", "controller.dt",
               "controller.last", "target", "controller.step(q)"),
    "loop": ("controller.last", "controller.last.success", "controller.last.status", "robot.wheel_speeds",
             "controller.step(read_joint_positions())", "controller.dt"),
}


def user_scripts(folder: Path) -> dict[Path, dict[str, int]]:
    """Two scripts of a user: the README's first python block, and the first python block of
    docs/control-loop.md after :data:`DRIVER`; each followed by a ``reveal_type`` per expression
    of :data:`REVEALED`. Returns the line of each reveal, by script."""
    readme = next(b.code for b in blocks(ROOT / "README.md") if b.language == "python")
    loop = next(b.code for b in blocks(ROOT / "docs" / "control-loop.md") if b.language == "python")
    lines = {}
    for name, parts in (("readme", [readme]), ("loop", [DRIVER, loop])):
        reveals = [f"reveal_type({expression})" for expression in REVEALED[name]]
        text = "\n".join(["from typing_extensions import reveal_type", *parts, *reveals]) + "\n"
        script = folder / f"{name}_user_script.py"
        script.write_text(text)
        first = len(text.splitlines()) - len(reveals) + 1
        lines[script] = {expression: first + k for k, expression in enumerate(REVEALED[name])}
    return lines


#: numpy's annotations changed in 2.3 (ndarray's type parameters got defaults, tolist() and
#: linalg results typed anew): the package is kept clean against numpy >= 2.3; numpy 2.2's stubs
#: alone would report ~180 differences (bare np.ndarray among them)
NUMPY_STUBS_CHECKED = tuple(int(part) for part in np.__version__.split(".")[:2]) >= (2, 3)


@pytest.mark.slow
@pytest.mark.skipif(not NUMPY_STUBS_CHECKED, reason=f"numpy {np.__version__}: wbc is typed against numpy >= 2.3")
def test_mypy_on_the_package_is_clean(request, tmp_path):
    """``mypy`` from the repository root checks wbc with the [tool.mypy] configuration (strict)."""
    cache = _mypy_cache(request, tmp_path, "mypy-package")
    result = run([sys.executable, "-m", "mypy", "--cache-dir", str(cache)], ROOT)
    assert result.returncode == 0 and "Success: no issues found" in result.stdout, result.stdout + result.stderr


def test_user_script_passes_pyright_strict(tmp_path):
    """basedpyright (pyright) in strict mode on the documentation's snippets: no error or warning --
    strict mode reports any partially unknown type of a name the scripts use -- and the types a
    user sees: the commands and poses float64 arrays, ``controller.dt`` a float and
    ``controller.last`` a TickDiagnostics (not Optional)."""
    scripts = user_scripts(tmp_path)
    config = tmp_path / "pyrightconfig.json"
    config.write_text(json.dumps({"typeCheckingMode": "strict", "pythonVersion": "3.10", "extraPaths": IMPORT_ROOT}))
    result = run([sys.executable, "-m", "basedpyright", "--outputjson", "--pythonpath", sys.executable,
                  "--project", str(config), *map(str, scripts)], tmp_path)
    report = json.loads(result.stdout)
    diagnostics = report["generalDiagnostics"]
    problems = [d for d in diagnostics if d["severity"] != "information"]
    assert not problems, json.dumps(problems, indent=1)
    assert report["summary"]["filesAnalyzed"] == len(scripts)
    revealed = {(Path(d["file"]).name, d["range"]["start"]["line"] + 1): d["message"] for d in diagnostics}
    assert len(revealed) == sum(map(len, scripts.values())), revealed
    for script, line_of in scripts.items():
        seen = {expression: revealed[script.name, line] for expression, line in line_of.items()}
        assert not [text for text in seen.values() if "Unknown" in text], seen
        for name in ("robot.frame_pose", "controller.step", "robot.integrate", "robot.wheel_speeds", "target",
                     "controller.step(q)", "controller.step(read_joint_positions())"):
            if name in seen:
                assert seen[name].endswith('dtype[float64]]"'), seen[name]
        expected = {"controller.dt": "float", "controller.last": "TickDiagnostics", "controller.last.success": "bool",
                    "controller.last.status": "str"}
        for name, type_name in expected.items():
            if name in seen:
                assert seen[name] == f'Type of "{name}" is "{type_name}"', seen[name]
        if "ee.set_target" in seen:
            assert seen["ee.set_target"].endswith('-> None"')


@pytest.mark.slow
def test_user_script_passes_mypy_strict(tmp_path, request):
    """mypy --strict on the same scripts, wbc read as an installed package (its own errors silent)."""
    scripts = user_scripts(tmp_path)
    config = tmp_path / "mypy.ini"
    path = f"mypy_path = {IMPORT_ROOT[0]}\n" if IMPORT_ROOT else ""
    config.write_text(f"[mypy]\nstrict = True\npython_version = 3.10\n{path}\n[mypy-wbc.*]\nfollow_imports = silent\n")
    cache = _mypy_cache(request, tmp_path, "mypy-user-script")
    result = run([sys.executable, "-m", "mypy", "--config-file", str(config), "--cache-dir", str(cache),
                  *map(str, scripts)], tmp_path)
    errors = [line for line in result.stdout.splitlines() if ": error:" in line]
    assert not errors and result.returncode == 0, result.stdout + result.stderr
    notes = re.findall(r"(\w+_user_script\.py):(\d+): note: Revealed type is \"(.*)\"", result.stdout)
    revealed = {(name, int(line)): text for name, line, text in notes}
    assert len(revealed) == sum(map(len, scripts.values())), result.stdout
    for script, line_of in scripts.items():
        seen = {expression: revealed[script.name, line] for expression, line in line_of.items()}
        assert seen["controller.dt"] in ("float", "builtins.float"), seen
        assert seen["controller.last"] == "wbc.control.diagnostics.TickDiagnostics", seen
        for name in ("controller.step", "robot.frame_pose", "robot.integrate", "robot.wheel_speeds",
                     "controller.step(q)", "target"):
            if name in seen:
                assert seen[name].endswith("numpy.dtype[numpy.float64]]"), seen[name]
