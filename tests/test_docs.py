"""Every code block of README.md and docs/*.md runs, and every ``wbc.`` name they or the
docstrings mention exists.

Blocks are collected from the Markdown files themselves (nothing is copied into the tests); the
fence's info string says what a block is:

* ``python``: executed; the blocks of one page run in order in one namespace (a page reads like a
  notebook), in a temporary folder that holds the clone's ``tasks/`` and ``models/``. The names a
  control-loop sketch leaves to the user's driver (:data:`DRIVER`) are defined there.
* ``bash``: each command runs in that folder (a trailing ``\\`` continues a line). ``pip install
  SPEC && COMMAND``: the extras SPEC names must exist; COMMAND runs (CI runs the install itself).
  A command commented ``# until Ctrl-C`` serves until interrupted: it gets SIGINT once it has
  printed a line and must then exit quietly (status 0 or 130, no traceback).
* ``toml``: parsed; ``[[tasks]]`` / ``[[constraints]]`` / ``[reference]`` fragments are loaded
  into a youBot scenario (every key checked, as ``wbc run`` does); a ``[base]`` table must be
  the table of a shipped model's sidecar.
* ``text`` (synopses, output, diagrams): not code.

A block preceded by ``<!-- excerpt: PATH -->`` is a verbatim excerpt of PATH (an example or a
module the tests run), checked to be in it.
"""

from __future__ import annotations

import ast
import importlib
import io
import os
import re
import shlex
import signal
import subprocess
import sys
import textwrap
from collections.abc import Iterator
from contextlib import redirect_stdout
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

import wbc
from conftest import ROOT, tomllib

PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
LANGUAGES = {"python", "bash", "toml", "text"}
FENCE = re.compile(r"^```([\w-]*)\s*$")
EXCERPT = re.compile(r"^<!--\s*excerpt:\s*(\S+)\s*-->\s*$")


@dataclass
class Block:
    page: Path
    line: int  #: 1-based line of the opening fence
    language: str
    code: str
    excerpt_of: str | None

    @property
    def label(self) -> str:
        return f"{self.page.relative_to(ROOT)}:{self.line}"


def blocks(page: Path) -> list[Block]:
    """The fenced blocks of ``page``, in order."""
    found, lines, i = [], page.read_text(encoding="utf-8").splitlines(), 0
    while i < len(lines):
        match = FENCE.match(lines[i])
        if match is None:
            i += 1
            continue
        start, body = i, []
        i += 1
        while i < len(lines) and lines[i] != "```":
            body.append(lines[i])
            i += 1
        excerpt = EXCERPT.match(lines[start - 1]) if start > 0 else None
        found.append(Block(page, start + 1, match.group(1), "\n".join(body) + "\n",
                           excerpt.group(1) if excerpt else None))
        i += 1
    return found


ALL_BLOCKS = [block for page in PAGES for block in blocks(page)]


def test_every_block_says_what_it_is():
    """An untagged fence would escape the checks below: every block is python, bash, toml or text."""
    assert [b.label for b in ALL_BLOCKS if b.language not in LANGUAGES] == []


# ---------------------------------------------------------------------------------- python
class _Driver:
    """The robot a control-loop sketch talks to: it integrates what it is sent, for 20 ticks."""

    def __init__(self) -> None:
        self.robot = wbc.load_robot("youbot")
        self.q = np.array([0, 0, 0, 0, 0.5, 1.0, 1.2, 0.0])
        self.ticks = 0
        self.sent: list[str] = []

    def running(self) -> bool:
        self.ticks += 1
        return self.ticks <= 20

    def read_joint_positions(self) -> np.ndarray:
        return self.q.copy()

    def target_pose(self) -> np.ndarray:
        pose = self.robot.frame_pose(np.array([0, 0, 0, 0, 0.5, 1.0, 1.2, 0.0]), "ee")
        pose[:3, 3] += (0.1, 0.05, 0.0)
        return pose

    def send_wheel_speeds(self, speeds: np.ndarray) -> None:
        assert speeds.shape == (4,) and np.all(np.isfinite(speeds))
        self.sent.append("wheels")

    def send_arm_velocities(self, rates: np.ndarray) -> None:
        assert rates.shape == (5,) and np.all(np.isfinite(rates))
        self.sent.append("arm")

    def log(self, message: str) -> None:
        raise AssertionError(f"a tick of the sketch failed: {message}")


