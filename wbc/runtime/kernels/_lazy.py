"""Kernels compiled when they are first handed out, for the one signature they declare.

A kernel module compiles nothing when it is imported: ``@declared(signature, ...)`` is numba's
``@njit(...)`` with ``signature`` (the argument types its Python callers pass) kept for
:func:`compile_declared`, which :mod:`wbc.runtime.kernels` calls when the kernel is fetched
(``kernels.<name>``) -- by the objects a controller builds, never in a tick. Compiled, the kernel
is frozen to its signature as an ``@njit(signature)`` kernel is: a call with C-contiguous or
transposed arrays converts to it instead of compiling again. A kernel called only by other
kernels (an op's, through its callback) is compiled for their argument types when they are.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from numba import njit

#: the attribute of a declared kernel's dispatcher holding its signature
SIGNATURE = "wbc_signature"

#: options of a kernel that Python calls on the control loop's path (``Controller.step``'s program,
#: ``set_target``, ``robot.integrate``, AccelerationLimits' bounds): compiled without numba's
#: reference-counted runtime (its internal option ``_nrt``), an array argument enters without a
#: meminfo of its own -- a malloc and a free, ~20 ns per array (a 2-array call 113 -> 70 ns; the
#: user's loop 2.38-2.46 -> 2.08-2.12 us, session 24, benchmarks/README.md section 3). Such a kernel
#: only reads and writes the arrays it is given, for the call: numba refuses to compile one that
#: makes an array (``carray`` and ``a[:] = b`` too: index the pointer, write the loop). Its callees
#: must not return a new array either (a caller without the runtime would never free it): the
#: declared kernels return numbers only.
ENTRY = {"_nrt": False}


def _nothing_before(dispatcher: Any) -> None:
    """The default :data:`before_compile`."""


#: called with a declared kernel's dispatcher before it compiles (the compile workers of a first
#: start: wait while a worker compiles it into the cache, see :mod:`._pool`)
before_compile: Callable[[Any], None] = _nothing_before


def declared(signature: Any, **options: Any) -> Callable[[Callable[..., Any]], Any]:
    """``@njit(**options)``, compiled for ``signature`` (a numba signature or its string) by
    :func:`compile_declared` (not at import)."""
    def decorate(function: Callable[..., Any]) -> Any:
        dispatcher = njit(**options)(function)
        setattr(dispatcher, SIGNATURE, signature)
        return dispatcher

    return decorate


def compile_declared(dispatcher: Any, seen: set[int] | None = None) -> None:
    """Compile ``dispatcher`` (a :func:`declared` kernel) for its signature -- read from numba's
    cache after the first time -- and allow no other signature (calls convert to it); once. The
    declared kernels it calls are compiled first (:func:`compile_callees`)."""
    compile_callees(dispatcher, seen)
    signature = getattr(dispatcher, SIGNATURE, None)
    if signature is not None:
        before_compile(dispatcher)
        if getattr(dispatcher, SIGNATURE, None) is None:  # compiled meanwhile (a job compiled while waiting)
            return
        dispatcher.compile(signature)
        dispatcher.disable_compile()
        setattr(dispatcher, SIGNATURE, None)


def compile_callees(function: Any, seen: set[int] | None = None) -> None:
    """:func:`compile_declared` for every declared kernel that ``function`` (a numba or Python
    function) calls, directly or through other numba functions, callees first: a kernel calling
    them is then compiled against their declared signatures, as when they compiled at import."""
    seen = set() if seen is None else seen
    code = getattr(function, "py_func", function)
    for name in getattr(getattr(code, "__code__", None), "co_names", ()):
        callee = getattr(code, "__globals__", {}).get(name)
        if hasattr(callee, "py_func") and id(callee) not in seen:
            seen.add(id(callee))
            compile_declared(callee, seen)


def compile_named(module: Any, *names: str) -> None:
    """:func:`compile_declared` for the declared kernels ``names`` of ``module`` -- a kernel module
    outside :mod:`wbc.runtime.kernels` (:mod:`wbc.collision.kernels`), whose objects call it when
    they are built, or when a controller built on them will call the kernels in Python."""
    for name in names:
        compile_declared(getattr(module, name))
