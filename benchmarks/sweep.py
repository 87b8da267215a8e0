"""Where the work units of a sweep run: here, one after another, or on a Dask cluster.

    with executor() as run:                              # here (Dask not needed)
    with executor(workers=2) as run:                     # a LocalCluster: 2 worker processes, 1 thread each
    with executor(scheduler="tcp://host:8786") as run:   # an existing Dask cluster
        results = run(function, items, labels)           # results in the items' order, whoever finished first

Dask (``distributed``, the ``[distributed]`` extra) is imported only for a cluster. Before anything
is submitted, every worker must report the versions this process has (:data:`VERSIONED`, the QP
backends, Python, and this checkout's ``benchmarks/`` code, which is shipped to the workers as a zip:
no shared filesystem needed); a mismatch, an unreachable scheduler, a failed or lost work unit stop
the sweep with a :class:`SweepError` naming the cause and the fix. Why Dask and not Ray:
benchmarks/README.md, section 2.
"""

from __future__ import annotations

import hashlib
import importlib.resources
import logging
import math
import os
import platform
import sys
import tempfile
import uuid
import zipfile
from collections.abc import Callable, Iterator, Sequence
from contextlib import ExitStack, contextmanager
from pathlib import Path

from .common import package_versions, progress

#: the extra that installs the engine
INSTALL = 'pip install "wbc[distributed]"'
#: distributions every worker must have in this process's version (plus the QP backends asked for)
VERSIONED = ("wbc", "numpy", "scipy", "pandas", "pin", "numba", "qpsolvers", "qpbenchmark")
#: drops the modules of ``benchmarks`` a long-lived worker kept from an earlier sweep (run by ``exec``
#: on the workers: no function of this checkout can be unpickled there before it is shipped)
_FORGET_BENCHMARKS = ("import sys\n"
                      "for name in [n for n in sys.modules if n.split('.')[0] == 'benchmarks']:\n"
                      "    del sys.modules[name]\n")

#: ``run(function, items, labels)``: ``function`` on every item, the results in the items' order
Mapper = Callable[[Callable, Sequence, Sequence[str]], list]


class SweepError(RuntimeError):
    """A sweep that cannot start or finish; the message names the cause and the fix."""


def code_digest() -> str:
    """SHA-256 of the ``benchmarks`` package's Python sources (a folder here, the shipped zip on a worker)."""
    digest = hashlib.sha256()
    files = importlib.resources.files("benchmarks")
    for name in sorted(entry.name for entry in files.iterdir() if entry.name.endswith(".py")):
        digest.update(name.encode() + b"\0" + files.joinpath(name).read_bytes())
    return digest.hexdigest()


def installed_versions(names: Sequence[str]) -> dict[str, str]:
    """Versions of ``names`` (``"-"``: missing), Python's, and ``benchmarks code``: :func:`code_digest`."""
    return {**package_versions(names), "python": platform.python_version(), "benchmarks code": code_digest()}


def check_versions(here: dict[str, str], workers: dict[str, dict[str, str]]) -> None:
    """Raise :class:`SweepError` on the first worker whose versions differ from ``here``."""
    for address, theirs in sorted(workers.items()):
        for name, version in here.items():
            if theirs.get(name) != version:
                fix = f"pip install {name}=={version}" if name not in ("python", "benchmarks code") else (
                    "the same Python" if name == "python" else "restart the workers")
                raise SweepError(
                    f"worker {address} has {name} {theirs.get(name, '-')}, this process {version} ('-': not "
                    "installed): on other versions a sweep does not reproduce the serial run; install the same "
                    f"versions on every worker ({fix})")


class Here:
    """Runs the work units in this process, one after another."""

    description = "serially, in this process"

    def __init__(self, show_progress: bool = True) -> None:
        self.show_progress = show_progress

    def __call__(self, function: Callable, items: Sequence, labels: Sequence[str]) -> list:
        iterator = progress(items, desc="work units", unit="unit") if self.show_progress and items else items
        return [function(item) for item in iterator]


class OnCluster:
    """Runs the work units on the workers of a Dask client, one task each."""

    def __init__(self, client, description: str, show_progress: bool = True) -> None:
        self.client, self.description, self.show_progress = client, description, show_progress

    def __call__(self, function: Callable, items: Sequence, labels: Sequence[str]) -> list:
        from distributed import as_completed

        run = uuid.uuid4().hex[:8]
        futures = [self.client.submit(function, item, key=f"{label} ({run})", pure=False)
                   for item, label in zip(items, labels, strict=True)]
        try:
            if self.show_progress and futures:
                for _ in progress(as_completed(futures), total=len(futures), desc="work units", unit="unit"):
                    pass
            return [self._result(future, label) for future, label in zip(futures, labels, strict=True)]
        finally:
            self.client.cancel(futures)

    @staticmethod
    def _result(future, label: str):
        from distributed.scheduler import KilledWorker

        try:
            return future.result()
        except KilledWorker as exc:
            raise SweepError(f"work unit {label!r}: the worker running it died (out of memory, killed, a crash in a "
                             f"solver?): {exc}; run that unit serially (without --workers / --scheduler) to see "
                             "why") from exc
        except Exception as exc:  # noqa: BLE001 - whatever the unit raised, named with the unit
            raise SweepError(f"work unit {label!r} failed on its worker: {type(exc).__name__}: {exc}") from exc


def _engine():
    try:
        import distributed
    except ImportError as exc:
        raise SweepError(f"running on workers (--workers / --scheduler) needs Dask's distributed scheduler, which "
                         f"does not import here ({exc}): {INSTALL}") from exc
    return distributed