#: names a control-loop sketch leaves to the user's driver
DRIVER = ("running", "read_joint_positions", "target_pose", "send_wheel_speeds", "send_arm_velocities", "log")


@pytest.fixture
def folder(tmp_path, monkeypatch) -> Path:
    """A scratch working directory holding the clone's tasks/ and models/ (as links)."""
    for name in ("tasks", "models"):
        (tmp_path / name).symlink_to(ROOT / name, target_is_directory=True)
    monkeypatch.chdir(tmp_path)
    return tmp_path


PYTHON_PAGES = sorted({b.page for b in ALL_BLOCKS if b.language == "python"})


@pytest.mark.parametrize("page", PYTHON_PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_python_blocks_run(page, folder):
    driver = _Driver()
    namespace: dict = {"__name__": "__docs__", **{name: getattr(driver, name) for name in DRIVER}}
    for block in blocks(page):
        if block.language != "python" or block.excerpt_of is not None:
            continue
        with redirect_stdout(io.StringIO()):
            try:
                exec(compile(block.code, block.label, "exec", dont_inherit=True), namespace)  # (no __future__ of ours)
            except Exception as exc:
                raise AssertionError(f"{block.label}: {type(exc).__name__}: {exc}") from exc
    if any(name in block.code for block in blocks(page) for name in ("send_wheel_speeds(", "send_arm_velocities(")):
        assert driver.sent, f"{page.name}: the control-loop sketch never commanded the robot"


# ------------------------------------------------------------------------------------ bash
def commands(block: Block) -> Iterator[str]:
    """The command lines of a bash block (continuations joined, comment lines skipped)."""
    for line in block.code.replace("\\\n", " ").splitlines():
        if line.strip() and not line.lstrip().startswith("#"):
            yield line.strip()


def extras() -> set[str]:
    return set(tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["optional-dependencies"])


BASH = [(block, command) for block in ALL_BLOCKS if block.language == "bash" for command in commands(block)]


@pytest.mark.parametrize(("block", "command"), BASH, ids=[f"{b.label}:{c[:40]}" for b, c in BASH])
def test_bash_commands_run(block, command, folder):
    install = re.match(r"pip install (\S+) && (.*)$", command)
    if install:
        named = set(re.findall(r"\[([\w,]+)\]", install.group(1))[0].split(",")) if "[" in install.group(1) else set()
        assert named <= extras(), f"{block.label}: no extra {named - extras()} in pyproject.toml"
        command = install.group(2)
    assert not command.startswith("pip "), f"{block.label}: a bare pip command cannot run in the tests"
    if command.startswith("pytest"):  # this test suite: CI runs the README's second bash block as written
        readme_bash = [b for b in ALL_BLOCKS if b.page.name == "README.md" and b.language == "bash"]
        assert block is readme_bash[1], f"{block.label}: only the README's test command may run pytest"
        return
    environment = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}"}
    if "# until Ctrl-C" in command:
        _interrupted(block, command.split("#")[0], environment)
        return
    result = subprocess.run(["bash", "-c", command], capture_output=True, text=True, timeout=900, env=environment)
    assert result.returncode == 0, f"{block.label}: {command}\n{result.stdout[-2000:]}\n{result.stderr[-2000:]}"


def _interrupted(block: Block, command: str, environment: dict) -> None:
    process = subprocess.Popen(shlex.split(command), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                               env=environment)
    try:
        first = process.stdout.readline() or process.stderr.readline()
        assert first, f"{block.label}: {command} printed nothing"
        process.send_signal(signal.SIGINT)
        out, err = process.communicate(timeout=120)
    finally:
        process.kill()
    assert process.returncode in (0, 130) and "Traceback" not in err, f"{block.label}: {command}\n{err[-2000:]}"


# ------------------------------------------------------------------------------------ toml
SCENARIO = textwrap.dedent("""
    [robot]
    name = "youbot"
    initial_configuration = [0.0, 0.0, 0.0, 0.0, 0.5, 1.0, 1.2, 0.0]
    [controller]
    duration = 0.05
""")


