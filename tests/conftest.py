import importlib
import os
import re
import signal
import sys
import tempfile
from collections.abc import Generator
from pathlib import Path
from types import ModuleType

# the TOML reader of the tests that read pyproject.toml or TOML blocks: `from conftest import tomllib`
if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib  # noqa: F401

import numpy as np
import pytest

import wbc

#: the checkout: its ``benchmarks`` package (not installed) is importable by the tests. Appended
#: after ``import wbc``: an installed wbc (``pip install .``) stays the one tested
ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.append(str(ROOT))

# the tests that interrupt a `wbc` child with SIGINT need it to reach the child's Python handler: a
# suite started in the background (`pytest ... &` without job control, nohup, some CI runners)
# inherits SIGINT ignored, which exec passes on and Python then keeps (no KeyboardInterrupt). A
# handler here is reset to the default in every child at exec.
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)

# CI replays the same examples every run (a red CI must be reproducible); locally
# hypothesis explores new ones (that is how the HiGHS cycling case was found)
try:
    from hypothesis import settings
except ModuleNotFoundError:  # the tests that use hypothesis are skipped, naming the [test] extra
    pass
else:
    settings.register_profile("ci", derandomize=True)
    # the fuzz campaign (tests/test_fuzz.py): `pytest tests/test_fuzz.py --hypothesis-profile=nightly`
    # or `WBC_FUZZ_EXAMPLES=5000 pytest tests/test_fuzz.py` (the count is split over the fuzz tests)
    settings.register_profile("nightly", max_examples=int(os.environ.get("WBC_FUZZ_EXAMPLES") or 3000),
                              deadline=None)
    if os.environ.get("WBC_FUZZ_EXAMPLES"):
        settings.load_profile("nightly")
    elif os.environ.get("CI"):
        settings.load_profile("ci")

# ------------------------------------------------------------------ missing extras
#: third-party packages the tests use beyond wbc's own dependencies -> the extra that installs them
EXTRA_OF = {
    "mujoco": "sim", "matplotlib": "plot", "viser": "view", "distributed": "distributed", "dask": "distributed",
    "mink": "bench", "pink": "bench", "qpbenchmark": "bench", "pandas": "bench", "pytest_benchmark": "bench",
    "quadprog": "solvers", "clarabel": "solvers", "piqp": "solvers", "highspy": "solvers",
    "hypothesis": "test", "sympy": "test", "mypy": "test", "basedpyright": "test", "sphinx": "test", "build": "test",
}
#: CI sets it: a missing extra then fails the test instead of skipping it
REQUIRE_EXTRAS = os.environ.get("WBC_REQUIRE_EXTRAS") == "1"
_MISSING = re.compile(r"No module named '([\w.]+)'")


def missing_extra(text: str) -> str | None:
    """The reason to skip when ``text`` (an error) says a module of an extra is missing, else None."""
    found = _MISSING.search(text)
    module = found.group(1).split(".")[0] if found else ""
    if module not in EXTRA_OF or REQUIRE_EXTRAS:
        return None
    extra = EXTRA_OF[module]
    return f"needs the [{extra}] extra ({module} is not installed): pip install \"wbc[{extra}]\""


def require(module: str) -> ModuleType:
    """Import ``module`` for a test; when an extra's package is missing, skip the test (or the
    whole file, called at its top) naming the extra -- fail instead under ``WBC_REQUIRE_EXTRAS=1``."""
    try:
        return importlib.import_module(module)
    except ModuleNotFoundError as error:
        reason = missing_extra(str(error))
        if reason is None:
            raise
        pytest.skip(reason, allow_module_level=True)


