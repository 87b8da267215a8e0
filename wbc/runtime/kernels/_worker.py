"""A compile worker of :mod:`wbc.runtime.kernels._pool` (started by its ``BOOTSTRAP``, which skips
``wbc/__init__.py``; ``python -m wbc.runtime.kernels._worker`` runs one too)."""

from __future__ import annotations

import sys

from wbc.runtime import kernels
from wbc.runtime.kernels._pool import READY


def run_worker() -> None:
    """A worker's loop: compile each job read from stdin into numba's cache, answer on stdout."""
    kernels.load()
    print(READY, flush=True)
    for line in sys.stdin:
        job = line.strip()
        try:
            kernels._compile_job(job)
            answer = f"ok {job}"
        except Exception:  # noqa: BLE001 - the job is compiled in the controller's process instead
            answer = f"failed {job}"
        print(answer, flush=True)


if __name__ == "__main__":
    run_worker()
