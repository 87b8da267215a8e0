"""QP backends behind one interface: ``QPSolver.solve(qp) -> QPSolution``.

Every solver that qpsolvers finds installed works by name through
:class:`~wbc.solvers.qpsolvers_backend.QpsolversBackend`. ``"daqp"`` additionally has a direct
backend (:mod:`wbc.solvers.daqp`) that hands the preallocated buffers of
:class:`~wbc.qp.problem.QP` to DAQP without any copy.

* :mod:`wbc.solvers.solver` -- the interface and the default settings;
* :mod:`wbc.solvers.options` -- the checks of each backend's options;
* :mod:`wbc.solvers.qpsolvers_backend` -- any backend through qpsolvers;
* :mod:`wbc.solvers.daqp` -- DAQP: its C layouts, their check, the native workspace, the backend.

:func:`make_solver` builds a backend by name; the names below are this package's interface.
"""

from __future__ import annotations

import importlib
from typing import Any

from ..core.errors import UnknownSolverError
from .daqp.backend import DaqpBackend
from .qpsolvers_backend import QpsolversBackend
from .solver import DEFAULT_SETTINGS, WARM_START_SOLVERS, QPSolution, QPSolver

__all__ = ["DEFAULT_SETTINGS", "WARM_START_SOLVERS", "DaqpBackend", "QPSolution", "QPSolver", "QpsolversBackend",
           "available_solvers", "make_solver"]


def available_solvers() -> list[str]:
    """Names of the QP solvers qpsolvers finds installed (qpsolvers is imported on the first call:
    ~0.06 s that ``import wbc`` and a DAQP controller do not pay)."""
    import qpsolvers

    return list(qpsolvers.available_solvers)


def make_solver(name: str, options: dict[str, Any] | None = None) -> QPSolver:
    """Backend for ``name``: the direct DAQP backend for ``"daqp"``, qpsolvers otherwise.

    ``options`` are checked by the backend's constructor
    (:func:`wbc.solvers.options.validate_options`).

    Raises:
        UnknownSolverError: ``name`` is not a solver qpsolvers finds installed.
        InvalidSolverOptionError: an unknown key or a bad value in ``options``.
    """
    if name == "daqp" and _imports("daqp"):
        return DaqpBackend(options)  # (without qpsolvers, which would import daqp to list it)
    if not isinstance(name, str) or name not in available_solvers():
        raise UnknownSolverError(
            f"unknown or uninstalled QP solver {name!r}; installed: {', '.join(available_solvers())}"
        )
    return QpsolversBackend(name, options)


def _imports(module: str) -> bool:
    """Whether ``module`` imports (a package that is there but broken, e.g. its shared library
    missing, does not: as qpsolvers, which then does not list it)."""
    try:
        importlib.import_module(module)
    except ImportError:
        return False
    return True
