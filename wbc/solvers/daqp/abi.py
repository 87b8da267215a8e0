"""DAQP's C interface as wbc calls it: the structures of ``types.h`` / ``api.h``, the entry
points (:mod:`wbc.solvers.daqp.probe` checks them on the installed build).

The ``daqp`` extension module exports DAQP's C functions (``setup_daqp``,
``daqp_update_ldp``, ``daqp_solve``, ...). Calling them from compiled code (one native
call per tick, :mod:`wbc.runtime.kernels.native_qp`) needs their structure layouts, which this
module writes down from DAQP 0.11's headers (``csrc/include/types.h``, ``api.h``,
``constants.h``). A layout is an ABI promise of one release, so it is *checked, not
trusted*: :func:`~wbc.solvers.daqp.probe.native` runs :func:`~wbc.solvers.daqp.probe.probe` once
per process -- the installed version must be one of :data:`SUPPORTED_VERSIONS`, and a set-up probe problem must show its
dimensions, problem pointer and settings pointer at the offsets written here and solve to
its known answer through the compiled path. When anything differs, the native path is off
(:func:`~wbc.solvers.daqp.probe.native` returns None, :func:`~wbc.solvers.daqp.probe.unavailable_reason`
says why) and
:class:`wbc.solvers.DaqpBackend` uses DAQP's Python binding instead.

The structures live in memory wbc owns (numpy arrays, see :func:`struct_in`), so the
compiled code reads and writes only buffers that outlive it.
"""

from __future__ import annotations

import ctypes
import functools
import importlib.metadata
import time
from typing import TYPE_CHECKING, NamedTuple, TypeVar

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:  # pragma: no cover
    from _ctypes import CFuncPtr

_Structure = TypeVar("_Structure", bound=ctypes.Structure)

#: DAQP releases whose C layout is the one written here (checked by :func:`wbc.solvers.daqp.probe.probe` too)
SUPPORTED_VERSIONS = ("0.11.",)

_int, _double, _ptr = ctypes.c_int, ctypes.c_double, ctypes.c_void_p


class Problem(ctypes.Structure):
    """``DAQPProblem``: min 1/2 x'Hx + f'x, blower <= [x; A x] <= bupper (``ms`` simple bounds)."""

    _fields_ = [("n", _int), ("m", _int), ("ms", _int), ("H", _ptr), ("f", _ptr), ("A", _ptr),
                ("bupper", _ptr), ("blower", _ptr), ("sense", _ptr), ("break_points", _ptr), ("nh", _int),
                ("problem_type", _int)]


class Settings(ctypes.Structure):
    """``DAQPSettings`` (field names are the keys of ``daqp.Model().settings``)."""

    _fields_ = [("primal_tol", _double), ("dual_tol", _double), ("zero_tol", _double), ("pivot_tol", _double),
                ("progress_tol", _double), ("cycle_tol", _int), ("iter_limit", _int), ("fval_bound", _double),
                ("eps_prox", _double), ("eta_prox", _double), ("rho_soft", _double), ("rel_subopt", _double),
                ("abs_subopt", _double), ("sing_tol", _double), ("refactor_tol", _double), ("time_limit", _double),
                ("w_soft", _double), ("eq_reduction", _int), ("presolve", _int)]


class Result(ctypes.Structure):
    """``DAQPResult``: where ``daqp_solve`` writes x, the multipliers and the exit flag."""

    _fields_ = [("x", _ptr), ("lam", _ptr), ("fval", _double), ("soft_slack", _double), ("exitflag", _int),
                ("iter", _int), ("nodes", _int), ("solve_time", _double), ("setup_time", _double)]


class Workspace(ctypes.Structure):
    """``DAQPWorkspace``, whole (wbc reads ``qp``, ``n``, ``m``, ``ms``, ``sense``, ``settings``;
    the rest is written down for the size; DAQP allocates what the pointers point to)."""

    _fields_ = [("qp", _ptr), ("n", _int), ("m", _int), ("ms", _int), ("M", _ptr), ("dupper", _ptr),
                ("dlower", _ptr), ("Rinv", _ptr), ("v", _ptr), ("sense", _ptr), ("scaling", _ptr), ("RinvD", _ptr),
                ("x", _ptr), ("xold", _ptr), ("lam", _ptr), ("lam_star", _ptr), ("u", _ptr), ("fval", _double),
                ("L", _ptr), ("D", _ptr), ("xldl", _ptr), ("zldl", _ptr), ("reuse_ind", _int), ("WS", _ptr),
                ("n_active", _int), ("iterations", _int), ("sing_ind", _int), ("prox_mask", _ptr), ("n_prox", _int),
                ("soft_slack", _double), ("settings", _ptr), ("bnb", _ptr), ("outer_iter", _int), ("hierarchy", _ptr),
                ("avi", _ptr), ("eq", _ptr), ("timer", _ptr), ("Mu", _ptr), ("rho_ls", _ptr), ("rho_us", _ptr),
                ("w_ls", _ptr), ("w_us", _ptr), ("state", _int)]