@pytest.hookimpl(hookwrapper=True)
def pytest_make_collect_report(collector: pytest.Collector) -> Generator[None, None, None]:
    """A test file that cannot import an extra's package is skipped, naming the extra."""
    outcome = yield
    report = outcome.get_result()
    reason = missing_extra(str(report.longrepr)) if report.failed else None
    if reason is not None:
        report.outcome, report.longrepr = "skipped", (str(collector.path), 0, f"Skipped: {reason}")


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo[None]) -> Generator[None, None, None]:
    """A test that imports a missing extra's package while it runs is skipped, naming the extra."""
    outcome = yield
    report = outcome.get_result()
    excinfo = call.excinfo
    if report.failed and excinfo is not None and excinfo.errisinstance(ModuleNotFoundError):
        reason = missing_extra(str(excinfo.value))
        if reason is not None:
            report.outcome, report.longrepr = "skipped", (str(item.path), 0, f"Skipped: {reason}")

TASKS = ROOT / "tasks"
#: working directory of `python -c` subprocesses: outside the checkout, so that they import
#: the installed wbc (from the checkout root, `-c` would import the source tree, which has
#: no wbc.models in a non-editable install)
NEUTRAL = tempfile.gettempdir()


def child_environment(*paths: Path | str) -> dict[str, str]:
    """``os.environ`` for a Python subprocess, with ``paths`` and then the folder of the ``wbc`` this
    process imported first on its PYTHONPATH: the child runs the wbc under test, also when the venv
    installs another checkout's (a venv editable on one worktree, pytest run from another)."""
    under_test = Path(wbc.__file__).resolve().parents[1]
    inherited = os.environ.get("PYTHONPATH", "")
    return {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [*map(str, paths), str(under_test), inherited]))}


@pytest.fixture(scope="session")
def youbot() -> wbc.Robot:
    return wbc.load_robot("youbot")


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20261122)


def random_youbot_configurations(rng: np.random.Generator, count: int) -> np.ndarray:
    """Base anywhere in a 10 m square with any heading; arm joints uniform within eq. (1)."""
    deg = np.pi / 180.0
    low = np.array([-5.0, -5.0, -np.pi, -169 * deg, -65 * deg, -151 * deg, -102.5 * deg, -167.5 * deg])
    high = np.array([5.0, 5.0, np.pi, 169 * deg, 90 * deg, 146 * deg, 102.5 * deg, 167.5 * deg])
    return rng.uniform(low, high, size=(count, 8))


def bounding_sphere(table: np.ndarray, shape: int, placements) -> tuple[np.ndarray, float]:
    """World centre and radius of a collision shape's bounding sphere (a row of the shape table of
    wbc.collision; ``placements``: Pinocchio's ``data.oMi``)."""
    from wbc.collision.layout import BOUND_CENTER, BOUND_RADIUS, JOINT, ROTATION, TRANSLATION

    local = table[shape, TRANSLATION] + table[shape, ROTATION].reshape(3, 3) @ table[shape, BOUND_CENTER]
    return placements[int(table[shape, JOINT])].act(local), float(table[shape, BOUND_RADIUS])


def pair_levers(model, data, table: np.ndarray, a: int, b: int) -> tuple[np.ndarray, list]:
    """The lever of each velocity coordinate k on the pair of shapes (a, b), written out:
    ``|v_O,k + w_k x c| + |w_k| r`` of the bounding sphere (c, r) of the one shape k moves, from
    Pinocchio's world joint Jacobians (``data`` after ``pin.computeJointJacobians``); NaN where k
    moves both shapes or neither. Also the two spheres."""
    import pinocchio as pin

    from wbc.collision.layout import JOINT

    jacobians = [pin.getJointJacobian(model, data, int(table[s, JOINT]), pin.ReferenceFrame.WORLD) for s in (a, b)]
    spheres = [bounding_sphere(table, s, data.oMi) for s in (a, b)]
    levers = np.full(model.nv, np.nan)
    for k in range(model.nv):
        moves = [bool(np.any(jacobian[:, k] != 0.0)) for jacobian in jacobians]
        if moves[0] != moves[1]:
            x = 0 if moves[0] else 1
            (centre, radius), v, w = spheres[x], jacobians[x][:3, k], jacobians[x][3:, k]
            levers[k] = np.linalg.norm(v + np.cross(w, centre)) + np.linalg.norm(w) * radius
    return levers, spheres
