"""Compile kernels in worker processes after an install, while the controller is built.

On a cold numba cache (the first start after an install, or after the kernel sources changed)
the kernels a controller uses compile once each, seconds of CPU in all, one after the other in
one process. This pool runs them on the machine's other cores: a *job* (``"op FRAME_TASK"``:
an op's C callback; ``"kernel qp_defect"``: a compiled function) is handed to an idle worker
process, which compiles it into numba's on-disk cache (the cache directory is shared, numba
writes each entry atomically); the controller's process then reads the machine code from
the cache instead of compiling it. The process never waits for work it could do itself: a job
no worker has started yet is taken back (:meth:`CompilePool.take`) and compiled in process;
only a job a worker is compiling is waited for (:meth:`CompilePool.wait`). Workers take the
most recently submitted job, the process the earliest, so the two meet in the middle of a
controller's list; while the process waits for a job a worker compiles, it compiles the earliest
job no worker has started (:meth:`CompilePool.take_oldest`) instead of idling. A job a worker
could not compile (it failed, or the worker died) is compiled in process, as without the pool.

Each worker runs :func:`._worker.run_worker` of this process's wbc (no pool of its own) with
``wbc`` itself *not* executed (:data:`BOOTSTRAP`): :mod:`wbc.runtime` imports nothing else of wbc,
so the worker skips Pinocchio, SciPy and the solvers and imports only numba and the kernel
modules (ready in 0.9-1.1 s instead of 1.1-2.4 s, measured under load ~2 on 2 cores); the process
compiles alone until then. It says ``ready``, then reads
one job a line on stdin and answers ``ok <job>`` or ``failed <job>``; it exits when its stdin
closes (this process exits or :meth:`CompilePool.close`).
"""

from __future__ import annotations

import atexit
import math
import os
import subprocess
import sys
import threading
import time
from pathlib import Path

#: environment variable: the number of worker processes (0: compile in process only); default
#: one per idle core beyond the first, at most :data:`MAX_WORKERS` (:func:`worker_count`)
WORKERS_VARIABLE = "WBC_COMPILE_WORKERS"
#: the most workers started without ``WBC_COMPILE_WORKERS``
MAX_WORKERS = 3
#: what a worker says once it can take jobs
READY = "ready"


#: [s] the shortest window over which :func:`worker_count` measures the idle cores
IDLE_WINDOW = 0.05
#: a worker: run :func:`._worker.run_worker` of the wbc in folder ``{folder}`` without executing
#: ``wbc/__init__.py`` (the package module is created from its spec, not run)
BOOTSTRAP = ("import importlib.util, sys\n"
             "spec = importlib.util.spec_from_file_location('wbc', {init!r}, submodule_search_locations=[{folder!r}])\n"
             "sys.modules['wbc'] = importlib.util.module_from_spec(spec)\n"
             "from wbc.runtime.kernels._worker import run_worker\n"
             "run_worker()\n")


def cpu_times() -> tuple[float, float, float] | None:
    """(time.monotonic(), idle, total) jiffies of all CPUs (Linux ``/proc/stat``: idle and I/O wait of
    user, nice, system, idle, iowait, irq, softirq, steal), None where there is no such file."""
    try:
        with open("/proc/stat", encoding="ascii") as stat:
            fields = stat.readline().split()
    except OSError:
        return None
    if not fields or fields[0] != "cpu" or len(fields) < 9:
        return None
    values = [float(value) for value in fields[1:9]]
    return time.monotonic(), values[3] + values[4], sum(values)


def process_jiffies(pid: int) -> float:
    """CPU time (user + system) of the process ``pid`` so far, in the clock ticks of ``/proc/stat``
    (Linux ``/proc/<pid>/stat``); 0 where it cannot be read."""
    try:
        with open(f"/proc/{pid}/stat", encoding="ascii") as stat:
            fields = stat.read().rsplit(")", 1)[1].split()
        return float(fields[11]) + float(fields[12])  # utime, stime (fields 14 and 15 of proc(5))
    except (OSError, IndexError, ValueError):
        return 0.0


#: the CPU times when this module was imported (with :mod:`wbc.runtime.kernels`, early in ``import wbc``)
_IMPORTED = cpu_times()
#: this process's own CPU time then (clock ticks, :func:`process_jiffies`)
_OWN_AT_IMPORT = process_jiffies(os.getpid())


def usable_cores() -> int:
    """The cores this process may run on (its affinity where the platform has one)."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)


def worker_count(helpers: tuple[int, ...] = ()) -> int:
    """Workers to start: ``WBC_COMPILE_WORKERS`` when set, else one per core left idle by everything
    else while this process ran (rounded; at most :data:`MAX_WORKERS` and the cores available
    less one). The idle cores are measured from ``/proc/stat`` since this module was imported
    (a window of at least :data:`IDLE_WINDOW`, during which this process imported wbc and built its
    objects on one core), elsewhere estimated from the 1-minute load average (which still counts a
    ``pip install`` that ended seconds ago: measured, it started no worker after one). A worker
    on a busy core only competes with the process it should relieve: on a 2-core machine kept
    busy by other work a first run took longer with one (benchmarks/README.md, section 8).
    With ``helpers`` (workers started early, whose work this process would otherwise do) the idle
    cores are the CPUs less this process's less the CPU time of every other process but theirs."""
    setting = os.environ.get(WORKERS_VARIABLE, "").strip()
    if setting:
        try:
            return max(0, int(setting))
        except ValueError:
            return 0
    cores = usable_cores()
    idle = _idle_cores(helpers)
    if idle is None:
        try:
            idle = cores - 1 - os.getloadavg()[0]  # (this process's own load counted as a busy core)
        except OSError:  # (no load average on this platform)
            idle = cores - 1
    return max(0, min(math.floor(idle + 0.5), cores - 1, MAX_WORKERS))


