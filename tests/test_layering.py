"""The package's layers: every import of a wbc module (module-level or inside a function,
read from the source with ``ast``) points to its own layer or a lower one, and no two modules
import each other, directly or through others. A new module joins a layer by its folder."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

#: lowest first; a module belongs to the last entry that is it or one of its packages
LAYERS: list[tuple[str, ...]] = [
    ("wbc.runtime",),
    ("wbc.core",),
    ("wbc.model",),
    ("wbc.item", "wbc.tasks", "wbc.constraints", "wbc.collision"),
    ("wbc.qp",),
    ("wbc.solvers",),
    ("wbc.control",),
    ("wbc.analysis",),
    ("wbc.trajectory",),
    ("wbc.app", "wbc.ros"),
    ("wbc", "wbc.__main__"),  # the public namespace and ``python -m wbc``: above everything
]

#: imports that point up, each with its reason
ALLOWED_UPWARD = {
    ("wbc.app.cli", "wbc"): "wbc.__version__, the one version string (pyproject reads it there)",
}


def module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


MODULES = {module_name(path): path for path in sorted((ROOT / "wbc").rglob("*.py"))}


def imports(name: str) -> set[str]:
    """The wbc modules ``name`` imports (a package when the name imported from it is not a module)."""
    path = MODULES[name]
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            found |= {alias.name for alias in node.names if alias.name.split(".")[0] == "wbc"}
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = ".".join(package.split(".")[: len(package.split(".")) - node.level + 1])
                target = f"{base}.{node.module}" if node.module else base
            else:
                target = node.module or ""
            if target.split(".")[0] != "wbc":
                continue
            submodules = {f"{target}.{alias.name}" for alias in node.names} & MODULES.keys()
            found |= submodules or {target}
    return found - {name}


GRAPH = {name: imports(name) for name in MODULES}


def layer(name: str) -> int:
    """Index in LAYERS of ``name``'s layer (-1: none)."""
    return max((index for index, prefixes in enumerate(LAYERS) for prefix in prefixes
                if name == prefix or (prefix != "wbc" and name.startswith(prefix + "."))), default=-1)


def test_every_module_has_a_layer():
    assert "wbc.core.errors" in MODULES and "wbc.control.controller" in MODULES  # (the walk found the package)
    assert [name for name in MODULES if layer(name) < 0] == [], "modules in no layer: add their folder to LAYERS"


def test_imports_only_point_down():
    upward = sorted(f"{name} -> {target}" for name, targets in GRAPH.items() for target in targets
                    if layer(target) > layer(name) and (name, target) not in ALLOWED_UPWARD)
    assert upward == []


def test_the_allowed_upward_imports_are_still_there():
    """An exception that is no longer needed is removed from ALLOWED_UPWARD."""
    assert [pair for pair in ALLOWED_UPWARD if pair[1] not in GRAPH[pair[0]]] == []


def strongly_connected(graph: dict[str, set[str]]) -> list[list[str]]:
    """Tarjan's strongly connected components with more than one module (the import circles)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    circles: list[list[str]] = []

    def visit(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        for target in graph.get(node, ()):
            if target not in index:
                visit(target)
                low[node] = min(low[node], low[target])
            elif target in stack:
                low[node] = min(low[node], index[target])
        if low[node] == index[node]:
            component = []
            while True:
                member = stack.pop()
                component.append(member)
                if member == node:
                    break
            if len(component) > 1:
                circles.append(sorted(component))

    for node in sorted(graph):
        if node not in index:
            visit(node)
    return circles


def test_no_import_circles():
    assert strongly_connected(GRAPH) == []


@pytest.mark.parametrize("graph, circles", [
    ({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}, [["a", "b", "c"]]),
    ({"a": {"b"}, "b": set(), "c": {"a", "b"}}, []),
])
def test_the_circle_finder_finds_circles(graph, circles):
    assert strongly_connected(graph) == circles


def test_the_import_reader_sees_function_level_and_relative_imports():
    source = MODULES["wbc.control.hierarchy"].read_text()
    assert "    from ..solvers.daqp import abi as daqp_abi" in source  # inside a function only
    assert "wbc.solvers.daqp.abi" in GRAPH["wbc.control.hierarchy"]
    assert "wbc.solvers.daqp.abi" in GRAPH["wbc.solvers.daqp.native"]  # from . import abi as daqp_abi
    assert "wbc.control.tick_buffers" in GRAPH["wbc.control.diagnostics"]  # from .tick_buffers import ...


def test_tests_import_their_helpers_as_the_folders_modules():
    """``from tests.x import ...`` resolves only once another test put the checkout on sys.path:
    a run of one file (or a plain ``pytest`` collecting it first) fails at import."""
    folder = Path(__file__).resolve().parent
    offenders = [f"{path.name}:{number}" for path in sorted(folder.glob("*.py"))
                 for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), start=1)
                 if line.lstrip().startswith(("from tests.", "import tests."))]
    assert offenders == []
