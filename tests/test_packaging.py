"""The package as users get it: the shipped files found installed and from a source tree, a wheel
installed elsewhere running every shipped scenario by name, an sdist that carries its own tests."""

import json
import os
import subprocess
import sys
import tarfile
import textwrap
import zipfile
from pathlib import Path

import pytest

import wbc
from conftest import NEUTRAL, ROOT
from wbc.model import shipped

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

PYPROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text())
SCENARIOS = sorted(path.stem for path in (ROOT / "tasks").glob("*.toml"))
MODELS = sorted(path.name for path in (ROOT / "models").iterdir() if path.is_dir() and path.name != "__pycache__")

#: the README snippet's first lines, as a user pastes them into a REPL
SNIPPET = textwrap.dedent("""
    import numpy as np
    import wbc
    robot = wbc.load_robot("youbot")
    q = np.array([0, 0, 0, 0, 0.5, 1.0, 1.2, 0.0])
    print(wbc.__file__, robot.frame_pose(q, "ee").shape == (4, 4), len(wbc.model.shipped.scenario_names()), sep="|")
""")


def test_every_model_folder_and_the_scenarios_are_packaged():
    """pyproject.toml lists one data package per robot folder (setuptools installs unlisted data
    folders only with a deprecation warning) and maps tasks/ to wbc.scenarios."""
    tool = PYPROJECT["tool"]["setuptools"]
    assert {f"wbc.models.{name}" for name in MODELS} <= set(tool["packages"])
    assert tool["package-dir"] == {"wbc.models": "models", "wbc.scenarios": "tasks"}
    assert MODELS == wbc.shipped_models() and SCENARIOS == shipped.scenario_names()


def test_every_shipped_scenario_says_what_it_shows():
    for name in SCENARIOS:
        description = shipped.scenario_description(name)
        assert 20 < len(description) <= 110, (name, description)


@pytest.mark.parametrize("where", ["clone root", "elsewhere"])
def test_the_snippet_runs_from_the_clone_root_and_from_elsewhere(where):
    """From the clone root a REPL imports the clone's wbc/, whatever is installed (in CI: a
    non-editable install); its models and scenarios are the clone's models/ and tasks/."""
    cwd = ROOT if where == "clone root" else NEUTRAL
    result = subprocess.run([sys.executable, "-c", SNIPPET], cwd=cwd, capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr
    module, pose, scenarios = result.stdout.strip().split("|")
    if where == "clone root":
        assert Path(module).resolve() == ROOT / "wbc" / "__init__.py"
    assert pose == "True" and int(scenarios) == len(SCENARIOS)


def test_an_unknown_scenario_name_is_refused_with_the_list():
    result = subprocess.run([sys.executable, "-m", "wbc", "run", "youbot_circel"], cwd=NEUTRAL,
                            capture_output=True, text=True, timeout=300)
    assert result.returncode == 2 and result.stdout == ""
    (line,) = result.stderr.splitlines()
    assert "did you mean 'youbot_circle'?" in line and "wbc scenarios" in line and "Traceback" not in line


@pytest.fixture(scope="module")
def built(tmp_path_factory) -> dict[str, Path]:
    """A wheel and an sdist of this tree, built as a user builds them (python -m build)."""
    out = tmp_path_factory.mktemp("dist")
    result = subprocess.run([sys.executable, "-m", "build", "--outdir", str(out), str(ROOT)],
                            capture_output=True, text=True, timeout=900)
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-3000:]
    # setuptools' own complaint about byte-compiling under PYTHONDONTWRITEBYTECODE is not ours
    warnings = [line for line in (result.stdout + result.stderr).splitlines()
                if "warn" in line.lower() and "byte-compiling is disabled" not in line]
    assert warnings == []
    (wheel,), (sdist,) = out.glob("*.whl"), out.glob("*.tar.gz")
    return {"wheel": wheel, "sdist": sdist}


@pytest.mark.slow
def test_a_wheel_installed_elsewhere_runs_every_shipped_scenario_by_name(built, tmp_path):
    target = tmp_path / "site"
    subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", "--target", str(target),
                    str(built["wheel"])], check=True, timeout=600)
    environment = {**os.environ, "PYTHONPATH": str(target)}
    where = subprocess.run([sys.executable, "-c", "import wbc; print(wbc.__file__)"], cwd=tmp_path,
                           env=environment, capture_output=True, text=True, check=True, timeout=300)
    assert Path(where.stdout.strip()).is_relative_to(target)  # the wheel's wbc, not this tree's
    listing = subprocess.run([sys.executable, "-m", "wbc", "scenarios"], cwd=tmp_path, env=environment,
                             capture_output=True, text=True, check=True, timeout=300)
    assert [line.split()[0] for line in listing.stdout.splitlines()[: len(SCENARIOS)]] == SCENARIOS
    run = subprocess.run([sys.executable, "-m", "wbc", "run", *SCENARIOS, "--json", "--no-progress"],
                         cwd=tmp_path, env=environment, capture_output=True, text=True, timeout=1800)
    assert run.returncode == 0, run.stderr
    summaries = json.loads(run.stdout)
    assert [summary["scenario"] for summary in summaries] == SCENARIOS
    assert all(summary["ticks"] > 0 for summary in summaries)


@pytest.mark.slow
def test_the_wheel_holds_the_package_and_its_data_only(built):
    names = zipfile.ZipFile(built["wheel"]).namelist()
    assert {f"wbc/scenarios/{name}.toml" for name in SCENARIOS} <= set(names)
    assert {f"wbc/models/{name}/{name}.urdf" for name in MODELS} <= set(names)
    assert "wbc/py.typed" in names
    assert not [name for name in names if name.startswith(("tests/", "benchmarks/", "docs/"))]


@pytest.mark.slow
def test_the_sdist_carries_what_its_tests_need(built):
    """Unpacked, the sdist is a source tree that installs and runs its own tests (CI runs them:
    .ci/run): every file of tests/, benchmarks/, docs/, examples/, tasks/, models/, .ci/ is in it."""
    with tarfile.open(built["sdist"]) as archive:
        top = archive.getnames()[0].split("/")[0]
        names = {name.removeprefix(top + "/") for name in archive.getnames()}
    for folder in ("tests", "benchmarks", "docs", "examples", "tasks", "models", ".ci"):
        files = {path.relative_to(ROOT).as_posix() for path in (ROOT / folder).rglob("*")
                 if path.is_file() and "__pycache__" not in path.parts and ".hypothesis" not in path.parts}
        assert files and files <= names, sorted(files - names)[:5]
    assert {"README.md", "CHANGELOG.md", "LICENSE", "pyproject.toml"} <= names
