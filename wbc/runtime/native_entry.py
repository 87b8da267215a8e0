"""Calling compiled functions without numba's argument dispatch, on the control loop's path.

Calling an ``@njit`` function from Python goes through its dispatcher, which types every
argument and looks the types up among the compiled signatures before it calls the compiled
entry (~0.03-0.04 us per argument, ~0.07 us for two arrays and a float). A caller that has
checked its arguments itself can call the compiled entry directly. The entry itself gives each
array argument a meminfo of numba's runtime (a malloc and a free, ~20 ns per array) unless the
kernel is compiled without it (:data:`wbc.runtime.kernels._lazy.ENTRY`, as the control loop's are).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np


def unchecked_entry(function: Any) -> Callable[..., Any]:
    """The compiled entry of ``function`` (an ``@njit`` dispatcher compiled for exactly one
    signature), called without the dispatcher's type check; the dispatcher itself when it has
    no such entry (another numba, or not compiled yet).

    The entry converts each argument as its signature says and checks only what that
    conversion needs: an array argument must be an ndarray, but its dtype is checked only by
    its item size and **its number of dimensions not at all** (numba's ``NRT_adapt_ndarray_from_python``
    copies as many shape entries as the array has). The caller must therefore pass arrays of
    the signature's dtype and dimensions -- checked by the caller, or its own buffers -- and
    layouts the signature accepts (a C-contiguous signature reads a strided array wrongly).
    """
    signatures: Any = getattr(function, "signatures", ())
    if len(signatures) != 1:
        return function
    entry = getattr(function.overloads.get(signatures[0]), "entry_point", None)
    return function if entry is None else entry


def fits_signature(function: Any, arguments: tuple[Any, ...]) -> bool:
    """Whether ``arguments`` are exactly what the one compiled signature of ``function`` takes
    when they are all arrays: each an ndarray of its dtype and dimensions, C-contiguous where the
    signature says so -- what :func:`unchecked_entry`'s callers must ensure. False when
    ``function`` has not exactly one signature, or an argument is not an array."""
    signatures: Any = getattr(function, "signatures", ())
    if len(signatures) != 1 or len(signatures[0]) != len(arguments):
        return False
    for argument, kind in zip(arguments, signatures[0], strict=True):
        if not (isinstance(argument, np.ndarray) and hasattr(kind, "ndim") and argument.ndim == kind.ndim
                and argument.dtype == np.dtype(str(kind.dtype))
                and (kind.layout != "C" or argument.flags.c_contiguous)):
            return False
    return True