# constants.h: what daqp_update_ldp re-forms, and the constraint states
UPDATE_RINV, UPDATE_M, UPDATE_V, UPDATE_D, UPDATE_SENSE = 1, 2, 4, 8, 16
#: a warm tick: H and A changed (R^-1, then M = A R^-1, v and d follow); the working set is kept.
#: UPDATE_M also restores the state of a row that was zero when DAQP last saw it (DAQP marks it
#: immutable and ignores it until an update with UPDATE_M: without it, the row, nonzero again,
#: would stay ignored)
WARM_UPDATE = UPDATE_RINV | UPDATE_M | UPDATE_SENSE
#: a cold tick: everything re-formed from the problem's sense array
COLD_UPDATE = UPDATE_RINV | UPDATE_M | UPDATE_V | UPDATE_D | UPDATE_SENSE
SENSE_EQUALITY = 5  # DAQP_ACTIVE | DAQP_IMMUTABLE

EXIT_FLAGS = {-1: "infeasible", -2: "cycling detected", -3: "unbounded", -4: "iteration limit", -5: "nonconvex",
              -6: "initial point infeasible", -7: "time limit", -8: "unsupported problem", 2: "soft optimal"}


def words(structure: type[ctypes.Structure]) -> int:
    """float64 words that hold one ``structure``."""
    return -(-ctypes.sizeof(structure) // 8)


def struct_in(buffer: NDArray[np.float64], structure: type[_Structure]) -> _Structure:
    """``structure`` laid over the float64 array ``buffer`` (which the result keeps alive)."""
    # numpy's stubs give ndarray the buffer protocol (__buffer__) on Python >= 3.12 only
    return structure.from_buffer(buffer)  # type: ignore[arg-type]


class Entry(NamedTuple):
    """Addresses of the C functions the compiled path calls, and the clock it times with."""

    update_ldp: int  #: int daqp_update_ldp(int mask, DAQPWorkspace*, DAQPProblem*)
    solve: int  #: void daqp_solve(DAQPResult*, DAQPWorkspace*)
    clock_gettime: int  #: int clock_gettime(clockid_t, struct timespec*) (libc)
    clock_id: int  #: CLOCK_MONOTONIC, the clock of time.perf_counter


class Library(NamedTuple):
    """The loaded ``daqp`` extension (ctypes) and its entry points."""

    lib: ctypes.CDLL
    entry: Entry


def _address(function: CFuncPtr) -> int:
    address = ctypes.cast(function, ctypes.c_void_p).value
    assert address is not None, f"{function} is NULL"  # ctypes resolves exported symbols only
    return address


@functools.cache
def _load() -> Library | str:
    """The library, or the reason it cannot be used natively."""
    try:
        version = importlib.metadata.version("daqp")
    except importlib.metadata.PackageNotFoundError:
        return "the daqp package is not installed"
    if not version.startswith(SUPPORTED_VERSIONS):
        known = ", ".join(release + "*" for release in SUPPORTED_VERSIONS)
        return f"daqp {version} is not a release whose C layout wbc knows ({known}); DAQP's Python binding is used"
    import daqp

    clock = getattr(time, "CLOCK_MONOTONIC", None)
    try:
        lib = ctypes.CDLL(daqp.__file__)
        libc = ctypes.CDLL(None)
        for name in ("setup_daqp", "daqp_update_ldp", "daqp_solve", "daqp_default_settings", "free_daqp_workspace",
                     "free_daqp_ldp"):
            getattr(lib, name)
        gettime = libc.clock_gettime
    except (OSError, AttributeError, TypeError) as exc:  # TypeError: no ctypes.CDLL(None) (Windows)
        return f"daqp's C entry points or libc's clock_gettime are not reachable ({exc})"
    if clock is None:
        return "this platform has no CLOCK_MONOTONIC"
    lib.setup_daqp.argtypes = [_ptr, _ptr, _ptr]
    lib.setup_daqp.restype = _int
    lib.daqp_default_settings.argtypes = [_ptr]
    lib.free_daqp_workspace.argtypes = [_ptr]
    lib.free_daqp_ldp.argtypes = [_ptr]
    entry = Entry(_address(lib.daqp_update_ldp), _address(lib.daqp_solve), _address(gettime), int(clock))
    return Library(lib, entry)
