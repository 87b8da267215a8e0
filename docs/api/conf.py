"""Sphinx configuration of wbc's API reference, built from the docstrings.

Build it (warnings are errors, as in the test suite, ``tests/test_api_reference.py``)::

    pip install ".[test]"
    sphinx-build -W --keep-going -b html docs/api docs/api/_build

Every cross-reference to a wbc name must resolve (``nitpicky``). A name may be written under
any path it can be imported from (``wbc.Controller``, ``wbc.tasks.FrameTask``): the objects
are documented once, in the module that defines them, and :func:`resolve_reexported` sends a
reference through a re-export to that definition.
"""

from __future__ import annotations

import importlib
import inspect
import pkgutil
import re
import sys
from pathlib import Path
from typing import Any

from docutils import nodes
from numpy.typing import ArrayLike
from sphinx.addnodes import pending_xref
from sphinx.application import Sphinx
from sphinx.environment import BuildEnvironment
from sphinx.ext.napoleon import _process_docstring as _napoleon_process_docstring
from sphinx.util.typing import stringify_annotation

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))  # the source tree's wbc (the installed one, when it is installed editable)

import wbc  # noqa: E402 -- after the path

# Every module imported before autodoc reads any: documenting a pydantic model (wbc.core.schema.Table)
# rewrites its __annotations__, after which the models that subclass it could not be built.
for _module in pkgutil.walk_packages(wbc.__path__, "wbc."):
    if not _module.name.endswith("__main__"):  # (python -m wbc: running it is the command)
        importlib.import_module(_module.name)
# The compiled kernels are numba dispatchers, which autodoc does not read as functions: the
# documentation sees their Python functions (this process never runs a kernel).
wbc.runtime.kernels.load()
_python_functions = {id(getattr(wbc.runtime.kernels, name)): getattr(wbc.runtime.kernels, name).py_func
                     for names in wbc.runtime.kernels.COMPILED.values() for name in names}
for _module in [module for name, module in sys.modules.items() if name.startswith("wbc.runtime.kernels")]:
    for _name, _value in list(vars(_module).items()):
        if id(_value) in _python_functions:
            setattr(_module, _name, _python_functions[id(_value)])

project = "wbc"
release = version = wbc.__version__
extensions = ["sphinx.ext.autodoc", "sphinx.ext.autosummary", "sphinx.ext.napoleon"]
autosummary_generate = False  # the summary tables link to the module pages; no generated files
nitpicky = True
#: targets outside wbc (no network at build time, so no intersphinx): shown as text, never resolved
nitpick_ignore_regex = [
    (r"py:.*", r"(numpy|np|pinocchio|pin|coal|pydantic|pydantic_core|qpsolvers|numba|ctypes|_ctypes|collections|abc"
               r"|numbers|threading|pathlib|concurrent|multiprocessing|matplotlib|mujoco|viser|argparse|enum|types|functools"
               r"|json|io|os|annotated_types|cyclonedds)(\..*)?"),
    (r"py:.*", r"(NDArray|ArrayLike|Path|Enum|Generator|Iterator|Iterable|Sequence|Mapping|Callable|Buffer|Figure"
               r"|Number|NoneType|FieldInfo|MinLen|MaxLen|Gt|Ge"
               r"|sequence|array|float64|uint8|bounded_str)"),  # (cyclonedds' IDL types of wbc.ros.messages)
    # private names (type variables, helpers) in signatures and text: not part of the reference
    (r"py:.*", r"(.*\.)?_[A-Za-z]\w*"),
]
autodoc_default_options = {"members": True, "show-inheritance": True, "member-order": "bysource",
                           "ignore-module-all": True}  # each object once, where it is defined
autodoc_typehints = "signature"
autodoc_class_signature = "separated"
napoleon_google_docstring = True
napoleon_numpy_docstring = False
napoleon_use_rtype = False
html_theme = "alabaster"
exclude_patterns = ["_build"]


def canonical_name(target: str) -> str | None:
    """``target`` (a dotted wbc name, through any re-export) as the name of its definition: the
    defining module and qualified name of the first class, function or module on its path,
    then the remaining attributes. None when the name does not import."""
    parts = target.split(".")
    for split in range(len(parts), 0, -1):
        try:
            obj: Any = importlib.import_module(".".join(parts[:split]))
        except ImportError:
            continue
        prefix, rest = obj.__name__, []
        for part in parts[split:]:  # (a slot of a class: its member descriptor)
            if not hasattr(obj, part) and not (inspect.isclass(obj) and part in getattr(obj, "__slots__", ())):
                return None
            obj = getattr(obj, part, None)
            if inspect.isclass(obj) or inspect.isfunction(obj) or inspect.ismodule(obj):
                prefix, rest = (obj.__name__ if inspect.ismodule(obj) else f"{obj.__module__}.{obj.__qualname__}"), []
            else:
                rest.append(part)
        return ".".join([prefix, *rest])
    return None


