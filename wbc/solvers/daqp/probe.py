"""The check that DAQP's C layouts (:mod:`wbc.solvers.daqp.abi`) hold on the installed build,
run once per process before the native path is used: :func:`native` is the checked library
(None when a check fails), :func:`unavailable_reason` says why it is off.
"""

from __future__ import annotations

import ctypes
import functools
import math

import numpy as np

from ...qp.problem import QP
from ...runtime import kernels
from .abi import Library, Problem, Result, Settings, Workspace, _load, words
from .native import NativeWorkspace


def native() -> Library | None:
    """The native DAQP path if this installation passes :func:`probe`, else None."""
    library = _load()
    if isinstance(library, str) or _probe_failure() is not None:
        return None
    return library


def unavailable_reason() -> str | None:
    """Why the native path is off (None when it is on)."""
    library = _load()
    return library if isinstance(library, str) else _probe_failure()


@functools.cache
def _probe_failure() -> str | None:
    library = _load()
    if isinstance(library, str):
        return library
    try:
        return probe(library)
    except Exception as exc:  # noqa: BLE001 -- any surprise means: do not trust the layout
        return f"the DAQP layout probe failed ({type(exc).__name__}: {exc})"


def probe(library: Library) -> str | None:
    """Check the layouts of this module on the installed DAQP; None when they hold.

    The sizes and offsets the compiled kernels assume (the ``DAQP_*`` constants of
    :mod:`wbc.runtime.kernels`) must be those of the structures here. Then it sets up
    ``min 1/2 |x|^2 - x1 - 2 x2`` s.t. ``x1 + x2 <= 1``, ``|x| <= 10`` through
    :class:`wbc.solvers.daqp.native.NativeWorkspace` and checks what ``setup_daqp`` wrote at the offsets
    of :class:`Workspace` (dimensions, problem and settings pointers) and the answer of one
    compiled solve: x = (0, 1) (the projection of (1, 2) onto the row).
    """
    layout = {"problem words": (words(Problem), kernels.DAQP_PROBLEM_WORDS),
              "workspace words": (words(Workspace), kernels.DAQP_WORKSPACE_WORDS),
              "result words": (words(Result), kernels.DAQP_RESULT_WORDS),
              "settings words": (words(Settings), kernels.DAQP_SETTINGS_WORDS),
              "settings primal_tol": (Settings.primal_tol.offset // 8, kernels.DAQP_SETTINGS_PRIMAL_TOL),
              "result exit flag": (Result.exitflag.offset // 4, kernels.DAQP_RESULT_EXITFLAG),
              "result iterations": (Result.iter.offset // 4, kernels.DAQP_RESULT_ITERATIONS),
              "problem m": (Problem.m.offset // 4, kernels.DAQP_PROBLEM_M),
              "problem A": (Problem.A.offset // 8, kernels.DAQP_PROBLEM_A),
              "problem bounds": ((Problem.bupper.offset // 8, Problem.blower.offset // 8),
                                 (kernels.DAQP_PROBLEM_A + 1, kernels.DAQP_PROBLEM_A + 2)),
              "workspace m": (Workspace.m.offset // 4, kernels.DAQP_WORKSPACE_M),
              "workspace sense": (Workspace.sense.offset // 8, kernels.DAQP_WORKSPACE_SENSE)}
    for name, (here, compiled) in layout.items():
        if here != compiled:  # a constant of wbc.runtime.kernels out of step with the layouts above
            return f"the compiled kernels assume {name} = {compiled}, the DAQP layout has {here}"
    qp = QP(2, 1, 0)
    qp.H[...] = np.eye(2)
    qp.c[...] = (-1.0, -2.0)
    qp.C[0] = (1.0, 1.0)
    qp.upper[...] = (10.0, 10.0, 1.0)
    qp.lower[:2] = -10.0
    workspace = NativeWorkspace(library, qp, {}, warm_start=True)
    work, problem = workspace.work, workspace.problem
    if (work.n, work.m, work.ms) != (2, 3, 2):
        return f"setup_daqp wrote dimensions {(work.n, work.m, work.ms)} where (2, 3, 2) was expected"
    if work.qp != ctypes.addressof(problem) or work.settings != ctypes.addressof(workspace.settings):
        return "setup_daqp's problem / settings pointers are not where the layout expects them"
    if not work.sense:
        return "setup_daqp left the constraint states unallocated"
    exitflag, _, _ = workspace.solve()
    x = workspace.x
    if exitflag != 1 or not (math.isclose(x[0], 0.0, abs_tol=1e-12) and math.isclose(x[1], 1.0, abs_tol=1e-12)):
        return f"the compiled solve of the probe returned exit flag {exitflag}, x = {x.tolist()} (expected 1, [0, 1])"
    return None