@pytest.mark.parametrize("block", [b for b in ALL_BLOCKS if b.language == "toml"], ids=lambda b: b.label)
def test_toml_blocks_are_valid(block, tmp_path):
    data = tomllib.loads(block.code)
    if set(data) & {"node", "state", "joints", "controllers", "targets", "diagnostics"}:
        from wbc.ros.config import parse_config  # a configuration of `wbc ros` (docs/ros.md): its schema

        parse_config(data, block.label)
        return
    if "urdf" in data:  # a sidecar of a third-party robot (docs/ros.md: TIAGo's), loaded on the installed URDF
        from test_declared_base import tiago_urdf

        assert data["urdf"].endswith("tiago_description/robots/tiago.urdf"), f"{block.label}: which robot?"
        sidecar = tmp_path / "robot.toml"
        sidecar.write_text(block.code.replace(data["urdf"], str(tiago_urdf())))
        assert wbc.load_robot(sidecar).base.kind is wbc.BaseKind.UNICYCLE
        return
    if "base" in data:
        sidecars = [tomllib.loads((ROOT / "models" / name / f"{name}.toml").read_text())
                    for name in wbc.shipped_models()]
        assert any(sidecar.get("base") == data["base"] for sidecar in sidecars), \
            f"{block.label}: the [base] table is not that of a shipped model's sidecar"
        return
    assert set(data) <= {"tasks", "constraints", "reference"}, f"{block.label}: a fragment of what?"
    path = tmp_path / "fragment.toml"
    # a fragment of constraints alone gets a posture task (a controller needs one)
    tasks = "" if "tasks" in data else '[[tasks]]\ntype = "PostureTask"\ncost = 1e-3\n\n'
    path.write_text(SCENARIO + tasks + block.code)
    from wbc.app.scenario import load_scenario

    scenario = load_scenario(path)
    assert len(scenario.tasks) == len(data.get("tasks", [1]))


# -------------------------------------------------------------------------------- excerpts
@pytest.mark.parametrize("block", [b for b in ALL_BLOCKS if b.excerpt_of], ids=lambda b: b.label)
def test_excerpts_are_in_their_file(block):
    source = (ROOT / block.excerpt_of).read_text(encoding="utf-8")
    assert block.code.strip() in source, f"{block.label}: not an excerpt of {block.excerpt_of} (any more)"


# ------------------------------------------------------------------------- cross-references
DOTTED = re.compile(r"(?<![\w.])wbc(?:\.[A-Za-z_]\w*)+")


def resolves(name: str) -> bool:
    """Whether ``wbc.a.b.c`` names a module, or an attribute reached from the longest module prefix."""
    parts = name.split(".")
    for cut in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:cut]))
        except ImportError:
            continue
        for attribute in parts[cut:]:
            if not hasattr(obj, attribute):
                return False
            obj = getattr(obj, attribute)
        return True
    return False


def docstrings() -> Iterator[tuple[str, str]]:
    """(where, text) of every docstring of the package."""
    for path in sorted((ROOT / "wbc").rglob("*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        for node in ast.walk(tree):
            if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
                text = ast.get_docstring(node)
                if text:
                    yield f"{path.relative_to(ROOT)}:{getattr(node, 'lineno', 1)}", text


def test_every_dotted_wbc_name_in_docs_and_docstrings_exists():
    texts = [(str(page.relative_to(ROOT)), page.read_text(encoding="utf-8")) for page in PAGES]
    missing = sorted({f"{where}: {name}" for where, text in [*texts, *docstrings()]
                      for name in DOTTED.findall(text) if not resolves(name.rstrip("."))})
    assert missing == []


def test_relative_links_point_to_files_of_the_source_tree():
    """Links of README.md and docs/ to files (not to web pages) resolve in the clone and the sdist."""
    broken = []
    for page in PAGES:
        for target in re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", page.read_text(encoding="utf-8")):
            if "://" not in target and not target.startswith("mailto:") and not (page.parent / target).exists():
                broken.append(f"{page.relative_to(ROOT)}: {target}")
    assert broken == []
