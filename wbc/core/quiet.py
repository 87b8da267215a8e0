"""Output of native code kept off the terminal, at the file-descriptor level.

QP backends are C/C++ libraries; some print from C whatever their ``verbose`` setting
(highspy 1.16 prints a two-line banner on **stdout** the first time a ``Highs`` object is
created in a process). A Python-level redirect (``contextlib.redirect_stdout``) cannot stop
that: the C library writes to file descriptor 1 directly. :func:`silenced` points fds 1 and
2 at ``/dev/null`` for the duration of a block, flushing C's stdio buffers before it
restores them, so that buffered output is discarded too rather than printed later.

wbc runs every backend's first-use code under :func:`silenced` when the backend is built
(:func:`wbc.solvers.make_solver`), so a banner, whenever a release adds one, is swallowed
there and never reaches a tick (``wbc run --json`` keeps stdout for the JSON alone).
"""

from __future__ import annotations

import ctypes
import os
import sys
import threading
from collections.abc import Iterator
from contextlib import contextmanager

_LOCK = threading.RLock()  # the fds are process-wide: one redirect at a time
_LIBC: ctypes.CDLL | None | bool = False  # False: not looked up yet


def _flush_c_streams() -> None:
    """``fflush(NULL)``: write out every C stdio buffer now (while the redirect holds)."""
    global _LIBC
    if _LIBC is False:
        try:
            _LIBC = ctypes.CDLL(None)
            _LIBC.fflush.argtypes = [ctypes.c_void_p]
        except (OSError, AttributeError, TypeError):  # TypeError: no CDLL(None) (Windows)
            _LIBC = None
    if isinstance(_LIBC, ctypes.CDLL):
        _LIBC.fflush(None)


@contextmanager
def silenced() -> Iterator[None]:
    """Discard everything written to file descriptors 1 and 2 inside the block, by Python or
    by native code. Not for the control loop's hot path: it costs a few system calls and
    holds a process-wide lock (another thread printing meanwhile is silenced too)."""
    with _LOCK:
        for stream in (sys.stdout, sys.stderr):
            if stream is not None:
                stream.flush()
        saved = [os.dup(1), os.dup(2)]
        devnull = os.open(os.devnull, os.O_WRONLY)
        try:
            os.dup2(devnull, 1)
            os.dup2(devnull, 2)
            yield
        finally:
            for stream in (sys.stdout, sys.stderr):
                if stream is not None:
                    try:
                        stream.flush()
                    except (OSError, ValueError):  # a stream closed inside the block
                        pass
            _flush_c_streams()
            os.dup2(saved[0], 1)
            os.dup2(saved[1], 2)
            for fd in (*saved, devnull):
                os.close(fd)