def _idle_cores(helpers: tuple[int, ...] = ()) -> float | None:
    """Cores idle since this module was imported, this process's own busy core not counted as idle
    (:func:`cpu_times`; with ``helpers``, see :func:`worker_count`); None without ``/proc/stat``."""
    now = cpu_times()
    if _IMPORTED is None or now is None:
        return None
    if now[0] - _IMPORTED[0] < IDLE_WINDOW:  # too short to tell: this process had no time to be busy
        time.sleep(IDLE_WINDOW)
        later = cpu_times()
        if later is None or later[2] <= now[2]:
            return None
        return (later[1] - now[1]) / (later[2] - now[2]) * (os.cpu_count() or 1) - 1.0  # (this process slept)
    if now[2] <= _IMPORTED[2]:
        return None
    cpus = os.cpu_count() or 1
    if helpers:  # idle = the CPUs less this process's core less what the others kept busy (not the helpers)
        busy = (now[2] - _IMPORTED[2]) - (now[1] - _IMPORTED[1])
        own = process_jiffies(os.getpid()) - _OWN_AT_IMPORT
        others = busy - own - sum(process_jiffies(pid) for pid in helpers)
        return cpus - 1 - max(others, 0.0) / ((now[2] - _IMPORTED[2]) / cpus)
    return (now[1] - _IMPORTED[1]) / (now[2] - _IMPORTED[2]) * cpus  # (all CPUs of the machine)


class CompilePool:
    """Worker processes compiling jobs into numba's cache (see the module docstring)."""

    def __init__(self, workers: int) -> None:
        self._condition = threading.Condition()
        self._pending: list[str] = []  #: submitted, not started (oldest first)
        self._running: set[str] = set()
        self._finished: dict[str, bool] = {}  #: by a worker: whether it compiled
        self._closed = False
        self._owner = os.getpid()  #: a forked child shares the workers' pipes, not the workers (close: its owner's)
        folder = Path(__file__).resolve().parents[2]  # this wbc
        bootstrap = BOOTSTRAP.format(init=str(folder / "__init__.py"), folder=str(folder))
        environment = {**os.environ, WORKERS_VARIABLE: "0"}
        self._processes = [subprocess.Popen([sys.executable, "-c", bootstrap], stdin=subprocess.PIPE,
                                            stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True,
                                            env=environment)
                           for _ in range(workers)]
        for process in self._processes:
            threading.Thread(target=self._serve, args=(process,), daemon=True).start()
        atexit.register(self.close)

    def submit(self, jobs: list[str]) -> None:
        """Queue ``jobs`` not yet known to the pool."""
        with self._condition:
            known = set(self._pending) | self._running | set(self._finished)
            self._pending += [job for job in dict.fromkeys(jobs) if job not in known]
            self._condition.notify_all()

    def take(self, job: str) -> bool:
        """Whether ``job`` was still waiting for a worker (it is then the caller's to compile)."""
        with self._condition:
            if job in self._pending:
                self._pending.remove(job)
                return True
            return False

    @property
    def pids(self) -> tuple[int, ...]:
        """The process ids of the workers."""
        return tuple(process.pid for process in self._processes)

    def take_oldest(self) -> str | None:
        """The earliest job no worker has started, now the caller's to compile; None when there is none."""
        with self._condition:
            return self._pending.pop(0) if self._pending else None

    def running(self, job: str) -> bool:
        """Whether a worker is compiling ``job`` now."""
        with self._condition:
            return job in self._running

    def wait(self, job: str) -> bool:
        """Wait while a worker compiles ``job``; whether a worker compiled it (else the caller compiles it)."""
        with self._condition:
            while job in self._running:
                self._condition.wait()
            return self._finished.get(job, False)

    def close(self) -> None:
        """Stop the workers now; pending jobs are dropped and a job at hand is abandoned: nobody
        waits for it (the pool closes when its process exits, or dismisses workers it started
        early), and numba writes each cache entry atomically, so nothing half-written stays."""
        if os.getpid() != self._owner:  # (a forked child's copy: the workers are its parent's)
            return
        with self._condition:
            self._closed = True
            self._pending.clear()
            self._condition.notify_all()
        for process in self._processes:
            for stop in (process.stdin.close, process.kill):  # type: ignore[union-attr]
                try:
                    stop()
                except OSError:
                    pass
            process.wait()

    def _serve(self, process: subprocess.Popen[str]) -> None:
        """Hand jobs to one worker, newest first, once it has started (until then the process
        takes them), until the pool closes or the worker dies."""
        if not _answer(process, (READY,)):
            return
        while True:
            with self._condition:
                while not self._pending and not self._closed:
                    self._condition.wait()
                if self._closed:
                    return
                job = self._pending.pop()
                self._running.add(job)
            try:
                process.stdin.write(job + "\n")  # type: ignore[union-attr]
                process.stdin.flush()  # type: ignore[union-attr]
            except (OSError, ValueError):
                pass
            answer = _answer(process, (f"ok {job}", f"failed {job}"))
            with self._condition:
                self._running.discard(job)
                self._finished[job] = answer == f"ok {job}"
                self._condition.notify_all()
            if not answer:  # the worker died: the rest goes to the other workers or the process
                return


def _answer(process: subprocess.Popen[str], answers: tuple[str, ...]) -> str:
    """The next line of ``answers`` the worker writes (other output, e.g. numba's debug prints,
    skipped); "" when it died."""
    while True:
        try:
            line = process.stdout.readline()  # type: ignore[union-attr]
        except (OSError, ValueError):
            return ""
        if not line or line.strip() in answers:
            return line.strip()