def resolve_reexported(app: Sphinx, env: BuildEnvironment, node: pending_xref,
                       contnode: nodes.TextElement) -> nodes.Element | None:
    """A reference to a wbc name through a re-export (``wbc.Controller``), or a name the current
    module imports: resolved to the documented definition."""
    if node.get("refdomain") != "py":
        return None
    target = node["reftarget"]
    candidates = [target]
    module, cls = node.get("py:module"), node.get("py:class")
    if module and cls:
        candidates.append(f"{module}.{cls}.{target}")  # a member the current class inherits
    if module:
        candidates.append(f"{module}.{target}")  # a name imported by the current module
    domain = env.get_domain("py")
    for candidate in candidates:
        if not candidate.startswith("wbc"):
            continue
        canonical = canonical_name(candidate)
        if canonical is None or canonical == target:
            continue
        resolved = node.deepcopy()
        resolved["reftarget"] = canonical
        found = domain.resolve_xref(env, node.get("refdoc", ""), app.builder, node["reftype"], canonical,
                                    resolved, contnode)
        if found is None:
            found = domain.resolve_any_xref(env, node.get("refdoc", ""), app.builder, canonical, resolved, contnode)
            found = found[0][1] if found else None
        if found is not None:
            return found
    # a bare name (an annotation imported for type checking only, a class named in a docstring):
    # the one documented object of that name, if it is unique
    matches = [name for name, entry in domain.objects.items()
               if name.endswith(f".{target}") and not entry.aliased and name.startswith("wbc.")]
    if len(matches) == 1:
        resolved = node.deepcopy()
        resolved["reftarget"] = matches[0]
        return domain.resolve_xref(env, node.get("refdoc", ""), app.builder, node["reftype"], matches[0], resolved,
                                   contnode)
    return None


def napoleon_except_attributes(app: Sphinx, what: str, name: str, obj: object, options: Any,
                               lines: list[str]) -> None:
    """Napoleon (Google-style sections: Args, Returns, Raises), except on attributes and data:
    their ``#:`` comments are plain text, which napoleon would read as ``type: description``
    (a property's docstring is read like a method's, sections included)."""
    if what not in ("attribute", "data"):
        _napoleon_process_docstring(app, "method" if what == "property" else what, name, obj, options, lines)


#: numpy's array aliases as autodoc expands them (ArrayLike: a union of eight private types)
_EXPANDED_ARRAY_LIKE = [stringify_annotation(ArrayLike, mode) for mode in ("smart", "fully-qualified-except-typing")]
_EXPANDED_NDARRAY = re.compile(r"~?numpy\.ndarray\[tuple\[[^\]]*\], ~?numpy\.dtype\[([^\]]+)\]\]")


def signature_as_written(app: Sphinx, what: str, name: str, obj: object, options: Any, signature: str | None,
                         return_annotation: str | None) -> tuple[str | None, str | None]:
    """Signatures closer to the source: ``ArrayLike`` and ``NDArray[...]`` as written (autodoc
    expands them); a default whose repr is not Python (a dataclass field's ``<factory>``, an
    enum member ``<BaseKind.FIXED: 'fixed'>``, ``<built-in function perf_counter>``), which would
    make Sphinx render the whole signature as plain text, as ``...``."""
    def written(text: str | None) -> str | None:
        if text is None:
            return None
        for expanded in _EXPANDED_ARRAY_LIKE:
            text = text.replace(expanded, "~numpy.typing.ArrayLike")
        text = _EXPANDED_NDARRAY.sub(r"~numpy.typing.NDArray[\1]", text)
        return re.sub(r"<[^<>]*>", "...", text)

    return written(signature), written(return_annotation)


def skip_pydantic_machinery(app: Sphinx, what: str, name: str, obj: object, skip: bool, options: Any) -> bool | None:
    """The TOML schemas are pydantic models: their ``model_*`` class attributes (configuration,
    computed fields; which of them autodoc finds depends on the pydantic release) are pydantic's."""
    if what == "class" and name.startswith("model_"):
        return True
    return None


def setup(app: Sphinx) -> None:
    app.connect("autodoc-skip-member", skip_pydantic_machinery)
    app.connect("missing-reference", resolve_reexported)
    app.connect("autodoc-process-signature", signature_as_written)
    # napoleon's own handler, replaced by the one above
    for listener in list(app.events.listeners["autodoc-process-docstring"]):
        if listener.handler is _napoleon_process_docstring:
            app.disconnect(listener.id)
    app.connect("autodoc-process-docstring", napoleon_except_attributes)