def _ship_benchmarks(client) -> None:
    """Every worker, present and future, imports this checkout's ``benchmarks/`` from a zip."""
    from distributed.diagnostics.plugin import UploadFile

    client.run(exec, _FORGET_BENCHMARKS, {})
    source = Path(__file__).resolve().parent
    with tempfile.TemporaryDirectory() as folder:
        archive = Path(folder) / f"wbc_benchmarks_{code_digest()[:12]}.zip"
        with zipfile.ZipFile(archive, "w") as stream:
            for path in sorted(source.glob("*.py")):
                stream.write(path, f"benchmarks/{path.name}")
        client.register_plugin(UploadFile(str(archive)), name="wbc-benchmarks")


def checked_options(workers: int | None, scheduler: str | None, timeout: float) -> int | None:
    """The options of :func:`executor`, checked before anything starts (a SweepError naming the option and
    the fix); returns ``workers`` capped at the cores available (:func:`_capped`)."""
    if workers is not None and workers < 1:
        raise SweepError(f"--workers {workers}: give 1 or more")
    if not (isinstance(timeout, (int, float)) and 0.0 < timeout < math.inf):
        raise SweepError(f"--connect-timeout {timeout}: give a finite number of seconds > 0")
    if scheduler is not None:
        _check_address(scheduler)
    return None if workers is None else _capped(workers)


def _check_address(address: str) -> None:
    """A scheduler address Dask can connect to (``tcp://host:port``, ``host:port``, ``tls://...``): a
    malformed one is refused here, before a Client half-built on it hangs the exit for 2 x the timeout."""
    try:
        from distributed.comm.addressing import get_address_host_port
    except ImportError:  # no Dask: executor says what to install
        return
    try:
        get_address_host_port(address)
    except ValueError as exc:
        raise SweepError(f"--scheduler {address!r} is not a scheduler address ({exc}); give tcp://HOST:PORT, "
                         "e.g. tcp://127.0.0.1:8786 (what `dask scheduler` prints)") from None


def _capped(workers: int) -> int:
    """``workers``, at most the cores this process may run on (more single-threaded workers only share
    them, and each costs a process with its own imports); says so on stderr when it caps."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    if workers > cores:
        print(f"--workers {workers}: capped at {cores}, the cores available to this process", file=sys.stderr)
    return min(workers, cores)


def _connect(distributed, address: str, timeout: float):
    try:
        client = distributed.Client(address, timeout=timeout, set_as_default=False)
    except (OSError, ValueError) as exc:  # OSError: refused, timed out (TimeoutError); ValueError: not an address
        raise SweepError(f"no Dask scheduler reachable at {address!r} within {timeout:g} s ({type(exc).__name__}: "
                         f"{exc}); start one (`dask scheduler`, then `dask worker {address}` on each machine), "
                         "check the address and port, or run on local workers with --workers N") from exc
    try:
        client.wait_for_workers(1, timeout=timeout)
    except (OSError, TimeoutError) as exc:
        client.close()
        raise SweepError(f"the Dask scheduler at {address!r} has no worker after {timeout:g} s; start some "
                         f"(`dask worker {address}`)") from exc
    return client


@contextmanager
def _environment(name: str, value: str) -> Iterator[None]:
    """``os.environ[name] = value`` within the block."""
    old = os.environ.get(name)
    os.environ[name] = value
    try:
        yield
    finally:
        if old is None:
            del os.environ[name]
        else:
            os.environ[name] = old


@contextmanager
def executor(workers: int | None = None, scheduler: str | None = None, timeout: float = 10.0,
             packages: Sequence[str] = (), show_progress: bool = True) -> Iterator[Here | OnCluster]:
    """Here (neither ``workers`` nor ``scheduler``), on a LocalCluster of ``workers`` processes of one
    thread, or on the cluster of ``scheduler``; workers checked for :data:`VERSIONED` + ``packages``."""
    if workers is None and scheduler is None:
        yield Here(show_progress)
        return
    if workers is not None and scheduler is not None:
        raise SweepError("give either --workers N (a local cluster) or --scheduler ADDRESS (an existing one)")
    workers = checked_options(workers, scheduler, timeout)
    distributed = _engine()
    with ExitStack() as stack:
        logger = logging.getLogger("distributed")  # its INFO chatter reaches the root logger's handlers
        stack.callback(logger.setLevel, logger.level)
        logger.setLevel(logging.WARNING)
        if workers is not None:
            # the worker processes inherit it: their distributed loggers start at WARNING (qpbenchmark gives
            # their root logger a handler when they import it)
            stack.enter_context(_environment("DASK_LOGGING__DISTRIBUTED", "warning"))
            try:
                cluster = stack.enter_context(distributed.LocalCluster(
                    n_workers=workers, threads_per_worker=1, processes=True, host="127.0.0.1",
                    dashboard_address="127.0.0.1:0", silence_logs=logging.WARNING))
            except (OSError, RuntimeError) as exc:  # RuntimeError: "Nanny failed to start" (a worker process died)
                raise SweepError(f"could not start {workers} local Dask workers ({type(exc).__name__}: {exc}); the "
                                 "worker processes re-import the main module: run the command as a script or "
                                 "with python -m, not from an interactive session") from exc
            address, description = cluster.scheduler_address, "on a local Dask cluster (LocalCluster)"
        else:
            address, description = scheduler, f"on the Dask cluster at {scheduler}"
        client = stack.enter_context(_connect(distributed, address, timeout))
        _ship_benchmarks(client)
        names = list(dict.fromkeys([*VERSIONED, *packages]))
        check_versions(installed_versions(names), client.run(installed_versions, names))
        threads = [worker["nthreads"] for worker in client.scheduler_info()["workers"].values()]
        yield OnCluster(client, f"{description} of {len(threads)} workers, {sum(threads)} threads", show_progress)
